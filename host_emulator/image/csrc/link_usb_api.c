/* The API of the laptop's USB host on each board's port (sam_api.h): plug in, profile, line state, bytes, info. */
#include <string.h>
#include "sam_world.h"
#include "sam_usb.h"

static uint64_t tu(double s) { return (uint64_t)(s * (double)SAM_TU_HZ); }

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
    /* USB_API_S after the world's time; a board already past that (its clock moved on by a stall, such as NVMCTRL
     * programming a row) sees the host's action at its own time: never in a board's past */
    uint64_t t = w->t + tu(USB_API_S);
    return m->t > t ? m->t : t;
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
    sam_usb_port_attach_check(m);
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
        sam_usb_host_line_state(m, dtr);
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
    sam_usb_port_bulk_ready(m);
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
        sam_usb_port_bulk_ready(m);   /* room again: a waiting packet may move */
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
    sam_usb_host_queue(m, setup, data, n);
    m->t_blk = saved;
    return 0;
}

int sam_usb_set_profile(sam_world_t *w, int mcu, int32_t profile)
{
    if (!board(w, mcu) || w->usb[mcu].attached || (profile != SAM_USB_PROFILE_SCRIPT && profile != SAM_USB_PROFILE_LINUX))
        return -1;
    sam_usbhost_t *h = &w->usb[mcu];
    h->profile = h->dev.profile = profile;
    h->want_baud = profile == SAM_USB_PROFILE_LINUX ? SAM_USB_LINUX_BAUD : 0;
    h->want_ctl = 0;
    return 0;
}

int sam_usb_set_line(sam_world_t *w, int mcu, uint32_t baud, int32_t dtr, int32_t rts)
{
    sam_mcu_t *m = board(w, mcu);
    if (!m || !w->usb[mcu].attached)
        return -1;
    sam_usbhost_t *h = &w->usb[mcu];
    if (baud)
        h->want_baud = baud;
    h->want_ctl = (dtr ? 1 : 0) | (rts ? 2 : 0);
    uint64_t saved = m->t_blk;
    m->t_blk = api_time(w, m);
    sam_usb_host_line_changed(m);
    m->t_blk = saved;
    return 0;
}

int sam_usb_device(const sam_world_t *w, int mcu, sam_usb_device_t *out)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU)
        return -1;
    *out = w->usb[mcu].dev;
    return 0;
}
