"""Parameter sweeps on Dask: a grid of scene overrides x noise seeds, run on a local or an existing cluster.

    python -m host_emulator sweep default --grid params.sigma=0.04:0.12:41 \
        --grid perturbation.1.torque_Nm=0.005,0.01,0.02,0.04 --seeds 5 --out out/sweep

* Grid: ``KEY=START:STOP:NUM`` (NUM values, both ends included, computed exactly: 0.04:0.12:41 gives 0.056, not
  0.055999999999999994; fractions such as 6/125 allowed) or ``KEY=V1,V2,...``; KEY is any ``run --set`` key
  (params.sigma, perturbation.1.torque_Nm, model_options.noise.band_spread, t_end_s, ...). ``--seeds S``
  adds a coordinate ``seed`` = 0..S-1 set as model_options.noise.seed (give the seeds something to vary,
  e.g. ``--set model_options.noise.band_spread=0.02``).
* Execution: points are cut into chunks; each Dask task evaluates one chunk through
  ``evaluate_points(specs) -> results`` (one place to plug a batched runner in). With no ``--scheduler`` a
  ``distributed.LocalCluster`` with one single-threaded worker process per core is started; with
  ``--scheduler tcp://HOST:PORT`` the sweep runs unchanged on that cluster. Tasks whose worker dies are
  retried by the scheduler; a chunk that still fails has each of its points recorded as failed, with the reason.
* Output in DIR: ``points.jsonl`` (one line per finished point, appended as chunks finish: the sweep is
  resumable, a re-run skips the points already there; ``--retry-failed`` runs failed ones again),
  ``sweep.json`` (the sweep's definition; a re-run with another definition is refused), ``sweep.nc``
  (xarray Dataset, NetCDF 3 through scipy: a coordinate per swept key, named plainly for ``.sel`` (``sigma``,
  ``torque_Nm``; the full key in the coordinate's ``key`` attribute), observables as variables, ``status``
  and ``error`` per point, provenance and every base-scene parameter as attributes), ``phase_diagram.png``
  (when params.sigma is swept) and ``regime_map.png`` (the first two swept keys, or ``--map KEY KEY``); for a
  sheet scene also ``pattern_kinds.png`` (the same keys: the pattern kind per point, its dominant wavelength, the
  linear theory's regime boundaries).

Observables per point (NaN where not defined or not produced): domain_walls, pattern_wavelength_cells
(2(N-1)/Z, cells), dominant_mode, pattern_period_cells, amplitude_rad, oscillation_period_s, growth_rate_per_s,
at_rest and steady (1/0), outcome (rest / pattern / oscillation / moving / failed), and from the linear theory
of the model that runs, at the point's parameters: regime (docs/analysis.md#regimes), theory_fastest_lambda_cells,
theory_fastest_growth_per_s and, over a dimension ``band`` (one entry per unstable interval, NaN-padded),
theory_band_lo_cells, theory_band_hi_cells (inf: the interval reaches infinitely long waves) and
theory_band_kind (stationary / oscillatory); on a sheet, pattern_kind (stripes / spots / labyrinth / rest /
oscillation, analysis.pattern2d; "" on a chain) and dominant_wavelength_cells. Units are attributes of each variable.

The modules, one job each: grid (parsing, the point specs), points (the Dask task: ``evaluate_points``), store
(points.jsonl), cluster (the Dask run), dataset (sweep.nc), figures (the phase diagram, the regime map), kinds
(a sheet's pattern kinds), schema (observables, outcomes, coordinate names), errors, driver (``sweep``) and cli
(``sweep_main``).
"""

# every name of the former single module, re-exported: `from host_emulator.workbench.sweep import X` as before
from .cli import EPILOG, sweep_main  # noqa: F401
from .cluster import chunk_size, local_cluster  # noqa: F401
from .dataset import to_dataset  # noqa: F401
from .driver import COST_SAMPLE, estimate_cost, sweep  # noqa: F401
from .errors import SweepError, SweepFailed  # noqa: F401
from .figures import (  # noqa: F401
    OUTCOME_STYLE,
    REGIME_MARKERS,
    outcome,
    plot_phase_diagram,
    plot_regime_map,
    theory_bands_over,
)
from .grid import MAX_POINTS, parse_grid, point_specs  # noqa: F401
from .kinds import KIND_COLOURS, plot_pattern_kinds  # noqa: F401
from .points import evaluate_points  # noqa: F401
from .schema import BANDS, OBSERVABLES, OUTCOMES, PATTERN_KINDS, STRINGS, coord_names, outcome_of  # noqa: F401
from .store import load_done  # noqa: F401
