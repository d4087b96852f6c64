/* Runs the cell glue (src/cell, src/common) on the host stand-ins: setup() and loop() after a watchdog reset; results as key=value lines. */
#include <stdio.h>
#include <string.h>
#include "stub_state.h"
#include "cell/main.cpp"
#include "cell/bus_glue.cpp"
extern "C" {
#include "bus/mc_crc8.h"
}

int main(void)
{
    stub.sda = stub.scl = 1;
    PM->RCAUSE.reg = PM_RCAUSE_WDT;
    setup();
    printf("setup_err=%d\n", g_setup_err);
    printf("ctrl_pa=0x%08lx\nctrl_pb=0x%08lx\n", (unsigned long)PORT->Group[0].CTRL.reg,
           (unsigned long)PORT->Group[1].CTRL.reg);
    printf("attached=0x%08lx\n", (unsigned long)stub.attached);
    printf("wdt_enabled=%d\nwdt_per=%u\n", (WDT->CTRL.reg & WDT_CTRL_ENABLE) != 0, (unsigned)WDT->CONFIG.reg);
    WDT->CLEAR.reg = 0;
    loop();
    printf("wdt_fed=%d\n", WDT->CLEAR.reg == WDT_CLEAR_CLEAR_KEY);
    /* the BOOT block as the primary reads it: POINTER write, then a read */
    uint8_t w[3 + MC_REG_POINTER_LEN] = {MC_REG_POINTER, 1, MC_BLK_BOOT, 0};
    uint8_t hdr = (uint8_t)(MC_CELL_ADDR << 1);
    w[3] = mc_crc8_update(mc_crc8(&hdr, 1), w, 3);
    mc_regs_on_receive(&g_regs, w, sizeof(w));
    uint8_t out[MC_BLK_MAX_LEN];
    uint32_t n = mc_regs_on_request(&g_regs, out, sizeof(out));
    printf("boot=");
    for (uint32_t k = 0; k < n; k++)
        printf("%02x", out[k]);
    printf("\n");
    return 0;
}
