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
 * the configuration descriptor parsed for the CDC data endpoints; opening the port sends SET_LINE_CODING
 * (115200 8N1) and SET_CONTROL_LINE_STATE (DTR, RTS), closing it clears DTR. Each packet the host moves takes
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
enum { S_DETACHED = 0, S_RESETTING, S_DEV64, S_ADDR, S_DEV18, S_CFG9, S_CFGALL, S_SETCFG, S_READY };

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
    int in = -1, out = -1;
    for (uint32_t i = 0; i + 2 <= n && d[i] >= 2; i += d[i]) {
        if (d[i + 1] == 5 && i + 7 <= n && (d[i + 3] & 3) == 2) {   /* a bulk endpoint */
            int ep = d[i + 2] & 0x0F;
            if (d[i + 2] & 0x80)
                in = ep;
            else
                out = ep;
        }
    }
    if (in < 0 || out < 0) {
        sam_note(m, "%s: USB host: no CDC bulk endpoints in the configuration descriptor", m->name);
        h->error = h->info.error = 1;
        return;
    }
    h->cdc_in = in;
    h->cdc_out = out;
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
    h->ctl_len = setup[0] & 0x80 ? wlen : (n < sizeof h->ctl_data ? n : sizeof h->ctl_data);
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
        setup_packet(s, 0x21, 0x20, 0, 0, 7);
        ctl_queue(m, s, coding, 7);
    }
    setup_packet(s, 0x21, 0x22, dtr ? 3 : 0, 0, 0);
    ctl_queue(m, s, NULL, 0);
}

static void next_script_step(sam_mcu_t *m)
{
    sam_usbhost_t *h = host(m);
    uint8_t s[8];
    uint64_t t = sam_now(m) + tu(USB_GAP_S);
    switch (h->step) {
    case S_DEV64: h->step = S_ADDR; break;
    case S_ADDR: h->step = S_DEV18; break;
    case S_DEV18: h->step = S_CFG9; break;
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
        h->step = S_SETCFG;
        break;
    case S_SETCFG:
        h->step = S_READY;
        h->configured = h->enumerated = 1;
        h->info.configured = h->info.enumerated = 1;
        sam_note(m, "%s: USB enumerated and configured at t = %.3f s", m->name,
                       (double)sam_now(m) / (double)SAM_TU_HZ);
        if (h->dtr)
            line_state(m, 1);
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
    case S_READY:
        if (!h->ctl_queue_n)
            return;
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
    }
    h->hq_n = 0;
    sam_slot_set(m, h->slot, SAM_NEVER);
}

void sam_usb_port_ep0_ready(sam_mcu_t *m) { ctl_poke(m); }
void sam_usb_port_bulk_ready(sam_mcu_t *m) { bulk_poke(m); }
void sam_usb_port_attach_check(sam_mcu_t *m) { attach_check(m); }
int sam_usb_port_attached(sam_mcu_t *m) { return host(m)->attached; }
int sam_usb_port_on(sam_mcu_t *m) { return host(m)->step >= S_DEV64; }

/* ---------------------------------------------------------------- the API (called between runs) */

void sam_usb_world_init(sam_world_t *w)
{
    memset(w->usb, 0, sizeof w->usb);
}

static sam_mcu_t *board(sam_world_t *w, int mcu)
{
    return mcu >= 0 && mcu < SAM_MAX_MCU ? w->mcu[mcu] : NULL;
}

/* A host action from outside (between runs) reaches the port USB_API_S after the world's time: later than any
 * board can be (a board stops at the first block boundary at or after the world's time, within a block's
 * cycles), and the same however the world schedules the boards. */
#define USB_API_S 50e-6
static uint64_t api_time(sam_world_t *w, sam_mcu_t *m)
{
    uint64_t t = w->t + tu(USB_API_S);
    if (m->t > t && !m->halted && !m->err)
        sam_fail(m, "USB host action at %.6f s but the board is already at %.6f s", (double)t / (double)SAM_TU_HZ,
                 (double)m->t / (double)SAM_TU_HZ);
    return t;
}

int sam_usb_attach(sam_world_t *w, int mcu)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m)
        return -1;
    sam_usbhost_t *h = &w->usb[mcu];
    if (h->attached)
        return 0;
    h->attached = 1;
    h->info.attached = 1;
    uint64_t saved = m->t_blk;
    m->t_blk = api_time(w, m);
    attach_check(m);
    m->t_blk = saved;
    return 0;
}

int sam_usb_set_dtr(sam_world_t *w, int mcu, int32_t dtr)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m || !w->usb[mcu].attached)
        return -1;
    sam_usbhost_t *h = &w->usb[mcu];
    dtr = dtr ? 1 : 0;
    if (h->dtr == dtr)
        return 0;
    h->dtr = dtr;
    h->info.dtr = dtr;
    if (h->configured) {
        uint64_t saved = m->t_blk;
        m->t_blk = api_time(w, m);
        line_state(m, dtr);
        m->t_blk = saved;
    }
    return 0;
}

int sam_usb_write(sam_world_t *w, int mcu, const uint8_t *data, uint32_t n)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m || !w->usb[mcu].attached)
        return -1;
    sam_usbhost_t *h = &w->usb[mcu];
    uint32_t k = 0;
    for (; k < n && h->out_n < SAM_USB_BUF; k++)
        h->out[(h->out_head + h->out_n++) % SAM_USB_BUF] = data[k];
    uint64_t saved = m->t_blk;
    m->t_blk = api_time(w, m);
    bulk_poke(m);
    m->t_blk = saved;
    return (int)k;
}

uint32_t sam_usb_read(sam_world_t *w, int mcu, uint8_t *buf, uint32_t cap)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m)
        return 0;
    sam_usbhost_t *h = &w->usb[mcu];
    uint32_t n = h->in_n < cap ? h->in_n : cap;
    for (uint32_t k = 0; k < n; k++)
        buf[k] = h->in[(h->in_head + k) % SAM_USB_BUF];
    h->in_head = (h->in_head + n) % SAM_USB_BUF;
    h->in_n -= n;
    if (n) {
        uint64_t saved = m->t_blk;
        m->t_blk = api_time(w, m);
        bulk_poke(m);   /* room again: a waiting packet may move */
        m->t_blk = saved;
    }
    return n;
}

int sam_usb_info(const sam_world_t *w, int mcu, sam_usb_info_t *out)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU)
        return -1;
    *out = w->usb[mcu].info;
    out->dtr = w->usb[mcu].dtr;
    return 0;
}

int sam_usb_control(sam_world_t *w, int mcu, const uint8_t setup[8], const uint8_t *data, uint32_t n)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m || !w->usb[mcu].attached)
        return -1;
    uint64_t saved = m->t_blk;
    m->t_blk = api_time(w, m);
    ctl_queue(m, setup, data, n);
    m->t_blk = saved;
    return 0;
}
