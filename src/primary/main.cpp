/* Primary program: polls the cells over I2C and speaks SLCAN to the laptop over USB CDC. */
#include <Arduino.h>
extern "C" {
#include "mc_cell.h"    /* MC_FW_VERSION: one release number for cell and primary */
#include "bus/mc_primary.h"
#include "../common/mc_ident.h"
}
#include "primary_hw.h"

/*
 * All logic is in lib/metacell/src/bus/mc_primary.c (scheduler, command forwarding,
 * SLCAN); this file moves bytes (docs/datapath.md):
 *   USB in  -> mc_link_rx  -> replies to USB
 *   mc_primary_next -> one guarded Wire transaction (primary_hw.cpp) -> mc_primary_complete
 *   mc_link_tx -> USB out (whole lines, only as much as the CDC buffer takes)
 * "ID?" lines are answered with the identity line (tools/flash); the SLCAN parser
 * also sees them and counts them as malformed, but its BEL reply is suppressed.
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

void setup()
{
    Serial.begin(115200);   /* USB CDC: the rate is ignored, never 1200 */
    mc_ident_rx_init(&g_rx);
    mc_link_init(&g_link, primary_hw_micros());
    mc_primary_configure(&g_link.p, MC_POLL_PERIOD_US, MC_TXN_TIMEOUT_US, MC_SCHED_ACK_TIMEOUT_US,
                         MC_SCHED_STATUS_EVERY);
    primary_hw_begin(MC_I2C_HZ);
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
        uint32_t n = mc_link_rx(&g_link, primary_hw_micros(), &b, 1, &used, out, sizeof(out));
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
    if (mc_primary_next(&g_link.p, primary_hw_micros(), &t)) {
        uint8_t rx[MC_BLK_MAX_LEN];
        uint32_t len;
        int st = primary_hw_txn(&t, rx, &len);
        mc_primary_complete(&g_link.p, primary_hw_micros(), st, rx, len);
    }
    /* whole lines only; with the channel closed mc_link_tx just empties the queue */
    int room = primary_hw_usb_room();
    if (room >= MC_SLCAN_FRAME_MAX || !g_link.s.open) {
        char out[256];
        uint32_t cap = room > (int)sizeof(out) ? (uint32_t)sizeof(out) : (uint32_t)MC_SLCAN_FRAME_MAX;
        if (room > MC_SLCAN_FRAME_MAX && room < (int)sizeof(out))
            cap = (uint32_t)room;
        uint32_t n = mc_link_tx(&g_link, primary_hw_micros(), out, cap);
        if (n)
            Serial.write((const uint8_t *)out, n);
    }
}
