"""The Arduino glue (src/) run on the host on register stand-ins: sampling, bounded I2C, recovery, watchdog, USB."""

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent / "glue_host"
INC = ["-I", str(ROOT / "tests/stubs/arduino"), "-I", str(HERE), "-I", str(ROOT / "lib/metacell/src")]
INC += ["-I", str(ROOT / "src"), "-I", str(ROOT / "src/cell")]
TXN_TIMEOUT_US = 1500  # what the drivers pass as txn.timeout_us
SYNC_US = 50  # primary_hw.cpp: bound of the STOP's sync wait
RECOVERY_US = 22 * 5 + 20  # 9 pulses + STOP at 5 us half periods, plus the stand-in clock's 1 us per read

pytestmark = pytest.mark.skipif(not (shutil.which("g++") and shutil.which("gcc")), reason="no host C/C++ compiler")


def _run(cmd):
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    return res.stdout


@pytest.fixture(scope="module")
def programs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("glue")
    objs = []
    for c in sorted((ROOT / "lib/metacell/src").rglob("*.c")):
        o = tmp / (c.stem + ".o")
        _run(["gcc", "-std=c99", "-O1", "-c", "-I", str(ROOT / "lib/metacell/src"), str(c), "-o", str(o)])
        objs.append(str(o))
    common = [str(HERE / "stub_impl.cpp"), str(ROOT / "src/common/samd21_sys.cpp"), str(ROOT / "src/common/mc_ident.c")]
    flags = ["g++", "-std=gnu++11", "-O1", "-Wall", "-Wextra", "-Werror", *INC]
    primary, cell = tmp / "primary", tmp / "cell"
    _run(
        [
            *flags,
            str(HERE / "primary_driver.cpp"),
            str(ROOT / "src/primary/primary_hw.cpp"),
            *common,
            *objs,
            "-o",
            str(primary),
        ]
    )
    _run(
        [
            *flags,
            "-DMC_CELL_INDEX=1",
            "-DMC_CELL_ADDR=0x10",
            str(HERE / "cell_driver.cpp"),
            str(ROOT / "src/cell/samd21_hw.cpp"),
        ]
        + common
        + objs
        + ["-o", str(cell)]
    )
    return primary, cell


def results(exe, *args) -> dict:
    out = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=600, check=True).stdout
    return dict(line.split("=", 1) for line in out.splitlines())


def test_encoder_pins_are_sampled_continuously(programs):
    """PA05, PA06, PA07 and PB09 are read through the IOBUS: PORT CTRL must sample them continuously."""
    r = results(programs[1])
    assert int(r["setup_err"]) == 0
    # pins from the variant table (D7 = PB09, D8 = PA07, D9 = PA05, D10 = PA06), not from the glue's constants
    assert int(r["ctrl_pa"], 16) == (1 << 5) | (1 << 6) | (1 << 7)
    assert int(r["ctrl_pb"], 16) == 1 << 9
    assert int(r["attached"], 16) == sum(1 << p for p in (7, 8, 9, 10))


@pytest.mark.parametrize("role", ["primary", "cell"])
def test_a_host_that_never_stops_sending_does_not_starve_the_loop(programs, role):
    """Each pass of loop() handles at most one USB packet of input, then serves the bus (primary: one poll per
    pass; cell: the watchdog fed after each tick). Without the cap the first pass never ends (the stand-in gives up
    after 100,000 reads and exits 3)."""
    exe = programs[0] if role == "primary" else programs[1]
    res = subprocess.run([str(exe), "flood"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and "starved" not in res.stdout, res.stdout
    r = dict(line.split("=", 1) for line in res.stdout.splitlines())
    assert 0 < int(r["most_reads_per_pass"]) <= 64
    if role == "primary":
        assert int(r["polls"]) >= 5
    else:
        assert int(r["passes_fed"]) == 5


def test_cell_receive_callback_reads_no_more_than_its_buffer(programs):
    """The SERCOM2 interrupt's work stays bounded whatever a babbling bus left in Wire's 256-byte buffer: the callback
    reads its 32 bytes (the core clears the rest after it) and the write is handed on as 32 bytes (rejected later as
    LENGTH)."""
    r = results(programs[1], "babble")
    assert (int(r["wire_reads"]), int(r["mailbox_len"])) == (32, 32)


def test_an_edge_during_encoder_start_up_is_not_lost(programs):
    """Channel B changes while start-up attaches the pins; then A changes. The decoder must have started from the
    level after B's edge, so A's edge is one legal count; started from the level before it, A's edge would look
    like both channels changing at once (an illegal transition, a count lost)."""
    r = results(programs[1], "startup_edge")
    assert int(r["setup_err"]) == 0 and int(r["irq_off"]) == 0  # interrupts on again after start-up
    assert int(r["errors"]) == 0
    assert abs(int(r["pos"]) - int(r["pos_at_start"])) == 1


def test_cell_interrupt_priorities_put_usb_below_encoders_tick_and_bus(programs):
    """The core leaves USB and the EIC at 0 and Wire at 3; the cell's map, set last in setup(), must win."""
    r = results(programs[1])
    prio = {k: int(r[f"prio_{k}"]) for k in ("eic", "tc3", "sercom2", "usb")}
    assert prio == {"eic": 0, "tc3": 1, "sercom2": 2, "usb": 3}


def test_cell_watchdog_is_fed_only_when_the_tick_ran(programs):
    r = results(programs[1])
    # nothing fed while the tick stands still, one feed after a tick, none again for the same tick
    assert (int(r["wdt_fed_no_tick"]), int(r["wdt_fed"]), int(r["wdt_fed_same_tick"])) == (0, 1, 0)


def test_cell_with_a_start_up_error_keeps_its_watchdog_fed(programs):
    """The tick never starts after a start-up error (drive off): the board must keep answering, not reset."""
    r = results(programs[1], "pins_err")
    assert int(r["setup_err"]) == 1  # SETUP_ERR_PINS
    assert int(r["wdt_fed_without_tick"]) == 1


def test_cell_watchdog_and_boot_block(programs):
    from metacell_tools.rigtools import proto

    r = results(programs[1])
    assert (int(r["wdt_enabled"]), int(r["wdt_per"])) == (1, 7)  # PER 0x7 = 1024 clocks
    boot = bytes.fromhex(r["boot"])
    d = proto.decode_block("BOOT", boot)
    assert proto.crc8(boot[:-1]) == boot[-1]
    assert d["tag"] == (proto.D.PROTO_VERSION << 4) | proto.D.BLOCKS["BOOT"]["id"]
    assert (d["addr"], d["reset_cause"], d["wdt_ms"]) == (0x10, 1 << proto.D.RESET_CAUSE["WDT"], 1000)
    assert (d["fault_exc"], d["fault_pc"]) == (0, 0)


def test_cell_fault_sleeps_the_drivers_and_is_reported_once_after_the_reboot(programs):
    """HardFault with the drive on: nSLEEP cleared before the reset, the next BOOT block says SYST + FAULT with the
    exception and the stacked PC; the boot after that, and a power-on with an intact-looking record, say no FAULT."""
    from metacell_tools.rigtools import proto

    rc = proto.D.RESET_CAUSE
    r = results(programs[1], "fault")
    assert int(r["nsleep_set_before"]) == 1
    assert (int(r["resets"]), int(r["nsleep_cleared"])) == (1, 1)
    boots = {}
    for key in ("boot_after_fault", "boot_after_next", "boot_after_por"):
        raw = bytes.fromhex(r[key])
        assert proto.crc8(raw[:-1]) == raw[-1]
        boots[key] = proto.decode_block("BOOT", raw)
    d = boots["boot_after_fault"]
    assert (d["reset_cause"], d["fault_exc"], d["fault_pc"]) == ((1 << rc["SYST"]) | (1 << rc["FAULT"]), 3, 0x3A5C)
    d = boots["boot_after_next"]
    assert (d["reset_cause"], d["fault_exc"], d["fault_pc"]) == (1 << rc["SYST"], 0, 0)
    d = boots["boot_after_por"]
    assert d["reset_cause"] == 1 << rc["POR"] and d["fault_exc"] == 0


def test_primary_watchdog_is_fed_only_while_polling_moves(programs):
    r = results(programs[0], "stalled_schedule")
    assert (int(r["fed_moving"]), int(r["fed_stalled"])) == (1, 0)


def test_primary_fault_is_reported_in_its_health_frame(programs):
    from metacell_tools.rigtools import proto

    rc = proto.D.RESET_CAUSE
    r = results(programs[0], "fault")
    assert int(r["resets"]) == 1
    assert int(r["reset_cause"]) == (1 << rc["SYST"]) | (1 << rc["FAULT"])


@pytest.mark.parametrize(
    "scenario,status",
    [("stuck_read", 3), ("stuck_write", 3), ("sync_stuck", 3), ("arblost_read", 4), ("buserr_mid_read", 4)],
)
def test_a_broken_bus_never_hangs_the_primary(programs, scenario, status):
    """Every wait ends by the deadline (timeout) or at the error; then a recovery: open-drain clocks and a STOP."""
    r = results(programs[0], scenario)
    assert int(r["status"]) == status  # MC_I2C_TIMEOUT = 3, MC_I2C_BUS_ERROR = 4
    assert int(r["len"]) == 0
    assert int(r["elapsed_us"]) <= TXN_TIMEOUT_US + SYNC_US + RECOVERY_US
    assert int(r["resets"]) == 1
    assert int(r["driven_high"]) == 0  # SCL/SDA only ever pulled low or released
    assert int(r["scl_falls"]) == 10  # 9 recovery clocks + the low phase before the STOP
    assert (int(r["stops"]), int(r["starts"])) == (1, 0)
    assert r["lines"].endswith("1023")  # SCL low/SDA high, SDA low, SCL up, SDA up: a STOP


@pytest.mark.parametrize("hz", [400000, 100000])
def test_primary_leaves_the_smbus_timeouts_off(programs, hz):
    """LOWTOUTEN needs a slow clock nothing enables (it could never fire); INACTOUT's longest setting (20-21 SCL
    periods) is shorter than a cell's worst clock stretch at 400 kHz and would declare the bus idle mid-transaction.
    The transaction deadline and the bus recovery cover both."""
    r = results(programs[0], "begin")
    assert (int(r[f"inactout_{hz}"]), int(r[f"lowtouten_{hz}"]), int(r[f"enabled_{hz}"])) == (0, 0, 1)


# UM10204 rev. 7 (I2C-bus specification), tables 10 and 11: f_SCL max, t_LOW min, t_HIGH min, t_r max (s)
I2C_SPEC = {400000: (400e3, 1.3e-6, 0.6e-6, 300e-9), 100000: (100e3, 4.7e-6, 4.0e-6, 1000e-9)}
F_GCLK = 48e6


@pytest.mark.parametrize("hz", sorted(I2C_SPEC))
def test_primary_scl_timing_meets_the_i2c_spec_for_any_allowed_rise_time(programs, hz):
    """DS40001882 (SERCOM I2C clock generation): T_LOW = (BAUDLOW + 5) / f_GCLK, T_HIGH = (BAUD + 5) / f_GCLK,
    f_SCL = f_GCLK / (10 + BAUD + BAUDLOW + f_GCLK t_r). The core's BAUD 52 (BAUDLOW 0) gives T_LOW 1.19 us at
    400 kHz, under the 1.3 us minimum."""
    f_max, t_low, t_high, t_r_max = I2C_SPEC[hz]
    r = results(programs[0], "begin")
    baud, baudlow = int(r[f"baud_{hz}"]), int(r[f"baudlow_{hz}"])
    assert baudlow > 0  # 0 would make the low time equal the high time (the core's choice)
    assert (baudlow + 5) / F_GCLK >= t_low
    assert (baud + 5) / F_GCLK >= t_high
    assert F_GCLK / (10 + baud + baudlow) <= f_max  # even with an instant rise
    assert F_GCLK / (10 + baud + baudlow + F_GCLK * t_r_max) >= 0.85 * f_max  # and not much slower at the slowest
    assert int(r[f"sdahold_{hz}"]) == 2  # 300-600 ns


def test_cell_i2c_secondary_holds_sda_like_the_primary(programs):
    r = results(programs[1])
    assert (int(r["i2cs_sdahold"]), int(r["i2cs_enabled"]), int(r["i2cs_mode"])) == (2, 1, 4)


@pytest.mark.parametrize("scenario,status,n", [("ok_read", 0, 23), ("nack_read", 1, 0), ("ok_write", 0, 0)])
def test_good_transactions(programs, scenario, status, n):
    r = results(programs[0], scenario)
    assert (int(r["status"]), int(r["len"]), int(r["resets"])) == (status, n, 0)
    if scenario == "ok_read":
        assert int(r["byte0"]) == 0x5A and int(r["acknack"]) == 1  # last byte NACKed


def test_primary_counts_usb_loss_and_starts_sessions(programs):
    r = results(programs[0], "main")
    assert (int(r["wdt_enabled"]), int(r["wdt_per"]), int(r["wdt_fed"])) == (1, 7, 1)
    assert int(r["reset_cause"]) == 0x20  # RCAUSE.WDT read at boot
    assert int(r["open"]) == 1 and int(r["sent"]) > 0
    # the host stopped reading: every byte offered that never reached it is counted, none silently; that includes
    # the packet the core zeroed when its wait timed out, which the write before had reported as sent
    assert int(r["usb_zeroed"]) > 0
    assert int(r["usb_lost"]) == int(r["usb_tried"]) - int(r["usb_delivered"]) > 0
    assert int(r["usb_fail"]) > 0
    assert int(r["max_write"]) <= 64  # one USB packet per write: all or nothing
    assert int(r["open_after_close"]) == 0  # DTR dropped: mc_link_session closed the channel
