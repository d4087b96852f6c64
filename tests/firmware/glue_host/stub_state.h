/* State of the host stand-ins that the glue test drivers set and inspect. */
#pragma once
#include <setjmp.h>
#include <stddef.h>
#include <stdint.h>

typedef struct {
    int mode, out;
} stub_pin_t;

typedef struct {
    unsigned long now_us;
    void (*on_micros)(void);   /* called at every micros(): a scenario's peripheral */
    stub_pin_t pin[32];
    int sda, scl;              /* line levels (released = high) */
    int starts, stops, scl_falls, driven_high;
    char log[256];             /* line states: '0' + (scl << 1 | sda) at each change */
    int n_log;
    uint32_t attached;
    void (*isr[32])(void);     /* attached pin handlers */
    int irq_off;               /* noInterrupts() in force */
    uint32_t pending;          /* pins whose edge waits for interrupts() */
    int edge_on_first_attach;  /* > 0: this pin changes level during the first attachInterrupt */
    int prio[32];              /* NVIC priority per IRQ as last set (a driver presets -1: never set) */
    /* USB serial */
    const char *in;
    size_t in_len, in_pos;
    bool flood;                /* the host never stops sending ('x' forever) */
    size_t reads;              /* bytes read since the driver last cleared it */
    bool dtr, usb_blocked;
    size_t usb_tried, usb_sent, usb_writes, usb_max_write;
    /* the core's IN endpoint bank (USBCore.cpp send): one armed packet until the host reads it */
    bool bank_ready, timed_out;
    size_t bank_bytes;
    size_t usb_delivered, usb_zeroed;   /* bytes the host read; armed bytes the core's timeout zeroed */
    int wire_begins, wire_ends;
    size_t wire_rx, wire_reads;   /* bytes the stand-in Wire holds from the primary; bytes read from it */
    jmp_buf reset;             /* NVIC_SystemReset() longjmps here (value 1) */
    int resets;
} stub_state_t;

extern stub_state_t stub;
/* The host reads the IN bank if it is reading (not usb_blocked). */
void stub_usb_host_reads(void);
/* The level of an Arduino pin flips (its PORT IN bit); its handler runs now, or at interrupts() when off. */
void stub_edge(uint32_t pin);
