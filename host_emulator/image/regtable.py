"""SAMD21 register table generated from the vendor's device headers (CMSIS-Atmel samd21g18a.h and CMSIS core_cm0plus.h).

Nothing here is typed by hand: every peripheral instance, its base address and interrupt line come from the device
header, and so does its PAC write-protection bit (``ID_<name>``: bit ``ID % 32`` of PAC ``ID // 32``);
every register's offset, width and access from the ``/**< \\brief Offset: 0x.. (R/W 16) ..`` comment of its
member in the component struct (arrays, nested groups such as ``PortGroup Group[2]`` and the mode views of unions
such as ``Tc.COUNT16`` / ``Sercom.I2CS`` flattened); reset values from ``<REG>_RESETVALUE``; fields from
``<REG>_<FIELD>_Pos`` / ``_Msk``. The system control space (NVIC, SCB, SysTick) comes from CMSIS's core_cm0plus.h
the same way (its comments carry offsets and access; widths from the member's C type).

The access rules of the emulator's generic register layer are derived from these facts (``Register.kind``):

* ``w1c``: a flag register (``INTFLAG``, ``EPINTFLAG``, ``PINTFLAG``, ``CHINTFLAG``, EIC's ``NMIFLAG``): writing 1
  clears a bit;
* ``set`` / ``clr`` / ``tgl``: an alias (``OUTSET`` of ``OUT``, ``INTENSET``/``INTENCLR`` of one hidden enable
  mask held by the ``...SET`` register, ``EPSTATUSSET`` of ``EPSTATUS``): writing 1 sets / clears / toggles;
* ``plain``: stored as written (reads of write-only and writes of read-only registers are errors).

``SWRST`` and ``SYNCBUSY`` are found by field name (``Register.field``) by the behaviour models. The table is
emitted as C (``emit_c``) for the compiled runtime and kept in Python for listings and tests.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from . import ImageTierUnavailable

CMSIS_ATMEL_SUBDIR = Path("framework-cmsis-atmel/CMSIS/Device/ATMEL/samd21/include")
CMSIS_CORE_SUBDIR = Path("framework-cmsis/CMSIS/Core/Include")
DEVICE_HEADER = "samd21g18a.h"

# unions of mode views (the CTRLA.MODE or the USB mode selects the active one)
VIEW_UNIONS = ("Tc", "Sercom", "Usb")

# What the compiled runtime can hold (csrc/sam.h, sam_regtab.h, sam_mmio.c), checked before a table reaches C (check):
# the peripheral regions it maps (sam_mmio.c's REGION_BASE/REGION_SIZE: APB A, B, C, the IOBUS, the system control
# space), the Cortex-M0+'s 32 external interrupt lines, SAM_MAX_PERIPH instances of at most 4 mode views each
PERIPHERAL_REGIONS = (
    (0x40000000, 0x2000),
    (0x41000000, 0x8000),
    (0x42000000, 0x6000),
    (0x60000000, 0x1000),
    (0xE000E000, 0x1000),
)
# the APB bridges A, B, C: each has its PAC (PAC0, PAC1, PAC2) at its base, the 64 KiB the runtime's write-protection
# pages cover (csrc/sam_pac.c: 1 KiB pages, a 64-bit mask per bridge)
APB_BRIDGES = (0x40000000, 0x41000000, 0x42000000)
APB_BRIDGE_SPAN = 0x10000
NVIC_LINES = 32
MAX_PERIPHERALS = 48
MAX_VIEWS = 4
MAX_REGISTERS = 0x7FFF  # register indices are int16_t in the offset maps
MAX_FIELDS = 0xFFFF  # sam_reg_t.field0 is a uint16_t


class RegTableError(ImageTierUnavailable):
    """The vendor headers are missing or not in the expected form."""


class HeadersMissing(RegTableError):
    """No vendor headers where they were looked for (the committed snapshot may stand in: regsnapshot)."""


@dataclass(frozen=True)
class Field:
    name: str
    pos: int
    width: int

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.pos


@dataclass(frozen=True)
class Register:
    periph: str  # instance, e.g. "TC3"
    view: str  # "" for registers of every view, else e.g. "COUNT16", "I2CS", "DEVICE"
    name: str  # path inside the instance, e.g. "CTRLA", "COUNT16.CC[0]", "Group[0].PINCFG[10]"
    offset: int  # from the instance base
    size: int  # bytes: 1, 2, 4
    access: str  # "RW", "R", "W"
    reset: int
    key: str  # the header's register key, e.g. "TC_COUNT16_CC" (the prefix of its _Pos/_Msk/_RESETVALUE)
    fields: tuple[Field, ...] = ()

    @property
    def full(self) -> str:
        return f"{self.periph}.{self.name}"

    @property
    def leaf(self) -> str:
        """The register's own name without group, view or index: "PINCFG" of "Group[0].PINCFG[10]"."""
        return re.sub(r"\[\d+\]$", "", self.name.rsplit(".", 1)[-1])

    def field(self, name: str) -> Field | None:
        return next((f for f in self.fields if f.name == name), None)

    @property
    def kind(self) -> str:
        leaf = self.leaf
        if leaf.endswith("INTFLAG") or leaf == "NMIFLAG":  # INTFLAG, EPINTFLAG, PINTFLAG, CHINTFLAG; EIC's NMIFLAG
            return "w1c"
        for suf in ("SET", "CLR", "TGL"):
            if leaf.endswith(suf) and len(leaf) > 3 and leaf != "TGL":
                return suf.lower()
        return "plain"


@dataclass
class Peripheral:
    name: str
    struct: str  # component struct type, e.g. "Tc"
    base: int
    size: int  # bytes of its register window
    irq: int | None  # NVIC line, or None
    views: tuple[str, ...] = ()  # mode views ("" = no views)
    registers: list[Register] = field(default_factory=list)
    pac: int | None = None  # ID_<name>: bit pac % 32 of PAC<pac // 32>'s write-protection mask, or None


@dataclass
class Table:
    peripherals: list[Peripheral]
    source: str  # where the headers were read (regsnapshot.SOURCE: the committed snapshot)
    pinmux: list[PinFunction] = field(default_factory=list)
    vendor_macros: tuple[str, ...] | None = None  # a snapshot's (regsnapshot.py): the runtime's vendor macros

    def registers(self) -> list[Register]:
        return [r for p in self.peripherals for r in p.registers]

    def periph(self, name: str) -> Peripheral:
        for p in self.peripherals:
            if p.name == name:
                return p
        raise KeyError(name)

    def reg(self, periph: str, name: str) -> Register:
        for r in self.periph(periph).registers:
            if r.name == name:
                return r
        raise KeyError(f"{periph}.{name}")


# ---------------------------------------------------------------- locating the headers


def find_include_dirs(pio_tree: str | os.PathLike | None = None) -> tuple[Path, Path]:
    """(samd21 include dir, CMSIS core include dir) in a PlatformIO tree: MC_PIO_TREE's packages, else
    ~/.platformio/packages. RegTableError naming what was looked at when neither holds them."""
    tried = []
    roots = []
    if pio_tree:
        roots.append(Path(pio_tree) / "packages")
    env = os.environ.get("MC_PIO_TREE")
    if env:
        roots.append(Path(env) / "packages")
    core = os.environ.get("PLATFORMIO_CORE_DIR")
    if core:
        roots.append(Path(core) / "packages")
    roots.append(Path.home() / ".platformio" / "packages")
    for r in roots:
        a, c = r / CMSIS_ATMEL_SUBDIR, r / CMSIS_CORE_SUBDIR
        tried.append(str(r))
        if (a / DEVICE_HEADER).is_file() and (c / "core_cm0plus.h").is_file():
            return a, c
    raise HeadersMissing(
        "the SAMD21 device headers (framework-cmsis-atmel, framework-cmsis) are not installed: looked in "
        + ", ".join(tried)
        + "; set MC_PIO_TREE to an offline PlatformIO tree or install PlatformIO's atmelsam platform"
    )


# ---------------------------------------------------------------- parsing

_MEMBER_ATMEL = re.compile(
    r"^\s*(__IO|__I|__O)\s+(\w+)_Type\s+(\w+)(?:\[(\w+)\])?;\s*/\*\*<\s*\\brief Offset:\s*(0x[0-9A-Fa-f]+)"
    r"\s*\((R?)\s*/\s*(W?)\s*(\d+)\)"
)
_MEMBER_GROUP = re.compile(r"^\s*(\w+)\s+(\w+)(?:\[(\w+)\])?;\s*/\*\*<\s*\\brief Offset:\s*(0x[0-9A-Fa-f]+)")
_MEMBER_RESERVED = re.compile(
    r"^\s*(RoReg8|RoReg16|RoReg|uint8_t|uint16_t|uint32_t)\s+(R\w*[Ss][Ee][Rr][Vv][Ee][Dd]\w*)(?:\[(\w+)\])?;"
)
_MEMBER_CMSIS = re.compile(
    r"^\s*(__IOM|__IM|__OM)\s+(uint8_t|uint16_t|uint32_t)\s+(\w+)(?:\[(\w+)\])?;\s*/\*!<\s*Offset:\s*(0x[0-9A-Fa-f]+)"
    r"\s*\((R?)\s*/\s*(W?)\s*\)"
)
_STRUCT = re.compile(r"typedef\s+(struct|union)\s*\{(.*?)\}\s*(\w+)\s*;", re.S)
_DEFINE = re.compile(r"^#define\s+(\w+)\s+(.*?)\s*(?:/\*.*)?$", re.M)
_CTYPE_SIZE = {"uint8_t": 1, "uint16_t": 2, "uint32_t": 4, "RoReg8": 1, "RoReg16": 2, "RoReg": 4}


def _int(text: str) -> int:
    return int(text.rstrip("uUlL"), 0)


@dataclass
class _Member:
    kind: str  # "reg", "group", "reserved"
    name: str
    count: int  # array length (1 when not an array)
    offset: int | None
    size: int = 0  # reg: width; reserved: bytes per element
    access: str = ""
    key: str = ""  # reg: header key; group: struct type
    is_array: bool = False


_COND = re.compile(r"^#\s*if\s+defined\s*\(\s*(\w+)\s*\)\s*&&\s*\(\s*\1\s*==\s*(\w+)\s*\)\s*$")


def _conditional_lines(body: str, config: dict[str, str]) -> list[str]:
    """The lines of a struct body kept by its preprocessor conditionals, evaluated against the device header's
    defines (core_cm0plus.h has `#if defined (__VTOR_PRESENT) && (__VTOR_PRESENT == 1U)` in SCB_Type)."""
    keep: list[bool] = []
    out = []
    for line in body.splitlines():
        s = line.strip()
        if s.startswith("#"):
            if m := _COND.match(s):
                keep.append(m.group(1) in config and _int(config[m.group(1)]) == _int(m.group(2)))
            elif s.startswith("#else"):
                keep[-1] = not keep[-1]
            elif s.startswith("#endif"):
                keep.pop()
            else:
                raise RegTableError(f"unsupported preprocessor line in a register struct: {s!r}")
            continue
        if all(keep):
            out.append(line)
    return out


def _parse_structs(text: str, config: dict[str, str]) -> dict[str, tuple[str, list[_Member]]]:
    """name -> ("struct"|"union", members) of every typedef struct/union whose members are registers."""
    out: dict[str, tuple[str, list[_Member]]] = {}
    for m in _STRUCT.finditer(text):
        what, body, name = m.group(1), m.group(2), m.group(3)
        members: list[_Member] = []
        for line in _conditional_lines(body, config):
            if a := _MEMBER_ATMEL.match(line):
                acc = ("R" if a.group(6) else "") + ("W" if a.group(7) else "")
                n = a.group(4)
                members.append(
                    _Member(
                        "reg",
                        a.group(3),
                        _int(n) if n else 1,
                        int(a.group(5), 16),
                        int(a.group(8)) // 8,
                        acc,
                        a.group(2),
                        bool(n),
                    )
                )
            elif c := _MEMBER_CMSIS.match(line):
                acc = ("R" if c.group(6) else "") + ("W" if c.group(7) else "")
                n = c.group(4)
                members.append(
                    _Member(
                        "reg",
                        c.group(3),
                        _int(n) if n else 1,
                        int(c.group(5), 16),
                        _CTYPE_SIZE[c.group(2)],
                        acc,
                        f"{name.removesuffix('_Type')}_{c.group(3)}",
                        bool(n),
                    )
                )
            elif r := _MEMBER_RESERVED.match(line):
                n = r.group(3)
                members.append(_Member("reserved", r.group(2), _int(n) if n else 1, None, _CTYPE_SIZE[r.group(1)]))
            elif g := _MEMBER_GROUP.match(line):
                n = g.group(3)
                members.append(
                    _Member(
                        "group", g.group(2), _int(n) if n else 1, int(g.group(4), 16), key=g.group(1), is_array=bool(n)
                    )
                )
        if any(mm.kind in ("reg", "group") for mm in members):
            out[name] = (what, members)
    return out


class _Headers:
    def __init__(self, atmel: Path, core: Path) -> None:
        self.atmel, self.core = atmel, core
        device = (atmel / DEVICE_HEADER).read_text(errors="replace")
        config = {d.group(1): d.group(2).split()[0] for d in _DEFINE.finditer(device) if d.group(2)}
        comp = atmel / "component"
        self.texts = {p.stem: p.read_text(errors="replace") for p in sorted(comp.glob("*.h"))}
        self.core_text = (core / "core_cm0plus.h").read_text(errors="replace")
        self.structs: dict[str, tuple[str, list[_Member]]] = {}
        self.defines: dict[str, str] = {}
        # the device header last: it adds the part's own values (DSU_DID_RESETVALUE, the device id)
        for t in [*self.texts.values(), self.core_text, device]:
            self.structs.update(_parse_structs(t, config))
            for d in _DEFINE.finditer(t):
                self.defines.setdefault(d.group(1), d.group(2))

    def sizeof(self, struct: str) -> int:
        what, members = self.structs[struct]
        end = 0
        cur = 0
        for m in members:
            if m.kind == "reserved":
                cur += m.size * m.count
            else:
                assert m.offset is not None
                if what == "struct" and m.offset != cur:
                    raise RegTableError(f"{struct}.{m.name}: offset 0x{m.offset:x}, expected 0x{cur:x} from the layout")
                size = m.size if m.kind == "reg" else self.sizeof(m.key)
                cur = m.offset + size * m.count
                if what == "union":
                    cur = 0
                    end = max(end, m.offset + size * m.count)
                    continue
            end = max(end, cur)
        return end

    def reset(self, key: str) -> int:
        v = self.defines.get(f"{key}_RESETVALUE")
        if v is None:
            return 0
        return _int(v.strip("()").replace("_U_(", "").replace(")", "").split()[0])

    def fields(self, key: str) -> tuple[Field, ...]:
        out = []
        pre = f"{key}_"
        for name, val in self.defines.items():
            if not (name.startswith(pre) and name.endswith("_Pos")):
                continue
            fname = name[len(pre) : -4]
            if not fname or "_" in fname and fname.split("_")[0].isdigit():
                continue
            try:
                pos = _int(val.split()[0])
            except ValueError:
                continue
            width = 1
            msk = self.defines.get(f"{pre}{fname}_Msk")
            if msk:
                # "(0x3ul << X_Pos)", or CMSIS's "(0x1FFUL /*<< X_Pos*/)" for a field at bit 0 (the comment is cut)
                mm = re.match(r"\(?\s*(?:_U_\()?(0x[0-9A-Fa-f]+|\d+)[uUlL]*\)?\s*(<<)?", msk)
                if mm:
                    value = _int(mm.group(1))
                    width = (value if mm.group(2) else value >> pos).bit_length()
            out.append(Field(fname, pos, width))
        return tuple(sorted(out, key=lambda f: (f.pos, f.name)))

    def flatten(self, struct: str, base: int, prefix: str, view: str, periph: str, sink: list[Register]) -> None:
        what, members = self.structs[struct]
        for m in members:
            if m.kind == "reserved":
                continue
            assert m.offset is not None
            if m.kind == "group":
                if what == "union":  # a mode view: its registers belong to that view only
                    self.flatten(m.key, base + m.offset, f"{prefix}{m.name}.", m.name, periph, sink)
                    continue
                stride = self.sizeof(m.key)
                for i in range(m.count):
                    idx = f"[{i}]" if m.is_array else ""
                    self.flatten(m.key, base + m.offset + i * stride, f"{prefix}{m.name}{idx}.", view, periph, sink)
                continue
            for i in range(m.count):
                idx = f"[{i}]" if m.is_array else ""
                sink.append(
                    Register(
                        periph,
                        view,
                        f"{prefix}{m.name}{idx}",
                        base + m.offset + i * m.size,
                        m.size,
                        m.access,
                        self.reset(m.key),
                        m.key,
                        self.fields(m.key),
                    )
                )


_INSTANCE = re.compile(r"^#define\s+(\w+)\s+\(\(\s*(\w+)\s*\*\)\s*(0x[0-9A-Fa-f]+)UL\)", re.M)
_IRQ = re.compile(r"^\s*(\w+)_IRQn\s*=\s*(-?\d+)", re.M)
_ID = re.compile(r"^#define\s+ID_(\w+)\s+(\d+)\b", re.M)
# core_cm0plus.h: <NAME>_BASE in the system control space
_SCS = {"SysTick": ("SysTick_Type", 0xE000E010), "NVIC": ("NVIC_Type", 0xE000E100), "SCB": ("SCB_Type", 0xE000ED00)}


_PINMUX = re.compile(r"^#define\s+PIN_P([AB])(\d\d)([A-H])_([A-Z0-9]+)_(\w+)\s+(\d+)L", re.M)


@dataclass(frozen=True)
class PinFunction:
    pin: int  # 0..31 PA, 32..63 PB
    func: int  # PMUX letter A..H = 0..7
    periph: str  # "TCC0"
    signal: str  # "WO2"

    @property
    def name(self) -> str:
        return f"P{'AB'[self.pin // 32]}{self.pin % 32:02d}{'ABCDEFGH'[self.func]}"


def _pinmux(atmel: Path) -> list[PinFunction]:
    text = (atmel / "pio" / DEVICE_HEADER).read_text(errors="replace")
    out = []
    for m in _PINMUX.finditer(text):
        pin = (0 if m.group(1) == "A" else 32) + int(m.group(2))
        if int(m.group(6)) != pin:
            raise RegTableError(f"pio header: PIN_P{m.group(1)}{m.group(2)}... is {m.group(6)}, expected {pin}")
        out.append(PinFunction(pin, "ABCDEFGH".index(m.group(3)), m.group(4), m.group(5)))
    if not out:
        raise RegTableError(f"{atmel / 'pio' / DEVICE_HEADER}: no PIN_Pxnn<F>_ definitions")
    return out


@lru_cache(maxsize=4)
def load(pio_tree: str | None = None) -> Table:
    """The register table of the SAMD21G18A, from the headers in a PlatformIO tree (find_include_dirs)."""
    atmel, core = find_include_dirs(pio_tree)
    h = _Headers(atmel, core)
    dev = (atmel / DEVICE_HEADER).read_text(errors="replace")
    irqs = {m.group(1): int(m.group(2)) for m in _IRQ.finditer(dev)}
    ids = {m.group(1): int(m.group(2)) for m in _ID.finditer(dev)}
    periphs: list[Peripheral] = []
    for m in _INSTANCE.finditer(dev):
        name, struct, base = m.group(1), m.group(2), int(m.group(3), 16)
        if struct not in h.structs:
            raise RegTableError(f"{DEVICE_HEADER}: instance {name} of unknown type {struct}")
        what, members = h.structs[struct]
        views = tuple(mm.name for mm in members if mm.kind == "group") if what == "union" else ()
        p = Peripheral(name, struct, base, h.sizeof(struct), irqs.get(name), views, pac=ids.get(name))
        h.flatten(struct, 0, "", "", name, p.registers)
        periphs.append(p)
    for name, (struct, base) in _SCS.items():
        p = Peripheral(name, struct, base, h.sizeof(struct), None)
        h.flatten(struct, 0, "", "", name, p.registers)
        periphs.append(p)
    if not any(p.name == "TC3" for p in periphs) or not any(p.name == "PORT_IOBUS" for p in periphs):
        raise RegTableError(f"{atmel / DEVICE_HEADER}: instances TC3 / PORT_IOBUS not found")
    for p in periphs:
        if not p.registers:
            raise RegTableError(f"{p.name} ({p.struct}): no registers parsed")
    table = Table(periphs, str(atmel), _pinmux(atmel))
    check(table)
    return table


def check(table: Table) -> None:
    """RegTableError (one line naming the value and where it came from) unless every value of the table fits the
    chip and the runtime's C: interrupt lines 0..31 and each used once, instance windows inside a peripheral region
    and apart, each APB instance's PAC bit on its own bridge and used once, registers 1, 2 or 4 bytes wide, aligned
    and inside their instance's window, resets and fields inside their width, views, pins and pin functions that
    exist, and counts the C's index types hold."""
    src = table.source

    def bad(what: str) -> RegTableError:
        return RegTableError(f"register table from {src}: {what}")

    if not 1 <= len(table.peripherals) <= MAX_PERIPHERALS:
        raise bad(f"{len(table.peripherals)} instances (1..{MAX_PERIPHERALS})")
    irqs: dict[int, str] = {}
    pacs: dict[int, str] = {}
    windows: list[tuple[int, int, str]] = []
    nregs = nfields = 0
    for p in table.peripherals:
        if p.irq is not None:
            if not 0 <= p.irq < NVIC_LINES:
                raise bad(f"{p.name}_IRQn = {p.irq}: the NVIC has lines 0..{NVIC_LINES - 1}")
            if p.irq in irqs:
                raise bad(f"{p.name}_IRQn = {p.irq}: the line of {irqs[p.irq]} already")
            irqs[p.irq] = p.name
        if len(p.views) > MAX_VIEWS:
            raise bad(f"{p.name}: {len(p.views)} mode views (at most {MAX_VIEWS})")
        if not any(b <= p.base and 0 < p.size <= b + n - p.base for b, n in PERIPHERAL_REGIONS):
            raise bad(f"{p.name} at 0x{p.base:x} (+0x{p.size:x}): outside the chip's peripheral regions")
        windows.append((p.base, p.size, p.name))
        _check_pac(p, pacs, bad)
        for r in p.registers:
            where = f"{r.full} at offset 0x{r.offset:x}"
            if r.size not in (1, 2, 4):
                raise bad(f"{where}: {r.size} bytes wide (1, 2 or 4)")
            if r.offset < 0 or r.offset % r.size or r.size > p.size - r.offset:
                raise bad(f"{where}: outside {p.name}'s 0x{p.size:x}-byte window or not aligned to its width")
            if r.access not in ACCESS_CODE or (r.view and r.view not in p.views):
                raise bad(f"{where}: access {r.access!r}, view {r.view!r} unknown")
            if not 0 <= r.reset < 1 << (8 * r.size):
                raise bad(f"{where}: reset value 0x{r.reset:x} wider than the register")
            if len(r.fields) > 255:
                raise bad(f"{where}: {len(r.fields)} fields")
            for f in r.fields:
                if f.pos < 0 or f.width < 1 or f.width > 8 * r.size - f.pos:
                    raise bad(f"{where}: field {f.name} at bit {f.pos}, {f.width} wide, outside its {8 * r.size} bits")
        nregs += len(p.registers)
        nfields += sum(len(r.fields) for r in p.registers)
    windows.sort()
    for (a, n, x), (b, _, y) in zip(windows, windows[1:]):
        if b < a + n:
            raise bad(f"the windows of {x} (0x{a:x} +0x{n:x}) and {y} (0x{b:x}) overlap")
    if nregs > MAX_REGISTERS or nfields > MAX_FIELDS:
        raise bad(f"{nregs} registers, {nfields} fields (at most {MAX_REGISTERS}, {MAX_FIELDS})")
    for pf in table.pinmux:
        if not (0 <= pf.pin < 64 and 0 <= pf.func < 8):
            raise bad(f"pin function {pf.periph}/{pf.signal}: pin {pf.pin} (0..63), function {pf.func} (0..7)")


def _check_pac(p: Peripheral, pacs: dict[int, str], bad) -> None:
    """An instance on an APB bridge has its bit in that bridge's PAC, once; bit 0 is the PAC itself (its own
    registers are never write-protected: the WP field is bits 31:1, PAC_WPSET_WP_Pos)."""
    bridge = next((k for k, b in enumerate(APB_BRIDGES) if b <= p.base < b + APB_BRIDGE_SPAN), None)
    if p.pac is None:
        if bridge is not None:
            raise bad(f"{p.name} at 0x{p.base:x}: on APB bridge {'ABC'[bridge]} but no ID_{p.name} (its PAC bit)")
        return
    if bridge is None or p.pac // 32 != bridge or p.base + p.size > APB_BRIDGES[bridge] + APB_BRIDGE_SPAN:
        raise bad(f"ID_{p.name} = {p.pac}: {p.name} at 0x{p.base:x} is not on APB bridge {p.pac // 32} (its PAC's)")
    if (p.pac % 32 == 0) != (p.struct == "Pac") or (p.struct == "Pac" and p.base != APB_BRIDGES[bridge]):
        raise bad(f"ID_{p.name} = {p.pac}: bit 0 of a bridge is its PAC, at the bridge's base, and only it")
    if p.pac in pacs:
        raise bad(f"ID_{p.name} = {p.pac}: the PAC bit of {pacs[p.pac]} already")
    pacs[p.pac] = p.name


# ---------------------------------------------------------------- C output

KIND_CODE = {"plain": 0, "w1c": 1, "set": 2, "clr": 3, "tgl": 4}
ACCESS_CODE = {"RW": 3, "R": 1, "W": 2}


def emit_c(table: Table) -> str:
    """C source of the table (sam_regtab.h declares the types): sam_periphs[], sam_regs[], sam_fields[].

    Registers are ordered by peripheral, then view, then offset; sam_regs[i].alias is the index of the register
    an alias (set/clr/tgl) acts on (itself when it holds the hidden value, as INTENSET does for INTENCLR). The table
    is checked first (check): nothing the runtime's C cannot hold is emitted."""
    check(table)
    lines = [
        "/* Generated by host_emulator.image.regtable from the vendor's device headers; do not edit. */",
        '#include "sam_regtab.h"',
        "",
    ]
    regs: list[Register] = []
    preg: list[tuple[int, int]] = []
    for p in table.peripherals:
        first = len(regs)
        views = ("",) + p.views
        for r in sorted(p.registers, key=lambda r: (views.index(r.view), r.offset)):
            regs.append(r)
        preg.append((first, len(regs)))
    index = {(r.periph, r.view, r.name): i for i, r in enumerate(regs)}

    def alias_of(i: int, r: Register) -> int:
        k = r.kind
        if k not in ("set", "clr", "tgl"):
            return i
        stem = r.name[:-3]
        for v in (r.view, ""):
            if (r.periph, v, stem) in index:  # OUTSET -> OUT, EPSTATUSSET -> EPSTATUS
                return index[(r.periph, v, stem)]
        for v in (r.view, ""):
            if (r.periph, v, stem + "SET") in index:  # INTENCLR -> INTENSET holds the mask
                return index[(r.periph, v, stem + "SET")]
        return i

    fields: list[tuple[int, Field]] = []
    lines.append(f"const sam_reg_t sam_regs[{len(regs)}] = {{")
    for i, r in enumerate(regs):
        f0 = len(fields)
        fields += [(i, f) for f in r.fields]
        pi = next(k for k, p in enumerate(table.peripherals) if p.name == r.periph)
        vi = (("",) + table.peripherals[pi].views).index(r.view)
        lines.append(
            f'    {{"{r.periph}.{r.name}", 0x{r.offset:03x}u, 0x{r.reset:x}u, {pi}, {vi}, {r.size}, '
            f"{ACCESS_CODE[r.access]}, {KIND_CODE[r.kind]}, {alias_of(i, r)}, {f0}, {len(r.fields)}}},"
        )
    lines.append("};")
    lines.append(f"const unsigned sam_nregs = {len(regs)};")
    lines.append(f"const sam_field_t sam_fields[{max(1, len(fields))}] = {{")
    for i, f in fields:
        lines.append(f'    {{"{f.name}", {i}, {f.pos}, {f.width}}},')
    if not fields:
        lines.append('    {"", 0, 0, 0},')
    lines.append("};")
    lines.append(f"const unsigned sam_nfields = {len(fields)};")
    lines.append(f"const sam_periph_t sam_periphs[{len(table.peripherals)}] = {{")
    for (first, last), p in zip(preg, table.peripherals):
        irq = -1 if p.irq is None else p.irq
        pac = -1 if p.pac is None else p.pac
        view_names = "|".join(p.views)
        lines.append(
            f'    {{"{p.name}", "{p.struct}", "{view_names}", 0x{p.base:08x}u, 0x{p.size:x}u, {irq}, {len(p.views)}, '
            f"{first}, {last}, {pac}}},"
        )
    lines.append("};")
    lines.append(f"const unsigned sam_nperiphs = {len(table.peripherals)};")
    lines.append(f"const sam_pinmux_t sam_pinmux[{len(table.pinmux)}] = {{")
    for pf in table.pinmux:
        lines.append(f'    {{{pf.pin}, {pf.func}, "{pf.periph}", "{pf.signal}"}},')
    lines.append("};")
    lines.append(f"const unsigned sam_npinmux = {len(table.pinmux)};")
    return "\n".join(lines) + "\n"


def emit_vendor_h(table: Table) -> str:
    """A host-compilable header of the vendor's component and instance definitions (register struct layouts,
    field masks, GCLK ids): the device header's own register typedefs, then every component/ and instance/ header.
    (samd21g18a.h itself pulls in core_cm0plus.h, whose inline functions assume 32-bit pointers.)"""
    if table.vendor_macros is not None:  # a snapshot: the macros the runtime uses, as the headers define them
        return (
            "\n".join(
                [
                    "/* Generated by host_emulator.image.regtable from its snapshot of the vendor's headers. */",
                    "#ifndef SAM_VENDOR_GEN_H",
                    "#define SAM_VENDOR_GEN_H",
                    *(f"#define {body}" for body in table.vendor_macros),
                    "#endif",
                ]
            )
            + "\n"
        )
    atmel = Path(table.source)
    dev = (atmel / DEVICE_HEADER).read_text(errors="replace")
    typedefs: list[tuple[str, str, str]] = []
    for line in dev.splitlines():
        m = re.match(r"^typedef volatile\s+(const\s+)?uint(8|16|32)_t\s+(\w+);", line)
        if m and m.group(3) not in {t[2] for t in typedefs}:
            typedefs.append((m.group(1) or "", m.group(2), m.group(3)))
    if len(typedefs) < 9:
        raise RegTableError(f"{atmel / DEVICE_HEADER}: register typedefs (RoReg, RwReg, ...) not found")
    out = [
        "/* Generated by host_emulator.image.regtable from the vendor's headers; do not edit. */",
        "#ifndef SAM_VENDOR_GEN_H",
        "#define SAM_VENDOR_GEN_H",
        "#include <stdint.h>",
    ]
    out += [f"typedef volatile {c}uint{w}_t {n};" for c, w, n in typedefs]
    out += ["#define __I volatile const", "#define __O volatile", "#define __IO volatile"]
    for sub in ("component", "instance"):
        out += [f'#include "{sub}/{p.name}"' for p in sorted((atmel / sub).glob("*.h"))]
    out.append("#endif")
    return "\n".join(out) + "\n"
