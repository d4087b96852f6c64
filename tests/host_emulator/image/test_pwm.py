"""The shipped cell image's PWM through the waveform path: where the waveform cannot matter (20 kHz, one whole PWM
period per 50 us plant window) it agrees with the mean-duty path; the tier reports the documented 20 kHz."""

from __future__ import annotations

import numpy as np
import pytest

from host_emulator.image import model as image_model
from host_emulator.image.world import MOTOR_TAU_S, WorldConfig
from host_emulator.models import ConfigError, make_model
from host_emulator.params import Params
from host_emulator.scene import load_scene

from .conftest import configured
from .test_world import _run_traced

pytestmark = pytest.mark.slow

COUNT_RAD = 2 * np.pi / 400  # one encoder count: what the firmware sees of an angle


@pytest.mark.parametrize("alpha,beta", [(37, -12), (250, -399)])
def test_a_steady_drive_gives_the_motors_the_same_voltage_on_both_paths(images, alpha, beta):
    """Encoders turned to fixed counts, the plant at rest: the duty stays put, and every 50 us window holds one whole
    20 kHz period, so the waveform path's high time is CC ticks per window, the mean path's CC / (PER + 1) of the
    window: the same voltage (to rounding) on both motors, with the electrical model too (its periodic steady state
    has the mean current of the mean duty)."""
    seen = {}
    for name, cfg in (
        ("mean", WorldConfig()),
        ("waveform", WorldConfig(pwm="waveform")),
        ("electrical", WorldConfig(pwm="waveform", motor_tau_s=MOTOR_TAU_S)),
    ):
        w, lap = configured(images, 1, cfg, start_plant=False)
        t = w.t + 0.001
        for chain, n in (("alpha", alpha), ("beta", beta)):
            w.spin(1, chain, 20000.0 * np.sign(n), t, t + abs(n) / 20000.0 - 1e-9)
        lap.pump(0.03)
        seen[name] = [w.motor(1, ch) for ch in (0, 1)]
        i = w.tcc_info(w.boards[0].index, 0)
        assert w.tu_hz / i.period_tu == 48e6 / Params().pwm_top == 20000.0
    for ch in (0, 1):
        volt, awake = seen["mean"][ch]
        assert awake == 1.0 and abs(volt) > 0.1
        assert seen["waveform"][ch] == pytest.approx((volt, awake), rel=1e-12, abs=1e-12)
        assert seen["electrical"][ch] == pytest.approx((volt, awake), rel=1e-9, abs=1e-9)


def test_a_push_moves_the_lattice_alike_on_both_paths(images):
    """Three cells, a push on cell 2, 0.25 s of motion (test_world's run). The paths differ only in the window holding
    each duty change (at every 500 us tick): the waveform's high part sits at the start of each PWM cycle, so the
    change's effect moves by less than one 50 us PWM period, and the moves do not add up (the high time over whole
    cycles is the same on both). So the angles may differ by the effect of shifting every duty step by under a tenth
    of a tick: less than a tenth of the motion, and less than a quarter of an encoder count, the firmware's own
    resolution (measured: 2.4 % of the motion, 0.07 count; 0.5 %, 0.014 count with the electrical model)."""
    _, x_mean, *_ = _run_traced(images, WorldConfig())
    _, x_wave, *_ = _run_traced(images, WorldConfig(pwm="waveform"))
    _, x_tau, *_ = _run_traced(images, WorldConfig(pwm="waveform", motor_tau_s=MOTOR_TAU_S))
    moved = np.max(np.abs(x_mean))
    assert moved > 2 * COUNT_RAD  # the push moved the lattice
    for x in (x_wave, x_tau):
        assert np.max(np.abs(x - x_mean)) < min(0.1 * moved, 0.25 * COUNT_RAD)


def test_a_scene_asks_for_the_waveform_and_the_electrical_model(images, monkeypatch):
    """`[model_options.image]` pwm and motor_inductance reach the world's configuration (the estimate's L / R);
    the electrical model without the waveform path is refused when the scene is read, in one line naming the key."""
    seen = {}

    class Booted(Exception):
        pass

    def world(*args, config, **kw):
        seen["config"] = config
        raise Booted

    monkeypatch.setattr(image_model, "World", world)
    s = load_scene("default", ["model=image", "model_options.image.pwm=waveform"])
    s2 = load_scene(
        "default", ["model=image", "model_options.image.pwm=waveform", "model_options.image.motor_inductance=true"]
    )
    for scene, tau in ((s, 0.0), (s2, MOTOR_TAU_S)):
        with pytest.raises(Booted):
            make_model("image", scene.params, options=scene.options).solver()
        assert (seen["config"].pwm, seen["config"].motor_tau_s) == ("waveform", tau)
    assert MOTOR_TAU_S == pytest.approx(100e-6 / (12 / 4.3))
    assert load_scene("default", ["model=image"]).options.image.pwm == "mean"
    with pytest.raises(ConfigError, match=r"^model_options.image.motor_inductance = true: needs .*pwm = \"waveform\"$"):
        load_scene("default", ["model=image", "model_options.image.motor_inductance=true"])
    with pytest.raises(ConfigError, match=r"model_options.image.pwm = 'edges': expected one of mean, waveform"):
        load_scene("default", ["model=image", "model_options.image.pwm=edges"])


def test_the_waveform_and_electrical_paths_do_not_depend_on_the_schedule(images):
    """As on the mean path (test_world.py): fast-forwarding off, and two threads in rounds of 20 us, give every board
    the same trace and the plant the same state, to the bit (the motors' pieces are merged per window, so where the
    integration was split does not show)."""
    base = dict(pwm="waveform", motor_tau_s=MOTOR_TAU_S)
    ref_traces, ref_x, *_ = _run_traced(images, WorldConfig(**base))
    for cfg in (WorldConfig(ff=False, **base), WorldConfig(threads=2, round_s=20e-6, **base)):
        traces, x, *_ = _run_traced(images, cfg)
        assert traces == ref_traces
        assert np.array_equal(x, ref_x)
