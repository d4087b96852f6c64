/* The image tier's world: boards on a plant, their notes, life cycle (creation, loading, freeing) and queries. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam_world.h"
#include "sam_vendor_gen.h"

/* The world is in four files: this one, the plant's side of the boards (sam_world_plant.c: pins, drivers, motors,
 * encoders, plant windows), faults (sam_world_faults.c) and the time loop (sam_world_run.c). */

static uint64_t tu_of(double s) { return (uint64_t)llround(s * (double)SAM_TU_HZ); }

/* Append a line to a notes buffer of capacity cap; when full, the oldest lines go (whole lines). */
static void notes_append(char *buf, uint32_t *len, uint32_t cap, const char *line, uint32_t n)
{
    if (n > cap - *len) {
        uint32_t drop = *len / 2;
        while (drop < *len && buf[drop - 1] != '\n')
            drop++;
        memmove(buf, buf + drop, *len - drop);
        *len -= drop;
    }
    if (n <= cap - *len) {
        memcpy(buf + *len, line, n);
        *len += n;
    }
}

static uint32_t vformat(char line[400], const char *fmt, va_list ap)
{
    int n = vsnprintf(line, 399, fmt, ap);
    if (n < 0)
        return 0;
    if (n > 398)
        n = 398;
    line[n++] = '\n';
    return (uint32_t)n;
}

/* A note from the world itself (run between boards' runs). */
void sam_world_note(sam_world_t *w, const char *fmt, ...)
{
    char line[400];
    va_list ap;
    va_start(ap, fmt);
    uint32_t n = vformat(line, fmt, ap);
    va_end(ap);
    notes_append(w->notes, &w->notes_len, sizeof w->notes, line, n);
}

/* A note from a board: kept with the board until the world collects the boards' notes in board order (boards
 * may run at the same time on several threads). */
void sam_note(sam_mcu_t *m, const char *fmt, ...)
{
    char line[400];
    va_list ap;
    va_start(ap, fmt);
    uint32_t n = vformat(line, fmt, ap);
    va_end(ap);
    notes_append(m->notes, &m->notes_len, SAM_BOARD_NOTES, line, n);
}

void sam_world_collect_notes(sam_world_t *w)
{
    for (int i = 0; i < w->nmcu; i++) {
        sam_mcu_t *m = w->mcu[i];
        if (m && m->notes_len) {
            notes_append(w->notes, &w->notes_len, sizeof w->notes, m->notes, m->notes_len);
            m->notes_len = 0;
        }
    }
}

uint32_t sam_world_notes(sam_world_t *w, char *buf, uint32_t cap)
{
    sam_world_collect_notes(w);
    uint32_t n = w->notes_len < cap ? w->notes_len : cap;
    memcpy(buf, w->notes, n);
    memmove(w->notes, w->notes + n, w->notes_len - n);
    w->notes_len -= n;
    return n;
}

int sam_world_fail(sam_world_t *w, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(w->err, sizeof w->err, fmt, ap);
    va_end(ap);
    return -1;
}

const char *sam_world_error(const sam_world_t *w) { return w->err; }

void sam_world_set_trace(sam_world_t *w, int32_t trace, int32_t boards)
{
    w->cfg.trace = trace;
    w->cfg.trace_boards = boards;
}
uint64_t sam_world_time(const sam_world_t *w) { return w->t; }
uint64_t sam_tu_hz(void) { return SAM_TU_HZ; }
uint32_t sam_world_nregs(void) { return sam_nregs; }
const char *sam_world_reg_name(uint32_t ri) { return sam_reg_name((int)ri); }

/* ---------------------------------------------------------------- life cycle */

int sam_world_new(sam_world_t **out, const sam_world_cfg_t *cfg)
{
    *out = NULL;
    sam_world_t *w = calloc(1, sizeof *w);
    if (!w)
        return -1;
    *out = w;
    w->cfg = *cfg;
    if (cfg->ncells < 1 || cfg->ncells > 16)
        return sam_world_fail(w, "ncells = %d: expected 1..16", cfg->ncells);
    if (!cfg->plant || !cfg->x || !cfg->v || cfg->plant->n != cfg->ncells)
        return sam_world_fail(w, "the plant must exist and have ncells cells");
    if (!(cfg->window_s > 0 && cfg->window_s <= 0.01) || cfg->substeps < 1 || cfg->substeps > 10000)
        return sam_world_fail(w, "window_s = %g (0 < W <= 10 ms), substeps = %d (1..10000)", cfg->window_s, cfg->substeps);
    if (cfg->cycle_model != SAM_CYCLES_CACHE && cfg->cycle_model != SAM_CYCLES_WORST)
        return sam_world_fail(w, "cycle_model = %d: expected %d (cache) or %d (worst)", cfg->cycle_model, SAM_CYCLES_CACHE,
                    SAM_CYCLES_WORST);
    if (cfg->cyc_exc_entry < 1 || cfg->cyc_exc_entry > 100 || cfg->cyc_exc_exit < 1 || cfg->cyc_exc_exit > 100 ||
        cfg->cyc_apb < 0 || cfg->cyc_apb > 100)
        return sam_world_fail(w, "cycle model: exception entry %d, return %d, APB access %d cycles (expected 1..100, 0..100)",
                    cfg->cyc_exc_entry, cfg->cyc_exc_exit, cfg->cyc_apb);
    if (!(cfg->supply_v > 0) || !(cfg->kt > 0) || !(cfg->counts_per_rad > 0))
        return sam_world_fail(w, "supply_v, kt and counts_per_rad must be > 0");
    const int32_t *pins[] = {&cfg->pin_nsleep, &cfg->pin_ph[0], &cfg->pin_ph[1], &cfg->pin_en[0], &cfg->pin_en[1],
                             &cfg->pin_enc[0][0], &cfg->pin_enc[0][1], &cfg->pin_enc[1][0], &cfg->pin_enc[1][1],
                             &cfg->pin_sda, &cfg->pin_scl};
    for (size_t k = 0; k < sizeof pins / sizeof pins[0]; k++)
        if (*pins[k] < 0 || *pins[k] > 63)
            return sam_world_fail(w, "board wiring: pin %d outside PA00..PB31", *pins[k]);
    w->window_tu = tu_of(cfg->window_s);
    w->round_tu = cfg->round_s > 0 ? tu_of(cfg->round_s) : w->window_tu;
    if (!(cfg->round_s >= 0) || w->round_tu == 0)
        return sam_world_fail(w, "round_s = %g: expected 0 (the window) or a positive time", cfg->round_s);
    w->plant_start = SAM_NEVER;
    w->primary_mcu = -1;
    for (int j = 0; j < 16; j++)
        w->cell_mcu[j] = -1;
    w->xprev = calloc(2 * (size_t)cfg->ncells, sizeof(double));
    if (!w->xprev)
        return sam_world_fail(w, "out of memory");
    for (int j = 0; j < cfg->ncells; j++)
        for (int ch = 0; ch < 2; ch++)
            w->count[j][ch] = (int32_t)floor(cfg->x[ch * cfg->ncells + j] * cfg->counts_per_rad);
    if (sam_bus_init(w))
        return sam_world_fail(w, "board wiring: SERCOM%d does not have SDA (pin %d) on PAD0 and SCL (pin %d) on PAD1",
                    cfg->bus_sercom, cfg->pin_sda, cfg->pin_scl);
    sam_world_plant_init();
    if (cfg->threads < 1 || cfg->threads > SAM_MAX_THREADS)
        return sam_world_fail(w, "threads = %d: expected 1..%d", cfg->threads, SAM_MAX_THREADS);
    if (sam_world_pool_start(w, cfg->threads))
        return -1;
    sam_usb_world_init(w);
    return 0;
}

void sam_world_free(sam_world_t *w)
{
    if (!w)
        return;
    sam_world_pool_stop(w);
    for (int i = 0; i < SAM_MAX_MCU; i++)
        if (w->mcu[i]) {
            sam_mcu_free(w->mcu[i]);
            free(w->mcu[i]);
        }
    free(w->xprev);
    free(w);
}

/* The factory rows the start-up code reads: the NVM software calibration row (NVMCTRL_OTP4, 0x00806020: ADC
 * linearity and bias, OSC32K, USB pad and DFLL48M coarse calibration, typical values) and the 128-bit serial
 * number (0x0080A00C, 0x0080A040..48), unique per board. */
static void nvm_rows(sam_mcu_t *m)
{
    uint8_t *n = m->nvm;
    memset(n, 0xFF, SAM_NVM_SIZE);
    n[SAM_NVM_USER_ROW - SAM_NVM_BASE] = (uint8_t)(0xF8u | SAM_NVM_BOOTPROT_ASSUMED);   /* erased, but BOOTPROT */
    uint64_t cal = 0;
    cal |= (uint64_t)0x1Du << 27;   /* ADC LINEARITY */
    cal |= (uint64_t)0x4u << 35;    /* ADC BIASCAL */
    cal |= (uint64_t)0x40u << 38;   /* OSC32K CAL */
    cal |= (uint64_t)0x9u << 45;    /* USB TRANSN */
    cal |= (uint64_t)0x19u << 50;   /* USB TRANSP */
    cal |= (uint64_t)0x5u << 55;    /* USB TRIM */
    cal |= (uint64_t)0x1Cu << 58;   /* DFLL48M COARSE */
    for (int b = 0; b < 8; b++)
        n[0x6020 + b] = (uint8_t)(cal >> (8 * b));
    uint32_t serial[4] = {0x4D43584Fu, 0x49414F00u + (uint32_t)m->id, 0x53414D44u, 0x3231AA00u + (uint32_t)m->id};
    uint32_t where[4] = {0xA00C, 0xA040, 0xA044, 0xA048};
    for (int k = 0; k < 4; k++)
        for (int b = 0; b < 4; b++)
            n[where[k] + (uint32_t)b] = (uint8_t)(serial[k] >> (8 * b));
}

int sam_world_load(sam_world_t *w, int mcu, const sam_image_t *img, const char *name, int32_t role, int32_t cell)
{
    const sam_seg_t *segs = img->segs;
    int32_t nsegs = img->nsegs;
    uint32_t code_end = img->code_end;
    if (mcu < 0 || mcu >= SAM_MAX_MCU || w->mcu[mcu])
        return sam_world_fail(w, "board %d: out of range or already loaded", mcu);
    if (role == SAM_ROLE_CELL && (cell < 0 || cell >= w->cfg.ncells || w->cell_mcu[cell] >= 0))
        return sam_world_fail(w, "board %d: cell %d out of range or taken", mcu, cell + 1);
    if (role == SAM_ROLE_PRIMARY && w->primary_mcu >= 0)
        return sam_world_fail(w, "board %d: a second primary", mcu);
    if (nsegs < 0 || (nsegs > 0 && !segs))
        return sam_world_fail(w, "board %d: %d image segments", mcu, nsegs);
    /* every segment inside the flash (below the application only with boot from the reset vector: the bootloader);
     * bounds as `len > SIZE - addr`, which no address can wrap */
    for (int k = 0; k < nsegs; k++)
        if ((!img->boot && segs[k].addr < SAM_APP_BASE) || segs[k].addr > SAM_FLASH_SIZE ||
            segs[k].len > SAM_FLASH_SIZE - segs[k].addr || (segs[k].len && !segs[k].data))
            return sam_world_fail(w, "board %d: image segment at 0x%x (+%u) outside the application flash", mcu,
                                  segs[k].addr, segs[k].len);
    /* the ELF's cycle tables, all or none (none: the decoder costs every block, sam_cost.c) */
    int tables = img->cost_core != NULL;
    if (tables != (img->cost_wait != NULL) || tables != (img->cost_lit != NULL) || tables != (img->refund != NULL) ||
        (tables && (code_end > SAM_FLASH_SIZE || code_end < SAM_APP_BASE)))
        return sam_world_fail(w, "board %d: cycle tables incomplete or code end 0x%x outside flash", mcu, code_end);
    sam_mcu_t *m = calloc(1, sizeof *m);
    if (!m)
        return sam_world_fail(w, "board %d: out of memory", mcu);
    if (sam_mcu_init(m, w, mcu)) {
        sam_world_fail(w, "board %d: %s", mcu, m->errmsg[0] ? m->errmsg : "cannot create the CPU or its memory");
        sam_mcu_free(m);
        free(m);
        return -1;
    }
    w->mcu[mcu] = m;
    if (mcu >= w->nmcu)
        w->nmcu = mcu + 1;
    /* the world's event sources on the board, in this order (events due at the same time are taken in it) */
    sam_world_pins_init(m);
    sam_bus_port_init(m);
    sam_usb_port_init(m);
    sam_world_faults_init(m);
    snprintf(m->name, sizeof m->name, "%s", name);
    m->role = role;
    m->cell = role == SAM_ROLE_CELL ? cell : -1;
    if (img->boot)
        memset(m->flash, 0xFF, SAM_FLASH_SIZE);   /* a real board's flash: erased but for what was programmed */
    for (int k = 0; k < nsegs; k++)
        if (segs[k].len)
            memcpy(m->flash + segs[k].addr, segs[k].data, segs[k].len);
    m->boot = img->boot != 0;
    m->entry_sp = img->entry_sp;
    m->entry_pc = img->entry_pc;
    m->cost_core = img->cost_core;
    m->cost_wait = img->cost_wait;
    m->cost_lit = img->cost_lit;
    m->cycle_model = w->cfg.cycle_model;
    m->refund = img->refund;
    m->app_end = tables ? code_end : 0;
    m->tab_lo = SAM_APP_BASE;
    /* static data end and heap break: unknown ones make the fast-forward compare the whole SRAM */
    m->heap_base = img->heap_base > SAM_RAM_BASE && img->heap_base <= SAM_RAM_BASE + SAM_RAM_SIZE
                       ? img->heap_base - SAM_RAM_BASE
                       : SAM_RAM_SIZE;
    m->brk_var = img->brk_var;
    m->ff.loop_pc = img->loop_pc;
    m->ff.enabled = w->cfg.ff && img->loop_pc != 0;
    m->ff.timed = w->cfg.ff_timed;
    m->ff.head = m->ff.loop_pc;
    m->ff.horizon = SAM_NEVER;
    m->ff.jcap = SAM_FF_JCAP0;
    nvm_rows(m);
    if (role == SAM_ROLE_CELL) {
        w->cell_mcu[cell] = mcu;
        /* the encoders drive their pins from power-up */
        for (int ch = 0; ch < 2; ch++) {
            int g = he_gray(w->count[cell][ch]);
            w->enc_level[cell][ch][0] = (uint8_t)((g >> 1) & 1);
            w->enc_level[cell][ch][1] = (uint8_t)(g & 1);
        }
    } else {
        w->primary_mcu = mcu;
    }
    m->t = m->pos = w->t;
    sam_mcu_power_on_reset(m);
    if (role == SAM_ROLE_CELL)
        for (int ch = 0; ch < 2; ch++)
            for (int k = 0; k < 2; k++)
                sam_pin_drive(m, w->cfg.pin_enc[ch][k], w->enc_level[cell][ch][k]);
    if (m->err)
        return sam_world_fail(w, "%s", m->errmsg);
    return 0;
}

void sam_world_start_plant(sam_world_t *w, uint64_t t_start)
{
    w->plant_start = t_start;
    w->plant_t = 0.0;
}

/* ---------------------------------------------------------------- queries */

int sam_world_mcu_info(const sam_world_t *w, int mcu, sam_mcu_info_t *o)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu])
        return -1;
    sam_mcu_t *m = w->mcu[mcu];
    memset(o, 0, sizeof *o);
    o->t_tu = m->ff.parked && m->t < w->t ? w->t : m->t;
    o->cycles = m->cycles;
    o->activity = m->act;
    uc_reg_read(m->uc, UC_ARM_REG_PC, &o->pc);
    uc_reg_read(m->uc, UC_ARM_REG_SP, &o->sp);
    uint32_t xpsr = 0;
    uc_reg_read(m->uc, UC_ARM_REG_XPSR, &xpsr);
    o->ipsr = xpsr & 0x3Fu;
    uc_reg_read(m->uc, UC_ARM_REG_PRIMASK, &o->primask);
    o->resets = m->resets;
    o->hardfaults = m->hardfaults;
    o->reset_cause = m->reset_cause;
    o->lockup = m->lockup;
    o->halted = m->halted;
    o->ff_passes_skipped = m->ff.passes_skipped;
    o->ff_cycles_skipped = m->ff.cycles_skipped;
    o->runs = m->runs;
    o->tlb_fills = m->tlb_fills;
    o->ff_parks = m->ff.parks;
    o->ff_checks = m->ff.checks;
    o->ff_misses = m->ff.misses;
    o->ff_probes = m->ff.probes;
    o->ff_probe_fails = m->ff.probe_fails;
    o->ff_traps = m->ff.traps;
    o->mmio_reads = m->mmio_reads;
    o->mmio_writes = m->mmio_writes;
    o->nvic_enabled = m->nvic.enabled;
    o->nvic_pending = m->nvic.pending;
    o->nvic_active = m->nvic.active;
    memcpy(o->nvic_prio, m->nvic.prio, 32);
    o->nvm_erases = m->nvm_erases;
    o->nvm_writes = m->nvm_writes;
    o->vtor = m->nvic.vtor;
    return 0;
}

int sam_world_read_mem(const sam_world_t *w, int mcu, uint32_t addr, uint8_t *buf, uint32_t len)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu])
        return -1;
    sam_mcu_t *m = w->mcu[mcu];
    if (addr >= SAM_RAM_BASE && addr - SAM_RAM_BASE <= SAM_RAM_SIZE && len <= SAM_RAM_SIZE - (addr - SAM_RAM_BASE)) {
        memcpy(buf, m->ram + (addr - SAM_RAM_BASE), len);
        return 0;
    }
    if (addr <= SAM_FLASH_SIZE && len <= SAM_FLASH_SIZE - addr) {
        memcpy(buf, m->flash + addr, len);
        return 0;
    }
    return -1;
}

int sam_world_set_user_row(sam_world_t *w, int mcu, const uint8_t *row, uint32_t len)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu] || len > 256u)
        return -1;
    sam_mcu_t *m = w->mcu[mcu];
    memcpy(m->nvm + (SAM_NVM_USER_ROW - SAM_NVM_BASE), row, len);
    sam_nvm_load_fuses(m);
    return 0;
}

int sam_world_reg_value(const sam_world_t *w, int mcu, uint32_t ri, uint32_t *value)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu] || ri >= sam_nregs)
        return -1;
    *value = sam_reg_get(w->mcu[mcu], (int)ri);
    return 0;
}

const uint32_t *sam_world_touch(const sam_world_t *w, int mcu)
{
    return mcu >= 0 && mcu < SAM_MAX_MCU && w->mcu[mcu] ? w->mcu[mcu]->touch : NULL;
}

const uint64_t *sam_world_profile(sam_world_t *w, int mcu)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu])
        return NULL;
    sam_mcu_t *m = w->mcu[mcu];
    if (!m->prof)
        m->prof = calloc(SAM_FLASH_SIZE / 2, sizeof *m->prof);
    return m->prof;
}

int sam_world_motor(const sam_world_t *w, int cell, int chain, double *volt, double *awake)
{
    if (cell < 0 || cell >= w->cfg.ncells || chain < 0 || chain > 1)
        return -1;
    *volt = w->motor[cell][chain].volt;
    *awake = w->motor[cell][chain].awake;
    return 0;
}
