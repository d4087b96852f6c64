/* Primary side: round-robin poll scheduler with per-transaction timeouts, command forwarding, CAN frames for the laptop. */
#ifndef MC_PRIMARY_H
#define MC_PRIMARY_H

#include <stdint.h>
#include "mc_proto.h"
#include "mc_slcan.h"

/*
 * Time is passed in (now_us, a free-running 32-bit microsecond clock; all
 * comparisons are on differences modulo 2^32). The I2C transport (Arduino Wire
 * glue or the emulator's bus model) asks mc_primary_next() for the transaction
 * to run, runs it, and reports with mc_primary_complete(). The transport must
 * abort a transaction at txn.timeout_us; the library also treats a completion
 * reported later than that as a timeout (the data may be stale).
 *
 * Schedule: a cycle polls cells 1..n_cells in order with one SNAPSHOT read each
 * (n_cells = MC_N_CELLS, the rig as built, unless mc_primary_set_cells names up to
 * MC_MAX_CELLS for a sheet: the poll order of cells 1..16 is the same either way);
 * cycles start every period_us (0: back to back). Pending command writes go
 * first. A cell that times out is skipped for a back-off of 1, 2, 4 .. BACKOFF_MAX
 * cycles (reset by its next good read); a NACK costs one address byte and is
 * not backed off. So a missing, stuck or babbling cell costs at most one
 * timeout per back-off period and never stalls the others.
 *
 * Per cell, every cycle slot advances a sequence counter; a good read emits
 * CELL_SAMPLE with it, so the laptop sees failed polls and lost frames as gaps.
 *
 * Commands: one per cell in flight. A register write is acknowledged through the
 * cell's snapshot (cmd_seq, cmd_result). A POINTER command reads a block back: the
 * pointer write is followed at once by the block read (before any other transaction),
 * the block is checked (length, tag, address, CRC) and sent as BLOCK_DATA frames.
 */
#define MC_PRIMARY_QLEN 128       /* outgoing CAN frames (power of two, <= 128) */
/*
 * Queue room: sample, status, link, heartbeat and block frames are queued only
 * while more than n_cells + 2 slots are free (MC_PRIMARY_QRESERVE for the rig as
 * built); the reserve belongs to command answers. A command is accepted (or answered BUSY/RANGE/...) only if the
 * queue keeps a slot for every result still owed plus this answer; otherwise it
 * is answered NO_ROOM; and only when not even that fits is the answer dropped,
 * counted in ans_drop. So the result of an accepted command is never dropped.
 * Dropped data frames count in tx_drop (32-bit; the heartbeat carries it
 * saturated at 255).
 *
 * Sessions: the channel opens with O/L and closes with C. When the parser opens
 * the channel, frames still queued (stale, from before the open) are dropped.
 * mc_link_session() starts a new host session: it closes the channel and drops
 * the queued frames and any half-received line; the glue calls it whenever the
 * host opens or closes the port (USB DTR edge), the emulator when its pty's
 * client comes or goes, so a client that died without C leaves nothing behind.
 */
#define MC_PRIMARY_QRESERVE (MC_N_CELLS + 2)   /* of the rig as built; n_cells + 2 in general */

enum { MC_TXN_READ = 0, MC_TXN_WRITE = 1 };
enum {
    MC_I2C_OK = 0,
    MC_I2C_NACK_ADDR = 1,   /* no cell answered its address */
    MC_I2C_NACK_DATA = 2,   /* a data byte of a write was not acknowledged */
    MC_I2C_TIMEOUT = 3,     /* transport gave up at the deadline (stuck bus) */
    MC_I2C_BUS_ERROR = 4,   /* arbitration lost / bus error */
};
enum { MC_CMD_IDLE = 0, MC_CMD_PENDING = 1, MC_CMD_AWAIT = 2, MC_CMD_READBLK = 3 };

typedef struct {
    uint8_t kind;          /* MC_TXN_READ / MC_TXN_WRITE */
    uint8_t addr;          /* 7-bit */
    uint8_t cell;          /* index 0..n_cells-1 */
    uint8_t len;           /* bytes to read / write */
    uint8_t buf[MC_WRITE_MAX_LEN];   /* write bytes */
    uint32_t timeout_us;
} mc_txn_t;

typedef struct {
    uint16_t nack, integrity, timeout, skipped;   /* link counters (wrap) */
    uint8_t seq;            /* cycle-slot counter */
    uint8_t backoff;        /* cycles still to skip */
    uint8_t backoff_len;    /* next back-off length */
    uint8_t nack_streak;    /* consecutive NACKs */
    uint8_t seen;           /* a good snapshot was read */
    uint8_t cell_seq;       /* cmd_seq of the last good snapshot */
    uint8_t last_flags;
    uint16_t last_faults;
    uint8_t rejected, dec_a, dec_b, bus_err;   /* low bytes of the cell counters */
    /* command slot */
    uint8_t cmd_state;
    uint8_t cmd_reg, cmd_lseq, cmd_wseq, cmd_len, cmd_tries;
    uint8_t cmd_payload[MC_REG_MAX_PAYLOAD];
    uint32_t cmd_deadline;
    /* last sample (for tools and tests) */
    int16_t alpha, beta;
    uint32_t tick;
} mc_pcell_t;

typedef struct {
    mc_pcell_t cell[MC_MAX_CELLS];
    uint8_t n_cells;          /* cells polled: 1..n_cells (MC_N_CELLS after init) */
    uint32_t period_us, txn_timeout_us, ack_timeout_us;
    uint32_t status_every, status_ctr;
    /* schedule */
    uint8_t in_cycle, next, busy, started;
    uint8_t txn_block;        /* the transaction in flight reads a block for a POINTER command */
    uint32_t cycle_start;
    mc_txn_t txn;
    uint32_t txn_start;
    uint32_t cycles;          /* completed cycles */
    uint32_t progress;        /* schedule steps: transactions completed, cycles ended, waits for the period */
    uint16_t cycles_window;   /* cycles since the last heartbeat */
    uint16_t reject_count;
    /* millisecond clock, kept without division */
    uint32_t last_us, ms, us_rem, hb_ms;
    /* outgoing frames */
    mc_can_frame_t q[MC_PRIMARY_QLEN];
    uint8_t q_head, q_tail;
    uint8_t inflight;         /* accepted commands whose result is still owed */
    uint32_t tx_drop;         /* data frames dropped for want of queue room */
    uint32_t no_room;         /* commands answered NO_ROOM */
    uint32_t ans_drop;        /* command answers dropped (queue full even for NO_ROOM) */
    uint32_t stale_drop;      /* queued frames dropped at a channel open or a new session */
    uint16_t slcan_err;       /* copied in by the link */
    /* health (PRIMARY_HEALTH frame, once a second after the heartbeat), reported by the glue */
    uint32_t usb_lost;        /* SLCAN output bytes the USB port did not take (saturates) */
    uint32_t usb_pending;     /* bytes of the last write the port took, not yet known to have left */
    uint16_t bus_reset;       /* I2C bus recoveries (wraps) */
    uint8_t usb_fail;         /* failed USB writes (wraps) */
    uint8_t reset_cause;      /* MC_RCAUSE_* bits read at boot */
} mc_primary_t;

void mc_primary_init(mc_primary_t *p, uint32_t now_us);
/* period_us: cycle period (0 = as fast as the bus allows, <= 10 s);
 * txn_timeout_us 100..100000; ack_timeout_us 1000..10000000; status_every 16..65535 and >= n_cells. */
int mc_primary_configure(mc_primary_t *p, uint32_t period_us, uint32_t txn_timeout_us,
                         uint32_t ack_timeout_us, uint32_t status_every);
/* Poll cells 1..n (1 <= n <= MC_MAX_CELLS, n <= status_every so every cell's status comes round):
 * before the first mc_primary_next only. Returns 0, or -1 (nothing changed) otherwise. Commands to
 * a cell above n are answered NO_CELL. */
int mc_primary_set_cells(mc_primary_t *p, uint32_t n);
/* The transaction to start now, if any (returns 1 and fills *t). */
int mc_primary_next(mc_primary_t *p, uint32_t now_us, mc_txn_t *t);
/* Report the end of the transaction started by mc_primary_next. */
void mc_primary_complete(mc_primary_t *p, uint32_t now_us, int status, const uint8_t *rx,
                         uint32_t len);
/* Steps the schedule has made (wraps): a transaction completed, a cycle ended, or a call of
 * mc_primary_next() that found the next cycle not yet due. It stands still while a transaction
 * is in flight and never completed, or while the glue stops calling the scheduler: the primary's
 * watchdog is fed only when it has moved. */
uint32_t mc_primary_progress(const mc_primary_t *p);
/* A frame from the laptop (commands); everything else is rejected and reported. */
void mc_primary_can_rx(mc_primary_t *p, uint32_t now_us, const mc_can_frame_t *f);
/* Pop one outgoing frame; 0 when the queue is empty. */
int mc_primary_pop(mc_primary_t *p, mc_can_frame_t *f);
uint32_t mc_primary_ms(mc_primary_t *p, uint32_t now_us);
/* Health the glue reports (sent in PRIMARY_HEALTH): n bytes of output the USB port did not
 * take (one failed write), one I2C bus recovery, the reset cause read at boot. */
void mc_primary_usb_lost(mc_primary_t *p, uint32_t n);
/*
 * One write of n bytes to the USB port (at most one 64-byte packet), taken = it reported all
 * n. A port like the SAMD21 core's (USBCore.cpp send) arms a packet and returns; the packet
 * leaves when the host reads it, and the next write waits for that first. When that wait
 * times out, the core zeroes the byte count of the packet still armed: the *previous* write,
 * reported taken, never arrives either. So a taken write stays pending until the next taken
 * one proves it left; a failed write counts its own n and the pending bytes as lost.
 */
void mc_primary_usb_write(mc_primary_t *p, uint32_t n, int taken);
void mc_primary_bus_reset(mc_primary_t *p);
void mc_primary_set_reset_cause(mc_primary_t *p, uint8_t cause);

/* ---- the primary as an SLCAN device: parser + scheduler + encoder ---- */
typedef struct {
    mc_primary_t p;
    mc_slcan_t s;
} mc_link_t;

void mc_link_init(mc_link_t *l, uint32_t now_us);
/* Bytes from the laptop; replies are written to out (returns their length).
 * cap >= MC_SLCAN_REPLY_MAX; input beyond what the replies fit is left unread:
 * *used tells how many bytes were consumed. */
uint32_t mc_link_rx(mc_link_t *l, uint32_t now_us, const uint8_t *in, uint32_t n,
                    uint32_t *used, char *out, uint32_t cap);
/* Encode queued frames into out (whole lines only); with the channel closed the
 * queue is emptied without output. Returns the byte count. */
uint32_t mc_link_tx(mc_link_t *l, uint32_t now_us, char *out, uint32_t cap);
/* A new host session (port opened or closed by the host): channel closed, queued
 * frames and any half-received line dropped. */
void mc_link_session(mc_link_t *l);
/* Free slots in the outgoing queue. */
uint32_t mc_primary_qfree(const mc_primary_t *p);

#endif /* MC_PRIMARY_H */
