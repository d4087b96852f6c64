/* Emulated lattice plant (docs/physics.md#equations-of-motion): band, honey, reaction and motor torques; physics only, no stepping. */
#ifndef HE_PLANT_H
#define HE_PLANT_H

#include <stdint.h>

/*
 * State layout (doubles, SI): x[0..n-1] = alpha_j, x[n..2n-1] = beta_j (rad),
 * v likewise (rad/s). The physics is written as
 *
 *     I_i * x_i'' = F_i(t, x) - C_i * x_i'          (inertia on)
 *           C_i * x_i' = F_i(t, x)                  (inertia off, overdamped)
 *
 * F_i = -sum_bonds tau(x_i, x_nb) + R_i(alpha_j, beta_j) + P_i(t) + m_i*V_i
 * (the sum over the bonds at cell i: the open chain's (j, j+1) when he_plant_t.bonds is NULL, else the edge list)
 * C_i = eta_i + m_i / S_L
 * where tau is the band torque (linear, cubic with slack, or geometric beta),
 * R the ideal floating-point reaction (docs/physics.md#reaction-torques) when reaction == HE_REACT_IDEAL, each
 * component clipped to +-react_limit (the actuators' torque limit),
 * P the external perturbations active at time t, and m_i*V_i the motor torque
 * Kt*(V - omega/S_L) with m_i = Kt while the driver is awake, 0 when it coasts
 * (hil: V_i is held by the control loop over a tick).
 * Steppers only ever call he_plant_forces(); this split keeps damping (linear in
 * v) separate so semi-implicit steppers can treat it implicitly.
 */
#define HE_MAX_CELLS 65536
#define HE_MAX_PERT 64
/* An edge list holds at most this many bonds per cell (a hexagonal sheet's 3: six neighbours, each bond counted
 * once); the steppers' scratch (he_step.h HE_WORK_PER_STATE) is sized for it. */
#define HE_MAX_BONDS_PER_CELL 3

enum { HE_BANDS_LINEAR = 0, HE_BANDS_CUBIC = 1 };
enum { HE_BETA_SMALL = 0, HE_BETA_GEOMETRIC = 1 };
enum { HE_REACT_NONE = 0, HE_REACT_IDEAL = 1 };
/* rows of he_plant_t.react_cell (per-cell reaction law) */
enum { HE_RC_K_AB = 0, HE_RC_SIGMA = 1, HE_RC_K1 = 2, HE_RC_K2 = 3, HE_RC_ASTAR = 4, HE_RC_COUNT = 5 };

enum {
    HE_OK = 0,
    HE_ERR_ARG = -1,        /* invalid plant configuration */
    HE_ERR_NONFINITE = -2,  /* state became NaN/inf */
    HE_ERR_DIVERGED = -3,   /* |angle| beyond HE_ANGLE_LIMIT_RAD or |speed| beyond HE_SPEED_LIMIT */
    HE_ERR_STEP = -4,       /* step larger than the stable limit */
    HE_ERR_STEPPER = -5,    /* unknown stepper id */
    HE_ERR_BAND = -6,       /* a band stretched beyond HE_BAND_STOP_FACTOR x the fit's range */
    HE_ERR_NOMEM = -7,      /* the steppers' scratch could not be allocated */
    HE_ERR_TOL = -8,        /* adaptive stepper: the error tolerance needs a step below its smallest step */
    HE_ERR_SOLVE = -9,      /* IMEX on an edge list: the conjugate-gradient solve did not converge (he_imex.h) */
};
#define HE_ANGLE_LIMIT_RAD 1000
#define HE_BAND_STOP_FACTOR 2
#define HE_SPEED_LIMIT_RAD_S 1000000

typedef struct {
    int32_t cell;        /* 0-based */
    int32_t chain;       /* 0 alpha, 1 beta */
    double torque;       /* N*m */
    double t0, t1;       /* active for t0 <= t < t1 (s) */
} he_pert_t;

typedef struct {
    int32_t n;               /* cells, 1..HE_MAX_CELLS */
    int32_t inertia;         /* 1: second order, 0: overdamped first order */
    int32_t bands;           /* HE_BANDS_* */
    int32_t beta_geometry;   /* HE_BETA_* (cubic bands only) */
    int32_t reaction;        /* HE_REACT_* */
    int32_t slack_f0;        /* 1: a slack band still pulls f(0); 0: it pulls nothing */
    double I[2];             /* inertia alpha, beta, kg m^2 */
    double k_lin[2];         /* table stiffness, N m/rad (linear bands) */
    double band_scale;       /* multiplies the cubic-law torque (docs/physics.md#band-torque choice) */
    double lever[2];         /* r (alpha) and 2r (beta arm), m */
    double lattice_m;        /* a, m */
    double delta0[2];        /* pre-stretch, m */
    double delta_max[2];     /* largest band stretch the step limit allows for (fit range: 0.3*L_rest), m */
    double coef[2][4];       /* cubic force fits f(delta) = c0 + c1 d + c2 d^2 + c3 d^3 */
    double k_ab, sigma, k1, k2, astar;   /* reaction law, N m/rad and rad (every cell, unless react_cell) */
    double speed_const;      /* S_L, rad/(V s) */
    /* Per-cylinder and per-bond arrays, owned by the plant's owner (models/plant.py build_plant allocates them
     * with the struct), so the struct stays small whatever the cell count: */
    double *eta[2];          /* [n] viscous coefficient per cell, N m s */
    double *kscale[2];       /* band stiffness factor per bond: [n] for the open chain (bond j = (j, j+1), the
                                first n-1 used), [nbond] for an edge list (bond b = bonds[2b], bonds[2b+1]) */
    double *mgain[2];        /* [n] motor gain Kt while driving, 0 coasting, N m/V */
    double *volt[2];         /* [n] motor voltage held over the step, V */
    /* Topology: NULL = the open chain, bonds (j, j+1) for j = 0..n-2 (nbond ignored), with its own kernels (the
     * golden digests' bits); else nbond bonds (0..HE_MAX_BONDS_PER_CELL * n), bonds[2b], bonds[2b+1] the 0-based
     * cells of bond b (distinct, in 0..n-1), in the order host_emulator/topology.py gives them; owned by the
     * plant's owner. The band torque of bond b acts on both of its cells; forces add the bonds in this order. */
    int32_t nbond;
    const int32_t *bonds;
    int32_t npert;
    he_pert_t pert[HE_MAX_PERT];
    double react_limit;      /* |R_a|, |R_b| clipped to this (N*m): the drivers' voltage cap kt*vmax;
                                INFINITY (or any value <= 0 is rejected) for no actuator limit */
    const double *react_cell; /* NULL: the scalars k_ab..astar above hold for every cell; else per-cell reaction
                                 law, HE_RC_COUNT rows of n doubles (row HE_RC_K_AB: cell j at [j], row r at
                                 [r * n + j]), owned by the plant's owner */
    double *work;            /* steppers' scratch, allocated once per model by its owner (HE_WORK_PER_STATE
                                doubles per state entry, 2n entries); NULL: he_advance mallocs per call */
    int64_t work_len;        /* doubles at work */
} he_plant_t;

/* Check sizes and finiteness; HE_OK or HE_ERR_ARG. */
int he_plant_check(const he_plant_t *p);
/* F and C of the header comment at time t for positions x (2n each). */
void he_plant_forces(const he_plant_t *p, double t, const double *x, double *F, double *C);
/* F alone (the same values he_plant_forces writes), for steppers that hold C fixed over a call. */
void he_plant_torques(const he_plant_t *p, double t, const double *x, double *F);
/* Add the band torques of both chains at x to F (2n): what he_plant_torques adds after F = m V, in the same order
 * (so F = m V, then this, gives he_plant_torques' bits without reaction and perturbations). */
void he_plant_band_torques(const he_plant_t *p, const double *x, double *F);
/* Bonds of the plant: n - 1 for the open chain (bonds NULL), else nbond. */
int he_plant_nbond(const he_plant_t *p);
/* Band torque on cylinder x_self from the bond to x_other (chain 0/1, bond index
 * for the stiffness spread): the tau(x_self, x_other) of docs/physics.md#band-torque. */
double he_band_torque(const he_plant_t *p, int chain, int bond, double x_self, double x_other);
/* Ideal reaction torques R_a, R_b of docs/physics.md#reaction-torques. The law has one copy per language:
 * this (C float), host_emulator/physics.py (Python), lib/metacell/src/control/mc_reaction.h (firmware,
 * fixed point); tests/host_emulator/test_physics.py checks all three against one float reference. */
void he_reaction(const he_plant_t *p, double alpha, double beta, double *ra, double *rb);
/* The same law with cell j's own parameters (react_cell; the scalars when it is NULL): the same operations. */
void he_reaction_cell(const he_plant_t *p, int j, double alpha, double beta, double *ra, double *rb);
/* Gershgorin row bound of the reaction Jacobian dR/dx on chain ch (N*m/rad), 0 without the ideal reaction:
 *   alpha: max(|k_ab + k1|, |k_ab + k2|) + |k_ab - sigma|,   beta: 2 |k_ab|   (the largest over the cells)
 * (Python: physics.reaction_gershgorin). */
double he_react_stiffness(const he_plant_t *p, int chain);
/* Cubic band law f(d) = c0 + c1 d + c2 d^2 + c3 d^3 (N) and its slope f'(d) = c1 + 2 c2 d + 3 c3 d^2 (N/m)
 * (Python: physics.band_force, physics.band_slope). */
double he_cubic(const double c[4], double d);
double he_cubic_slope(const double c[4], double d);
/* Tangent stiffness of bond b (cells i, k; the chain's (j, j+1)) at x_i - x_k = dx: d tau / d dx (N*m/rad), small-angle
 * band form (the geometric beta form uses it too: the IMEX stepper's W-matrix). */
double he_bond_slope(const he_plant_t *p, int chain, int bond, double dx);
/* Viscous + back-EMF damping of cylinder j of a chain: C = eta + m / S_L (N*m*s). */
double he_damping(const he_plant_t *p, int chain, int j);
/* Cubic bands: HE_ERR_BAND if some stretch exceeds HE_BAND_STOP_FACTOR * delta_max
 * (the motion left the range where the band law means anything), else HE_OK.
 * *where = 0-based bond index b of the first such bond, + n on the beta chain for the open chain (bonds NULL),
 * + nbond on the beta chain for an edge list (its cells: bonds[2b], bonds[2b + 1]). */
int he_plant_range_check(const he_plant_t *p, const double *x, int *where);
/* The force law is smooth except where a branch of it switches: a band going slack (cubic bands; two per
 * bond and chain, bonds in he_plant_nbond order), psi' changing piece (|alpha_j| = b*, ideal reaction) and the actuator clip (ideal reaction
 * with a finite react_limit: R_a and R_b against +-react_limit). he_plant_switches writes the side of every
 * such switch at positions x (1 or 0 per switch, the branch condition itself) and returns their number,
 * he_plant_nswitch(p) (<= 4 nbond + 5n <= 17n). An adaptive stepper compares the sides at the two ends of a step to find the
 * steps that cross one (he_dop853.h). */
int he_plant_nswitch(const he_plant_t *p);
int he_plant_switches(const he_plant_t *p, const double *x, unsigned char *side);
/* Upper bounds used for the stable step limit: per chain the largest
 * stiffness/inertia w2 (1/s^2), the smallest and largest damping/inertia c (1/s),
 * and for the overdamped system the largest stiffness/damping rate (1/s). */
void he_plant_bounds(const he_plant_t *p, double w2[2], double cmin[2], double cmax[2], double rate[2]);

#endif /* HE_PLANT_H */
