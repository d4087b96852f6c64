"""The generated SAMD21 register table (host_emulator.image.regtable) against independent references: the vendor's
instance defines, the ARM compiler's own layout of the vendor structs, the headers' descriptions and the datasheet."""

from __future__ import annotations

import itertools
import re
import shutil
import subprocess
from collections import defaultdict
from pathlib import Path

import pytest

from host_emulator.image import board, regtable
from tests.host_emulator.image import vendor

ROOT = Path(__file__).resolve().parents[3]
ARM_CC = "arm-none-eabi-gcc"
needs_arm_cc = pytest.mark.skipif(shutil.which(ARM_CC) is None, reason=f"{ARM_CC} missing (tools/setup.sh installs it)")


@pytest.fixture(scope="module")
def table() -> regtable.Table:
    vendor.include_dirs()  # skips with one line when the headers are absent
    return regtable.load()


def by_name(table: regtable.Table) -> dict[str, regtable.Register]:
    return {r.full: r for r in table.registers()}


# ---------------------------------------------------------------- addresses: the vendor's instance defines

# `#define REG_TC3_COUNT16_CC0 (*(RwReg16*)0x42002C18U)`: the C branch of every instance header
_INSTANCE_DEFINE = re.compile(
    r"^#define\s+REG_(\w+)\s+\(\*\(\s*(R[wo]Reg|WoReg)(8|16|)\s*\*\)\s*(0x[0-9A-Fa-f]+)U?\)", re.M
)
_TYPE_ACCESS = {"RwReg": "RW", "RoReg": "R", "WoReg": "W"}


def instance_defines(atmel: Path) -> dict[str, tuple[int, int, str]]:
    """REG_<INSTANCE>_<REG> -> (address, bytes, access), from instance/*.h."""
    out = {}
    for h in sorted((atmel / "instance").glob("*.h")):
        for m in _INSTANCE_DEFINE.finditer(h.read_text(errors="replace")):
            size = int(m.group(3) or 32) // 8
            out[m.group(1)] = (int(m.group(4), 16), size, _TYPE_ACCESS[m.group(2)])
    return out


def _camel_last(group: str) -> str:
    """ "DeviceEndpoint" -> "ENDPOINT", "Mode2Alarm" -> "ALARM": the word the vendor keeps in a group's define."""
    return re.findall(r"[A-Z][a-z0-9]*", group)[-1].upper()


def vendor_names(periph: str, r: regtable.Register) -> set[str]:
    """The names the vendor's instance headers may give this register: <INSTANCE>_[<VIEW>_][<GROUP>_]<REG><n>, where
    n is the first index of the path (the group's or the register's) and only element 0 of inner arrays is named."""
    parts = r.name.split(".")
    if r.view:
        assert parts[0] == r.view, r.full
        parts = parts[1:]
    idx = [int(i) for i in re.findall(r"\[(\d+)\]", ".".join(parts))]
    if any(i != 0 for i in idx[1:]):
        return set()
    suffix = str(idx[0]) if idx else ""
    groups = [re.sub(r"\[\d+\]$", "", g) for g in parts[:-1]]
    leaf = re.sub(r"\[\d+\]$", "", parts[-1]) + suffix
    names = set()
    for view in {r.view, ""}:
        for gtoks in itertools.product(*[("", _camel_last(g)) for g in groups]):
            names.add("_".join(t for t in (periph, view, *gtoks, leaf) if t))
    return names


def test_every_register_address_width_and_access_matches_the_vendors_instance_defines(table):
    atmel, _ = vendor.include_dirs()
    defines = instance_defines(atmel)
    instances = {p.name for p in table.peripherals}
    claims: dict[str, list[tuple[regtable.Peripheral, regtable.Register]]] = defaultdict(list)
    for p in table.peripherals:
        for r in p.registers:
            for n in vendor_names(p.name, r):
                claims[n].append((p, r))
    compared, unmatched, wrong = 0, [], []
    ours = 0
    for name, (addr, size, access) in sorted(defines.items()):
        inst = max((i for i in instances if name.startswith(i + "_")), key=len, default=None)
        if inst is None:
            continue  # TC6, TC7: instance headers of bigger parts, no such instance on the SAMD21G18A
        ours += 1
        if name not in claims:
            unmatched.append(name)
            continue
        compared += 1
        for p, r in claims[name]:
            got = (p.base + r.offset, r.size, r.access)
            if "[" in r.name:
                # the vendor types the first element of an array (PMUX0, PINCFG0, MODE2_ALARM_MASK0) as a 32-bit
                # RwReg whatever the element's width: only the address and access say something there
                size = r.size
            if got != (addr, size, access):
                wrong.append(
                    f"REG_{name} = 0x{addr:08X} ({size} B, {access}); table {r.full} = 0x{got[0]:08X} "
                    f"({got[1]} B, {got[2]})"
                )
    assert not wrong, "\n".join(wrong)
    print(f"{compared} of {ours} instance defines compared with the table ({len(unmatched)} not named: {unmatched})")
    assert ours > 800 and compared >= 0.98 * ours, (
        f"only {compared} of {ours} defines matched a register, e.g. {unmatched[:20]}"
    )


def test_each_apb_instances_pac_bit_is_its_peripheral_id(table):
    """DS40001882 11.6 (PAC): bit n of PACk's WPSET/WPCLR protects the peripheral whose ID_<name> (samd21g18a.h) is
    32 k + n; bit 0 of each bridge is its PAC. On bridge B the bit is not the peripheral's 1 KiB slot (the DSU
    spans 8 slots): PORT at 0x41004400 is bit 3."""
    atmel, _ = vendor.include_dirs()
    text = (atmel / regtable.DEVICE_HEADER).read_text(errors="replace")
    ids = {m.group(1): int(m.group(2)) for m in re.finditer(r"#define ID_([A-Z0-9_]+)\s+(\d+)", text)}
    apb = [p for p in table.peripherals if 0x40000000 <= p.base < 0x43000000]
    assert len(apb) > 30
    for p in apb:
        assert p.pac == ids[p.name], p.name
        assert (p.pac % 32 == 0) == (p.struct == "Pac") and p.pac // 32 == (p.base >> 24) - 0x40, p.name
    assert [p.pac for p in table.peripherals if p.base >= 0x60000000] == [None] * 4  # IOBUS, SysTick, NVIC, SCB
    assert table.periph("PORT").pac == 32 + 3 and (table.periph("PORT").base - 0x41000000) >> 10 == 17


def test_the_iobus_alias_of_port_has_ports_registers(table):
    port, iobus = table.periph("PORT"), table.periph("PORT_IOBUS")
    assert iobus.base == 0x6000_0000  # the Cortex-M0+ single-cycle I/O port (SAMD21 datasheet, "IOBUS")
    assert [(r.name, r.offset, r.size, r.kind) for r in port.registers] == [
        (r.name, r.offset, r.size, r.kind) for r in iobus.registers
    ]


# ---------------------------------------------------------------- layout: the ARM compiler


def _c_member_type(p: regtable.Peripheral, r: regtable.Register) -> str:
    if p.struct.endswith("_Type"):  # CMSIS core: plain uintN_t members
        return f"uint{8 * r.size}_t"
    return f"{r.key}_Type"


def layout_asserts(table: regtable.Table, *, core: bool, resets: bool = True) -> tuple[str, int]:
    """C11 static assertions of every register's offset, size, const-ness (read-only), reset value and field masks,
    one struct at a time (instances of one struct share its layout); (source, number of registers)."""
    lines, seen = [], set()
    for p in table.peripherals:
        if p.struct.endswith("_Type") and not core:
            continue
        if core:  # the ARM build: the instance macros are the vendor's base addresses, <NAME>_IRQn its lines
            lines.append(f'_Static_assert((uintptr_t){p.name} == 0x{p.base:08x}u, "{p.name}: base 0x{p.base:08x}");')
            if p.irq is not None:
                lines.append(f'_Static_assert({p.name}_IRQn == {p.irq}, "{p.name}: interrupt line {p.irq}");')
        first = p.struct not in {s for s, _ in seen}
        if first:
            lines.append(
                f"_Static_assert(sizeof({p.struct}) >= 0x{p.size:x} && sizeof({p.struct}) < 0x{p.size:x} + 4, "
                f'"{p.struct}: register window 0x{p.size:x}");'
            )
        for r in p.registers:
            if (p.struct, r.name) in seen:
                continue
            seen.add((p.struct, r.name))
            what = f"{p.name}.{r.name}"
            m = f"(({p.struct} *)0)->{r.name}"
            lines.append(f'_Static_assert(offsetof({p.struct}, {r.name}) == 0x{r.offset:x}u, "{what}: offset");')
            lines.append(f'_Static_assert(sizeof({m}) == {r.size}u, "{what}: size");')
            ro = int(r.access == "R")
            lines.append(
                f"_Static_assert(_Generic(&{m}, const volatile {_c_member_type(p, r)} *: 1, default: 0) == {ro}, "
                f'"{what}: read-only is {ro}");'
            )
            if resets:
                lines += [
                    f"#ifdef {r.key}_RESETVALUE",
                    f'_Static_assert(({r.key}_RESETVALUE) == 0x{r.reset:x}u, "{what}: reset 0x{r.reset:x}");',
                    "#else",
                    f'_Static_assert(0x{r.reset:x}u == 0u, "{what}: no reset value in the header");',
                    "#endif",
                ]
            for f in r.fields:
                lines.append(
                    f'_Static_assert(({r.key}_{f.name}_Pos) == {f.pos}u, "{what}.{f.name}: position {f.pos}");'
                )
                lines.append(f"#ifdef {r.key}_{f.name}_Msk")
                lines.append(
                    f'_Static_assert(({r.key}_{f.name}_Msk) == 0x{f.mask:x}u, "{what}.{f.name}: mask 0x{f.mask:x}");'
                )
                lines.append("#endif")
    return "\n".join(lines) + "\n", len(seen)


def _compile(cmd: list[str], src: str, tmp_path: Path) -> subprocess.CompletedProcess:
    c = tmp_path / "layout.c"
    c.write_text(src)
    return subprocess.run([*cmd, str(c)], capture_output=True, text=True)


def _failures(stderr: str) -> list[str]:
    return sorted(set(re.findall(r'static assertion failed: "([^"]+)"', stderr))) or [stderr[-3000:]]


@needs_arm_cc
def test_offsets_sizes_resets_and_fields_match_the_arm_compilers_layout_of_the_vendor_structs(table, tmp_path):
    atmel, core = vendor.include_dirs()
    body, n = layout_asserts(table, core=True)
    src = '#include <stddef.h>\n#include <stdint.h>\n#include "samd21.h"\n' + body
    cmd = [
        ARM_CC,
        "-fsyntax-only",
        "-std=c11",
        "-mcpu=cortex-m0plus",
        "-mthumb",
        "-D__SAMD21G18A__",
        f"-I{atmel}",
        f"-I{core}",
        "-x",
        "c",
    ]
    res = _compile(cmd, src, tmp_path)
    assert res.returncode == 0, "the ARM compiler disagrees with the table:\n" + "\n".join(_failures(res.stderr))
    # the representative peripherals are all in (and each struct's registers are checked once)
    structs = {p.struct for p in table.peripherals}
    assert {
        "Port",
        "Eic",
        "Tc",
        "Tcc",
        "Sercom",
        "Usb",
        "Gclk",
        "Pm",
        "Sysctrl",
        "Wdt",
        "Nvmctrl",
        "NVIC_Type",
        "SCB_Type",
        "SysTick_Type",
    } <= structs
    assert n > 650, n


def test_the_host_view_of_the_vendor_headers_has_the_same_layout(table, tmp_path):
    """emit_vendor_h is what the runtime's C models are compiled against (on a 64-bit host): same offsets."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no host C compiler")
    atmel, _ = vendor.include_dirs()
    (tmp_path / "sam_vendor_gen.h").write_text(regtable.emit_vendor_h(table))
    body, n = layout_asserts(table, core=False, resets=False)  # (the part's own reset values are not in it)
    src = '#include <stddef.h>\n#include "sam_vendor_gen.h"\n' + body
    res = _compile([cc, "-fsyntax-only", "-std=c11", f"-I{tmp_path}", f"-isystem{atmel}", "-x", "c"], src, tmp_path)
    assert res.returncode == 0, "the host view disagrees with the table:\n" + "\n".join(_failures(res.stderr))
    assert n > 600, n


def test_the_emitted_c_table_compiles_pedantically_and_lists_every_register(table, tmp_path):
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no host C compiler")
    gen = tmp_path / "sam_regtab_gen.c"
    gen.write_text(regtable.emit_c(table))
    csrc = ROOT / "host_emulator" / "image" / "csrc"
    res = subprocess.run(
        [cc, "-fsyntax-only", "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", f"-I{csrc}", str(gen)],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    assert sorted(n for n, _, _ in _emitted_rows(table)) == sorted(r.full for r in table.registers())


# ---------------------------------------------------------------- access kinds

# a member line of a component struct: its register key and the vendor's description
_MEMBER = re.compile(
    r"^\s*__(?:IO|I|O)\s+(\w+)_Type\s+\w+(?:\[\w+\])?;"
    r"\s*/\*\*<\s*\\brief Offset:\s*0x[0-9A-Fa-f]+\s*\([^)]*\)\s*(.*?)\s*\*/",
    re.M,
)


def descriptions(atmel: Path) -> dict[str, str]:
    out = {}
    for h in sorted((atmel / "component").glob("*.h")):
        for m in _MEMBER.finditer(h.read_text(errors="replace")):
            out[m.group(1)] = m.group(2)
    return out


def kind_from_description(desc: str) -> str:
    """The access kind the vendor's description of a register states. The datasheet adds the USB controller's flag
    registers ("Device Interrupt Flag", "End Point Interrupt Flag", ...: writing a one clears the flag)."""
    if "Flag Status and Clear" in desc or desc.endswith("Interrupt Flag"):
        return "w1c"
    for word, kind in (("Toggle", "tgl"), ("Clear", "clr"), ("Set", "set")):
        if re.search(rf"\b{word}\b", desc):
            return kind
    return "plain"


def test_access_kinds_agree_with_the_vendors_descriptions(table):
    atmel, _ = vendor.include_dirs()
    desc = descriptions(atmel)
    wrong, checked = [], 0
    for r in table.registers():
        if r.key not in desc:
            continue  # the system control space (core_cm0plus.h): the core's NVIC/SCB/SysTick models own it
        want = kind_from_description(desc[r.key])
        if r.key == "WDT_CLEAR":
            # described as "Clear", but it is the watchdog's key register (0xA5 restarts the count, any other value
            # resets the chip), modelled by the WDT model, not an alias
            want = "plain"
        checked += 1
        if r.kind != want:
            wrong.append(f"{r.full} ({desc[r.key]!r}): kind {r.kind}, the description says {want}")
    assert not wrong, "\n".join(wrong)
    assert checked > 1000


@pytest.mark.parametrize(
    "reg",
    [
        "TC3.COUNT16.INTFLAG",
        "TC3.COUNT8.INTFLAG",
        "TCC0.INTFLAG",
        "EIC.INTFLAG",
        "SERCOM2.I2CS.INTFLAG",
        "SERCOM2.I2CM.INTFLAG",
        "USB.DEVICE.INTFLAG",
        "USB.DEVICE.DeviceEndpoint[3].EPINTFLAG",
        "SYSCTRL.INTFLAG",
        "PM.INTFLAG",
        "NVMCTRL.INTFLAG",
        "WDT.INTFLAG",
        "EIC.NMIFLAG",
        "DMAC.CHINTFLAG",
    ],
)
def test_interrupt_flag_registers_are_write_one_to_clear(table, reg):
    assert by_name(table)[reg].kind == "w1c"


def _emitted_rows(table: regtable.Table) -> list[tuple[str, int, int]]:
    """(name, kind code, alias index) of every row of emit_c's sam_regs[]."""
    rows = re.findall(
        r'^\s*\{"([^"]+)", 0x[0-9a-f]+u, 0x[0-9a-f]+u, \d+, \d+, \d+, \d+, (\d+), (\d+), \d+, \d+\},$',
        regtable.emit_c(table),
        re.M,
    )
    return [(n, int(k), int(a)) for n, k, a in rows]


@pytest.mark.parametrize("port", ["PORT", "PORT_IOBUS"])
@pytest.mark.parametrize("group", [0, 1])
@pytest.mark.parametrize("reg", ["OUT", "DIR"])
def test_port_set_clear_toggle_aliases_act_on_their_own_groups_register(table, port, group, reg):
    rows = _emitted_rows(table)
    at = {n: i for i, (n, _, _) in enumerate(rows)}
    base = f"{port}.Group[{group}].{reg}"
    assert rows[at[base]][1:] == (regtable.KIND_CODE["plain"], at[base])
    for suffix, kind in (("SET", "set"), ("CLR", "clr"), ("TGL", "tgl")):
        name, code, alias = rows[at[base + suffix]]
        assert (code, rows[alias][0]) == (regtable.KIND_CODE[kind], base), name


@pytest.mark.parametrize(
    "stem",
    [
        "TC3.COUNT16.INTEN",
        "TCC0.INTEN",
        "EIC.INTEN",
        "SERCOM2.I2CS.INTEN",
        "SERCOM2.I2CM.INTEN",
        "USB.DEVICE.INTEN",
        "USB.DEVICE.DeviceEndpoint[5].EPINTEN",
        "TC3.COUNT16.CTRLB",
        "TCC0.CTRLB",
    ],
)
def test_enable_set_and_clear_share_one_hidden_mask_held_by_the_set_register(table, stem):
    rows = _emitted_rows(table)
    at = {n: i for i, (n, _, _) in enumerate(rows)}
    s, c = at[stem + "SET"], at[stem + "CLR"]
    assert rows[s][1:] == (regtable.KIND_CODE["set"], s)
    assert rows[c][1:] == (regtable.KIND_CODE["clr"], s)


def test_endpoint_status_set_and_clear_act_on_the_status_of_their_endpoint(table):
    rows = _emitted_rows(table)
    at = {n: i for i, (n, _, _) in enumerate(rows)}
    for ep in range(8):
        st = f"USB.DEVICE.DeviceEndpoint[{ep}].EPSTATUS"
        assert rows[rows[at[st + "SET"]][2]][0] == st
        assert rows[rows[at[st + "CLR"]][2]][0] == st


def test_every_alias_has_a_register_to_act_on(table):
    """No ...SET/CLR/TGL register that acts on nothing (a name that merely ends in those letters)."""
    rows = _emitted_rows(table)
    alone = [n for i, (n, k, a) in enumerate(rows) if k in (2, 3, 4) and a == i and not n.endswith("SET")]
    assert not alone, alone


@pytest.mark.parametrize(
    "reg",
    [
        "TC3.COUNT16.CTRLA",
        "TCC0.CTRLA",
        "SERCOM2.I2CS.CTRLA",
        "SERCOM2.I2CM.CTRLA",
        "USB.DEVICE.CTRLA",
        "EIC.CTRL",
        "GCLK.CTRL",
        "NVMCTRL.CTRLB",
    ],
)
def test_software_reset_bits_are_found_by_field_name(table, reg):
    """SWRST is bit 0 of each peripheral's control register (datasheet), the bit the models clear by themselves; the
    NVM controller has no SWRST (its CTRLB must not offer one)."""
    f = by_name(table)[reg].field("SWRST")
    if reg == "NVMCTRL.CTRLB":
        assert f is None
    else:
        assert f is not None and (f.pos, f.width) == (0, 1), f


@pytest.mark.parametrize(
    "reg", ["TCC0.SYNCBUSY", "SERCOM2.I2CS.SYNCBUSY", "SERCOM2.I2CM.SYNCBUSY", "USB.DEVICE.SYNCBUSY", "I2S.SYNCBUSY"]
)
def test_syncbusy_registers_are_read_only(table, reg):
    r = by_name(table)[reg]
    assert r.access == "R" and r.field("ENABLE") is not None


@pytest.mark.parametrize("reg", ["TC3.COUNT16.STATUS", "GCLK.STATUS", "WDT.STATUS", "EIC.STATUS"])
def test_status_syncbusy_is_bit_7_of_a_read_only_status(table, reg):
    r = by_name(table)[reg]
    assert r.access == "R"
    assert r.field("SYNCBUSY") == regtable.Field("SYNCBUSY", 7, 1)


# the datasheet's reset values (SAMD21 family datasheet, register summaries)
DATASHEET_RESET = {
    "WDT.CONFIG": 0xBB,
    "WDT.EWCTRL": 0x0B,
    "PM.RCAUSE": 0x01,
    "PM.AHBMASK": 0x7F,
    "PM.APBAMASK": 0x7F,
    "PM.APBBMASK": 0x7F,
    "PM.APBCMASK": 0x0001_0000,
    "TCC0.PER": 0xFFFF_FFFF,
    "TCC0.STATUS": 0x01,
    "TC3.COUNT8.PER": 0xFF,
    "TC3.COUNT16.STATUS": 0x08,
    "SYSCTRL.DFLLCTRL": 0x0080,
    "USB.DEVICE.QOSCTRL": 0x05,
    "DMAC.QOSCTRL": 0x15,
    "TC3.COUNT16.CTRLA": 0x0000,
}


@pytest.mark.parametrize("reg,value", sorted(DATASHEET_RESET.items()))
def test_reset_values_are_the_datasheets(table, reg, value):
    assert by_name(table)[reg].reset == value


# ---------------------------------------------------------------- pin multiplexing

_PIO = re.compile(r"^#define\s+PIN_P([AB])(\d\d)([A-H])_(\w+?)_(\w+)\s+\d+L", re.M)


def test_the_pinmux_table_is_the_pio_headers(table):
    atmel, _ = vendor.include_dirs()
    text = (atmel / "pio" / regtable.DEVICE_HEADER).read_text(errors="replace")
    want = {(f"P{m.group(1)}{m.group(2)}", m.group(3), m.group(4), m.group(5)) for m in _PIO.finditer(text)}
    got = {(f.name[:4], f.name[4], f.periph, f.signal) for f in table.pinmux}
    assert got == want and len(want) > 150


def functions(table: regtable.Table, pin: str) -> dict[str, tuple[str, str]]:
    """PMUX letter -> (peripheral, signal) of a pin."""
    n = board.pin_number(pin)
    return {"ABCDEFGH"[f.func]: (f.periph, f.signal) for f in table.pinmux if f.pin == n}


def test_the_bus_pins_are_sercom2_pads_0_and_1_under_the_function_the_core_selects(table):
    """PA08/PA09 are SERCOM0 under C and SERCOM2 under D; the XIAO variant gives them PIO_SERCOM_ALT, which the core's
    pinPeripheral() writes to PMUX as that enum's value: it must be the letter whose function is SERCOM2."""
    for pin, pad in ((board.CELL_WIRING["sda"], "PAD0"), (board.CELL_WIRING["scl"], "PAD1")):
        f = functions(table, pin)
        assert f["C"] == ("SERCOM0", pad) and f["D"] == ("SERCOM2", pad), (pin, f)
        arduino = vendor.variant_define("PIN_WIRE_SDA" if pad == "PAD0" else "PIN_WIRE_SCL")
        vp = vendor.variant_pins()[arduino]
        assert vp.port_pin == pin
        assert f[vendor.pio_type_letter(vp.pio_type)] == ("SERCOM2", pad) == (board.BUS_SERCOM, pad)


def test_the_en_pins_are_tcc0_wo2_and_wo3_under_the_firmwares_pmux_letter(table):
    src = (ROOT / "src" / "cell" / "samd21_hw.cpp").read_text()
    m = re.search(r"PMUX\[10 >> 1\]\.reg\s*=\s*PORT_PMUX_PMUXE_([A-H])\s*\|\s*PORT_PMUX_PMUXO_([A-H])", src)
    assert m, "samd21_hw.cpp: the PMUX write of PA10/PA11 not found"
    even, odd = m.group(1), m.group(2)
    cc = {k: int(v) for k, v in re.findall(r"#define PWM_CC_([AB])\s+(\d+)", src)}
    assert re.search(r"PINCFG\[10\]\.reg\s*\|=\s*PORT_PINCFG_PMUXEN", src)
    assert re.search(r"PINCFG\[11\]\.reg\s*\|=\s*PORT_PINCFG_PMUXEN", src)
    assert (board.CELL_WIRING["en_alpha"], board.CELL_WIRING["en_beta"]) == ("PA10", "PA11")  # PMUX[5]: even, odd
    assert functions(table, "PA10")[even] == ("TCC0", f"WO{cc['A']}")
    assert functions(table, "PA11")[odd] == ("TCC0", f"WO{cc['B']}")


@pytest.mark.parametrize("signal", ["enc_alpha_a", "enc_alpha_b", "enc_beta_a", "enc_beta_b"])
def test_each_encoder_pin_has_the_external_interrupt_line_the_core_attaches(table, signal):
    """attachInterrupt() muxes the pin to function A (PIO_EXTINT) and enables the EIC line the variant names."""
    pin = board.CELL_WIRING[signal]
    eic, line = functions(table, pin)["A"]
    vp = next(v for v in vendor.variant_pins() if v.port_pin == pin)
    assert vendor.pio_type_letter("PIO_EXTINT") == "A"
    assert (eic, line) == ("EIC", "EXTINT" + vp.extint.removeprefix("EXTERNAL_INT_"))


def test_the_encoder_lines_are_distinct(table):
    lines = [functions(table, board.CELL_WIRING[s])["A"] for s in board.CELL_WIRING if s.startswith("enc_")]
    assert len(set(lines)) == 4, lines


# ---------------------------------------------------------------- no headers


def test_missing_headers_are_one_line_naming_mc_pio_tree(tmp_path, monkeypatch):
    monkeypatch.delenv("MC_PIO_TREE", raising=False)
    monkeypatch.delenv("PLATFORMIO_CORE_DIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    empty = tmp_path / "tree"
    empty.mkdir()
    with pytest.raises(regtable.RegTableError) as e:
        regtable.load(str(empty))
    msg = str(e.value)
    assert "\n" not in msg and "MC_PIO_TREE" in msg and str(empty) in msg
