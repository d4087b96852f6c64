"""Scenes in the image tier: the default scene selects the hil tier's pattern; faults from a scene show up as the
rig's tools would see them; keys the tier does not take are refused with one line."""

from __future__ import annotations

import pytest

from host_emulator.analysis.observables import domain_walls
from host_emulator.controller import build_solver, run_scene, run_solver
from host_emulator.models.options import ConfigError
from host_emulator.scene import load_scene

pytestmark = pytest.mark.slow


def test_default_scene_selects_the_same_domain_walls_as_hil(images):
    hil = run_scene(load_scene("default"), progress=False)
    img = run_scene(load_scene("default", ["model=image"]), progress=False)
    walls = domain_walls(hil.alpha[-1])
    assert walls >= 2  # a pattern grew
    assert domain_walls(img.alpha[-1]) == walls
    # and the cells' signs agree where the pattern is developed (|alpha| beyond 0.3 rad)
    strong = abs(hil.alpha[-1]) > 0.3
    assert (hil.alpha[-1][strong] * img.alpha[-1][strong] > 0).all()
    info = img.info
    assert info["laptop"]["cell_samples"] > 16 * 100
    assert all(info["laptop"]["cell_status"][j]["faults"] == 0 for j in range(1, 17))
    assert img.info.get("cell_faults") == [0] * 16


def test_per_cell_parameters_reach_each_cell_image(images):
    """Each cell image is configured with its own reaction values (the laptop sends them per cell): the image run
    follows the hil run of the same per-cell scene, and both leave the uniform chain's pattern."""
    import numpy as np

    per_cell = ["t_end_s=3", "params.sigma.8=0.02", "params.k_ab.3=0.05"]
    hil = run_scene(load_scene("default", per_cell), progress=False).alpha[-1]
    img = run_scene(load_scene("default", [*per_cell, "model=image"]), progress=False).alpha[-1]
    uniform = run_scene(load_scene("default", ["t_end_s=3"]), progress=False).alpha[-1]
    assert np.abs(hil - uniform).max() > 0.2  # the per-cell values change the pattern (cells 2 and 3)
    np.testing.assert_allclose(img, hil, atol=0.05)


def test_faults_from_a_scene_are_seen_through_the_laptop(images):
    """A HardFault in cell 3, a dead tick in cell 5 and a power loss of cell 7, 0.1 s into the scene; 3 s later
    the laptop (the same SLCAN path as the rig's tools) reads each cell's BOOT block: cell 3 was reset by its fault
    handler (FAULT and SYST, exception 3), cell 5 by its watchdog, cell 7 powered up again; the primary counted
    their silence as NACKs."""
    sets = [
        "model=image",
        "t_end_s=3.2",
        "fault.1.kind=hardfault",
        "fault.1.cell=3",
        "fault.1.start_s=0.1",
        "fault.2.kind=tick_dead",
        "fault.2.cell=5",
        "fault.2.start_s=0.1",
        "fault.3.kind=silent",
        "fault.3.cell=7",
        "fault.3.start_s=0.1",
        "fault.3.duration_s=0.2",
    ]
    scene = load_scene("default", sets)
    s = build_solver(scene)
    run_solver(s, scene.t_end_s)
    boot = s.laptop.read_blocks([1, 3, 5, 7])
    from protocol.definition import RESET_CAUSE

    def cause(j):
        bits = boot[j]["BOOT"]["reset_cause"]
        return {name for name, bit in RESET_CAUSE.items() if bits >> bit & 1}

    assert cause(1) == {"POR"}
    assert cause(3) == {"FAULT", "SYST"} and boot[3]["BOOT"]["fault_exc"] == 3 and boot[3]["BOOT"]["fault_pc"]
    assert cause(5) == {"WDT"}
    assert cause(7) == {"POR"}
    link = s.info()["laptop"]["cell_link"]
    assert all(link[j]["nack"] > 0 for j in (3, 5, 7)) and link[1]["nack"] == 0
    truth = {b["board"]: b for b in s.info()["boards"]}
    assert truth["cell 3"]["hardfaults"] == 1 and truth["cell 5"]["reset_cause"] == ["WDT"]


def test_faults_are_image_only_and_checked():
    with pytest.raises(ConfigError, match="only the image model"):
        load_scene("default", ["fault.1.kind=silent", "fault.1.cell=2", "fault.1.start_s=0", "fault.1.duration_s=1"])
    with pytest.raises(ConfigError, match=r"fault\[1\].rate_hz"):
        load_scene(
            "default",
            [
                "model=image",
                "fault.1.kind=edge_storm",
                "fault.1.cell=2",
                "fault.1.start_s=0",
                "fault.1.duration_s=1",
                "fault.1.rate_hz=1e9",
            ],
        )
    with pytest.raises(ConfigError, match="takes"):
        load_scene(
            "default",
            ["model=image", "fault.1.kind=tick_dead", "fault.1.cell=2", "fault.1.start_s=0", "fault.1.duration_s=1"],
        )
    with pytest.raises(ConfigError, match="threads"):
        load_scene("default", ["model=image", "model_options.image.threads=99"])


def test_the_boot_option_is_direct_unless_a_scene_asks_for_the_bootloader():
    assert load_scene("default", ["model=image"]).options.image.boot == "direct"
    s = load_scene("default", ["model=image", "model_options.image.boot=bootloader"])
    assert s.options.image.boot == "bootloader"
    with pytest.raises(ConfigError, match=r"model_options.image.boot = 'uf2': expected one of direct, bootloader"):
        load_scene("default", ["model=image", "model_options.image.boot=uf2"])
