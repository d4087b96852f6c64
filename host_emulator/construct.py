"""From a scene to its solver, in one module: build_solver (the one construction path: runs, the bus rig, bench-speed
and the benchmarks) and checked_solver, the solver built behind limits' two guards (the scene's values before
anything is built, its resolved plant step after); scene_cost prices a run by the same path."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .accuracy import resolve_options
from .limits import RunTooLarge, cell_steps, check_run, check_solver
from .models import ConfigError, Solver, make_model

if TYPE_CHECKING:
    from .scene import Scene

__all__ = ["build_solver", "checked_solver", "scene_cost"]


def build_solver(scene, *, resolve: bool = True, options=None, perturbations=None, x0=None) -> Solver:
    """The one construction path of a scene's solver (runs, the bus rig, bench-speed and the benchmarks).

    resolve: apply the scene's accuracy preset (accuracy.resolve_options) to its model options, as a run does;
    False keeps the options as given (benchmarks sweeping steppers and steps set them themselves).
    options / perturbations replace the scene's; x0 is the initial state (2n angles) where the model takes one."""
    options = scene.options if options is None else options
    perturbations = scene.perturbations if perturbations is None else perturbations
    if resolve:
        options = resolve_options(
            scene.model,
            scene.params,
            perturbations,
            options,
            getattr(scene, "accuracy", "balanced"),
            getattr(scene, "explicit_options", ()),
        )
    model = make_model(scene.model, scene.params, list(perturbations), options)
    faults = getattr(scene, "faults", ())
    if faults:
        inject = getattr(model, "inject", None)
        if inject is None:
            raise ConfigError(f"fault: the {scene.model} model has no boards to inject faults into")
        inject(faults)
    return model.solver() if x0 is None else model.solver(x0=x0)


def checked_solver(scene: Scene):
    """The scene's built solver once the run has passed both guards: the scene (check_run) before anything is built,
    then its resolved plant step (check_solver). RunTooLarge naming the key and the figure otherwise."""
    problem = check_run(scene)
    if problem:
        raise RunTooLarge(problem)
    solver = build_solver(scene)
    problem = check_solver(scene, solver)
    if problem:
        raise RunTooLarge(problem)
    return solver


def scene_cost(scene: Scene) -> float:
    """Cell steps of one run of the scene, from its built solver (RunTooLarge / ConfigError / ValueError if the
    scene itself is refused)."""
    return cell_steps(scene, checked_solver(scene))
