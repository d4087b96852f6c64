/* QEMU instruction-count program: known-length calibration calls, then a representative run of mc_cell_tick. */
#include "semihost.h"
#include "mc_cell.h"

int known_seq17(int x);
int known_loop(int n);

#define N_TICKS 400

static mc_cell_t cell;
static mc_quad_t qa, qb;
static uint32_t tags[N_TICKS]; /* per tick: enabled | bemf<<1 | pert<<2 | faults<<16 */

/* Triangle wave in [-amp, amp] with the given period (ticks), no division. */
static int32_t tri(int32_t t, int32_t amp, int32_t quarter)
{
    int32_t p = t & (4 * quarter - 1);       /* quarter is a power of two */
    int32_t v = p < 2 * quarter ? p - quarter : 3 * quarter - p;
    return (v * amp) >> 6;                    /* quarter = 64 */
}

/* Feed the decoder the Gray edges needed to reach `target` (what the ISR would do). */
static void move_to(mc_quad_t *q, int32_t target)
{
    static const uint8_t up[4] = {1, 3, 0, 2}, down[4] = {2, 0, 3, 1};
    while (q->pos < target)
        mc_quad_update(q, up[q->ab]);
    while (q->pos > target)
        mc_quad_update(q, down[q->ab]);
}

int main(void)
{
    mc_quad_snap_t sa, sb;
    volatile int sink = 0;
    /* calibration: 17 and 3n+2 instructions */
    sink += known_seq17(1);
    sink += known_loop(5);
    sink += known_loop(100);

    mc_cell_init(&cell);
    mc_quad_init(&qa, 0);
    mc_quad_init(&qb, 0);
    mc_cell_enable(&cell, 1);
    mc_cell_set_bemf(&cell, 0);   /* the shipped default; on from tick 120 */
    for (int32_t t = 0; t < N_TICKS; t++) {
        if (t == 120)
            mc_cell_set_bemf(&cell, 1);
        if (t == 40)
            mc_cell_perturb(&cell, MC_ALPHA, 20000, 60);
        if (t == 150)
            mc_cell_perturb(&cell, MC_BETA, -15000, 30);
        if (t == 230)
            mc_cell_clear_faults(&cell);
        if (t == 250)
            mc_cell_enable(&cell, 0);
        if (t == 270)
            mc_cell_enable(&cell, 1);
        if (t == 300)
            mc_cell_set_bemf(&cell, 0);
        if (t == 350)
            mc_cell_set_bemf(&cell, 1);
        /* angles in range (|theta| < 600 < runaway 800); 200..229 a runaway */
        int32_t a = tri(t, 500, 64) + (t >= 200 && t < 230 ? 900 : 0);
        int32_t b = tri(t + 32, 300, 64);
        move_to(&qa, a);
        move_to(&qb, b);
        uint32_t tag = cell.enabled | (uint32_t)cell.bemf_comp << 1 |
                       (uint32_t)(cell.pert_ticks != 0) << 2;
        mc_quad_snapshot(&qa, &sa);
        mc_quad_snapshot(&qb, &sb);
        uint16_t f = mc_cell_tick(&cell, &sa, &sb);
        tags[t] = tag | (uint32_t)f << 16;
    }
    int fd = sh_open("bench.bin", 5);
    if (fd < 0 || sh_write(fd, tags, sizeof tags) != 0)
        return 1;
    return sink == 0 ? 1 : 0;
}
