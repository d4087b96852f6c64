/* SERCOM in I2C master and slave modes (smart mode off, SCLSM = 0) and the bus steps that join the boards. */
#include <stdlib.h>
#include <string.h>
#include "sam_world.h"
#include "sam_vendor_gen.h"

/*
 * The bus is modelled per byte with clock stretching. T is the master's SCL period from its BAUD register,
 * f_GCLK / (10 + BAUD + BAUDLOW) plus the bus's rise time (the datasheet's f_SCL formula); at least
 * SAM_BUS_TMIN (Fast mode, the fastest with CTRLA.SPEED = 0). Boards affect each other only through bus steps:
 * messages into the receiver's queue, each timestamped at least T after its cause, and no board reads another
 * board's state. That is what lets the world run boards apart in time (sam_world.c) with results that do not
 * depend on how it schedules them. The steps, with the time they take effect (t: the cause):
 *
 *   master ADDR      ADDRESS to every other board at t + 9T (START and 8 address bits); each slave compares it
 *                    with its own ADDR: the one that matches sets AMATCH, holds SCL and CLAIMs it (the master
 *                    learns at t + 10T); the master's NACK check at t + 10T gives MB with RXNACK when none did
 *   slave CMD        (after AMATCH, or DRDY of a received byte) the ACK/NACK bit: the master's MB at t + T
 *                    (which also tells it SCL is free again); after AMATCH of a read: RELEASE to the master and
 *                    the slave's own DRDY (data wanted) at t + T
 *   master DATA      8 bits: the slave's DRDY (byte received, SCL held before the ACK) at t + 8T
 *   slave DATA       RELEASE at t + T, 8 bits: the master's SB at t + 8T (it holds SCL before its ACK)
 *   master CMD 2     the ACK bit: the slave's DRDY (next byte wanted) at t + T
 *   master CMD 3     the ACK/NACK bit of a read (the slave's DRDY with RXNACK at t + T) and STOP: the slave's PREC
 *                    and the master's bus state IDLE one bit later
 *   slave holds SCL  HOLD to the master at t + T (t: when the slave began to stretch, carried along)
 *
 * The master's view of the lines (a slave holds SCL: from HOLD/CLAIM until RELEASE/MB) decides what it can do:
 * while SCL is held no START, STOP or clock reaches the bus (an ADDR written then waits for the release, SYSOP
 * busy), as on the wire. A board that cannot answer (powered off, its SERCOM reset or not addressed) answers as
 * an absent slave does: a byte sent to it is not acknowledged (MB with RXNACK at t + T after its 8 bits), a byte
 * asked of it reads 0xFF; one that loses power or resets while it holds SCL releases it (the master sees a NACK,
 * or 0xFF bits).
 *
 * The master's inactive-bus time-out (CTRLA.INACTOUT: 5, 10, 20 SCL periods) counts from the start of a stretch
 * while SCL stays held in its view, and then gives the bus up (bus state IDLE); its SCL-low time-out (LOWTOUTEN,
 * 25 ms) counts only with GCLK_SERCOMx_SLOW running. When the master drives SDA and SCL as GPIO (bus recovery),
 * the lines are the wired AND of its pins, a held SCL and a stuck-SDA fault; a STOP on them (SDA rising while
 * SCL is high) ends every slave's transaction at t + T.
 */

#define SAM_BUS_TMIN_S 2400e-9   /* 400 kHz with 4 % tolerance: Fast mode, the fastest SCL with CTRLA.SPEED = 0 */

enum { S_IDLE = 0, S_AMATCH, S_RX, S_RX_HOLD, S_TX_NEED, S_TX, S_TX_DONE, S_WAIT };
#define M_MB 0x01u
#define M_SB 0x02u
#define F_ERROR 0x80u
#define S_PREC 0x01u
#define S_AMATCHF 0x02u
#define S_DRDY 0x04u
#define BUSSTATE_UNKNOWN 0u
#define BUSSTATE_IDLE 1u
#define BUSSTATE_OWNER 2u
#define BUSSTATE_BUSY 3u
#define LOWTOUT_S 25e-3

typedef struct {
    uint64_t sync_until;
    uint32_t sync_bits;
    int enabled, mode;
    uint64_t tbit;              /* SCL period of the transaction (tu): the master's, or the one its steps carry */
    /* master */
    uint8_t m_flags;
    uint16_t m_status;          /* BUSERR, ARBLOST, RXNACK, LOWTOUT, CLKHOLD (BUSSTATE kept apart) */
    uint32_t busstate;
    uint8_t m_data;
    int m_dir, sysop_stuck, stop_pending;
    int slave;                  /* the board that claimed the address, -1 */
    int awaiting, claims;       /* an address on the bus: claims until its NACK check */
    int pending_start;          /* ADDR written while SCL is held: the START waits for the release */
    uint32_t pending_addr;
    uint64_t t_inactive, t_lowtout;   /* time-outs of the stretch in the view, SAM_NEVER */
    /* slave */
    uint8_t s_flags;
    uint16_t s_status;          /* COLL, RXNACK, DIR, SR, CLKHOLD */
    uint8_t s_rx, s_tx;
    int s_state;
    int addressed, master;      /* addressed by this master (board index) since its ADDRESS, until STOP or a START */
    uint64_t stretch_start;
} sercom_t;

static int sercom2_pi = -1;

static sercom_t *st(sam_mcu_t *m, int pi) { return m->pst[pi]; }
static sercom_t *bus_sercom(sam_mcu_t *m) { return sercom2_pi >= 0 ? st(m, sercom2_pi) : NULL; }
static uint32_t reg32(sam_mcu_t *m, int pi, uint32_t off)
{
    const uint8_t *p = m->regs[pi] + off;
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint64_t tu_of(double s) { return (uint64_t)(s * (double)SAM_TU_HZ); }
uint64_t sam_bus_tmin(void) { return tu_of(SAM_BUS_TMIN_S); }

static int sercom_view(sam_mcu_t *m, int pi)
{
    /* views in header order: I2CM, I2CS, SPI, USART; CTRLA.MODE 5 master, 4 slave, 2-3 SPI, 0-1 USART */
    uint32_t mode = (m->regs[pi][0] >> 2) & 7u;
    return mode == 5 ? 1 : mode == 4 ? 2 : (mode == 2 || mode == 3) ? 3 : 4;
}

static uint8_t inten(sam_mcu_t *m, int pi) { return m->regs[pi][SERCOM_I2CM_INTENSET_OFFSET]; }

static void irq(sam_mcu_t *m, int pi)
{
    sercom_t *s = st(m, pi);
    uint8_t f = s->mode == 5 ? s->m_flags : s->mode == 4 ? s->s_flags : 0;
    sam_irq_level(m, sam_periphs[pi].irq, (f & inten(m, pi)) != 0);
}

static int pins_connected(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    /* SDA and SCL muxed to this SERCOM's PAD0/PAD1 (the generated pin table names the function) */
    const char *want[2] = {"PAD0", "PAD1"};
    int pins[2] = {w->cfg.pin_sda, w->cfg.pin_scl};
    for (int k = 0; k < 2; k++) {
        int f = sam_pin_function(m, pins[k]);
        int ok = 0;
        for (unsigned i = 0; f >= 0 && i < sam_npinmux; i++) {
            const sam_pinmux_t *p = &sam_pinmux[i];
            if (p->pin == pins[k] && p->func == f && !strcmp(p->periph, sam_periphs[sercom2_pi].name) &&
                !strcmp(p->signal, want[k]))
                ok = 1;
        }
        if (!ok)
            return 0;
    }
    return 1;
}

static sam_bus_info_t *info(sam_mcu_t *m) { return &m->w->bus.info[m->id]; }
static sam_lineview_t *view(sam_mcu_t *m) { return &m->w->bus.view[m->id]; }

/* ---------------------------------------------------------------- bus steps */

/* A step from board `from` to board `to`, taking effect at t. Ordered by time, then kind, then sender: the same
 * order however the boards were scheduled. The sender stops before t + T: the receiver may answer then. */
static void push(sam_mcu_t *from, int to, uint64_t t, int kind, int arg, int arg2, uint64_t T)
{
    sam_world_t *w = from->w;
    sam_mcu_t *m = w->mcu[to];
    sam_busq_t *q = &w->bus.q[to];
    if (t < m->pos) {
        sam_fail(from, "I2C: a bus step for %s at %.6f s, which has already run to %.6f s (scheduling error)",
                 m->name, (double)t / (double)SAM_TU_HZ, (double)m->pos / (double)SAM_TU_HZ);
        return;
    }
    if (q->n >= SAM_BUSQ) {
        sam_fail(m, "I2C: more than %d bus steps pending", SAM_BUSQ);
        return;
    }
    sam_busev_t e = {t, (uint32_t)T, (uint8_t)kind, (uint8_t)arg, (uint8_t)arg2, (uint8_t)from->id};
    int i = q->n++;
    while (i > 0) {
        const sam_busev_t *p = &q->ev[i - 1];
        if (p->t < t || (p->t == t && (p->kind < kind || (p->kind == kind && p->src <= e.src))))
            break;
        q->ev[i] = *p;
        i--;
    }
    q->ev[i] = e;
    sam_slot_set(m, SAM_SLOT_BUS, q->ev[0].t);
    if (to != from->id)
        sam_stop_before(from, t + sam_bus_tmin());
}

static int address_matches(sam_mcu_t *m, sercom_t *s, uint8_t addr7)
{
    if (m->halted || !s->enabled || s->mode != 4 || !pins_connected(m))
        return 0;
    uint32_t a = reg32(m, sercom2_pi, SERCOM_I2CS_ADDR_OFFSET);
    uint32_t sa = (a >> SERCOM_I2CS_ADDR_ADDR_Pos) & 0x7Fu, mask = (a >> SERCOM_I2CS_ADDR_ADDRMASK_Pos) & 0x7Fu;
    return ((sa ^ addr7) & ~mask) == 0 || (addr7 == 0 && (a & SERCOM_I2CS_ADDR_GENCEN));
}

/* Earliest time a step from this slave to a master can take effect, from its state (SAM_NEVER: none can). */
uint64_t sam_bus_eot_slave(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    sam_busq_t *q = &w->bus.q[m->id];
    uint64_t t = SAM_NEVER;
    uint64_t T = sam_bus_tmin();   /* every answer takes at least this */
    sercom_t *s = bus_sercom(m);
    if (!q->n && !(s && s->addressed))
        return SAM_NEVER;   /* the common case: nothing to answer, not addressed */
    /* a step it has yet to take may be answered; but a parked board (nothing changes it before its next event)
     * does not answer an address that is not its own */
    uint64_t frozen_until = SAM_NEVER;
    if (m->ff.parked)
        for (int k = 0; k < SAM_NSLOTS; k++)
            if (k != SAM_SLOT_BUS && m->slot[k] < frozen_until)
                frozen_until = m->slot[k];
    for (int i = 0; i < q->n; i++) {
        const sam_busev_t *e = &q->ev[i];
        if (e->t < frozen_until && e->kind == BUS_EV_S_ADDRESS && s && !s->addressed &&
            !address_matches(m, s, (uint8_t)(e->arg >> 1)))
            continue;
        t = e->t + T;
        break;
    }
    if (s && s->addressed && (s->s_state == S_AMATCH || s->s_state == S_RX_HOLD || s->s_state == S_TX_NEED) &&
        m->pos + T < t)
        t = m->pos + T;   /* it holds SCL: its software may answer at any time */
    return t;
}

/* Earliest time a step from this master can reach a slave. While it sees SCL held nothing it does reaches the
 * bus until a release it has yet to take (from its queue); otherwise anything may, from T on. */
uint64_t sam_bus_eot_master(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    uint64_t T = sam_bus_tmin();
    if (!view(m)->held)
        return m->pos + T;
    sam_busq_t *q = &w->bus.q[m->id];
    for (int i = 0; i < q->n; i++) {
        int k = q->ev[i].kind;
        if (k == BUS_EV_M_RELEASE || k == BUS_EV_M_MB || k == BUS_EV_M_SB)
            return (q->ev[i].t > m->pos ? q->ev[i].t : m->pos) + T;
    }
    return SAM_NEVER;
}

/* ---------------------------------------------------------------- the master's view of the lines */

static void master_addr(sam_mcu_t *m, int pi, uint32_t v);

static void timeouts_arm(sam_mcu_t *m, uint64_t hold_start)
{
    sercom_t *s = bus_sercom(m);
    int pi = sercom2_pi;
    if (!s || s->mode != 5 || s->busstate != BUSSTATE_OWNER)
        return;
    uint32_t ctrla = reg32(m, pi, SERCOM_I2CM_CTRLA_OFFSET);
    uint32_t it = (ctrla >> SERCOM_I2CM_CTRLA_INACTOUT_Pos) & 3u;
    static const int periods[4] = {0, 5, 10, 20};
    s->t_inactive = it ? hold_start + (uint64_t)periods[it] * s->tbit : SAM_NEVER;
    s->t_lowtout = (ctrla & SERCOM_I2CM_CTRLA_LOWTOUTEN) && sam_gclk_hz(m, SERCOM2_GCLK_ID_SLOW)
                       ? hold_start + tu_of(LOWTOUT_S)
                       : SAM_NEVER;
    uint64_t t = s->t_inactive < s->t_lowtout ? s->t_inactive : s->t_lowtout;
    if (t != SAM_NEVER)
        push(m, m->id, t < sam_now(m) ? sam_now(m) : t, BUS_EV_M_TIMEOUT, 0, 0, s->tbit);
}

static void view_hold(sam_mcu_t *m, uint64_t since)
{
    sam_lineview_t *v = view(m);
    if (!v->held) {
        v->held = 1;
        v->hold_start = since;
        timeouts_arm(m, since);
    }
}

static void view_release(sam_mcu_t *m)
{
    sam_lineview_t *v = view(m);
    sercom_t *s = bus_sercom(m);
    if (!v->held)
        return;
    v->held = 0;
    if (s) {
        s->t_inactive = s->t_lowtout = SAM_NEVER;
        if (s->pending_start && s->enabled && s->mode == 5) {   /* the START that waited for SCL goes out now */
            s->pending_start = 0;
            s->sysop_stuck = 0;
            master_addr(m, sercom2_pi, s->pending_addr);
        }
    }
}

/* ---------------------------------------------------------------- a slave */


static int holds_scl(const sercom_t *s)
{
    return s->addressed && (s->s_state == S_AMATCH || s->s_state == S_RX_HOLD || s->s_state == S_TX_NEED);
}

static void stretch_begin(sam_mcu_t *m, sercom_t *s, uint64_t t, int claim)
{
    s->stretch_start = t;
    s->s_status |= 0x80u;   /* CLKHOLD */
    push(m, s->master, t + s->tbit, claim ? BUS_EV_M_CLAIM : BUS_EV_M_HOLD, 0, 0, s->tbit);
}

static void stretch_end(sam_mcu_t *m, sercom_t *s, uint64_t t)
{
    s->s_status &= (uint16_t)~0x80u;
    if (t > s->stretch_start)
        info(m)->stretch_tu += t - s->stretch_start;
}

/* The slave lets go of the bus now (power lost, its SERCOM reset or disabled): SCL, if it held it, is released
 * with SDA high, which the master reads as a NACK or as 1 bits. */
static void slave_vanish(sam_mcu_t *m, sercom_t *s, uint64_t t)
{
    if (holds_scl(s)) {
        stretch_end(m, s, t);
        if (s->s_state == S_TX_NEED) {
            push(m, s->master, t + s->tbit, BUS_EV_M_RELEASE, 0, 0, s->tbit);
            push(m, s->master, t + 8 * s->tbit, BUS_EV_M_SB, 0xFF, 0, s->tbit);
        } else {
            push(m, s->master, t + s->tbit, BUS_EV_M_MB, 1, 0, s->tbit);
        }
    }
    s->addressed = 0;
    s->s_state = S_IDLE;
}

/* A step for this board as a slave; returns 0 when it changed nothing (an address that is not its own). */
static int slave_step(sam_mcu_t *m, sercom_t *s, const sam_busev_t *e)
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
        int match = s && address_matches(m, s, (uint8_t)(e->arg >> 1));
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
        s->s_flags |= S_AMATCHF;
        s->s_status = (uint16_t)((s->s_status & ~(0x18u)) | (e->arg & 1u ? 0x08u : 0) | (e->arg2 ? 0x10u : 0));
        s->s_state = S_AMATCH;
        stretch_begin(m, s, e->t, 1);
        return 1;
    }
    case BUS_EV_S_DRDY_RX:
        if (!present || s->s_state != S_RX) {   /* nobody takes the byte: not acknowledged */
            push(m, from, e->t + e->tbit, BUS_EV_M_MB, 1, 0, e->tbit);
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
            push(m, from, e->t + 8 * (uint64_t)e->tbit, BUS_EV_M_SB, 0xFF, 0, e->tbit);
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

/* ---------------------------------------------------------------- a master */

static void master_end(sercom_t *s)
{
    s->slave = -1;
    s->awaiting = 0;
}

static void master_step(sam_mcu_t *m, sercom_t *s, const sam_busev_t *e)
{
    int own = s && s->enabled && s->mode == 5 && s->busstate == BUSSTATE_OWNER;
    uint64_t now = e->t;
    switch (e->kind) {
    case BUS_EV_M_CLAIM:
        view_hold(m, now - e->tbit);
        if (!own || !s->awaiting)
            break;   /* a START that was given up meanwhile */
        if (s->claims++) {
            sam_fail(m, "I2C address 0x%02x answered by %s and %s", (reg32(m, sercom2_pi, SERCOM_I2CM_ADDR_OFFSET) >> 1) & 0x7Fu,
                     m->w->mcu[s->slave]->name, m->w->mcu[e->src]->name);
            break;
        }
        s->slave = e->src;
        break;
    case BUS_EV_M_HOLD:
        view_hold(m, now - e->tbit);
        break;
    case BUS_EV_M_RELEASE:
        view_release(m);
        break;
    case BUS_EV_M_NACKCHECK:
        if (!own || !s->awaiting)
            break;
        s->awaiting = 0;
        if (s->claims)
            break;
        info(m)->nacks++;   /* no slave answered its address */
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
            view_release(m);   /* a slave's ACK bit or its data: it let go of SCL */
        break;
    case BUS_EV_M_IDLE:
        if (!s || !s->stop_pending)
            break;
        s->busstate = BUSSTATE_IDLE;
        s->m_status &= (uint16_t)~0x80u;
        s->stop_pending = 0;
        master_end(s);
        break;
    case BUS_EV_M_ARBLOST:
        if (!own)
            break;
        s->m_status |= 0x02u;   /* ARBLOST */
        s->m_flags |= M_MB | F_ERROR;
        s->busstate = BUSSTATE_IDLE;
        info(m)->arblost++;
        master_end(s);
        break;
    case BUS_EV_M_TIMEOUT:
        if (!own || !view(m)->held)
            break;
        if (now >= s->t_lowtout) {
            s->m_status |= 0x40u;   /* LOWTOUT */
            s->m_flags |= M_MB | F_ERROR;
            s->busstate = BUSSTATE_IDLE;
            sam_note(m, "%s: I2C SCL low time-out", m->name);
            master_end(s);
        } else if (now >= s->t_inactive) {
            s->busstate = BUSSTATE_IDLE;   /* the bus looks inactive: the master gives it up */
            info(m)->timeouts_seen++;
            sam_note(m, "%s: I2C inactive-bus time-out after %.1f us of SCL held low", m->name,
                           (double)(now - view(m)->hold_start) * 1e6 / (double)SAM_TU_HZ);
            master_end(s);
        }
        if (s->busstate == BUSSTATE_IDLE)
            s->t_inactive = s->t_lowtout = SAM_NEVER;
        break;
    default: break;
    }
}

/* SAM_SLOT_BUS: the steps due now, each at its own time. */
void sam_bus_fire(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    sam_busq_t *q = &w->bus.q[m->id];
    uint64_t now = sam_now(m);
    sercom_t *s = bus_sercom(m);
    int changed = 0;
    while (q->n && q->ev[0].t <= now && q->ev[0].t < m->stop_at) {
        sam_busev_t e = q->ev[0];
        memmove(q->ev, q->ev + 1, sizeof q->ev[0] * (size_t)(q->n - 1));
        q->n--;
        if (w->cfg.trace & 1) {
            static const char *const names[BUS_EV_COUNT] = {
                "-", "S_ADDRESS", "S_DRDY_RX", "S_DRDY_TX", "S_PREC", "S_RESET", "M_CLAIM", "M_HOLD", "M_RELEASE",
                "M_MB", "M_SB", "M_NACKCHECK", "M_IDLE", "M_ARBLOST", "M_TIMEOUT"};
            sam_note(m, "bus %.3f us %s <- %s %s arg %u", (double)e.t * 1e6 / (double)SAM_TU_HZ, m->name,
                           w->mcu[e.src]->name, names[e.kind], e.arg);
        }
        uint64_t saved = m->t_blk;
        m->t_blk = e.t;
        if (e.kind < BUS_EV_M_CLAIM) {
            changed |= slave_step(m, s, &e);
        } else {
            master_step(m, s, &e);
            changed = 1;
        }
        m->t_blk = saved;
        if (s && !m->halted)
            irq(m, sercom2_pi);
        if (m->err)
            break;
    }
    if (!changed)
        m->ev_quiet = 1;   /* nothing here took notice: a fast-forwarded pass stays valid */
    sam_slot_set(m, SAM_SLOT_BUS, q->n ? q->ev[0].t : SAM_NEVER);
}

/* Steps a parked board would take without any effect (addresses that are not its own), due before t_end and
 * before anything else happens to it: taken now, without waking it (its state cannot change before them). */
void sam_bus_take_quiet(sam_mcu_t *m, uint64_t t_end)
{
    sam_busq_t *q = &m->w->bus.q[m->id];
    sercom_t *s = bus_sercom(m);
    for (int k = 0; k < SAM_NSLOTS; k++)
        if (k != SAM_SLOT_BUS && m->slot[k] < t_end)
            t_end = m->slot[k];
    int k = 0;
    while (k < q->n && q->ev[k].t < t_end) {
        const sam_busev_t *e = &q->ev[k];
        if (e->kind != BUS_EV_S_ADDRESS || (s && (s->addressed || address_matches(m, s, (uint8_t)(e->arg >> 1)))))
            break;
        if (m->w->cfg.trace & 1)
            sam_note(m, "bus %.3f us %s <- %s S_ADDRESS arg %u", (double)e->t * 1e6 / (double)SAM_TU_HZ,
                           m->name, m->w->mcu[e->src]->name, e->arg);
        k++;
    }
    if (k) {
        memmove(q->ev, q->ev + k, sizeof q->ev[0] * (size_t)(q->n - k));
        q->n -= k;
        sam_slot_set(m, SAM_SLOT_BUS, q->n ? q->ev[0].t : SAM_NEVER);
    }
}

/* ---------------------------------------------------------------- the master's actions */

static uint64_t scl_period(sam_mcu_t *m, int pi)
{
    sam_world_t *w = m->w;
    uint64_t hz = sam_gclk_hz(m, SERCOM2_GCLK_ID_CORE);
    if (!hz) {
        sam_fail(m, "I2C START with GCLK_SERCOM2_CORE off: the master has no clock");
        return 0;
    }
    uint32_t baud = reg32(m, pi, SERCOM_I2CM_BAUD_OFFSET);
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

static void master_addr(sam_mcu_t *m, int pi, uint32_t v)
{
    sam_world_t *w = m->w;
    sercom_t *s = st(m, pi);
    uint64_t t = sam_now(m);
    s->m_flags &= (uint8_t)~(M_MB | M_SB | F_ERROR);
    s->m_status &= (uint16_t)~(0x02u | 0x04u | 0x40u | 0x80u);
    s->sysop_stuck = 0;
    if (v & SERCOM_I2CM_ADDR_TENBITEN) {
        sam_fail(m, "I2C 10-bit addressing is not modelled");
        return;
    }
    if (s->busstate == BUSSTATE_UNKNOWN || s->busstate == BUSSTATE_BUSY) {
        sam_note(m, "%s: I2C START with the bus state %s: it waits", m->name,
                       s->busstate == BUSSTATE_UNKNOWN ? "UNKNOWN" : "BUSY");
        return;
    }
    if (view(m)->held) {   /* SCL held low by a slave: no START can be made until it lets go */
        s->pending_start = 1;
        s->pending_addr = v;
        s->sysop_stuck = 1;
        return;
    }
    uint64_t T = scl_period(m, pi);
    if (!T)
        return;
    int repeated = s->busstate == BUSSTATE_OWNER;
    s->tbit = T;
    s->busstate = BUSSTATE_OWNER;
    s->m_dir = (int)(v & 1u);
    s->slave = -1;
    info(m)->transactions++;
    info(m)->busy_tu += 10 * T;
    if (w->bus.sda_stuck || !pins_connected(m)) {
        /* SDA does not follow the master: arbitration lost on the first bit it drives high */
        s->awaiting = 0;
        push(m, m->id, t + T, BUS_EV_M_ARBLOST, 0, 0, T);
        return;
    }
    for (int i = 0; i < w->nmcu; i++)
        if (w->mcu[i] && i != m->id)
            push(m, i, t + 9 * T, BUS_EV_S_ADDRESS, (int)(v & 0xFFu), repeated, T);
    s->awaiting = 1;
    s->claims = 0;
    push(m, m->id, t + 10 * T, BUS_EV_M_NACKCHECK, 0, 0, T);
}

static void master_data(sam_mcu_t *m, int pi, uint8_t b)
{
    sercom_t *s = st(m, pi);
    uint64_t t = sam_now(m), T = s->tbit;
    if (s->busstate != BUSSTATE_OWNER || !(s->m_flags & M_MB) || s->m_dir) {
        sam_note(m, "%s: I2C DATA written outside a write transaction's MB: ignored", m->name);
        return;
    }
    s->m_flags &= (uint8_t)~(M_MB | M_SB);
    s->m_status &= (uint16_t)~0x80u;
    info(m)->busy_tu += 9 * T;
    if (s->slave >= 0)
        push(m, s->slave, t + 8 * T, BUS_EV_S_DRDY_RX, b, 0, T);
    else
        push(m, m->id, t + 9 * T, BUS_EV_M_MB, 1, 0, T);   /* no slave: not acknowledged */
}

static void master_cmd(sam_mcu_t *m, int pi, uint32_t cmd, int nack)
{
    sercom_t *s = st(m, pi);
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
        master_addr(m, pi, reg32(m, pi, SERCOM_I2CM_ADDR_OFFSET));
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
            push(m, sl, t + T, BUS_EV_S_DRDY_TX, 0, 0, T);
        else
            push(m, m->id, t + 9 * T, BUS_EV_M_SB, 0xFF, 0, T);   /* nobody drives SDA: 0xFF */
        info(m)->busy_tu += T;
        return;
    }
    /* cmd 3: (ACK/NACK of a read) then STOP */
    uint64_t tstop = t + (read ? 2 : 1) * T;
    if (read && sl >= 0)
        push(m, sl, t + T, BUS_EV_S_DRDY_TX, nack ? 1 : 0, 0, T);
    if (sl >= 0)
        push(m, sl, tstop, BUS_EV_S_PREC, 0, 0, T);
    push(m, m->id, tstop, BUS_EV_M_IDLE, 0, 0, T);
    s->stop_pending = 1;   /* SYSOP until the STOP is on the bus */
    info(m)->stops++;
    info(m)->busy_tu += tstop - t;
}

/* ---------------------------------------------------------------- the slave's actions */

static void slave_cmd(sam_mcu_t *m, int pi, uint32_t cmd, int nack)
{
    sercom_t *s = st(m, pi);
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
            push(m, s->master, t + T, BUS_EV_M_MB, 1, 0, T);
            info(m)->nacks++;
            s->s_state = S_IDLE;
            s->addressed = 0;
        } else if (s->s_status & 0x08u) {   /* a master read: after the ACK, the slave's data interrupt */
            push(m, s->master, t + T, BUS_EV_M_RELEASE, 0, 0, T);
            push(m, m->id, t + T, BUS_EV_S_DRDY_TX, 0, 0, T);
            s->s_state = S_TX;   /* until that DRDY it does not hold SCL */
        } else {
            push(m, s->master, t + T, BUS_EV_M_MB, 0, 0, T);
            s->s_state = S_RX;
        }
        return;
    }
    if (state == S_RX_HOLD) {
        stretch_end(m, s, t);
        push(m, s->master, t + T, BUS_EV_M_MB, nack ? 1 : 0, 0, T);
        s->s_state = cmd == 3 && !nack ? S_RX : S_WAIT;   /* S_WAIT: it listens no more, bytes go unacknowledged */
        return;
    }
    if (state == S_TX_NEED) {
        stretch_end(m, s, t);
        push(m, s->master, t + T, BUS_EV_M_RELEASE, 0, 0, T);
        if (cmd == 3) {   /* send what DATA holds */
            push(m, s->master, t + 8 * T, BUS_EV_M_SB, s->s_tx, 0, T);
            s->s_state = S_TX;
        } else {
            push(m, s->master, t + 8 * T, BUS_EV_M_SB, 0xFF, 0, T);   /* released: the master reads 1s */
            s->s_state = S_WAIT;
        }
        info(m)->busy_tu += 8 * T;
        return;
    }
    /* after a STOP, or with no flag: the command only clears flags */
}

static void slave_data(sam_mcu_t *m, int pi, uint8_t b)
{
    sercom_t *s = st(m, pi);
    uint64_t t = sam_now(m), T = s->tbit;
    s->s_tx = b;
    if (s->s_state != S_TX_NEED || !s->addressed)
        return;   /* not asked for data (after a NACK: the master ends with STOP) */
    s->s_flags &= (uint8_t)~S_DRDY;
    stretch_end(m, s, t);
    push(m, s->master, t + T, BUS_EV_M_RELEASE, 0, 0, T);
    push(m, s->master, t + 8 * T, BUS_EV_M_SB, b, 0, T);
    info(m)->busy_tu += 8 * T;
    s->s_state = S_TX;
}

/* ---------------------------------------------------------------- reset, enable */

/* The SERCOM's state machines restart (SWRST, disable, the chip's reset): a slave lets go of the bus; a master's
 * own pending steps are gone (what it learns of the lines stays). */
static void sercom_restart(sam_mcu_t *m, sercom_t *s)
{
    sam_world_t *w = m->w;
    uint64_t t = sam_now(m);
    slave_vanish(m, s, t);
    sam_busq_t *q = &w->bus.q[m->id];
    int k = 0;
    for (int i = 0; i < q->n; i++)
        if (q->ev[i].src != m->id)   /* its own steps (a master's, or a slave's DRDY) are gone */
            q->ev[k++] = q->ev[i];
    q->n = k;
    sam_slot_set(m, SAM_SLOT_BUS, q->n ? q->ev[0].t : SAM_NEVER);
    s->busstate = BUSSTATE_UNKNOWN;
    s->m_flags = 0;
    s->stop_pending = s->sysop_stuck = s->pending_start = 0;
    s->t_inactive = s->t_lowtout = SAM_NEVER;
    master_end(s);
}

static void sercom_reset(sam_mcu_t *m, int pi)
{
    if (sercom2_pi < 0)
        sercom2_pi = sam_periph_index("SERCOM2");
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(sercom_t));
    sercom_t *s = m->pst[pi];
    if (pi == sercom2_pi && m->w)
        sercom_restart(m, s);
    memset(s, 0, sizeof *s);
    s->slave = s->master = -1;
    s->t_inactive = s->t_lowtout = SAM_NEVER;
}

/* The board lost power (sam_world.c): it lets go of the bus. */
void sam_bus_power_lost(sam_mcu_t *m)
{
    sercom_t *s = bus_sercom(m);
    if (s)
        sercom_restart(m, s);
}
static void sync(sam_mcu_t *m, sercom_t *s, uint32_t bits)
{
    uint64_t hz = sam_gclk_hz(m, SERCOM2_GCLK_ID_CORE), now = sam_now(m);
    if (now >= s->sync_until)
        s->sync_bits = 0;
    s->sync_bits |= bits;
    s->sync_until = hz ? now + (3u * SAM_TU_HZ + hz - 1) / hz : SAM_NEVER;
    if (sercom2_pi >= 0 && s->sync_until != SAM_NEVER)
        sam_slot_set(m, sercom2_pi, s->sync_until);   /* SYNCBUSY changes then: an event */
}

static void sercom_fire(sam_mcu_t *m, int pi)
{
    (void)m;
    (void)pi;   /* a synchronisation ended */
}

static int sercom_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    sercom_t *s = st(m, pi);
    uint32_t off = sam_regs[ri].offset;
    uint64_t now = sam_now(m);
    if (off == SERCOM_I2CM_SYNCBUSY_OFFSET) {
        *v = (now < s->sync_until ? s->sync_bits & 7u : 0u) | (s->stop_pending || s->sysop_stuck ? 4u : 0u);
        return SAM_DONE;
    }
    if (s->mode != 4 && s->mode != 5)
        return SAM_GENERIC;
    if (off == SERCOM_I2CM_INTFLAG_OFFSET) {
        *v = s->mode == 5 ? s->m_flags : s->s_flags;
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_STATUS_OFFSET) {
        *v = s->mode == 5 ? (uint32_t)s->m_status | s->busstate << 4 : s->s_status;
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_DATA_OFFSET) {
        *v = s->mode == 5 ? s->m_data : s->s_rx;
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int sercom_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    sercom_t *s = st(m, pi);
    uint32_t off = sam_regs[ri].offset;
    v &= mask;
    sam_activity(m);
    if (off == 0) {   /* CTRLA, every mode */
        if (v & 1u) {  /* SWRST */
            memset(m->regs[pi], 0, sam_periphs[pi].size);
            sercom_reset(m, pi);
            sync(m, st(m, pi), 1u);
            irq(m, pi);
            return SAM_DONE;
        }
        uint32_t old = reg32(m, pi, 0);
        sam_generic_write(m, ri, v, mask);
        uint32_t nv = reg32(m, pi, 0);
        s->mode = (int)((nv >> 2) & 7u);
        if ((nv & 2u) && !(old & 2u)) {
            sync(m, s, 2u);
            if (s->mode != 4 && s->mode != 5) {
                sam_fail(m, "%s enabled in mode %d: only I2C master and slave are modelled", sam_periphs[pi].name,
                         s->mode);
                return SAM_DONE;
            }
            if (nv & (SERCOM_I2CM_CTRLA_SCLSM | SERCOM_I2CM_CTRLA_SPEED_Msk | SERCOM_I2CM_CTRLA_MEXTTOEN |
                      SERCOM_I2CM_CTRLA_SEXTTOEN | SERCOM_I2CM_CTRLA_PINOUT)) {
                sam_fail(m, "%s.CTRLA = 0x%08x: SCL stretch after ACK, Fm+/Hs speeds, extend time-outs and 4-wire "
                         "operation are not modelled", sam_periphs[pi].name, nv);
                return SAM_DONE;
            }
            if (pi != sercom2_pi) {
                sam_fail(m, "%s enabled in I2C mode: only SERCOM2 is wired to the bus (PA08, PA09)",
                         sam_periphs[pi].name);
                return SAM_DONE;
            }
            if (s->mode == 5 && m->role != SAM_ROLE_PRIMARY) {
                sam_fail(m, "%s enabled as I2C master on a cell: only the primary masters the bus in this model",
                         sam_periphs[pi].name);
                return SAM_DONE;
            }
            s->enabled = 1;
            if (s->mode == 5)
                s->busstate = BUSSTATE_UNKNOWN;
        } else if (!(nv & 2u) && (old & 2u)) {
            sync(m, s, 2u);
            if (pi == sercom2_pi)
                sercom_restart(m, s);
            s->enabled = 0;
            s->busstate = BUSSTATE_UNKNOWN;
            s->s_state = S_IDLE;
            s->sysop_stuck = 0;
        }
        return SAM_DONE;
    }
    if (s->mode != 4 && s->mode != 5)
        return SAM_GENERIC;
    if (off == SERCOM_I2CM_CTRLB_OFFSET) {
        if (v & SERCOM_I2CM_CTRLB_SMEN) {
            sam_fail(m, "I2C smart mode (CTRLB.SMEN) is not modelled");
            return SAM_DONE;
        }
        uint32_t cmd = (v >> 16) & 3u;
        int nack = (v & SERCOM_I2CM_CTRLB_ACKACT) != 0;
        sam_reg_put(m, ri, (sam_reg_get(m, ri) & ~mask) | (v & ~SERCOM_I2CM_CTRLB_CMD_Msk));
        if (cmd && s->enabled) {
            if (s->mode == 5) {
                sync(m, s, 4u);
                master_cmd(m, pi, cmd, nack);
            } else {
                slave_cmd(m, pi, cmd, nack);
            }
            irq(m, pi);
        }
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_INTFLAG_OFFSET) {
        if (s->mode == 5) {
            s->m_flags &= (uint8_t)~v;
        } else {
            uint8_t st_before = (uint8_t)s->s_state;
            if ((v & S_AMATCHF) && st_before == S_AMATCH)
                slave_cmd(m, pi, 3, (sam_reg_get(m, sam_idx.sercom2_i2cs_ctrlb) & SERCOM_I2CS_CTRLB_ACKACT) != 0);
            else if ((v & S_DRDY) && st_before == S_RX_HOLD)
                slave_cmd(m, pi, 3, (sam_reg_get(m, sam_idx.sercom2_i2cs_ctrlb) & SERCOM_I2CS_CTRLB_ACKACT) != 0);
            else
                s->s_flags &= (uint8_t)~v;
        }
        irq(m, pi);
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_STATUS_OFFSET) {
        if (s->mode == 5) {
            s->m_status &= (uint16_t)~(v & 0x43u);   /* BUSERR, ARBLOST, LOWTOUT: write 1 to clear */
            if (((v >> 4) & 3u) == BUSSTATE_IDLE && s->busstate == BUSSTATE_UNKNOWN) {
                s->busstate = BUSSTATE_IDLE;
                sync(m, s, 4u);
            }
        } else {
            s->s_status &= (uint16_t)~(v & 0x43u);
        }
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_ADDR_OFFSET) {
        sam_generic_write(m, ri, v, mask);
        if (s->mode == 5 && s->enabled) {
            sync(m, s, 4u);
            master_addr(m, pi, reg32(m, pi, SERCOM_I2CM_ADDR_OFFSET));
            irq(m, pi);
        }
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_DATA_OFFSET) {
        if (s->mode == 5) {
            if (s->enabled)
                master_data(m, pi, (uint8_t)v);
        } else if (s->enabled) {
            slave_data(m, pi, (uint8_t)v);
        }
        irq(m, pi);
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_BAUD_OFFSET || off == SERCOM_I2CM_INTENSET_OFFSET || off == SERCOM_I2CM_INTENCLR_OFFSET ||
        off == SERCOM_I2CM_DBGCTRL_OFFSET) {
        sam_generic_write(m, ri, v, mask);
        irq(m, pi);
        return SAM_DONE;
    }
    return SAM_UNCOVERED;
}

const sam_model_t sam_model_sercom = {"Sercom", sercom_reset, sercom_view, sercom_read, sercom_write, sercom_fire};


/* ---------------------------------------------------------------- the lines, for GPIO bus recovery */

void sam_bus_init(sam_world_t *w)
{
    memset(&w->bus, 0, sizeof w->bus);
    for (int i = 0; i < SAM_MAX_MCU; i++)
        w->bus.view[i].gpio_sda = w->bus.view[i].gpio_scl = 1;
}

/* The primary's SDA/SCL pins or the stuck-SDA fault changed: when it drives the lines as GPIO (bus recovery),
 * they are the wired AND of its pins, SCL held by a slave (as it knows) and the fault; a STOP on them (SDA rising
 * while SCL is high) ends every slave's transaction. Only the primary drives the lines as GPIO in this model. */
void sam_bus_lines_changed(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    if (m->role != SAM_ROLE_PRIMARY || sercom2_pi < 0 || m->halted || pins_connected(m))
        return;   /* the SERCOM drives the lines: the byte-level model holds */
    sam_lineview_t *v = view(m);
    int drv, sda = sam_pin_out(m, w->cfg.pin_sda, &drv);
    sda = drv ? sda : 1;
    int scl = sam_pin_out(m, w->cfg.pin_scl, &drv);
    scl = drv ? scl : 1;
    if (w->bus.sda_stuck)
        sda = 0;
    if (v->held)
        scl = 0;
    int prev_sda = v->gpio_sda, prev_scl = v->gpio_scl;
    v->gpio_sda = sda;
    v->gpio_scl = scl;
    if (prev_scl && scl && !prev_sda && sda) {
        info(m)->gpio_stops++;
        uint64_t T = bus_sercom(m) && bus_sercom(m)->tbit ? bus_sercom(m)->tbit : tu_of(2.5e-6);
        for (int i = 0; i < w->nmcu; i++)
            if (w->mcu[i] && i != m->id)
                push(m, i, sam_now(m) + T, BUS_EV_S_RESET, 0, 0, T);
        if (bus_sercom(m))
            master_end(bus_sercom(m));
    }
}

int sam_world_bus_info(const sam_world_t *w, sam_bus_info_t *out)
{
    memset(out, 0, sizeof *out);
    for (int i = 0; i < SAM_MAX_MCU; i++) {
        const sam_bus_info_t *b = &w->bus.info[i];
        out->transactions += b->transactions;
        out->nacks += b->nacks;
        out->timeouts_seen += b->timeouts_seen;
        out->stretch_tu += b->stretch_tu;
        out->busy_tu += b->busy_tu;
        out->arblost += b->arblost;
        out->buserr += b->buserr;
        out->stops += b->stops;
        out->gpio_stops += b->gpio_stops;
    }
    const sam_lineview_t *v = w->primary_mcu >= 0 ? &w->bus.view[w->primary_mcu] : NULL;
    out->sda = w->bus.sda_stuck ? 0 : v ? v->gpio_sda : 1;
    out->scl = v && v->held ? 0 : v ? v->gpio_scl : 1;
    return 0;
}
