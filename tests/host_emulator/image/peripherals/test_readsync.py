"""Read-synchronised counters on the register-level harness: TC3's COUNT through READREQ and TCC0's COUNT through the
READSYNC command return the value of the last read synchronisation, against the SAMD21 datasheet (Microchip
DS40001882, 30.6.6 and 30.10.2 for the TC, 31.6.6 and 31.8.3 for the TCC)."""

from __future__ import annotations

from host_emulator.image.harness import Asm, Harness, Program

from .bench import (
    CMD_READSYNC,
    GCLK_TCC0_TCC1,
    GCLK_TCC2_TC3,
    SYNCBUSY_CTRLB,
    bus_clock,
    gclk_channel,
    systick_free_running,
)
from .test_fast_forward import FLAG, RESULT, _after_flag, _word, leave_with_the_time

TU_HZ = 1_536_000_000
ULP_HZ = 32_768  # OSCULP32K: a slow clock, so a synchronisation outlasts several CPU accesses
ULP_TICK = TU_HZ // ULP_HZ  # 46875 tu, exact
SYNC_TU = -(-3 * TU_HZ // ULP_HZ)  # 3 GCLK cycles (the tier's synchronisation time), rounded up to a whole tu
CC0 = 59_999  # MFRQ's period: 60000 counts (1.8 s at 32 kHz), so a few ms never wrap
MFRQ, ENABLE = 1 << 5, 1 << 1
RREQ, RCONT = 1 << 15, 1 << 14
ADDR_COUNT, ADDR_CC0, ADDR_INTFLAG = 0x10, 0x18, 0x0E  # COUNT16's offsets (30.10, the 16-bit mode's registers)
SYNCBUSY = 1 << 7  # STATUS.SYNCBUSY


def slow_generator(h: Harness) -> None:
    """GCLK generator 2 from OSCULP32K, undivided."""
    h.write("GCLK.GENDIV", 2)
    h.write("GCLK.GENCTRL", 2 | 0x03 << 8 | 1 << 16)


def tc3_counting() -> tuple[Harness, int]:
    """TC3 in COUNT16 MFRQ on the 32 kHz clock, prescaler DIV1; returns the time (tu) the counter starts: when the
    enable has synchronised (30.6.6), counting from COUNT's reset value 0 (30.6.2.1)."""
    h = Harness()
    bus_clock(h, "TC3")
    slow_generator(h)
    gclk_channel(h, GCLK_TCC2_TC3, gen=2)
    h.write("TC3.COUNT16.CC[0]", CC0)
    h.advance(1e-3)  # CC0's write synchronises first (a write meanwhile would wait for it)
    h.write("TC3.COUNT16.CTRLA", MFRQ | ENABLE)
    t_start = h.t_access + SYNC_TU
    h.advance(1e-3)
    assert not h.read("TC3.COUNT16.STATUS") & 1 << 3, "STATUS.STOP: the counter runs"
    return h, t_start


def counted(t_start: int, t: int) -> int:
    """The count at time t of a counter started at t_start: one count per 32 kHz cycle, period CC0 + 1."""
    return (t - t_start) // ULP_TICK % (CC0 + 1)


def test_a_tc_count_read_without_a_read_request_returns_the_reset_value_while_the_counter_runs():
    """DS40001882 30.6.6 Synchronization and 30.10.2 READREQ: COUNT is read-synchronised; until a read request (RREQ)
    has brought it over, a read returns its reset value 0 however far the counter has run."""
    h, t_start = tc3_counting()
    for dt in (2e-3, 7e-3, 31e-3):
        h.advance(dt)
        assert counted(t_start, h.now()) > 0
        assert h.read("TC3.COUNT16.COUNT") == 0


def test_a_tc_read_request_holds_syncbusy_then_count_reads_the_count_at_its_completion():
    """DS40001882 30.10.2 READREQ: writing RREQ with ADDR = COUNT requests its synchronisation and sets STATUS.SYNCBUSY
    until it completes; COUNT then reads the counter's value at that completion, the same on every read until the
    next request."""
    h, t_start = tc3_counting()
    h.advance(3e-3)
    h.write("TC3.COUNT16.READREQ", RREQ | ADDR_COUNT)
    t_sync = h.t_access + SYNC_TU
    assert h.read("TC3.COUNT16.STATUS") & SYNCBUSY and h.t_access < t_sync
    assert h.read("TC3.COUNT16.COUNT") == 0, "the synchronisation has not completed"
    h.advance_to(t_sync + 1)
    assert not h.read("TC3.COUNT16.STATUS") & SYNCBUSY
    want = counted(t_start, t_sync)
    assert want > 50
    assert h.read("TC3.COUNT16.COUNT") == want
    h.advance(5e-3)
    assert h.read("TC3.COUNT16.COUNT") == want, "no new request: the same value"
    assert h.read("TC3.COUNT16.READREQ") & RREQ == 0, "RREQ reads as zero"
    h.write("TC3.COUNT16.READREQ", RREQ | ADDR_COUNT)
    t_sync = h.t_access + SYNC_TU
    h.advance_to(t_sync + 1)
    assert h.read("TC3.COUNT16.COUNT") == counted(t_start, t_sync) > want


def test_tc_continuous_read_synchronisation_reads_the_live_count_until_it_is_cleared():
    """DS40001882 30.10.2 READREQ.RCONT: with RCONT set and one RREQ, COUNT is synchronised automatically from then on,
    so each read returns the count at that read; RCONT cleared, COUNT keeps the value synchronised last."""
    h, t_start = tc3_counting()
    h.write("TC3.COUNT16.READREQ", RREQ | RCONT | ADDR_COUNT)
    h.advance_to(h.t_access + SYNC_TU + 1)
    for dt in (1e-3, 4e-3, 9e-3):
        h.advance(dt)
        assert h.read("TC3.COUNT16.COUNT") == counted(t_start, h.t_access)
    h.write("TC3.COUNT16.READREQ", ADDR_COUNT)
    frozen = counted(t_start, h.t_access)
    h.advance(6e-3)
    assert h.read("TC3.COUNT16.COUNT") == frozen


def test_a_tc_read_request_for_another_register_does_not_synchronise_count():
    """DS40001882 30.10.2 READREQ.ADDR: only COUNT and CCx can be read-synchronised; a request for CC0 or for another
    offset (INTFLAG's) still sets SYNCBUSY but leaves COUNT at the value of its last synchronisation (here none: 0)."""
    h, t_start = tc3_counting()
    h.advance(4e-3)
    for addr in (ADDR_CC0, ADDR_INTFLAG):
        h.write("TC3.COUNT16.READREQ", RREQ | addr)
        assert h.read("TC3.COUNT16.STATUS") & SYNCBUSY
        h.advance(1e-3)
        assert not h.read("TC3.COUNT16.STATUS") & SYNCBUSY
        assert counted(t_start, h.t_access) > 0
        assert h.read("TC3.COUNT16.COUNT") == 0
    assert h.read("TC3.COUNT16.CC[0]") == CC0


TC3_COUNT = 0x4200_2C00 + ADDR_COUNT
TARGET = 500  # counts of the 1 MHz clock: the loop below leaves after about 0.5 ms


def _count_poll_program() -> Program:
    """Reset: wait for FLAG, then poll TC3's COUNT in loop() until it reaches TARGET; SysTick's VAL when it left goes
    to RESULT."""

    def body(a: Asm) -> None:
        a.ldr_const(0, TC3_COUNT)
        a.ldr_const(4, TARGET)
        a.label("loop")  # while (TC3->COUNT16.COUNT.reg < TARGET) {}
        a.mem("ldrh", 1, 0)
        a._h(0x42A1, "cmp", "r1, r4")
        a.movs(1, 0)  # the count leaves no trace in the registers at the loop's head (MOVS keeps the carry)
        a.bcond(3, "loop", "bcc")
        leave_with_the_time(a)

    return _after_flag(body)


def _count_poll(ff: bool) -> int:
    h = Harness(program=_count_poll_program(), ff=ff)
    systick_free_running(h)
    bus_clock(h, "TC3")
    gclk_channel(h, GCLK_TCC2_TC3)  # GCLK0: 1 MHz
    h.write("TC3.COUNT16.CC[0]", CC0)
    h.advance(20e-6)
    h.write("TC3.COUNT16.CTRLA", MFRQ | ENABLE)
    h.advance(20e-6)
    h.write("TC3.COUNT16.READREQ", RREQ | RCONT | ADDR_COUNT)
    h.advance(20e-6)
    h.write(FLAG, 1)
    h.advance(3e-3)
    return _word(h, RESULT)


def test_a_loop_polling_a_continuously_synchronised_tc_count_leaves_at_the_same_cycle_fast_forwarded():
    """DS40001882 30.10.2 READREQ.RCONT: COUNT read live changes with time but by no event of the board's, so its read
    is activity and no pass of a loop() polling it is skipped: the loop leaves at the same cycle with fast-forwarding
    on as off (SysTick's VAL when it left). (A COUNT not synchronised continuously reads a constant: no activity.)"""
    on, off = _count_poll(True), _count_poll(False)
    assert off != 0
    assert on == off


TCC_PER = 59_999  # 60000 counts per period on the 32 kHz clock


def tcc0_counting() -> tuple[Harness, int]:
    """TCC0 in normal PWM on the 32 kHz clock, prescaler DIV1; returns when it starts counting from 0: when the enable
    has synchronised (31.6.2.1, SYNCBUSY.ENABLE)."""
    h = Harness()
    bus_clock(h, "TCC0")
    slow_generator(h)
    gclk_channel(h, GCLK_TCC0_TCC1, gen=2)
    h.write("TCC0.WAVE", 0x2)  # NPWM
    h.write("TCC0.PER", TCC_PER)
    h.advance(1e-3)
    h.write("TCC0.CTRLA", ENABLE)
    t_start = h.t_access + SYNC_TU
    h.advance(1e-3)
    assert h.tcc_info().running
    return h, t_start


def tcc_counted(t_start: int, t: int) -> int:
    return (t - t_start) // ULP_TICK % (TCC_PER + 1)


def test_a_tcc_count_read_without_readsync_returns_the_reset_value_while_the_counter_runs():
    """DS40001882 31.6.6 Synchronization and 31.8.3 CTRLBSET.CMD: COUNT is read-synchronised on demand, by the READSYNC
    command; without one, a read returns its reset value 0 however far the counter has run."""
    h, t_start = tcc0_counting()
    for dt in (2e-3, 7e-3, 31e-3):
        h.advance(dt)
        assert tcc_counted(t_start, h.now()) > 0
        assert h.read("TCC0.COUNT") == 0


def test_the_readsync_command_holds_syncbusy_ctrlb_then_count_reads_the_count_when_it_was_carried_out():
    """DS40001882 31.8.3 CTRLBSET.CMD = READSYNC, the command that synchronises COUNT for reading: it is written
    through CTRLB's synchronisation (SYNCBUSY.CTRLB set meanwhile) and reads back as zero once carried out;
    COUNT then reads the counter's value at that time, the same until the next command."""
    h, t_start = tcc0_counting()
    h.advance(3e-3)
    h.write("TCC0.CTRLBSET", CMD_READSYNC)
    t_sync = h.t_access + SYNC_TU
    assert h.read("TCC0.SYNCBUSY") & SYNCBUSY_CTRLB and h.t_access < t_sync
    assert h.read("TCC0.CTRLBSET") & 0xE0 == CMD_READSYNC, "not yet carried out"
    assert h.read("TCC0.COUNT") == 0
    h.advance_to(t_sync + 1)
    assert not h.read("TCC0.SYNCBUSY") & SYNCBUSY_CTRLB
    assert h.read("TCC0.CTRLBSET") & 0xE0 == 0
    want = tcc_counted(t_start, t_sync)
    assert want > 50
    assert h.read("TCC0.COUNT") == want
    h.advance(5e-3)
    assert h.read("TCC0.COUNT") == want, "no new command: the same value"
    h.write("TCC0.CTRLBSET", CMD_READSYNC)
    t_sync = h.t_access + SYNC_TU
    h.advance_to(t_sync + 1)
    assert h.read("TCC0.COUNT") == tcc_counted(t_start, t_sync) > want


def test_a_tc_read_request_written_as_its_high_byte_uses_the_address_written_before():
    """DS40001882 30.10.2 READREQ: ADDR (bits 4:0) and RREQ (bit 15) lie in different bytes; a byte write of RREQ
    (with RCONT) after ADDR was written synchronises COUNT, continuously, as the 16-bit write would."""
    h, t_start = tc3_counting()
    h.write("TC3.COUNT16.READREQ", ADDR_COUNT, size=1)
    h.write(h.address("TC3.COUNT16.READREQ")[0] + 1, (RREQ | RCONT) >> 8, size=1)
    h.advance(1e-3)
    assert h.read("TC3.COUNT16.COUNT") == counted(t_start, h.t_access) > 0
