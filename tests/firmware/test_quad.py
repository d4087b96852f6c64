"""Quadrature decoder (exact counts on legal streams, every glitch counted) and velocity observer."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.firmware.reference import ObserverFloat, ObserverInt

GRAY = [0b00, 0b01, 0b11, 0b10]  # counting up


def new_quad(ffi, lib, ab=0):
    q = ffi.new("mc_quad_t*")
    lib.mc_quad_init(q, ab)
    return q


# an event: +1/-1 legal step, 0 = re-sample without change (bounce), 2 = illegal jump
EVENTS = st.lists(st.sampled_from([1, -1, 0, 2]), min_size=1, max_size=400)


@settings(max_examples=600, deadline=None)
@given(events=EVENTS, start=st.integers(0, 3))
def test_counts_equal_net_legal_steps_and_glitches_are_counted(fw, events, start):
    ffi, lib = fw
    phase = start
    q = new_quad(ffi, lib, GRAY[phase])
    expect_pos = 0
    expect_err = 0
    for e in events:
        if e == 2:
            phase = (phase + 2) % 4  # both channels change: a missed edge
            expect_err += 1
        else:
            phase = (phase + e) % 4
            expect_pos += e
        lib.mc_quad_update(q, GRAY[phase])
    snap = ffi.new("mc_quad_snap_t*")
    lib.mc_quad_snapshot(q, snap)
    assert snap.pos == expect_pos
    assert snap.errors == expect_err
    assert snap.saturated == 0


@settings(max_examples=200, deadline=None)
@given(steps=st.integers(1, 50), up=st.booleans())
def test_position_saturates_never_wraps(fw, steps, up):
    ffi, lib = fw
    q = new_quad(ffi, lib, 0)
    lim = 2**31 - 1 if up else -(2**31)
    lib.mc_quad_set_pos(q, lim - (3 if up else -3))
    phase = 0
    for _ in range(steps):
        phase = (phase + (1 if up else -1)) % 4
        lib.mc_quad_update(q, GRAY[phase])
    if steps > 3:
        assert q.pos == lim and q.saturated == 1
    else:
        assert q.pos == lim - (3 - steps if up else -(3 - steps))
    # moving back out of the limit counts normally again
    before = q.pos
    phase = (phase + (-1 if up else 1)) % 4
    lib.mc_quad_update(q, GRAY[phase])
    assert q.pos == before + (-1 if up else 1)


def test_upper_bits_of_sample_are_ignored(fw):
    ffi, lib = fw
    q = new_quad(ffi, lib, 0)
    lib.mc_quad_update(q, 0b101)  # 01 with a stray bit
    assert q.pos == 1 and q.errors == 0


THETA = st.integers(-3000, 3000)


@settings(max_examples=300, deadline=None)
@given(
    a0=THETA, b0=THETA, steps=st.lists(st.tuples(st.integers(-40, 40), st.integers(-40, 40)), min_size=1, max_size=300)
)
def test_velocity_observer_matches_float_reference(fw, a0, b0, steps):
    """The fixed-point observer (Q16 states, floor shifts) stays within one output LSB
    (1/64 count/tick) of the real-valued observer, inputs clamped to +-2048."""
    ffi, lib = fw

    def clamp(x):
        return max(-2048, min(2048, x))

    vel = ffi.new("mc_vel_t*")
    lib.mc_vel_reset(vel, a0, b0)
    out = ffi.new("int32_t[2]")
    refs = [ObserverFloat(clamp(a0)), ObserverFloat(clamp(b0))]
    a, b = a0, b0
    for da, db in steps:
        a, b = a + da, b + db
        lib.mc_vel_update(vel, a, b, out)
        for i, th in enumerate((a, b)):
            r = min(max(refs[i].step(clamp(th)) * 64, -4096), 4095)
            assert abs(out[i] - r) <= 1.01, (i, out[i], r)


@settings(max_examples=200, deadline=None)
@given(a0=THETA, b0=THETA, path=st.lists(st.tuples(THETA, THETA), min_size=1, max_size=200))
def test_velocity_observer_bit_exact_and_bounded_for_any_jumps(fw, a0, b0, path):
    """Arbitrary angle jumps (the worst case of the range proof): the integer model is
    matched bit for bit and the output never leaves [-4096, 4095]."""
    ffi, lib = fw
    vel = ffi.new("mc_vel_t*")
    lib.mc_vel_reset(vel, a0, b0)
    out = ffi.new("int32_t[2]")
    refs = [ObserverInt(a0), ObserverInt(b0)]
    for a, b in path:
        lib.mc_vel_update(vel, a, b, out)
        assert (out[0], out[1]) == (refs[0].step(a), refs[1].step(b))
        assert -4096 <= out[0] <= 4095 and -4096 <= out[1] <= 4095


def test_velocity_observer_tracks_a_ramp_without_lag_error(fw):
    """Type-2 loop: a constant velocity is estimated exactly once the transient is gone."""
    ffi, lib = fw
    vel = ffi.new("mc_vel_t*")
    lib.mc_vel_reset(vel, -1000, 1000)
    out = ffi.new("int32_t[2]")
    for k in range(1, 200):
        lib.mc_vel_update(vel, -1000 + 5 * k, 1000 - 3 * k, out)
    assert (out[0], out[1]) == (5 * 64, -3 * 64)


def test_velocity_observer_lag_at_the_long_wave_oscillation(fw):
    """A 34.5 Hz sine at 2 kHz (the 14/125 long-wave mode): the estimate, against the
    velocity half a tick later (when the command acts), is within 10 % and 5 degrees."""
    ffi, lib = fw
    vel = ffi.new("mc_vel_t*")
    lib.mc_vel_reset(vel, 0, 0)
    out = ffi.new("int32_t[2]")
    w = 2 * np.pi * 34.5 / 2000
    n = np.arange(4000)
    th = np.round(150 * np.sin(w * n)).astype(int)  # 16 counts/tick peak
    est = []
    for t in th:
        lib.mc_vel_update(vel, int(t), 0, out)
        est.append(out[0] / 64)
    est = np.array(est[1000:])
    true = 150 * w * np.cos(w * (n[1000:] + 0.5))
    ph = np.exp(1j * w * n[1000:])
    r = np.vdot(ph, est) / np.vdot(ph, true)
    assert abs(abs(r) - 1) < 0.10 and abs(np.degrees(np.angle(r))) < 5
