/* libFuzzer harness: arbitrary I2C writes/reads into a cell's register handler; rejected writes must change nothing. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "bus/mc_regs.h"
#include "bus/mc_crc8.h"

typedef struct {
    mc_reaction_t law;
    mc_drive_t drive;
    int32_t zero[2];
    uint8_t enabled, bemf;
    int32_t pert_torque;
    uint32_t pert_ticks;
    uint16_t faults;
} config_t;

static void config_of(const mc_cell_t *c, config_t *k)
{
    memset(k, 0, sizeof(*k));
    k->law = c->law;
    k->drive = c->drive;
    k->zero[0] = c->zero[0];
    k->zero[1] = c->zero[1];
    k->enabled = c->enabled;
    k->bemf = c->bemf_comp;
    k->pert_torque = c->pert_torque;
    k->pert_ticks = c->pert_ticks;
    k->faults = c->faults;
}

/* Input: a sequence of records  [op][len][bytes...]; op&3: 0 write, 1 tick, 2 read, 3 write+tick */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static mc_cell_t c;
    static mc_regs_t r;
    mc_quad_snap_t a = {0, 0, 0}, b = {0, 0, 0};
    mc_cell_init(&c);
    if (mc_regs_init(&r, &c, 0x14, 1, NULL) != MC_OK)
        abort();
    size_t k = 0;
    while (k + 2 <= size) {
        uint8_t op = data[k], len = data[k + 1];
        k += 2;
        if (len > size - k)
            len = (uint8_t)(size - k);
        const uint8_t *p = data + k;
        k += len;
        a.pos += (int8_t)op;
        b.errors += op & 1u;
        switch (op & 3u) {
        case 0:
            mc_regs_on_receive(&r, p, len);
            break;
        case 2: {
            uint8_t out[64];
            uint32_t n = mc_regs_on_request(&r, out, len < sizeof(out) ? len : sizeof(out));
            if (n > sizeof(out))
                abort();
            if (n >= MC_BLK_SNAPSHOT_LEN && out[0] == MC_BLK_SNAPSHOT_TAG &&
                mc_crc8(out, MC_BLK_SNAPSHOT_LEN - 1) != out[MC_BLK_SNAPSHOT_LEN - 1])
                abort();   /* a published snapshot always carries a valid CRC */
            break;
        }
        default: {
            if (op & 2u)
                mc_regs_on_receive(&r, p, len);
            config_t before, after;
            config_of(&c, &before);
            uint8_t rej = r.rejected;
            uint8_t had = r.rx_full;
            mc_regs_apply(&r, &c, &a, &b);
            config_of(&c, &after);
            if (had && r.last_result != MC_RES_OK) {
                if (memcmp(&before, &after, sizeof(before)) != 0)
                    abort();   /* a rejected write changed the configuration */
                if ((uint8_t)(rej + 1) != r.rejected)
                    abort();
            }
            if (r.rx_full)
                abort();       /* the tick always empties the mailbox */
            mc_cell_tick(&c, &a, &b);
            mc_regs_publish(&r, &c, &a, &b);
            break;
        }
        }
    }
    return 0;
}
