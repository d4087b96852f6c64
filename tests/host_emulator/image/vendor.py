"""Test helpers: the PlatformIO tree's vendor files (SAMD21 headers, the Seeed XIAO variant), parsed independently."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from host_emulator.image import regtable

SEEED = Path("framework-arduino-samd-seeed")
VARIANT_CPP = SEEED / "variants" / "XIAO_m0" / "variant.cpp"
VARIANT_H = SEEED / "variants" / "XIAO_m0" / "variant.h"
WVARIANT_H = SEEED / "cores" / "arduino" / "WVariant.h"
NO_TREE = "no SAMD21 vendor headers (set MC_PIO_TREE to an offline PlatformIO tree, or install PlatformIO's atmelsam)"


def include_dirs() -> tuple[Path, Path]:
    """(samd21 include dir, CMSIS core include dir), or skip the test with one line when the tree is absent."""
    try:
        return regtable.find_include_dirs()
    except regtable.RegTableError:
        pytest.skip(NO_TREE)


def packages_dir() -> Path:
    """The `packages` folder of the PlatformIO tree that holds the vendor headers."""
    atmel, _ = include_dirs()
    depth = len(regtable.CMSIS_ATMEL_SUBDIR.parts)
    return atmel.parents[depth - 1]


def seeed_file(rel: Path) -> Path:
    """A file of the Seeed SAMD core in the tree, or skip with one line."""
    p = packages_dir() / rel
    if not p.is_file():
        pytest.skip(f"{rel} not in the PlatformIO tree (the Seeed SAMD core is not installed)")
    return p


@dataclass(frozen=True)
class VariantPin:
    arduino: int  # index in g_APinDescription (the Arduino pin number, D0 = 0)
    port_pin: str  # "PA02"
    pio_type: str  # "PIO_SERCOM_ALT"
    extint: str  # "EXTERNAL_INT_9", "EXTERNAL_INT_NMI", "EXTERNAL_INT_NONE"


_ROW = re.compile(r"^\s*\{\s*PORT([AB])\s*,\s*(\d+)\s*,\s*(\w+)\s*,.*?,\s*(EXTERNAL_INT_\w+)\s*\}", re.M)


def variant_pins() -> list[VariantPin]:
    """g_APinDescription of the XIAO variant, row by row (the row's index is its Arduino pin number)."""
    text = seeed_file(VARIANT_CPP).read_text(errors="replace")
    m = re.search(r"g_APinDescription\s*\[\s*\]\s*=\s*\{(.*?)\n\}\s*;", text, re.S)
    assert m, f"{VARIANT_CPP}: g_APinDescription[] not found"
    body = re.sub(r"//[^\n]*", "", m.group(1))
    rows = [
        VariantPin(i, f"P{r.group(1)}{int(r.group(2)):02d}", r.group(3), r.group(4))
        for i, r in enumerate(_ROW.finditer(body))
    ]
    assert len(rows) == body.count("{"), f"{VARIANT_CPP}: a g_APinDescription row not understood"
    return rows


def variant_define(name: str) -> int:
    """An integer #define of the XIAO variant.h (e.g. PIN_WIRE_SDA)."""
    text = seeed_file(VARIANT_H).read_text(errors="replace")
    m = re.search(rf"^#define\s+{name}\s+\(?\s*(\d+)u?\s*\)?", text, re.M)
    assert m, f"{VARIANT_H}: {name} not defined"
    return int(m.group(1))


def pio_type_letter(pio_type: str) -> str:
    """The PMUX letter pinPeripheral() writes for a pin type: its value in WVariant.h's EPioType (PIO_EXTINT = 0 =
    function A, then one letter per member, in the order the enum lists them before its first #if)."""
    text = seeed_file(WVARIANT_H).read_text(errors="replace")
    m = re.search(r"typedef\s+enum\s+_EPioType\s*\{(.*?)\}\s*EPioType", text, re.S)
    assert m, f"{WVARIANT_H}: EPioType not found"
    body = re.sub(r"/\*.*?\*/", "", m.group(1), flags=re.S)
    members = []
    for line in body.splitlines():
        s = line.strip()
        if s.startswith("#"):
            break
        members += [t.strip() for t in s.split(",") if t.strip()]
    assert members[:2] == ["PIO_NOT_A_PIN=-1", "PIO_EXTINT=0"], members[:2]
    names = [t.split("=")[0] for t in members[1:]]
    return "ABCDEFGH"[names.index(pio_type)]
