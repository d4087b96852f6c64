/* One unit cell: decoder snapshots in, reaction torque, drive commands out. */
#ifndef MC_CELL_H
#define MC_CELL_H

#include <stdint.h>
#include "mc_fixed.h"
#include "sensors/mc_quad.h"
#include "sensors/mc_velocity.h"
#include "control/mc_reaction.h"
#include "drivers/mc_drive.h"

#define MC_FW_VERSION 0x0100   /* major.minor of the cell library */

enum { MC_ALPHA = 0, MC_BETA = 1 };

/* Latched fault flags: any of them turns both drivers off until cleared. */
enum {
    MC_FAULT_RUNAWAY_A = 1u << 0,   /* |alpha| beyond runaway_counts */
    MC_FAULT_RUNAWAY_B = 1u << 1,
    MC_FAULT_ENCODER_A = 1u << 2,   /* burst of illegal quadrature transitions */
    MC_FAULT_ENCODER_B = 1u << 3,
    MC_FAULT_SATURATED = 1u << 4,   /* a decoder position hit an int32 limit */
    MC_FAULT_DRIVER = 1u << 5,      /* DRV8874 nFAULT reported by the glue */
};

/*
 * Encoder-error burst detector (leaky bucket, per encoder):
 *   bucket += 256 * new_errors;  bucket -= min(bucket, 1)  each tick
 *   fault when bucket > 256 * enc_burst
 * so more than enc_burst errors faster than one per 256 ticks latch a fault,
 * while isolated glitches (counted, and visible in `errors`) do not. The decay
 * is applied lazily on the next error, so a quiet tick costs one comparison.
 *
 * Runaway: the angles are theta = pos - zero limited to +-runaway_counts; a
 * limited angle latches MC_FAULT_RUNAWAY_x. That limit (<= MC_ANGLE_CLAMP) is the
 * only clamp the law needs, and pos - zero is computed without overflow.
 *
 * Back-EMF compensation (V += omega/S_L) is off by default. With it on, the
 * velocity comes from a low-lag tracking observer (sensors/mc_velocity.h: time
 * constants of 1.5 ms and 0.5 ms at 2 kHz) that runs only while compensation is
 * on and restarts, at rest, from the last angles when it is switched on.
 * Off, each motor adds Kt/S_L (about 1.5e-4 N*m*s) of viscous damping; on, the
 * lattice follows its own dynamics up to the 5.86 V cap (docs/firmware-proof.md
 * says which the rig should use).
 *
 * Cost (Cortex-M0+, -Os, measured under QEMU by `python -m metacell_tools.fwcheck ticks`):
 * at most 200 instructions per tick in the default configuration, at most 240
 * with back-EMF compensation on.
 */
typedef struct {
    /* hot fields first: Thumb-1 word loads reach only 124 bytes past the base */
    mc_reaction_t law;
    mc_drive_t drive;
    int32_t zero[2];          /* encoder zero offsets, counts */
    uint32_t err_last[2];     /* decoder error counters seen last */
    int32_t runaway_counts;   /* 1..MC_ANGLE_CLAMP, default 800 (2 rev) */
    int32_t pert_torque;      /* TU */
    uint32_t pert_ticks;      /* remaining ticks of the perturbation */
    uint8_t pert_chain;       /* MC_ALPHA or MC_BETA */
    uint8_t enabled;          /* drive enable requested */
    uint8_t bemf_comp;        /* back-EMF compensation on (default off) */
    uint8_t spare;
    uint16_t faults;          /* latched MC_FAULT_* */
    uint32_t tick;            /* ticks since init */
    int32_t theta[2];         /* last zeroed angles (counts), limited to +-runaway_counts */
    int32_t torque[2];        /* last commanded torque (TU), before the drive */
    mc_drive_out_t out[2];    /* commands for the alpha and beta drivers */
    mc_vel_t vel;             /* velocity observer, used with back-EMF compensation */
    /* cold: touched only when a decoder error counter moves */
    int32_t enc_burst;        /* errors, default 8 */
    int32_t bucket[2];        /* leaky buckets, as of err_tick */
    uint32_t err_tick[2];     /* tick of the last error per encoder */
} mc_cell_t;

/* docs/physics.md#reaction-torques experiment defaults: k_ab = 1/50, k1 = 3/50, k2 = -3/50,
 * a_s = 3*pi/8, sigma = 9/125 (uN*m/rad and urad). */
void mc_cell_default_params(mc_reaction_phys_t *p);
void mc_cell_init(mc_cell_t *c);
int mc_cell_set_params(mc_cell_t *c, const mc_reaction_phys_t *p);
int mc_cell_set_drive(mc_cell_t *c, const mc_drive_config_t *cfg);
int mc_cell_set_runaway(mc_cell_t *c, int32_t counts);
void mc_cell_enable(mc_cell_t *c, int on);
void mc_cell_set_bemf(mc_cell_t *c, int on);
/* Perturbing torque in uN*m (|t| <= MC_PERTURB_MAX_UNM) on one chain for `ticks` ticks. */
int mc_cell_perturb(mc_cell_t *c, int chain, int32_t torque_unm, uint32_t ticks);
/* Make the given raw positions the new zero of both angles; the velocity observer restarts. */
void mc_cell_zero(mc_cell_t *c, int32_t pos_a, int32_t pos_b);
void mc_cell_clear_faults(mc_cell_t *c);
void mc_cell_report_driver_fault(mc_cell_t *c);
/* One control tick. Returns the latched fault flags; commands are in c->out. */
uint16_t mc_cell_tick(mc_cell_t *c, const mc_quad_snap_t *a, const mc_quad_snap_t *b);

#endif /* MC_CELL_H */
