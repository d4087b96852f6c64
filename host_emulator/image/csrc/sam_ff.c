/* Fast-forward: a loop() pass that changed nothing and met no event repeats exactly until the next event: skip it. */
#include <string.h>
#include "sam_core.h"

#define SAM_FF_CHUNK 1024u   /* bytes compared before a copy of the snapshot between the break and SP */

/* The snapshot's RAM between the break (lo) and SP (hi) made equal to the board's, copied where it differs. */
static void sync_mid(sam_mcu_t *m, uint32_t lo, uint32_t hi)
{
    uint8_t *snap = m->ff.snap_ram;
    for (uint32_t a = lo; a < hi; a += SAM_FF_CHUNK) {
        uint32_t n = hi - a < SAM_FF_CHUNK ? hi - a : SAM_FF_CHUNK;
        if (memcmp(m->ram + a, snap + a, n))
            memcpy(snap + a, m->ram + a, n);
    }
}

int sam_ff_boundary(sam_mcu_t *m)
{
    sam_ff_t *f = &m->ff;
    if (f->resumed) {
        f->resumed = 0;
        return 0;
    }
    uint32_t regs[SAM_NCORE_REGS];
    void *ptrs[SAM_NCORE_REGS];
    for (int i = 0; i < SAM_NCORE_REGS; i++)
        ptrs[i] = &regs[i];
    uc_reg_read_batch(m->uc, (int *)sam_core_regs, ptrs, SAM_NCORE_REGS);
    /* The RAM a pass can leave changed is all of it: static data and the heap below the break, the live stack above
     * SP, and between them the free stack and objects at fixed addresses (the fault record at 0x20007800). A pass
     * parks only when the whole RAM is as it was at the previous entry. The part between the break and SP is mostly
     * free stack no pass touches and costs a compare of ~28 KB: it is kept in the snapshot (copied where it changed)
     * only while the board looks idle (its last compared pass parked); otherwise a pass that matches elsewhere takes
     * it then, and parks at the next entry if that pass changed nothing either (one pass later). */
    uint32_t lo = m->heap_base, hi = regs[13] - SAM_RAM_BASE;
    if (m->brk_var) {
        int ok = 0;
        uint32_t brk = sam_mem_read32(m, m->brk_var, &ok);
        if (ok && brk > SAM_RAM_BASE + lo && brk <= SAM_RAM_BASE + SAM_RAM_SIZE)
            lo = brk - SAM_RAM_BASE;
    }
    if (hi > SAM_RAM_SIZE || hi < lo)
        hi = lo;   /* SP outside SRAM (the core faults soon): [0, lo) and [lo, end) are the whole RAM */
    if (f->snap_valid && m->act == f->snap_act) {
        f->checks++;
        if (!memcmp(regs, f->snap_regs, sizeof regs) && !memcmp(m->cache_tag, f->snap_cache, sizeof m->cache_tag) &&
            !memcmp(m->ram, f->snap_ram, lo) && !memcmp(m->ram + hi, f->snap_ram + hi, SAM_RAM_SIZE - hi)) {
            if (f->mid_valid && !memcmp(m->ram + lo, f->snap_ram + lo, hi - lo)) {
                /* one whole pass changed nothing and met nothing: it repeats exactly until the next event */
                f->period = m->t - f->snap_t;
                f->period_cycles = m->cycles - f->snap_cycles;
                f->anchor = m->t;
                f->parked = 1;
                f->parks++;
                f->idle = 1;
                return 1;
            }
            if (!f->mid_valid) {   /* the rest of RAM from here; the snapshot is this entry's */
                sync_mid(m, lo, hi);
                f->mid_valid = 1;
                f->snap_t = m->t;
                f->snap_cycles = m->cycles;
                return 0;
            }
        }
        f->misses++;
        f->idle = 0;
    }
    memcpy(f->snap_regs, regs, sizeof regs);
    memcpy(f->snap_cache, m->cache_tag, sizeof m->cache_tag);
    memcpy(f->snap_ram, m->ram, lo);
    memcpy(f->snap_ram + hi, m->ram + hi, SAM_RAM_SIZE - hi);
    f->mid_valid = f->idle;   /* it parked last time it was compared: keep the rest of RAM in the snapshot too */
    if (f->mid_valid)
        sync_mid(m, lo, hi);
    f->snap_act = m->act;
    f->snap_t = m->t;
    f->snap_cycles = m->cycles;
    f->snap_valid = 1;
    return 0;
}

/* Parked until an event: resume at the last loop() entry before it (the pass it falls in runs); the passes
 * skipped ran, as far as anyone can tell. */
void sam_ff_resume(sam_mcu_t *m)
{
    uint64_t k = m->next_ev > m->ff.anchor ? (m->next_ev - m->ff.anchor) / m->ff.period : 0;
    m->t = m->ff.anchor + k * m->ff.period;
    m->ff.passes_skipped += k;
    m->cycles += k * m->ff.period_cycles;
    m->ff.cycles_skipped += k * m->ff.period_cycles;
    m->ff.parked = 0;
    m->ff.resumed = 1;
    m->prev_end = 0xFFFFFFFFu;
}
