/* Primary hardware layer: bounded I2C master transactions on SERCOM2, open-drain bus recovery, micros(). */
#include <Arduino.h>
#include <Wire.h>
#include "primary_hw.h"

/*
 * Every wait here is bounded. The core's Wire master (1.8.5) waits on MB/SB alone:
 * after a bus error or lost arbitration while reading, SB never comes and
 * requestFrom() never returns (only the write path checks BUSERR). So Wire is used
 * only to set up SERCOM2 (clock, pins, baud); each transaction drives the I2CM
 * registers itself, and every wait (MB/SB, SYNCBUSY) ends at the transaction's
 * deadline, txn.timeout_us after its start, or at a bus error / lost arbitration.
 *   - SERCOM2's own SMBus timeouts stay off. The SCL low timeout (LOWTOUTEN, 25-35 ms)
 *     counts on GCLK_SERCOMx_SLOW, which nothing here clocks, so it could never fire; and
 *     the deadline above ends a stuck transaction 17x sooner. The inactive-bus timeout
 *     (INACTOUT) sets the bus state to idle when SCL stays low for 5-6, 10-11 or 20-21 SCL
 *     periods (at most ~53 us at 400 kHz), and a cell legitimately stretches SCL longer
 *     while its tick and encoder interrupts run (up to 482 us with its I2C handler by
 *     `fwcheck cpu-budget` on a cell image): the master would take the bus for idle in
 *     the middle of a transaction. A bus left busy is recovered below instead;
 *   - a transaction that fails with a timeout or a bus error ends with a STOP when
 *     the primary owns the bus; a bus still not idle is recovered at once (9 SCL
 *     pulses, open-drain, then a STOP) and the recovery counted (PRIMARY_HEALTH);
 *   - the library counts the timeout and backs the cell off 1, 2, 4 .. 64 cycles.
 * So a stuck or babbling cell costs at most txn.timeout_us + one recovery (~0.2 ms)
 * per back-off period, and the main loop never stops long enough for the watchdog.
 * Writes always end with STOP and reads are separate transactions (no repeated start).
 */
static uint32_t g_hz;
static uint32_t g_t0, g_limit;   /* deadline of the transaction in progress */
static uint32_t g_recoveries;    /* bus recoveries (primary_hw_bus_resets) */

#define I2CM (SERCOM2->I2CM)
#define BUSSTATE_IDLE 1u
#define BUSSTATE_OWNER 2u
#define CMD_READ_MORE 2u   /* acknowledge action, then read one more byte */
#define CMD_STOP 3u        /* acknowledge action, then STOP */
#define SYNC_US 50u        /* bound of a SYNCBUSY wait outside a transaction */

static int expired(void) { return (uint32_t)(micros() - g_t0) > g_limit; }

/* Wait for SYNCBUSY.SYSOP to clear until the deadline; 0 when it did. */
static int sync_sysop(void)
{
    while (I2CM.SYNCBUSY.bit.SYSOP) {
        if (expired())
            return -1;
    }
    return 0;
}

static void deadline(uint32_t us)
{
    g_t0 = micros();
    g_limit = us;
}

/*
 * SCL timing (docs/hardware.md, "Bus timing"). The core computes BAUD = 48 MHz / (2 f) - 5 - 3
 * with BAUDLOW = 0: at 400 kHz BAUD 52, an SCL low time of (52 + 5) / 48 MHz = 1.19 us, under
 * Fast-mode's 1.3 us. Per DS40001882, T_LOW = (BAUDLOW + 5) / f_GCLK, T_HIGH = (BAUD + 5) /
 * f_GCLK, and the period adds the rise time: f_SCL = f_GCLK / (10 + BAUD + BAUDLOW +
 * f_GCLK t_r). Here BAUD + BAUDLOW + 10 = 48 MHz / f, so f_SCL <= f for any rise time, and
 * T_LOW, T_HIGH clear the spec's minimum with the rest:
 *   400 kHz: BAUDLOW 62 (T_LOW 1.396 us >= 1.3), BAUD 48 (T_HIGH 1.104 us >= 0.6)
 *   100 kHz: BAUDLOW 226 (4.813 us >= 4.7), BAUD 244 (5.188 us >= 4.0)
 * Other rates keep the core's value.
 */
struct scl_timing {
    uint32_t hz;
    uint8_t baud, baudlow;
};
static const scl_timing k_scl[] = {{400000, 48, 62}, {100000, 244, 226}};
/* SDA hold 300-600 ns after SCL falls (the default of Atmel's ASF I2C secondary driver): it
 * bridges a slow SCL fall on a long bus, where 0 could change SDA while a receiver still
 * sees SCL high (a false START or STOP). */
#define SDAHOLD_300_600NS 2u

/* CTRLA and BAUD fields the core's Wire leaves at its defaults, set while SERCOM2 is disabled. */
static void sercom_setup(void)
{
    deadline(SYNC_US);
    I2CM.CTRLA.bit.ENABLE = 0;
    while (I2CM.SYNCBUSY.bit.ENABLE && !expired()) {
    }
    I2CM.CTRLA.bit.LOWTOUTEN = 0;   /* no slow clock: it could never fire (see above) */
    I2CM.CTRLA.bit.INACTOUT = 0;    /* shorter than a cell's clock stretch (see above) */
    I2CM.CTRLA.bit.SDAHOLD = SDAHOLD_300_600NS;
    for (unsigned i = 0; i < sizeof(k_scl) / sizeof(k_scl[0]); i++)
        if (k_scl[i].hz == g_hz)
            I2CM.BAUD.reg = SERCOM_I2CM_BAUD_BAUD(k_scl[i].baud) |
                            SERCOM_I2CM_BAUD_BAUDLOW(k_scl[i].baudlow);
    I2CM.CTRLA.bit.ENABLE = 1;
    deadline(SYNC_US);
    while (I2CM.SYNCBUSY.bit.ENABLE && !expired()) {
    }
    I2CM.STATUS.bit.BUSSTATE = BUSSTATE_IDLE;   /* force idle */
    deadline(SYNC_US);
    sync_sysop();
}

void primary_hw_begin(uint32_t hz)
{
    g_hz = hz;
    Wire.begin();
    Wire.setClock(hz);
    sercom_setup();
}

/* SCL / SDA as open-drain lines: low = output driving 0; released = input with pull-up.
 * digitalWrite(LOW) on an input clears OUT (and the pull) before the pin becomes an
 * output, so a line is never driven high. */
static void line_low(uint32_t pin)
{
    digitalWrite(pin, LOW);
    pinMode(pin, OUTPUT);
}

static void line_release(uint32_t pin) { pinMode(pin, INPUT_PULLUP); }

/* 9 clock pulses with SDA released free a secondary stuck mid-byte (it sees its byte end
 * and a NACK); then a STOP (SDA rising while SCL is high) resets every secondary's bus
 * state machine; then SERCOM2 is set up again. ~0.2 ms at 5 us half periods. */
static void bus_recover(void)
{
    Wire.end();
    line_release(PIN_WIRE_SDA);
    line_release(PIN_WIRE_SCL);
    delayMicroseconds(5);
    for (int i = 0; i < 9; i++) {
        line_low(PIN_WIRE_SCL);
        delayMicroseconds(5);
        line_release(PIN_WIRE_SCL);
        delayMicroseconds(5);
    }
    /* STOP: SDA low while SCL is low, SCL up, then SDA up */
    line_low(PIN_WIRE_SCL);
    delayMicroseconds(5);
    line_low(PIN_WIRE_SDA);
    delayMicroseconds(5);
    line_release(PIN_WIRE_SCL);
    delayMicroseconds(5);
    line_release(PIN_WIRE_SDA);
    delayMicroseconds(5);
    g_recoveries++;
    primary_hw_begin(g_hz);
}

static int bus_fault(void)
{
    return (I2CM.STATUS.reg & (SERCOM_I2CM_STATUS_BUSERR | SERCOM_I2CM_STATUS_ARBLOST)) != 0;
}

/* Wait for MB or SB. MC_I2C_OK, MC_I2C_BUS_ERROR (bus error, lost arbitration) or
 * MC_I2C_TIMEOUT (deadline). */
static int wait_bus(void)
{
    for (;;) {
        if (expired())
            return MC_I2C_TIMEOUT;
        if (bus_fault())
            return MC_I2C_BUS_ERROR;
        if (I2CM.INTFLAG.reg & (SERCOM_I2CM_INTFLAG_MB | SERCOM_I2CM_INTFLAG_SB))
            return bus_fault() ? MC_I2C_BUS_ERROR : MC_I2C_OK;
    }
}

/* Issue a command (CTRLB.CMD) with ACKACT = nack; sync bounded by the deadline. */
static int command(uint32_t cmd, uint32_t nack)
{
    I2CM.CTRLB.reg = (I2CM.CTRLB.reg & ~(SERCOM_I2CM_CTRLB_CMD_Msk | SERCOM_I2CM_CTRLB_ACKACT)) |
                     SERCOM_I2CM_CTRLB_CMD(cmd) | (nack ? SERCOM_I2CM_CTRLB_ACKACT : 0u);
    return sync_sysop();
}

/* End a transaction: STOP if the primary still owns the bus; a failed one that leaves
 * the bus not idle (held, unknown, lost), an error flag set or SERCOM2 unsynchronised
 * is recovered (SERCOM2 reset included). */
static int finish(int st)
{
    if (I2CM.STATUS.bit.BUSSTATE == BUSSTATE_OWNER) {
        deadline(SYNC_US);   /* room for the STOP even after the transaction's deadline */
        command(CMD_STOP, 1);
    }
    if (st == MC_I2C_TIMEOUT || st == MC_I2C_BUS_ERROR)
        if (I2CM.STATUS.bit.BUSSTATE != BUSSTATE_IDLE || bus_fault() || I2CM.SYNCBUSY.bit.SYSOP)
            bus_recover();
    return st;
}

static int start(uint8_t addr_rw)
{
    if (sync_sysop())
        return MC_I2C_TIMEOUT;
    I2CM.ADDR.reg = addr_rw;
    return wait_bus();
}

static int write_txn(const mc_txn_t *t)
{
    int st = start((uint8_t)(t->addr << 1));
    if (st != MC_I2C_OK)
        return finish(st);
    if (I2CM.STATUS.bit.RXNACK)
        return finish(MC_I2C_NACK_ADDR);
    for (uint32_t k = 0; k < t->len; k++) {
        if (sync_sysop())
            return finish(MC_I2C_TIMEOUT);
        I2CM.DATA.reg = t->buf[k];
        st = wait_bus();
        if (st != MC_I2C_OK)
            return finish(st);
        if (I2CM.STATUS.bit.RXNACK)
            return finish(MC_I2C_NACK_DATA);
    }
    return finish(MC_I2C_OK);
}

static int read_txn(const mc_txn_t *t, uint8_t *rx, uint32_t *len)
{
    uint32_t want = t->len < MC_BLK_MAX_LEN ? t->len : MC_BLK_MAX_LEN;
    int st = start((uint8_t)((t->addr << 1) | 1u));
    if (st != MC_I2C_OK)
        return finish(st);
    /* MB instead of SB on a read: the address was not acknowledged */
    if (!I2CM.INTFLAG.bit.SB)
        return finish(I2CM.STATUS.bit.RXNACK ? MC_I2C_NACK_ADDR : MC_I2C_BUS_ERROR);
    for (uint32_t k = 0; k < want; k++) {
        if (k > 0) {
            /* ACK the previous byte and clock in the next */
            if (command(CMD_READ_MORE, 0))
                return finish(MC_I2C_TIMEOUT);
            st = wait_bus();
            if (st != MC_I2C_OK)
                return finish(st);
        }
        if (sync_sysop())
            return finish(MC_I2C_TIMEOUT);
        rx[(*len)++] = (uint8_t)I2CM.DATA.reg;
    }
    /* NACK the last byte, then STOP (finish) */
    I2CM.CTRLB.bit.ACKACT = 1;
    return finish(MC_I2C_OK);
}

int primary_hw_txn(const mc_txn_t *t, uint8_t *rx, uint32_t *len)
{
    *len = 0;
    deadline(t->timeout_us);
    if (I2CM.STATUS.bit.BUSSTATE == 3u) {   /* busy: left so by a missing STOP or a glitch */
        bus_recover();
        return MC_I2C_BUS_ERROR;
    }
    if (t->kind == MC_TXN_WRITE)
        return write_txn(t);
    int st = read_txn(t, rx, len);
    if (st != MC_I2C_OK)
        *len = 0;
    return st;
}

uint32_t primary_hw_bus_resets(void) { return g_recoveries; }
uint32_t primary_hw_micros(void) { return (uint32_t)micros(); }
