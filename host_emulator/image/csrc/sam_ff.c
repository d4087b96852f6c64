/* Fast-forward: a loop() pass that changed nothing and met no event repeats exactly until the next event: skip it. */
#include <string.h>
#include "sam_core.h"

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
    /* The RAM a pass can leave changed: static data and the heap up to its break, and the live stack above SP.
     * RAM below SP at a loop() entry is free stack: whatever a pass leaves there is never read before written. */
    uint32_t lo = m->heap_base, hi = regs[13] - SAM_RAM_BASE;
    if (m->brk_var) {
        int ok = 0;
        uint32_t brk = sam_mem_read32(m, m->brk_var, &ok);
        if (ok && brk > SAM_RAM_BASE + lo && brk <= SAM_RAM_BASE + SAM_RAM_SIZE)
            lo = brk - SAM_RAM_BASE;
    }
    if (hi > SAM_RAM_SIZE || hi < lo)
        hi = lo;   /* SP outside SRAM (the core faults soon): the whole RAM counts */
    if (f->snap_valid && m->act == f->snap_act) {
        f->checks++;
        if (!memcmp(regs, f->snap_regs, sizeof regs) && !memcmp(m->cache_tag, f->snap_cache, sizeof m->cache_tag) &&
            lo == f->snap_lo && !memcmp(m->ram, f->snap_ram, lo) &&
            !memcmp(m->ram + hi, f->snap_ram + hi, SAM_RAM_SIZE - hi)) {
            /* one whole pass changed nothing and met nothing: it repeats exactly until the next event */
            f->period = m->t - f->snap_t;
            f->period_cycles = m->cycles - f->snap_cycles;
            f->anchor = m->t;
            f->parked = 1;
            f->parks++;
            return 1;
        }
        f->misses++;
    }
    memcpy(f->snap_regs, regs, sizeof regs);
    memcpy(f->snap_cache, m->cache_tag, sizeof m->cache_tag);
    memcpy(f->snap_ram, m->ram, lo);
    memcpy(f->snap_ram + hi, m->ram + hi, SAM_RAM_SIZE - hi);
    f->snap_lo = lo;
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
