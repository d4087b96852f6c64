"""The software NVIC on the register-level harness: enable, pend and clear-pend bookkeeping, a peripheral's request
line, pre-emption by priority and tail-chaining, with a stub program whose handlers log to SRAM; against the
SAMD21 datasheet (Microchip DS40001882, 11.2 "Nested Vector Interrupt Controller") and the ARMv6-M Architecture
Reference Manual it refers to (B1.5 "ARMv6-M exception model")."""

from __future__ import annotations

import struct

import pytest

from host_emulator.image import cycles
from host_emulator.image.harness import Asm, Harness, stub

from .bench import systick_free_running

LOGP, LOG = 0x2000_0000, 0x2000_0100  # the log pointer and the log: (tag, SysTick VAL) per entry
ISPR = 0xE000_E200
SYST_CVR = 0xE000_E018
A, B = 9, 10  # two IRQ lines no model drives here


def log(a: Asm, tag: int) -> None:
    """*LOGP++ = (tag, SysTick VAL): uses r0-r3 only (stacked on entry)."""
    a.ldr_const(0, LOGP)
    a.mem("ldr", 1, 0)
    a.movs(2, tag)
    a.mem("str", 2, 1)
    a.ldr_const(3, SYST_CVR)
    a.mem("ldr", 2, 3)
    a.mem("str", 2, 1, 4)
    a.adds(1, 8)
    a.mem("str", 1, 0)


def handlers(a: Asm) -> dict[int, str]:
    a.label("irq_a")  # logs 0xA1, pends B, logs 0xA2
    log(a, 0xA1)
    a.ldr_const(0, ISPR)
    a.ldr_const(1, 1 << B)
    a.mem("str", 1, 0)
    a.dsb_isb()
    log(a, 0xA2)
    a.bx_lr()
    a.pool()
    a.label("irq_b")
    log(a, 0xB1)
    a.bx_lr()
    a.pool()
    return {16 + A: "irq_a", 16 + B: "irq_b"}


def board(prio_a: int, prio_b: int) -> Harness:
    h = Harness(program=stub(handlers, irqs_enabled=True))
    h.write(LOGP, LOG)
    systick_free_running(h)
    ip = {A: prio_a, B: prio_b}
    for n, p in ip.items():
        reg = f"NVIC.IP[{n // 4}]"
        h.write(reg, h.read(reg) & ~(0xFF << 8 * (n % 4)) | p << 6 << 8 * (n % 4))
    h.write("NVIC.ISER[0]", 1 << A | 1 << B)
    return h


def entries(h: Harness) -> list[tuple[int, int]]:
    (end,) = struct.unpack("<I", h.ram(LOGP, 4))
    raw = h.ram(LOG, end - LOG)
    return [struct.unpack_from("<II", raw, k) for k in range(0, len(raw), 8)]


def run(prio_a: int, prio_b: int) -> list[tuple[int, int]]:
    h = board(prio_a, prio_b)
    h.write("NVIC.ISPR[0]", 1 << A)
    h.advance(2e-3)
    assert h.nvic().active == 0 and h.nvic().pending == 0
    return entries(h)


def test_a_higher_priority_interrupt_preempts_a_running_handler():
    """DS40001882 11.2 NVIC / ARMv6-M B1.5.4 Exception priorities and pre-emption: an exception with a higher
    priority (a lower value of the IPR field's two implemented bits) pre-empts the active handler."""
    assert [t for t, _ in run(prio_a=2, prio_b=0)] == [0xA1, 0xB1, 0xA2]


@pytest.mark.parametrize("prio_b", [2, 3], ids=["equal", "lower"])
def test_an_equal_or_lower_priority_interrupt_waits_for_the_handler_to_return(prio_b):
    """ARMv6-M B1.5.4: pre-emption needs a strictly higher priority; the pending exception is taken when the
    handler returns."""
    assert [t for t, _ in run(prio_a=2, prio_b=prio_b)] == [0xA1, 0xA2, 0xB1]


def test_the_waiting_interrupt_is_tail_chained_without_unstacking():
    """ARMv6-M B1.5.12 Exceptions on exception return, and tail-chaining (the NVIC of DS40001882 11.2 supports
    it): the pending exception is entered straight from the returning handler, without restoring and saving the
    context: A's return to B's first log takes less than a return plus an entry would."""
    log_ = run(prio_a=2, prio_b=3)
    (_, val_a2), (_, val_b) = log_[1], log_[2]
    gap = (val_a2 - val_b) & 0xFFFFFF  # SysTick counts down, one per CPU cycle
    cm = cycles.CycleModel()
    assert gap < cm.exc_exit + cm.exc_entry, gap


def test_pending_interrupts_of_equal_priority_are_taken_lowest_number_first():
    """ARMv6-M B1.5.4: of pending exceptions with the same priority, the lowest exception number is taken first."""
    h = board(prio_a=1, prio_b=1)
    h.write("NVIC.ISPR[0]", 1 << A | 1 << B)  # (A pends B again inside: already pending)
    h.advance(2e-3)
    assert [t for t, _ in entries(h)] == [0xA1, 0xA2, 0xB1]


def test_pend_clear_pend_and_enable_bookkeeping():
    """ARMv6-M B3.4 NVIC: ISPR sets and ICPR clears a pending state, ISER and ICER enable and disable; a pending
    interrupt that is disabled stays pending (and is not taken: interrupts are masked by PRIMASK in this stub)."""
    h = Harness()
    h.write("NVIC.ISPR[0]", 1 << A | 1 << B)
    assert h.pending() == {A, B} and h.read("NVIC.ISPR[0]") == 1 << A | 1 << B
    h.write("NVIC.ICPR[0]", 1 << A)
    assert h.pending() == {B}
    h.write("NVIC.ISER[0]", 1 << B)
    assert h.read("NVIC.ISER[0]") == 1 << B and h.read("NVIC.ICER[0]") == 1 << B
    h.write("NVIC.ICER[0]", 1 << B)
    assert h.read("NVIC.ISER[0]") == 0 and h.pending() == {B}
    h.advance(1e-3)
    assert h.pending() == {B} and h.active() == set()
