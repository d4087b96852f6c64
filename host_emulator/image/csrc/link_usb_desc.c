/* What the laptop's USB host reads in a device's descriptors: its ids, CDC interfaces and endpoints, its strings. */
#include <string.h>
#include "sam_usb.h"

static uint16_t le16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }

/* The device descriptor (18 bytes): ids, release numbers and the string indices in the order Linux reads them
 * (iProduct, iManufacturer, iSerialNumber); *ep0: bMaxPacketSize0. */
int sam_usbd_parse_device(sam_usb_device_t *dev, const uint8_t *d, uint32_t n, uint8_t istr[3], int *ep0)
{
    if (n < 18 || d[0] < 18 || d[1] != 1)
        return -1;
    dev->described = 1;
    dev->bcd_usb = le16(d + 2);
    dev->vid = le16(d + 8);
    dev->pid = le16(d + 10);
    dev->bcd_device = le16(d + 12);
    istr[0] = d[15];
    istr[1] = d[14];
    istr[2] = d[16];
    *ep0 = d[7] ? d[7] : 64;
    return 0;
}

/* The configuration descriptor: the CDC data interface's bulk endpoints (interface class 0x0A) and the CDC comm
 * interface (class 0x02, subclass 0x02: ACM), whose number class requests carry in wIndex. A configuration with no
 * data interface falls back to its last bulk pair (0 if it has no comm interface); -1: no bulk pair at all. */
int sam_usbd_parse_config(const uint8_t *d, uint32_t n, int *comm_if, int *in, int *out)
{
    int cls = -1, ifnum = -1, comm = -1;
    int din = -1, dout = -1, lin = -1, lout = -1;
    for (uint32_t i = 0; i + 2 <= n && d[i] >= 2; i += d[i]) {
        if (d[i + 1] == 4 && i + 9 <= n) {   /* an interface */
            ifnum = d[i + 2];
            cls = d[i + 5];
            if (cls == 0x02 && d[i + 6] == 0x02 && comm < 0)
                comm = ifnum;
        } else if (d[i + 1] == 5 && i + 7 <= n && (d[i + 3] & 3) == 2) {   /* a bulk endpoint */
            int ep = d[i + 2] & 0x0F, is_in = (d[i + 2] & 0x80) != 0;
            if (is_in)
                lin = ep;
            else
                lout = ep;
            if (cls == 0x0A && is_in && din < 0)
                din = ep;
            if (cls == 0x0A && !is_in && dout < 0)
                dout = ep;
        }
    }
    if (din < 0 || dout < 0) {
        din = lin;
        dout = lout;
    }
    if (din < 0 || dout < 0)
        return -1;
    *in = din;
    *out = dout;
    *comm_if = comm < 0 ? 0 : comm;
    return 0;
}

int sam_usb_parse_config(const uint8_t *d, uint32_t n, int32_t *comm_if, int32_t *in, int32_t *out)
{
    int c, i, o;
    if (sam_usbd_parse_config(d, n, &c, &i, &o))
        return -1;
    *comm_if = c;
    *in = i;
    *out = o;
    return 0;
}

/* A string descriptor (UTF-16LE) as ASCII, others '?', NUL-terminated within cap. */
void sam_usbd_string(char *dst, uint32_t cap, const uint8_t *d, uint32_t n)
{
    uint32_t k = 0;
    if (n >= 2 && d[1] == 3) {
        uint32_t len = d[0] < n ? d[0] : n;
        for (uint32_t i = 2; i + 1 < len && k + 1 < cap; i += 2) {
            uint16_t c = le16(d + i);
            dst[k++] = c >= 0x20 && c < 0x7F ? (char)c : '?';
        }
    }
    if (cap)
        dst[k] = 0;
}
