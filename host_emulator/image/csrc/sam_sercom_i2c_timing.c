/* SERCOM I2C master: SCL timing from BAUD, BAUDLOW, SDAHOLD and the bus's rise time, against the I2C-bus limits. */
#include <stdio.h>
#include "sam_sercom.h"
#include "sam_vendor_gen.h"

/*
 * The master's SCL (DS40001882D 28.6.2.4.1 "Clock Generation", Figure 28-7 "SCL Timing"): it holds SCL low for
 * T_LOW = (BAUDLOW + 5) / f_GCLK (BAUD when BAUDLOW = 0), releases it, and once it sees the line high counts
 * T_HIGH = (BAUD + 5) / f_GCLK: f_SCL = 1 / (T_LOW + T_HIGH + T_RISE) = f_GCLK / (10 + BAUD + BAUDLOW + f_GCLK
 * T_RISE) (2 BAUD when BAUDLOW = 0). T_RISE is the bus's (cfg.i2c_rise_ns, WorldConfig.i2c_rise_ns). SDA changes
 * CTRLA.SDAHOLD after SCL falls (28.10.1: 0 off, 1 50-100 ns, 2 300-600 ns, 3 400-800 ns); the data setup time
 * before SCL rises is what the low phase leaves of it, with SDA's own rise: t_SU;DAT = T_LOW - hold(max) - T_RISE.
 * T_LOW and T_HIGH count neither the rise nor the fall (the specification measures at the 30 % and 70 % points:
 * its low time is a little longer, which this leaves as margin).
 *
 * Limits of the I2C-bus specification (NXP UM10204 rev. 7, Table 10), by mode: the mode is CTRLA.SPEED's (1:
 * Fast-mode Plus; enabling it is refused elsewhere, as Fm+ is not modelled) or, with SPEED = 0, Standard-mode up to
 * 100 kHz and Fast-mode above:
 *
 *                  T_LOW min  T_HIGH min  t_SU;DAT min
 *   Standard-mode  4.7 us     4.0 us      250 ns
 *   Fast-mode      1.3 us     0.6 us      100 ns
 *   Fast-mode Plus 0.5 us     0.26 us      50 ns
 *
 * What a violation does on the bus (sam_i2cm_addr, link_i2c_bus.c): SDA still changing once SCL is released
 * (hold(max) >= T_LOW) changes it while SCL is high, a START or STOP condition in the middle of a byte: every
 * secondary's state machine restarts (none sees its address) and the master, owner of the bus, detects the
 * misplaced condition: STATUS.BUSERR (with ARBLOST and MB, 28.10.8), bus state BUSY. Any other violation (a low or
 * high phase or a setup time under the limit) leaves the conditions in place but the secondaries are not
 * guaranteed to sample the bits: none recognises its address and the master reads a NACK. The first violation on
 * a bus is noted once with the figures.
 */

#define CTRLA_SDAHOLD_POS 20u   /* CTRLA.SDAHOLD[21:20] (28.10.1) */

static const double LIMITS[3][3] = {
    /* T_LOW, T_HIGH, t_SU;DAT (s) */
    {4.7e-6, 4.0e-6, 250e-9},
    {1.3e-6, 0.6e-6, 100e-9},
    {0.5e-6, 0.26e-6, 50e-9},
};
static const char *const MODE_NAMES[3] = {"Standard-mode", "Fast-mode", "Fast-mode Plus"};
static const double HOLD_NS[4][2] = {{0, 0}, {50, 100}, {300, 600}, {400, 800}};

int sam_i2cm_timing(sam_mcu_t *m, int pi, sam_i2c_timing_t *t)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint64_t hz = s ? sam_gclk_hz(m, s->gclk_core) : 0;
    if (!hz)
        return -1;
    uint32_t ctrla = sam_sercom_reg32(m, pi, SERCOM_I2CM_CTRLA_OFFSET);
    uint32_t baud = sam_sercom_reg32(m, pi, SERCOM_I2CM_BAUD_OFFSET);
    t->baud = baud & 0xFFu;
    t->baudlow = (baud >> 8) & 0xFFu;
    t->sdahold = (ctrla >> CTRLA_SDAHOLD_POS) & 3u;
    t->f_gclk_hz = (double)hz;
    t->t_low_s = (double)((t->baudlow ? t->baudlow : t->baud) + 5u) / t->f_gclk_hz;
    t->t_high_s = (double)(t->baud + 5u) / t->f_gclk_hz;
    t->t_rise_s = m->w->cfg.i2c_rise_ns * 1e-9;
    t->f_scl_hz = 1.0 / (t->t_low_s + t->t_high_s + t->t_rise_s);
    t->t_hold_min_s = HOLD_NS[t->sdahold][0] * 1e-9;
    t->t_hold_max_s = HOLD_NS[t->sdahold][1] * 1e-9;
    t->t_setup_s = t->t_low_s - t->t_hold_max_s - t->t_rise_s;
    uint32_t speed = (ctrla & SERCOM_I2CM_CTRLA_SPEED_Msk) >> SERCOM_I2CM_CTRLA_SPEED_Pos;
    t->mode = speed == 1 ? SAM_I2C_FAST_PLUS : t->f_scl_hz <= 100e3 ? SAM_I2C_STANDARD : SAM_I2C_FAST;
    t->min_low_s = LIMITS[t->mode][0];
    t->min_high_s = LIMITS[t->mode][1];
    t->min_setup_s = LIMITS[t->mode][2];
    /* a tolerance of 0.1 ns: values equal to a limit as the datasheet's counts give them pass */
    t->violations = (t->t_low_s < t->min_low_s - 1e-10 ? SAM_I2C_VIOL_LOW : 0) |
                    (t->t_high_s < t->min_high_s - 1e-10 ? SAM_I2C_VIOL_HIGH : 0) |
                    (t->t_setup_s < t->min_setup_s - 1e-10 ? SAM_I2C_VIOL_SETUP : 0) |
                    (t->t_hold_max_s >= t->t_low_s ? SAM_I2C_VIOL_SDA_IN_HIGH : 0);
    return 0;
}

/* The violations of the timing a START now would use (0: none or no clock); the first on the bus is noted. */
int sam_i2cm_timing_check(sam_mcu_t *m, int pi)
{
    sam_i2c_timing_t t;
    if (sam_i2cm_timing(m, pi, &t) || !t.violations)
        return 0;
    if (!m->w->bus.timing_noted) {
        m->w->bus.timing_noted = 1;
        char what[256];
        int n = 0;
        if (t.violations & SAM_I2C_VIOL_LOW)
            n += snprintf(what + n, sizeof what - (size_t)n, ", T_LOW %.3f us < %.2f us", t.t_low_s * 1e6,
                          t.min_low_s * 1e6);
        if (t.violations & SAM_I2C_VIOL_HIGH)
            n += snprintf(what + n, sizeof what - (size_t)n, ", T_HIGH %.3f us < %.2f us", t.t_high_s * 1e6,
                          t.min_high_s * 1e6);
        if (t.violations & SAM_I2C_VIOL_SETUP)
            n += snprintf(what + n, sizeof what - (size_t)n, ", data setup %.3f us < %.3f us", t.t_setup_s * 1e6,
                          t.min_setup_s * 1e6);
        sam_note(m, "%s: I2C SCL timing outside %s's limits (I2C-bus specification UM10204, Table 10): %s (BAUD %u, "
                 "BAUDLOW %u at %.3f MHz: T_LOW %.3f us, T_HIGH %.3f us, rise %.0f ns, f_SCL %.1f kHz; SDA hold "
                 "%.0f-%.0f ns): %s", m->name, MODE_NAMES[t.mode], what + 2, t.baud, t.baudlow, t.f_gclk_hz * 1e-6,
                 t.t_low_s * 1e6, t.t_high_s * 1e6, t.t_rise_s * 1e9, t.f_scl_hz * 1e-3, t.t_hold_min_s * 1e9,
                 t.t_hold_max_s * 1e9,
                 t.violations & SAM_I2C_VIOL_SDA_IN_HIGH
                     ? "SDA changes while SCL is high: the secondaries see false START/STOP conditions, the master "
                       "a bus error"
                     : "the secondaries cannot sample the bits: no address is recognised (NACK)");
    }
    return t.violations;
}

int sam_world_i2c_timing(sam_world_t *w, int mcu, sam_i2c_timing_t *out)
{
    sam_mcu_t *m = w && mcu >= 0 && mcu < SAM_MAX_MCU ? w->mcu[mcu] : NULL;
    if (!m || w->bus.pi < 0 || !m->pst[w->bus.pi])
        return -1;
    return sam_i2cm_timing(m, w->bus.pi, out);
}
