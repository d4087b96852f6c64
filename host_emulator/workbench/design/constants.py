"""The design's fixed numbers: the push range, the noise model and its seeds, the search's weights, the parameters'
search box and the registers' resolution, and the landing thresholds (see the package docstring)."""

from ...models.options import RIG_UNCERTAINTY

# the documented range of hand pushes (as the robustness command): torque (N m) x duration (s), no noise
PUSH_TORQUES_NM = (0.005, 0.01, 0.02, 0.04)
PUSH_DURATIONS_S = (0.05, 0.1, 0.2)
SEARCH_PUSHES = ((0.01, 0.05), (0.04, 0.2), (0.005, 0.2), (0.04, 0.05))  # the range's corners, in the search
NOMINAL_PUSH = (0.02, 0.1)  # the scene's push: 20 mN m for 0.1 s, 0.1 s after the start
# the search's and the verification's ensemble: the rig's uncertainty (docs/physics.md#the-rigs-uncertainty), each
# noise seed one draw of band stiffness, viscosity, inertia, push magnitude and timing
NOISE = dict(RIG_UNCERTAINTY)
CROSS_MODEL = "lattice"  # the second model a design is re-checked in, under the same draws (no motors: no back-EMF)
VERIFY_SEED0 = 2000  # verification seeds (the robustness command's)
SEARCH_SEED0 = 3000  # search seeds: never the verification's
CONFIRM_SEED0 = 5000  # the confirmation: as many fresh draws as the verification's (5000..), pooled with them
CHECK_SEED0 = 4000  # a search candidate that lands in every search run is checked on as many fresh seeds (4000..)
REQUIRE = 0.9
MARGIN_WEIGHT = 0.05
CLOSE_WEIGHT = 0.3  # in the search only: a missed run earns this x how close its walls came (closeness)
FULL_BONUS = 0.1  # in the search only: added to a candidate that landed in every search and check run
# search box of each parameter (N m/rad; alpha* rad): inside the firmware's |k| <= 0.25, 0 <= alpha* <= 2 pi
BOUNDS = {
    "k_ab": (0.002, 0.12),
    "sigma": (0.0, 0.25),
    "k1": (0.02, 0.25),
    "k2": (-0.2, 0.05),
    "alpha_star": (0.3, 2.5),
}
LSB_DIGITS = 6  # register resolution: 1 uN m/rad (gains), 1 urad (alpha*): values rounded to 6 decimals
MIN_GROWTH_PER_S = 1.0  # the target mode must grow at least this fast (e^9 over a 10 s run)
DOMAIN_MIN_RAD = 0.3  # every domain of a landed pattern reaches this |alpha| (about half a pattern's 0.6-0.7 rad)
DOMAIN_FILL_MODE = 0.2  # in the linear theory, every cell of a domain off its walls this share of the mode's peak
MAX_NEAREST_VERIFIED = 6  # neighbours verified with the firmware in the loop at most (those with a linear score > 1)
