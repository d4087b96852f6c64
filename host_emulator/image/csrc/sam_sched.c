/* Time and scheduling of a board: event slots and sources, events in time order, the run loop (and its idle forms). */
#include "sam_core.h"

/* ---------------------------------------------------------------- events */

void sam_next_event(sam_mcu_t *m)
{
    uint64_t t = sam_slot_earliest(m, -1);
    /* a probe, or the rest of a block to come after a stopped store, holds it at 0: the block hook sees them there
     * (sam_ff.c) */
    m->next_ev = m->ff.probing || m->cont_pc != 0xFFFFFFFFu ? 0 : t;
}

/* When the next event that may change what the board's software sees is due: the next event, past the bus steps
 * that are quiet (link_i2c_bus.c: sam_bus_next_loud), which a parked board takes without running (stays_parked). */
uint64_t sam_next_loud(sam_mcu_t *m)
{
    int bs = m->w->bus.slot[m->id];
    uint64_t t = sam_slot_earliest(m, bs >= SAM_SLOT_SOURCE0 ? bs : -1);
    if (bs >= SAM_SLOT_SOURCE0 && m->slot[bs] < t) {
        uint64_t b = sam_bus_next_loud(m);
        if (b < t)
            t = b;
    }
    return t;
}

void sam_slot_set(sam_mcu_t *m, int slot, uint64_t t)
{
    uint64_t old = m->slot[slot];
    m->slot[slot] = t;
    if (t != SAM_NEVER)
        m->slot_live |= 1ull << slot;
    else
        m->slot_live &= ~(1ull << slot);
    if (t < m->next_ev)
        m->next_ev = t;
    else if (old == m->next_ev && t != old)
        sam_next_event(m);
}

int sam_source_add(sam_mcu_t *m, void (*fire)(sam_mcu_t *m, void *ctx),
                   void (*quiet)(sam_mcu_t *m, void *ctx, uint64_t t_end), void *ctx, unsigned flags)
{
    if (m->nsrc >= SAM_MAX_SOURCES)
        return -1;
    sam_source_t *x = &m->src[m->nsrc];
    x->fire = fire;
    x->quiet = quiet;
    x->ctx = ctx;
    x->flags = flags;
    return SAM_SLOT_SOURCE0 + m->nsrc++;
}

static void fire_slot(sam_mcu_t *m, int s)
{
    if (s < SAM_MAX_PERIPH) {
        if (m->model[s] && m->model[s]->fire)
            m->model[s]->fire(m, s);
    } else if (s == SAM_SLOT_SYSTICK) {
        sam_systick_fire(m);
    } else if (s - SAM_SLOT_SOURCE0 < m->nsrc) {
        const sam_source_t *x = &m->src[s - SAM_SLOT_SOURCE0];
        x->fire(m, x->ctx);
    }
}

/* Every event due at or before the current boundary, in time order, each at its own time. */
void sam_process_events(sam_mcu_t *m)
{
    uint64_t saved = m->t_blk;
    while (m->next_ev <= m->t && m->next_ev < m->stop_at && !m->err && !m->in_reset) {
        int s = sam_slot_first(m, -1);   /* (one is set: next_ev <= t) */
        uint64_t ts = m->slot[s];
        m->slot[s] = SAM_NEVER;
        m->slot_live &= ~(1ull << s);
        sam_next_event(m);
        m->t_blk = ts;
        m->ev_quiet = 0;
        fire_slot(m, s);
        if (!m->ev_quiet)
            m->act++;
    }
    m->t_blk = saved;
}

/* Events only (the core is stopped: lockup): peripherals keep running, a watchdog may reset the board. */
static void run_events_only(sam_mcu_t *m)
{
    while (m->next_ev < m->stop_at && !m->err && !m->in_reset) {
        m->t = m->next_ev;
        sam_process_events(m);
    }
    if (m->t < m->stop_at && !m->in_reset)
        m->t = m->stop_at;
}

/* No power: nothing runs; the sources that fire unpowered still do (the bus sees the board as an absent slave, the
 * encoders still turn); on a tie the later registered first (the pins' edges do nothing to an unpowered board). */
static void run_unpowered(sam_mcu_t *m)
{
    for (;;) {
        int s = -1;
        for (int k = 0; k < m->nsrc; k++)
            if ((m->src[k].flags & SAM_SRC_UNPOWERED) && (s < 0 || m->slot[SAM_SLOT_SOURCE0 + k] <= m->slot[s]))
                s = SAM_SLOT_SOURCE0 + k;
        if (s < 0)
            break;
        uint64_t ts = m->slot[s];
        if (ts >= m->stop_at || m->err)
            break;
        sam_slot_set(m, s, SAM_NEVER);
        m->t_blk = ts;
        fire_slot(m, s);
    }
    if (m->t < m->stop_at)
        m->t = m->stop_at;
}

/* Parked: the steps before t_end that change nothing (an address that is not its own) are taken as they would
 * be; it stays parked when no other event comes before t_end. */
static int stays_parked(sam_mcu_t *m, uint64_t t_end)
{
    /* a pass that reads the time was proved the same only up to its horizon (sam_ff.c): the quiet steps before it
     * are taken, and the board runs from there */
    uint64_t lim = m->ff.horizon < t_end ? m->ff.horizon : t_end;
    if (m->next_ev < lim)
        for (int k = 0; k < m->nsrc; k++)
            if (m->src[k].quiet)
                m->src[k].quiet(m, m->src[k].ctx, lim);
    return m->ff.horizon >= t_end && m->next_ev >= t_end;
}

/* A parked board that stays parked until t_end has run to it (1); 0: it needs to run. */
int sam_mcu_idle_to(sam_mcu_t *m, uint64_t t_end)
{
    if (m->err || m->halted || !m->ff.parked || !stays_parked(m, t_end))
        return 0;
    m->pos = t_end;
    return 1;
}

/* Run the board until t_end, or until the earlier time it was told to stop before (sam_stop_before): m->pos. */
int sam_mcu_run(sam_mcu_t *m, uint64_t t_end)
{
    if (m->err)
        return -1;
    m->stop_at = t_end;
    if (m->halted) {
        run_unpowered(m);
        m->pos = m->stop_at;
        return m->err ? -1 : 0;
    }
    while (!m->err) {
        if (m->ff.parked) {
            if (stays_parked(m, m->stop_at))
                break;   /* the pass repeats unchanged up to stop_at */
            sam_ff_resume(m);
        }
        if (m->t >= m->stop_at && m->cont_pc == 0xFFFFFFFFu) {
            /* (the rest of a block a stopped store split runs first: it was charged with the block) A step that
             * arrived behind the board's time (its last block ran past the time it was let run to, or the harness
             * ran it on alone) is taken now, as the next block's hook would: otherwise its answer, which others
             * may wait for, would wait for a run that never comes */
            if (m->next_ev <= m->t)
                sam_process_events(m);
            break;
        }
        if (m->in_reset) {
            sam_do_reset(m, (uint8_t)m->in_reset);
            continue;
        }
        if (m->lockup) {
            run_events_only(m);
            continue;
        }
        uint32_t pc = sam_cpu_reg(m, UC_ARM_REG_PC);
        m->runs++;
        uc_err e = uc_emu_start(m->uc, pc | 1u, 0, 0, 0);
        if (m->ff.probing) {   /* a speculative pass stopped astray (an access refused, a fault, a store to a page the
                                * fast-forward protects, which does not happen): undone */
            sam_ff_probe_end(m, 0, 1);
            continue;
        }
        if (m->err)
            break;
        if (e == UC_ERR_FETCH_PROT && (pc = sam_cpu_reg(m, UC_ARM_REG_PC)) >= SAM_RAM_BASE &&
            pc < SAM_RAM_BASE + SAM_RAM_SIZE) {
            sam_fail(m, "code executed from SRAM at 0x%08x: only flash has a cycle model", pc);
            break;
        }
        if ((e == UC_ERR_WRITE_PROT || e == UC_ERR_EXCEPTION) && sam_nvm_cpu_store(m))
            continue;   /* a store to flash: into NVMCTRL's page buffer */
        if ((e == UC_ERR_WRITE_PROT || e == UC_ERR_EXCEPTION) && sam_pac_store(m))
            continue;   /* a store to a page the PAC traps: to a PAC's register, or a bus error (sam_pac.c) */
        if ((e == UC_ERR_WRITE_PROT || e == UC_ERR_EXCEPTION) && sam_ff_ram_trap(m))
            continue;   /* a store to an SRAM page the fast-forward protects: noted, let through (sam_ff.c) */
        if (e != UC_ERR_OK)
            sam_cpu_enter_fault(m, e);
    }
    m->pos = m->stop_at;
    return m->err ? -1 : 0;
}
