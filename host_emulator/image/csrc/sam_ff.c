/* Fast-forward: a pass of loop() or of a polling loop that changed nothing and met no event repeats until the next event: skip it. */
#include <string.h>
#include "sam_core.h"

#define SAM_FF_CHUNK 1024u     /* bytes compared before a copy of the snapshot between the break and SP */
#define SAM_FF_QUIET 2000u     /* cycles without activity, outside loop(), after which a polling loop is looked for */
#define SAM_FF_HEAD_MISSES 4   /* arrivals at a polling head with other registers before it is given up */
#define SAM_FF_JCAP_MAX (1u << 20)
#define SAM_FF_JMIN 4u         /* fewest passes a probe must cover: below, it costs more than the passes it skips */
#define SAM_FF_KEEP 2048u      /* bytes below SP at the boundary never protected: a pass's calls and interrupts use them */
#define SAM_FF_PAGE 1024u      /* the CPU's TLB page (Unicorn's ARM: 1 KiB) */

/*
 * The boundary (f->head) is loop()'s entry, or, with timed passes on, a polling loop's block: the block that reads
 * a register SAM_FF_QUIET cycles after the board's last activity without it entering loop() (the primary's wait
 * for its I2C bus), or at once a block that parked before (f->known) when SAM_FF_JMIN of its passes fit before the
 * next event that may change what it reads (sam_next_loud). A pass is the code from one arrival at the boundary to
 * the next. A pass that left the registers, the NVM cache and the whole RAM as they were and had no activity (no
 * register write, no read that changes anything, no event, no interrupt) repeats exactly until the next event: the
 * board parks and its time jumps there (sam_ff_resume).
 *
 * A pass that read the time (SysTick VAL: m->tread) also left everything as it was, but a later pass reads a later
 * time and may branch otherwise (a deadline: `micros() - t0 > limit`). It is skipped only after a probe: the pass
 * starting J passes later (the last whole one before the next event, at most f->jcap) runs speculatively, making
 * exactly the register accesses the candidate pass made (a write, or a read the candidate did not make, stops it
 * before it happens), and must come back to the boundary in the same time with the same registers, cache and RAM.
 * The board is then rolled back and parked with the horizon t1 + (J + 1) P: the passes in between are those of
 * the two ends. A probe that fails is rolled back (registers, RAM, cache, time) and the pass runs. What this
 * assumes: each branch of the pass is a monotone function of the time it read (true of the deadline and
 * elapsed-time checks polling loops make, not of a loop that tests a bit of SysTick VAL); off with
 * `model_options.image.fast_forward_timed = false`. The probe runs before the events in its time are taken, so
 * none may be in it but bus steps that change nothing the pass can read (a slave holding SCL, or letting go of
 * it: link_i2c_bus.c, step_quiet), which a parked board takes without running: "the next event" above is the
 * next other one (sam_sched.c: sam_next_loud). The tier's schedule test checks every board's register changes,
 * times and plant trajectory bit for bit with it on and off.
 *
 * Most of the RAM compare is the free stack between the break and SP, which a pass hardly touches. From each
 * reference point (the state a compare is against) the whole 1 KiB pages of [break, SP - SAM_FF_KEEP) are read only
 * in the CPU's TLB (hook_tlb), and the compare skips them: a store there stops the CPU (UC_ERR_EXCEPTION, PC at the
 * store), sam_ff_ram_trap notes it (the next compare is a miss), lifts the protection and lets the store run; the
 * block it stopped in was charged whole before it ran, so its rest, translated as a block of its own, is not charged
 * again, nor is anything due taken before it (sam_cpu.c: cont_pc): the board's times are those of a run without the
 * stop. Writes into SRAM from C (exception frames, the USB controller's) count as such a store
 * (sam_ff_ram_written). A probe that stores there is stopped before the store happens and undone (the run loop),
 * so the protected pages are as they were: its compare and its rollback are of the rest of RAM (probe_ram_same,
 * probe_ram_restore).
 */

/* The protected pages (the header comment): none from here (a store reached one, or a reset). */
static void unprotect(sam_mcu_t *m)
{
    sam_ff_t *f = &m->ff;
    if (f->prot_lo < f->prot_hi) {
        f->prot_lo = f->prot_hi = 0;
        uc_ctl_flush_tlb(m->uc);
    }
}

/* A reference point (the state the next compare is against): the whole pages of [lo, hi - SAM_FF_KEEP) read only
 * from here, lo the break and hi SP. */
static void protect(sam_mcu_t *m, uint32_t lo, uint32_t hi)
{
    sam_ff_t *f = &m->ff;
    uint32_t plo = 0, phi = 0;
    if (hi >= lo + SAM_FF_KEEP) {
        plo = (lo + SAM_FF_PAGE - 1u) & ~(SAM_FF_PAGE - 1u);
        phi = (hi - SAM_FF_KEEP) & ~(SAM_FF_PAGE - 1u);
        if (phi <= plo)
            plo = phi = 0;
    }
    if (plo != f->prot_lo || phi != f->prot_hi) {
        int flush = f->prot_lo < f->prot_hi || plo < phi;   /* TLB entries made under the old pages go */
        f->prot_lo = plo;
        f->prot_hi = phi;
        if (flush)
            uc_ctl_flush_tlb(m->uc);
    }
    f->ref_lo = plo;
    f->ref_hi = phi;
    f->mid_dirty = 0;
}

void sam_ff_ram_written(sam_mcu_t *m) { m->ff.mid_dirty = 1; }

int sam_ff_ram_trap(sam_mcu_t *m)
{
    sam_ff_t *f = &m->ff;
    if (f->prot_lo >= f->prot_hi)
        return 0;
    /* the store runs when the CPU starts again, the pages writable (any other cause of the stop recurs then, and
     * is taken as it would have been); the rest of its block was charged with it (sam_cpu.c: cont_pc) */
    unprotect(m);
    f->mid_dirty = 1;
    f->traps++;
    m->cont_pc = sam_cpu_reg(m, UC_ARM_REG_PC) & ~1u;
    m->next_ev = 0;   /* (sam_next_event keeps it there until the block hook has seen the rest) */
    return 1;
}

static void sync_range(sam_mcu_t *m, uint32_t lo, uint32_t hi)
{
    uint8_t *snap = m->ff.snap_ram;
    for (uint32_t a = lo; a < hi; a += SAM_FF_CHUNK) {
        uint32_t n = hi - a < SAM_FF_CHUNK ? hi - a : SAM_FF_CHUNK;
        if (memcmp(m->ram + a, snap + a, n))
            memcpy(snap + a, m->ram + a, n);
    }
}

/* The pages protected since the reference point, inside [lo, hi): whether there are any. */
static int protected_in(const sam_ff_t *f, uint32_t lo, uint32_t hi)
{
    return f->ref_lo < f->ref_hi && lo <= f->ref_lo && f->ref_hi <= hi;
}

/* The snapshot's RAM between the break (lo) and SP (hi) made equal to the board's, copied where it differs; the
 * pages protected from this reference point on need no copy: they are compared by their protection. */
static void sync_mid(sam_mcu_t *m, uint32_t lo, uint32_t hi)
{
    sam_ff_t *f = &m->ff;
    if (protected_in(f, lo, hi)) {
        sync_range(m, lo, f->ref_lo);
        sync_range(m, f->ref_hi, hi);
    } else {
        sync_range(m, lo, hi);
    }
}

/* RAM between the break and SP as the snapshot holds it: outside the protected pages, which no store reached since
 * the reference point (a stopped store, or one from C, makes it a miss), or all of it when none were. */
static int mid_same(sam_mcu_t *m, uint32_t lo, uint32_t hi)
{
    sam_ff_t *f = &m->ff;
    if (f->ref_lo < f->ref_hi) {
        if (f->mid_dirty || !protected_in(f, lo, hi))
            return 0;
        return !memcmp(m->ram + lo, f->snap_ram + lo, f->ref_lo - lo) &&
               !memcmp(m->ram + f->ref_hi, f->snap_ram + f->ref_hi, hi - f->ref_hi);
    }
    return !memcmp(m->ram + lo, f->snap_ram + lo, hi - lo);
}

/* The RAM a probe may have changed, as the snapshot holds it: all of it but the pages protected since the reference
 * point, where a store stops the probe before it happens (the run loop), so they are as they were. */
static int probe_ram_same(sam_mcu_t *m)
{
    const sam_ff_t *f = &m->ff;
    if (f->ref_lo < f->ref_hi)
        return !f->mid_dirty && !memcmp(m->ram, f->snap_ram, f->ref_lo) &&
               !memcmp(m->ram + f->ref_hi, f->snap_ram + f->ref_hi, SAM_RAM_SIZE - f->ref_hi);
    return !memcmp(m->ram, f->snap_ram, SAM_RAM_SIZE);
}

static void probe_ram_restore(sam_mcu_t *m)
{
    const sam_ff_t *f = &m->ff;
    if (f->ref_lo < f->ref_hi) {
        memcpy(m->ram, f->snap_ram, f->ref_lo);
        memcpy(m->ram + f->ref_hi, f->snap_ram + f->ref_hi, SAM_RAM_SIZE - f->ref_hi);
    } else {
        memcpy(m->ram, f->snap_ram, SAM_RAM_SIZE);
    }
}

/* Give up a polling head: loop() is the boundary again, and no other head is looked for until the board does
 * something. */
static void drop_head(sam_ff_t *f)
{
    f->head = f->loop_pc;
    f->q_dead = 1;
}

/* A new quiet stretch starts (the board did something, or entered loop()): loop()'s entry is the boundary again. */
static void quiet_start(sam_mcu_t *m)
{
    sam_ff_t *f = &m->ff;
    f->q_act = m->act;
    f->q_t = m->t;
    f->q_dead = 0;
    f->head = f->loop_pc;
}

void sam_ff_loop_entry(sam_mcu_t *m) { quiet_start(m); }

/* A pass starts at the boundary now (t, cycles): the snapshot's time and time reads are its start's, the record of
 * its register accesses empty. */
static void pass_starts(sam_mcu_t *m, uint64_t t, uint64_t cycles)
{
    sam_ff_t *f = &m->ff;
    f->snap_t = t;
    f->snap_cycles = cycles;
    f->snap_tread = m->tread;
    f->rec_n = 0;
}

/* A register access with timed passes on (the pass's record; a polling loop is found here, where it reads its
 * register: no cost per block). */
void sam_ff_access(sam_mcu_t *m, uint32_t key)
{
    sam_ff_t *f = &m->ff;
    if (f->rec_n < SAM_FF_REC)
        f->rec[f->rec_n] = key;
    f->rec_n++;
    if (key & 1u)
        return;
    if (m->act != f->q_act)   /* the board did something */
        quiet_start(m);
    if (f->head != f->loop_pc || f->q_dead || m->blk == f->loop_pc)
        return;
    int k = m->blk == f->known[0] ? 0 : m->blk == f->known[1] ? 1 : -1;
    if (k >= 0 || m->t - f->q_t > (uint64_t)SAM_FF_QUIET * m->cyc_tu) {
        /* a known polling loop, worth it only with room for SAM_FF_JMIN passes before the next event */
        uint64_t loud = sam_next_loud(m);
        if (k >= 0 && loud != SAM_NEVER && loud - m->t < SAM_FF_JMIN * f->known_period[k])
            return;
        f->head = m->blk;   /* (poll_regs stay: a known head's registers are often those of its last wait) */
        f->head_misses = 0;
    }
}

int sam_ff_probe_access(sam_mcu_t *m, uint32_t key)
{
    sam_ff_t *f = &m->ff;
    if (!f->probe_bad && !(key & 1u) && f->probe_n < f->cand_n && f->cand[f->probe_n] == key) {
        f->probe_n++;
        return 1;
    }
    f->probe_bad = 1;   /* a write, or not the candidate's next access: it does not happen */
    uc_emu_stop(m->uc);
    return 0;
}

/* A polling head that parked: found again at its first register read next time. */
static void remember(sam_ff_t *f, uint32_t head, uint64_t period)
{
    if (f->known[0] != head) {
        f->known[1] = f->known[0];
        f->known_period[1] = f->known_period[0];
        f->known[0] = head;
    }
    f->known_period[0] = period;
}

/* Start the probe at a boundary where the pass just ended repeated the one before it but read the time: the pass J
 * passes on runs now, speculatively. 0: no probe (too little time before the next event); the pass runs. */
static int probe_start(sam_mcu_t *m, uint64_t period, uint64_t period_cycles)
{
    sam_ff_t *f = &m->ff;
    uint64_t t1 = m->t, loud = sam_next_loud(m);
    if (f->rec_n > SAM_FF_REC || loud <= t1 + SAM_FF_JMIN * period)
        return 0;
    /* t1 + (J + 1) P < loud: nothing in the probe's time but steps that change nothing the pass can see (sam_sched.c:
     * sam_next_loud), which it then need not have taken */
    uint64_t j = (loud - 1 - t1 - period) / period;
    if (j > f->jcap)
        j = f->jcap;
    if (j < SAM_FF_JMIN - 1)
        return 0;   /* a probe costs about as much as a few passes: not worth it for fewer */
    memcpy(f->cand, f->rec, sizeof f->rec);
    f->cand_n = f->rec_n;
    f->probe_n = 0;
    f->probe_bad = 0;
    f->pr_t1 = t1;
    f->pr_c1 = m->cycles;
    f->pr_stop = m->stop_at;
    f->pr_act = m->act;
    f->pr_tread = m->tread;
    f->period = period;
    f->period_cycles = period_cycles;
    m->t = t1 + j * period;
    m->cycles += j * period_cycles;
    f->pr_end = m->t + period;
    f->probing = 1;
    m->next_ev = 0;   /* the block hook's first test then sees the probe (no event is due before pr_end) */
    f->probes++;
    return 1;
}

/* The probe ends: at the boundary (compared there), or astray. The board is back at t1 either way; parked when
 * the probe held. One that failed is undone once the CPU has stopped (stopped = 1: from the run loop): the
 * registers written from the block hook would not hold, Unicorn setting the PC back to the block's start when it
 * stops there. */
int sam_ff_probe_end(sam_mcu_t *m, int at_head, int stopped)
{
    sam_ff_t *f = &m->ff;
    int held = 0;
    if (at_head && !f->probe_bad && m->t == f->pr_end && f->probe_n == f->cand_n && m->act == f->pr_act &&
        m->cycles - f->pr_c1 == (f->pr_end - f->pr_t1) / f->period * f->period_cycles) {
        uint32_t regs[SAM_NCORE_REGS];
        sam_cpu_core_read(m, regs);
        held = !memcmp(regs, f->snap_regs, sizeof regs) && !memcmp(m->cache_tag, f->snap_cache, sizeof m->cache_tag) &&
               probe_ram_same(m);
    }
    if (!held && !stopped) {
        f->probe_bad = 1;
        return 0;
    }
    f->probing = 0;
    sam_next_event(m);   /* (0 while probing) */
    m->stop_at = f->pr_stop;
    m->t = m->t_blk = f->pr_t1;
    m->cycles = f->pr_c1;
    m->act = f->pr_act;
    m->tread = f->pr_tread;
    m->prev_end = 0xFFFFFFFFu;
    if (held) {
        if (f->head != f->loop_pc)
            remember(f, f->head, f->period);
        f->anchor = f->pr_t1;
        f->horizon = f->pr_end;
        f->parked = 1;
        f->parks++;
        f->idle = 1;
        if (f->jcap < SAM_FF_JCAP_MAX)
            f->jcap *= 2;
        return 1;
    }
    /* astray: what the probe changed is undone (it wrote no register: each access was checked before it happened) */
    void *ptrs[SAM_NCORE_REGS];
    for (int i = 0; i < SAM_NCORE_REGS; i++)
        ptrs[i] = &f->snap_regs[i];
    uc_reg_write_batch(m->uc, (int *)sam_core_regs, ptrs, SAM_NCORE_REGS);
    memcpy(m->cache_tag, f->snap_cache, sizeof m->cache_tag);
    probe_ram_restore(m);
    f->probe_fails++;
    f->jcap = f->jcap > 16 ? f->jcap / 8 : 2;
    f->resumed = 1;   /* the pass from t1 runs, unchecked at its first boundary */
    return 0;
}

int sam_ff_boundary(sam_mcu_t *m)
{
    sam_ff_t *f = &m->ff;
    if (f->resumed) {   /* at the snapshot's state (parked there, or a probe rolled back): a pass starts now */
        f->resumed = 0;
        pass_starts(m, m->t, m->cycles);
        return 0;
    }
    uint32_t regs[SAM_NCORE_REGS];
    sam_cpu_core_read(m, regs);
    int poll = f->head != f->loop_pc;
    if (poll && !(f->regs_valid && !memcmp(regs, f->poll_regs, sizeof regs))) {
        /* a polling head: the registers alone until they repeat (a loop that computes costs a register read per
         * arrival, never a copy of RAM) */
        memcpy(f->poll_regs, regs, sizeof regs);
        f->regs_valid = 1;
        f->rec_n = 0;
        if (++f->head_misses > SAM_FF_HEAD_MISSES)
            drop_head(f);
        return 0;
    }
    /* The RAM a pass can leave changed is all of it: static data and the heap below the break, the live stack above
     * SP, and between them the free stack and objects at fixed addresses (the fault record at 0x20007800). A pass
     * parks only when the whole RAM is as it was at the previous entry. The part between the break and SP is mostly
     * free stack no pass touches and costs a compare of ~28 KB: it is kept in the snapshot (copied where it changed)
     * only while the board looks idle (its last compared pass parked) or at a polling head; otherwise a pass that
     * matches elsewhere takes it then, and parks at the next entry if that pass changed nothing either (one pass
     * later). */
    uint32_t lo = m->heap_base, hi = regs[13] - SAM_RAM_BASE;
    if (m->brk_var) {
        int ok = 0;
        uint32_t brk = sam_mem_read32(m, m->brk_var, &ok);
        if (ok && brk > SAM_RAM_BASE + lo && brk <= SAM_RAM_BASE + SAM_RAM_SIZE)
            lo = brk - SAM_RAM_BASE;
    }
    if (hi > SAM_RAM_SIZE || hi < lo)
        hi = lo;   /* SP outside SRAM (the core faults soon): [0, lo) and [lo, end) are the whole RAM */
    if (f->snap_valid && f->snap_head == f->head && m->act == f->snap_act && (f->timed || m->tread == f->snap_tread)) {
        f->checks++;
        if (!memcmp(regs, f->snap_regs, sizeof regs) && !memcmp(m->cache_tag, f->snap_cache, sizeof m->cache_tag) &&
            !memcmp(m->ram, f->snap_ram, lo) && !memcmp(m->ram + hi, f->snap_ram + hi, SAM_RAM_SIZE - hi)) {
            if (f->mid_valid && mid_same(m, lo, hi)) {
                uint64_t period = m->t - f->snap_t, period_cycles = m->cycles - f->snap_cycles;
                if (m->tread != f->snap_tread) {
                    /* it read the time (only compared with timed passes on): skipped only once a probe shows a
                     * later pass is the same */
                    uint64_t t1 = m->t, c1 = m->cycles;
                    probe_start(m, period, period_cycles);   /* when it starts, the time is the probe's from here */
                    pass_starts(m, t1, c1);
                    return 0;
                }
                /* one whole pass changed nothing and met nothing: it repeats exactly until the next event */
                if (poll)
                    remember(f, f->head, period);
                f->period = period;
                f->period_cycles = period_cycles;
                f->anchor = m->t;
                f->horizon = SAM_NEVER;
                f->parked = 1;
                f->parks++;
                f->idle = 1;
                return 1;
            }
            if (!f->mid_valid) {   /* the rest of RAM from here; the snapshot is this entry's */
                protect(m, lo, hi);
                sync_mid(m, lo, hi);
                f->mid_valid = 1;
                pass_starts(m, m->t, m->cycles);
                return 0;
            }
        }
        f->misses++;
        f->idle = 0;
        if (poll && ++f->head_misses > SAM_FF_HEAD_MISSES) {
            drop_head(f);
            f->rec_n = 0;
            return 0;
        }
    }
    memcpy(f->snap_regs, regs, sizeof regs);
    memcpy(f->snap_cache, m->cache_tag, sizeof m->cache_tag);
    memcpy(f->snap_ram, m->ram, lo);
    memcpy(f->snap_ram + hi, m->ram + hi, SAM_RAM_SIZE - hi);
    protect(m, lo, hi);
    f->mid_valid = f->idle || poll;   /* it parked last time it was compared, or a polling loop: the rest of RAM too */
    if (f->mid_valid)
        sync_mid(m, lo, hi);
    f->snap_act = m->act;
    f->snap_valid = 1;
    f->snap_head = f->head;
    pass_starts(m, m->t, m->cycles);
    return 0;
}

/* Parked until an event, or a probed pass's horizon: resume at the last boundary before it (the pass it falls in
 * runs); the passes skipped ran, as far as anyone can tell. */
void sam_ff_resume(sam_mcu_t *m)
{
    uint64_t until = m->next_ev < m->ff.horizon ? m->next_ev : m->ff.horizon;
    uint64_t k = until > m->ff.anchor ? (until - m->ff.anchor) / m->ff.period : 0;
    m->t = m->ff.anchor + k * m->ff.period;
    m->ff.passes_skipped += k;
    m->cycles += k * m->ff.period_cycles;
    m->ff.cycles_skipped += k * m->ff.period_cycles;
    m->ff.parked = 0;
    m->ff.resumed = 1;
    m->prev_end = 0xFFFFFFFFu;
}
