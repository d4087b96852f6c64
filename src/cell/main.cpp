/* Cell program: wires the metacell library to the XIAO's pins, timer and USB serial. */
#include <Arduino.h>
#include "cell_config.h"
#include "metacell.h"
#include "samd21_hw.h"
#include "../common/samd21_sys.h"
#include "cell_app.h"
#include "bus_glue.h"

/*
 * No control arithmetic here: every tick is
 *   snapshot both decoders -> mc_cell_tick() -> hw_apply(out[alpha], out[beta])
 * The USB serial port answers the identity request "ID?" (src/common/mc_ident.h)
 * and nothing else; the bus glue (docs/datapath.md) carries every other command.
 * The watchdog (src/common/samd21_sys.h) is fed from loop() only when the control tick
 * has run since the last feed, so it proves the tick, not just the loop; the reset cause
 * read at boot goes out in the BOOT block.
 */

enum { SETUP_OK = 0, SETUP_ERR_PINS, SETUP_ERR_DRIVE, SETUP_ERR_TICK };
static const char *const k_setup_err[] = {"", "pins", "drive", "tick"};

static mc_cell_t g_cell;
static mc_quad_t g_quad[2];
static volatile uint32_t g_ticks;
static int g_setup_err = SETUP_OK;
static mc_ident_rx_t g_rx;
static uint8_t g_reset_cause;
static uint16_t g_wdt_ms;
static uint32_t g_wdt_ticks;   /* g_ticks at the last watchdog feed */

/* TC3 interrupt, MC_CTRL_RATE_HZ times a second. */
extern "C" void hw_tick_handler(void)
{
    mc_quad_snap_t a, b;
    mc_quad_snapshot(&g_quad[MC_ALPHA], &a);
    mc_quad_snapshot(&g_quad[MC_BETA], &b);
    if (hw_nfault_active())
        mc_cell_report_driver_fault(&g_cell);
    mc_cell_tick(&g_cell, &a, &b);
    hw_apply(&g_cell.out[MC_ALPHA], &g_cell.out[MC_BETA]);
    g_ticks = g_ticks + 1u;
}

mc_cell_t *cell_app_cell(void) { return &g_cell; }
void cell_app_lock(void) { hw_tick_mask(); }
void cell_app_unlock(void) { hw_tick_unmask(); }
uint8_t cell_app_index(void) { return MC_CELL_INDEX; }
uint8_t cell_app_addr(void) { return MC_CELL_ADDR; }
uint32_t cell_app_ticks(void) { return g_ticks; }
uint8_t cell_app_reset_cause(void) { return g_reset_cause; }
uint16_t cell_app_wdt_ms(void) { return g_wdt_ms; }

uint8_t cell_app_fault_exc(void) { return sys_fault_exc(); }
uint32_t cell_app_fault_pc(void) { return sys_fault_pc(); }

/* The fault handler's first act (src/common/samd21_sys.h): both drivers asleep. */
extern "C" void sys_safe_outputs(void) { hw_drivers_off(); }

void cell_app_positions(int32_t *pos_a, int32_t *pos_b)
{
    mc_quad_snap_t a, b;
    mc_quad_snapshot(&g_quad[MC_ALPHA], &a);
    mc_quad_snapshot(&g_quad[MC_BETA], &b);
    *pos_a = a.pos;
    *pos_b = b.pos;
}

void cell_app_zero(void)
{
    int32_t pa, pb;
    cell_app_lock();
    cell_app_positions(&pa, &pb);
    mc_cell_zero(&g_cell, pa, pb);
    cell_app_unlock();
}

static uint32_t g_rx_pass;   /* USB bytes read in this pass of loop() */

static void answer_identity(void)
{
    char line[MC_IDENT_LINE_MAX];
    if (g_setup_err != SETUP_OK) {
        Serial.print("MC error=");
        Serial.print(k_setup_err[g_setup_err]);
        Serial.print("\r\n");
    }
    int n = mc_ident_format(line, sizeof(line), MC_IDENT_ROLE_CELL, MC_CELL_INDEX,
                            MC_CELL_ADDR, MC_FW_VERSION);
    if (n > 0)
        Serial.write((const uint8_t *)line, (size_t)n);
}

void setup()
{
    hw_drivers_init();   /* drivers asleep before anything else */
    g_reset_cause = sys_reset_cause();
    sys_wdt_start();     /* fed by loop() as the tick runs (always after a start-up error) */
    g_wdt_ms = SYS_WDT_MS;
    pinMode(LED_BUILTIN, OUTPUT);
    digitalWrite(LED_BUILTIN, HIGH);   /* XIAO user LED is active low: off */
    Serial.begin(115200);              /* USB CDC: the rate is ignored, never 1200 */
    mc_ident_rx_init(&g_rx);

    if (hw_check_pins() != 0) {
        g_setup_err = SETUP_ERR_PINS;
        return;
    }
    mc_cell_init(&g_cell);
    mc_drive_config_t cfg;
    mc_drive_default_config(&cfg);
    cfg.pwm_top = MC_PWM_TOP;
    cfg.ctrl_rate_hz = MC_CTRL_RATE_HZ;
    if (mc_cell_set_drive(&g_cell, &cfg) != MC_OK) {
        g_setup_err = SETUP_ERR_DRIVE;
        return;
    }
    hw_pwm_init(MC_PWM_TOP);
    hw_encoders_init(&g_quad[MC_ALPHA], &g_quad[MC_BETA]);
    int32_t pa, pb;
    cell_app_positions(&pa, &pb);
    mc_cell_zero(&g_cell, pa, pb);
    mc_cell_enable(&g_cell, MC_ENABLE_AT_BOOT);
    if (hw_tick_start(MC_CTRL_RATE_HZ) == 0) {
        g_setup_err = SETUP_ERR_TICK;
        return;
    }
    if (MC_CELL_INDEX != 0)
        bus_setup(MC_CELL_ADDR);
    hw_irq_priorities();   /* last: USB below the encoders, the tick and the bus */
}

void loop()
{
    /* Feed only when the tick has advanced since the last feed: a tick that stopped (TC3
     * off, its interrupt left masked) then resets the chip like a hung loop, instead of
     * leaving the drivers at their last duty. After a start-up error the tick never runs
     * and the drive stays off: fed unconditionally then (the board keeps answering "ID?"). */
    uint32_t t = g_ticks;
    if ((t != g_wdt_ticks || g_setup_err != SETUP_OK) && sys_wdt_feed())
        g_wdt_ticks = t;
    while (Serial.available() > 0) {
        if (mc_ident_rx_feed(&g_rx, (uint8_t)Serial.read()))
            answer_identity();
        if (++g_rx_pass >= SYS_USB_RX_PER_PASS)
            break;   /* the rest waits for the next pass: bus service and watchdog first */
    }
    g_rx_pass = 0;
    if (g_setup_err == SETUP_OK)
        bus_service();
    /* LED: fast blink = start-up error (drive never enabled), on = latched fault. */
    uint32_t ms = millis();
    if (g_setup_err != SETUP_OK)
        digitalWrite(LED_BUILTIN, (ms >> 7) & 1u ? LOW : HIGH);
    else
        digitalWrite(LED_BUILTIN, g_cell.faults ? LOW : HIGH);
}
