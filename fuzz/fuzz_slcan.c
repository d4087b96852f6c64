/* libFuzzer harness: arbitrary bytes from the laptop into the primary's SLCAN link (parser, command forwarding, encoder). */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "bus/mc_primary.h"

static void check_output(const char *o, uint32_t n)
{
    /* replies and frames: printable ASCII, '\r' or BEL only */
    for (uint32_t k = 0; k < n; k++) {
        char c = o[k];
        if (!((c >= 0x20 && c <= 0x7E) || c == '\r' || c == '\a'))
            abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static mc_link_t l;
    char out[512];
    uint32_t now = 0;
    mc_link_init(&l, now);
    size_t k = 0;
    while (k < size) {
        uint32_t used = 0;
        uint32_t n = mc_link_rx(&l, now, data + k, (uint32_t)(size - k), &used, out, sizeof(out));
        check_output(out, n);
        if (used == 0)
            abort();   /* must always make progress with a large reply buffer */
        k += used;
        now += 997;
        /* drive the scheduler a little: outcomes and read bytes come from the input too */
        mc_txn_t t;
        for (int i = 0; i < 4; i++) {
            if (mc_primary_next(&l.p, now, &t)) {
                if (t.cell >= MC_N_CELLS || t.len > (t.kind == MC_TXN_WRITE ? sizeof(t.buf) : MC_BLK_MAX_LEN))
                    abort();
                uint8_t sel = data[(k + (size_t)i) % size];
                size_t avail = size - k < t.len ? size - k : t.len;
                mc_primary_complete(&l.p, now + (sel & 0x80u ? 5000u : 50u), sel & 7u, data + k,
                                    t.kind == MC_TXN_READ ? (uint32_t)avail : 0u);
            }
            now += 300;
        }
        n = mc_link_tx(&l, now, out, sizeof(out));
        check_output(out, n);
        /* every owed command result keeps its queue slot */
        if (mc_primary_qfree(&l.p) < l.p.inflight)
            abort();
        if (k < size && data[k] == 0x7F)
            mc_link_session(&l);   /* a host session edge (DEL is never part of a valid line) */
    }
    /* every parsed frame round-trips through the encoder */
    mc_slcan_t s;
    mc_slcan_init(&s);
    s.open = 1;
    mc_can_frame_t f, g;
    char reply[MC_SLCAN_REPLY_MAX];
    char line[MC_SLCAN_FRAME_MAX];
    if (mc_slcan_line(&s, (const char *)data, size < MC_SLCAN_LINE_MAX ? (uint32_t)size : 0u, &f, reply) ==
        MC_SLCAN_EV_FRAME) {
        uint32_t n = mc_slcan_encode(&s, &f, 0, line);
        if (n < 2 || line[n - 1] != '\r')
            abort();
        if (mc_slcan_line(&s, line, n - 1, &g, reply) != MC_SLCAN_EV_FRAME || g.id != f.id || g.dlc != f.dlc ||
            (!(f.id & MC_CAN_RTR) && memcmp(g.data, f.data, f.dlc) != 0))
            abort();
    }
    return 0;
}
