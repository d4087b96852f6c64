/* Board identity over USB CDC: `ID?` line matcher and reply formatter (no printf). */
#include "mc_ident.h"

void mc_ident_rx_init(mc_ident_rx_t *rx)
{
    rx->len = 0;
    rx->overflow = 0;
}

int mc_ident_rx_feed(mc_ident_rx_t *rx, uint8_t byte)
{
    if (byte == '\r' || byte == '\n') {
        int hit = !rx->overflow && rx->len == 3 && rx->buf[0] == 'I' &&
                  rx->buf[1] == 'D' && rx->buf[2] == '?';
        rx->len = 0;
        rx->overflow = 0;
        return hit;
    }
    if (rx->len < sizeof(rx->buf))
        rx->buf[rx->len++] = (char)byte;
    else
        rx->overflow = 1;
    return 0;
}

/* Append a string; returns the new position. */
static int put_str(char *out, int pos, const char *s)
{
    while (*s)
        out[pos++] = *s++;
    return pos;
}

/* Append v (0..255) in decimal without division: subtract powers of ten. */
static int put_dec(char *out, int pos, unsigned v)
{
    static const unsigned pow10[] = {100u, 10u, 1u};
    int started = 0;
    for (int i = 0; i < 3; i++) {
        char d = '0';
        while (v >= pow10[i]) {
            v -= pow10[i];
            d++;
        }
        if (d != '0' || started || i == 2) {
            out[pos++] = d;
            started = 1;
        }
    }
    return pos;
}

static int put_hex2(char *out, int pos, unsigned v)
{
    static const char hex[] = "0123456789abcdef";
    out[pos++] = '0';
    out[pos++] = 'x';
    out[pos++] = hex[(v >> 4) & 0xfu];
    out[pos++] = hex[v & 0xfu];
    return pos;
}

int mc_ident_format(char *buf, int size, int role, int cell, int addr, uint16_t fw)
{
    char tmp[MC_IDENT_LINE_MAX];
    int n = 0;
    if (role == MC_IDENT_ROLE_CELL) {
        if (cell < 0 || cell > MC_IDENT_CELL_MAX)
            return -1;
        if (cell == 0 ? addr != 0 : (addr < 0x08 || addr > 0x77))
            return -1;
        n = put_str(tmp, n, "MC role=cell addr=");
        n = cell == 0 ? put_str(tmp, n, "none") : put_hex2(tmp, n, (unsigned)addr);
        n = put_str(tmp, n, " cell=");
        n = put_dec(tmp, n, (unsigned)cell);
    } else if (role == MC_IDENT_ROLE_PRIMARY) {
        n = put_str(tmp, n, "MC role=primary");
    } else {
        return -1;
    }
    n = put_str(tmp, n, " fw=");
    n = put_dec(tmp, n, (unsigned)(fw >> 8));
    tmp[n++] = '.';
    n = put_dec(tmp, n, (unsigned)(fw & 0xffu));
    n = put_str(tmp, n, "\r\n");
    if (buf == 0 || size < n + 1)
        return -1;
    for (int i = 0; i < n; i++)
        buf[i] = tmp[i];
    buf[n] = '\0';
    return n;
}
