/* Primary program: polls the cells over I2C and speaks SLCAN to the laptop over USB CDC. */
#include <Arduino.h>
extern "C" {
#include "mc_cell.h"    /* MC_FW_VERSION: one release number for cell and primary */
#include "bus/mc_primary.h"
#include "../common/mc_ident.h"
}
#include "../common/samd21_sys.h"
#include "primary_hw.h"

/*
 * All logic is in lib/metacell/src/bus/mc_primary.c (scheduler, command forwarding,
 * SLCAN); this file moves bytes (docs/datapath.md):
 *   USB in  -> mc_link_rx  -> replies to USB
 *   mc_primary_next -> one guarded Wire transaction (primary_hw.cpp) -> mc_primary_complete
 *   mc_link_tx -> USB out (whole lines, one USB packet per write, see usb_out)
 *   USB DTR edge (the laptop opened or closed the port) -> mc_link_session
 * The watchdog (src/common/samd21_sys.h) is fed when the poll schedule has moved since the
 * last feed (mc_primary_progress); the reset cause read at boot, the bus recoveries and the
 * USB bytes lost go out in PRIMARY_HEALTH.
 * "ID?" lines are answered with the identity line (metacell_tools/flash); the SLCAN parser
 * also sees them and counts them as malformed, but its BEL reply is suppressed.
 */
#ifndef MC_I2C_HZ
#define MC_I2C_HZ 400000
#endif
#ifndef MC_RIG_CELLS
#define MC_RIG_CELLS MC_N_CELLS   /* cells polled; a sheet's primary is built with -DMC_RIG_CELLS=N (flash tool) */
#endif
#if MC_RIG_CELLS < 1 || MC_RIG_CELLS > MC_MAX_CELLS
#error "MC_RIG_CELLS must be 1..MC_MAX_CELLS (cell addresses 0x10..0x4F)"
#endif
#ifndef MC_POLL_PERIOD_US
#define MC_POLL_PERIOD_US 0   /* 0: as fast as the bus allows */
#endif
#if MC_I2C_HZ == 400000
#define MC_TXN_TIMEOUT_US 1500
#elif MC_I2C_HZ == 100000
#define MC_TXN_TIMEOUT_US 5000   /* the fallback for a bus too slow for Fast-mode (docs/hardware.md) */
#else
#error "MC_I2C_HZ must be 400000 or 100000 (the two SCL timings primary_hw.cpp sets)"
#endif

/* One write = at most one USB full-speed bulk packet: the core sends it whole or not at all. */
#define USB_PACKET 64

static mc_link_t g_link;
static mc_ident_rx_t g_rx;
static char g_line_first;    /* first byte of the USB line being received */
static bool g_dtr;           /* last seen USB DTR (host has the port open) */
static uint32_t g_resets;    /* bus recoveries already reported to the library */
static uint32_t g_wdt_progress;   /* mc_primary_progress at the last watchdog feed */

/* The fault handler's first act (src/common/samd21_sys.h): the primary drives nothing that moves. */
extern "C" void sys_safe_outputs(void) {}

void setup()
{
    uint8_t cause = sys_reset_cause();
    Serial.begin(115200);   /* USB CDC: the rate is ignored, never 1200 */
    mc_ident_rx_init(&g_rx);
    mc_link_init(&g_link, primary_hw_micros());
#if MC_RIG_CELLS != MC_N_CELLS
    mc_primary_set_cells(&g_link.p, MC_RIG_CELLS);   /* before configure: status_every >= the cells polled */
#endif
    mc_primary_configure(&g_link.p, MC_POLL_PERIOD_US, MC_TXN_TIMEOUT_US, MC_SCHED_ACK_TIMEOUT_US,
                         MC_SCHED_STATUS_EVERY);
    mc_primary_set_reset_cause(&g_link.p, cause);
    primary_hw_begin(MC_I2C_HZ);
    g_dtr = Serial.dtr();
    sys_wdt_start();
}

/*
 * Serial.availableForWrite() is a constant on this core (63), so it cannot pace the
 * output. Serial.write() blocks up to 70 ms when the host stops reading, then gives
 * up (returning 0, or (size_t)-1 from the core's failed send); later writes fail at
 * once until the host reads again. On that timeout the core also zeroes the packet
 * still armed, the previous write, which had reported all its bytes. So every write is
 * at most one packet (whole SLCAN lines, all or nothing), and the library counts a
 * failed write's bytes and those of the write before it, not yet known to have left, as
 * lost (mc_primary_usb_write, PRIMARY_HEALTH.usb_lost); nothing is dropped silently.
 */
static bool usb_write(const void *buf, uint32_t n)
{
    size_t w = Serial.write((const uint8_t *)buf, n);
    mc_primary_usb_write(&g_link.p, n, w == n);
    return w == n;
}

/* A laptop opening or closing the port starts a new link session. The core takes the new line
 * state (DTR) in its USB interrupt before the laptop's first byte can arrive (its open() returns
 * after that control transfer), so a look right before each byte is read never hands the new
 * session's bytes to the old one. */
static void session_check(void)
{
    bool dtr = Serial.dtr();
    if (dtr != g_dtr) {
        g_dtr = dtr;
        mc_link_session(&g_link);
    }
}

/* At most SYS_USB_RX_PER_PASS bytes per pass: a laptop streaming without pause must not starve
 * the polling and the watchdog feed. */
static void usb_in(void)
{
    char out[MC_SLCAN_REPLY_MAX + 1];
    for (uint32_t k = 0; k < SYS_USB_RX_PER_PASS && Serial.available() > 0; k++) {
        session_check();
        uint8_t b = (uint8_t)Serial.read();
        if (mc_ident_rx_feed(&g_rx, b)) {
            char line[MC_IDENT_LINE_MAX];
            int n = mc_ident_format(line, sizeof(line), MC_IDENT_ROLE_PRIMARY, 0, 0, MC_FW_VERSION);
            if (n > 0)
                usb_write(line, (uint32_t)n);
        }
        uint32_t used;
        uint32_t n = mc_link_rx(&g_link, primary_hw_micros(), &b, 1, &used, out, sizeof(out));
        if (n && g_line_first != 'I')
            usb_write(out, n);
        if (b == '\r' || b == '\n')
            g_line_first = 0;
        else if (!g_line_first)
            g_line_first = (char)b;
    }
}

/* Queued frames out: whole lines, one packet per write, a few packets per pass; stop at the
 * first failed write (the host is not reading: the queue fills and counts its drops). */
static void usb_out(void)
{
    char out[USB_PACKET];
    for (int k = 0; k < 4; k++) {
        uint32_t n = mc_link_tx(&g_link, primary_hw_micros(), out, sizeof(out));
        if (n == 0 || !usb_write(out, n))
            return;
    }
}

void loop()
{
    session_check();
    usb_in();
    mc_txn_t t;
    if (mc_primary_next(&g_link.p, primary_hw_micros(), &t)) {
        uint8_t rx[MC_BLK_MAX_LEN];
        uint32_t len;
        int st = primary_hw_txn(&t, rx, &len);
        mc_primary_complete(&g_link.p, primary_hw_micros(), st, rx, len);
    }
    for (uint32_t r = primary_hw_bus_resets(); g_resets != r; g_resets++)
        mc_primary_bus_reset(&g_link.p);
    usb_out();
    /* fed only when polling moved: a schedule stuck on a transaction that never completes, or a
     * loop that no longer reaches it, resets the board */
    uint32_t pr = mc_primary_progress(&g_link.p);
    if (pr != g_wdt_progress) {
        sys_wdt_feed();   /* a feed skipped while the last one synchronises: the next step feeds */
        g_wdt_progress = pr;
    }
}
