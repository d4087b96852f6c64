"""Cortex-M0+ cycle model of the SAMD21 at 48 MHz, per instruction, from a linked image's disassembly.

One model (``metacell_common.target.cycles``, where it is defined) serves the static CPU budget
(``metacell_tools.fwcheck.cpubudget``: worst paths) and the image tier (time charged per executed block: the tables
here). Core timings are the Cortex-M0+ ones (ARMv6-M): data processing and MULS (the SAMD21 has the single-cycle
multiplier) 1, load/store 2, LDM/STM/PUSH 1+N, POP with PC 3+N, B taken 2 / not taken 1, BL 3, BX/BLX 2,
MRS/MSR/barriers 3. On top of them, flash wait states (NVMCTRL.CTRLB.RWS, one at 48 MHz): one on every instruction's
fetch, one more on every change of flow (the refill) and on every PC-relative load, and a surcharge on every access
through the AHB-APB bridge. The model is conservative: the core reads 32 bits per fetch and the NVM cache may hit,
so real code pays less. In the image tier the APB surcharge is charged when an access reaches a peripheral
(exactly), loads of flash through a register are not surcharged, and a conditional branch is charged taken and
refunded when execution falls through.

The image tier has two models of the flash (``CYCLE_MODELS``): ``"cache"`` (default, the typical case) charges
RWS wait states per miss of the NVM controller's cache (8 direct-mapped lines of 64 bits, DS40001882 "Cache")
when a block's instructions are fetched, plus the PC-relative loads; ``"worst"`` is the CPU budget's bound, a
wait state on every instruction fetch and on every refill.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

# the one cycle model (instruction classes, wait states) and the disassembly it reads: the target's, shared with the
# CPU budget (metacell_common/target/cycles.py)
from metacell_common.target.board import FLASH_SIZE
from metacell_common.target.cycles import (
    F_CPU_HZ,
    LOADS,
    STORES,
    CycleModel,
    Function,
    Image,
    Insn,
    UnsupportedInsn,
    base_cycles,
    disassemble,
    parse_disassembly,
)

__all__ = [
    "F_CPU_HZ",
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
    "BlockTables",
    "InsnCost",
    "block_tables",
    "insn_cost",
    "CYCLE_MODELS",
    "FLASH_SIZE",
]

CYCLE_MODELS = ("cache", "worst")
_COND = "eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le"
BCOND = re.compile(rf"^b({_COND})(\.n|\.w)?$")
#: the 32-bit instructions of ARMv6-M
WIDE = {"bl", "mrs", "msr", "dmb", "dsb", "isb"}


def changes_flow(insn: Insn) -> bool:
    """Always changes the flow (calls, returns, unconditional branches, writes of the PC)."""
    m, ops = insn.mnem, insn.ops
    if m in ("b", "bl", "bx", "blx"):
        return True
    if m == "pop" and "pc" in ops:
        return True
    return m in ("mov", "add") and ops.replace(" ", "").startswith("pc,")


@dataclass
class BlockTables:
    """Per-halfword tables of a flash image for the image tier's block hook.

    The cycles of a block [a, b) at RWS wait states are ``core[b/2] - core[a/2] + RWS * (wait[b/2] - wait[a/2])``
    (prefix sums); a block ending in a conditional branch at halfword h is charged taken and refunded
    ``(refund[h] & 15) + RWS * (refund[h] >> 4)`` when the next block starts at its fall-through."""

    core: np.ndarray  # uint32 prefix sums of core cycles, one entry per halfword + 1
    wait: np.ndarray  # uint32 prefix sums of the worst-case model's waited flash accesses (fetch, refill, literal)
    literal: np.ndarray  # uint32 prefix sums of PC-relative loads (a flash data read each)
    refund: np.ndarray  # uint8 per halfword: low nibble core cycles, high nibble waits (worst-case model)
    code_end: int  # end of the last instruction
    unsupported: list[str]  # instructions the model has no time for (they fault in the image tier)


class InsnCost(NamedTuple):
    """What one instruction adds to the tables: its size, core cycles (a conditional branch charged taken), the
    worst-case model's waited flash accesses, its PC-relative loads and its untaken-branch refund (as in
    BlockTables.refund)."""

    size: int
    core: int
    wait: int
    literal: int
    refund: int


def insn_cost(ins: Insn, model: CycleModel, core: int | None = None) -> InsnCost:
    """The cost of an instruction (UnsupportedInsn when the model has no time for it, unless `core` is given)."""
    c = base_cycles(ins) if core is None else core
    refund = 0
    w = model.fetch_wait
    lit = model.literal_wait if "[pc" in ins.ops and ins.mnem in LOADS else 0
    w += lit
    if changes_flow(ins):
        w += model.refill_wait
    if BCOND.match(ins.mnem):
        c += 1  # charged taken ...
        w += model.refill_wait
        refund = 1 | (model.refill_wait << 4)  # ... refunded when it falls through
    return InsnCost(4 if ins.mnem in WIDE else 2, c, w, lit, refund)


def block_tables(image: Image, flash_size: int = FLASH_SIZE, model: CycleModel | None = None) -> BlockTables:
    model = model or CycleModel()
    nh = flash_size // 2
    core = np.zeros(nh + 1, dtype=np.uint32)
    wait = np.zeros(nh + 1, dtype=np.uint32)
    literal = np.zeros(nh + 1, dtype=np.uint32)
    refund = np.zeros(nh, dtype=np.uint8)
    code_end = 0
    unsupported = []
    for f in image.functions.values():
        for ins in f.insns:
            h = ins.addr // 2
            if h >= nh:
                continue
            try:
                k = insn_cost(ins, model)
            except UnsupportedInsn:
                unsupported.append(f"{ins.mnem} at {ins.addr:#x} in {f.name}")
                k = insn_cost(ins, model, core=1)
            code_end = max(code_end, ins.addr + k.size)
            if k.literal:
                literal[h + 1] = k.literal
            if k.refund:
                refund[h] = k.refund
            core[h + 1] = k.core
            wait[h + 1] = k.wait
    return BlockTables(
        np.cumsum(core, dtype=np.uint32),
        np.cumsum(wait, dtype=np.uint32),
        np.cumsum(literal, dtype=np.uint32),
        refund,
        code_end,
        unsupported,
    )
