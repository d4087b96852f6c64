/* Runs the primary glue (src/primary) on the host stand-ins: one scenario per argv[1], results as key=value lines. */
#include <stdio.h>
#include <string.h>
#include "stub_state.h"
#include "primary/main.cpp"

static void reset_bus(void)
{
    memset((void *)SERCOM2, 0, sizeof(*SERCOM2));
    SERCOM2->I2CM.STATUS.bit.BUSSTATE = 1;
}

static int run_txn(int kind, uint32_t timeout_us, uint8_t *rx, uint32_t *len)
{
    mc_txn_t t;
    memset(&t, 0, sizeof(t));
    t.kind = (uint8_t)kind;
    t.addr = 0x10;
    t.len = kind == MC_TXN_READ ? MC_BLK_SNAPSHOT_LEN : 4;
    t.timeout_us = timeout_us;
    unsigned long t0 = stub.now_us;
    int st = primary_hw_txn(&t, rx, len);
    printf("status=%d\nelapsed_us=%lu\nlen=%u\n", st, stub.now_us - t0, (unsigned)*len);
    return st;
}

/* a cell that has taken the bus and holds it: the primary owns it but nothing completes */
static void owner_forever(void) { SERCOM2->I2CM.STATUS.bit.BUSSTATE = 2; }

int main(int argc, char **argv)
{
    const char *sc = argc > 1 ? argv[1] : "";
    uint8_t rx[MC_BLK_MAX_LEN];
    uint32_t len = 0;
    stub.sda = stub.scl = 1;
    reset_bus();
    if (!strcmp(sc, "stuck_read") || !strcmp(sc, "stuck_write")) {
        stub.on_micros = owner_forever;
        SERCOM2->I2CM.STATUS.bit.BUSSTATE = 2;
        run_txn(sc[6] == 'r' ? MC_TXN_READ : MC_TXN_WRITE, 1500, rx, &len);
    } else if (!strcmp(sc, "sync_stuck")) {
        SERCOM2->I2CM.SYNCBUSY.bit.SYSOP = 1;
        run_txn(MC_TXN_READ, 1500, rx, &len);
    } else if (!strcmp(sc, "arblost_read")) {
        SERCOM2->I2CM.STATUS.bit.ARBLOST = 1;
        SERCOM2->I2CM.STATUS.bit.BUSSTATE = 0;   /* unknown */
        run_txn(MC_TXN_READ, 1500, rx, &len);
    } else if (!strcmp(sc, "buserr_mid_read")) {
        /* the address is acknowledged (SB), then a bus error: SB never comes again (the core hangs here) */
        SERCOM2->I2CM.INTFLAG.bit.SB = 1;
        SERCOM2->I2CM.STATUS.bit.BUSSTATE = 2;
        struct H {
            static void f(void)
            {
                if (stub.now_us > 3) {
                    SERCOM2->I2CM.INTFLAG.reg = 0;
                    SERCOM2->I2CM.STATUS.bit.BUSERR = 1;
                }
            }
        };
        stub.on_micros = H::f;
        run_txn(MC_TXN_READ, 1500, rx, &len);
    } else if (!strcmp(sc, "ok_read")) {
        SERCOM2->I2CM.INTFLAG.bit.SB = 1;
        SERCOM2->I2CM.DATA.reg = 0x5A;
        run_txn(MC_TXN_READ, 1500, rx, &len);
        printf("byte0=%u\nacknack=%u\n", rx[0], (unsigned)SERCOM2->I2CM.CTRLB.bit.ACKACT);
    } else if (!strcmp(sc, "nack_read")) {
        SERCOM2->I2CM.INTFLAG.bit.MB = 1;
        SERCOM2->I2CM.STATUS.bit.RXNACK = 1;
        run_txn(MC_TXN_READ, 1500, rx, &len);
    } else if (!strcmp(sc, "ok_write")) {
        SERCOM2->I2CM.INTFLAG.bit.MB = 1;
        run_txn(MC_TXN_WRITE, 1500, rx, &len);
    } else if (!strcmp(sc, "begin")) {
        /* SERCOM2 as primary_hw_begin leaves it, at each supported rate */
        static const uint32_t rates[] = {400000, 100000};
        for (int i = 0; i < 2; i++) {
            primary_hw_begin(rates[i]);
            unsigned long f = rates[i];
            printf("inactout_%lu=%u\nlowtouten_%lu=%u\nenabled_%lu=%u\n", f, (unsigned)SERCOM2->I2CM.CTRLA.bit.INACTOUT,
                   f, (unsigned)SERCOM2->I2CM.CTRLA.bit.LOWTOUTEN, f, (unsigned)SERCOM2->I2CM.CTRLA.bit.ENABLE);
            printf("baud_%lu=%u\nbaudlow_%lu=%u\nsdahold_%lu=%u\n", f, (unsigned)SERCOM2->I2CM.BAUD.bit.BAUD, f,
                   (unsigned)SERCOM2->I2CM.BAUD.bit.BAUDLOW, f, (unsigned)SERCOM2->I2CM.CTRLA.bit.SDAHOLD);
        }
        return 0;
    } else if (!strcmp(sc, "flood")) {
        /* the laptop sends without pause: every pass still ends, polls a cell and feeds the watchdog */
        SERCOM2->I2CM.INTFLAG.bit.MB = 1;   /* every cell NACKs its address */
        SERCOM2->I2CM.STATUS.bit.RXNACK = 1;
        setup();
        stub.flood = true;
        size_t most = 0;
        for (int pass = 0; pass < 5; pass++) {
            stub.reads = 0;
            loop();
            most = stub.reads > most ? stub.reads : most;
        }
        uint32_t nacks = 0;
        for (int i = 0; i < MC_N_CELLS; i++)
            nacks += g_link.p.cell[i].nack;
        printf("polls=%lu\nmost_reads_per_pass=%lu\n", (unsigned long)nacks, (unsigned long)most);
        return 0;
    } else if (!strcmp(sc, "stalled_schedule")) {
        /* polling that no longer moves: a transaction handed out and never completed */
        SERCOM2->I2CM.INTFLAG.bit.MB = 1;
        SERCOM2->I2CM.STATUS.bit.RXNACK = 1;
        setup();
        WDT->CLEAR.reg = 0;
        loop();
        int fed_moving = WDT->CLEAR.reg == WDT_CLEAR_CLEAR_KEY;
        mc_txn_t t;
        while (!mc_primary_next(&g_link.p, primary_hw_micros(), &t)) {
        }
        int fed_stalled = 0;
        for (int pass = 0; pass < 20; pass++) {
            WDT->CLEAR.reg = 0;
            loop();
            fed_stalled |= WDT->CLEAR.reg == WDT_CLEAR_CLEAR_KEY;
        }
        printf("fed_moving=%d\nfed_stalled=%d\n", fed_moving, fed_stalled);
        return 0;
    } else if (!strcmp(sc, "fault")) {
        /* a HardFault, then the boot after it: PRIMARY_HEALTH.reset_cause says SYST and FAULT */
        static uint32_t frame[8] = {0, 0, 0, 0, 0, 0, 0x2468u, 0x01000000u};
        PM->RCAUSE.reg = PM_RCAUSE_POR;
        setup();
        if (setjmp(stub.reset) == 0)
            sys_fault(frame, 3);
        PM->RCAUSE.reg = PM_RCAUSE_SYST;
        setup();
        printf("resets=%d\nreset_cause=%u\n", stub.resets, (unsigned)g_link.p.reset_cause);
        return 0;
    } else if (!strcmp(sc, "main")) {
        /* the whole program: boot after a watchdog reset, laptop opens, stops reading, reconnects */
        PM->RCAUSE.reg = PM_RCAUSE_WDT;
        SERCOM2->I2CM.INTFLAG.bit.MB = 1;   /* every cell NACKs its address: fast polls */
        SERCOM2->I2CM.STATUS.bit.RXNACK = 1;
        stub.dtr = false;
        setup();
        printf("wdt_enabled=%d\nwdt_per=%u\nreset_cause=%u\n", (WDT->CTRL.reg & WDT_CTRL_ENABLE) != 0,
               (unsigned)WDT->CONFIG.reg, (unsigned)g_link.p.reset_cause);
        stub.dtr = true;
        static const char open_cmd[] = "O\r";
        stub.in = open_cmd;
        stub.in_len = 2;
        WDT->CLEAR.reg = 0;
        while (stub.now_us < 3000000ul)
            loop();
        printf("wdt_fed=%d\nopen=%d\nsent=%lu\n", WDT->CLEAR.reg == WDT_CLEAR_CLEAR_KEY, g_link.s.open,
               (unsigned long)stub.usb_sent);
        stub.usb_blocked = true;   /* the laptop stops reading */
        while (stub.now_us < 6000000ul)
            loop();
        stub.usb_blocked = false;   /* and reads again: the bank empties */
        stub_usb_host_reads();
        printf("usb_lost=%lu\nusb_tried=%lu\nusb_delivered=%lu\nusb_zeroed=%lu\nusb_fail=%u\nmax_write=%lu\n",
               (unsigned long)g_link.p.usb_lost, (unsigned long)stub.usb_tried, (unsigned long)stub.usb_delivered,
               (unsigned long)stub.usb_zeroed, (unsigned)g_link.p.usb_fail, (unsigned long)stub.usb_max_write);
        stub.dtr = false;   /* the laptop closes the port: a new session */
        loop();
        printf("open_after_close=%d\n", g_link.s.open);
        return 0;
    }
    printf("resets=%u\nstarts=%d\nstops=%d\nscl_falls=%d\ndriven_high=%d\nlines=%.*s\n",
           (unsigned)primary_hw_bus_resets(), stub.starts, stub.stops, stub.scl_falls, stub.driven_high, stub.n_log,
           stub.log);
    return 0;
}
