/* Cell I2C secondary glue: Wire callbacks into the library's register handler (lib/metacell/src/bus/mc_regs.h). */
#include <Arduino.h>
#include <Wire.h>
#include "bus_glue.h"
#include "cell_app.h"
#include "samd21_hw.h"
extern "C" {
#include "bus/mc_regs.h"
}

/*
 * Transactions (docs/datapath.md): a write "reg seq payload crc" ended by STOP, and
 * a separate read returning the selected block (snapshot by default) with its CRC.
 * The Wire callbacks run in the SERCOM2 interrupt and only copy bytes:
 *   onReceive -> mc_regs_on_receive (mailbox / read pointer)
 *   onRequest -> mc_regs_on_request (copy of the published block)
 * bus_service() in loop() applies a pending write and publishes the snapshot of
 * each new tick, both under cell_app_lock(): the TC3 tick is held off, so the write
 * takes effect between two ticks and the snapshot is that of exactly one tick.
 */
#ifndef MC_BUILD_ID
#define MC_BUILD_ID 0u   /* metacell_tools/flash may pass e.g. the git hash prefix */
#endif

static mc_regs_t g_regs;
static uint32_t g_published;
static uint8_t g_up;

static void on_receive(int n)
{
    uint8_t buf[32];
    int k = 0;
    /* At most sizeof(buf) bytes: the core clears its receive buffer after this callback, so
     * the rest needs no draining, and a babbling bus (up to 255 buffered bytes) cannot make
     * this interrupt, and the clock stretch of the next transaction, any longer. */
    while (k < (int)sizeof(buf) && Wire.available() > 0)
        buf[k++] = (uint8_t)Wire.read();
    (void)n;
    /* n == 0 (the core's onReceive(0) after a read) is ignored by the handler;
     * a write longer than buf arrives as 32 bytes and is rejected as LENGTH */
    mc_regs_on_receive(&g_regs, buf, (uint32_t)k);
}

static void on_request(void)
{
    uint8_t out[MC_BLK_MAX_LEN];
    uint32_t n = mc_regs_on_request(&g_regs, out, sizeof(out));
    Wire.write(out, (size_t)n);
}

/* Snapshots for the handler: positions now (for ZERO), decoder error counts of the last tick. */
static void snaps(const mc_cell_t *c, mc_quad_snap_t *a, mc_quad_snap_t *b)
{
    cell_app_positions(&a->pos, &b->pos);
    a->errors = c->err_last[MC_ALPHA];
    b->errors = c->err_last[MC_BETA];
    a->saturated = b->saturated = 0;
}

extern "C" void bus_setup(uint8_t addr)
{
    mc_cell_t *c = cell_app_cell();
    cell_app_lock();
    int rc = mc_regs_init(&g_regs, c, addr, MC_BUILD_ID, NULL);
    if (rc == MC_OK)
        mc_regs_set_boot(&g_regs, cell_app_reset_cause(), cell_app_wdt_ms(), cell_app_fault_exc(),
                         cell_app_fault_pc());
    cell_app_unlock();
    if (rc != MC_OK)
        return;
    g_published = cell_app_ticks() - 1u;
    Wire.begin(addr);
    hw_i2c_secondary_timing();
    Wire.onReceive(on_receive);
    Wire.onRequest(on_request);
    g_up = 1;
}

extern "C" void bus_service(void)
{
    if (!g_up)
        return;
    mc_cell_t *c = cell_app_cell();
    mc_quad_snap_t a, b;
    if (g_regs.rx_full) {
        cell_app_lock();
        snaps(c, &a, &b);
        mc_regs_apply(&g_regs, c, &a, &b);
        cell_app_unlock();
    }
    uint32_t t = cell_app_ticks();
    if (t != g_published) {
        cell_app_lock();
        snaps(c, &a, &b);
        mc_regs_publish(&g_regs, c, &a, &b);
        g_published = cell_app_ticks();
        cell_app_unlock();
    }
}
