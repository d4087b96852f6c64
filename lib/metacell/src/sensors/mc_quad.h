/* x4 table-driven quadrature decoder, updated from pin interrupts. */
#ifndef MC_QUAD_H
#define MC_QUAD_H

#include <stdint.h>

/*
 * State is the last sampled (A,B) pair as ab = (A << 1) | B. Every pin-change
 * interrupt samples both channels and calls mc_quad_update():
 *
 *   idx   = (prev_ab << 2) | ab
 *   delta = table[idx]        in {-1, 0, +1}, or ILLEGAL when A and B both changed
 *   pos  += delta             saturating at INT32_MIN/INT32_MAX (flag set)
 *
 * A legal Gray sequence (00 -> 01 -> 11 -> 10 -> 00) counts +1 per edge (CCW
 * positive by wiring convention), the reverse -1. An illegal transition (a missed
 * edge: both channels changed) adds nothing and increments `errors`; the new state
 * is adopted, so decoding resumes from the next legal edge. Errors are never
 * absorbed silently: the cell tick turns a burst of them into a latched fault.
 *
 * Concurrency: only the ISR writes; the control loop takes a consistent copy of
 * (pos, errors, saturated) with mc_quad_snapshot(), which masks interrupts for
 * three loads.
 */
typedef struct {
    volatile int32_t pos;        /* counts */
    volatile uint32_t errors;    /* illegal transitions since init (wraps mod 2^32) */
    volatile uint8_t ab;         /* last (A<<1)|B */
    volatile uint8_t saturated;  /* 1 once pos hit an int32 limit */
} mc_quad_t;

typedef struct {
    int32_t pos;
    uint32_t errors;
    uint8_t saturated;
} mc_quad_snap_t;

void mc_quad_init(mc_quad_t *q, uint8_t ab);
void mc_quad_update(mc_quad_t *q, uint8_t ab);
void mc_quad_snapshot(const mc_quad_t *q, mc_quad_snap_t *out);
/* Set the position (e.g. re-zero) without touching error counters. */
void mc_quad_set_pos(mc_quad_t *q, int32_t pos);

#endif /* MC_QUAD_H */
