/* x4 table-driven quadrature decoder (see mc_quad.h for the discrete rule). */
#include "mc_quad.h"
#include "../mc_fixed.h"

#define QX 2 /* marker: illegal transition (both channels changed) */

/* index = (prev_ab << 2) | ab; Gray order 00,01,11,10 counts up. */
static const int8_t quad_table[16] = {
    /* prev 00 */ 0, +1, -1, QX,
    /* prev 01 */ -1, 0, QX, +1,
    /* prev 10 */ +1, QX, 0, -1,
    /* prev 11 */ QX, -1, +1, 0,
};

void mc_quad_init(mc_quad_t *q, uint8_t ab)
{
    q->pos = 0;
    q->errors = 0;
    q->ab = (uint8_t)(ab & 3u);
    q->saturated = 0;
}

void mc_quad_update(mc_quad_t *q, uint8_t ab)
{
    ab &= 3u;
    int8_t d = quad_table[((unsigned)q->ab << 2) | ab];
    q->ab = ab;
    if (d == QX) {
        q->errors = q->errors + 1u;
        return;
    }
    if (d == 0)
        return;
    int32_t p = q->pos;
    if ((d > 0 && p == INT32_MAX) || (d < 0 && p == INT32_MIN)) {
        q->saturated = 1;
        return;
    }
    q->pos = p + d;
}

void mc_quad_snapshot(const mc_quad_t *q, mc_quad_snap_t *out)
{
    uint32_t m = mc_irq_save();
    out->pos = q->pos;
    out->errors = q->errors;
    out->saturated = q->saturated;
    mc_irq_restore(m);
}

void mc_quad_set_pos(mc_quad_t *q, int32_t pos)
{
    uint32_t m = mc_irq_save();
    q->pos = pos;
    q->saturated = 0;
    mc_irq_restore(m);
}
