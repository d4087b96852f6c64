/* USB: the full-speed device controller (registers, endpoint banks in SRAM through DESCADD, flags, its interrupt). */
#include <stdlib.h>
#include <string.h>
#include "sam_usb.h"
#include "sam_vendor_gen.h"

/*
 * The registers of the SAMD21's USB in device mode; endpoint n's banks are 16-byte descriptors in SRAM at
 * DESCADD + 32 n + 16 b (ADDR, PCKSIZE: BYTE_COUNT, MULTI_PACKET_SIZE, SIZE). EPSTATUS.BK0RDY of an OUT bank set
 * means "full" (the CPU clears it to receive), BK1RDY of an IN bank set means "data ready for the host". The host
 * on the port is a link between boards and the laptop (link_usb_host.c).
 */

typedef struct {
    uint8_t connected;
    uint16_t fnum;
} usbdev_t;

static uint8_t *R(sam_mcu_t *m) { return sam_usb_regs(m); }
static uint32_t rd(const uint8_t *p, int n)
{
    uint32_t v = 0;
    for (int k = n - 1; k >= 0; k--)
        v = (v << 8) | p[k];
    return v;
}
static void wr(uint8_t *p, int n, uint32_t v)
{
    for (int k = 0; k < n; k++, v >>= 8)
        p[k] = (uint8_t)v;
}

void sam_usb_irq(sam_mcu_t *m)
{
    uint16_t f = (uint16_t)rd(R(m) + USB_DEVICE_INTFLAG_OFFSET, 2) & (uint16_t)rd(R(m) + USB_DEVICE_INTENSET_OFFSET, 2);
    int any = f != 0;
    for (int ep = 0; ep < 8 && !any; ep++)
        any = (EPINTFLAG(m, ep) & EPINTEN(m, ep)) != 0;
    sam_irq_level(m, sam_periphs[sam_idx.usb].irq, any);
}

/* ---------------------------------------------------------------- endpoint banks in SRAM */

static uint32_t desc_addr(sam_mcu_t *m, int ep, int bank)
{
    return (uint32_t)rd(R(m) + USB_DESCADD_OFFSET, 4) + 32u * (uint32_t)ep + 16u * (uint32_t)bank;
}

uint8_t *sam_usb_ram(sam_mcu_t *m, uint32_t a, uint32_t n)
{
    if (a < SAM_RAM_BASE || a - SAM_RAM_BASE > SAM_RAM_SIZE || n > SAM_RAM_SIZE - (a - SAM_RAM_BASE))
        return NULL;
    sam_ff_ram_written(m);   /* (the controller's DMA, or the host's copy: taken as a write either way) */
    return m->ram + (a - SAM_RAM_BASE);
}

int sam_usb_bank_get(sam_mcu_t *m, int ep, int bank, uint32_t *addr, uint32_t *pck)
{
    uint8_t *d = sam_usb_ram(m, desc_addr(m, ep, bank), 16);
    if (!d)
        return -1;
    *addr = rd(d, 4);
    *pck = rd(d + 4, 4);
    return 0;
}

void sam_usb_bank_set_count(sam_mcu_t *m, int ep, int bank, uint32_t count)
{
    uint8_t *d = sam_usb_ram(m, desc_addr(m, ep, bank), 16);
    if (d)
        wr(d + 4, 4, (rd(d + 4, 4) & ~0x3FFFu) | (count & 0x3FFFu));
}

int sam_usb_present(sam_mcu_t *m)
{
    uint8_t *r = R(m);
    return !m->halted && (r[USB_CTRLA_OFFSET] & USB_CTRLA_ENABLE) && !(r[USB_CTRLA_OFFSET] & USB_CTRLA_MODE) &&
           !(rd(r + USB_DEVICE_CTRLB_OFFSET, 2) & USB_DEVICE_CTRLB_DETACH);
}

void sam_usb_bus_reset_end(sam_mcu_t *m)
{
    wr(R(m) + USB_DEVICE_INTFLAG_OFFSET, 2, rd(R(m) + USB_DEVICE_INTFLAG_OFFSET, 2) | USB_DEVICE_INTFLAG_EORST);
}

void sam_usb_sof(sam_mcu_t *m)
{
    usbdev_t *d = m->pst[sam_idx.usb];
    d->fnum = (uint16_t)((d->fnum + 1) & 0x7FFu);
    wr(R(m) + USB_DEVICE_FNUM_OFFSET, 2, (uint32_t)d->fnum << 3);
    wr(R(m) + USB_DEVICE_INTFLAG_OFFSET, 2, rd(R(m) + USB_DEVICE_INTFLAG_OFFSET, 2) | USB_DEVICE_INTFLAG_SOF);
}

/* ---------------------------------------------------------------- device registers */

static void usb_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(usbdev_t));
    memset(m->pst[pi], 0, sizeof(usbdev_t));
    if (m->w)
        sam_usb_port_reset(m);
}

static int usb_view(sam_mcu_t *m, int pi) { return (m->regs[pi][USB_CTRLA_OFFSET] & USB_CTRLA_MODE) ? 2 : 1; }

static int usb_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    uint32_t off = sam_regs[ri].offset;
    (void)pi;
    if (off == USB_SYNCBUSY_OFFSET) {
        *v = 0;
        return SAM_DONE;
    }
    if (off == USB_DEVICE_EPINTSMRY_OFFSET) {
        uint32_t s = 0;
        for (int ep = 0; ep < 8; ep++)
            if (EPINTFLAG(m, ep) & EPINTEN(m, ep))
                s |= 1u << ep;
        *v = s;
        return SAM_DONE;
    }
    if (off == USB_DEVICE_STATUS_OFFSET) {
        *v = sam_usb_port_attached(m) && sam_usb_present(m) ? 0x44u : 0x04u;   /* LINESTATE J (idle) when connected, full speed */
        return SAM_DONE;
    }
    if (off == USB_FSMSTATUS_OFFSET) {
        *v = sam_usb_port_on(m) ? 0x02u : 0x01u;   /* ON, else OFF */
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int usb_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    uint32_t off = sam_regs[ri].offset;
    if (off == USB_CTRLA_OFFSET) {
        if (v & mask & USB_CTRLA_SWRST) {
            memset(m->regs[pi], 0, sam_periphs[pi].size);
            usb_reset(m, pi);
            sam_usb_irq(m);
            sam_usb_port_attach_check(m);
            return SAM_DONE;
        }
        if (v & mask & USB_CTRLA_MODE) {
            sam_fail(m, "USB host mode is not modelled");
            return SAM_DONE;
        }
    }
    uint8_t before[8];
    for (int ep = 0; ep < 8; ep++)
        before[ep] = EPSTATUS(m, ep);
    sam_generic_write(m, ri, v, mask);
    sam_usb_irq(m);
    if (off == USB_CTRLA_OFFSET || off == USB_DEVICE_CTRLB_OFFSET)
        sam_usb_port_attach_check(m);
    for (int ep = 0; ep < 8; ep++) {
        uint8_t ch = before[ep] ^ EPSTATUS(m, ep);
        if (!ch)
            continue;
        if (ep == 0)
            sam_usb_port_ep0_ready(m);
        else
            sam_usb_port_bulk_ready(m);
    }
    return SAM_DONE;
}

const sam_model_t sam_model_usb = {"Usb", usb_reset, usb_view, usb_read, usb_write, NULL};
