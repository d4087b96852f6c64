/* SERCOM I2C slave: address match, clock stretching, received and sent bytes, ACK/NACK, STOP and repeated START. */
#include <string.h>
#include "sam_sercom.h"
#include "sam_vendor_gen.h"

static int holds_scl(const sam_sercom_t *s)
{
    return s->addressed && (s->s_state == S_AMATCH || s->s_state == S_RX_HOLD || s->s_state == S_TX_NEED);
}

static void stretch_begin(sam_mcu_t *m, sam_sercom_t *s, uint64_t t, int claim)
{
    s->stretch_start = t;
    s->s_status |= 0x80u;   /* CLKHOLD */
    sam_bus_push(m, s->master, t + s->tbit, claim ? BUS_EV_M_CLAIM : BUS_EV_M_HOLD, 0, 0, s->tbit);
}

static void stretch_end(sam_mcu_t *m, sam_sercom_t *s, uint64_t t)
{
    s->s_status &= (uint16_t)~0x80u;
    if (t > s->stretch_start)
        sam_bus_counts(m)->stretch_tu += t - s->stretch_start;
}

/* The slave lets go of the bus now (power lost, its SERCOM reset or disabled): SCL, if it held it, is released
 * with SDA high, which the master reads as a NACK or as 1 bits. */
void sam_i2cs_vanish(sam_mcu_t *m, sam_sercom_t *s, uint64_t t)
{
    if (holds_scl(s)) {
        stretch_end(m, s, t);
        if (s->s_state == S_TX_NEED) {
            sam_bus_push(m, s->master, t + s->tbit, BUS_EV_M_RELEASE, 0, 0, s->tbit);
            sam_bus_push(m, s->master, t + 8 * s->tbit, BUS_EV_M_SB, 0xFF, 0, s->tbit);
        } else {
            sam_bus_push(m, s->master, t + s->tbit, BUS_EV_M_MB, 1, 0, s->tbit);
        }
    }
    s->addressed = 0;
    s->s_state = S_IDLE;
}

/* A step for this board as a slave; returns 0 when it changed nothing (an address that is not its own). */
int sam_i2cs_step(sam_mcu_t *m, sam_sercom_t *s, const sam_busev_t *e)
{
    if (e->src == m->id && (!s || s->master < 0))
        return 0;
    /* the master this step is about (a slave's own DRDY after its ACK of a read is about its master) */
    int from = e->src == m->id && s ? s->master : e->src;
    int present = s && !m->halted && s->enabled && s->mode == 4 && s->addressed && s->master == from;
    switch (e->kind) {
    case BUS_EV_S_ADDRESS: {
        if (s && s->mode == 5 && s->busstate == BUSSTATE_OWNER) {
            sam_fail(m, "a second I2C master on the bus (%s): arbitration is not modelled", m->w->mcu[e->src]->name);
            return 1;
        }
        int match = s && sam_i2c_address_matches(m, sam_bus_sercom(m), s, (uint8_t)(e->arg >> 1));
        if (!match) {
            if (!s || !s->addressed)
                return 0;
            /* a START for another slave ends this one's transaction */
            if (s->s_state != S_IDLE)
                s->s_flags |= S_PREC;
            s->s_state = S_IDLE;
            s->addressed = 0;
            s->s_status &= (uint16_t)~0x80u;
            return 1;
        }
        s->addressed = 1;
        s->master = e->src;
        s->tbit = e->tbit;
        s->s_status = (uint16_t)((s->s_status & ~(0x18u)) | (e->arg & 1u ? 0x08u : 0) | (e->arg2 ? 0x10u : 0));
        if (sam_sercom_reg32(m, sam_bus_sercom(m), SERCOM_I2CS_CTRLB_OFFSET) & SERCOM_I2CS_CTRLB_AACKEN) {
            /* CTRLB.AACKEN, "Automatic Address Acknowledge" (the CMSIS header's name; DS40001882 28.10.2): the slave
             * acknowledges the matching address itself. What we could find of the datasheet does not say what
             * becomes of AMATCH then; the model neither sets AMATCH nor holds SCL for the address (as the vendor's
             * ASF4 slave driver, hpl_sercom.c, expects: with AACKEN it enables only DRDY and ERROR), and goes on as
             * after an acknowledge action of ACK on AMATCH: a master write waits for its first byte (DRDY when it
             * has come), a master read asks for data at once (DRDY). ACKACT plays no part in the address. */
            uint64_t T = e->tbit;
            sam_bus_push(m, s->master, e->t + T, BUS_EV_M_CLAIM, 1, 0, T);   /* 1: acknowledged, SCL not held */
            if (e->arg & 1u) {
                sam_bus_push(m, m->id, e->t + T, BUS_EV_S_DRDY_TX, 0, 0, T);
                s->s_state = S_TX;
            } else {
                sam_bus_push(m, s->master, e->t + T, BUS_EV_M_MB, 0, 0, T);
                s->s_state = S_RX;
            }
            return 1;
        }
        s->s_flags |= S_AMATCHF;
        s->s_state = S_AMATCH;
        stretch_begin(m, s, e->t, 1);
        return 1;
    }
    case BUS_EV_S_DRDY_RX:
        if (!present || s->s_state != S_RX) {   /* nobody takes the byte: not acknowledged */
            sam_bus_push(m, from, e->t + e->tbit, BUS_EV_M_MB, 1, 0, e->tbit);
            return 1;
        }
        s->s_rx = e->arg;
        s->s_flags |= S_DRDY;
        s->s_state = S_RX_HOLD;
        stretch_begin(m, s, e->t, 0);
        return 1;
    case BUS_EV_S_DRDY_TX:
        if (e->arg) {   /* the master refused the last byte: STOP follows */
            if (present) {
                s->s_flags |= S_DRDY;
                s->s_status |= 0x04u;
                s->s_state = S_TX_DONE;
            }
            return 1;
        }
        if (!present || (s->s_state != S_TX && s->s_state != S_TX_NEED)) {   /* nobody drives SDA: 1 bits */
            sam_bus_push(m, from, e->t + 8 * (uint64_t)e->tbit, BUS_EV_M_SB, 0xFF, 0, e->tbit);
            return 1;
        }
        s->s_flags |= S_DRDY;
        s->s_status &= (uint16_t)~0x04u;
        s->s_state = S_TX_NEED;
        stretch_begin(m, s, e->t, 0);
        return 1;
    case BUS_EV_S_PREC:
    case BUS_EV_S_RESET:
        if (!s || m->halted || (!s->addressed && e->kind == BUS_EV_S_PREC))
            return 0;
        if (s->s_state != S_IDLE || e->kind == BUS_EV_S_PREC)
            s->s_flags |= S_PREC;
        if (holds_scl(s))
            stretch_end(m, s, e->t);
        s->s_state = S_IDLE;
        s->addressed = 0;
        s->s_status &= (uint16_t)~0x80u;
        return 1;
    default: return 1;
    }
}

/* ---------------------------------------------------------------- the slave's actions */

void sam_i2cs_cmd(sam_mcu_t *m, int pi, uint32_t cmd, int nack)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint64_t t = sam_now(m), T = s->tbit;
    int state = s->s_state;
    s->s_flags &= (uint8_t)~(S_PREC | S_AMATCHF | S_DRDY);   /* a command clears every flag */
    if (cmd == 0 || !s->addressed)
        return;
    if (state == S_AMATCH) {
        stretch_end(m, s, t);
        if (cmd != 3) {
            sam_fail(m, "I2C slave CMD %u after an address match: only 3 (acknowledge action) is modelled", cmd);
            return;
        }
        if (nack) {
            sam_bus_push(m, s->master, t + T, BUS_EV_M_MB, 1, 0, T);
            sam_bus_counts(m)->nacks++;
            s->s_state = S_IDLE;
            s->addressed = 0;
        } else if (s->s_status & 0x08u) {   /* a master read: after the ACK, the slave's data interrupt */
            sam_bus_push(m, s->master, t + T, BUS_EV_M_RELEASE, 0, 0, T);
            sam_bus_push(m, m->id, t + T, BUS_EV_S_DRDY_TX, 0, 0, T);
            s->s_state = S_TX;   /* until that DRDY it does not hold SCL */
        } else {
            sam_bus_push(m, s->master, t + T, BUS_EV_M_MB, 0, 0, T);
            s->s_state = S_RX;
        }
        return;
    }
    if (state == S_RX_HOLD) {
        stretch_end(m, s, t);
        sam_bus_push(m, s->master, t + T, BUS_EV_M_MB, nack ? 1 : 0, 0, T);
        s->s_state = cmd == 3 && !nack ? S_RX : S_WAIT;   /* S_WAIT: it listens no more, bytes go unacknowledged */
        return;
    }
    if (state == S_TX_NEED) {
        stretch_end(m, s, t);
        sam_bus_push(m, s->master, t + T, BUS_EV_M_RELEASE, 0, 0, T);
        if (cmd == 3) {   /* send what DATA holds */
            sam_bus_push(m, s->master, t + 8 * T, BUS_EV_M_SB, s->s_tx, 0, T);
            s->s_state = S_TX;
        } else {
            sam_bus_push(m, s->master, t + 8 * T, BUS_EV_M_SB, 0xFF, 0, T);   /* released: the master reads 1s */
            s->s_state = S_WAIT;
        }
        sam_bus_counts(m)->busy_tu += 8 * T;
        return;
    }
    /* after a STOP, or with no flag: the command only clears flags */
}

void sam_i2cs_data(sam_mcu_t *m, int pi, uint8_t b)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint64_t t = sam_now(m), T = s->tbit;
    s->s_tx = b;
    if (s->s_state != S_TX_NEED || !s->addressed)
        return;   /* not asked for data (after a NACK: the master ends with STOP) */
    s->s_flags &= (uint8_t)~S_DRDY;
    stretch_end(m, s, t);
    sam_bus_push(m, s->master, t + T, BUS_EV_M_RELEASE, 0, 0, T);
    sam_bus_push(m, s->master, t + 8 * T, BUS_EV_M_SB, b, 0, T);
    sam_bus_counts(m)->busy_tu += 8 * T;
    s->s_state = S_TX;
}
