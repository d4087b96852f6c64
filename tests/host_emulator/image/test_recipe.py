"""docs/image-tier.md's recipe for adding a peripheral model, followed as written in a scratch copy of the runtime's
C: a model of the RTC (which the tier does not model) written, registered and built, and an RTC register access
that was an error naming the RTC reaches it. Needs no image and no PlatformIO tree."""

from __future__ import annotations

import dataclasses
import re
import shutil
from pathlib import Path

import pytest

from host_emulator.image import regsnapshot, regtable, runtime
from host_emulator.image.harness import Harness, HarnessError

RECIPE = Path(__file__).resolve().parents[3] / "docs" / "image-tier.md"

# Step 1: csrc/sam_rtc.c. Mode 0 (32-bit counter) only, its registers stored; a COUNT written equal to COMP0 sets
# INTFLAG.CMP0, and the RTC's interrupt follows INTFLAG & INTENSET (DS40001882, 19.6.2.3 and 19.6.5).
SAM_RTC_C = """\
/* RTC: mode 0's registers stored; a COUNT written equal to COMP0 sets CMP0 and the interrupt (a recipe test's). */
#include "sam.h"
#include "sam_vendor_gen.h"

static uint32_t rtc_reg(sam_mcu_t *m, int pi, uint32_t off)
{
    return sam_rd32(m->regs[pi] + off);
}

static int rtc_view(sam_mcu_t *m, int pi)
{
    /* views in header order: MODE0, MODE1, MODE2; CTRL.MODE 0 = COUNT32, 1 = COUNT16, 2 = CLOCK */
    return (int)((rtc_reg(m, pi, RTC_MODE0_CTRL_OFFSET) & RTC_MODE0_CTRL_MODE_Msk) >> RTC_MODE0_CTRL_MODE_Pos) + 1;
}

static int rtc_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    uint8_t *r = m->regs[pi];
    if (rtc_view(m, pi) != 1)
        return SAM_GENERIC;
    sam_generic_write(m, ri, v, mask);
    if (sam_regs[ri].offset == RTC_MODE0_COUNT_OFFSET
        && rtc_reg(m, pi, RTC_MODE0_COUNT_OFFSET) == rtc_reg(m, pi, RTC_MODE0_COMP_OFFSET))
        r[RTC_MODE0_INTFLAG_OFFSET] |= RTC_MODE0_INTFLAG_CMP0;
    sam_irq_level(m, sam_periphs[pi].irq, (r[RTC_MODE0_INTFLAG_OFFSET] & r[RTC_MODE0_INTENSET_OFFSET]) != 0);
    sam_activity(m);
    return SAM_DONE;
}

const sam_model_t sam_model_rtc = {"Rtc", NULL, rtc_view, NULL, rtc_write, NULL};
"""
USED_MACROS = {
    "RTC_MODE0_CTRL_OFFSET",
    "RTC_MODE0_CTRL_MODE_Pos",
    "RTC_MODE0_CTRL_MODE_Msk",
    "RTC_MODE0_COUNT_OFFSET",
    "RTC_MODE0_COMP_OFFSET",
    "RTC_MODE0_INTFLAG_OFFSET",
    "RTC_MODE0_INTENSET_OFFSET",
    "RTC_MODE0_INTFLAG_CMP0_Pos",
    "RTC_MODE0_INTFLAG_CMP0",
}
CMP0 = 1 << 0


def register_in_models(text: str) -> str:
    """Step 2, as the recipe words it: the row in MODELS and the name on the `extern` line above the table."""
    extern = re.compile(r"(extern const sam_model_t [^;]*);")
    row = re.compile(r"(MODELS\[\] = \{\n)")
    assert len(extern.findall(text)) == 1 and len(row.findall(text)) == 1, "sam_models.c no longer as the recipe says"
    text = extern.sub(r"\1, sam_model_rtc;", text)
    return row.sub(r'\1    {"Rtc", &sam_model_rtc},\n', text)


def stand_in_macros(table: regtable.Table) -> list[str]:
    """What step 3 (`regsnapshot --write` where the vendor's headers are) adds to the snapshot for sam_rtc.c: the
    vendor's macros it uses, here valued from the snapshot's own register table, in the headers' form."""
    rtc = next(p for p in table.peripherals if p.name == "RTC")
    reg = {r.name: r for r in rtc.registers}
    mode = next(f for f in reg["MODE0.CTRL"].fields if f.name == "MODE")
    cmp0 = next(f for f in reg["MODE0.INTFLAG"].fields if f.name == "CMP0")
    return [
        *(f"RTC_MODE0_{n}_OFFSET 0x{reg[f'MODE0.{n}'].offset:x}" for n in ("CTRL", "INTENSET", "INTFLAG", "COUNT")),
        f"RTC_MODE0_COMP_OFFSET 0x{reg['MODE0.COMP[0]'].offset:x}",
        f"RTC_MODE0_CTRL_MODE_Pos {mode.pos}",
        f"RTC_MODE0_CTRL_MODE_Msk (0x{(1 << mode.width) - 1:x}ul << RTC_MODE0_CTRL_MODE_Pos)",
        f"RTC_MODE0_INTFLAG_CMP0_Pos {cmp0.pos}",
        "RTC_MODE0_INTFLAG_CMP0 (0x1ul << RTC_MODE0_INTFLAG_CMP0_Pos)",
    ]


def table_for(csrc: Path) -> regtable.Table:
    """The table the copy builds against after step 3: the vendor's headers where they are, else the snapshot with
    the new file's macros added."""
    snap = regsnapshot.load_snapshot()
    assert snap.vendor_macros is not None
    missing = USED_MACROS - {m.split()[0] for m in snap.vendor_macros}
    try:
        table = regtable.load()
    except regtable.RegTableError:
        assert missing == USED_MACROS, "the committed snapshot already keeps RTC macros: step 3 needs rewording"
        return dataclasses.replace(snap, vendor_macros=(*snap.vendor_macros, *stand_in_macros(snap)))
    # with the headers: `regsnapshot --write` would keep these, and the stand-in's values are the headers'
    kept = {m.split()[0] for m in regsnapshot.runtime_macros(Path(table.source), csrc)}
    assert USED_MACROS <= kept
    vendor = dict(m.split(maxsplit=1) for m in regsnapshot.runtime_macros(Path(table.source), csrc))
    ours = dict(m.split(maxsplit=1) for m in stand_in_macros(snap))
    assert {n: macro_value(n, vendor) for n in ours} == {n: macro_value(n, ours) for n in ours}
    return table


def macro_value(name: str, defs: dict[str, str]) -> int:
    """The integer an object-like macro of these forms (`0x18`, `2`, `(0x3ul << X_Pos)`) expands to."""
    expr = re.sub(r"\b(0x[0-9a-fA-F]+|\d+)[uUlL]*\b", r"\1", defs[name])
    expr = re.sub(r"\b[A-Z]\w*_Pos\b", lambda m: str(macro_value(m.group(0), defs)), expr)
    assert re.fullmatch(r"[0-9a-fx()<\s]+", expr), f"{name}: {defs[name]}"
    return int(eval(expr))


def test_the_recipe_is_the_one_in_the_docs():
    text = RECIPE.read_text()
    assert "To add a model of a peripheral (say the RTC):" in text
    assert '`{"Rtc", &sam_model_rtc},`' in text and "`extern`" in text
    assert "python -m host_emulator.image.regsnapshot --write" in text


def test_following_the_recipe_makes_the_rtc_reachable(tmp_path):
    # before: the tier has no RTC model, and an access to its registers is an error naming the peripheral
    with pytest.raises(HarnessError, match=r"write of RTC \+ 0x18: the RTC peripheral is not modelled"):
        Harness().write("RTC.MODE0.COMP[0]", 1000)

    csrc = tmp_path / "csrc"
    shutil.copytree(runtime.IMAGE_CSRC, csrc)
    (csrc / "sam_rtc.c").write_text(SAM_RTC_C)  # step 1
    models = csrc / "sam_models.c"
    models.write_text(register_in_models(models.read_text()))  # step 2
    built = runtime.load(csrc=csrc, table=table_for(csrc), build_dir=tmp_path / "build")  # step 3, then the build

    h = Harness(built=built)
    h.write("RTC.MODE0.COMP[0]", 1000)
    assert h.read("RTC.MODE0.COMP[0]") == 1000
    h.write("RTC.MODE0.INTENSET", CMP0)
    h.write("RTC.MODE0.COUNT", 999)
    assert h.read("RTC.MODE0.INTFLAG") == 0 and h.irq("RTC") not in h.pending()
    h.write("RTC.MODE0.COUNT", 1000)
    assert h.read("RTC.MODE0.INTFLAG") == CMP0 and h.irq("RTC") in h.pending()
    assert built is not runtime.load()  # the copy's build did not replace the tier's own
