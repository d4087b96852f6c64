"""The cycle model as a decode table of ARMv6-M Thumb encodings, generated into C for the decoder csrc/sam_cost.c.

Code that was not loaded from an ELF (the bootloader, an application written into flash at run time, garbage) has
no disassembly, so the image tier costs it from its encodings. The model stays defined once, in ``cycles``
(``insn_cost``: core cycles per mnemonic, wait states, literal loads, the untaken-branch refund): each row here
names the encodings (``mask``/``value`` over ``first halfword << 16 | second halfword``) that objdump prints as one
representative instruction, and the row's numbers are the model's cost of that instruction. A register-list row
adds one core cycle per bit of the first halfword's low byte (the registers r0-r7; LR/PC are in the
representative's list). An instruction the model has no time for (WFI, SVC, BKPT, ...) is a row marked
unsupported; an encoding no row matches, or whose row names no instruction, is not an ARMv6-M instruction. Either
halts the board with a note naming the address (never a zero cost). Rows are tried in order: the first match counts.

``emit_c()`` is the generated header (the runtime build writes it beside the register table's, runtime.py). The
tests (tests/host_emulator/image/test_cost.py) prove the decoder equal to the ELF tables on every instruction of the
shipped images and of the bootloader, and to the model's cost of objdump's reading of every 16-bit encoding and of
the 32-bit ones ARMv6-M has.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import cycles


@dataclass(frozen=True)
class Row:
    mask: int  # over hw1 << 16 | hw2 (a 16-bit instruction's rows mask only the upper half)
    value: int
    mnem: str  # the representative instruction, as objdump prints it ("": not an ARMv6-M instruction)
    ops: str
    reglist: bool = False  # add popcount(hw1 & 0xFF) core cycles


def _h(mask: int, value: int, mnem: str, ops: str = "", reglist: bool = False) -> Row:
    """A 16-bit instruction's row: mask/value over its halfword."""
    return Row(mask << 16, value << 16, mnem, ops, reglist)


# 32-bit encodings (first halfword 0b11101..., 0b11110..., 0b11111...): ARMv6-M has BL, MSR, MRS and the barriers
WIDE_ROWS = (
    Row(0xF800D000, 0xF000D000, "bl", "0 <f>"),
    Row(0xFFF0FF00, 0xF3808800, "msr", "PRIMASK, r0"),
    Row(0xFFFFF000, 0xF3EF8000, "mrs", "r0, PRIMASK"),
    Row(0xFFFFFFF0, 0xF3BF8F40, "dsb", "sy"),
    Row(0xFFFFFFF0, 0xF3BF8F50, "dmb", "sy"),
    Row(0xFFFFFFF0, 0xF3BF8F60, "isb", "sy"),
    Row(0xFFF0F000, 0xF7F0A000, "udf", "#0"),
)

NARROW_ROWS = (
    # shifts, add/sub register and 3-bit immediate, mov/cmp/add/sub 8-bit immediate
    _h(0xF800, 0x0000, "lsls", "r0, r0, #1"),
    _h(0xF800, 0x0800, "lsrs", "r0, r0, #1"),
    _h(0xF800, 0x1000, "asrs", "r0, r0, #1"),
    _h(0xFC00, 0x1800, "adds", "r0, r0, r0"),
    _h(0xFC00, 0x1C00, "subs", "r0, r0, #1"),
    _h(0xE000, 0x2000, "movs", "r0, #1"),
    # data processing on registers
    _h(0xFFC0, 0x4340, "muls", "r0, r0"),
    _h(0xFC00, 0x4000, "ands", "r0, r0"),
    # ADD/MOV with high registers: writing the PC changes the flow
    _h(0xFF87, 0x4487, "add", "pc, r0"),
    _h(0xFF00, 0x4400, "add", "r0, r8"),
    _h(0xFF00, 0x4500, "cmp", "r0, r8"),
    _h(0xFF87, 0x4687, "mov", "pc, r0"),
    _h(0xFF00, 0x4600, "mov", "r0, r8"),
    _h(0xFF87, 0x4704, ""),  # ARMv8-M's BXNS, BLXNS: not ARMv6-M
    _h(0xFF87, 0x4784, ""),
    _h(0xFF80, 0x4700, "bx", "r0"),
    _h(0xFF87, 0x4780, "blx", "r0"),
    # loads and stores
    _h(0xF800, 0x4800, "ldr", "r0, [pc, #0]"),
    _h(0xFE00, 0x5000, "str", "r0, [r0, r0]"),
    _h(0xFE00, 0x5200, "strh", "r0, [r0, r0]"),
    _h(0xFE00, 0x5400, "strb", "r0, [r0, r0]"),
    _h(0xFE00, 0x5600, "ldrsb", "r0, [r0, r0]"),
    _h(0xFE00, 0x5800, "ldr", "r0, [r0, r0]"),
    _h(0xFE00, 0x5A00, "ldrh", "r0, [r0, r0]"),
    _h(0xFE00, 0x5C00, "ldrb", "r0, [r0, r0]"),
    _h(0xFE00, 0x5E00, "ldrsh", "r0, [r0, r0]"),
    _h(0xF800, 0x6000, "str", "r0, [r0, #0]"),
    _h(0xF800, 0x6800, "ldr", "r0, [r0, #0]"),
    _h(0xF800, 0x7000, "strb", "r0, [r0, #0]"),
    _h(0xF800, 0x7800, "ldrb", "r0, [r0, #0]"),
    _h(0xF800, 0x8000, "strh", "r0, [r0, #0]"),
    _h(0xF800, 0x8800, "ldrh", "r0, [r0, #0]"),
    _h(0xF800, 0x9000, "str", "r0, [sp, #0]"),
    _h(0xF800, 0x9800, "ldr", "r0, [sp, #0]"),
    # ADR (objdump: add rd, pc, #imm) and ADD rd, SP, #imm
    _h(0xF800, 0xA000, "add", "r0, pc, #0"),
    _h(0xF800, 0xA800, "add", "r0, sp, #0"),
    # miscellaneous
    _h(0xFF80, 0xB000, "add", "sp, #0"),
    _h(0xFF80, 0xB080, "sub", "sp, #0"),
    _h(0xFF00, 0xB200, "sxth", "r0, r0"),
    _h(0xFF00, 0xB400, "push", "{}", reglist=True),
    _h(0xFF00, 0xB500, "push", "{lr}", reglist=True),
    _h(0xFFE8, 0xB660, "cpsie", "i"),
    _h(0xFFC0, 0xBA00, "rev", "r0, r0"),
    _h(0xFFC0, 0xBA40, "rev16", "r0, r0"),
    _h(0xFFC0, 0xBAC0, "revsh", "r0, r0"),
    _h(0xFF00, 0xBC00, "pop", "{}", reglist=True),
    _h(0xFF00, 0xBD00, "pop", "{pc}", reglist=True),
    _h(0xFF00, 0xBE00, "bkpt", "0x0000"),
    _h(0xFFFF, 0xBF00, "nop"),
    _h(0xFFFF, 0xBF10, "yield"),
    _h(0xFFFF, 0xBF20, "wfe"),
    _h(0xFFFF, 0xBF30, "wfi"),
    _h(0xFFFF, 0xBF40, "sev"),
    _h(0xFF0F, 0xBF00, "nop", "{5}"),  # the reserved hints 5..15 execute as NOP
    # STM, LDM
    _h(0xF800, 0xC000, "stmia", "r0!, {}", reglist=True),
    _h(0xF800, 0xC800, "ldmia", "r0!, {}", reglist=True),
    # UDF, SVC, conditional and unconditional branches
    _h(0xFF00, 0xDE00, "udf", "#0"),
    _h(0xFF00, 0xDF00, "svc", "0"),
    _h(0xF000, 0xD000, "beq", "0 <f>"),
    _h(0xF800, 0xE000, "b", "0 <f>"),
)

ROWS = NARROW_ROWS + WIDE_ROWS


@dataclass(frozen=True)
class RowCost:
    core: int  # without the register list's registers
    wait: int
    literal: int
    refund: int
    unsupported: bool


def row_cost(row: Row, model: cycles.CycleModel | None = None) -> RowCost:
    """The model's cost of a row's representative instruction."""
    model = model or cycles.CycleModel()
    if not row.mnem:
        return RowCost(0, 0, 0, 0, True)
    ins = cycles.Insn(0, row.mnem, row.ops, "")
    try:
        k = cycles.insn_cost(ins, model)
        unsupported = False
    except cycles.UnsupportedInsn:
        k = cycles.insn_cost(ins, model, core=0)
        unsupported = True
    return RowCost(k.core, k.wait, k.literal, k.refund, unsupported)


def decode(hw1: int, hw2: int, model: cycles.CycleModel | None = None) -> tuple[Row, RowCost, int] | None:
    """(row, its cost, core cycles of this encoding) of the instruction starting with `hw1` (`hw2`: the next
    halfword), or None: not an ARMv6-M instruction. The C decoder's reference (it reads the generated table)."""
    wide = hw1 >> 11 in (0b11101, 0b11110, 0b11111)
    key = hw1 << 16 | (hw2 if wide else 0)
    for row in WIDE_ROWS if wide else NARROW_ROWS:
        if key & row.mask == row.value:
            if not row.mnem:
                return None
            rc = row_cost(row, model)
            return row, rc, rc.core + (bin(hw1 & 0xFF).count("1") if row.reglist else 0)
    return None


def emit_c(model: cycles.CycleModel | None = None) -> str:
    """The C table (csrc/sam_cost.c includes it; the row type is declared there)."""
    out = [
        "/* Generated by host_emulator/image/costtable.py from the cycle model (cycles.insn_cost): do not edit. */",
        "/* mask, value (hw1 << 16 | hw2), core, wait, literal, refund, flags, the representative instruction */",
        "static const sam_cost_row_t sam_cost_rows[] = {",
    ]
    for row in ROWS:
        rc = row_cost(row, model)
        flags = " | ".join(
            f
            for f, on in (
                ("SAM_COST_REGLIST", row.reglist),
                ("SAM_COST_UNSUPPORTED", rc.unsupported and bool(row.mnem)),
                ("SAM_COST_WIDE", row in WIDE_ROWS),
                ("SAM_COST_UNDEFINED_ROW", not row.mnem),
            )
            if on
        )
        text = f"{row.mnem} {row.ops}".strip() if row.mnem else "an encoding ARMv6-M does not define"
        text = text.replace("\\", "\\\\").replace('"', '\\"')
        out.append(
            f"    {{0x{row.mask:08x}u, 0x{row.value:08x}u, {rc.core}, {rc.wait}, {rc.literal}, "
            f'{rc.refund}, {flags or "0"}, "{text}"}},'
        )
    out += ["};", f"#define SAM_COST_NROWS {len(ROWS)}", ""]
    return "\n".join(out)
