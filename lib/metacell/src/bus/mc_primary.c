/* Primary poll scheduler, command forwarding and SLCAN link (portable C99, no division, time passed in). */
#include "mc_primary.h"
#include "mc_crc8.h"

#define QMASK (MC_PRIMARY_QLEN - 1)
#if (MC_PRIMARY_QLEN & QMASK) != 0
#error "MC_PRIMARY_QLEN must be a power of two"
#endif

static int due(uint32_t now, uint32_t t) { return (int32_t)(now - t) >= 0; }

void mc_primary_init(mc_primary_t *p, uint32_t now_us)
{
    uint8_t *raw = (uint8_t *)p;
    for (uint32_t k = 0; k < sizeof(*p); k++)
        raw[k] = 0;
    p->period_us = 0;
    p->txn_timeout_us = MC_SCHED_TXN_TIMEOUT_US;
    p->ack_timeout_us = MC_SCHED_ACK_TIMEOUT_US;
    p->status_every = MC_SCHED_STATUS_EVERY;
    p->n_cells = MC_N_CELLS;
    p->last_us = now_us;
}

int mc_primary_set_cells(mc_primary_t *p, uint32_t n)
{
    if (n < 1u || n > MC_MAX_CELLS || n > p->status_every || p->started || p->busy)
        return -1;
    p->n_cells = (uint8_t)n;
    return 0;
}

int mc_primary_configure(mc_primary_t *p, uint32_t period_us, uint32_t txn_timeout_us,
                         uint32_t ack_timeout_us, uint32_t status_every)
{
    if (period_us > 10000000u || txn_timeout_us < 100u || txn_timeout_us > 100000u ||
        ack_timeout_us < 1000u || ack_timeout_us > 10000000u || status_every < 16u ||
        status_every > 65535u || status_every < p->n_cells)
        return -1;
    p->period_us = period_us;
    p->txn_timeout_us = txn_timeout_us;
    p->ack_timeout_us = ack_timeout_us;
    p->status_every = status_every;
    return 0;
}

/* ms += (d + rem) / 1000 as a multiply-shift: floor(n / 1000) = (n * 274877907) >> 38,
 * exact for n < 2^33; rem keeps the microseconds left over. */
uint32_t mc_primary_ms(mc_primary_t *p, uint32_t now_us)
{
    uint64_t n = (uint64_t)(uint32_t)(now_us - p->last_us) + p->us_rem;
    uint32_t q = (uint32_t)((n * 274877907u) >> 38);
    p->last_us = now_us;
    p->ms += q;
    p->us_rem = (uint32_t)(n - (uint64_t)q * 1000u);
    return p->ms;
}

uint32_t mc_primary_qfree(const mc_primary_t *p)
{
    return (uint32_t)((p->q_tail - p->q_head - 1u) & QMASK);
}

static void wide_inc(uint32_t *c)
{
    if (*c != 0xFFFFFFFFu)
        (*c)++;
}

/* Queue a frame; the caller has checked the room. */
static void put(mc_primary_t *p, uint32_t id, uint8_t dlc, const uint8_t *d)
{
    uint8_t nh = (uint8_t)((p->q_head + 1u) & QMASK);
    mc_can_frame_t *f = &p->q[p->q_head];
    f->id = id;
    f->dlc = dlc;
    for (uint32_t k = 0; k < 8; k++)
        f->data[k] = k < dlc ? d[k] : 0;
    p->q_head = nh;
}

/* A data frame (sample, status, link, heartbeat, block): only above the reserve. */
static void push(mc_primary_t *p, uint32_t id, uint8_t dlc, const uint8_t *d)
{
    if (mc_primary_qfree(p) <= (uint32_t)p->n_cells + 2u) {   /* the reserve: MC_PRIMARY_QRESERVE at 16 cells */
        wide_inc(&p->tx_drop);
        return;
    }
    put(p, id, dlc, d);
}

int mc_primary_pop(mc_primary_t *p, mc_can_frame_t *f)
{
    if (p->q_tail == p->q_head)
        return 0;
    *f = p->q[p->q_tail];
    p->q_tail = (uint8_t)((p->q_tail + 1u) & QMASK);
    return 1;
}

static void result_frame(mc_primary_t *p, uint32_t j, uint8_t reg, uint8_t lseq, uint8_t result,
                         uint8_t tries)
{
    uint8_t d[MC_CAN_CMD_RESULT_DLC];
    d[MC_CAN_CMD_RESULT_REG] = reg;
    d[MC_CAN_CMD_RESULT_SEQ] = lseq;
    d[MC_CAN_CMD_RESULT_RESULT] = result;
    d[MC_CAN_CMD_RESULT_RETRIES] = tries;
    put(p, MC_CAN_CMD_RESULT + j, MC_CAN_CMD_RESULT_DLC, d);
}

/* The result of an accepted command: its slot was kept when it was accepted. */
static void report(mc_primary_t *p, uint32_t j, uint8_t reg, uint8_t lseq, uint8_t result,
                   uint8_t tries)
{
    if (p->inflight)
        p->inflight--;
    if (mc_primary_qfree(p) == 0) {   /* cannot happen while the invariant holds */
        wide_inc(&p->ans_drop);
        return;
    }
    result_frame(p, j, reg, lseq, result, tries);
}

/* Room for an immediate answer (or an acceptance) that keeps a slot for every owed result? */
static int answer_room(const mc_primary_t *p, uint32_t extra)
{
    return mc_primary_qfree(p) >= (uint32_t)p->inflight + 1u + extra;
}

/* An immediate answer to a command frame: itself if it fits, else NO_ROOM, else counted. */
static void answer(mc_primary_t *p, uint32_t j, uint8_t reg, uint8_t lseq, uint8_t result)
{
    if (answer_room(p, 1)) {
        result_frame(p, j, reg, lseq, result, 0);
    } else if (answer_room(p, 0)) {
        wide_inc(&p->no_room);
        result_frame(p, j, reg, lseq, MC_RES_NO_ROOM, 0);
    } else {
        wide_inc(&p->ans_drop);
    }
}

static void reject(mc_primary_t *p, uint8_t reason, const mc_can_frame_t *f)
{
    uint8_t d[MC_CAN_PRIMARY_REJECT_DLC];
    p->reject_count++;
    d[MC_CAN_PRIMARY_REJECT_REASON] = reason;
    mc_put_u32(d + MC_CAN_PRIMARY_REJECT_BAD_ID, f->id);
    d[MC_CAN_PRIMARY_REJECT_BAD_DLC] = f->dlc;
    mc_put_u16(d + MC_CAN_PRIMARY_REJECT_COUNT, p->reject_count);
    if (answer_room(p, 0))
        put(p, MC_CAN_PRIMARY_REJECT, MC_CAN_PRIMARY_REJECT_DLC, d);
    else
        wide_inc(&p->ans_drop);
}

static void emit_status(mc_primary_t *p, uint32_t i)
{
    const mc_pcell_t *c = &p->cell[i];
    uint8_t d[8];
    if (c->seen) {
        mc_put_u16(d + MC_CAN_CELL_STATUS_FAULTS, c->last_faults);
        mc_put_u16(d + MC_CAN_CELL_STATUS_TICK_LO, (uint16_t)c->tick);
        d[MC_CAN_CELL_STATUS_REJECTED] = c->rejected;
        d[MC_CAN_CELL_STATUS_DEC_ERR_A] = c->dec_a;
        d[MC_CAN_CELL_STATUS_DEC_ERR_B] = c->dec_b;
        d[MC_CAN_CELL_STATUS_BUS_ERR] = c->bus_err;
        push(p, MC_CAN_CELL_STATUS + i + 1, MC_CAN_CELL_STATUS_DLC, d);
    }
}

static void emit_link(mc_primary_t *p, uint32_t i)
{
    const mc_pcell_t *c = &p->cell[i];
    uint8_t d[8];
    mc_put_u16(d + MC_CAN_CELL_LINK_NACK, c->nack);
    mc_put_u16(d + MC_CAN_CELL_LINK_INTEGRITY, c->integrity);
    mc_put_u16(d + MC_CAN_CELL_LINK_TIMEOUT, c->timeout);
    mc_put_u16(d + MC_CAN_CELL_LINK_SKIPPED, c->skipped);
    push(p, MC_CAN_CELL_LINK + i + 1, MC_CAN_CELL_LINK_DLC, d);
}

void mc_primary_can_rx(mc_primary_t *p, uint32_t now_us, const mc_can_frame_t *f)
{
    uint32_t id = f->id & MC_CAN_ID_MASK;
    if ((f->id & (MC_CAN_EFF | MC_CAN_RTR)) || f->dlc > 8) {
        reject(p, MC_RES_BAD_FRAME, f);
        return;
    }
    if (id < MC_CAN_CMD || id >= MC_CAN_CMD_RESULT) {
        reject(p, MC_RES_BAD_FRAME, f);   /* not a command id */
        return;
    }
    uint32_t j = id - MC_CAN_CMD;
    if (j < 1 || j > p->n_cells) {
        reject(p, MC_RES_NO_CELL, f);
        return;
    }
    mc_pcell_t *c = &p->cell[j - 1];
    uint8_t reg = f->dlc > 0 ? f->data[0] : 0;
    uint8_t lseq = f->dlc > 1 ? f->data[1] : 0;
    int plen = mc_proto_reg_len(reg);
    uint8_t res = 0;
    if (f->dlc < 2)
        res = MC_RES_BAD_FRAME;
    else if (plen < 0)
        res = MC_RES_REG;
    else if (f->dlc != (uint32_t)plen + 2 && f->dlc != 8)   /* exact, or DBC-padded to 8 */
        res = MC_RES_BAD_FRAME;
    else if (reg == MC_REG_POINTER && mc_proto_block_len(f->data[2 + MC_REG_POINTER_BLOCK]) < 0)
        res = MC_RES_RANGE;
    else if (c->cmd_state != MC_CMD_IDLE)
        res = MC_RES_BUSY;
    else if (!answer_room(p, 1))
        res = MC_RES_NO_ROOM;   /* accepting would leave no slot for its result */
    if (res) {
        p->reject_count++;
        answer(p, j, reg, lseq, res);
        return;
    }
    p->inflight++;
    c->cmd_reg = reg;
    c->cmd_lseq = lseq;
    c->cmd_len = (uint8_t)plen;
    for (int k = 0; k < plen; k++)
        c->cmd_payload[k] = f->data[2 + k];
    c->cmd_tries = 0;
    c->cmd_deadline = now_us + p->ack_timeout_us;
    c->cmd_state = MC_CMD_PENDING;
}

static void start(mc_primary_t *p, uint32_t now, mc_txn_t *t)
{
    t->timeout_us = p->txn_timeout_us;
    p->txn = *t;
    p->txn_start = now;
    p->busy = 1;
    p->txn_block = 0;
}

/* A failed step of a command: retry from the write, or report `res` after the retries. */
static void cmd_failed(mc_primary_t *p, mc_pcell_t *c, uint32_t j, uint8_t res)
{
    if (++c->cmd_tries > MC_SCHED_WRITE_RETRIES) {
        report(p, j, c->cmd_reg, c->cmd_lseq, res, c->cmd_tries);
        c->cmd_state = MC_CMD_IDLE;
    } else {
        c->cmd_state = MC_CMD_PENDING;
    }
}

/* Validate a block read for a POINTER command and send it as BLOCK_DATA chunks. */
static void block_done(mc_primary_t *p, mc_pcell_t *c, uint32_t j, int status, const uint8_t *rx,
                       uint32_t len)
{
    uint8_t blk = c->cmd_payload[MC_REG_POINTER_BLOCK];
    int n = mc_proto_block_len(blk);
    if (status == MC_I2C_NACK_ADDR || status == MC_I2C_NACK_DATA) {
        cmd_failed(p, c, j, MC_RES_NACK);
        return;
    }
    if (status != MC_I2C_OK) {
        cmd_failed(p, c, j, MC_RES_TIMEOUT);
        return;
    }
    if (n < 2 || len != (uint32_t)n || rx[0] != (uint8_t)((MC_PROTO_VERSION << 4) | blk) ||
        rx[1] != p->txn.addr || mc_crc8(rx, (uint32_t)n - 1) != rx[n - 1]) {
        c->integrity++;
        cmd_failed(p, c, j, MC_RES_CRC);
        return;
    }
    uint32_t chunks = 0;
    for (uint32_t off = 0; off < (uint32_t)n; off += 7)
        chunks++;
    if (mc_primary_qfree(p) < chunks + p->inflight) {
        report(p, j, c->cmd_reg, c->cmd_lseq, MC_RES_NO_ROOM, c->cmd_tries);   /* no room for the chunks */
        wide_inc(&p->no_room);
        c->cmd_state = MC_CMD_IDLE;
        return;
    }
    /* chunk k carries bytes 7k .. 7k+6: k = 0, 1, ... while 7k < n (no division) */
    uint32_t k = 0;
    for (uint32_t off = 0; off < (uint32_t)n; off += 7, k++) {
        uint8_t d[MC_CAN_BLOCK_DATA_DLC];
        d[MC_CAN_BLOCK_DATA_PART] = (uint8_t)((blk << 4) | k);
        for (uint32_t b = 0; b < 7; b++)
            d[MC_CAN_BLOCK_DATA_CHUNK + b] = off + b < (uint32_t)n ? rx[off + b] : 0;
        put(p, MC_CAN_BLOCK_DATA + j, MC_CAN_BLOCK_DATA_DLC, d);
    }
    report(p, j, c->cmd_reg, c->cmd_lseq, MC_RES_OK, c->cmd_tries);
    c->cmd_state = MC_CMD_IDLE;
}

static void heartbeat(mc_primary_t *p)
{
    if (p->ms - p->hb_ms < 1000u)
        return;
    p->hb_ms = (p->ms - p->hb_ms < 2000u) ? p->hb_ms + 1000u : p->ms;
    uint8_t d[8];
    mc_put_u32(d + MC_CAN_PRIMARY_STATUS_UPTIME_MS, p->ms);
    mc_put_u16(d + MC_CAN_PRIMARY_STATUS_CYCLES, p->cycles_window);
    d[MC_CAN_PRIMARY_STATUS_SLCAN_ERR] = (uint8_t)p->slcan_err;
    d[MC_CAN_PRIMARY_STATUS_TX_DROP] = (uint8_t)(p->tx_drop > 255u ? 255u : p->tx_drop);
    push(p, MC_CAN_PRIMARY_STATUS, MC_CAN_PRIMARY_STATUS_DLC, d);
    p->cycles_window = 0;
    d[MC_CAN_PRIMARY_HEALTH_RESET_CAUSE] = p->reset_cause;
    mc_put_u32(d + MC_CAN_PRIMARY_HEALTH_USB_LOST, p->usb_lost);
    mc_put_u16(d + MC_CAN_PRIMARY_HEALTH_BUS_RESET, p->bus_reset);
    d[MC_CAN_PRIMARY_HEALTH_USB_FAIL] = p->usb_fail;
    push(p, MC_CAN_PRIMARY_HEALTH, MC_CAN_PRIMARY_HEALTH_DLC, d);
}

void mc_primary_usb_lost(mc_primary_t *p, uint32_t n)
{
    p->usb_lost = n > 0xFFFFFFFFu - p->usb_lost ? 0xFFFFFFFFu : p->usb_lost + n;
    p->usb_fail++;
}

void mc_primary_usb_write(mc_primary_t *p, uint32_t n, int taken)
{
    if (taken) {
        p->usb_pending = n;   /* and the one before it has left */
        return;
    }
    uint32_t pending = p->usb_pending;
    p->usb_pending = 0;
    mc_primary_usb_lost(p, n);
    if (pending)
        p->usb_lost = pending > 0xFFFFFFFFu - p->usb_lost ? 0xFFFFFFFFu : p->usb_lost + pending;
}

uint32_t mc_primary_progress(const mc_primary_t *p) { return p->progress; }

void mc_primary_bus_reset(mc_primary_t *p) { p->bus_reset++; }
void mc_primary_set_reset_cause(mc_primary_t *p, uint8_t cause) { p->reset_cause = cause; }

int mc_primary_next(mc_primary_t *p, uint32_t now, mc_txn_t *t)
{
    mc_primary_ms(p, now);
    if (p->busy)
        return 0;
    heartbeat(p);
    /* command deadlines */
    for (uint32_t i = 0; i < p->n_cells; i++) {
        mc_pcell_t *c = &p->cell[i];
        if (c->cmd_state != MC_CMD_IDLE && due(now, c->cmd_deadline)) {
            uint8_t r = (c->cmd_state == MC_CMD_PENDING && c->nack_streak) ? MC_RES_NACK
                                                                             : MC_RES_TIMEOUT;
            report(p, i + 1, c->cmd_reg, c->cmd_lseq, r, c->cmd_tries);
            c->cmd_state = MC_CMD_IDLE;
        }
    }
    /* a block read right after its POINTER write (nothing may move the pointer between) */
    for (uint32_t i = 0; i < p->n_cells; i++) {
        mc_pcell_t *c = &p->cell[i];
        if (c->cmd_state != MC_CMD_READBLK)
            continue;
        t->kind = MC_TXN_READ;
        t->cell = (uint8_t)i;
        t->addr = (uint8_t)(MC_ADDR_BASE + i);
        t->len = (uint8_t)mc_proto_block_len(c->cmd_payload[MC_REG_POINTER_BLOCK]);
        start(p, now, t);
        p->txn_block = 1;
        return 1;
    }
    /* pending writes next: S addr+W reg seq payload crc P */
    for (uint32_t i = 0; i < p->n_cells; i++) {
        mc_pcell_t *c = &p->cell[i];
        if (c->cmd_state != MC_CMD_PENDING || !c->seen)
            continue;
        uint8_t w = (uint8_t)(c->cell_seq + 1u);
        if (w == 0)
            w = 1;   /* 0 means "no write yet" in the snapshot */
        c->cmd_wseq = w;
        t->kind = MC_TXN_WRITE;
        t->cell = (uint8_t)i;
        t->addr = (uint8_t)(MC_ADDR_BASE + i);
        t->len = (uint8_t)(c->cmd_len + MC_WRITE_OVERHEAD);
        t->buf[0] = c->cmd_reg;
        t->buf[1] = w;
        for (uint32_t k = 0; k < c->cmd_len; k++)
            t->buf[2 + k] = c->cmd_payload[k];
        uint8_t hdr = (uint8_t)(t->addr << 1);
        t->buf[t->len - 1] = mc_crc8_update(mc_crc8(&hdr, 1), t->buf, t->len - 1u);
        start(p, now, t);
        return 1;
    }
    /* round-robin snapshot reads */
    if (!p->in_cycle) {
        if (p->started && !due(now, p->cycle_start + p->period_us)) {
            p->progress++;   /* idle by design until the period is up */
            return 0;
        }
        /* keep the period's phase unless more than one period behind */
        if (p->started && p->period_us && !due(now, p->cycle_start + 2 * p->period_us))
            p->cycle_start += p->period_us;
        else
            p->cycle_start = now;
        p->started = 1;
        p->in_cycle = 1;
        p->next = 0;
    }
    while (p->next < p->n_cells) {
        uint32_t i = p->next++;
        mc_pcell_t *c = &p->cell[i];
        c->seq++;
        if (c->backoff) {
            c->backoff--;
            c->skipped++;
            continue;
        }
        t->kind = MC_TXN_READ;
        t->cell = (uint8_t)i;
        t->addr = (uint8_t)(MC_ADDR_BASE + i);
        t->len = MC_BLK_SNAPSHOT_LEN;
        start(p, now, t);
        return 1;
    }
    /* end of cycle: status and link frames of one cell per cycle, in rotation */
    p->in_cycle = 0;
    p->cycles++;
    p->progress++;
    p->cycles_window++;
    if (p->status_ctr < p->n_cells) {
        emit_status(p, p->status_ctr);
        emit_link(p, p->status_ctr);
    }
    if (++p->status_ctr >= p->status_every)
        p->status_ctr = 0;
    return 0;
}

static void back_off(mc_pcell_t *c)
{
    uint32_t n = c->backoff_len ? 2u * c->backoff_len : 1u;
    if (n > MC_SCHED_BACKOFF_MAX)
        n = MC_SCHED_BACKOFF_MAX;
    c->backoff_len = (uint8_t)n;
    c->backoff = (uint8_t)n;
}

void mc_primary_complete(mc_primary_t *p, uint32_t now, int status, const uint8_t *rx,
                         uint32_t len)
{
    if (!p->busy)
        return;
    p->busy = 0;
    p->progress++;
    mc_pcell_t *c = &p->cell[p->txn.cell];
    uint32_t j = p->txn.cell + 1u;
    if (status == MC_I2C_OK && now - p->txn_start > p->txn.timeout_us)
        status = MC_I2C_TIMEOUT;   /* late: treat as timed out, data may be stale */
    if (status == MC_I2C_NACK_ADDR || status == MC_I2C_NACK_DATA) {
        c->nack++;
        if (c->nack_streak < 255)
            c->nack_streak++;
    } else if (status != MC_I2C_OK) {
        c->timeout++;
        back_off(c);
    }
    if (p->txn.kind == MC_TXN_WRITE) {
        if (c->cmd_state != MC_CMD_PENDING)
            return;
        if (status == MC_I2C_OK) {
            c->cmd_state = c->cmd_reg == MC_REG_POINTER ? MC_CMD_READBLK : MC_CMD_AWAIT;
            c->nack_streak = 0;
        } else {
            cmd_failed(p, c, j, status == MC_I2C_NACK_ADDR || status == MC_I2C_NACK_DATA
                                    ? MC_RES_NACK : MC_RES_TIMEOUT);
        }
        return;
    }
    if (p->txn_block) {
        if (c->cmd_state == MC_CMD_READBLK)
            block_done(p, c, j, status, rx, len);
        return;
    }
    if (status != MC_I2C_OK)
        return;
    /* integrity: length, tag, address, CRC (an all-0xFF read fails the tag) */
    if (len != MC_BLK_SNAPSHOT_LEN || rx[MC_SNAPSHOT_TAG] != MC_BLK_SNAPSHOT_TAG ||
        rx[MC_SNAPSHOT_ADDR] != p->txn.addr ||
        mc_crc8(rx, MC_BLK_SNAPSHOT_LEN - 1) != rx[MC_SNAPSHOT_CRC]) {
        c->integrity++;
        return;
    }
    c->nack_streak = 0;
    c->backoff_len = 0;
    c->seen = 1;
    c->cell_seq = rx[MC_SNAPSHOT_CMD_SEQ];
    c->alpha = (int16_t)mc_get_i16(rx + MC_SNAPSHOT_ALPHA);
    c->beta = (int16_t)mc_get_i16(rx + MC_SNAPSHOT_BETA);
    c->tick = mc_get_u32(rx + MC_SNAPSHOT_TICK);
    c->rejected = rx[MC_SNAPSHOT_REJECTED];
    c->dec_a = rx[MC_SNAPSHOT_DEC_ERR_A];
    c->dec_b = rx[MC_SNAPSHOT_DEC_ERR_B];
    c->bus_err = rx[MC_SNAPSHOT_BUS_ERR];
    uint8_t flags = rx[MC_SNAPSHOT_FLAGS];
    uint16_t faults = mc_get_u16(rx + MC_SNAPSHOT_FAULTS);

    uint8_t d[8];
    d[MC_CAN_CELL_SAMPLE_SEQ] = c->seq;
    d[MC_CAN_CELL_SAMPLE_ALPHA] = rx[MC_SNAPSHOT_ALPHA];
    d[MC_CAN_CELL_SAMPLE_ALPHA + 1] = rx[MC_SNAPSHOT_ALPHA + 1];
    d[MC_CAN_CELL_SAMPLE_BETA] = rx[MC_SNAPSHOT_BETA];
    d[MC_CAN_CELL_SAMPLE_BETA + 1] = rx[MC_SNAPSHOT_BETA + 1];
    mc_put_u16(d + MC_CAN_CELL_SAMPLE_T128, (uint16_t)(now >> 7));   /* 128 us units */
    d[MC_CAN_CELL_SAMPLE_FLAGS] = flags;
    push(p, MC_CAN_CELL_SAMPLE + j, MC_CAN_CELL_SAMPLE_DLC, d);

    if (c->cmd_state == MC_CMD_AWAIT && c->cell_seq == c->cmd_wseq) {
        report(p, j, c->cmd_reg, c->cmd_lseq, rx[MC_SNAPSHOT_CMD_RESULT], c->cmd_tries);
        c->cmd_state = MC_CMD_IDLE;
    }
    /* status frame at once when faults or the steady flags change */
    uint8_t steady = (uint8_t)(flags & (MC_CF_ENABLED | MC_CF_BEMF | MC_CF_FAULT));
    if (faults != c->last_faults || steady != c->last_flags) {
        c->last_faults = faults;
        c->last_flags = steady;
        emit_status(p, p->txn.cell);
    }
}

/* Drop every queued frame (counted in stale_drop): they were meant for an earlier client. */
static void drop_queue(mc_primary_t *p)
{
    while (p->q_tail != p->q_head) {
        p->q_tail = (uint8_t)((p->q_tail + 1u) & QMASK);
        wide_inc(&p->stale_drop);
    }
}

void mc_link_session(mc_link_t *l)
{
    l->s.open = 0;
    l->s.listen_only = 0;
    l->s.len = 0;
    l->s.bad = 0;
    drop_queue(&l->p);
}

void mc_link_init(mc_link_t *l, uint32_t now_us)
{
    mc_primary_init(&l->p, now_us);
    mc_slcan_init(&l->s);
}

uint32_t mc_link_rx(mc_link_t *l, uint32_t now_us, const uint8_t *in, uint32_t n,
                    uint32_t *used, char *out, uint32_t cap)
{
    uint32_t o = 0, k = 0;
    for (; k < n && cap - o >= MC_SLCAN_REPLY_MAX; k++) {
        mc_can_frame_t f;
        char reply[MC_SLCAN_REPLY_MAX];
        uint8_t was_open = l->s.open;
        int ev = mc_slcan_rx(&l->s, in[k], &f, reply);
        if (l->s.open && !was_open)
            drop_queue(&l->p);   /* frames queued before the open are stale */
        if (ev == MC_SLCAN_EV_FRAME)
            mc_primary_can_rx(&l->p, now_us, &f);
        for (uint32_t r = 0; reply[r]; r++)
            out[o++] = reply[r];
    }
    l->p.slcan_err = l->s.errors;
    if (used)
        *used = k;
    return o;
}

uint32_t mc_link_tx(mc_link_t *l, uint32_t now_us, char *out, uint32_t cap)
{
    uint32_t o = 0;
    mc_can_frame_t f;
    uint32_t ms = mc_primary_ms(&l->p, now_us);
    while (l->p.q_tail != l->p.q_head) {
        if (l->s.open && cap - o < MC_SLCAN_FRAME_MAX)
            break;
        mc_primary_pop(&l->p, &f);
        if (l->s.open)
            o += mc_slcan_encode(&l->s, &f, ms, out + o);
    }
    return o;
}
