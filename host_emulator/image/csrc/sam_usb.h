/* The USB device controller's endpoint banks and flags, shared by its model (sam_usb.c) and the host on its port. */
#ifndef SAM_USB_H
#define SAM_USB_H

#include "sam.h"
#include "sam_vendor_gen.h"   /* before the short names below: its structs have fields so named */

/* Endpoint n's registers in the device's window; its banks are 16-byte descriptors in SRAM at DESCADD + 32 n + 16 b
 * (ADDR, PCKSIZE: BYTE_COUNT, MULTI_PACKET_SIZE, SIZE). */
static inline uint8_t *sam_usb_regs(sam_mcu_t *m) { return m->regs[sam_idx.usb]; }
#define EP_BASE(ep) (0x100u + 0x20u * (uint32_t)(ep))
#define EPCFG(m, ep) (sam_usb_regs(m)[EP_BASE(ep) + 0x00])
#define EPSTATUS(m, ep) (sam_usb_regs(m)[EP_BASE(ep) + 0x06])
#define EPINTFLAG(m, ep) (sam_usb_regs(m)[EP_BASE(ep) + 0x07])
#define EPINTEN(m, ep) (sam_usb_regs(m)[EP_BASE(ep) + 0x09])
#define BK0RDY 0x40u
#define BK1RDY 0x80u
#define TRCPT0 0x01u
#define TRCPT1 0x02u
#define RXSTP 0x10u

/* ---- sam_usb.c: the device, as the host on its port sees it ---- */
void sam_usb_irq(sam_mcu_t *m);                            /* after a flag changed */
int sam_usb_present(sam_mcu_t *m);                         /* enabled in device mode, attached (CTRLB.DETACH = 0) */
uint8_t *sam_usb_ram(sam_mcu_t *m, uint32_t addr, uint32_t n);   /* SRAM at addr, NULL outside it */
int sam_usb_bank_get(sam_mcu_t *m, int ep, int bank, uint32_t *addr, uint32_t *pck);
void sam_usb_bank_set_count(sam_mcu_t *m, int ep, int bank, uint32_t count);
void sam_usb_bus_reset_end(sam_mcu_t *m);                  /* the host ended a bus reset: EORST */
void sam_usb_sof(sam_mcu_t *m);                            /* a start of frame: FNUM, SOF */

/* ---- link_usb_host.c: the host on the board's port, as the device sees it ---- */
void sam_usb_port_reset(sam_mcu_t *m);                     /* the device was reset: the host starts over */
void sam_usb_port_attach_check(sam_mcu_t *m);              /* the device's attach state may have changed */
void sam_usb_port_ep0_ready(sam_mcu_t *m);                 /* a bank of EP0 changed */
void sam_usb_port_bulk_ready(sam_mcu_t *m);                /* a bank of another endpoint changed */
int sam_usb_port_attached(sam_mcu_t *m);                   /* a host is plugged in */
int sam_usb_port_on(sam_mcu_t *m);                         /* the host ended the bus reset (FSMSTATUS ON) */
/* and to its API (link_usb_api.c), between runs */
#define SAM_USB_LINUX_BAUD 9600u                           /* the line coding cdc_acm's probe sets (a new tty) */
void sam_usb_host_line_state(sam_mcu_t *m, int dtr);       /* the script profile's open (dtr 1) and close */
void sam_usb_host_queue(sam_mcu_t *m, const uint8_t setup[8], const uint8_t *data, uint32_t n);
void sam_usb_host_line_changed(sam_mcu_t *m);              /* sam_usb_set_line changed what the laptop wants */

/* ---- link_usb_desc.c: the device's descriptors, as the host reads them ---- */
int sam_usbd_parse_device(sam_usb_device_t *dev, const uint8_t *d, uint32_t n, uint8_t istr[3], int *ep0);
int sam_usbd_parse_config(const uint8_t *d, uint32_t n, int *comm_if, int *in, int *out);
void sam_usbd_string(char *dst, uint32_t cap, const uint8_t *d, uint32_t n);

#endif /* SAM_USB_H */
