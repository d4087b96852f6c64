/* Primary hardware layer: Wire on SERCOM2 guarded by the SERCOM timeouts and bus recovery; micros(); USB room. */
#include <Arduino.h>
#include <Wire.h>
#include "primary_hw.h"

/*
 * Guarding Wire (the core's primary calls block while the bus is held):
 *   - SERCOM2 runs with its SCL low timeout (LOWTOUTEN, 25-35 ms) and an inactive
 *     bus timeout (INACTOUT), so a held SCL ends the blocking call with an error;
 *   - before each transaction a bus seen busy is recovered with 9 SCL pulses;
 *   - a transaction that returns after txn.timeout_us counts as a timeout in the
 *     library (its data is dropped) and the cell is backed off 1, 2, 4 .. 64 cycles.
 * So a stuck cell costs at most ~35 ms per back-off period and never stalls the others.
 * Writes always end with STOP and reads are separate transactions (no repeated start).
 */
static uint32_t g_hz;

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

void primary_hw_begin(uint32_t hz)
{
    g_hz = hz;
    Wire.begin();
    Wire.setClock(hz);
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
    primary_hw_begin(g_hz);
}

int primary_hw_txn(const mc_txn_t *t, uint8_t *rx, uint32_t *len)
{
    *len = 0;
    if (SERCOM2->I2CM.STATUS.bit.BUSSTATE == 3 || SERCOM2->I2CM.STATUS.bit.LOWTOUT) {
        bus_recover();
        return MC_I2C_BUS_ERROR;
    }
    if (t->kind == MC_TXN_WRITE) {
        Wire.beginTransmission(t->addr);
        Wire.write(t->buf, t->len);
        uint8_t e = Wire.endTransmission(true);
        return e == 0 ? MC_I2C_OK : e == 2 ? MC_I2C_NACK_ADDR : e == 3 ? MC_I2C_NACK_DATA : MC_I2C_BUS_ERROR;
    }
    uint8_t n = Wire.requestFrom(t->addr, (size_t)t->len, true);
    if (n == 0)
        return SERCOM2->I2CM.STATUS.bit.LOWTOUT ? MC_I2C_TIMEOUT : MC_I2C_NACK_ADDR;
    while (Wire.available() > 0 && *len < MC_BLK_MAX_LEN)
        rx[(*len)++] = (uint8_t)Wire.read();
    return MC_I2C_OK;
}

uint32_t primary_hw_micros(void) { return (uint32_t)micros(); }
int primary_hw_usb_room(void) { return Serial.availableForWrite(); }
