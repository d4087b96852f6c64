"""The core's own exceptions on the register-level harness: UDF, BKPT, SVC, an unaligned access, an access to no
memory, an instruction ARMv6-M does not have and a branch to ARM state each enter the program's HardFault (or
SVCall) handler with the frame ARMv6-M stacks, and an interrupt of higher priority that arrives while another's
entry is under way is entered in its place (late arrival). Against the ARMv6-M Architecture Reference Manual (DDI
0419E) B1.5 "ARMv6-M exception model" and the SAMD21 datasheet (DS40001882) 11.2 "Nested Vector Interrupt
Controller"."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Asm, Harness, stub

from .test_nvic import LOG, LOGP, entries

ISPR = 0xE000_E200
A = 9  # an IRQ line no model drives here


def _faulting(a: Asm) -> dict[int, str]:
    """Sites that fault, each followed by `b .`; the HardFault and SVCall handlers put the stacked PC and xPSR in
    R1 and R2 (the frame at SP: R0-R3, R12, LR, PC, xPSR) and stop at `hf_done` / `svc_done`."""
    a.label("udf")
    a._h(0xDE00, "udf", "#0")
    a.b()
    a.label("bkpt")
    a._h(0xBE00, "bkpt", "0x0000")
    a.b()
    a.label("svc")
    a._h(0xDF00, "svc", "0")
    a.label("after_svc")
    a.b()
    a.label("unaligned")  # r0 = an odd SRAM address
    a.mem("ldr", 1, 0)
    a.b()
    a.label("nowhere")  # r0 = an address with no memory behind it
    a.mem("ldr", 1, 0)
    a.b()
    a.label("thumb2")  # a 32-bit Thumb-2 instruction ARMv7-M has and ARMv6-M does not: UNDEFINED on the M0+
    a._w(0xF04F, 0x0001, "mov.w", "r0, #1")
    a.b()
    a.label("arm_state")  # r0 = an address with bit 0 clear
    a._h(0x4700, "bx", "r0")
    a.b()
    for name in ("hf", "svc_h"):
        a.label(name)
        a.mov_from_sp(0)
        a.mem("ldr", 1, 0, 24)
        a.mem("ldr", 2, 0, 28)
        a.label("hf_done" if name == "hf" else "svc_done")
        a.b()
    return {3: "hf", 11: "svc_h"}


def _board(irqs_enabled: bool = True) -> Harness:
    return Harness(program=stub(_faulting, irqs_enabled=irqs_enabled))


def _hardfault(h: Harness, site: str, r0: int = 0) -> tuple[int, int]:
    """(stacked PC, stacked xPSR) as the HardFault handler found them after running `site`."""
    pc = h.call(site, "hf_done", r0=r0)
    assert h.error() is None, h.error()
    return pc, h.nvic().sys_active


@pytest.mark.parametrize(
    "site, r0",
    [
        ("udf", 0),
        ("bkpt", 0),
        ("unaligned", 0x2000_0101),
        ("nowhere", 0x1000_0000),
        ("thumb2", 0),
    ],
    ids=["udf", "bkpt", "unaligned-ldr", "unmapped-ldr", "thumb2-only-insn"],
)
def test_a_faulting_instruction_enters_hardfault_with_its_own_address_stacked(site, r0):
    """B1.5.6 and B1.5.14 (HardFault is the only fault on ARMv6-M): UDF, BKPT with no debugger (C1.7), an
    unaligned LDR (A3.2: every unaligned word access faults), a bus error (an address with no memory) and a 32-bit
    instruction outside ARMv6-M's few (A5.3: MOV.W is ARMv7-M's; UNDEFINED here) enter HardFault; the stacked return
    address is the faulting instruction's, and HardFault is active. The last two hold only because the CPU is
    Unicorn's Cortex-M0 model: opened as an M-class CPU, Unicorn 2.1.4 runs a Cortex-M33 whatever model is asked for,
    which executes both (csrc/sam_cpu.c, sam_cpu_open)."""
    h = _board()
    stacked_pc, sys_active = _hardfault(h, site, r0)
    assert stacked_pc == h.program.labels[site]
    assert sys_active == 1 << 3
    assert h.info().hardfaults == 1


def test_a_branch_to_arm_state_enters_hardfault():
    """B1.4.2 (EPSR.T): a BX to an address with bit 0 clear clears T; the next instruction faults (INVSTATE on
    ARMv6-M is a HardFault)."""
    h = _board()
    h.call("arm_state", "hf_done", r0=h.program.labels["udf"] & ~1)
    assert h.error() is None and h.nvic().sys_active == 1 << 3


def test_svc_enters_svcall_and_returns_after_the_instruction():
    """B1.5.2 / B1.5.6: SVC takes SVCall (exception 11) when its priority is above the execution priority; the
    stacked return address is the instruction after the SVC."""
    h = _board()
    stacked_pc = h.call("svc", "svc_done")
    assert stacked_pc == h.program.labels["after_svc"]
    assert h.nvic().sys_active == 1 << 11 and h.info().hardfaults == 0


def test_svc_escalates_to_hardfault_when_it_cannot_be_taken():
    """B1.5.14 (priority escalation): SVC executed while PRIMASK masks every configurable exception cannot take
    SVCall: it takes HardFault."""
    h = _board(irqs_enabled=False)
    stacked_pc = h.call("svc", "hf_done")
    assert stacked_pc == h.program.labels["after_svc"]
    assert h.nvic().sys_active == 1 << 3 and h.info().hardfaults == 1


SYST_CSR = 0xE000_E010
SYSTICK = 15


def _late_handlers(pend_a: bool):
    def handlers(a: Asm) -> dict[int, str]:
        """`go` starts SysTick (LOAD preset: it fires LOAD + 1 cycles later) and, with pend_a, pends IRQ A right
        after; each handler logs its tag and the SP it runs on (the frames below it)."""
        a.label("go")
        a.ldr_const(0, SYST_CSR)
        a.ldr_const(3, ISPR)
        a.movs(1, 7)  # ENABLE, TICKINT, the processor clock
        a.movs(2, 0)
        if pend_a:
            a.ldr_const(2, 1 << A)
        a.mem("str", 1, 0)
        a.mem("str", 2, 3)
        a.label("go_done")
        a.b()
        a.pool()
        for name, tag in (("irq_a", 0xA1), ("systick", 0x51)):
            a.label(name)
            a.ldr_const(0, LOGP)
            a.mem("ldr", 1, 0)
            a.movs(2, tag)
            a.mem("str", 2, 1)
            a.mov_from_sp(2)
            a.mem("str", 2, 1, 4)
            a.adds(1, 8)
            a.mem("str", 1, 0)
            a.movs(2, 0)  # SysTick off: one tick
            a.ldr_const(3, SYST_CSR)
            a.mem("str", 2, 3)
            a.bx_lr()
            a.pool()
        return {16 + A: "irq_a", SYSTICK: "systick"}

    return handlers


def _race(load: int, pend_a: bool) -> list[tuple[int, int]]:
    """(tag, SP) per handler entry: SysTick (priority 0) firing `load` + 1 cycles after it is started, IRQ A
    (priority 2) pended right after the start."""
    h = Harness(program=stub(_late_handlers(pend_a), irqs_enabled=True))
    h.write(LOGP, LOG)
    h.write("NVIC.IP[2]", 2 << 6 << 8 * (A % 4))
    h.write("NVIC.ISER[0]", 1 << A)
    h.write("SysTick.LOAD", load)
    h.write("SysTick.VAL", 0)
    h.call("go", "go_done")
    h.advance(1e-3)
    assert h.nvic().active == 0 and h.nvic().sys_active == 0
    return entries(h)


def test_a_higher_priority_exception_arriving_during_an_entry_is_taken_instead():
    """B1.5.12 (late arrival; the Cortex-M0+ implements it): SysTick (priority 0) firing while IRQ A's (priority
    2) entry is stacking is entered in A's place, on A's frame, and A's handler runs after it (tail-chained): for
    every firing time that puts SysTick first, its handler runs on the same SP as when SysTick fires alone (a
    nested entry would have stacked a second frame, 32 bytes lower)."""
    sp_alone = _race(40, pend_a=False)[0][1]
    late = []
    for load in range(0, 40):
        log_ = _race(load, pend_a=True)
        tags = [t for t, _ in log_]
        if tags[0] == 0x51 and 0xA1 in tags:
            late.append((load, log_[0][1]))
    assert late, "SysTick never came first: the race tests nothing"
    assert all(sp == sp_alone for _, sp in late), (sp_alone, late)
