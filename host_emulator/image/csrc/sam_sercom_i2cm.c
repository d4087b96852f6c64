/* SERCOM I2C master: START and address, data, commands (ACK, repeated START, STOP), its view of the lines, time-outs. */
#include <string.h>
#include "sam_sercom.h"
#include "sam_vendor_gen.h"

static uint64_t tu_of(double s) { return (uint64_t)(s * (double)SAM_TU_HZ); }

/* ---------------------------------------------------------------- the master's view of the lines */

static void timeouts_arm(sam_mcu_t *m, int pi, uint64_t hold_start)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    if (!s || s->mode != 5 || s->busstate != BUSSTATE_OWNER)
        return;
    uint32_t ctrla = sam_sercom_reg32(m, pi, SERCOM_I2CM_CTRLA_OFFSET);
    uint32_t it = (ctrla >> SERCOM_I2CM_CTRLA_INACTOUT_Pos) & 3u;
    static const int periods[4] = {0, 5, 10, 20};
    s->t_inactive = it ? hold_start + (uint64_t)periods[it] * s->tbit : SAM_NEVER;
    s->t_lowtout = (ctrla & SERCOM_I2CM_CTRLA_LOWTOUTEN) && sam_gclk_hz(m, s->gclk_slow)
                       ? hold_start + tu_of(LOWTOUT_S)
                       : SAM_NEVER;
    uint64_t t = s->t_inactive < s->t_lowtout ? s->t_inactive : s->t_lowtout;
    if (t != SAM_NEVER)
        sam_bus_push(m, m->id, t < sam_now(m) ? sam_now(m) : t, BUS_EV_M_TIMEOUT, 0, 0, s->tbit);
}

static void view_hold(sam_mcu_t *m, int pi, uint64_t since)
{
    sam_lineview_t *v = sam_bus_view(m);
    if (!v->held) {
        v->held = 1;
        v->hold_start = since;
        timeouts_arm(m, pi, since);
    }
}

static void view_release(sam_mcu_t *m, int pi)
{
    sam_lineview_t *v = sam_bus_view(m);
    sam_sercom_t *s = sam_sercom_st(m, pi);
    if (!v->held)
        return;
    v->held = 0;
    if (s) {
        s->t_inactive = s->t_lowtout = SAM_NEVER;
        if (s->pending_start && s->enabled && s->mode == 5) {   /* the START that waited for SCL goes out now */
            s->pending_start = 0;
            s->sysop_stuck = 0;
            sam_i2cm_addr(m, pi, s->pending_addr);
        }
    }
}

/* A step that would change nothing the master's software can see or that starts anything (a slave holding SCL
 * with no time-out to arm, or letting go of it with no START waiting): a board can take it without running
 * (link_i2c_bus.c: bus_quiet), and the fast-forward's proofs need not stop at it. What it does change, the
 * master's view of SCL, no register shows (the view only delays a START, and a parked pass writes none). */
int sam_i2cm_step_quiet(sam_mcu_t *m, int pi, const sam_sercom_t *s, int kind, int held)
{
    if (kind == BUS_EV_M_HOLD) {
        if (held || !s || s->mode != 5 || s->busstate != BUSSTATE_OWNER)
            return 1;   /* nothing to arm (timeouts_arm) */
        uint32_t ctrla = sam_sercom_reg32(m, pi, SERCOM_I2CM_CTRLA_OFFSET);
        return !((ctrla >> SERCOM_I2CM_CTRLA_INACTOUT_Pos) & 3u) &&
               !((ctrla & SERCOM_I2CM_CTRLA_LOWTOUTEN) && sam_gclk_hz(m, s->gclk_slow));
    }
    if (kind == BUS_EV_M_RELEASE)
        return !held || !s || !(s->pending_start && s->enabled && s->mode == 5);   /* (view_release) */
    return 0;
}

/* ---------------------------------------------------------------- steps from the bus */

void sam_i2cm_end(sam_sercom_t *s)
{
    s->slave = -1;
    s->awaiting = 0;
}

void sam_i2cm_bus_idle(sam_mcu_t *m, int pi, sam_sercom_t *s)
{
    s->busstate = BUSSTATE_IDLE;
    if (s->pending_start && s->enabled && s->mode == 5 && !sam_bus_view(m)->held) {
        s->pending_start = 0;   /* the START written while the bus was not idle goes out now */
        s->sysop_stuck = 0;
        sam_i2cm_addr(m, pi, s->pending_addr);
    }
}

/* The master, owner of the bus, detects a misplaced START or STOP (28.10.8 STATUS.BUSERR): BUSERR with ARBLOST and
 * MB, as arbitration lost; the bus state BUSY until a STOP is seen (Figure 28-4). */
static void bus_error(sam_mcu_t *m, sam_sercom_t *s)
{
    s->m_status |= ST_BUSERR | ST_ARBLOST;
    s->m_flags |= M_MB | F_ERROR;
    s->busstate = BUSSTATE_BUSY;
    sam_bus_counts(m)->buserr++;
    sam_i2cm_end(s);
}

/* A step to the master (from a slave, or one of its own); s: the state of the bus SERCOM pi (or NULL). */
void sam_i2cm_step(sam_mcu_t *m, int pi, sam_sercom_t *s, const sam_busev_t *e)
{
    int own = s && s->enabled && s->mode == 5 && s->busstate == BUSSTATE_OWNER;
    uint64_t now = e->t;
    switch (e->kind) {
    case BUS_EV_M_CLAIM:   /* a slave acknowledged the address; arg 0: it holds SCL (AMATCH), 1: it does not (AACKEN) */
        if (!e->arg)
            view_hold(m, pi, now - e->tbit);
        if (!own || !s->awaiting)
            break;   /* a START that was given up meanwhile */
        if (s->claims++) {
            sam_fail(m, "I2C address 0x%02x answered by %s and %s", (sam_sercom_reg32(m, pi, SERCOM_I2CM_ADDR_OFFSET) >> 1) & 0x7Fu,
                     m->w->mcu[s->slave]->name, m->w->mcu[e->src]->name);
            break;
        }
        s->slave = e->src;
        break;
    case BUS_EV_M_HOLD:
        view_hold(m, pi, now - e->tbit);
        break;
    case BUS_EV_M_RELEASE:
        view_release(m, pi);
        break;
    case BUS_EV_M_NACKCHECK:
        if (!own || !s->awaiting)
            break;
        s->awaiting = 0;
        if (s->claims)
            break;
        sam_bus_counts(m)->nacks++;   /* no slave answered its address */
        s->m_flags |= M_MB;
        s->m_status = (uint16_t)(s->m_status | 0x04u | 0x80u);
        break;
    case BUS_EV_M_MB:
    case BUS_EV_M_SB:
        if (own) {   /* else the transaction was abandoned meanwhile */
            if (e->kind == BUS_EV_M_MB) {
                s->m_flags |= M_MB;
                s->m_status = (uint16_t)((s->m_status & ~0x04u) | (e->arg ? 0x04u : 0));
            } else {
                s->m_data = e->arg;
                s->m_flags |= M_SB;
                s->m_status &= (uint16_t)~0x04u;
            }
            s->m_status |= 0x80u;   /* CLKHOLD */
        }
        if (e->src != m->id)
            view_release(m, pi);   /* a slave's ACK bit or its data: it let go of SCL */
        break;
    case BUS_EV_M_IDLE:
        if (!s || !s->stop_pending)
            break;
        s->busstate = BUSSTATE_IDLE;
        s->m_status &= (uint16_t)~0x80u;
        s->stop_pending = 0;
        sam_i2cm_end(s);
        break;
    case BUS_EV_M_ARBLOST:
        if (!own)
            break;
        s->m_status |= ST_ARBLOST;
        s->m_flags |= M_MB | F_ERROR;
        s->busstate = BUSSTATE_BUSY;   /* Figure 28-4: arbitration lost, BUSY until a STOP is seen */
        sam_bus_counts(m)->arblost++;
        sam_i2cm_end(s);
        break;
    case BUS_EV_M_BUSERR:
        if (own)
            bus_error(m, s);
        break;
    case BUS_EV_M_SDA:
        /* SDA pulled low or let go by a fault, as the master's bus monitor sees it: only with SCL high (no slave
         * holds it) and the pins on the SERCOM */
        if (!s || !s->enabled || s->mode != 5 || sam_bus_view(m)->held || !sam_bus_pins_connected(m))
            break;
        if (e->arg) {   /* SDA falls while SCL is high: a START by someone else */
            if (s->busstate == BUSSTATE_IDLE)
                s->busstate = BUSSTATE_BUSY;
            else if (own)   /* SDA no longer follows the master: it loses arbitration at its next high bit */
                sam_bus_push(m, m->id, now + s->tbit, BUS_EV_M_ARBLOST, 0, 0, s->tbit);
        } else {        /* SDA rises while SCL is high: a STOP */
            if (own)
                bus_error(m, s);   /* in the middle of its transaction */
            if (s->busstate != BUSSTATE_IDLE)
                sam_i2cm_bus_idle(m, pi, s);
        }
        break;
    case BUS_EV_M_TIMEOUT:
        if (!own || !sam_bus_view(m)->held)
            break;
        if (now >= s->t_lowtout) {
            s->m_status |= 0x40u;   /* LOWTOUT */
            s->m_flags |= M_MB | F_ERROR;
            s->busstate = BUSSTATE_IDLE;
            sam_note(m, "%s: I2C SCL low time-out", m->name);
            sam_i2cm_end(s);
        } else if (now >= s->t_inactive) {
            s->busstate = BUSSTATE_IDLE;   /* the bus looks inactive: the master gives it up */
            sam_bus_counts(m)->timeouts_seen++;
            sam_note(m, "%s: I2C inactive-bus time-out after %.1f us of SCL held low", m->name,
                           (double)(now - sam_bus_view(m)->hold_start) * 1e6 / (double)SAM_TU_HZ);
            sam_i2cm_end(s);
        }
        if (s->busstate == BUSSTATE_IDLE)
            s->t_inactive = s->t_lowtout = SAM_NEVER;
        break;
    default: break;
    }
}

/* ---------------------------------------------------------------- the master's actions */

static uint64_t scl_period(sam_mcu_t *m, int pi)
{
    sam_world_t *w = m->w;
    uint64_t hz = sam_gclk_hz(m, sam_sercom_st(m, pi)->gclk_core);
    if (!hz) {
        sam_fail(m, "I2C START with GCLK_%s_CORE off: the master has no clock", sam_periphs[pi].name);
        return 0;
    }
    uint32_t baud = sam_sercom_reg32(m, pi, SERCOM_I2CM_BAUD_OFFSET);
    uint32_t b = baud & 0xFFu, bl = (baud >> 8) & 0xFFu;
    uint64_t counts = 10u + b + (bl ? bl : b);
    uint64_t t = counts * SAM_TU_HZ / hz + (uint64_t)(w->cfg.i2c_rise_ns * 1e-9 * (double)SAM_TU_HZ);
    if (t < sam_bus_tmin()) {
        sam_fail(m, "I2C SCL period %.3f us (BAUD 0x%04x at %.3f MHz) is faster than Fast mode (%.2f us), the fastest "
                 "with CTRLA.SPEED = 0: not modelled", (double)t * 1e6 / (double)SAM_TU_HZ, baud, (double)hz * 1e-6,
                 SAM_BUS_TMIN_S * 1e6);
        return 0;
    }
    return t;
}

void sam_i2cm_addr(sam_mcu_t *m, int pi, uint32_t v)
{
    sam_world_t *w = m->w;
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint64_t t = sam_now(m);
    s->m_flags &= (uint8_t)~(M_MB | M_SB | F_ERROR);
    s->m_status &= (uint16_t)~(ST_BUSERR | ST_ARBLOST | 0x04u | 0x40u | 0x80u);   /* ADDR clears them (28.10.8) */
    s->sysop_stuck = 0;
    if (v & SERCOM_I2CM_ADDR_TENBITEN) {
        sam_fail(m, "I2C 10-bit addressing is not modelled");
        return;
    }
    if (s->busstate == BUSSTATE_UNKNOWN || s->busstate == BUSSTATE_BUSY) {
        sam_note(m, "%s: I2C START with the bus state %s: it waits", m->name,
                       s->busstate == BUSSTATE_UNKNOWN ? "UNKNOWN" : "BUSY");
        s->pending_start = 1;   /* until the bus state becomes IDLE (sam_i2cm_bus_idle) */
        s->pending_addr = v;
        return;
    }
    if (sam_bus_view(m)->held) {   /* SCL held low by a slave: no START can be made until it lets go */
        s->pending_start = 1;
        s->pending_addr = v;
        s->sysop_stuck = 1;
        return;
    }
    uint64_t T = scl_period(m, pi);
    if (!T)
        return;
    int viol = sam_i2cm_timing_check(m, pi);
    int repeated = s->busstate == BUSSTATE_OWNER;
    s->tbit = T;
    s->busstate = BUSSTATE_OWNER;
    s->m_dir = (int)(v & 1u);
    s->slave = -1;
    sam_bus_counts(m)->transactions++;
    sam_bus_counts(m)->busy_tu += 10 * T;
    if (w->bus.sda_stuck || !sam_bus_pins_connected(m)) {
        /* SDA does not follow the master: arbitration lost on the first bit it drives high */
        s->awaiting = 0;
        sam_bus_push(m, m->id, t + T, BUS_EV_M_ARBLOST, 0, 0, T);
        return;
    }
    if (viol & SAM_I2C_VIOL_SDA_IN_HIGH) {
        /* SDA changes while SCL is high (sam_sercom_i2c_timing.c): at the first address bit that changes it (SDA is
         * low after the START) a false START or STOP; every secondary restarts, the master sees a bus error */
        uint64_t k = 1;
        while (k < 9 && !((v >> (8 - k)) & 1u))
            k++;
        s->awaiting = 0;
        for (int i = 0; i < w->nmcu; i++)
            if (w->mcu[i] && i != m->id)
                sam_bus_push(m, i, t + k * T, BUS_EV_S_RESET, 0, 0, T);
        sam_bus_push(m, m->id, t + k * T, BUS_EV_M_BUSERR, 0, 0, T);
        return;
    }
    s->awaiting = 1;
    s->claims = 0;
    if (viol) {   /* the secondaries cannot sample the bits: none sees its address (a START for another, to each),
                   * the NACK check finds no claim */
        for (int i = 0; i < w->nmcu; i++)
            if (w->mcu[i] && i != m->id)
                sam_bus_push(m, i, t + 9 * T, BUS_EV_S_RESET, 0, 0, T);
        sam_bus_push(m, m->id, t + 10 * T, BUS_EV_M_NACKCHECK, 0, 0, T);
        return;
    }
    for (int i = 0; i < w->nmcu; i++)
        if (w->mcu[i] && i != m->id)
            sam_bus_push(m, i, t + 9 * T, BUS_EV_S_ADDRESS, (int)(v & 0xFFu), repeated, T);
    sam_bus_push(m, m->id, t + 10 * T, BUS_EV_M_NACKCHECK, 0, 0, T);
}

void sam_i2cm_data(sam_mcu_t *m, int pi, uint8_t b)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint64_t t = sam_now(m), T = s->tbit;
    if (s->busstate != BUSSTATE_OWNER || !(s->m_flags & M_MB) || s->m_dir) {
        sam_note(m, "%s: I2C DATA written outside a write transaction's MB: ignored", m->name);
        return;
    }
    s->m_flags &= (uint8_t)~(M_MB | M_SB);
    s->m_status &= (uint16_t)~0x80u;
    sam_bus_counts(m)->busy_tu += 9 * T;
    if (m->w->bus.sda_stuck) {   /* SDA does not follow the master: arbitration lost on its first high bit */
        sam_bus_push(m, m->id, t + T, BUS_EV_M_ARBLOST, 0, 0, T);
        return;
    }
    if (s->slave >= 0)
        sam_bus_push(m, s->slave, t + 8 * T, BUS_EV_S_DRDY_RX, b, 0, T);
    else
        sam_bus_push(m, m->id, t + 9 * T, BUS_EV_M_MB, 1, 0, T);   /* no slave: not acknowledged */
}

void sam_i2cm_cmd(sam_mcu_t *m, int pi, uint32_t cmd, int nack)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint64_t t = sam_now(m), T = s->tbit;
    if (!(s->m_flags & (M_MB | M_SB)) || s->busstate != BUSSTATE_OWNER) {
        s->sysop_stuck = 1;   /* the command waits for a bus it does not hold */
        return;
    }
    int read = (s->m_flags & M_SB) != 0;
    s->m_flags &= (uint8_t)~(M_MB | M_SB);
    s->m_status &= (uint16_t)~0x80u;
    int sl = s->slave;
    if (cmd == 1) {   /* repeated START with the current address */
        sam_i2cm_addr(m, pi, sam_sercom_reg32(m, pi, SERCOM_I2CM_ADDR_OFFSET));
        return;
    }
    if (cmd == 2) {
        if (!read) {
            s->m_flags |= M_MB;   /* no operation in a write */
            return;
        }
        if (nack) {
            sam_fail(m, "I2C CMD 2 with a NACK (read on after refusing the byte) is not modelled");
            return;
        }
        if (sl >= 0)
            sam_bus_push(m, sl, t + T, BUS_EV_S_DRDY_TX, 0, 0, T);
        else
            sam_bus_push(m, m->id, t + 9 * T, BUS_EV_M_SB, 0xFF, 0, T);   /* nobody drives SDA: 0xFF */
        sam_bus_counts(m)->busy_tu += T;
        return;
    }
    /* cmd 3: (ACK/NACK of a read) then STOP */
    uint64_t tstop = t + (read ? 2 : 1) * T;
    if (read && sl >= 0)
        sam_bus_push(m, sl, t + T, BUS_EV_S_DRDY_TX, nack ? 1 : 0, 0, T);
    if (sl >= 0)
        sam_bus_push(m, sl, tstop, BUS_EV_S_PREC, 0, 0, T);
    sam_bus_push(m, m->id, tstop, BUS_EV_M_IDLE, 0, 0, T);
    s->stop_pending = 1;   /* SYSOP until the STOP is on the bus */
    sam_bus_counts(m)->stops++;
    sam_bus_counts(m)->busy_tu += tstop - t;
}
