/* The register layer: the generated table's lookups and storage, the access rules, and MMIO dispatch to the models. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam_core.h"

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

/* ---------------------------------------------------------------- generic register layer */

static uint32_t generic_read(sam_mcu_t *m, int ri)
{
    return sam_reg_get(m, sam_regs[ri].alias != ri ? sam_regs[ri].alias : ri);
}

/* what the table's access rule leaves in a register's storage that holds old, after a write of v under mask */
static uint32_t generic_next(const sam_reg_t *r, uint32_t old, uint32_t v, uint32_t mask)
{
    switch (r->kind) {
    case SAM_KIND_W1C: return old & ~(v & mask);
    case SAM_KIND_SET: return old | (v & mask);
    case SAM_KIND_CLR: return old & ~(v & mask);
    case SAM_KIND_TGL: return old ^ (v & mask);
    default: return (old & ~mask) | (v & mask);
    }
}

int sam_generic_changes(sam_mcu_t *m, int ri, uint32_t v, uint32_t mask)
{
    const sam_reg_t *r = &sam_regs[ri];
    uint32_t old = sam_reg_get(m, r->alias);
    return generic_next(r, old, v, mask) != old;
}

void sam_generic_write(sam_mcu_t *m, int ri, uint32_t v, uint32_t mask)
{
    const sam_reg_t *r = &sam_regs[ri];
    int target = r->alias;
    uint32_t old = sam_reg_get(m, target), nv = generic_next(r, old, v, mask);
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

/* (regtable.PERIPHERAL_REGIONS lists the same regions) */
#define NREGIONS 5
static const uint32_t REGION_BASE[NREGIONS] = {0x40000000u, 0x41000000u, 0x42000000u, 0x60000000u, 0xE000E000u};
static const uint32_t REGION_SIZE[NREGIONS] = {0x2000u, 0x8000u, 0x6000u, 0x1000u, 0x1000u};  /* whole 4 KiB pages */

/* The generated table's values, checked before any board uses them: regtable.check refuses a bad table in Python
 * first; this keeps one that got past it from indexing outside the runtime's arrays. 0, or -1 with err set. */
int sam_regtab_check(char *err, size_t cap)
{
    static const char *const needed[] = {"PM", "SYSCTRL", "GCLK", "WDT", "EIC", "NVMCTRL", "PORT", "PORT_IOBUS",
                                         "USB", "TC3", "TCC0", "TCC1", "TCC2", "NVIC", "SCB", "SysTick"};
    if (sam_nperiphs < 1 || sam_nperiphs > SAM_MAX_PERIPH || sam_nregs > 0x7FFFu) {
        snprintf(err, cap, "register table: %u instances (1..%d), %u registers", sam_nperiphs, SAM_MAX_PERIPH, sam_nregs);
        return -1;
    }
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        int inside = 0;
        for (int i = 0; i < NREGIONS; i++)
            if (p->base >= REGION_BASE[i] && p->base - REGION_BASE[i] < REGION_SIZE[i] && p->size > 0 &&
                p->size <= REGION_SIZE[i] - (p->base - REGION_BASE[i]))
                inside = 1;
        /* a PAC bit (sam_pac.c): on the instance's own bridge, inside the 64 KiB its page mask covers */
        uint32_t bridge = 0x40000000u + ((uint32_t)(p->pac / 32) << 24);
        int pac_ok = p->pac == -1 ||
                     (p->pac >= 0 && p->pac < 96 && p->base >= bridge && p->base + p->size <= bridge + 0x10000u);
        if (!inside || !pac_ok || p->irq < -1 || p->irq > 31 || p->nviews > 4 || p->reg0 > p->reg1 ||
            p->reg1 > sam_nregs) {
            snprintf(err, cap,
                     "register table: %s at 0x%x (+0x%x), IRQ %d, PAC bit %d, %u views, registers %u..%u: out of range",
                     p->name, p->base, p->size, p->irq, p->pac, p->nviews, p->reg0, p->reg1);
            return -1;
        }
        for (unsigned ri = p->reg0; ri < p->reg1; ri++) {
            const sam_reg_t *r = &sam_regs[ri];
            if ((r->size != 1 && r->size != 2 && r->size != 4) || r->size > p->size || r->offset > p->size - r->size ||
                r->periph != pi || r->view > p->nviews || r->alias >= sam_nregs || r->field0 > sam_nfields ||
                r->nfields > sam_nfields - r->field0) {
                snprintf(err, cap, "register table: %s at offset 0x%x, %u bytes: out of range", r->name, r->offset,
                         r->size);
                return -1;
            }
        }
    }
    for (unsigned k = 0; k < sam_nfields; k++) {
        const sam_field_t *f = &sam_fields[k];
        if (f->reg >= sam_nregs || f->width < 1 || f->pos >= 32 || f->width > 32 - f->pos) {
            snprintf(err, cap, "register table: field %s at bit %u, %u wide: out of range", f->name, f->pos, f->width);
            return -1;
        }
    }
    for (unsigned k = 0; k < sam_npinmux; k++)
        if (sam_pinmux[k].pin > 63 || sam_pinmux[k].func > 7) {
            snprintf(err, cap, "register table: pin function %s/%s on pin %u, function %u", sam_pinmux[k].periph,
                     sam_pinmux[k].signal, sam_pinmux[k].pin, sam_pinmux[k].func);
            return -1;
        }
    for (size_t k = 0; k < sizeof needed / sizeof needed[0]; k++)
        if (sam_periph_index(needed[k]) < 0) {
            snprintf(err, cap, "register table: no instance %s", needed[k]);
            return -1;
        }
    int port = sam_periph_index("PORT"), iobus = sam_periph_index("PORT_IOBUS");
    if (sam_periphs[iobus].size > sam_periphs[port].size) {
        snprintf(err, cap, "register table: PORT_IOBUS's window is larger than PORT's");
        return -1;
    }
    return 0;
}

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
        if (ri < 0 && b > 0) {
            /* a reserved byte inside a wider access that starts on a register: it reads as zero and a write to it
             * is ignored (DS40001882: reserved bits read as zero, writing them has no effect); bossac reads the
             * 16-bit NVMCTRL.STATUS as a word. An access that starts on no register stays an error. */
            b++;
            continue;
        }
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
                         v >> (8 * lo), sam_cpu_reg(m, UC_ARM_REG_IPSR) & 0x3Fu);
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
                         (v & mask) >> (8 * lo), sam_cpu_reg(m, UC_ARM_REG_IPSR) & 0x3Fu);
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

/* Every access by the CPU: with timed passes on, the fast-forward's record of the pass (and a probe's check before
 * the access happens, sam_ff.c); the counters; the register layer. */
static int cpu_access(sam_mcu_t *m, region_t *rg, uint32_t addr, unsigned size, int write, uint32_t *v)
{
    if (m->ff.timed) {
        uint32_t key = addr << 4 | size << 1 | (write ? 1u : 0u);
        if (m->ff.probing && !sam_ff_probe_access(m, key))
            return 0;
        sam_ff_access(m, key);
    }
    if (write)
        m->mmio_writes++;
    else
        m->mmio_reads++;
    return reg_access(m, rg, addr, size, write, v);
}

static uint64_t mmio_read(uc_engine *uc, uint64_t offset, unsigned size, void *ud)
{
    region_t *rg = ud;
    (void)uc;
    uint32_t v = 0;
    cpu_access(rg->m, rg, rg->base + (uint32_t)offset, size, 0, &v);
    return v;
}

static void mmio_write(uc_engine *uc, uint64_t offset, unsigned size, uint64_t value, void *ud)
{
    region_t *rg = ud;
    (void)uc;
    uint32_t v = (uint32_t)value;
    cpu_access(rg->m, rg, rg->base + (uint32_t)offset, size, 1, &v);
}

/* A store the CPU stopped at and the run loop carries out (to a PAC: sam_pac.c), as the MMIO dispatch does it. */
int sam_mmio_store(sam_mcu_t *m, uint32_t addr, unsigned size, uint32_t v)
{
    for (int i = 0; i < NREGIONS; i++) {
        region_t *rg = m->regions[i];
        if (rg && addr - rg->base < rg->size && size <= rg->size - (addr - rg->base))
            return cpu_access(m, rg, addr, size, 1, &v);
    }
    sam_fail(m, "write of %u bytes at 0x%08x: no peripheral there", size, addr);
    return -1;
}

/* The peripheral regions, each mapped into Unicorn with a page table of its peripherals. */
int sam_mmio_map(sam_mcu_t *m)
{
    uc_err ue;
    for (int i = 0; i < NREGIONS; i++) {
        region_t *rg = calloc(1, sizeof *rg);
        if (!rg)
            return -1;
        m->regions[i] = rg;
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
            return sam_init_fail(m, "mapping the peripheral region", ue);
    }
    return 0;
}

void sam_mmio_free(sam_mcu_t *m)
{
    for (int i = 0; i < NREGIONS; i++) {
        region_t *rg = m->regions[i];
        if (rg)
            free(rg->page);
        free(rg);
        m->regions[i] = NULL;
    }
}
