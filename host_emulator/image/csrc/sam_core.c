/* SAMD21 board core: memory map, generic register layer, software NVIC, SysTick/SCB, resets, run loop, fast-forward. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_world.h"
#include "sam_vendor_gen.h"

/* ---------------------------------------------------------------- cycle model constants (sam_cycles.py) */
/* exception entry and return, an access through the AHB-APB bridge: the CPU budget's cycle model (sam_world_cfg_t,
 * from metacell_tools.fwcheck.cpubudget.CycleModel) */
#define EXC_ENTRY_CYCLES ((uint64_t)m->w->cfg.cyc_exc_entry)
#define EXC_EXIT_CYCLES ((uint64_t)m->w->cfg.cyc_exc_exit)
#define APB_EXTRA_CYCLES ((uint64_t)m->w->cfg.cyc_apb)
#define TAIL_CHAIN_CYCLES 11  /* ARMv6-M tail-chaining: no unstacking, a new vector fetch */

#define CPUID_M0PLUS 0x410CC601u
#define CCR_M0PLUS 0x00000208u  /* STKALIGN, UNALIGN_TRP: read-only on ARMv6-M */
#define EXC_RETURN_THREAD 0xFFFFFFF9u
#define EXC_RETURN_HANDLER 0xFFFFFFF1u

static const int CORE_REGS[] = {UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2,  UC_ARM_REG_R3,  UC_ARM_REG_R4,
                                UC_ARM_REG_R5, UC_ARM_REG_R6, UC_ARM_REG_R7,  UC_ARM_REG_R8,  UC_ARM_REG_R9,
                                UC_ARM_REG_R10, UC_ARM_REG_R11, UC_ARM_REG_R12, UC_ARM_REG_SP, UC_ARM_REG_LR,
                                UC_ARM_REG_PC, UC_ARM_REG_XPSR, UC_ARM_REG_PRIMASK, UC_ARM_REG_CONTROL};
#define NCORE_REGS ((int)(sizeof(CORE_REGS) / sizeof(CORE_REGS[0])))

/* ---------------------------------------------------------------- errors */

void sam_fail(sam_mcu_t *m, const char *fmt, ...)
{
    if (m->err)
        return;
    uint32_t pc = 0;
    uc_reg_read(m->uc, UC_ARM_REG_PC, &pc);
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    snprintf(m->errmsg, sizeof m->errmsg, "%s: %s (pc 0x%05x, t = %.6f s)", m->name, msg, pc,
             (double)m->t / (double)SAM_TU_HZ);
    m->err = 1;
    uc_emu_stop(m->uc);
}

/* ---------------------------------------------------------------- register table lookups */

const char *sam_reg_name(int ri) { return ri >= 0 && (unsigned)ri < sam_nregs ? sam_regs[ri].name : "?"; }

const sam_field_t *sam_field(int ri, const char *name)
{
    const sam_reg_t *r = &sam_regs[ri];
    for (unsigned k = 0; k < r->nfields; k++)
        if (strcmp(sam_fields[r->field0 + k].name, name) == 0)
            return &sam_fields[r->field0 + k];
    return NULL;
}

sam_index_t sam_idx;
static int idx_ready;

void sam_index_init(void)
{
    if (idx_ready)
        return;
    sam_idx.pm = sam_periph_index("PM");
    sam_idx.sysctrl = sam_periph_index("SYSCTRL");
    sam_idx.gclk = sam_periph_index("GCLK");
    sam_idx.wdt = sam_periph_index("WDT");
    sam_idx.eic = sam_periph_index("EIC");
    sam_idx.nvmctrl = sam_periph_index("NVMCTRL");
    sam_idx.port = sam_periph_index("PORT");
    sam_idx.iobus = sam_periph_index("PORT_IOBUS");
    sam_idx.usb = sam_periph_index("USB");
    sam_idx.sercom2 = sam_periph_index("SERCOM2");
    sam_idx.tc3 = sam_periph_index("TC3");
    sam_idx.tcc[0] = sam_periph_index("TCC0");
    sam_idx.tcc[1] = sam_periph_index("TCC1");
    sam_idx.tcc[2] = sam_periph_index("TCC2");
    sam_idx.nvic = sam_periph_index("NVIC");
    sam_idx.scb = sam_periph_index("SCB");
    sam_idx.systick = sam_periph_index("SysTick");
    sam_idx.pm_cpusel = sam_reg_index(sam_idx.pm, "CPUSEL");
    sam_idx.wdt_ctrl = sam_reg_index(sam_idx.wdt, "CTRL");
    sam_idx.wdt_config = sam_reg_index(sam_idx.wdt, "CONFIG");
    sam_idx.sercom2_i2cs_ctrlb = sam_reg_index(sam_idx.sercom2, "I2CS.CTRLB");
    sam_idx.tc3_count16_count = sam_reg_index(sam_idx.tc3, "COUNT16.COUNT");
    idx_ready = 1;
}

int sam_periph_index(const char *name)
{
    for (unsigned i = 0; i < sam_nperiphs; i++)
        if (strcmp(sam_periphs[i].name, name) == 0)
            return (int)i;
    return -1;
}

/* "COUNT16.CC[0]" of TC3 -> its index (the name after the instance's dot) */
int sam_reg_index(int pi, const char *name)
{
    const sam_periph_t *p = &sam_periphs[pi];
    size_t n = strlen(p->name);
    for (unsigned ri = p->reg0; ri < p->reg1; ri++)
        if (strcmp(sam_regs[ri].name + n + 1, name) == 0)
            return (int)ri;
    return -1;
}

static uint8_t *reg_ptr(sam_mcu_t *m, int ri) { return m->regs[sam_regs[ri].periph] + sam_regs[ri].offset; }

uint32_t sam_reg_get(sam_mcu_t *m, int ri)
{
    const uint8_t *b = reg_ptr(m, ri);
    uint32_t v = 0;
    for (int k = sam_regs[ri].size - 1; k >= 0; k--)
        v = (v << 8) | b[k];
    return v;
}

void sam_reg_put(sam_mcu_t *m, int ri, uint32_t v)
{
    uint8_t *b = reg_ptr(m, ri);
    for (int k = 0; k < sam_regs[ri].size; k++, v >>= 8)
        b[k] = (uint8_t)v;
}

int sam_reg_at(sam_mcu_t *m, int pi, uint32_t offset)
{
    int view = m->model[pi] && m->model[pi]->view ? m->model[pi]->view(m, pi) : 0;
    if (offset >= sam_periphs[pi].size || !m->omap[pi][view])
        return -1;
    return m->omap[pi][view][offset];
}

/* ---------------------------------------------------------------- memory */

uint32_t sam_mem_read32(sam_mcu_t *m, uint32_t addr, int *ok)
{
    const uint8_t *p = NULL;
    if (addr + 4 <= SAM_FLASH_SIZE)
        p = m->flash + addr;
    else if (addr >= SAM_RAM_BASE && addr + 4 <= SAM_RAM_BASE + SAM_RAM_SIZE)
        p = m->ram + (addr - SAM_RAM_BASE);
    if (!p || (addr & 3)) {
        if (ok)
            *ok = 0;
        return 0;
    }
    if (ok)
        *ok = 1;
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int ram_write32(sam_mcu_t *m, uint32_t addr, uint32_t v)
{
    if (addr < SAM_RAM_BASE || addr + 4 > SAM_RAM_BASE + SAM_RAM_SIZE || (addr & 3))
        return 0;
    uint8_t *p = m->ram + (addr - SAM_RAM_BASE);
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
    return 1;
}

/* ---------------------------------------------------------------- events */

static void next_event(sam_mcu_t *m)
{
    uint64_t t = SAM_NEVER;
    for (int s = 0; s < SAM_NSLOTS; s++)
        if (m->slot[s] < t)
            t = m->slot[s];
    m->next_ev = t;
}

void sam_slot_set(sam_mcu_t *m, int slot, uint64_t t)
{
    uint64_t old = m->slot[slot];
    m->slot[slot] = t;
    if (t < m->next_ev)
        m->next_ev = t;
    else if (old == m->next_ev && t != old)
        next_event(m);
}

static void systick_fire(sam_mcu_t *m);

static void fire_slot(sam_mcu_t *m, int s)
{
    if (s < SAM_MAX_PERIPH) {
        if (m->model[s] && m->model[s]->fire)
            m->model[s]->fire(m, s);
        return;
    }
    switch (s) {
    case SAM_SLOT_SYSTICK: systick_fire(m); break;
    case SAM_SLOT_PINS: sam_world_pin_event(m); break;
    case SAM_SLOT_BUS: sam_bus_fire(m); break;
    case SAM_SLOT_USB: sam_usb_fire(m); break;
    case SAM_SLOT_FAULT: sam_world_fault_fire(m); break;
    default: break;
    }
}

/* Every event due at or before the current boundary, in time order, each at its own time. */
static void process_events(sam_mcu_t *m)
{
    uint64_t saved = m->t_blk;
    while (m->next_ev <= m->t && m->next_ev < m->stop_at && !m->err && !m->in_reset) {
        int s = 0;
        for (int k = 1; k < SAM_NSLOTS; k++)
            if (m->slot[k] < m->slot[s])
                s = k;
        uint64_t ts = m->slot[s];
        m->slot[s] = SAM_NEVER;
        next_event(m);
        m->t_blk = ts;
        m->ev_quiet = 0;
        fire_slot(m, s);
        if (!m->ev_quiet)
            m->act++;
    }
    m->t_blk = saved;
}

/* ---------------------------------------------------------------- exceptions (ARMv6-M, software NVIC) */

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
static int active_prio(const sam_mcu_t *m)
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
static int best_pending(const sam_mcu_t *m, int *prio)
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
    m->nvic.sys_pending |= 1u << exc;
    m->irq_check = 1;
}

static uint32_t reg_u32(sam_mcu_t *m, int id)
{
    uint32_t v = 0;
    uc_reg_read(m->uc, id, &v);
    return v;
}

static void reg_w32(sam_mcu_t *m, int id, uint32_t v) { uc_reg_write(m->uc, id, &v); }

/* Unicorn caches the handler-mode flag of the TB state (hflags); an IPSR/XPSR write does not rebuild it, a write
 * of APSR's NZCV does (and changes nothing when it writes the flags back as they are). */
static void rebuild_hflags(sam_mcu_t *m)
{
    uint32_t nzcv = reg_u32(m, UC_ARM_REG_APSR_NZCV);
    reg_w32(m, UC_ARM_REG_APSR_NZCV, nzcv);
}

static void lockup(sam_mcu_t *m, const char *why)
{
    if (!m->lockup)
        sam_note(m, "%s: core lockup (%s) at t = %.6f s; only a reset ends it", m->name, why,
                       (double)m->t / (double)SAM_TU_HZ);
    m->lockup = 1;
    uc_emu_stop(m->uc);
}

/* Stack the caller-saved frame and enter exception e; ret = address of the next instruction. 1 on success. */
static int exc_enter(sam_mcu_t *m, int e, uint32_t ret)
{
    uint32_t r[8];
    int ids[8] = {UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12, UC_ARM_REG_LR,
                  UC_ARM_REG_SP, UC_ARM_REG_XPSR};
    void *ptrs[8];
    for (int i = 0; i < 8; i++)
        ptrs[i] = &r[i];
    uc_reg_read_batch(m->uc, ids, ptrs, 8);
    uint32_t sp = r[6], xpsr = r[7], ipsr = xpsr & 0x3Fu;
    uint32_t frame = sp - 32u, stacked_xpsr = (xpsr & ~(1u << 9)) | (1u << 24);
    if (frame & 4u) {   /* 8-byte aligned frames (CCR.STKALIGN): xPSR bit 9 records the padding */
        frame -= 4u;
        stacked_xpsr |= 1u << 9;
    }
    const uint32_t words[8] = {r[0], r[1], r[2], r[3], r[4], r[5], ret & ~1u, stacked_xpsr};
    for (int i = 0; i < 8; i++)
        if (!ram_write32(m, frame + 4u * (uint32_t)i, words[i])) {
            lockup(m, "exception stack frame outside SRAM");
            return 0;
        }
    int ok = 0;
    uint32_t vec = sam_mem_read32(m, m->nvic.vtor + 4u * (uint32_t)e, &ok);
    if (!ok || !(vec & 1u)) {
        lockup(m, "exception vector unreadable or not Thumb");
        return 0;
    }
    if (e >= 16) {
        m->nvic.pending &= ~(1u << (e - 16));
        m->nvic.active |= 1u << (e - 16);
    } else {
        m->nvic.sys_pending &= ~(1u << e);
        m->nvic.sys_active |= 1u << e;
    }
    if ((m->w->cfg.trace & 8) && (m->w->cfg.trace_boards >> m->id & 1))
        sam_note(m, "exc %.3f us %s enter %d from %u at 0x%05x", (double)m->t * 1e6 / (double)SAM_TU_HZ,
                       m->name, e, ipsr, ret);
    else if ((m->w->cfg.trace & 32) && (m->w->cfg.trace_boards >> m->id & 1))
        sam_note(m, "chg %llu %s enter %d from %u at 0x%05x", (unsigned long long)m->t, m->name, e, ipsr,
                       ret);
    reg_w32(m, UC_ARM_REG_SP, frame);
    reg_w32(m, UC_ARM_REG_LR, ipsr ? EXC_RETURN_HANDLER : EXC_RETURN_THREAD);
    reg_w32(m, UC_ARM_REG_IPSR, (uint32_t)e);
    rebuild_hflags(m);
    reg_w32(m, UC_ARM_REG_PC, vec);
    m->t += (uint64_t)EXC_ENTRY_CYCLES * m->cyc_tu;
    m->cycles += EXC_ENTRY_CYCLES;
    m->act++;
    m->irq_check = 1;
    if (e == 3)
        m->hardfaults++;
    return 1;
}

/* Take the best pending exception if it may pre-empt now; ret = where the interrupted code resumes. */
static int take_irq(sam_mcu_t *m, uint32_t ret)
{
    int bp;
    int e = best_pending(m, &bp);
    m->irq_check = 0;
    m->primask_wait = 0;
    if (!e)
        return 0;
    int ap = active_prio(m);
    if (bp >= ap)
        return 0;   /* re-evaluated when an exception returns */
    if (bp >= 0 && reg_u32(m, UC_ARM_REG_PRIMASK) & 1u) {
        m->primask_wait = 1;   /* CPSIE ends its translation block: checked at every block until taken */
        return 0;
    }
    return exc_enter(m, e, ret);
}

/* Exception return (Unicorn raises EXCP_EXCEPTION_EXIT for a branch to EXC_RETURN in handler mode). */
#define EXCP_EXCEPTION_EXIT 8

static void hook_intr(uc_engine *uc, uint32_t intno, void *ud)
{
    sam_mcu_t *m = ud;
    (void)uc;
    if (intno != EXCP_EXCEPTION_EXIT) {
        m->fault_addr = reg_u32(m, UC_ARM_REG_PC);
        sam_fail(m, "CPU exception %u (an instruction the model does not execute: SVC, BKPT, UDF, WFI)", intno);
        return;
    }
    uint32_t excret = reg_u32(m, UC_ARM_REG_PC) | 1u;
    uint32_t xpsr_now = reg_u32(m, UC_ARM_REG_XPSR);
    int e = (int)(xpsr_now & 0x3Fu);
    if (excret != EXC_RETURN_THREAD && excret != EXC_RETURN_HANDLER) {
        sam_fail(m, "exception return 0x%08x (only the main stack is modelled)", excret);
        return;
    }
    /* deactivate e */
    if (e >= 16) {
        m->nvic.active &= ~(1u << (e - 16));
        if (m->nvic.level & (1u << (e - 16)))
            m->nvic.pending |= 1u << (e - 16);   /* still requested: pending again */
    } else {
        m->nvic.sys_active &= ~(1u << e);
    }
    uint32_t sp = reg_u32(m, UC_ARM_REG_SP);
    int ok = 1;
    uint32_t f[8];
    for (int i = 0; i < 8 && ok; i++)
        f[i] = sam_mem_read32(m, sp + 4u * (uint32_t)i, &ok);
    if (!ok) {
        lockup(m, "exception frame unreadable on return");
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
    int e2 = best_pending(m, &bp);
    if (e2 && bp < active_prio(m) && !(bp >= 0 && (reg_u32(m, UC_ARM_REG_PRIMASK) & 1u))) {
        int ok2 = 0;
        uint32_t vec = sam_mem_read32(m, m->nvic.vtor + 4u * (uint32_t)e2, &ok2);
        if (!ok2 || !(vec & 1u)) {
            lockup(m, "exception vector unreadable or not Thumb");
            return;
        }
        if (e2 >= 16) {
            m->nvic.pending &= ~(1u << (e2 - 16));
            m->nvic.active |= 1u << (e2 - 16);
        } else {
            m->nvic.sys_pending &= ~(1u << e2);
            m->nvic.sys_active |= 1u << e2;
        }
        if (e2 == 3)
            m->hardfaults++;
        reg_w32(m, UC_ARM_REG_LR, excret);
        reg_w32(m, UC_ARM_REG_IPSR, (uint32_t)e2);
        rebuild_hflags(m);
        reg_w32(m, UC_ARM_REG_PC, vec);
        m->t += (uint64_t)TAIL_CHAIN_CYCLES * m->cyc_tu;
        m->cycles += TAIL_CHAIN_CYCLES;
        m->irq_check = 1;
        return;
    }
    int ids[6] = {UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12, UC_ARM_REG_LR};
    void *ptrs[6] = {&f[0], &f[1], &f[2], &f[3], &f[4], &f[5]};
    uc_reg_write_batch(m->uc, ids, ptrs, 6);
    reg_w32(m, UC_ARM_REG_SP, sp + 32u + ((f[7] >> 9) & 1u) * 4u);
    reg_w32(m, UC_ARM_REG_XPSR, f[7] & ~(1u << 9));
    rebuild_hflags(m);
    reg_w32(m, UC_ARM_REG_PC, f[6] | 1u);
    m->t += (uint64_t)EXC_EXIT_CYCLES * m->cyc_tu;
    m->cycles += EXC_EXIT_CYCLES;
    m->irq_check = 1;
}

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

static void systick_fire(sam_mcu_t *m)
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
static void systick_reclock(sam_mcu_t *m, uint32_t old_cyc_tu)
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

void sam_set_cpu_clock(sam_mcu_t *m)
{
    uint64_t hz = sam_gen_hz(m, 0);
    int sel = (int)(sam_reg_get(m, sam_idx.pm_cpusel) & 7u);
    m->clk_epoch++;
    hz >>= sel;
    if (hz == 0) {
        sam_fail(m, "the CPU clock (GCLK0) stopped");
        return;
    }
    if (SAM_TU_HZ % hz) {
        sam_fail(m, "CPU clock %llu Hz is not modelled (the time unit must divide it)", (unsigned long long)hz);
        return;
    }
    uint32_t old = m->cyc_tu;
    m->cyc_tu = (uint32_t)(SAM_TU_HZ / hz);
    if (old != m->cyc_tu)
        systick_reclock(m, old);
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
            m->act++;   /* changes with time: a pass that reads it is never idle */
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
        int e = best_pending(m, &bp);
        uint32_t ipsr = reg_u32(m, UC_ARM_REG_XPSR) & 0x3Fu;
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

static void request_reset(sam_mcu_t *m, uint8_t cause)
{
    m->in_reset = 0x100 | cause;
    uc_emu_stop(m->uc);
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
            request_reset(m, PM_RCAUSE_SYST);
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

static const sam_model_t model_scs = {"SCS", NULL, NULL, scs_read, scs_write, NULL};

/* ---------------------------------------------------------------- generic register layer */

static uint32_t generic_read(sam_mcu_t *m, int ri)
{
    return sam_reg_get(m, sam_regs[ri].alias != ri ? sam_regs[ri].alias : ri);
}

void sam_generic_write(sam_mcu_t *m, int ri, uint32_t v, uint32_t mask)
{
    const sam_reg_t *r = &sam_regs[ri];
    int target = r->alias;
    uint32_t old = sam_reg_get(m, target), nv;
    switch (r->kind) {
    case SAM_KIND_W1C: nv = old & ~(v & mask); break;
    case SAM_KIND_SET: nv = old | (v & mask); break;
    case SAM_KIND_CLR: nv = old & ~(v & mask); break;
    case SAM_KIND_TGL: nv = old ^ (v & mask); break;
    default: nv = (old & ~mask) | (v & mask); break;
    }
    if (nv != old) {
        sam_reg_put(m, target, nv);
        m->act++;
    }
}

typedef struct {
    sam_mcu_t *m;
    uint32_t base, size;
    int16_t *page;   /* 16-byte pages -> peripheral index, -1 */
    int scs, iobus;
} region_t;

#define NREGIONS 5
static const uint32_t REGION_BASE[NREGIONS] = {0x40000000u, 0x41000000u, 0x42000000u, 0x60000000u, 0xE000E000u};
static const uint32_t REGION_SIZE[NREGIONS] = {0x2000u, 0x8000u, 0x6000u, 0x1000u, 0x1000u};  /* whole 4 KiB pages */

static int reg_access(sam_mcu_t *m, region_t *rg, uint32_t addr, unsigned size, int write, uint32_t *val)
{
    int pi = rg->page[(addr - rg->base) >> 4];
    if (pi < 0) {
        sam_fail(m, "%s of %u bytes at 0x%08x: no peripheral there", write ? "write" : "read", size, addr);
        return -1;
    }
    const sam_periph_t *p = &sam_periphs[pi];
    const sam_model_t *md = m->model[pi];
    if (!md) {
        sam_fail(m, "%s of %s + 0x%x: the %s peripheral is not modelled", write ? "write" : "read", p->name,
                 addr - p->base, p->name);
        return -1;
    }
    if (!sam_apb_on(m, pi)) {
        sam_fail(m, "%s of %s + 0x%x while its bus clock is off in PM", write ? "write" : "read", p->name,
                 addr - p->base);
        return -1;
    }
    int view = md->view ? md->view(m, pi) : 0;
    uint32_t off = addr - p->base, out = 0;
    for (unsigned b = 0; b < size;) {
        int ri = off + b < p->size && m->omap[pi][view] ? m->omap[pi][view][off + b] : -1;
        if (ri < 0) {
            sam_fail(m, "%s of %s + 0x%x: no register at that offset%s", write ? "write" : "read", p->name, off + b,
                     p->nviews ? " in the active mode" : "");
            return -1;
        }
        const sam_reg_t *r = &sam_regs[ri];
        unsigned lo = off + b - r->offset, n = r->size - lo;
        if (n > size - b)
            n = size - b;
        uint32_t mask = (n == 4 ? 0xFFFFFFFFu : ((1u << (8 * n)) - 1u)) << (8 * lo);
        if (write) {
            if (!(r->access & SAM_ACC_W)) {   /* the chip ignores it; worth a note, once per register */
                if (!m->touch[2 * ri + 1])
                    sam_note(m, "%s: write to read-only register %s ignored (pc t = %.6f s)", m->name,
                                   r->name, (double)m->t / (double)SAM_TU_HZ);
                m->touch[2 * ri + 1]++;
                b += n;
                continue;
            }
            uint32_t v = ((*val >> (8 * b)) << (8 * lo)) & mask;
            uint64_t act0 = m->act;
            int rc = md->write ? md->write(m, pi, ri, v, mask) : SAM_GENERIC;
            if (rc == SAM_GENERIC)
                sam_generic_write(m, ri, v, mask);
            else if (rc == SAM_UNCOVERED) {
                sam_fail(m, "write of 0x%x to %s: register not modelled", v >> (8 * lo), r->name);
                return -1;
            }
            m->touch[2 * ri + 1]++;
            if ((m->w->cfg.trace & 4) && (m->w->cfg.trace_boards >> m->id & 1))
                sam_note(m, "reg %.3f us %s W %s = 0x%x", (double)m->t_blk * 1e6 / (double)SAM_TU_HZ,
                               m->name, r->name, v >> (8 * lo));
            else if ((m->w->cfg.trace & 32) && m->act != act0 && (m->w->cfg.trace_boards >> m->id & 1))
                sam_note(m, "chg %llu %s W %s = 0x%x in %u", (unsigned long long)m->t_blk, m->name, r->name,
                         v >> (8 * lo), reg_u32(m, UC_ARM_REG_IPSR) & 0x3Fu);
        } else {
            uint32_t v = 0;
            if (!(r->access & SAM_ACC_R)) {   /* reads as zero (a bit-field write reads it first) */
                m->touch[2 * ri]++;
                b += n;
                continue;
            }
            uint64_t act0 = m->act;
            int rc = md->read ? md->read(m, pi, ri, &v) : SAM_GENERIC;
            if (rc == SAM_GENERIC)
                v = generic_read(m, ri);
            else if (rc == SAM_UNCOVERED) {
                sam_fail(m, "read of %s: register not modelled", r->name);
                return -1;
            }
            out |= ((v & mask) >> (8 * lo)) << (8 * b);
            m->touch[2 * ri]++;
            if ((m->w->cfg.trace & 4) && (m->w->cfg.trace_boards >> m->id & 1))
                sam_note(m, "reg %.3f us %s R %s -> 0x%x", (double)m->t_blk * 1e6 / (double)SAM_TU_HZ,
                               m->name, r->name, (v & mask) >> (8 * lo));
            else if ((m->w->cfg.trace & 32) && m->act != act0 && (m->w->cfg.trace_boards >> m->id & 1))
                sam_note(m, "chg %llu %s R %s -> 0x%x in %u", (unsigned long long)m->t_blk, m->name, r->name,
                         (v & mask) >> (8 * lo), reg_u32(m, UC_ARM_REG_IPSR) & 0x3Fu);
        }
        b += n;
    }
    if (!write)
        *val = out;
    if (!rg->scs && !rg->iobus) {
        m->t += (uint64_t)APB_EXTRA_CYCLES * m->cyc_tu;
        m->cycles += APB_EXTRA_CYCLES;
    }
    return 0;
}

static uint64_t mmio_read(uc_engine *uc, uint64_t offset, unsigned size, void *ud)
{
    region_t *rg = ud;
    (void)uc;
    uint32_t v = 0;
    rg->m->mmio_reads++;
    reg_access(rg->m, rg, rg->base + (uint32_t)offset, size, 0, &v);
    return v;
}

static void mmio_write(uc_engine *uc, uint64_t offset, unsigned size, uint64_t value, void *ud)
{
    region_t *rg = ud;
    (void)uc;
    uint32_t v = (uint32_t)value;
    rg->m->mmio_writes++;
    reg_access(rg->m, rg, rg->base + (uint32_t)offset, size, 1, &v);
}

/* ---------------------------------------------------------------- faults from the memory system */

static bool hook_badmem(uc_engine *uc, uc_mem_type type, uint64_t address, int size, int64_t value, void *ud)
{
    sam_mcu_t *m = ud;
    (void)uc;
    (void)type;
    (void)size;
    (void)value;
    m->fault_addr = (uint32_t)address;
    return false;   /* the emulation stops with an error; the run loop enters HardFault */
}


/* The TLB entry of a page (Unicorn's virtual TLB): flash read and execute, SRAM read and write, the NVM rows
 * read only, peripherals read and write; anywhere else the memory system reports the fault. SRAM is not
 * executable: Unicorn then lets stores to it take the fast path (it keeps pages that could hold code on a slow
 * path for every store), and code there has no cycle model anyway. */
static bool hook_tlb(uc_engine *uc, uint64_t vaddr, uc_mem_type type, uc_tlb_entry *e, void *ud)
{
    (void)uc;
    (void)type;
    (void)ud;
    uint32_t a = (uint32_t)vaddr;
    e->paddr = vaddr;
    if (a < SAM_FLASH_SIZE)
        e->perms = UC_PROT_READ | UC_PROT_EXEC;
    else if (a >= SAM_RAM_BASE && a < SAM_RAM_BASE + SAM_RAM_SIZE)
        e->perms = UC_PROT_READ | UC_PROT_WRITE;
    else if (a >= SAM_NVM_BASE && a < SAM_NVM_BASE + SAM_NVM_SIZE)
        e->perms = UC_PROT_READ;
    else if (a >= 0x40000000u && a < 0x60000000u)
        e->perms = UC_PROT_READ | UC_PROT_WRITE;
    else
        e->perms = UC_PROT_ALL;
    return true;
}

/* ---------------------------------------------------------------- fast-forward of idle loop() passes */

static int ff_boundary(sam_mcu_t *m)
{
    sam_ff_t *f = &m->ff;
    if (f->resumed) {
        f->resumed = 0;
        return 0;
    }
    uint32_t regs[NCORE_REGS];
    void *ptrs[NCORE_REGS];
    for (int i = 0; i < NCORE_REGS; i++)
        ptrs[i] = &regs[i];
    uc_reg_read_batch(m->uc, (int *)CORE_REGS, ptrs, NCORE_REGS);
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

/* ---------------------------------------------------------------- the block hook */

static void hook_block(uc_engine *uc, uint64_t address, uint32_t size, void *ud)
{
    sam_mcu_t *m = ud;
    uint32_t addr = (uint32_t)address;
    if (addr == m->prev_end) {   /* the previous block ended in a conditional branch that was not taken */
        uint32_t back = (m->prev_refund & 15u) + (m->cycle_model == SAM_CYCLES_WORST ? m->rws * (m->prev_refund >> 4) : 0u);
        m->t -= (uint64_t)back * m->cyc_tu;
        m->cycles -= back;
    }
    m->prev_end = 0xFFFFFFFFu;
    if (m->t >= m->next_ev)
        process_events(m);   /* those due before stop_at; an answer they send may lower stop_at */
    if (m->err || m->in_reset || m->lockup || m->t >= m->stop_at) {
        uc_emu_stop(uc);
        return;
    }
    if ((m->irq_check | m->primask_wait) && take_irq(m, addr))
        return;   /* the PC moved to the handler: this block does not run now */
    if (addr == m->ff.loop_pc && m->ff.enabled && ff_boundary(m)) {
        uc_emu_stop(uc);
        return;
    }
    if (addr + size > m->app_end || size == 0) {
        if (size == 0)
            return;
        sam_fail(m, "execution at 0x%05x outside the image's code (ends 0x%05x)", addr, m->app_end);
        return;
    }
    /* the block's cost (sam_cycles: prefix sums over its halfwords), memoised per block start */
    sam_blkcost_t *bc = &m->memo[(addr >> 1) & (SAM_MEMO - 1)];
    if (bc->addr != addr || bc->size != size) {
        uint32_t h0 = addr >> 1, h1 = (addr + size) >> 1;
        bc->addr = addr;
        bc->size = (uint16_t)size;
        bc->core = m->cost_core[h1] - m->cost_core[h0];
        bc->wait = (uint16_t)(m->cost_wait[h1] - m->cost_wait[h0]);
        bc->lit = (uint16_t)(m->cost_lit[h1] - m->cost_lit[h0]);
        bc->refund = m->refund[h1 - 1];
    }
    uint64_t cyc = bc->core;
    if (m->cycle_model == SAM_CYCLES_WORST) {
        cyc += (uint64_t)m->rws * bc->wait;
    } else if (m->rws) {
        /* the NVM cache: a fetch of a 64-bit line that is not cached waits RWS cycles and fills its line */
        uint32_t waits = bc->lit;
        for (uint32_t a = addr & ~7u; a < addr + size; a += 8) {
            uint32_t idx = (a >> 3) & 7u, tag = (a >> 6) | 0x80000000u;
            if (m->cache_tag[idx] != tag) {
                m->cache_tag[idx] = tag;
                waits++;
            }
        }
        cyc += (uint64_t)m->rws * waits;
    }
    m->t_blk = m->t;
    m->t += cyc * m->cyc_tu;
    m->cycles += cyc;
    if (m->prof)
        m->prof[addr >> 1] += cyc;
    m->prev_end = addr + size;
    m->prev_refund = bc->refund;
}

/* ---------------------------------------------------------------- models by vendor struct */

static const sam_model_t *model_for(const char *type)
{
    static const sam_model_t *const all[] = {&sam_model_pm,  &sam_model_sysctrl, &sam_model_gclk, &sam_model_nvmctrl,
                                             &sam_model_wdt, &sam_model_port,    &sam_model_eic,  &sam_model_tc,
                                             &sam_model_tcc, &sam_model_sercom,  &sam_model_usb,  &sam_model_adc,
                                             &sam_model_dac, &sam_model_pac,     &sam_model_dsu};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
        if (!strcmp(all[i]->type, type))
            return all[i];
    if (!strcmp(type, "NVIC_Type") || !strcmp(type, "SCB_Type") || !strcmp(type, "SysTick_Type"))
        return &model_scs;
    return NULL;
}

/* ---------------------------------------------------------------- life cycle */

/* uc_hook_add takes its callback as void *, a conversion ISO C does not define for function pointers: the
 * pointer's bytes are copied instead (the platforms Unicorn runs on give both the same representation). */
typedef void (*any_fn)(void);
static void *hook_fn(any_fn f)
{
    void *p;
    _Static_assert(sizeof(void *) == sizeof(any_fn), "function and object pointers differ in size");
    memcpy(&p, &f, sizeof p);
    return p;
}

static int init_fail(sam_mcu_t *m, const char *what, uc_err e)
{
    snprintf(m->errmsg, sizeof m->errmsg, "creating the CPU: %s failed (%s)", what, uc_strerror(e));
    return -1;
}

int sam_mcu_init(sam_mcu_t *m, sam_world_t *w, int id)
{
    sam_index_init();
    memset(m, 0, sizeof *m);
    m->w = w;
    m->id = id;
    snprintf(m->name, sizeof m->name, "board %d", id);
    m->flash = calloc(1, SAM_FLASH_SIZE);
    m->ram = calloc(1, SAM_RAM_SIZE);
    m->nvm = calloc(1, SAM_NVM_SIZE);
    m->ff.snap_ram = malloc(SAM_RAM_SIZE);
    m->touch = calloc(2 * (size_t)sam_nregs, sizeof(uint32_t));
    m->notes = malloc(SAM_BOARD_NOTES);
    if (!m->flash || !m->ram || !m->nvm || !m->ff.snap_ram || !m->touch || !m->notes)
        return -1;
    if (sam_nperiphs > SAM_MAX_PERIPH)
        return -1;
    uc_err ue;
    if ((ue = uc_open(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS, &m->uc)) != UC_ERR_OK)
        return init_fail(m, "uc_open", ue);
    if ((ue = uc_ctl_set_cpu_model(m->uc, UC_CPU_ARM_CORTEX_M0)) != UC_ERR_OK)
        return init_fail(m, "the Cortex-M0 CPU model", ue);
    if ((ue = uc_mem_map_ptr(m->uc, 0, SAM_FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, m->flash)) ||
        (ue = uc_mem_map_ptr(m->uc, SAM_RAM_BASE, SAM_RAM_SIZE, UC_PROT_READ | UC_PROT_WRITE, m->ram)) ||
        (ue = uc_mem_map_ptr(m->uc, SAM_NVM_BASE, SAM_NVM_SIZE, UC_PROT_READ, m->nvm)))
        return init_fail(m, "mapping flash, SRAM and the NVM rows", ue);
    /* peripherals: storage, models, offset maps */
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        m->model[pi] = model_for(p->type);
        if (!strcmp(p->name, "PORT_IOBUS")) {
            m->regs[pi] = m->regs[sam_idx.port];   /* the IOBUS is another door to the same registers */
        } else {
            m->regs[pi] = calloc(1, p->size + 4u);
            if (!m->regs[pi])
                return -1;
        }
        for (unsigned v = 0; v <= p->nviews && v < 5; v++) {
            m->omap[pi][v] = malloc(p->size * sizeof(int16_t));
            if (!m->omap[pi][v])
                return -1;
            for (unsigned o = 0; o < p->size; o++)
                m->omap[pi][v][o] = -1;
            for (unsigned ri = p->reg0; ri < p->reg1; ri++) {
                const sam_reg_t *r = &sam_regs[ri];
                if (r->view == 0 || r->view == v)
                    for (unsigned b = 0; b < r->size; b++)
                        m->omap[pi][v][r->offset + b] = (int16_t)ri;
            }
        }
    }
    for (int i = 0; i < NREGIONS; i++) {
        region_t *rg = calloc(1, sizeof *rg);
        if (!rg)
            return -1;
        rg->m = m;
        rg->base = REGION_BASE[i];
        rg->size = REGION_SIZE[i];
        rg->scs = rg->base == 0xE000E000u;
        rg->iobus = rg->base == 0x60000000u;
        rg->page = malloc((rg->size >> 4) * sizeof(int16_t));
        if (!rg->page)
            return -1;
        for (uint32_t k = 0; k < (rg->size >> 4); k++)
            rg->page[k] = -1;
        for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
            const sam_periph_t *p = &sam_periphs[pi];
            if (p->base < rg->base || p->base >= rg->base + rg->size)
                continue;
            for (uint32_t a = p->base; a < p->base + p->size; a += 16)
                rg->page[(a - rg->base) >> 4] = (int16_t)pi;
        }
        if ((ue = uc_mmio_map(m->uc, rg->base, rg->size, mmio_read, rg, mmio_write, rg)) != UC_ERR_OK)
            return init_fail(m, "mapping the peripheral region", ue);
    }
    if ((ue = uc_hook_add(m->uc, &m->hooks[0], UC_HOOK_BLOCK, hook_fn((any_fn)hook_block), m, 0, SAM_FLASH_SIZE - 1)))
        return init_fail(m, "the block hook", ue);
    if ((ue = uc_hook_add(m->uc, &m->hooks[1], UC_HOOK_INTR, hook_fn((any_fn)hook_intr), m, 1, 0)))
        return init_fail(m, "the exception hook", ue);
    /* Memory fault hooks everywhere but SRAM: Unicorn sends every store to a page a memory hook covers down its
     * slow path. SRAM cannot fault but for a fetch (it is mapped without execute: code there has no cycle model),
     * which the run loop reports. */
    if ((ue = uc_hook_add(m->uc, &m->hooks[2], UC_HOOK_MEM_UNMAPPED | UC_HOOK_MEM_PROT, hook_fn((any_fn)hook_badmem),
                          m, 0, SAM_RAM_BASE - 1)) ||
        (ue = uc_hook_add(m->uc, &m->hooks[3], UC_HOOK_MEM_UNMAPPED | UC_HOOK_MEM_PROT, hook_fn((any_fn)hook_badmem),
                          m, SAM_RAM_BASE + SAM_RAM_SIZE, 0xFFFFFFFFu)))
        return init_fail(m, "the memory fault hook", ue);
    if ((ue = uc_ctl_tlb_mode(m->uc, UC_TLB_VIRTUAL)) != UC_ERR_OK ||
        (ue = uc_hook_add(m->uc, &m->hooks[4], UC_HOOK_TLB_FILL, hook_fn((any_fn)hook_tlb), m, 1, 0)) != UC_ERR_OK)
        return init_fail(m, "the TLB", ue);
    if ((ue = uc_ctl_exits_enable(m->uc)) != UC_ERR_OK)
        return init_fail(m, "exits mode", ue);
    for (int s = 0; s < SAM_NSLOTS; s++)
        m->slot[s] = SAM_NEVER;
    m->next_ev = SAM_NEVER;
    return 0;
}

void sam_mcu_free(sam_mcu_t *m)
{
    if (m->uc)
        uc_close(m->uc);
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        if ((int)pi != sam_idx.iobus)
            free(m->regs[pi]);
        free(m->pst[pi]);
        for (int v = 0; v < 5; v++)
            free(m->omap[pi][v]);
    }
    free(m->flash);
    free(m->ram);
    free(m->nvm);
    free(m->ff.snap_ram);
    free(m->touch);
    free(m->prof);
    free(m->notes);
}

/* Every peripheral to its reset state, the core to the application's entry (the bootloader's hand-off: VTOR at
 * the application's vector table, SP and PC from it). RAM is kept (a power-on reset clears it first). */
static void do_reset(sam_mcu_t *m, uint8_t cause)
{
    m->t_blk = m->t;
    sam_world_pins_will_change(m);
    m->reset_cause = cause;
    m->resets++;
    m->lockup = 0;
    m->in_reset = 0;
    m->irq_check = m->primask_wait = 0;
    memset(&m->nvic, 0, sizeof m->nvic);
    memset(&m->systick, 0, sizeof m->systick);
    m->nvic.vtor = SAM_APP_BASE;
    for (int s = 0; s < SAM_NSLOTS; s++)
        if (s != SAM_SLOT_PINS && s != SAM_SLOT_FAULT && s != SAM_SLOT_USB && s != SAM_SLOT_BUS)
            m->slot[s] = SAM_NEVER;
    next_event(m);
    m->rws = 0;
    m->cyc_tu = (uint32_t)(SAM_TU_HZ / 1000000u);   /* GCLK0 = OSC8M / 8 = 1 MHz after reset */
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        if (strcmp(p->name, "PORT_IOBUS"))
            memset(m->regs[pi], 0, p->size);
        for (unsigned ri = p->reg0; ri < p->reg1; ri++)
            if (sam_regs[ri].reset && sam_regs[ri].kind == SAM_KIND_PLAIN)
                sam_reg_put(m, (int)ri, sam_regs[ri].reset);
    }
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        /* the default view's reset values win where views share an offset */
        int v = m->model[pi] && m->model[pi]->view ? m->model[pi]->view(m, (int)pi) : 0;
        for (unsigned ri = p->reg0; ri < p->reg1; ri++)
            if (sam_regs[ri].view == v && sam_regs[ri].kind == SAM_KIND_PLAIN)
                sam_reg_put(m, (int)ri, sam_regs[ri].reset);
        if (m->model[pi] && m->model[pi]->reset)
            m->model[pi]->reset(m, (int)pi);
    }
    uint32_t zero = 0, lr = 0xFFFFFFFFu;
    for (int i = 0; i < 13; i++)
        uc_reg_write(m->uc, CORE_REGS[i], &zero);
    reg_w32(m, UC_ARM_REG_PRIMASK, 0);
    reg_w32(m, UC_ARM_REG_CONTROL, 0);
    reg_w32(m, UC_ARM_REG_IPSR, 0);
    rebuild_hflags(m);
    reg_w32(m, UC_ARM_REG_LR, lr);
    reg_w32(m, UC_ARM_REG_SP, m->entry_sp);
    reg_w32(m, UC_ARM_REG_PC, m->entry_pc | 1u);
    m->prev_end = 0xFFFFFFFFu;
    memset(m->cache_tag, 0, sizeof m->cache_tag);
    m->ff.snap_valid = 0;
    m->ff.parked = 0;
    m->ff.resumed = 0;
    m->act++;
    sam_world_pins_changed(m);
}

void sam_mcu_power_on_reset(sam_mcu_t *m)
{
    memset(m->ram, 0, SAM_RAM_SIZE);
    m->halted = 0;
    do_reset(m, PM_RCAUSE_POR);
}

void sam_mcu_system_reset(sam_mcu_t *m, uint8_t cause) { request_reset(m, cause); }

/* ---------------------------------------------------------------- run */

static void enter_fault(sam_mcu_t *m, uc_err e)
{
    uint32_t pc = reg_u32(m, UC_ARM_REG_PC);
    uint32_t ipsr = reg_u32(m, UC_ARM_REG_XPSR) & 0x3Fu;
    sam_note(m, "%s: HardFault (%s at 0x%08x, pc 0x%05x) at t = %.6f s", m->name, uc_strerror(e),
                   m->fault_addr, pc, (double)m->t / (double)SAM_TU_HZ);
    if (ipsr == 3 || ipsr == 2) {
        lockup(m, "fault in the HardFault handler");
        return;
    }
    m->nvic.sys_pending |= 1u << 3;
    exc_enter(m, 3, pc);
}

/* Events only (the core is stopped: lockup): peripherals keep running, a watchdog may reset the board. */
static void run_events_only(sam_mcu_t *m)
{
    while (m->next_ev < m->stop_at && !m->err && !m->in_reset) {
        m->t = m->next_ev;
        process_events(m);
    }
    if (m->t < m->stop_at && !m->in_reset)
        m->t = m->stop_at;
}

/* No power: nothing runs; the bus still sees it (as an absent slave) and the encoders still turn. */
static void run_unpowered(sam_mcu_t *m)
{
    static const int slots[2] = {SAM_SLOT_BUS, SAM_SLOT_PINS};
    for (;;) {
        int s = m->slot[slots[0]] <= m->slot[slots[1]] ? slots[0] : slots[1];
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
    if (m->next_ev >= t_end)
        return 1;
    sam_bus_take_quiet(m, t_end);
    return m->next_ev >= t_end;
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
            /* resume at the last loop() entry before the event: the pass it falls in runs */
            uint64_t k = m->next_ev > m->ff.anchor ? (m->next_ev - m->ff.anchor) / m->ff.period : 0;
            m->t = m->ff.anchor + k * m->ff.period;
            m->ff.passes_skipped += k;
            m->cycles += k * m->ff.period_cycles;   /* the passes skipped ran, as far as anyone can tell */
            m->ff.cycles_skipped += k * m->ff.period_cycles;
            m->ff.parked = 0;
            m->ff.resumed = 1;
            m->prev_end = 0xFFFFFFFFu;
        }
        if (m->t >= m->stop_at)
            break;
        if (m->in_reset) {
            do_reset(m, (uint8_t)m->in_reset);
            continue;
        }
        if (m->lockup) {
            run_events_only(m);
            continue;
        }
        uint32_t pc = reg_u32(m, UC_ARM_REG_PC);
        m->runs++;
        uc_err e = uc_emu_start(m->uc, pc | 1u, 0, 0, 0);
        if (m->err)
            break;
        if (e == UC_ERR_FETCH_PROT && (pc = reg_u32(m, UC_ARM_REG_PC)) >= SAM_RAM_BASE &&
            pc < SAM_RAM_BASE + SAM_RAM_SIZE) {
            sam_fail(m, "code executed from SRAM at 0x%08x: only flash has a cycle model", pc);
            break;
        }
        if (e != UC_ERR_OK)
            enter_fault(m, e);
    }
    m->pos = m->stop_at;
    return m->err ? -1 : 0;
}
