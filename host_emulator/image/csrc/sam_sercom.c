/* SERCOM: the serial communication interface's common part (CTRLA, SWRST, SYNCBUSY), dispatching by CTRLA.MODE. */
#include <stdlib.h>
#include <string.h>
#include "sam_sercom.h"
#include "sam_vendor_gen.h"

/* The modes by CTRLA.MODE: 0 USART with an external clock, 1 USART, 2 SPI slave, 3 SPI master, 4 I2C slave,
 * 5 I2C master; NULL: not modelled (enabling it is an error naming the mode). A new mode is a file with a
 * sam_sercom_mode_t, its rows here and in ALL_MODES. */
static const sam_sercom_mode_t *const MODES[8] = {NULL, NULL, NULL, NULL, &sam_sercom_i2c, &sam_sercom_i2c, NULL, NULL};
static const sam_sercom_mode_t *const ALL_MODES[] = {&sam_sercom_i2c};
#define NMODES (sizeof ALL_MODES / sizeof ALL_MODES[0])

/* generic clock channels of SERCOM0..5 */
static const int GCLK_CORE[6] = {SERCOM0_GCLK_ID_CORE, SERCOM1_GCLK_ID_CORE, SERCOM2_GCLK_ID_CORE,
                                 SERCOM3_GCLK_ID_CORE, SERCOM4_GCLK_ID_CORE, SERCOM5_GCLK_ID_CORE};
static const int GCLK_SLOW[6] = {SERCOM0_GCLK_ID_SLOW, SERCOM1_GCLK_ID_SLOW, SERCOM2_GCLK_ID_SLOW,
                                 SERCOM3_GCLK_ID_SLOW, SERCOM4_GCLK_ID_SLOW, SERCOM5_GCLK_ID_SLOW};

static const sam_sercom_mode_t *mode_of(const sam_sercom_t *s) { return MODES[s->mode & 7]; }

static int sercom_view(sam_mcu_t *m, int pi)
{
    /* views in header order: I2CM, I2CS, SPI, USART; CTRLA.MODE 5 master, 4 slave, 2-3 SPI, 0-1 USART */
    uint32_t mode = (m->regs[pi][0] >> 2) & 7u;
    return mode == 5 ? 1 : mode == 4 ? 2 : (mode == 2 || mode == 3) ? 3 : 4;
}

void sam_sercom_irq(sam_mcu_t *m, int pi)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    const sam_sercom_mode_t *md = mode_of(s);
    uint8_t f = md && md->flags ? md->flags(s) : 0;
    /* INTENSET is at the same offset in every mode */
    sam_irq_level(m, sam_periphs[pi].irq, (f & m->regs[pi][SERCOM_I2CM_INTENSET_OFFSET]) != 0);
}

void sam_sercom_sync(sam_mcu_t *m, int pi, uint32_t bits)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint64_t hz = sam_gclk_hz(m, s->gclk_core), now = sam_now(m);
    if (now >= s->sync_until)
        s->sync_bits = 0;
    s->sync_bits |= bits;
    s->sync_until = hz ? now + (SAM_SYNC_GCLK_CYCLES * SAM_TU_HZ + hz - 1) / hz : SAM_NEVER;
    if (s->sync_until != SAM_NEVER)
        sam_slot_set(m, pi, s->sync_until);   /* SYNCBUSY changes then: an event */
}

static void sercom_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(sam_sercom_t));
    sam_sercom_t *s = m->pst[pi];
    for (size_t k = 0; k < NMODES; k++)
        if (ALL_MODES[k]->reset)
            ALL_MODES[k]->reset(m, pi);
    memset(s, 0, sizeof *s);
    int n = sam_periphs[pi].name[6] - '0';   /* SERCOMn */
    s->gclk_core = n >= 0 && n < 6 ? GCLK_CORE[n] : -1;
    s->gclk_slow = n >= 0 && n < 6 ? GCLK_SLOW[n] : -1;
    for (size_t k = 0; k < NMODES; k++)
        if (ALL_MODES[k]->init)
            ALL_MODES[k]->init(s);
}

static void sercom_fire(sam_mcu_t *m, int pi)
{
    (void)m;
    (void)pi;   /* a synchronisation ended */
}

static int sercom_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint32_t off = sam_regs[ri].offset;
    uint64_t now = sam_now(m);
    if (off == SERCOM_I2CM_SYNCBUSY_OFFSET) {   /* the same offset in every mode; bit 2: an I2C master's SYSOP */
        *v = (now < s->sync_until ? s->sync_bits & 7u : 0u) | (s->stop_pending || s->sysop_stuck ? 4u : 0u);
        return SAM_DONE;
    }
    const sam_sercom_mode_t *md = mode_of(s);
    return md && md->read ? md->read(m, pi, ri, v) : SAM_GENERIC;
}

static int sercom_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint32_t off = sam_regs[ri].offset;
    v &= mask;
    sam_activity(m);
    if (off == 0) {   /* CTRLA, every mode */
        if (v & 1u) {  /* SWRST */
            memset(m->regs[pi], 0, sam_periphs[pi].size);
            sercom_reset(m, pi);
            sam_sercom_sync(m, pi, 1u);
            sam_sercom_irq(m, pi);
            return SAM_DONE;
        }
        uint32_t old = sam_sercom_reg32(m, pi, 0);
        /* every field but SWRST and ENABLE: enable-protected (sam_protect.c) */
        v = sam_enable_protected(m, ri, v, mask, ~3u, (old & 2u) != 0);
        sam_generic_write(m, ri, v, mask);
        uint32_t nv = sam_sercom_reg32(m, pi, 0);
        s->mode = (int)((nv >> 2) & 7u);
        if ((nv & 2u) && !(old & 2u)) {
            sam_sercom_sync(m, pi, 2u);
            const sam_sercom_mode_t *md = mode_of(s);
            if (!md) {
                sam_fail(m, "%s enabled in mode %d: only I2C master and slave are modelled", sam_periphs[pi].name,
                         s->mode);
                return SAM_DONE;
            }
            if (md->enable && md->enable(m, pi, nv))
                return SAM_DONE;
            s->enabled = 1;
        } else if (!(nv & 2u) && (old & 2u)) {
            sam_sercom_sync(m, pi, 2u);
            /* every mode's state machines stop (a mode changed while enabled leaves the old mode's state) */
            for (size_t k = 0; k < NMODES; k++)
                if (ALL_MODES[k]->disable)
                    ALL_MODES[k]->disable(m, pi);
            s->enabled = 0;
        }
        return SAM_DONE;
    }
    const sam_sercom_mode_t *md = mode_of(s);
    return md && md->write ? md->write(m, pi, ri, v, mask) : SAM_GENERIC;
}

const sam_model_t sam_model_sercom = {"Sercom", sercom_reset, sercom_view, sercom_read, sercom_write, sercom_fire};
