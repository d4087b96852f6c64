/* Cell side of the I2C link: register writes (CRC-8, applied at a tick boundary) and consistent read blocks. */
#ifndef MC_REGS_H
#define MC_REGS_H

#include <stdint.h>
#include "mc_proto.h"
#include "../mc_cell.h"

/*
 * Transactions (docs/datapath.md), designed around the SAMD21 Wire quirks:
 *   write: S addr+W reg seq payload crc8 P   -> mc_regs_on_receive() (ISR)
 *   read:  S addr+R block... crc8 P          -> mc_regs_on_request() (ISR)
 * No repeated start is needed: the read pointer defaults to the SNAPSHOT block
 * and returns to it after every read, so a poll is a single read. onReceive(0)
 * (sent by the core after a read ending in STOP) is ignored. If a primary does
 * use write-then-repeated-start-read, onRequest runs first and returns the old
 * pointer's block: its tag byte tells the primary which block it got.
 *
 * Concurrency: the ISR only (a) copies a write into a one-slot mailbox,
 * (b) sets the read pointer (CRC-checked POINTER writes) and (c) copies the
 * published block into the transmit buffer. Everything else runs in
 * mc_regs_tick() in the control loop:
 *   1. apply the mailbox write (validate CRC, register, length, range; apply via
 *      the mc_cell_* setters, which leave the cell unchanged on error);
 *   2. mc_cell_tick() with the decoder snapshots of this tick;
 *   3. publish the snapshot of this tick into the idle half of a double buffer
 *      and flip the index (one byte store), so a read never mixes ticks.
 */
typedef struct {
    uint8_t addr;                        /* 7-bit address */
    volatile uint8_t ptr;                /* MC_BLK_* for the next read */
    volatile uint8_t rx_full;            /* mailbox holds a write */
    volatile uint8_t rx_len;             /* received length (clipped to 255) */
    volatile uint8_t rx[MC_WRITE_MAX_LEN];
    volatile uint16_t bus_err;           /* bad POINTER writes, writes dropped (mailbox full) */
    volatile uint8_t snap_idx;           /* published half of snap[] */
    volatile uint8_t params_idx;
    uint8_t snap[2][MC_BLK_SNAPSHOT_LEN];
    uint8_t params[2][MC_BLK_PARAMS_LEN];
    uint8_t ident[MC_BLK_IDENT_LEN];
    uint8_t boot[MC_BLK_BOOT_LEN];       /* BOOT block: reset cause, watchdog, fault (mc_regs_set_boot) */
    mc_reaction_phys_t phys;             /* parameters in force (last accepted) */
    uint8_t last_seq;                    /* seq of the last write processed */
    uint8_t last_result;                 /* MC_RES_* of it */
    uint8_t rejected;                    /* rejected writes (wraps) */
} mc_regs_t;

/* phys: the parameters the cell runs with (NULL: mc_cell_default_params).
 * Returns MC_ERR_RANGE for an address outside 0x08..0x77. */
int mc_regs_init(mc_regs_t *r, const mc_cell_t *c, uint8_t addr, uint32_t build,
                 const mc_reaction_phys_t *phys);
/* Fill the BOOT block: reset_cause = MC_RCAUSE_* bits read at boot, wdt_ms = watchdog
 * timeout in force (0 = off), fault_exc / fault_pc = exception number and stacked PC of the
 * fault that reset the cell (MC_RCAUSE_FAULT; 0 / 0 otherwise). Call after mc_regs_init,
 * before the bus starts. */
void mc_regs_set_boot(mc_regs_t *r, uint8_t reset_cause, uint16_t wdt_ms, uint8_t fault_exc,
                      uint32_t fault_pc);
/* ISR: a write of len bytes ended (len 0 is ignored). */
void mc_regs_on_receive(mc_regs_t *r, const uint8_t *data, uint32_t len);
/* ISR: a read started; fills out[0..cap) and returns the byte count. */
uint32_t mc_regs_on_request(mc_regs_t *r, uint8_t *out, uint32_t cap);
/* Control loop, once per tick: apply pending write, tick the cell, publish.
 * Same as mc_regs_apply(); f = mc_cell_tick(); mc_regs_publish(). */
uint16_t mc_regs_tick(mc_regs_t *r, mc_cell_t *c, const mc_quad_snap_t *a,
                      const mc_quad_snap_t *b);

/* The two halves of mc_regs_tick, for a loop that ticks the cell itself (the
 * emulator's compiled plant loop): apply before the tick, publish after it. */
void mc_regs_apply(mc_regs_t *r, mc_cell_t *c, const mc_quad_snap_t *a, const mc_quad_snap_t *b);
void mc_regs_publish(mc_regs_t *r, const mc_cell_t *c, const mc_quad_snap_t *a,
                     const mc_quad_snap_t *b);

#endif /* MC_REGS_H */
