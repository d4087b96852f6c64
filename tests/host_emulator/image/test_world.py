"""The image tier's world: what fast-forwarding, the schedule and threads may not change, and the flashed cell's
drive outputs against the control library's own commands for the same encoder inputs."""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
import pytest

from host_emulator import firmware
from host_emulator.image.world import WorldConfig
from host_emulator.models.hil import firmware_config
from host_emulator.params import Params
from protocol import wire

from .conftest import configured

pytestmark = pytest.mark.slow


def _run_traced(images, config: WorldConfig) -> tuple[dict[str, str], np.ndarray, dict, dict, dict]:
    """Three cells and the primary configured, a push on cell 2, 0.25 s of motion: every board's change of state
    (trace bit 5: each register access that changed something, each exception entry and return, with its time)
    hashed per board, the plant's final state, the boards' counters, the registers each board wrote, and each
    board's fast-forward (probes of passes that read the time, passes and cycles skipped)."""
    w, lap = configured(images, 3, config)
    w.trace(32, (1 << len(w.boards)) - 1)
    lap.seq = (lap.seq + 1) & 0xFF
    lap.send(wire.cmd_frame_id(2), wire.cmd_data("PERTURB", lap.seq, chain=0, torque=30000, ticks=100))
    digests = {b.name: hashlib.sha256() for b in w.boards}
    lines = dict.fromkeys(digests, 0)
    for _ in range(25):
        lap.pump(0.01)
        for n in w.take_notes():
            if n.startswith("chg "):
                name = " ".join(n.split(" ")[2:4]) if n.split(" ")[2] == "cell" else n.split(" ")[2]
                digests[name].update(n.encode())
                lines[name] += 1
    infos = {b.name: w.info(b.index) for b in w.boards}
    counters = {k: int(i.cycles) for k, i in infos.items()}
    written = {b.name: {r for r, _, n in w.touched(b.index) if n} for b in w.boards}
    ff = {k: (int(i.ff_probes), int(i.ff_passes_skipped), int(i.ff_cycles_skipped)) for k, i in infos.items()}
    traces = {k: f"{h.hexdigest()[:16]}/{lines[k]}" for k, h in digests.items()}
    return traces, w.x.copy(), counters, written, ff


@pytest.fixture(scope="module")
def reference(images):
    return _run_traced(images, WorldConfig())


@pytest.mark.parametrize(
    "config",
    [
        pytest.param(WorldConfig(ff=False), id="no-fast-forward"),
        pytest.param(WorldConfig(round_s=2.6e-6), id="rounds-of-one-bit"),
        pytest.param(WorldConfig(threads=2, round_s=20e-6), id="two-threads"),
        pytest.param(WorldConfig(ff_timed=False), id="timed-passes-run"),
    ],
)
def test_fast_forward_schedule_and_threads_change_nothing(images, reference, config):
    traces, x, cycles, _, ff = _run_traced(images, config)
    ref_traces, ref_x, ref_cycles, _, ref_ff = reference
    assert all(int(v.split("/")[1]) > 100 for v in ref_traces.values()), ref_traces  # every board did things
    assert traces == ref_traces
    assert np.array_equal(x, ref_x)  # bit for bit: the plant saw the same drive
    assert np.any(ref_x != 0)  # the push moved it
    if config.ff:
        assert cycles == ref_cycles
    if not config.ff_timed:  # the reference's primary probed and skipped its waits on the bus, this one never
        assert ref_ff["primary"][0] > 10 and ref_ff["primary"][1] > ff["primary"][1], (ff, ref_ff)
        assert ff["primary"][0] == 0
        # a slave holding SCL and letting go are quiet steps (csrc/link_i2c_bus.c): a probe spans them, and most of
        # the primary's waits are skipped (0.44 of its cycles; 0.30 when each of them ends the probes)
        assert ref_ff["primary"][2] > 0.38 * ref_cycles["primary"], (ref_ff, ref_cycles)


def test_every_block_costed_from_the_flash_bytes_changes_nothing(images, reference, monkeypatch):
    """The boards loaded without their ELF's cycle tables: the decoder (csrc/sam_cost.c) costs every block from the
    flash bytes, with the same times to the cycle."""
    from host_emulator.image import world

    load = world.load_image
    monkeypatch.setattr(world, "load_image", lambda path: dataclasses.replace(load(path), tables=None))
    traces, x, cycles, _, _ = _run_traced(images, WorldConfig())
    assert (traces, cycles) == (reference[0], reference[2])
    assert np.array_equal(x, reference[1])


def test_the_released_unicorn_gives_the_same_run(images, reference, monkeypatch):
    """The tier's Unicorn carries patches that change how fast it gets somewhere, never where (image/ucpatches/):
    the released wheel's library (MC_UNICORN=stock) gives the same change of state on every board, cycle counts,
    fast-forward and plant, bit for bit. Its one visible difference, the TLB refills the first patch removes, is
    counted: the released library refills peripheral pages all the time, the patched one only once per page."""
    from host_emulator.image import runtime

    def refills(config_env: str | None) -> list[int]:
        if config_env:
            monkeypatch.setenv(runtime.UNICORN_ENV, config_env)
        else:
            monkeypatch.delenv(runtime.UNICORN_ENV, raising=False)
        w, lap = configured(images, 3)
        before = [int(w.info(b.index).tlb_fills) for b in w.boards]
        lap.pump(0.1)
        return [int(w.info(b.index).tlb_fills) - n for b, n in zip(w.boards, before, strict=True)]

    monkeypatch.setenv(runtime.UNICORN_ENV, "stock")
    traces, x, cycles, written, ff = _run_traced(images, WorldConfig())
    assert (traces, cycles, written, ff) == (reference[0], reference[2], reference[3], reference[4])
    assert np.array_equal(x, reference[1])
    stock, patched = refills("stock"), refills(None)
    assert all(n > 200 for n in stock), stock  # 0.1 board second: thousands per cell (docs/image-tier.md)
    assert all(n <= 2 for n in patched), patched


def test_the_images_never_write_the_pac(reference):
    """No image sets (or clears) a peripheral's write protection (PAC0..2 WPSET/WPCLR, csrc/sam_pac.c): the runs
    above are not shaped by the PAC model; the DSU stays protected as from reset, and no image writes it."""
    written = reference[3]
    assert all(len(regs) > 20 for regs in written.values()), written  # every board configured its peripherals
    assert not {r for regs in written.values() for r in regs if r.startswith(("PAC", "DSU."))}


# ---- the drive outputs against the library ------------------------------------------------------------------


def _library_outputs(params: Params, limit_ticks: int, alpha: int, beta: int):
    """(duty, dir, enable) of both drivers from the control library compiled for the host, for zeroed angles
    (alpha, beta) counts, configured as the scene's commands configure the flashed cell."""
    ffi, lib = firmware.load()
    phys, drv = firmware_config(ffi, lib, params)
    c = ffi.new("mc_cell_t *")
    lib.mc_cell_init(c)
    assert lib.mc_cell_set_params(c, phys) == lib.MC_OK
    assert lib.mc_cell_set_drive(c, drv) == lib.MC_OK
    lib.mc_drive_set_limit(ffi.addressof(c, "drive"), limit_ticks)
    lib.mc_cell_zero(c, 0, 0)
    lib.mc_cell_enable(c, 1)
    snaps = [ffi.new("mc_quad_snap_t *") for _ in range(2)]
    snaps[0].pos, snaps[1].pos = alpha, beta
    for _ in range(3):
        lib.mc_cell_tick(c, snaps[0], snaps[1])
    return [(int(c.out[k].duty), int(c.out[k].dir), int(c.out[k].enable)) for k in range(2)]


@pytest.mark.parametrize("alpha,beta", [(37, -12), (-180, 95), (400, 400), (-3, 0), (250, -399)])
def test_drive_outputs_match_the_library_for_the_same_encoder_inputs(images, alpha, beta):
    """The encoders of a cell at rest are turned to (alpha, beta) counts (quadrature edges on its pins, the plant
    not running); the mean voltage and awake fraction the motors then see over a PWM period are the library's
    duty / top x supply with its direction, exactly."""
    p = Params(cells=1)
    w, lap = configured(images, 1, start_plant=False)
    t = w.t + 0.001
    for chain, n in (("alpha", alpha), ("beta", beta)):
        if n:
            w.spin(1, chain, 20000.0 * np.sign(n), t, t + abs(n) / 20000.0 - 1e-9)
    lap.pump(0.03)  # the edges, then ticks with the angles steady
    status = lap.rx.status(1)
    assert status and status["faults"] == 0 and status["dec_err_a"] == 0 and status["dec_err_b"] == 0, status
    top = int(p.pwm_top)
    limit = round(min(p.vmax_v, p.supply_v) / p.supply_v * top)
    for chain, (duty, direction, enable) in enumerate(_library_outputs(p, limit, alpha, beta)):
        volt, awake = w.motor(1, chain)
        assert awake == (1.0 if enable else 0.0)
        want = duty / top * p.supply_v * (1.0 if direction else -1.0)
        assert volt == pytest.approx(want, rel=1e-12, abs=1e-12), (chain, duty, direction, volt)
