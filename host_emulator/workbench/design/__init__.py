"""`python -m host_emulator design` and ``he.design(...)``: from a target pattern to reaction-law parameters.

See docs/design.md. A target is a wavelength in cells (``lambda=10``: Z = 2 (n - 1) / lambda domain walls
anywhere, the rig's reading of a pattern) or a layout of domain walls at named bonds (``walls=5.5,10.5``: between
cells 5|6 and 10|11), and optionally cells that must stay at rest (``--rest 9-16``). The pushes are the
experimenter's (``--push 8``, ``--push 6,10``, ``--push 1:+,16:-``: CCW (+) or CW (-) hand pushes on alpha).

The design, in three steps:

1. first guess from linear theory (analysis.chain): over the free parameters (``--vary``; those in ``--per-cell``
   take one value per domain of the target layout), scipy's differential evolution maximises the linear score:
   the chain's fastest mode (hil theory: inertia and the motors' back-EMF damping) must be stationary, grow, have
   the target's walls (or wall count) and fill every domain, with as large a gap as possible to the next mode;
2. search over batched hil ensembles (workbench.batch, firmware in the loop; on Dask with ``--scheduler``):
   differential evolution again, seeded around the first guess, each generation one batched call, maximising
   the fraction of runs that land on the target over ``search_seeds`` noise seeds (each a draw of the rig's
   uncertainty, models.options.RIG_UNCERTAINTY: band stiffness, viscosity, inertia, push magnitude and timing) and
   the corners of the push range (a missed run earning 0.3 x its closeness: the share of the
   target's walls it has and of the chain it fills, so the search can climb before anything lands), plus a
   margin: 0.05 x the linear gap (so among equally successful designs the one farthest from a competing mode
   wins). A candidate that lands in every search run is run again on as many fresh noise seeds (4000..), which
   count too; the search stops at the first candidate that lands in all of them (else after ``maxiter``
   generations, keeping the best). A run lands when its final pattern is steady, has exactly the target's walls
   (sign changes among the cells above 0.1 rad, each rounded to the nearest bond), every cell off the walls
   beyond 0.1 rad and every domain reaching 0.3 rad (a filled pattern, not a bump on a chain at rest), the rest
   cells within 0.1 rad, and no reaction torque beyond the drivers' 5.86 V (44 mN m);
3. verification of the written scene.toml as ``run`` loads it: 20 draws of the rig's uncertainty (seeds 2000.., as
   the robustness command's `rig` column) and the whole push range (PUSH_TORQUES_NM x PUSH_DURATIONS_S, no noise);
   then as many fresh draws (seeds 5000.., the confirmation): the target is reached when the verification's and
   the confirmation's draws together land in at least ``require`` (20 draws are a noisy estimate of the rate);
4. the cross-model check: the same 20 draws in the ``lattice`` (CROSS_MODEL: the ideal reaction, no motors and so
   no back-EMF damping), reported beside the hil's fraction (design.json ``cross_check``).

design.json's ``assumes`` names what the search held fixed: the firmware settings (back-EMF compensation, PWM limit
in force, PWM period, control rate, supply and the drivers' cap) and the hil's model options (stepper, plant steps
per tick, accuracy preset); scene.toml writes them explicitly, and ``rigtools.command apply`` refuses a rig whose
cells run another back-EMF or PWM setting (``--configure`` sets them).

Parameters stay in the firmware's ranges (|k| <= 0.25 N m/rad, 0 <= alpha* <= 2 pi, k1 > max(k2, 0)) and are
rounded to the registers' resolution (1 uN m/rad, 1 urad). A target the search cannot bring to ``require``
(default 0.9) of those draws is reported as unreachable, with the nearest target that is reachable.
Outputs in --out: design.json, scene.toml, design.png.

The modules, one job each: constants (the numbers above), target (the input: target and pushes), landing (does a
run land), space (the search vector), linear (step 1), ensembles (batched hil runs, in process or on Dask), search
(step 2), verification (step 3), nearest (the nearest reachable target), scenefile (scene.toml), plot
(design.png), driver (``design``, design.json) and cli (``design_main``).

On a square sheet (``design --sheet ROWSxCOLS``, docs/design.md "Sheets"): a region that patterns beside one that
rests (``--rest cols=9-16``), optionally at a stripe wavelength (``--target lambda=12``), one law per region; the
modules sheet_target (the input), sheet_landing (does a run land), sheet_linear (step 1: each region's law on the
square lattice, the whole sheet's eigenproblem as the check), sheet_runs (steps 2 and 3 over batched sheet
ensembles) and sheet_driver (design.json, scene.toml, design.png).
"""

# every name of the former single module, re-exported: `from host_emulator.workbench.design import X` as before
from .cli import design_main
from .constants import (  # noqa: F401
    BOUNDS,
    CHECK_SEED0,
    CLOSE_WEIGHT,
    CONFIRM_SEED0,
    DOMAIN_FILL_MODE,
    DOMAIN_MIN_RAD,
    FULL_BONUS,
    LSB_DIGITS,
    MARGIN_WEIGHT,
    MAX_NEAREST_VERIFIED,
    MIN_GROWTH_PER_S,
    NOISE,
    NOMINAL_PUSH,
    PUSH_DURATIONS_S,
    PUSH_TORQUES_NM,
    REQUIRE,
    SEARCH_PUSHES,
    SEARCH_SEED0,
    VERIFY_SEED0,
)
from .driver import design
from .ensembles import Runner, _noise, noise_overrides, run_tables  # noqa: F401
from .landing import closeness, domain_peaks, final_walls, interior_cells, lands, miss_reason, torque_ok  # noqa: F401
from .linear import first_guess, linear_score  # noqa: F401
from .nearest import nearest_reachable  # noqa: F401
from .plot import plot_design  # noqa: F401
from .search import hil_search  # noqa: F401
from .space import Space, space_for  # noqa: F401
from .target import DesignError, Push, Target, parse_pushes, parse_target  # noqa: F401
from .verification import verify  # noqa: F401

__all__ = ["Target", "parse_target", "parse_pushes", "design", "design_main", "lands", "DesignError"]
