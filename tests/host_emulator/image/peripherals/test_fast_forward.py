"""Fast-forwarding on the register-level harness: a loop() whose passes change only a fixed-address object in the
RAM between the heap's break and SP, and one that polls TCC0's STATUS for a buffered compare value to be taken
over, run the same with fast-forwarding on and off (csrc/sam_ff.c; DS40001882 31.6.2.6 "Double Buffering" for the
CCBV flags)."""

from __future__ import annotations

import dataclasses
import struct

from host_emulator.image.harness import Asm, Harness, Program, stub

from .bench import GCLK_TCC0_TCC1, bus_clock, gclk_channel

FLAG = 0x2000_0000  # the harness sets it to start the loop
RESULT = 0x2000_0004
STATIC_END = 0x2000_0100  # the program's static data: FLAG, RESULT (the heap would start here)
FIXED = 0x2000_7800  # a fixed-address object (the firmware's fault record lives here), below SP, above the heap
SYST_CVR = 0xE000_E018
STATUS_CCBV0 = 1 << 16


def _program(loop: str) -> Program:
    """Reset: wait for FLAG (set by the test), then run `loop` (loop() for the fast-forward)."""

    def code(a: Asm) -> dict[int, str]:
        a.label("start")
        a.cpsid()
        a.ldr_const(0, FLAG)
        a.label("wait")
        a.mem("ldr", 1, 0)
        a._h(0x2900, "cmp", "r1, #0")
        here = a.here
        a._h(0xD000 | ((a.labels["wait"] - (here + 4)) >> 1) & 0xFF, "beq", "wait")
        if loop == "fixed":
            a.ldr_const(0, FIXED)
            a.label("loop")  # *FIXED += 1, the registers as they were
            a.mem("ldr", 1, 0)
            a.adds(1, 1)
            a.mem("str", 1, 0)
            a.movs(1, 0)
            a.b("loop")
        else:
            a.ldr_const(0, 0x4200_2000 + 0x30)  # TCC0.STATUS
            a.label("loop")  # while (TCC0->STATUS.bit.CCBV0) {}
            a.mem("ldr", 1, 0)
            a._h(0x0C49, "lsrs", "r1, r1, #17")  # CCBV0 (bit 16) into the carry
            here = a.here
            a._h(0xD200 | ((a.labels["loop"] - (here + 4)) >> 1) & 0xFF, "bcs", "loop")
            a.ldr_const(2, SYST_CVR)  # taken over: when, by SysTick
            a.mem("ldr", 3, 2)
            a.ldr_const(2, RESULT)
            a.mem("str", 3, 2)
            a.label("done")
            a.b()
        a.pool()
        return {}

    p = stub(code)
    return dataclasses.replace(p, entry=p.labels["start"], idle=p.labels["loop"], heap_base=STATIC_END)


def _word(h: Harness, addr: int) -> int:
    return struct.unpack("<I", h.ram(addr, 4))[0]


def _fixed(ff: bool) -> int:
    h = Harness(program=_program("fixed"), ff=ff)
    h.write(FLAG, 1)
    h.advance(2e-3)
    return _word(h, FIXED)


def test_a_pass_that_writes_only_a_fixed_address_object_is_never_skipped():
    """The object lies between the heap's break and SP, where the free stack is: each pass changes it, so no pass
    repeats and none may be skipped; the count after 2 ms is the same as without fast-forwarding."""
    on, off = _fixed(True), _fixed(False)
    assert off > 100, off
    assert on == off


def _tcc_poll(ff: bool) -> tuple[int, int]:
    h = Harness(program=_program("tcc"), ff=ff)
    h.write("SysTick.LOAD", 0xFFFFFF)
    h.write("SysTick.VAL", 0)
    h.write("SysTick.CTRL", 0x5)
    bus_clock(h, "TCC0")
    gclk_channel(h, GCLK_TCC0_TCC1)
    h.write("TCC0.WAVE", 0x2)
    h.write("TCC0.PER", 999)  # 1 ms periods at 1 MHz
    h.write("TCC0.CC[0]", 100)
    h.write("TCC0.CTRLA", 1 << 1)
    h.advance(20e-6)
    h.write("TCC0.CCB[0]", 500)  # taken over at the next UPDATE, within 1 ms
    pending = h.read("TCC0.STATUS") & STATUS_CCBV0
    h.write(FLAG, 1)
    h.advance(3e-3)
    return pending, _word(h, RESULT)


def test_a_loop_polling_tcc_status_sees_the_buffer_taken_over_when_it_is():
    """DS40001882 31.8.13 STATUS.CCBVn: set while CCBn holds a value not yet taken over; it clears at the UPDATE,
    which is no event of the board's: a loop() polling it leaves at the same cycle with fast-forwarding on as
    off (SysTick's count when it left)."""
    (pend_on, t_on), (pend_off, t_off) = _tcc_poll(True), _tcc_poll(False)
    assert pend_on and pend_off
    assert t_off != 0
    assert t_on == t_off
