/* Runs the cell glue (src/cell, src/common) on the host stand-ins: setup() and loop() after a watchdog reset, a fault and its reboots; key=value lines. */
#include <stdio.h>
#include <string.h>
#include "stub_state.h"
#include "cell/main.cpp"
#include "cell/bus_glue.cpp"
extern "C" {
#include "bus/mc_crc8.h"
}

static int fed_by_loop(void)
{
    WDT->CLEAR.reg = 0;
    loop();
    return WDT->CLEAR.reg == WDT_CLEAR_CLEAR_KEY;
}

/* The BOOT block as the primary reads it: POINTER write, then a read; printed as key=hex. */
static void print_boot(const char *key)
{
    uint8_t w[3 + MC_REG_POINTER_LEN] = {MC_REG_POINTER, 1, MC_BLK_BOOT, 0};
    uint8_t hdr = (uint8_t)(MC_CELL_ADDR << 1);
    w[3] = mc_crc8_update(mc_crc8(&hdr, 1), w, 3);
    mc_regs_on_receive(&g_regs, w, sizeof(w));
    uint8_t out[MC_BLK_MAX_LEN];
    uint32_t n = mc_regs_on_request(&g_regs, out, sizeof(out));
    printf("%s=", key);
    for (uint32_t k = 0; k < n; k++)
        printf("%02x", out[k]);
    printf("\n");
}

/* A HardFault with the drive running: the fault path, then the boots that follow it. */
static void fault_scenario(void)
{
    static uint32_t frame[8] = {0, 0, 0, 0, 0, 0, 0x00003a5cu, 0x01000000u};   /* stacked PC 0x3a5c */
    setup();
    mc_cell_enable(&g_cell, 1);
    hw_tick_handler();   /* the drive runs: nSLEEP set */
    printf("nsleep_set_before=%d\n", (PORT_IOBUS->Group[0].OUTSET.reg & (1u << 2)) != 0);
    PORT_IOBUS->Group[0].OUTCLR.reg = 0;
    if (setjmp(stub.reset) == 0)
        sys_fault(frame, 3);   /* HardFault: what sys_fault_entry passes */
    printf("resets=%d\nnsleep_cleared=%d\n", stub.resets, (PORT_IOBUS->Group[0].OUTCLR.reg & (1u << 2)) != 0);
    PM->RCAUSE.reg = PM_RCAUSE_SYST;   /* the boot after the fault */
    setup();
    print_boot("boot_after_fault");
    PM->RCAUSE.reg = PM_RCAUSE_SYST;   /* a later software reset (bootloader entry): record consumed */
    setup();
    print_boot("boot_after_next");
    mc_fault_record.magic = SYS_FAULT_MAGIC;   /* an intact-looking record after a power-on: RAM noise */
    mc_fault_record.exc = 3;
    mc_fault_record.pc = 0x1234;
    mc_fault_record.check = ~(SYS_FAULT_MAGIC ^ 3u ^ 0x1234u);
    PM->RCAUSE.reg = PM_RCAUSE_POR;
    setup();
    print_boot("boot_after_por");
}

int main(int argc, char **argv)
{
    const char *sc = argc > 1 ? argv[1] : "";
    stub.sda = stub.scl = 1;
    for (int i = 0; i < 32; i++)
        stub.prio[i] = -1;
    stub.prio[USB_IRQn] = 0;   /* the core's USBDevice.init() before setup() */
    PM->RCAUSE.reg = PM_RCAUSE_WDT;
    if (!strcmp(sc, "babble")) {
        /* a babbling bus left 200 bytes in Wire's buffer when the STOP came */
        setup();
        stub.wire_rx = 200;
        on_receive(200);
        printf("wire_reads=%lu\nmailbox_len=%u\n", (unsigned long)stub.wire_reads, (unsigned)g_regs.rx_len);
        return 0;
    }
    if (!strcmp(sc, "flood")) {
        /* the host sends without pause: every pass still ends, serves the bus and feeds the watchdog */
        setup();
        stub.flood = true;
        size_t most = 0;
        int fed = 0;
        for (int pass = 0; pass < 5; pass++) {
            stub.reads = 0;
            hw_tick_handler();
            fed += fed_by_loop();
            most = stub.reads > most ? stub.reads : most;
        }
        printf("passes_fed=%d\nmost_reads_per_pass=%lu\n", fed, (unsigned long)most);
        return 0;
    }
    if (!strcmp(sc, "startup_edge")) {
        /* alpha B (D8) changes while start-up attaches the pins, then alpha A (D7) after it: +1 each way
         * round the Gray code, never an illegal transition */
        stub.edge_on_first_attach = CELL_PIN_ENC_A_B;
        setup();
        int32_t at_start = g_quad[MC_ALPHA].pos;
        stub_edge(CELL_PIN_ENC_A_A);
        printf("setup_err=%d\nirq_off=%d\npos_at_start=%ld\npos=%ld\nerrors=%lu\n", g_setup_err, stub.irq_off,
               (long)at_start, (long)g_quad[MC_ALPHA].pos, (unsigned long)g_quad[MC_ALPHA].errors);
        return 0;
    }
    if (!strcmp(sc, "fault")) {
        fault_scenario();
        return 0;
    }
    if (!strcmp(sc, "pins_err")) {
        /* another variant's pin table: setup() stops before the tick starts */
        g_APinDescription[CELL_PIN_ENC_A_A].ulPin = 3;
        setup();
        int a = fed_by_loop(), b = fed_by_loop();
        printf("setup_err=%d\nwdt_fed_without_tick=%d\n", g_setup_err, a && b);
        return 0;
    }
    setup();
    printf("setup_err=%d\n", g_setup_err);
    printf("prio_eic=%d\nprio_tc3=%d\nprio_sercom2=%d\nprio_usb=%d\n", stub.prio[EIC_IRQn], stub.prio[TC3_IRQn],
           stub.prio[SERCOM2_IRQn], stub.prio[USB_IRQn]);
    printf("ctrl_pa=0x%08lx\nctrl_pb=0x%08lx\n", (unsigned long)PORT->Group[0].CTRL.reg,
           (unsigned long)PORT->Group[1].CTRL.reg);
    printf("attached=0x%08lx\n", (unsigned long)stub.attached);
    printf("i2cs_sdahold=%u\ni2cs_enabled=%u\ni2cs_mode=%u\n", (unsigned)SERCOM2->I2CS.CTRLA.bit.SDAHOLD,
           (unsigned)SERCOM2->I2CS.CTRLA.bit.ENABLE, (unsigned)SERCOM2->I2CS.CTRLA.bit.MODE);
    printf("wdt_enabled=%d\nwdt_per=%u\n", (WDT->CTRL.reg & WDT_CTRL_ENABLE) != 0, (unsigned)WDT->CONFIG.reg);
    /* the watchdog proves the tick: no feed while it stands still, one after it ran */
    int idle = fed_by_loop();
    hw_tick_handler();
    int after_tick = fed_by_loop();
    int again = fed_by_loop();
    printf("wdt_fed_no_tick=%d\nwdt_fed=%d\nwdt_fed_same_tick=%d\n", idle, after_tick, again);
    print_boot("boot");
    return 0;
}
