"""The SAMD21's Cortex-M0+ at 48 MHz as the analyses see it: a linked image's disassembly (objdump -d, parsed into
functions, instructions and literal words) and the cycle model per instruction (core timings, flash wait states,
the APB surcharge). One model serves fwcheck's static CPU budget (worst paths: metacell_tools.fwcheck.wcet) and the
emulator's image tier (time charged per executed block: host_emulator.image.cycles)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from .board import F_CPU_HZ
from .toolchain import run

__all__ = [
    "BCOND",
    "BRANCH_TARGET",
    "LITERAL_REF",
    "nregs",
    "F_CPU_HZ",
    "CORE_ONLY",
    "LOADS",
    "STORES",
    "CycleModel",
    "Function",
    "Image",
    "Insn",
    "UnsupportedInsn",
    "base_cycles",
    "disassemble",
    "parse_disassembly",
]

# --------------------------------------------------------------------------- parsing

LABEL_LINE = re.compile(r"^([0-9a-f]+) <(.+)>:$")
INSN_LINE = re.compile(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$")
LITERAL_REF = re.compile(r"@ \(([0-9a-f]+) <")
BRANCH_TARGET = re.compile(r"^([0-9a-f]+) <([^>+]+)(?:\+0x([0-9a-f]+))?>")
COND = "eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le"
BCOND = re.compile(rf"^b({COND})(\.n|\.w)?$")
REGLIST = re.compile(r"\{([^}]*)\}")


@dataclass(frozen=True)
class Insn:
    addr: int
    mnem: str  # without .n/.w
    ops: str  # operands, comment stripped
    comment: str


@dataclass
class Function:
    name: str
    start: int
    insns: list[Insn] = field(default_factory=list)


@dataclass
class Image:
    functions: dict[str, Function]
    by_addr: dict[int, str]  # start address -> function name
    words: dict[int, int]  # literal-pool address -> 32-bit value


def parse_disassembly(text: str) -> Image:
    """Functions, their instructions and the literal words of ``objdump -d --no-show-raw-insn`` output."""
    funcs: dict[str, Function] = {}
    words: dict[int, int] = {}
    cur: Function | None = None
    for ln in text.splitlines():
        m = LABEL_LINE.match(ln)
        if m:
            cur = Function(m.group(2), int(m.group(1), 16))
            funcs[cur.name] = cur
            continue
        m = INSN_LINE.match(ln)
        if not m or cur is None:
            continue
        addr, mnem, rest = int(m.group(1), 16), m.group(2), m.group(3)
        if mnem == ".word":
            words[addr] = int(rest.split()[0], 16) & 0xFFFFFFFF
            continue
        if mnem.startswith("."):
            continue
        ops, _, comment = rest.partition("@")
        mnem = mnem.removesuffix(".n").removesuffix(".w")
        cur.insns.append(Insn(addr, mnem, ops.strip(), comment.strip()))
    by_addr = {f.start: f.name for f in funcs.values()}
    return Image(funcs, by_addr, words)


def disassemble(elf: Path) -> str:
    """``arm-none-eabi-objdump -d --no-show-raw-insn`` of a linked image (ToolError when binutils are missing)."""
    return run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(elf)])


# --------------------------------------------------------------------------- cycle model


@dataclass(frozen=True)
class CycleModel:
    """Cycles per instruction class on the SAMD21's Cortex-M0+ at 48 MHz (conservative).

    Core timings are the Cortex-M0+ ones (ARMv6-M): data processing and MULS (the SAMD21 has the
    single-cycle multiplier) 1, load/store 2, LDM/STM/PUSH 1+N, POP with PC 3+N, B taken 2 / not
    taken 1, BL 3, BX/BLX 2, MRS/MSR/barriers 3. On top:

    * ``fetch_wait``: one flash wait state (NVMCTRL RWS=1 at 48 MHz) charged on *every*
      instruction, as if each 16-bit instruction were its own flash read (the core reads 32 bits
      and the NVM cache may hit: real code pays less);
    * ``refill_wait``: a further wait state for every change of flow (taken branch, call, return);
    * ``literal_wait``: a PC-relative load reads flash;
    * ``apb_extra``: a load/store through the AHB-APB bridge; charged whenever the base is not
      proven SRAM, stack or flash (IOBUS PORT accesses are single-cycle, charged as SRAM);
    * ``exc_entry`` / ``exc_exit``: 15 cycles each (zero-wait-state latency), plus the vector
      read and the first fetch (entry) or the refill (exit) from flash.
    """

    fetch_wait: int = 1
    refill_wait: int = 1
    literal_wait: int = 1
    apb_extra: int = 3
    exc_entry: int = 15 + 2
    exc_exit: int = 15 + 1


#: The core's own timings only (zero-wait memory): not a bound, a reference for what the surcharges add.
CORE_ONLY = CycleModel(fetch_wait=0, refill_wait=0, literal_wait=0, apb_extra=0, exc_entry=15, exc_exit=15)

LOADS = {"ldr", "ldrb", "ldrh", "ldrsb", "ldrsh"}
STORES = {"str", "strb", "strh"}


def nregs(ops: str) -> int:
    m = REGLIST.search(ops)
    if not m:
        raise ValueError(f"no register list in {ops!r}")
    n = 0
    for part in m.group(1).split(","):
        part = part.strip()
        if "-" in part:
            a, b = (int(x.strip()[1:]) for x in part.split("-"))
            n += b - a + 1
        elif part:
            n += 1
    return n


class UnsupportedInsn(ValueError):
    """An instruction the model has no timing for (e.g. WFI in an interrupt path)."""


def base_cycles(insn: Insn) -> int:
    """Core cycles of one instruction (branches: the not-taken / non-branch part; see edge costs)."""
    m, ops = insn.mnem, insn.ops
    if m in LOADS or m in STORES:
        return 2
    if m in ("push", "stmia", "stm", "ldmia", "ldm"):
        return 1 + nregs(ops)
    if m == "pop":
        return (3 if "pc" in ops else 1) + nregs(ops)
    if m in ("mrs", "msr", "isb", "dsb", "dmb"):
        return 3
    if m in ("wfi", "wfe", "svc", "bkpt", "udf", "sev"):
        raise UnsupportedInsn(f"{m} at {insn.addr:#x}")
    if m == "bl":
        return 3
    if m in ("bx", "blx"):
        return 2
    if m == "b":
        return 2
    if BCOND.match(m) or m in ("beq", "bne"):
        return 1  # not taken; taken adds 1 (edge cost)
    return 1
