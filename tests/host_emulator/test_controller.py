"""Chunked output sampling (advance_many, many samples per C call) is bit-identical to the per-sample path, and
stops at the same sample with the same message when a run goes unstable."""

import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator import controller
from host_emulator.controller import run_solver
from host_emulator.models import STEPPERS, ModelOptions, NoiseOptions, NumericalInstability, Perturbation, make_model
from host_emulator.params import Params
from host_emulator.workbench.trackers import ProgressTracker

# edges off the 10 ms output grid, so chunks must not straddle them differently from the per-sample path
PERTS = [Perturbation(5, "alpha", 0.03, 0.0137, 0.0519), Perturbation(11, "beta", -0.02, 0.2031, 0.0402)]
NOISE = NoiseOptions(seed=3, band_spread=0.05, eta_spread=0.05, encoder_jitter_counts=0.4, encoder_glitch_prob=1e-3)


def per_sample(solver, n_out):
    """The reference: one advance() per output sample, state() copied after each."""
    t, a, b = [0.0], [], []
    a0, b0 = solver.state()
    a.append(a0)
    b.append(b0)
    for _ in range(n_out):
        solver.advance()
        x, y = solver.state()
        t.append(solver.t)
        a.append(x)
        b.append(y)
    return np.array(t), np.array(a), np.array(b)


def chunked(solver, n_out, sizes):
    """advance_many with the given chunk sizes (cycled) until n_out samples are done."""
    a0, b0 = solver.state()
    t, a, b = [np.zeros(1)], [a0[None]], [b0[None]]
    done, i = 0, 0
    while done < n_out:
        tt, aa, bb = solver.advance_many(min(sizes[i % len(sizes)], n_out - done))
        assert 1 <= len(tt) <= sizes[i % len(sizes)]
        t.append(tt)
        a.append(aa)
        b.append(bb)
        done += len(tt)
        i += 1
    return np.concatenate(t), np.concatenate(a), np.concatenate(b)


def same(r1, r2):
    for u, w in zip(r1, r2):
        assert u.shape == w.shape
        assert np.array_equal(u, w), np.abs(u - w).max()


@pytest.mark.parametrize("stepper", sorted(STEPPERS))
def test_lattice_chunked_is_bit_identical(stepper):
    p = Params(sigma=9 / 125)
    opts = ModelOptions(stepper=stepper, noise=NoiseOptions(seed=1, band_spread=0.05, eta_spread=0.05))
    n_out = 60
    ref_s = make_model("lattice", p, PERTS, opts).solver()
    ref = per_sample(ref_s, n_out)
    assert np.abs(ref[1]).max() > 1e-3  # the push moved something
    for sizes in ([256], [1, 7, 3, 50], [13]):
        s = make_model("lattice", p, PERTS, opts).solver()
        same(ref, chunked(s, n_out, sizes))
        assert np.array_equal(s.x, ref_s.x) and np.array_equal(s.v, ref_s.v)
        assert s.k == ref_s.k and s.t == ref_s.t
    # and through the controller (which chunks): the same recording as the per-sample loop
    res = run_solver(make_model("lattice", p, PERTS, opts).solver(), n_out * opts.dt_out)
    same(ref, (res.t, res.alpha, res.beta))


@pytest.mark.parametrize("via", ["firmware", "plant"])
def test_hil_chunked_is_bit_identical_with_noise_and_perturbations(via):
    """Encoder jitter and glitches on (the RNG sequence must match too), firmware commands at ticks inside
    output samples (the chunk splits there and that sample takes the per-sample path)."""
    p = Params()
    opts = ModelOptions(perturb_via=via, noise=NOISE)
    n_out = 40
    ref_s = make_model("hil", p, PERTS, opts).solver()
    ref = per_sample(ref_s, n_out)
    assert np.abs(ref[1]).max() > 1e-3
    for sizes in ([256], [5, 1, 9]):
        s = make_model("hil", p, PERTS, opts).solver()
        same(ref, chunked(s, n_out, sizes))
        assert np.array_equal(s.x, ref_s.x) and np.array_equal(s.v, ref_s.v)
        assert s.info() == ref_s.info() and s.faults() == ref_s.faults()
        assert int(s.h.rng) == int(ref_s.h.rng) and s.tick == ref_s.tick
    assert ref_s.info()["glitches_injected"] > 0
    res = run_solver(make_model("hil", p, PERTS, opts).solver(), n_out * opts.dt_out)
    same(ref, (res.t, res.alpha, res.beta))


def test_hil_chunks_split_at_firmware_commands():
    """A chunk never runs past a firmware command: the command's sample is a chunk of its own (or the end)."""
    opts = ModelOptions(perturb_via="firmware")
    s = make_model("hil", Params(), PERTS, opts).solver()
    t1, _, _ = s.advance_many(256)  # command at tick 27 (13.7 ms): samples ending at 10 ms only
    assert len(t1) == 1 and t1[-1] == pytest.approx(0.01)
    t2, _, _ = s.advance_many(256)  # the sample containing tick 27, alone
    assert len(t2) == 1
    t3, _, _ = s.advance_many(256)  # next command at tick 406 (203.1 ms): up to 200 ms
    assert t3[-1] == pytest.approx(0.2)


def unstable_lattice():
    """A symplectic-Euler lattice stepped at 3x its stable limit (as test_steppers does): it blows up."""
    m = make_model("lattice", Params(actuator_limit=False, band_scale=0.5), PERTS, ModelOptions())
    s = m.solver()
    s.nsub = max(1, int(s.dt_out / (3 * s.limit)))
    s.h = s.dt_out / s.nsub
    assert s.h > 2 * s.limit
    return s


def fail_per_sample(s, n):
    for k in range(n):
        try:
            s.advance()
        except NumericalInstability as e:
            return k, str(e)
    raise AssertionError("the run did not go unstable")


def test_lattice_unstable_run_stops_at_the_same_sample_with_the_same_time():
    k_fail, msg = fail_per_sample(unstable_lattice(), 2000)
    assert k_fail > 2  # it grows for a while first
    s = unstable_lattice()
    with pytest.raises(NumericalInstability) as ei:
        s.advance_many(2000)
    assert str(ei.value) == msg  # same cause and the failing sample's time
    t, a, b = ei.value.samples
    assert len(t) == k_fail and t[-1] == pytest.approx(k_fail * s.dt_out)
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    # through the controller: the samples before the failure reach the trackers, then the error propagates
    got = []

    class Keep(controller.Tracker):
        def sample(self, t, alpha, beta):
            got.append(t)

    with pytest.raises(NumericalInstability, match="at t = "):
        run_solver(unstable_lattice(), 2000 * s.dt_out, [Keep()])
    assert len(got) == k_fail + 1  # t = 0 and every completed sample


def unstable_hil():
    """The hil loop with one plant step per control tick at 100 Hz: far above the stable limit."""
    m = make_model("hil", Params(control_rate_hz=100), PERTS, ModelOptions())
    s = m.solver()
    s.h.substeps = s.substeps = 1
    assert s.h.tick_s > 2 * s.limit
    return s


def test_hil_unstable_run_stops_at_the_same_sample_with_the_same_time():
    k_fail, msg = fail_per_sample(unstable_hil(), 2000)
    s = unstable_hil()
    with pytest.raises(NumericalInstability) as ei:
        s.advance_many(2000)
    assert str(ei.value) == msg
    assert len(ei.value.samples[0]) == k_fail


def test_advance_many_rejects_a_bad_count():
    s = make_model("lattice", Params(cells=3), [], ModelOptions()).solver()
    with pytest.raises(ValueError, match="k_max"):
        s.advance_many(0)
    assert s.k == 0


@settings(max_examples=25, deadline=None)
@given(
    starts=st.lists(st.integers(0, 120), min_size=1, max_size=4),
    ticks=st.integers(1, 30),
    sizes=st.lists(st.integers(1, 12), min_size=1, max_size=4),
    seed=st.integers(0, 2**32 - 1),
)
def test_hil_chunking_property(starts, ticks, sizes, seed):
    """Any firmware command ticks (on or off the sample grid), any chunk sizes: the same trajectory, bit for bit,
    as the per-sample path (3 cells, 1 kHz control, 5 ticks per 5 ms sample)."""
    p = Params(cells=3, control_rate_hz=1000)
    perts = [
        Perturbation(1 + i % 3, "alpha" if i % 2 else "beta", 0.02, k / 1000, ticks / 1000)
        for i, k in enumerate(starts)
    ]
    opts = ModelOptions(
        perturb_via="firmware",
        dt_out=0.005,
        noise=NoiseOptions(seed=seed % 1000, encoder_jitter_counts=0.3, encoder_glitch_prob=1e-3),
    )
    n_out = 30
    ref_s = make_model("hil", p, perts, opts).solver()
    ref = per_sample(ref_s, n_out)
    s = make_model("hil", p, perts, opts).solver()
    same(ref, chunked(s, n_out, sizes))
    assert s.info() == ref_s.info() and int(s.h.rng) == int(ref_s.h.rng)


def test_progress_bar_reaches_the_end_with_chunks():
    bar = ProgressTracker(delay_s=0.0, file=io.StringIO(), disable=False)  # shown although the file is no terminal
    res = run_solver(
        make_model("hil", Params(cells=4), [Perturbation(2, "alpha", 0.03, 0.0137, 0.05)], ModelOptions()).solver(),
        1.0,
        [bar],
    )
    assert len(res.t) == 101 and bar.last == pytest.approx(1.0) and bar.bar.n == pytest.approx(1.0)


def test_sampled_c_calls_refuse_bad_arguments_and_change_nothing():
    m = make_model("lattice", Params(cells=3), [Perturbation(2, "alpha", 0.03, 0.0, 0.05)], ModelOptions())
    s = m.solver()
    ffi, lib = m.ffi, m.lib
    out = ffi.new("double[]", 6)
    done = ffi.new("int64_t *", -7)
    x0 = s.x.copy()
    for nsamp, dt_out in ((-1, 0.01), (1, 0.0), (1, float("nan"))):
        rc = lib.he_advance_sampled(m.plant, s.sid, s.h, s.nsub, dt_out, 0, nsamp, s._pt, s._px, s._pv, out, done)
        assert rc == lib.HE_ERR_ARG and done[0] == -7 and np.array_equal(s.x, x0)
    h = make_model("hil", Params(cells=3), [], ModelOptions()).solver()
    for rate, tpo in ((0, 1), (1000, 0)):
        rc = lib.he_hil_run_sampled(h.h, 0, rate, tpo, 1, h._pt, h._px, h._pv, out, done)
        assert rc == h.model.lib.HE_ERR_ARG and int(h.h.ticks) == 0


def test_progress_bar_is_off_without_a_terminal():
    """The default: tqdm's rule, a bar only on a TTY (never in a pipe, a log file or a test's captured stream)."""
    out = io.StringIO()
    bar = ProgressTracker(delay_s=0.0, file=out)
    run_solver(make_model("lattice", Params(cells=2), [], ModelOptions()).solver(), 0.1, [bar])
    assert bar.bar.disable and out.getvalue() == ""
