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

#endif /* SAM_USB_H */
