"""Quadrature decoder and velocity window: exact counts on legal streams, every glitch counted."""

from hypothesis import given, settings, strategies as st

GRAY = [0b00, 0b01, 0b11, 0b10]   # counting up


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
            phase = (phase + 2) % 4            # both channels change: a missed edge
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
    lib.mc_quad_update(q, 0b101)   # 01 with a stray bit
    assert q.pos == 1 and q.errors == 0


@settings(max_examples=300, deadline=None)
@given(log2w=st.integers(0, 8), va=st.integers(-8, 8), vb=st.integers(-8, 8), n=st.integers(1, 600),
       a0=st.integers(-3000, 3000), b0=st.integers(-3000, 3000))
def test_velocity_window_difference(fw, log2w, va, vb, n, a0, b0):
    """dtheta[n] = theta[n] - theta[n-W] per angle (inputs clamped to +-2048), with the
    reset angles standing in before the first W ticks."""
    ffi, lib = fw
    clamp = lambda x: max(-2048, min(2048, x))
    vel = ffi.new("mc_vel_t*")
    lib.mc_vel_reset(vel, log2w, a0, b0)
    out = ffi.new("int32_t[2]")
    w = 1 << log2w
    hist = []
    for k in range(1, n + 1):
        th = (clamp(a0 + va * k), clamp(b0 + vb * k))
        hist.append(th)
        lib.mc_vel_update(vel, a0 + va * k, b0 + vb * k, out)
        past = hist[-1 - w] if len(hist) > w else (clamp(a0), clamp(b0))
        assert (out[0], out[1]) == (th[0] - past[0], th[1] - past[1])
