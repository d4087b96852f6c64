/* The system control space: the NVIC's, SCB's and SysTick's registers, and the SysTick timer on the CPU clock. */
#include "sam_core.h"
#include "sam_vendor_gen.h"

#define CPUID_M0PLUS 0x410CC601u
#define CCR_M0PLUS 0x00000208u  /* STKALIGN, UNALIGN_TRP: read-only on ARMv6-M */

/* ---------------------------------------------------------------- SysTick (CPU clock) */

static uint32_t systick_val(sam_mcu_t *m, uint64_t t)
{
    sam_systick_t *s = &m->systick;
    if (!(s->ctrl & 1u))
        return s->val_at;
    uint64_t cyc = (t - s->t0) / m->cyc_tu;
    return s->load - (uint32_t)(cyc % ((uint64_t)s->load + 1u));
}

static void systick_schedule(sam_mcu_t *m)
{
    sam_systick_t *s = &m->systick;
    if (!(s->ctrl & 1u)) {
        sam_slot_set(m, SAM_SLOT_SYSTICK, SAM_NEVER);
        return;
    }
    s->period = ((uint64_t)s->load + 1u) * m->cyc_tu;
    /* VAL reaches 0 at t0 + LOAD cycles; the reload (COUNTFLAG, the exception) is the cycle after */
    uint64_t now = m->t_blk, k = now >= s->t0 ? (now - s->t0) / s->period + 1u : 1u;
    sam_slot_set(m, SAM_SLOT_SYSTICK, s->t0 + k * s->period);
}

void sam_systick_fire(sam_mcu_t *m)
{
    sam_systick_t *s = &m->systick;
    if (!(s->ctrl & 1u))
        return;
    s->countflag = 1;
    if (s->ctrl & 2u)
        sam_irq_pend_sys(m, 15);
    uint64_t now = m->t_blk;
    sam_slot_set(m, SAM_SLOT_SYSTICK, now + s->period);
}

/* the CPU clock changed: SysTick keeps its count */
void sam_systick_reclock(sam_mcu_t *m, uint32_t old_cyc_tu)
{
    sam_systick_t *s = &m->systick;
    if (!(s->ctrl & 1u))
        return;
    uint64_t now = m->t_blk;
    uint64_t cyc = (now - s->t0) / old_cyc_tu;
    uint64_t into = cyc % ((uint64_t)s->load + 1u);
    s->t0 = now - into * m->cyc_tu;
    systick_schedule(m);
}

/* ---------------------------------------------------------------- system control space (NVIC, SCB, SysTick) */

static int scs_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    uint32_t off = sam_regs[ri].offset;
    sam_nvic_t *n = &m->nvic;
    if (pi == sam_idx.nvic) {
        if (off == 0x000 || off == 0x080)   /* ISER, ICER */
            *v = n->enabled;
        else if (off == 0x100 || off == 0x180)   /* ISPR, ICPR */
            *v = n->pending;
        else if (off >= 0x300 && off < 0x320)   /* IP[0..7] */
            *v = n->ipr[(off - 0x300) / 4];
        else
            return SAM_UNCOVERED;
        return SAM_DONE;
    }
    if (pi == sam_idx.systick) {
        sam_systick_t *s = &m->systick;
        switch (off) {
        case 0x0:   /* CTRL */
            *v = s->ctrl | (s->countflag ? 1u << 16 : 0u);
            if (s->countflag) {
                s->countflag = 0;   /* read-to-clear */
                m->act++;
            }
            break;
        case 0x4: *v = s->load; break;
        case 0x8:
            *v = systick_val(m, sam_now(m));
            m->tread++;   /* changes with time: a pass that reads it is never idle, or skipped after a probe (sam_ff.c) */
            break;
        case 0xC: *v = 0x40000000u; break;   /* CALIB: no reference clock, TENMS unknown */
        default: return SAM_UNCOVERED;
        }
        return SAM_DONE;
    }
    switch (off) {   /* SCB */
    case 0x00: *v = CPUID_M0PLUS; break;
    case 0x04: {   /* ICSR */
        int bp;
        int e = sam_nvic_best_pending(m, &bp);
        uint32_t ipsr = sam_cpu_reg(m, UC_ARM_REG_XPSR) & 0x3Fu;
        *v = ipsr | ((uint32_t)e << 12) | ((n->pending & n->enabled) ? 1u << 22 : 0u) |
             (n->sys_pending & (1u << 15) ? 1u << 26 : 0u) | (n->sys_pending & (1u << 14) ? 1u << 28 : 0u) |
             (n->sys_pending & (1u << 2) ? 1u << 31 : 0u);
        break;
    }
    case 0x08: *v = n->vtor; break;
    case 0x0C: *v = 0xFA050000u; break;
    case 0x10: *v = n->scr; break;
    case 0x14: *v = CCR_M0PLUS; break;
    case 0x1C: *v = n->shpr2; break;
    case 0x20: *v = n->shpr3; break;
    case 0x24: *v = n->sys_pending & (1u << 11) ? 1u << 15 : 0u; break;
    default: return SAM_UNCOVERED;
    }
    return SAM_DONE;
}

static int scs_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    uint32_t off = sam_regs[ri].offset;
    sam_nvic_t *n = &m->nvic;
    v &= mask;
    if (pi == sam_idx.nvic) {
        if (off == 0x000)
            n->enabled |= v;
        else if (off == 0x080)
            n->enabled &= ~v;
        else if (off == 0x100)
            n->pending |= v;
        else if (off == 0x180)
            n->pending = (n->pending & ~v) | (n->level & v);   /* a request still asserted pends again */
        else if (off >= 0x300 && off < 0x320) {
            int w = (int)(off - 0x300) / 4;
            n->ipr[w] = (n->ipr[w] & ~mask) | (v & 0xC0C0C0C0u);
            for (int b = 0; b < 4; b++)
                n->prio[4 * w + b] = (uint8_t)((n->ipr[w] >> (8 * b + 6)) & 3u);
        } else
            return SAM_UNCOVERED;
        m->irq_check = 1;
        m->act++;
        return SAM_DONE;
    }
    if (pi == sam_idx.systick) {
        sam_systick_t *s = &m->systick;
        if (off == 0x0) {
            uint32_t old = s->ctrl;
            if (!(v & 4u) && (v & 1u)) {
                sam_fail(m, "SysTick on the external reference clock is not modelled (CTRL.CLKSOURCE = 0)");
                return SAM_DONE;
            }
            s->ctrl = v & 7u;
            if (!(old & 1u) && (s->ctrl & 1u)) {
                /* enabled: counts down from VAL (0: reloads at the first cycle) */
                uint32_t val = s->val_at;
                s->t0 = sam_now(m) - (uint64_t)((val ? (uint64_t)s->load + 1u - val : 0u) % ((uint64_t)s->load + 1u)) * m->cyc_tu;
            } else if ((old & 1u) && !(s->ctrl & 1u)) {
                s->val_at = systick_val(m, sam_now(m));
            }
            systick_schedule(m);
        } else if (off == 0x4) {
            s->load = v & 0xFFFFFFu;
            systick_schedule(m);
        } else if (off == 0x8) {
            /* any write clears VAL and COUNTFLAG; the next cycle reloads */
            s->countflag = 0;
            s->val_at = 0;
            if (s->ctrl & 1u) {
                s->t0 = sam_now(m) + m->cyc_tu;
                s->period = ((uint64_t)s->load + 1u) * m->cyc_tu;
                sam_slot_set(m, SAM_SLOT_SYSTICK, s->t0);
            }
        } else
            return SAM_UNCOVERED;
        m->act++;
        return SAM_DONE;
    }
    switch (off) {   /* SCB */
    case 0x04:   /* ICSR */
        if (v & (1u << 31))
            sam_irq_pend_sys(m, 2);
        if (v & (1u << 28))
            sam_irq_pend_sys(m, 14);
        if (v & (1u << 27))
            n->sys_pending &= ~(1u << 14);
        if (v & (1u << 26))
            sam_irq_pend_sys(m, 15);
        if (v & (1u << 25))
            n->sys_pending &= ~(1u << 15);
        break;
    case 0x08: n->vtor = v & 0xFFFFFF80u; break;
    case 0x0C:   /* AIRCR */
        if ((v >> 16) == 0x05FAu && (v & 4u)) {
            sam_note(m, "%s: system reset requested (AIRCR.SYSRESETREQ) at t = %.6f s", m->name,
                           (double)sam_now(m) / (double)SAM_TU_HZ);
            sam_request_reset(m, PM_RCAUSE_SYST);
        }
        break;
    case 0x10: n->scr = v & 0x16u; break;
    case 0x1C:
        n->shpr2 = (n->shpr2 & ~mask) | (v & 0xC0000000u);
        n->prio_svc = (uint8_t)(n->shpr2 >> 30);
        break;
    case 0x20:
        n->shpr3 = (n->shpr3 & ~mask) | (v & 0xC0C00000u);
        n->prio_pendsv = (uint8_t)((n->shpr3 >> 22) & 3u);
        n->prio_systick = (uint8_t)(n->shpr3 >> 30);
        break;
    case 0x00:
    case 0x14: return SAM_DONE;   /* CPUID, CCR: read-only on ARMv6-M, writes ignored */
    default: return SAM_UNCOVERED;
    }
    m->irq_check = 1;
    m->act++;
    return SAM_DONE;
}

const sam_model_t sam_model_scs = {"SCS", NULL, NULL, scs_read, scs_write, NULL};
