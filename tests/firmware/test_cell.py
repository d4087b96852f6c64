"""Cell tick: reference chain (reaction -> drive) within one LSB, perturbation, zeroing and latched faults."""

from hypothesis import given, settings
from hypothesis import strategies as st

from protocol.definition import LIMITS
from tests.firmware.reference import ObserverInt, drive_duty, reaction
from tests.firmware.test_reaction import law_dict

RIG = {
    "supply_mv": 9000,
    "vmax_mv": 5860,
    "kt_unm_per_v": 7500,
    "kv_mrad_per_vs": 49800,
    "pwm_top": 2400,
    "ctrl_rate_hz": 2000,
    "vel_window_log2": -1,
}


class Cell:
    """Thin driver of one mc_cell_t with hand-made decoder snapshots."""

    def __init__(self, fw, enable=True):
        self.ffi, self.lib = fw
        self.c = self.ffi.new("mc_cell_t*")
        self.lib.mc_cell_init(self.c)
        self.lib.mc_cell_enable(self.c, int(enable))
        self.sa = self.ffi.new("mc_quad_snap_t*")
        self.sb = self.ffi.new("mc_quad_snap_t*")

    def tick(self, a, b, err_a=0, err_b=0, sat=0):
        self.sa.pos, self.sa.errors, self.sa.saturated = a, err_a, sat
        self.sb.pos, self.sb.errors, self.sb.saturated = b, err_b, 0
        return self.lib.mc_cell_tick(self.c, self.sa, self.sb)

    def signed(self, i):
        o = self.c.out[i]
        return o.duty if o.dir else -o.duty


PATH = st.lists(st.tuples(st.integers(-3, 3), st.integers(-3, 3)), min_size=1, max_size=120)


@settings(max_examples=300, deadline=None)
@given(
    path=PATH,
    a0=st.integers(-300, 300),
    b0=st.integers(-300, 300),
    bemf=st.booleans(),
    pert=st.integers(-LIMITS["PERTURB_MAX_UNM"], LIMITS["PERTURB_MAX_UNM"]),
    pert_ticks=st.integers(0, 60),
    chain=st.integers(0, 1),
)
def test_tick_matches_reference_chain(fw, path, a0, b0, bemf, pert, pert_ticks, chain):
    cell = Cell(fw)
    lib = cell.lib
    lib.mc_cell_set_runaway(cell.c, 2048)
    lib.mc_cell_set_bemf(cell.c, int(bemf))
    assert lib.mc_cell_perturb(cell.c, chain, pert, pert_ticks) == lib.MC_OK
    law = law_dict(cell.c.law)
    # the observer restarts at rest from the angles held when compensation was switched on (0, 0)
    obs = [ObserverInt(0), ObserverInt(0)]
    a, b = a0, b0
    for k, (da, db) in enumerate(path):
        a, b = a + da, b + db
        assert cell.tick(a, b) == 0
        wa, wb = obs[0].step(a), obs[1].step(b)
        ra, rb = reaction(law, a, b)
        if k < pert_ticks:
            if chain == 0:
                ra += pert * 32
            else:
                rb += pert * 32
        for i, (tau, dth) in enumerate([(ra, wa), (rb, wb)]):
            ref = drive_duty(RIG, tau, dth, bemf, cell.c.drive.vel_log2)
            assert abs(cell.signed(i) - ref) <= 1, (k, i, cell.signed(i), ref)
            assert cell.c.out[i].enable == 1


def test_disabled_cell_drives_nothing(fw):
    cell = Cell(fw, enable=False)
    for a in (-500, -75, 0, 40, 75, 500):
        assert cell.tick(a, -a) == 0
        for i in (0, 1):
            assert cell.c.out[i].enable == 0 and cell.c.out[i].duty == 0
    assert cell.c.torque[0] != 0  # the law still runs (telemetry), the drive is off


def test_perturbation_lasts_exactly_its_ticks(fw):
    cell = Cell(fw)
    lib = cell.lib
    assert lib.mc_cell_perturb(cell.c, lib.MC_ALPHA, 10000, 5) == lib.MC_OK
    torques = []
    for _ in range(8):
        cell.tick(0, 0)
        torques.append(cell.c.torque[0])
    assert torques == [10000 * 32] * 5 + [0] * 3
    assert lib.mc_cell_perturb(cell.c, 2, 1000, 5) == lib.MC_ERR_RANGE
    assert lib.mc_cell_perturb(cell.c, 0, 131001, 5) == lib.MC_ERR_RANGE
    assert cell.c.pert_ticks == 0  # the rejected commands changed nothing


def test_zero_offsets(fw):
    cell = Cell(fw)
    lib = cell.lib
    lib.mc_cell_zero(cell.c, 1000, -2000)
    assert cell.tick(1010, -2030) == 0
    assert (cell.c.theta[0], cell.c.theta[1]) == (10, -30)
    lib.mc_cell_zero(cell.c, -(2**31), 2**31 - 1)  # extreme zeros: saturate, never wrap
    f = cell.tick(2**31 - 1, -(2**31))
    assert (cell.c.theta[0], cell.c.theta[1]) == (800, -800)  # held at the runaway limit
    assert f & lib.MC_FAULT_RUNAWAY_A and f & lib.MC_FAULT_RUNAWAY_B


@settings(max_examples=500, deadline=None)
@given(pos=st.integers(-(2**31), 2**31 - 1), zero=st.integers(-(2**31), 2**31 - 1), lim=st.integers(1, 2048))
def test_angle_is_exact_difference_or_limited_with_fault(fw, pos, zero, lim):
    cell = Cell(fw)
    lib = cell.lib
    assert lib.mc_cell_set_runaway(cell.c, lim) == lib.MC_OK
    lib.mc_cell_zero(cell.c, zero, 0)
    f = cell.tick(pos, 0)
    true = pos - zero  # exact, in Python integers
    if abs(true) <= lim:
        assert cell.c.theta[0] == true and not f & lib.MC_FAULT_RUNAWAY_A
    else:
        assert cell.c.theta[0] == (lim if true > 0 else -lim) and f & lib.MC_FAULT_RUNAWAY_A


def test_runaway_latches_until_cleared(fw):
    cell = Cell(fw)
    lib = cell.lib
    assert cell.tick(801, 0) & lib.MC_FAULT_RUNAWAY_A
    assert cell.c.out[0].enable == 0 and cell.c.out[1].enable == 0
    assert cell.tick(0, 0) & lib.MC_FAULT_RUNAWAY_A  # latched
    assert cell.c.out[0].duty == 0
    lib.mc_cell_clear_faults(cell.c)
    assert cell.tick(0, 5) == 0 and cell.c.out[0].enable == 1
    assert cell.tick(0, -801) & lib.MC_FAULT_RUNAWAY_B
    assert lib.mc_cell_set_runaway(cell.c, 0) == lib.MC_ERR_RANGE
    assert lib.mc_cell_set_runaway(cell.c, 2049) == lib.MC_ERR_RANGE
    assert cell.c.runaway_counts == 800


def test_encoder_burst_faults_isolated_glitches_do_not(fw):
    cell = Cell(fw)
    lib = cell.lib
    errs = 0
    for k in range(3000):  # one glitch every 300 ticks: counted, tolerated
        if k % 300 == 0:
            errs += 1
        assert cell.tick(0, 0, err_a=errs) == 0
    for _ in range(9):  # nine in a row: a burst
        errs += 1
        f = cell.tick(0, 0, err_a=errs)
    assert f & lib.MC_FAULT_ENCODER_A and not f & lib.MC_FAULT_ENCODER_B
    assert cell.c.out[0].enable == 0


def test_error_counter_wrap_is_not_a_burst(fw):
    cell = Cell(fw)
    cell.c.err_last[0] = 2**32 - 1
    assert cell.tick(0, 0, err_a=0) == 0  # one new error across the wrap


def test_saturated_decoder_and_driver_fault_latch(fw):
    cell = Cell(fw)
    lib = cell.lib
    assert cell.tick(0, 0, sat=1) & lib.MC_FAULT_SATURATED
    lib.mc_cell_clear_faults(cell.c)
    lib.mc_cell_report_driver_fault(cell.c)
    assert cell.tick(0, 0) & lib.MC_FAULT_DRIVER
    assert cell.c.out[0].enable == 0


def test_rejected_drive_config_keeps_running_drive_and_limit(fw):
    cell = Cell(fw)
    ffi, lib = cell.ffi, cell.lib
    lib.mc_drive_set_limit(ffi.addressof(cell.c, "drive"), 500)
    before = bytes(ffi.buffer(ffi.addressof(cell.c, "drive")))
    cfg = ffi.new("mc_drive_config_t*")
    lib.mc_drive_default_config(cfg)
    cfg.pwm_top = 100000
    assert lib.mc_cell_set_drive(cell.c, cfg) == lib.MC_ERR_CONFIG
    assert bytes(ffi.buffer(ffi.addressof(cell.c, "drive"))) == before
    cfg.pwm_top = 1023
    assert lib.mc_cell_set_drive(cell.c, cfg) == lib.MC_OK
    assert cell.c.drive.duty_limit == 500 and cell.c.drive.pwm_top == 1023
