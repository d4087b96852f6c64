/* Register-level harness: a board runs a stub program (no image); tests reach its registers as its CPU would. */
#include <string.h>
#include "sam.h"
#include "sam_world.h"

/*
 * The board's CPU does the accesses: a routine of the stub ("ldr r1, [r0]" or "str r1, [r0]" and "b .") is run
 * with R0 and R1 set, through Unicorn, the MMIO dispatch and the models, at the board's own time, with the cycles
 * it costs; then the interrupted context (PC, R0, R1) is put back. Nothing here reaches into a model.
 */

static sam_mcu_t *board(sam_world_t *w, int mcu)
{
    return mcu >= 0 && mcu < SAM_MAX_MCU ? w->mcu[mcu] : NULL;
}

uint64_t sam_harness_now(const sam_world_t *w, int mcu)
{
    const sam_mcu_t *m = mcu >= 0 && mcu < SAM_MAX_MCU ? w->mcu[mcu] : NULL;
    if (!m)
        return 0;
    return m->ff.parked && m->t < w->t ? w->t : m->t;
}

const char *sam_harness_error(const sam_world_t *w, int mcu)
{
    const sam_mcu_t *m = mcu >= 0 && mcu < SAM_MAX_MCU ? w->mcu[mcu] : NULL;
    return m && m->err ? m->errmsg : NULL;
}

/* A parked board (an idle pass repeating) resumes at its last loop entry at or before t, as sam_mcu_run does. */
static void unpark(sam_mcu_t *m, uint64_t t)
{
    sam_ff_t *f = &m->ff;
    if (!f->parked)
        return;
    uint64_t k = t > f->anchor ? (t - f->anchor) / f->period : 0;
    m->t = f->anchor + k * f->period;
    f->passes_skipped += k;
    m->cycles += k * f->period_cycles;
    f->cycles_skipped += k * f->period_cycles;
    f->parked = 0;
    f->resumed = 1;
    m->prev_end = 0xFFFFFFFFu;
}

static uint32_t rd(sam_mcu_t *m, int reg)
{
    uint32_t v = 0;
    uc_reg_read(m->uc, reg, &v);
    return v;
}

static void wr(sam_mcu_t *m, int reg, uint32_t v) { uc_reg_write(m->uc, reg, &v); }

int sam_harness_call(sam_world_t *w, int mcu, uint32_t pc, uint32_t done_pc, uint32_t r0, uint32_t *r1,
                     uint64_t *t_start)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m || m->err || m->halted)
        return -1;
    int ff = m->ff.enabled;
    m->ff.enabled = 0;   /* the board runs block by block here: no idle pass is skipped */
    unpark(m, w->t);
    int bad = m->t < w->t && sam_mcu_run(m, w->t);   /* every event before now taken */
    /* a board at its reset vector runs its reset handler first (the stub's masks interrupts) */
    for (int n = 0; n < 16 && !bad && (rd(m, UC_ARM_REG_PC) & ~1u) == (m->entry_pc & ~1u); n++)
        bad = sam_mcu_run(m, m->t + 1);
    if (bad) {
        m->ff.enabled = ff;
        return -1;
    }
    uint32_t saved[3] = {rd(m, UC_ARM_REG_PC), rd(m, UC_ARM_REG_R0), rd(m, UC_ARM_REG_R1)};
    uint32_t resets = m->resets;
    wr(m, UC_ARM_REG_R0, r0);
    wr(m, UC_ARM_REG_R1, *r1);
    wr(m, UC_ARM_REG_PC, pc | 1u);
    m->prev_end = 0xFFFFFFFFu;
    *t_start = m->t;
    int rc = 0, done = 0;
    for (int n = 0; n < 1000000 && !m->err; n++) {
        if (sam_mcu_run(m, m->t + 1)) {
            rc = -1;
            break;
        }
        if (m->in_reset || m->resets != resets || m->lockup)
            break;   /* the access reset the board (or stopped its core): nothing to put back */
        if ((rd(m, UC_ARM_REG_PC) & ~1u) == done_pc) {
            done = 1;
            break;
        }
    }
    if (m->in_reset && !m->err)
        sam_mcu_run(m, m->t + 1);   /* the reset happens now */
    if (done) {
        *r1 = rd(m, UC_ARM_REG_R1);
        wr(m, UC_ARM_REG_R0, saved[1]);
        wr(m, UC_ARM_REG_R1, saved[2]);
        wr(m, UC_ARM_REG_PC, saved[0]);
        m->prev_end = 0xFFFFFFFFu;
    } else if (!m->err && m->resets == resets && !m->lockup) {
        sam_fail(m, "harness: the CPU did not reach the end of the access routine");
        rc = -1;
    }
    m->ff.enabled = ff;
    m->ff.snap_valid = 0;
    return m->err ? -1 : rc;
}

int sam_harness_flash(sam_world_t *w, int mcu, uint32_t addr, const uint8_t *data, uint32_t n)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m || addr > SAM_FLASH_SIZE || n > SAM_FLASH_SIZE - addr)
        return -1;
    memcpy(m->flash + addr, data, n);
    return sam_cpu_flash_changed(m, addr, n);
}

int sam_harness_pin(sam_world_t *w, int mcu, int32_t pin, int32_t level)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m || pin < 0 || pin > 63 || level < -1 || level > 1)
        return -1;
    return sam_world_pinq_push(w, mcu, sam_harness_now(w, mcu), pin, level);
}

int sam_harness_pin_state(const sam_world_t *w, int mcu, int32_t pin, sam_pin_info_t *out)
{
    sam_mcu_t *m = mcu >= 0 && mcu < SAM_MAX_MCU ? w->mcu[mcu] : NULL;
    if (!m || pin < 0 || pin > 63)
        return -1;
    int driven = 0;
    out->level = sam_pin_level(m, pin);
    out->out = sam_pin_out(m, pin, &driven);
    out->driven = driven;
    out->function = sam_pin_function(m, pin);
    return 0;
}

int sam_harness_nvic(const sam_world_t *w, int mcu, sam_nvic_info_t *out)
{
    const sam_mcu_t *m = mcu >= 0 && mcu < SAM_MAX_MCU ? w->mcu[mcu] : NULL;
    if (!m)
        return -1;
    out->enabled = m->nvic.enabled;
    out->pending = m->nvic.pending;
    out->active = m->nvic.active;
    out->level = m->nvic.level;
    out->sys_pending = m->nvic.sys_pending;
    out->sys_active = m->nvic.sys_active;
    out->cyc_tu = m->cyc_tu;
    return 0;
}
