/* Exceptions (ARMv6-M, a software NVIC): priorities, pending and active bits, entry, return and tail-chaining. */
#include <stdio.h>
#include "sam_core.h"

static int exc_prio(const sam_mcu_t *m, int e)
{
    const sam_nvic_t *n = &m->nvic;
    switch (e) {
    case 2: return -2;
    case 3: return -1;
    case 11: return n->prio_svc;
    case 14: return n->prio_pendsv;
    case 15: return n->prio_systick;
    default: return e >= 16 && e < 48 ? n->prio[e - 16] : 4;
    }
}

/* Execution priority of the active exceptions (4: thread mode, none active), before PRIMASK. */
int sam_nvic_exec_prio(const sam_mcu_t *m)
{
    int p = 4;
    for (int e = 2; e < 16; e++)
        if (m->nvic.sys_active & (1u << e) && exc_prio(m, e) < p)
            p = exc_prio(m, e);
    uint32_t a = m->nvic.active;
    while (a) {
        int i = __builtin_ctz(a);
        a &= a - 1;
        if (m->nvic.prio[i] < p)
            p = m->nvic.prio[i];
    }
    return p;
}

/* The highest-priority pending exception (lowest number on a tie), or 0. */
int sam_nvic_best_pending(const sam_mcu_t *m, int *prio)
{
    int best = 0, bp = 5;
    uint32_t s = m->nvic.sys_pending;
    while (s) {
        int e = __builtin_ctz(s);
        s &= s - 1;
        if (exc_prio(m, e) < bp) {
            bp = exc_prio(m, e);
            best = e;
        }
    }
    uint32_t x = m->nvic.pending & m->nvic.enabled;
    while (x) {
        int i = __builtin_ctz(x);
        x &= x - 1;
        if (m->nvic.prio[i] < bp) {
            bp = m->nvic.prio[i];
            best = 16 + i;
        }
    }
    *prio = bp;
    return best;
}

void sam_irq_level(sam_mcu_t *m, int irq, int on)
{
    if (irq < 0 || irq > 31)   /* no line (sam_regtab_check admits -1 .. 31 only) */
        return;
    uint32_t bit = 1u << irq;
    if (on) {
        if (!(m->nvic.level & bit)) {
            m->nvic.level |= bit;
            m->nvic.pending |= bit;   /* a rising request pends the interrupt */
            m->irq_check = 1;
        }
    } else {
        m->nvic.level &= ~bit;        /* a pending state stays latched */
    }
}

void sam_irq_pend_sys(sam_mcu_t *m, int exc)
{
    if (exc < 0 || exc > 15)
        return;
    m->nvic.sys_pending |= 1u << exc;
    m->irq_check = 1;
}

/* Mark exception e pending (on = 1) or not, and active (on = 1) or not: the NVIC's bits for IRQs, SCB's for the
 * system exceptions. */
static void set_pending(sam_mcu_t *m, int e, int on)
{
    uint32_t *bits = e >= 16 ? &m->nvic.pending : &m->nvic.sys_pending;
    uint32_t bit = 1u << (e >= 16 ? e - 16 : e);
    *bits = on ? *bits | bit : *bits & ~bit;
}

static void set_active(sam_mcu_t *m, int e, int on)
{
    uint32_t *bits = e >= 16 ? &m->nvic.active : &m->nvic.sys_active;
    uint32_t bit = 1u << (e >= 16 ? e - 16 : e);
    *bits = on ? *bits | bit : *bits & ~bit;
}

/* Take exception e's vector: read it from the table at VTOR (lockup, 0, when unreadable or not Thumb), then e
 * leaves pending and becomes active. The first step of every entry: a fresh one, a late arrival, a tail-chain. */
static int take_vector(sam_mcu_t *m, int e, uint32_t *vec)
{
    int ok = 0;
    *vec = sam_mem_read32(m, m->nvic.vtor + 4u * (uint32_t)e, &ok);
    if (!ok || !(*vec & 1u)) {
        sam_cpu_lockup(m, "exception vector unreadable or not Thumb");
        return 0;
    }
    set_pending(m, e, 0);
    set_active(m, e, 1);
    if (e == 3)
        m->hardfaults++;
    return 1;
}

/* The last step of every entry: IPSR = e, the handler's first instruction next, e recorded as being entered. */
static void run_handler(sam_mcu_t *m, int e, uint32_t vec)
{
    sam_cpu_set(m, UC_ARM_REG_IPSR, (uint32_t)e);
    sam_cpu_rebuild_hflags(m);
    sam_cpu_set(m, UC_ARM_REG_PC, vec);
    m->nvic.entering = (uint8_t)e;
    m->irq_check = 1;
}

/* Trace line of an entry into e from context `from` at address ret (late = the exception left pending by a late
 * arrival, 0 for none): trace bit 3 in microseconds, bit 5 in time units. */
static void trace_enter(sam_mcu_t *m, int e, uint32_t from, uint32_t ret, int late)
{
    if (!(m->w->cfg.trace_boards >> m->id & 1))
        return;
    char tail[48] = "";
    if (late)
        snprintf(tail, sizeof tail, " (late arrival: %d pending)", late);
    if (m->w->cfg.trace & 8)
        sam_note(m, "exc %.3f us %s enter %d from %u at 0x%05x%s", (double)m->t * 1e6 / (double)SAM_TU_HZ, m->name,
                 e, from, ret, tail);
    else if (m->w->cfg.trace & 32)
        sam_note(m, "chg %llu %s enter %d from %u at 0x%05x%s", (unsigned long long)m->t, m->name, e, from, ret,
                 tail);
}

/* Stack the caller-saved frame and enter exception e; ret = address of the next instruction. 1 on success. */
int sam_nvic_enter(sam_mcu_t *m, int e, uint32_t ret)
{
    uint32_t r[SAM_NCORE_REGS];
    sam_cpu_core_read(m, r);
    uint32_t sp = r[SAM_CORE_SP], xpsr = r[SAM_CORE_XPSR], ipsr = xpsr & 0x3Fu;
    uint32_t frame = sp - 32u, stacked_xpsr = (xpsr & ~(1u << 9)) | (1u << 24);
    if (frame & 4u) {   /* 8-byte aligned frames (CCR.STKALIGN): xPSR bit 9 records the padding */
        frame -= 4u;
        stacked_xpsr |= 1u << 9;
    }
    const uint32_t words[8] = {r[0], r[1], r[2], r[3], r[SAM_CORE_R12], r[SAM_CORE_LR], ret & ~1u, stacked_xpsr};
    for (int i = 0; i < 8; i++)
        if (!sam_cpu_ram_write32(m, frame + 4u * (uint32_t)i, words[i])) {
            sam_cpu_lockup(m, "exception stack frame outside SRAM");
            return 0;
        }
    uint32_t vec;
    if (!take_vector(m, e, &vec))
        return 0;
    trace_enter(m, e, ipsr, ret, 0);
    sam_cpu_set(m, UC_ARM_REG_SP, frame);
    sam_cpu_set(m, UC_ARM_REG_LR, ipsr ? EXC_RETURN_HANDLER : EXC_RETURN_THREAD);
    run_handler(m, e, vec);
    m->t += (uint64_t)EXC_ENTRY_CYCLES * m->cyc_tu;
    m->cycles += EXC_ENTRY_CYCLES;
    m->act++;
    return 1;
}

/* Late arrival (ARMv6-M B1.5.12; the Cortex-M0+ implements it): an exception of higher priority than the one being
 * entered that becomes pending before that entry ends (here: an event processed at the handler's first
 * instruction, which falls due during the entry's cycles) is entered instead, on the same frame and at no extra
 * cost; the first stays pending, its handler runs after (tail-chained) unless it is pre-empted again. */
static void late_arrival(sam_mcu_t *m, int e0, int e)
{
    uint32_t vec;
    if (!take_vector(m, e, &vec))
        return;
    set_active(m, e0, 0);
    set_pending(m, e0, 1);
    uint32_t sp = sam_cpu_reg(m, UC_ARM_REG_SP);
    uint32_t ret = sam_mem_read32(m, sp + 24u, NULL), from = sam_mem_read32(m, sp + 28u, NULL) & 0x3Fu;
    trace_enter(m, e, from, ret, e0);
    run_handler(m, e, vec);
    m->act++;
}

/* Take the best pending exception if it may pre-empt now; ret = where the interrupted code resumes. */
int sam_nvic_take(sam_mcu_t *m, uint32_t ret)
{
    int bp;
    int e = sam_nvic_best_pending(m, &bp);
    m->irq_check = 0;
    m->primask_wait = 0;
    if (!e)
        return 0;
    int ap = sam_nvic_exec_prio(m);
    if (bp >= ap)
        return 0;   /* re-evaluated when an exception returns */
    if (bp >= 0 && sam_cpu_reg(m, UC_ARM_REG_PRIMASK) & 1u) {
        m->primask_wait = 1;   /* CPSIE ends its translation block: checked at every block until taken */
        return 0;
    }
    int e0 = m->nvic.entering;
    if (e0) {   /* still at the first instruction of e0's handler: its entry has just ended */
        late_arrival(m, e0, e);
        return 1;
    }
    return sam_nvic_enter(m, e, ret);
}

/* An exception return (Unicorn raises EXCP_EXCEPTION_EXIT for a branch to EXC_RETURN in handler mode). */
void sam_nvic_return(sam_mcu_t *m)
{
    uint32_t excret = sam_cpu_reg(m, UC_ARM_REG_PC) | 1u;
    uint32_t xpsr_now = sam_cpu_reg(m, UC_ARM_REG_XPSR);
    int e = (int)(xpsr_now & 0x3Fu);
    if (excret != EXC_RETURN_THREAD && excret != EXC_RETURN_HANDLER) {
        sam_fail(m, "exception return 0x%08x (only the main stack is modelled)", excret);
        return;
    }
    /* deactivate e; an interrupt still requested is pending again */
    set_active(m, e, 0);
    if (e >= 16 && m->nvic.level & (1u << (e - 16)))
        set_pending(m, e, 1);
    uint32_t sp = sam_cpu_reg(m, UC_ARM_REG_SP);
    int ok = 1;
    uint32_t f[8];
    for (int i = 0; i < 8 && ok; i++)
        f[i] = sam_mem_read32(m, sp + 4u * (uint32_t)i, &ok);
    if (!ok) {
        sam_cpu_lockup(m, "exception frame unreadable on return");
        return;
    }
    uint32_t ret_ipsr = f[7] & 0x3Fu;
    if ((excret == EXC_RETURN_THREAD) != (ret_ipsr == 0)) {
        sam_fail(m, "exception return 0x%08x into a context with IPSR %u", excret, ret_ipsr);
        return;
    }
    m->act++;
    if ((m->w->cfg.trace & 8) && (m->w->cfg.trace_boards >> m->id & 1))
        sam_note(m, "exc %.3f us %s return from %d", (double)m->t * 1e6 / (double)SAM_TU_HZ, m->name, e);
    else if ((m->w->cfg.trace & 32) && (m->w->cfg.trace_boards >> m->id & 1))
        sam_note(m, "chg %llu %s return from %d", (unsigned long long)m->t, m->name, e);
    /* tail-chaining: a pending exception that may pre-empt the context being returned to is entered directly,
     * reusing the frame (ARMv6-M); PRIMASK is part of that context and unchanged by the return */
    int bp;
    int e2 = sam_nvic_best_pending(m, &bp);
    if (e2 && bp < sam_nvic_exec_prio(m) && !(bp >= 0 && (sam_cpu_reg(m, UC_ARM_REG_PRIMASK) & 1u))) {
        uint32_t vec;
        if (!take_vector(m, e2, &vec))
            return;
        sam_cpu_set(m, UC_ARM_REG_LR, excret);
        run_handler(m, e2, vec);
        m->t += (uint64_t)TAIL_CHAIN_CYCLES * m->cyc_tu;
        m->cycles += TAIL_CHAIN_CYCLES;
        return;
    }
    int ids[6] = {UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12, UC_ARM_REG_LR};
    void *ptrs[6] = {&f[0], &f[1], &f[2], &f[3], &f[4], &f[5]};
    uc_reg_write_batch(m->uc, ids, ptrs, 6);
    sam_cpu_set(m, UC_ARM_REG_SP, sp + 32u + ((f[7] >> 9) & 1u) * 4u);
    sam_cpu_set(m, UC_ARM_REG_XPSR, f[7] & ~(1u << 9));
    sam_cpu_rebuild_hflags(m);
    sam_cpu_set(m, UC_ARM_REG_PC, f[6] | 1u);
    m->t += (uint64_t)EXC_EXIT_CYCLES * m->cyc_tu;
    m->cycles += EXC_EXIT_CYCLES;
    m->irq_check = 1;
}
