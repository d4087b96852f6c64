/* Primary program: polls the cells over I2C (Wire, guarded) and speaks SLCAN to the laptop over USB CDC. */
#include <Arduino.h>
#include <Wire.h>
extern "C" {
#include "mc_cell.h"    /* MC_FW_VERSION: one release number for cell and primary */
#include "bus/mc_primary.h"
#include "../common/mc_ident.h"
}

/*
 * All logic is in lib/metacell/src/bus/mc_primary.c (scheduler, command forwarding,
 * SLCAN); this file moves bytes:
 *   USB in  -> mc_link_rx  -> replies to USB
 *   mc_primary_next -> one Wire transaction -> mc_primary_complete
 *   mc_link_tx -> USB out (whole lines, only as much as the CDC buffer takes)
 * "ID?" lines are answered with the identity line (tools/flash); the SLCAN parser
 * also sees them and counts them as malformed, but its BEL reply is suppressed.
 *
 * Guarding Wire (the core's primary calls block while the bus is held):
 *   - SERCOM2 runs with its SCL low timeout (LOWTOUTEN, 25-35 ms) and an inactive
 *     bus timeout (INACTOUT), so a held SCL ends the blocking call with an error;
 *   - before each transaction a bus seen busy is recovered with 9 SCL pulses;
 *   - a transaction that returns after txn.timeout_us counts as a timeout in the
 *     library (its data is dropped) and the cell is backed off 1, 2, 4 .. 64 cycles.
 * So a stuck cell costs at most ~35 ms per back-off period and never stalls the others.
 */
#ifndef MC_I2C_HZ
#define MC_I2C_HZ 400000
#endif
#ifndef MC_POLL_PERIOD_US
#define MC_POLL_PERIOD_US 0   /* 0: as fast as the bus allows */
#endif
#if MC_I2C_HZ == 400000
#define MC_TXN_TIMEOUT_US 1500
#else
#define MC_TXN_TIMEOUT_US 5000
#endif

static mc_link_t g_link;
static mc_ident_rx_t g_rx;
static char g_line_first;    /* first byte of the USB line being received */

static void sercom_timeouts(void)
{
    Sercom *s = SERCOM2;
    s->I2CM.CTRLA.bit.ENABLE = 0;
    while (s->I2CM.SYNCBUSY.bit.ENABLE) {}
    s->I2CM.CTRLA.bit.LOWTOUTEN = 1;   /* SCL low > 25-35 ms: error, Wire returns */
    s->I2CM.CTRLA.bit.INACTOUT = 3;    /* bus idle after ~205 us of inactivity */
    s->I2CM.CTRLA.bit.ENABLE = 1;
    while (s->I2CM.SYNCBUSY.bit.ENABLE) {}
    s->I2CM.STATUS.bit.BUSSTATE = 1;   /* force idle */
    while (s->I2CM.SYNCBUSY.bit.SYSOP) {}
}

static void bus_begin(void)
{
    Wire.begin();
    Wire.setClock(MC_I2C_HZ);
    sercom_timeouts();
}

/* 9 clock pulses with SDA released free a secondary stuck mid-byte; then restart Wire. */
static void bus_recover(void)
{
    Wire.end();
    pinMode(PIN_WIRE_SDA, INPUT_PULLUP);
    pinMode(PIN_WIRE_SCL, OUTPUT);
    for (int i = 0; i < 9; i++) {
        digitalWrite(PIN_WIRE_SCL, LOW);
        delayMicroseconds(5);
        digitalWrite(PIN_WIRE_SCL, HIGH);
        delayMicroseconds(5);
    }
    bus_begin();
}

static int run_txn(const mc_txn_t *t, uint8_t *rx, uint32_t *len)
{
    *len = 0;
    if (SERCOM2->I2CM.STATUS.bit.BUSSTATE == 3 || SERCOM2->I2CM.STATUS.bit.LOWTOUT) {
        bus_recover();
        return MC_I2C_BUS_ERROR;
    }
    if (t->kind == MC_TXN_WRITE) {
        Wire.beginTransmission(t->addr);
        Wire.write(t->buf, t->len);
        uint8_t e = Wire.endTransmission(true);   /* always STOP: no repeated start */
        return e == 0 ? MC_I2C_OK : e == 2 ? MC_I2C_NACK_ADDR : e == 3 ? MC_I2C_NACK_DATA : MC_I2C_BUS_ERROR;
    }
    uint8_t n = Wire.requestFrom(t->addr, (size_t)t->len, true);
    if (n == 0)
        return SERCOM2->I2CM.STATUS.bit.LOWTOUT ? MC_I2C_TIMEOUT : MC_I2C_NACK_ADDR;
    while (Wire.available() > 0 && *len < MC_BLK_MAX_LEN)
        rx[(*len)++] = (uint8_t)Wire.read();
    return MC_I2C_OK;
}

void setup()
{
    Serial.begin(115200);   /* USB CDC: the rate is ignored, never 1200 */
    mc_ident_rx_init(&g_rx);
    mc_link_init(&g_link, micros());
    mc_primary_configure(&g_link.p, MC_POLL_PERIOD_US, MC_TXN_TIMEOUT_US, MC_SCHED_ACK_TIMEOUT_US,
                         MC_SCHED_STATUS_EVERY);
    bus_begin();
}

static void usb_in(void)
{
    char out[MC_SLCAN_REPLY_MAX + 1];
    while (Serial.available() > 0) {
        uint8_t b = (uint8_t)Serial.read();
        if (mc_ident_rx_feed(&g_rx, b)) {
            char line[MC_IDENT_LINE_MAX];
            int n = mc_ident_format(line, sizeof(line), MC_IDENT_ROLE_PRIMARY, 0, 0, MC_FW_VERSION);
            if (n > 0)
                Serial.write((const uint8_t *)line, (size_t)n);
        }
        uint32_t used;
        uint32_t n = mc_link_rx(&g_link, micros(), &b, 1, &used, out, sizeof(out));
        if (n && g_line_first != 'I')
            Serial.write((const uint8_t *)out, n);
        if (b == '\r' || b == '\n')
            g_line_first = 0;
        else if (!g_line_first)
            g_line_first = (char)b;
    }
}

void loop()
{
    usb_in();
    mc_txn_t t;
    if (mc_primary_next(&g_link.p, micros(), &t)) {
        uint8_t rx[MC_BLK_MAX_LEN];
        uint32_t len;
        int st = run_txn(&t, rx, &len);
        mc_primary_complete(&g_link.p, micros(), st, rx, len);
    }
    int room = Serial.availableForWrite();
    if (room >= MC_SLCAN_FRAME_MAX || !g_link.s.open) {
        char out[256];
        uint32_t cap = room > (int)sizeof(out) ? sizeof(out) : (uint32_t)(room < MC_SLCAN_FRAME_MAX ? MC_SLCAN_FRAME_MAX : room);
        uint32_t n = mc_link_tx(&g_link, micros(), out, cap);
        if (n)
            Serial.write((const uint8_t *)out, n);
    }
}
