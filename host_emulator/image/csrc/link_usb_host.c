/* The link between a board's USB port and the laptop: a scripted USB host (enumeration, CDC line state, bulk IN/OUT). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam_world.h"
#include "sam_usb.h"

/*
 * The laptop's USB stack, one per port, when attached: once the device is enabled and not detached,
 * a debounce and bus reset (USB_CONNECT_S) end in EORST; SOF every 1 ms; enumeration as an operating system
 * does it (GET_DESCRIPTOR device, SET_ADDRESS, GET_DESCRIPTOR device and configuration, SET_CONFIGURATION),
 * the configuration descriptor parsed for the CDC data interface's endpoints (class 0x0A) and the comm
 * interface (wIndex of class requests); opening the port sends SET_LINE_CODING (115200 8N1) and
 * SET_CONTROL_LINE_STATE (DTR, RTS), closing it clears DTR. That is the script profile (the default). The Linux
 * profile reads what Linux reads besides: the BOS after the device descriptor when bcdUSB >= 2.01, and after the
 * configuration the strings 0, iProduct, iManufacturer and iSerialNumber (wLength 255), recorded with the ids in
 * sam_usb_device_t; once configured it sends cdc_acm's probe (SET_LINE_CODING 9600 8N1), then the laptop's line
 * state as cdc_acm does (sam_usb_set_line). A control IN data stage may come in several banks (full packets until
 * a short or zero-length one, or wLength). Each packet the host moves takes
 * usb_packet_us after the device made it available (an IN bank set ready, an OUT bank armed). A control
 * transfer's stage that the device does not complete in USB_STAGE_TIMEOUT_S fails the transfer (noted). What
 * is not modelled: electrical signalling, NAK handshakes between packets (a bank not ready is simply waited
 * for), isochronous endpoints, suspend/resume and remote wakeup, the host's own retries.
 */

#define USB_CONNECT_S 0.110          /* debounce (100 ms) + bus reset (10 ms) */
#define USB_STAGE_TIMEOUT_S 0.5
#define USB_GAP_S 200e-6             /* between two control transfers of the host's script */
#define SOF_S 1e-3

enum { H_NONE = 0, H_RESET_END, H_SOF, H_CTRL, H_IN, H_OUT, H_START, H_TIMEOUT };
enum { C_IDLE = 0, C_DATA_IN, C_DATA_OUT, C_STATUS_IN, C_STATUS_OUT };
/* the host's script position */
enum { S_DETACHED = 0, S_RESETTING, S_DEV64, S_ADDR, S_DEV18, S_CFG9, S_CFGALL, S_SETCFG, S_READY,
       S_BOS5, S_BOSALL, S_STR0, S_STR };   /* the Linux profile's own steps */


static int linux_profile(const sam_usbhost_t *h) { return h->profile == SAM_USB_PROFILE_LINUX; }

/* the device left the bus (a reset, DETACH): counted; under the Linux profile its next enumeration is a new tty */
static void host_detached(sam_usbhost_t *h)
{
    h->dev.detaches++;
    h->sent_baud = 0;
    h->sent_ctl = 0;
    h->dev.baud = 0;
    h->dev.dtr = h->dev.rts = 0;
    if (linux_profile(h)) {
        h->want_baud = SAM_USB_LINUX_BAUD;
        h->want_ctl = 0;
    }
}

static uint64_t tu(double s) { return (uint64_t)(s * (double)SAM_TU_HZ); }

/* ---------------------------------------------------------------- the host's event queue (its event source) */

static sam_usbhost_t *host(sam_mcu_t *m) { return &m->w->usb[m->id]; }

static void hpush(sam_mcu_t *m, uint64_t t, int kind, int arg)
{
    sam_usbhost_t *h = host(m);
    for (int i = 0; i < h->hq_n; i++)   /* one pending event of a kind and argument at a time */
        if (h->hq[i].kind == kind && h->hq[i].arg == arg)
            return;
    if (h->hq_n >= SAM_USB_HQ) {
        sam_fail(m, "USB host: event queue full");
        return;
    }
    int i = h->hq_n++;
    while (i > 0 && h->hq[i - 1].t > t) {
        h->hq[i] = h->hq[i - 1];
        i--;
    }
    h->hq[i].t = t;
    h->hq[i].kind = kind;
    h->hq[i].arg = arg;
    sam_slot_set(m, h->slot, h->hq[0].t);
}

static void hclear(sam_mcu_t *m, int kind)
{
    sam_usbhost_t *h = host(m);
    int k = 0;
    for (int i = 0; i < h->hq_n; i++)
        if (h->hq[i].kind != kind)
            h->hq[k++] = h->hq[i];
    h->hq_n = k;
    sam_slot_set(m, h->slot, k ? h->hq[0].t : SAM_NEVER);
}

/* out-of-band connect/disconnect as the device's attach state or the cable changes */
static void attach_check(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    if (!h->attached)
        return;
    int present = sam_usb_present(m);
    if (present && h->step == S_DETACHED) {
        h->step = S_RESETTING;
        hpush(m, sam_now(m) + tu(USB_CONNECT_S), H_RESET_END, 0);
    } else if (!present && h->step != S_DETACHED) {
        h->step = S_DETACHED;
        h->enumerated = h->configured = 0;
        h->busy = C_IDLE;
        hclear(m, H_SOF);
        hclear(m, H_CTRL);
        hclear(m, H_IN);
        hclear(m, H_OUT);
        h->info.attached = 1;
        h->info.enumerated = h->info.configured = 0;
        host_detached(h);
    }
}

static void setup_packet(uint8_t s[8], uint8_t type, uint8_t req, uint16_t value, uint16_t index, uint16_t len)
{
    s[0] = type;
    s[1] = req;
    s[2] = (uint8_t)value;
    s[3] = (uint8_t)(value >> 8);
    s[4] = (uint8_t)index;
    s[5] = (uint8_t)(index >> 8);
    s[6] = (uint8_t)len;
    s[7] = (uint8_t)(len >> 8);
}


static void parse_config(sam_mcu_t *m, const uint8_t *d, uint32_t n)
{
    sam_usbhost_t *h = host(m);
    int comm, in, out;
    if (sam_usbd_parse_config(d, n, &comm, &in, &out)) {
        sam_note(m, "%s: USB host: no CDC bulk endpoints in the configuration descriptor", m->name);
        h->error = h->info.error = 1;
        return;
    }
    h->cdc_in = h->dev.data_in = in;
    h->cdc_out = h->dev.data_out = out;
    h->dev.comm_if = comm;
}

static void ctl_start(sam_mcu_t *m, const uint8_t setup[8], const uint8_t *data, uint32_t n)
{
    sam_usbhost_t *h = host(m);
    uint32_t addr, pck;
    uint64_t now = sam_now(m);
    if (sam_usb_bank_get(m, 0, 0, &addr, &pck) || !sam_usb_ram(m, addr, 8)) {
        sam_note(m, "%s: USB host: EP0 has no SETUP buffer (DESCADD not set up)", m->name);
        h->error = h->info.error = 1;
        return;
    }
    memcpy(h->setup, setup, 8);
    uint16_t wlen = (uint16_t)(setup[6] | setup[7] << 8);
    h->ctl_len = setup[0] & 0x80 ? (wlen < sizeof h->ctl_data ? wlen : sizeof h->ctl_data)
                                 : (n < sizeof h->ctl_data ? n : sizeof h->ctl_data);
    if (!(setup[0] & 0x80) && data)
        memcpy(h->ctl_data, data, h->ctl_len);
    h->ctl_done = 0;
    memcpy(sam_usb_ram(m, addr, 8), setup, 8);
    sam_usb_bank_set_count(m, 0, 0, 8);
    EPSTATUS(m, 0) |= BK0RDY;
    EPINTFLAG(m, 0) |= RXSTP;
    h->info.control_transfers++;
    h->busy = setup[0] & 0x80 ? C_DATA_IN : (wlen ? C_DATA_OUT : C_STATUS_IN);
    hpush(m, now + tu(USB_STAGE_TIMEOUT_S), H_TIMEOUT, (int)h->info.control_transfers);
    sam_usb_irq(m);
}

static void next_script_step(sam_mcu_t *m);

/* the device made a bank of EP0 available: move the stage's packet after the packet time */
static void ctl_poke(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    uint64_t t = sam_now(m) + tu(m->w->cfg.usb_packet_us * 1e-6);
    if ((h->busy == C_DATA_IN || h->busy == C_STATUS_IN) && (EPSTATUS(m, 0) & BK1RDY))
        hpush(m, t, H_CTRL, 0);
    if (h->busy == C_DATA_OUT && !(EPSTATUS(m, 0) & BK0RDY))
        hpush(m, t, H_CTRL, 0);
}

static void ctl_step(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    uint32_t addr, pck;
    uint64_t now = sam_now(m);
    if (h->busy == C_DATA_IN || h->busy == C_STATUS_IN) {
        if (!(EPSTATUS(m, 0) & BK1RDY))
            return;
        if (sam_usb_bank_get(m, 0, 1, &addr, &pck))
            return;
        uint32_t cnt = pck & 0x3FFFu;
        if (h->busy == C_DATA_IN) {
            uint32_t take = cnt < h->ctl_len - h->ctl_done ? cnt : h->ctl_len - h->ctl_done;
            uint8_t *src = sam_usb_ram(m, addr, take);
            if (take && src) {
                memcpy(h->ctl_data + h->ctl_done, src, take);
                h->ctl_done += take;
            }
        }
        EPSTATUS(m, 0) &= (uint8_t)~BK1RDY;
        EPINTFLAG(m, 0) |= TRCPT1;
        h->info.in_packets++;
        /* a full packet (a bank of whole packets) with more asked for: the data stage goes on; a short packet, a
         * zero-length one or all that was asked ends it */
        int ep0 = h->ep0_size > 0 ? h->ep0_size : 64;
        if (h->busy == C_DATA_IN && cnt && cnt % (uint32_t)ep0 == 0 && h->ctl_done < h->ctl_len) {
            sam_usb_irq(m);
            return;
        }
        if (h->busy == C_DATA_IN) {
            /* status stage: an OUT ZLP, accepted by the hardware whatever the CPU does */
            h->busy = C_STATUS_OUT;
            hpush(m, now + tu(m->w->cfg.usb_packet_us * 1e-6), H_CTRL, 0);
        } else {
            h->busy = C_IDLE;
            hclear(m, H_TIMEOUT);
            next_script_step(m);
        }
        sam_usb_irq(m);
        return;
    }
    if (h->busy == C_STATUS_OUT) {
        sam_usb_bank_set_count(m, 0, 0, 0);
        EPSTATUS(m, 0) |= BK0RDY;
        EPINTFLAG(m, 0) |= TRCPT0;
        h->busy = C_IDLE;
        hclear(m, H_TIMEOUT);
        sam_usb_irq(m);
        next_script_step(m);
        return;
    }
    if (h->busy == C_DATA_OUT) {
        if (EPSTATUS(m, 0) & BK0RDY)
            return;
        if (sam_usb_bank_get(m, 0, 0, &addr, &pck))
            return;
        uint8_t *dst = sam_usb_ram(m, addr, h->ctl_len);
        if (!dst) {
            sam_note(m, "%s: USB host: EP0 OUT buffer outside SRAM", m->name);
            return;
        }
        memcpy(dst, h->ctl_data, h->ctl_len);
        sam_usb_bank_set_count(m, 0, 0, h->ctl_len);
        EPSTATUS(m, 0) |= BK0RDY;
        EPINTFLAG(m, 0) |= TRCPT0;
        h->info.out_packets++;
        h->busy = C_STATUS_IN;
        sam_usb_irq(m);
        ctl_poke(m);
    }
}

static void ctl_queue(sam_mcu_t *m, const uint8_t setup[8], const uint8_t *data, uint32_t n)
{
    sam_usbhost_t *h = host(m);
    if (h->ctl_queue_n >= 8)
        return;
    memcpy(h->ctl_queue[h->ctl_queue_n], setup, 8);
    if (n > 64)
        n = 64;
    if (data && n)
        memcpy(h->ctl_queue[h->ctl_queue_n] + 8, data, n);
    h->ctl_queue_len[h->ctl_queue_n++] = n;
    if (h->busy == C_IDLE && h->step == S_READY)
        hpush(m, sam_now(m) + tu(USB_GAP_S), H_START, 0);
}

static void line_state(sam_mcu_t *m, int dtr)
{
    uint8_t s[8];
    if (dtr) {
        static const uint8_t coding[7] = {0x00, 0xC2, 0x01, 0x00, 0, 0, 8};   /* 115200 baud, 1 stop, none, 8 */
        setup_packet(s, 0x21, 0x20, 0, (uint16_t)host(m)->dev.comm_if, 7);
        ctl_queue(m, s, coding, 7);
    }
    setup_packet(s, 0x21, 0x22, dtr ? 3 : 0, (uint16_t)host(m)->dev.comm_if, 0);
    ctl_queue(m, s, NULL, 0);
}

/* the laptop's line state, one request at a time as cdc_acm sends them: raising DTR/RTS (an open) before a new
 * speed (its tcsetattr), a new speed before dropping them (a close) */
static void line_sync(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    uint8_t s[8];
    uint16_t comm = (uint16_t)h->dev.comm_if;
    int ctl_diff = h->want_ctl != h->sent_ctl;
    int baud_diff = h->want_baud && h->want_baud != h->sent_baud;
    if (ctl_diff && (!baud_diff || (h->want_ctl & ~h->sent_ctl & 1))) {
        setup_packet(s, 0x21, 0x22, (uint16_t)h->want_ctl, comm, 0);
        h->sent_ctl = h->want_ctl;
        h->dev.dtr = h->sent_ctl & 1;
        h->dev.rts = (h->sent_ctl >> 1) & 1;
        ctl_start(m, s, NULL, 0);
    } else if (baud_diff) {
        uint32_t b = h->want_baud;
        uint8_t coding[7] = {(uint8_t)b, (uint8_t)(b >> 8), (uint8_t)(b >> 16), (uint8_t)(b >> 24), 0, 0, 8};
        setup_packet(s, 0x21, 0x20, 0, comm, 7);
        h->sent_baud = h->dev.baud = b;
        ctl_start(m, s, coding, 7);
    }
}

static uint16_t le16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }

/* the Linux profile: the next string to read (iProduct, iManufacturer, iSerialNumber), or SET_CONFIGURATION */
static int next_string(sam_usbhost_t *h)
{
    while (h->str_k < 3 && !h->istr[h->str_k])
        h->str_k++;
    return h->str_k < 3 ? S_STR : S_SETCFG;
}

static void next_script_step(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    uint8_t s[8];
    uint64_t t = sam_now(m) + tu(USB_GAP_S);
    switch (h->step) {
    case S_DEV64: h->step = S_ADDR; break;
    case S_ADDR: h->step = S_DEV18; break;
    case S_DEV18:
        sam_usbd_parse_device(&h->dev, h->ctl_data, h->ctl_done, h->istr, &h->ep0_size);
        h->step = linux_profile(h) && h->dev.bcd_usb >= 0x0201 ? S_BOS5 : S_CFG9;
        break;
    case S_BOS5: {
        uint16_t total = h->ctl_done >= 4 ? le16(h->ctl_data + 2) : 5;
        h->step = S_BOSALL;
        setup_packet(s, 0x80, 6, 0x0F00, 0, total > sizeof h->ctl_data ? sizeof h->ctl_data : total);
        memcpy(h->setup, s, 8);
        hpush(m, t, H_START, 1);
        return;
    }
    case S_BOSALL: h->step = S_CFG9; break;
    case S_STR0:
        h->langid = h->ctl_done >= 4 ? le16(h->ctl_data + 2) : 0x0409;
        h->str_k = 0;
        h->step = next_string(h);
        break;
    case S_STR: {
        char *dst = h->str_k == 0 ? h->dev.product : h->str_k == 1 ? h->dev.manufacturer : h->dev.serial;
        sam_usbd_string(dst, sizeof h->dev.serial, h->ctl_data, h->ctl_done);
        h->str_k++;
        h->step = next_string(h);
        break;
    }
    case S_CFG9: {
        uint16_t total = (uint16_t)(h->ctl_data[2] | h->ctl_data[3] << 8);
        h->ctl_len = total;
        h->step = S_CFGALL;
        setup_packet(s, 0x80, 6, 0x0200, 0, total > sizeof h->ctl_data ? sizeof h->ctl_data : total);
        memcpy(h->setup, s, 8);
        hpush(m, t, H_START, 1);
        return;
    }
    case S_CFGALL:
        parse_config(m, h->ctl_data, h->ctl_done);
        h->step = linux_profile(h) && (h->istr[0] || h->istr[1] || h->istr[2]) ? S_STR0 : S_SETCFG;
        break;
    case S_SETCFG:
        h->step = S_READY;
        h->configured = h->enumerated = 1;
        h->info.configured = h->info.enumerated = 1;
        h->dev.enumerations++;
        sam_note(m, "%s: USB enumerated and configured at t = %.3f s", m->name,
                       (double)sam_now(m) / (double)SAM_TU_HZ);
        if (linux_profile(h)) {   /* cdc_acm's probe: 9600 8N1; then the laptop's line state (line_sync) */
            static const uint8_t probe[7] = {0x80, 0x25, 0, 0, 0, 0, 8};
            setup_packet(s, 0x21, 0x20, 0, (uint16_t)h->dev.comm_if, 7);
            ctl_queue(m, s, probe, 7);
            h->sent_baud = h->dev.baud = SAM_USB_LINUX_BAUD;
        } else if (h->dtr) {
            line_state(m, 1);
        }
        break;
    case S_READY:
        break;
    default: return;
    }
    hpush(m, t, H_START, 0);
}

/* start the script's next control transfer, or the next queued request */
static void start_next(sam_mcu_t *m, int keep_setup)
{
    sam_usbhost_t *h = host(m);
    uint8_t s[8];
    if (h->busy != C_IDLE)
        return;
    switch (h->step) {
    case S_DEV64: setup_packet(s, 0x80, 6, 0x0100, 0, 64); break;
    case S_ADDR: setup_packet(s, 0x00, 5, 5, 0, 0); break;
    case S_DEV18: setup_packet(s, 0x80, 6, 0x0100, 0, 18); break;
    case S_CFG9: setup_packet(s, 0x80, 6, 0x0200, 0, 9); break;
    case S_CFGALL: memcpy(s, h->setup, 8); break;
    case S_SETCFG: setup_packet(s, 0x00, 9, 1, 0, 0); break;
    case S_BOS5: setup_packet(s, 0x80, 6, 0x0F00, 0, 5); break;
    case S_BOSALL: memcpy(s, h->setup, 8); break;
    case S_STR0: setup_packet(s, 0x80, 6, 0x0300, 0, 255); break;
    case S_STR: setup_packet(s, 0x80, 6, (uint16_t)(0x0300 | h->istr[h->str_k]), h->langid, 255); break;
    case S_READY:
        if (!h->ctl_queue_n) {
            line_sync(m);
            return;
        }
        memcpy(s, h->ctl_queue[0], 8);
        ctl_start(m, s, h->ctl_queue[0] + 8, h->ctl_queue_len[0]);
        memmove(h->ctl_queue, h->ctl_queue + 1, sizeof h->ctl_queue[0] * (size_t)(h->ctl_queue_n - 1));
        memmove(h->ctl_queue_len, h->ctl_queue_len + 1, sizeof h->ctl_queue_len[0] * (size_t)(h->ctl_queue_n - 1));
        h->ctl_queue_n--;
        return;
    default: return;
    }
    (void)keep_setup;
    ctl_start(m, s, NULL, 0);
}

/* bulk IN: the host takes the packet the device made ready */
static void bulk_in(sam_mcu_t *m, int ep)
{
    sam_usbhost_t *h = host(m);
    uint32_t addr, pck;
    if (!(EPSTATUS(m, ep) & BK1RDY) || h->no_read || sam_usb_bank_get(m, ep, 1, &addr, &pck))
        return;
    uint32_t cnt = pck & 0x3FFFu;
    if (h->in_n + cnt > SAM_USB_BUF)
        return;   /* the laptop's buffer is full: the packet waits (NAK) */
    uint8_t *src = cnt ? sam_usb_ram(m, addr, cnt) : NULL;
    for (uint32_t k = 0; k < cnt && src; k++)
        h->in[(h->in_head + h->in_n++) % SAM_USB_BUF] = src[k];
    h->info.in_bytes += cnt;
    h->info.in_packets++;
    EPSTATUS(m, ep) &= (uint8_t)~BK1RDY;
    EPINTFLAG(m, ep) |= TRCPT1;
    sam_usb_irq(m);
}

/* bulk OUT: the host fills the armed bank with the laptop's bytes */
static void bulk_out(sam_mcu_t *m, int ep)
{
    sam_usbhost_t *h = host(m);
    uint32_t addr, pck;
    if ((EPSTATUS(m, ep) & BK0RDY) || !h->out_n || sam_usb_bank_get(m, ep, 0, &addr, &pck))
        return;
    uint32_t room = (pck >> 14) & 0x3FFFu;   /* MULTI_PACKET_SIZE: bytes the bank takes */
    uint32_t n = h->out_n < 64 ? h->out_n : 64;
    if (room && n > room)
        n = room;
    uint8_t *dst = sam_usb_ram(m, addr, n);
    if (!dst) {
        sam_note(m, "%s: USB host: OUT bank outside SRAM", m->name);
        return;
    }
    for (uint32_t k = 0; k < n; k++)
        dst[k] = h->out[(h->out_head + k) % SAM_USB_BUF];
    h->out_head = (h->out_head + n) % SAM_USB_BUF;
    h->out_n -= n;
    h->info.out_bytes += n;
    h->info.out_packets++;
    sam_usb_bank_set_count(m, ep, 0, n);
    EPSTATUS(m, ep) |= BK0RDY;
    EPINTFLAG(m, ep) |= TRCPT0;
    sam_usb_irq(m);
}

static void bulk_poke(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    if (!h->configured || h->cdc_in <= 0)
        return;
    uint64_t t = sam_now(m) + tu(m->w->cfg.usb_packet_us * 1e-6);
    if ((EPSTATUS(m, h->cdc_in) & BK1RDY) && !h->no_read)
        hpush(m, t, H_IN, h->cdc_in);
    if (!(EPSTATUS(m, h->cdc_out) & BK0RDY) && h->out_n && EPCFG(m, h->cdc_out))
        hpush(m, t, H_OUT, h->cdc_out);
}

static void host_fire(sam_mcu_t *m, void *ctx)
{
    (void)ctx;
    uint64_t now = sam_now(m);
    sam_usbhost_t *h = host(m);
    while (h->hq_n && h->hq[0].t <= now) {
        sam_hev_t e = h->hq[0];
        memmove(h->hq, h->hq + 1, sizeof h->hq[0] * (size_t)(h->hq_n - 1));
        h->hq_n--;
        if (m->halted)
            continue;
        switch (e.kind) {
        case H_RESET_END:
            if (h->step != S_RESETTING)
                break;
            sam_usb_bus_reset_end(m);
            h->step = S_DEV64;
            memset(h->istr, 0, sizeof h->istr);   /* a new enumeration: what the device says is read again */
            h->dev.described = 0;
            h->dev.vid = h->dev.pid = h->dev.bcd_usb = h->dev.bcd_device = 0;
            h->dev.manufacturer[0] = h->dev.product[0] = h->dev.serial[0] = 0;
            hpush(m, now + tu(SOF_S), H_SOF, 0);
            hpush(m, now + tu(1e-3), H_START, 0);
            sam_usb_irq(m);
            break;
        case H_SOF:
            sam_usb_sof(m);
            h->info.sof++;
            hpush(m, e.t + tu(SOF_S), H_SOF, 0);
            sam_usb_irq(m);
            break;
        case H_START: start_next(m, e.arg); break;
        case H_CTRL: ctl_step(m); break;
        case H_IN: bulk_in(m, e.arg); break;
        case H_OUT: bulk_out(m, e.arg); break;
        case H_TIMEOUT:
            if (h->busy != C_IDLE && (uint64_t)e.arg == h->info.control_transfers) {
                sam_note(m, "%s: USB host: control request %02x %02x not completed by the device in "
                               "%.0f ms", m->name, h->setup[0], h->setup[1], USB_STAGE_TIMEOUT_S * 1e3);
                h->busy = C_IDLE;
                h->error = h->info.error = 1;
            }
            break;
        default: break;
        }
    }
    sam_slot_set(m, h->slot, h->hq_n ? h->hq[0].t : SAM_NEVER);
    bulk_poke(m);
}

/* ---------------------------------------------------------------- the port, as the device sees it */

/* The host's event source on a board (registered when the world loads it; the host is plugged in later). */
void sam_usb_port_init(sam_mcu_t *m)
{
    host(m)->slot = sam_source_add(m, host_fire, NULL, NULL, 0);
}

void sam_usb_port_reset(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    if (h->attached && h->step != S_DETACHED) {
        h->step = S_DETACHED;
        h->busy = C_IDLE;
        h->enumerated = h->configured = 0;
        h->info.enumerated = h->info.configured = 0;
        host_detached(h);
    }
    h->hq_n = 0;
    sam_slot_set(m, h->slot, SAM_NEVER);
}

void sam_usb_port_ep0_ready(sam_mcu_t *m) { ctl_poke(m); }
void sam_usb_port_bulk_ready(sam_mcu_t *m) { bulk_poke(m); }
void sam_usb_port_attach_check(sam_mcu_t *m) { attach_check(m); }
int sam_usb_port_attached(sam_mcu_t *m) { return host(m)->attached; }
int sam_usb_port_on(sam_mcu_t *m) { return host(m)->step >= S_DEV64; }

/* ---------------------------------------------------------------- to the API (link_usb_api.c) */

void sam_usb_host_line_state(sam_mcu_t *m, int dtr) { line_state(m, dtr); }
void sam_usb_host_queue(sam_mcu_t *m, const uint8_t setup[8], const uint8_t *data, uint32_t n)
{
    ctl_queue(m, setup, data, n);
}

/* the laptop's line state changed: an idle, configured host sends it after the gap between two requests */
void sam_usb_host_line_changed(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    if (h->step == S_READY && h->busy == C_IDLE)
        hpush(m, sam_now(m) + tu(USB_GAP_S), H_START, 0);
}
