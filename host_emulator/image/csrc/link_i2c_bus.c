/* The link between the boards' I2C pins: bus steps between SERCOMs in I2C mode, with their times, and the lines. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam_sercom.h"
#include "sam_vendor_gen.h"

/*
 * The bus is modelled per byte with clock stretching. T is the master's SCL period from its BAUD register,
 * f_GCLK / (10 + BAUD + BAUDLOW) plus the bus's rise time (the datasheet's f_SCL formula); at least
 * SAM_BUS_TMIN (Fast mode, the fastest with CTRLA.SPEED = 0). Boards affect each other only through bus steps:
 * messages into the receiver's queue, each timestamped at least T after its cause, and no board reads another
 * board's state. That is what lets the world run boards apart in time (sam_world_run.c) with results that do not
 * depend on how it schedules them. The steps, with the time they take effect (t: the cause):
 *
 *   master ADDR      ADDRESS to every other board at t + 9T (START and 8 address bits); each slave compares it
 *                    with its ADDR by its CTRLB.AMODE: the one that matches sets AMATCH, holds SCL and CLAIMs it
 *                    (the master learns at t + 10T), or with CTRLB.AACKEN CLAIMs it without holding SCL and
 *                    acknowledges at once (MB at t + 10T; for a read its own DRDY then); the master's NACK check at
 *                    t + 10T gives MB with RXNACK when none did
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
 *
 * Which SERCOM is on the bus is the board's wiring (sam_world_cfg_t.bus_sercom, from image/board.py): the one whose
 * PAD0 and PAD1 the SDA and SCL pins carry. The SERCOM's I2C mode (sam_sercom_i2c*.c) sends the steps and reacts
 * to them; this file queues them per board and delivers them as the board's event source.
 */

static uint64_t tu_of(double s) { return (uint64_t)(s * (double)SAM_TU_HZ); }
uint64_t sam_bus_tmin(void) { return tu_of(SAM_BUS_TMIN_S); }

int sam_bus_sercom(sam_mcu_t *m) { return m->w->bus.pi; }
static sam_sercom_t *bus_sercom(sam_mcu_t *m) { return m->w->bus.pi >= 0 ? sam_sercom_st(m, m->w->bus.pi) : NULL; }
sam_bus_info_t *sam_bus_counts(sam_mcu_t *m) { return &m->w->bus.info[m->id]; }
sam_lineview_t *sam_bus_view(sam_mcu_t *m) { return &m->w->bus.view[m->id]; }
static sam_bus_info_t *info(sam_mcu_t *m) { return sam_bus_counts(m); }
static sam_lineview_t *view(sam_mcu_t *m) { return sam_bus_view(m); }

/* the pin table has SIGNAL of the bus SERCOM on function f of pin */
static int pin_has(int pin, int f, int pi, const char *signal)
{
    for (unsigned i = 0; f >= 0 && i < sam_npinmux; i++) {
        const sam_pinmux_t *p = &sam_pinmux[i];
        if (p->pin == pin && p->func == f && !strcmp(p->periph, sam_periphs[pi].name) && !strcmp(p->signal, signal))
            return 1;
    }
    return 0;
}

/* SDA and SCL muxed to the bus SERCOM's PAD0/PAD1 (the functions the generated pin table names: sam_bus_init) */
int sam_bus_pins_connected(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    int fa = sam_pin_function(m, w->cfg.pin_sda), fl = sam_pin_function(m, w->cfg.pin_scl);
    return fa >= 0 && (w->bus.sda_funcs >> fa & 1u) && fl >= 0 && (w->bus.scl_funcs >> fl & 1u);
}

/* ---------------------------------------------------------------- bus steps */

/* A step from board `from` to board `to`, taking effect at t. Ordered by time, then kind, then sender: the same
 * order however the boards were scheduled. The sender stops before t + T: the receiver may answer then. */
void sam_bus_push(sam_mcu_t *from, int to, uint64_t t, int kind, int arg, int arg2, uint64_t T)
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
    sam_slot_set(m, w->bus.slot[to], q->ev[0].t);
    if (to != from->id)
        sam_stop_before(from, t + sam_bus_tmin());
}

/* Earliest time a step from this slave to a master can take effect, from its state (SAM_NEVER: none can). */
uint64_t sam_bus_eot_slave(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    sam_busq_t *q = &w->bus.q[m->id];
    sam_sercom_t *s = bus_sercom(m);
    if (!q->n && !(s && s->addressed))
        return SAM_NEVER;   /* the common case: nothing to answer, not addressed */
    uint64_t t = SAM_NEVER;
    uint64_t T = sam_bus_tmin();   /* every answer takes at least this */
    /* a step it has yet to take may be answered; but a parked board (nothing changes it before its next event)
     * does not answer an address that is not its own */
    uint64_t frozen_until = SAM_NEVER;
    if (m->ff.parked) {
        frozen_until = m->ff.horizon;   /* a probed pass repeats only up to its horizon (sam_ff.c) */
        uint64_t other = sam_slot_earliest(m, w->bus.slot[m->id]);
        if (other < frozen_until)
            frozen_until = other;
    }
    for (int i = 0; i < q->n; i++) {
        const sam_busev_t *e = &q->ev[i];
        if (e->t < frozen_until && e->kind == BUS_EV_S_ADDRESS && s && !s->addressed &&
            !sam_i2c_address_matches(m, w->bus.pi, s, (uint8_t)(e->arg >> 1)))
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

static void note_step(sam_mcu_t *m, const sam_busev_t *e)
{
    static const char *const names[BUS_EV_COUNT] = {
        "-", "S_ADDRESS", "S_DRDY_RX", "S_DRDY_TX", "S_PREC", "S_RESET", "M_CLAIM", "M_HOLD", "M_RELEASE",
        "M_MB", "M_SB", "M_NACKCHECK", "M_IDLE", "M_ARBLOST", "M_TIMEOUT", "M_BUSERR", "M_SDA"};
    sam_note(m, "bus %.3f us %s <- %s %s arg %u", (double)e->t * 1e6 / (double)SAM_TU_HZ, m->name,
             m->w->mcu[e->src]->name, names[e->kind], e->arg);
}

/* A step the board takes without any effect its software could see, given whether it (as a master) sees SCL held
 * then: an address that is not its own, to a slave; a slave holding or letting go of SCL with nothing waiting on
 * it, to a master (sam_i2cm_step_quiet). */
static int step_quiet(sam_mcu_t *m, sam_sercom_t *s, const sam_busev_t *e, int held)
{
    if (e->kind == BUS_EV_S_ADDRESS)
        return s && !s->addressed && !sam_i2c_address_matches(m, m->w->bus.pi, s, (uint8_t)(e->arg >> 1));
    if (e->kind == BUS_EV_M_HOLD || e->kind == BUS_EV_M_RELEASE)
        return sam_i2cm_step_quiet(m, m->w->bus.pi, s, e->kind, held);
    return 0;
}

/* When the first step in the board's queue that is not quiet takes effect (SAM_NEVER: none is queued). The quiet
 * ones before it change only the master's view of SCL, followed here as they would change it. */
uint64_t sam_bus_next_loud(sam_mcu_t *m)
{
    sam_busq_t *q = &m->w->bus.q[m->id];
    sam_sercom_t *s = bus_sercom(m);
    int held = view(m)->held;
    for (int i = 0; i < q->n; i++) {
        const sam_busev_t *e = &q->ev[i];
        if (!step_quiet(m, s, e, held))
            return e->t;
        if (e->kind == BUS_EV_M_HOLD)
            held = 1;
        else if (e->kind == BUS_EV_M_RELEASE)
            held = 0;
    }
    return SAM_NEVER;
}

/* The bus's event source: the steps due now, each at its own time. */
static void bus_fire(sam_mcu_t *m, void *ctx)
{
    (void)ctx;
    sam_world_t *w = m->w;
    sam_busq_t *q = &w->bus.q[m->id];
    uint64_t now = sam_now(m);
    sam_sercom_t *s = bus_sercom(m);
    int changed = 0;
    while (q->n && q->ev[0].t <= now && q->ev[0].t < m->stop_at) {
        sam_busev_t e = q->ev[0];
        memmove(q->ev, q->ev + 1, sizeof q->ev[0] * (size_t)(q->n - 1));
        q->n--;
        if (w->cfg.trace & 1)
            note_step(m, &e);
        uint64_t saved = m->t_blk;
        m->t_blk = e.t;
        if (e.kind < BUS_EV_M_CLAIM) {
            changed |= sam_i2cs_step(m, s, &e);
        } else {
            changed |= !step_quiet(m, s, &e, view(m)->held);
            sam_i2cm_step(m, w->bus.pi, s, &e);
        }
        m->t_blk = saved;
        if (s && !m->halted)
            sam_sercom_irq(m, w->bus.pi);
        if (m->err)
            break;
    }
    if (!changed)
        m->ev_quiet = 1;   /* nothing here took notice: a fast-forwarded pass stays valid */
    sam_slot_set(m, w->bus.slot[m->id], q->n ? q->ev[0].t : SAM_NEVER);
}

/* Steps a parked board would take without any effect its software could see (step_quiet), due before t_end and
 * before anything else happens to it: taken now, each at its own time, without waking it (its state cannot change
 * before them). */
static void bus_quiet(sam_mcu_t *m, void *ctx, uint64_t t_end)
{
    (void)ctx;
    sam_busq_t *q = &m->w->bus.q[m->id];
    if (!q->n)
        return;
    sam_sercom_t *s = bus_sercom(m);
    uint64_t other = sam_slot_earliest(m, m->w->bus.slot[m->id]);
    if (other < t_end)
        t_end = other;
    int k = 0;
    while (k < q->n && q->ev[k].t < t_end && step_quiet(m, s, &q->ev[k], view(m)->held)) {
        const sam_busev_t *e = &q->ev[k];
        if (m->w->cfg.trace & 1)
            note_step(m, e);
        if (e->kind != BUS_EV_S_ADDRESS) {   /* a master's view of SCL follows it */
            uint64_t saved = m->t_blk;
            m->t_blk = e->t;
            sam_i2cm_step(m, m->w->bus.pi, s, e);
            m->t_blk = saved;
        }
        k++;
    }
    if (k) {
        memmove(q->ev, q->ev + k, sizeof q->ev[0] * (size_t)(q->n - k));
        q->n -= k;
        sam_slot_set(m, m->w->bus.slot[m->id], q->n ? q->ev[0].t : SAM_NEVER);
    }
}

/* The board's SERCOM restarted: its own pending steps (a master's, or a slave's DRDY) are gone. */
void sam_bus_drop_own(sam_mcu_t *m)
{
    sam_busq_t *q = &m->w->bus.q[m->id];
    int k = 0;
    for (int i = 0; i < q->n; i++)
        if (q->ev[i].src != m->id)
            q->ev[k++] = q->ev[i];
    q->n = k;
    sam_slot_set(m, m->w->bus.slot[m->id], q->n ? q->ev[0].t : SAM_NEVER);
}

/* The board lost power (sam_world_faults.c): it lets go of the bus. */
void sam_bus_power_lost(sam_mcu_t *m)
{
    if (bus_sercom(m))
        sam_i2c_restart(m, m->w->bus.pi);
}

/* The stuck-SDA fault began (stuck 1) or ended, at the primary's time now: its bus monitor learns of it as a bus
 * step now (SDA falling while SCL is high is a START by someone else, rising a STOP: sam_i2cm_step). */
void sam_bus_sda_fault(sam_mcu_t *m, int stuck)
{
    if (m->role == SAM_ROLE_PRIMARY && m->w->bus.pi >= 0 && !m->halted)
        sam_bus_push(m, m->id, sam_now(m), BUS_EV_M_SDA, stuck ? 1 : 0, 0, sam_bus_tmin());
}

/* ---------------------------------------------------------------- the lines, for GPIO bus recovery */

/* The bus of the world's wiring: the SERCOM (SERCOMn, n = cfg.bus_sercom) whose PAD0 and PAD1 the SDA and SCL pins
 * can carry. -1 when the pin table has no such function. */
int sam_bus_init(sam_world_t *w)
{
    memset(&w->bus, 0, sizeof w->bus);
    for (int i = 0; i < SAM_MAX_MCU; i++)
        w->bus.view[i].gpio_sda = w->bus.view[i].gpio_scl = 1;
    char name[16];
    snprintf(name, sizeof name, "SERCOM%d", (int)w->cfg.bus_sercom);
    w->bus.pi = w->cfg.bus_sercom >= 0 && w->cfg.bus_sercom < 10 ? sam_periph_index(name) : -1;
    if (w->bus.pi < 0)
        return -1;
    for (int f = 0; f < 8; f++) {
        w->bus.sda_funcs |= (uint8_t)(pin_has(w->cfg.pin_sda, f, w->bus.pi, "PAD0") << f);
        w->bus.scl_funcs |= (uint8_t)(pin_has(w->cfg.pin_scl, f, w->bus.pi, "PAD1") << f);
    }
    return w->bus.sda_funcs && w->bus.scl_funcs ? 0 : -1;
}

/* The bus's event source on a board (registered when the world loads it). */
void sam_bus_port_init(sam_mcu_t *m)
{
    m->w->bus.slot[m->id] = sam_source_add(m, bus_fire, bus_quiet, NULL, SAM_SRC_UNPOWERED);
}

/* The primary's SDA/SCL pins or the stuck-SDA fault changed: when it drives the lines as GPIO (bus recovery),
 * they are the wired AND of its pins, SCL held by a slave (as it knows) and the fault; a STOP on them (SDA rising
 * while SCL is high) ends every slave's transaction. Only the primary drives the lines as GPIO in this model. */
void sam_bus_lines_changed(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    if (m->role != SAM_ROLE_PRIMARY || w->bus.pi < 0 || m->halted || sam_bus_pins_connected(m))
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
                sam_bus_push(m, i, sam_now(m) + T, BUS_EV_S_RESET, 0, 0, T);
        if (bus_sercom(m))
            sam_i2cm_end(bus_sercom(m));
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
