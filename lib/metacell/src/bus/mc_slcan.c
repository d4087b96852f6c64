/* SLCAN line parser (bytes -> commands/frames) and encoder (frame -> line); no allocation, no division. */
#include "mc_slcan.h"
#include "mc_proto.h"

static const char HEX[] = "0123456789ABCDEF";

void mc_slcan_init(mc_slcan_t *s)
{
    uint8_t *raw = (uint8_t *)s;
    for (uint32_t k = 0; k < sizeof(*s); k++)
        raw[k] = 0;
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    return -1;
}

/* n hex digits -> *v; 0 on a bad digit */
static int parse_hex(const char *p, uint32_t n, uint32_t *v)
{
    uint32_t x = 0;
    for (uint32_t k = 0; k < n; k++) {
        int h = hexval(p[k]);
        if (h < 0)
            return 0;
        x = (x << 4) | (uint32_t)h;
    }
    *v = x;
    return 1;
}

static void put_reply(char *reply, const char *txt)
{
    uint32_t k = 0;
    for (; txt[k] && k < MC_SLCAN_REPLY_MAX - 1; k++)
        reply[k] = txt[k];
    reply[k] = 0;
}

static int fail(mc_slcan_t *s, char *reply)
{
    s->errors++;
    put_reply(reply, "\a");
    return MC_SLCAN_EV_ERROR;
}

static int ok(char *reply)
{
    put_reply(reply, "\r");
    return MC_SLCAN_EV_REPLY;
}

static int parse_frame(mc_slcan_t *s, const char *l, uint32_t len, mc_can_frame_t *f, char *reply)
{
    char k = l[0];
    uint32_t idlen = (k == 'T' || k == 'R') ? 8u : 3u;
    int rtr = (k == 'r' || k == 'R');
    uint32_t id, dlc;
    if (!s->open || s->listen_only)
        return fail(s, reply);
    if (len < 2 + idlen || !parse_hex(l + 1, idlen, &id) || !parse_hex(l + 1 + idlen, 1, &dlc))
        return fail(s, reply);
    if (dlc > 8 || id > (idlen == 3 ? 0x7FFu : MC_CAN_ID_MASK))
        return fail(s, reply);
    uint32_t need = 2 + idlen + (rtr ? 0 : 2 * dlc);
    if (len != need)
        return fail(s, reply);
    mc_can_frame_t out;
    out.id = id | (idlen == 8 ? MC_CAN_EFF : 0u) | (rtr ? MC_CAN_RTR : 0u);
    out.dlc = (uint8_t)dlc;
    for (uint32_t i = 0; i < 8; i++) {
        uint32_t b = 0;
        if (!rtr && i < dlc && !parse_hex(l + 2 + idlen + 2 * i, 2, &b))
            return fail(s, reply);
        out.data[i] = (uint8_t)b;
    }
    *f = out;
    put_reply(reply, idlen == 8 ? "Z\r" : "z\r");
    return MC_SLCAN_EV_FRAME;
}

int mc_slcan_line(mc_slcan_t *s, const char *l, uint32_t len, mc_can_frame_t *f, char *reply)
{
    uint32_t v;
    reply[0] = 0;
    if (len == 0)
        return MC_SLCAN_EV_NONE;
    switch (l[0]) {
    case 'O':
    case 'L':
        if (len != 1)
            return fail(s, reply);
        s->open = 1;
        s->listen_only = (uint8_t)(l[0] == 'L');
        return ok(reply);
    case 'C':
        if (len != 1)
            return fail(s, reply);
        s->open = 0;
        s->listen_only = 0;
        return ok(reply);
    case 'S':
        if (len != 2 || l[1] < '0' || l[1] > '8')
            return fail(s, reply);
        s->bitrate = (uint8_t)(l[1] - '0');
        return ok(reply);
    case 's':
        if (len != 5 || !parse_hex(l + 1, 4, &v))
            return fail(s, reply);
        return ok(reply);
    case 'V':
    case 'v':
        if (len != 1)
            return fail(s, reply);
        /* hardware 01, software = protocol version (two decimal digits) */
        reply[0] = l[0];
        reply[1] = '0';
        reply[2] = '1';
        reply[3] = (char)('0' + ((MC_PROTO_VERSION >> 4) & 7));
        reply[4] = (char)('0' + (MC_PROTO_VERSION & 7));
        reply[5] = '\r';
        reply[6] = 0;
        return MC_SLCAN_EV_REPLY;
    case 'N':
        if (len != 1)
            return fail(s, reply);
        put_reply(reply, "NMC01\r");
        return MC_SLCAN_EV_REPLY;
    case 'F':
        if (len != 1)
            return fail(s, reply);
        put_reply(reply, "F00\r");
        return MC_SLCAN_EV_REPLY;
    case 'Z':
        if (len != 2 || (l[1] != '0' && l[1] != '1'))
            return fail(s, reply);
        s->timestamps = (uint8_t)(l[1] == '1');
        return ok(reply);
    case 'M':
    case 'm':
        if (len != 9 || !parse_hex(l + 1, 8, &v))
            return fail(s, reply);
        return ok(reply);
    case 't':
    case 'T':
    case 'r':
    case 'R':
        return parse_frame(s, l, len, f, reply);
    default:
        return fail(s, reply);
    }
}

int mc_slcan_rx(mc_slcan_t *s, uint8_t byte, mc_can_frame_t *frame, char *reply)
{
    reply[0] = 0;
    if (byte == '\n')
        return MC_SLCAN_EV_NONE;
    if (byte != '\r') {
        if (byte < 0x20 || byte > 0x7E || s->len >= MC_SLCAN_LINE_MAX)
            s->bad = 1;
        else
            s->line[s->len++] = (char)byte;
        return MC_SLCAN_EV_NONE;
    }
    int ev;
    if (s->bad)
        ev = fail(s, reply);
    else
        ev = mc_slcan_line(s, s->line, s->len, frame, reply);
    s->len = 0;
    s->bad = 0;
    return ev;
}

static char *put_hex(char *o, uint32_t v, uint32_t digits)
{
    for (uint32_t k = digits; k-- > 0;)
        *o++ = HEX[(v >> (4 * k)) & 15u];
    return o;
}

uint32_t mc_slcan_encode(const mc_slcan_t *s, const mc_can_frame_t *f, uint32_t ts_ms, char *out)
{
    int ext = (f->id & MC_CAN_EFF) != 0;
    int rtr = (f->id & MC_CAN_RTR) != 0;
    uint32_t id = f->id & MC_CAN_ID_MASK;
    if (f->dlc > 8 || (!ext && id > 0x7FFu))
        return 0;
    char *o = out;
    *o++ = rtr ? (ext ? 'R' : 'r') : (ext ? 'T' : 't');
    o = put_hex(o, id, ext ? 8u : 3u);
    *o++ = (char)('0' + f->dlc);
    if (!rtr)
        for (uint32_t i = 0; i < f->dlc; i++)
            o = put_hex(o, f->data[i], 2);
    if (s->timestamps) {
        /* Lawicel timestamp: ms modulo 60000, by subtraction (ts_ms < 2^32) */
        uint32_t t = ts_ms;
        while (t >= 60000u * 16384u)
            t -= 60000u * 16384u;
        for (uint32_t step = 60000u * 8192u; step >= 60000u; step >>= 1)
            if (t >= step)
                t -= step;
        o = put_hex(o, t, 4);
    }
    *o++ = '\r';
    return (uint32_t)(o - out);
}
