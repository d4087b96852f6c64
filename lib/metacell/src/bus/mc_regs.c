/* Cell-side register handler: mailbox write validation/application at tick boundaries, double-buffered read blocks. */
#include "mc_regs.h"
#include "mc_crc8.h"

static void seal(uint8_t *blk, uint32_t len)
{
    blk[len - 1] = mc_crc8(blk, len - 1);   /* last byte = CRC-8 of the others */
}

static void publish_params(mc_regs_t *r, const mc_cell_t *c)
{
    uint8_t i = (uint8_t)(r->params_idx ^ 1u);
    uint8_t *p = r->params[i];
    p[MC_PARAMS_TAG] = MC_BLK_PARAMS_TAG;
    p[MC_PARAMS_ADDR] = r->addr;
    mc_put_u32(p + MC_PARAMS_K_AB, (uint32_t)r->phys.k_ab_unm);
    mc_put_u32(p + MC_PARAMS_SIGMA, (uint32_t)r->phys.sigma_unm);
    mc_put_u32(p + MC_PARAMS_K1, (uint32_t)r->phys.k1_unm);
    mc_put_u32(p + MC_PARAMS_K2, (uint32_t)r->phys.k2_unm);
    mc_put_u32(p + MC_PARAMS_ASTAR, (uint32_t)r->phys.astar_urad);
    mc_put_u16(p + MC_PARAMS_PWM_LIMIT, (uint16_t)c->drive.duty_limit);
    seal(p, MC_BLK_PARAMS_LEN);
    r->params_idx = i;
}

static uint8_t cell_flags(const mc_regs_t *r, const mc_cell_t *c)
{
    uint8_t f = 0;
    if (c->enabled)
        f |= MC_CF_ENABLED;
    if (c->bemf_comp)
        f |= MC_CF_BEMF;
    if (c->pert_ticks)
        f |= MC_CF_PERTURBING;
    if (r->rx_full)
        f |= MC_CF_PENDING;
    if (c->faults)
        f |= MC_CF_FAULT;
    return f;
}

static void publish_snapshot(mc_regs_t *r, const mc_cell_t *c, const mc_quad_snap_t *a,
                             const mc_quad_snap_t *b)
{
    uint8_t i = (uint8_t)(r->snap_idx ^ 1u);
    uint8_t *s = r->snap[i];
    s[MC_SNAPSHOT_TAG] = MC_BLK_SNAPSHOT_TAG;
    s[MC_SNAPSHOT_ADDR] = r->addr;
    mc_put_u32(s + MC_SNAPSHOT_TICK, c->tick);
    /* theta is clamped to +-MC_ANGLE_CLAMP (2048): fits int16 */
    mc_put_u16(s + MC_SNAPSHOT_ALPHA, (uint16_t)c->theta[0]);
    mc_put_u16(s + MC_SNAPSHOT_BETA, (uint16_t)c->theta[1]);
    mc_put_u16(s + MC_SNAPSHOT_FAULTS, c->faults);
    s[MC_SNAPSHOT_FLAGS] = cell_flags(r, c);
    s[MC_SNAPSHOT_CMD_SEQ] = r->last_seq;
    s[MC_SNAPSHOT_CMD_RESULT] = r->last_result;
    s[MC_SNAPSHOT_REJECTED] = r->rejected;
    mc_put_u16(s + MC_SNAPSHOT_DEC_ERR_A, (uint16_t)a->errors);
    mc_put_u16(s + MC_SNAPSHOT_DEC_ERR_B, (uint16_t)b->errors);
    mc_put_u16(s + MC_SNAPSHOT_BUS_ERR, r->bus_err);
    seal(s, MC_BLK_SNAPSHOT_LEN);
    r->snap_idx = i;   /* single byte store: the ISR sees the old or the new block */
}

int mc_regs_init(mc_regs_t *r, const mc_cell_t *c, uint8_t addr, uint32_t build,
                 const mc_reaction_phys_t *phys)
{
    if (addr < 0x08 || addr > 0x77)
        return MC_ERR_RANGE;
    uint8_t *raw = (uint8_t *)r;
    for (uint32_t k = 0; k < sizeof(*r); k++)
        raw[k] = 0;
    r->addr = addr;
    r->ptr = MC_BLK_SNAPSHOT;
    r->last_result = MC_RES_NONE;
    if (phys)
        r->phys = *phys;
    else
        mc_cell_default_params(&r->phys);
    uint8_t *id = r->ident;
    id[MC_IDENT_TAG] = MC_BLK_IDENT_TAG;
    id[MC_IDENT_ADDR] = addr;
    mc_put_u16(id + MC_IDENT_FW_VERSION, MC_FW_VERSION);
    mc_put_u32(id + MC_IDENT_BUILD, build);
    mc_put_u16(id + MC_IDENT_MAP_ID, MC_PROTO_MAP_ID);
    seal(id, MC_BLK_IDENT_LEN);
    mc_regs_set_boot(r, 0, 0, 0, 0);
    publish_params(r, c);
    mc_quad_snap_t z = {0, 0, 0};
    publish_snapshot(r, c, &z, &z);
    return MC_OK;
}

void mc_regs_set_boot(mc_regs_t *r, uint8_t reset_cause, uint16_t wdt_ms, uint8_t fault_exc,
                      uint32_t fault_pc)
{
    uint8_t *b = r->boot;
    b[MC_BOOT_TAG] = MC_BLK_BOOT_TAG;
    b[MC_BOOT_ADDR] = r->addr;
    b[MC_BOOT_RESET_CAUSE] = reset_cause;
    mc_put_u16(b + MC_BOOT_WDT_MS, wdt_ms);
    b[MC_BOOT_FAULT_EXC] = fault_exc;
    mc_put_u32(b + MC_BOOT_FAULT_PC, fault_pc);
    seal(b, MC_BLK_BOOT_LEN);
}

void mc_regs_on_receive(mc_regs_t *r, const uint8_t *data, uint32_t len)
{
    if (len == 0)
        return;   /* SAMD21 core: onReceive(0) after every read ending in STOP */
    if (data[0] == MC_REG_POINTER) {
        /* applied at once (it only selects what the next read returns) */
        uint8_t hdr = (uint8_t)(r->addr << 1);
        if (len == MC_REG_POINTER_LEN + MC_WRITE_OVERHEAD &&
            mc_crc8_update(mc_crc8(&hdr, 1), data, len - 1) == data[len - 1] &&
            data[2 + MC_REG_POINTER_BLOCK] < MC_BLK_COUNT)
            r->ptr = data[2 + MC_REG_POINTER_BLOCK];
        else
            r->bus_err++;
        return;
    }
    if (r->rx_full) {
        r->bus_err++;   /* previous write not applied yet: dropped, primary times out */
        return;
    }
    uint32_t n = len < MC_WRITE_MAX_LEN ? len : MC_WRITE_MAX_LEN;
    for (uint32_t k = 0; k < n; k++)
        r->rx[k] = data[k];
    r->rx_len = (uint8_t)(len < 255u ? len : 255u);
    r->rx_full = 1;
}

uint32_t mc_regs_on_request(mc_regs_t *r, uint8_t *out, uint32_t cap)
{
    const uint8_t *src;
    uint32_t n;
    uint32_t m = mc_irq_save();   /* a higher-priority tick may not flip mid-copy */
    switch (r->ptr) {
    case MC_BLK_IDENT:
        src = r->ident;
        n = MC_BLK_IDENT_LEN;
        break;
    case MC_BLK_BOOT:
        src = r->boot;
        n = MC_BLK_BOOT_LEN;
        break;
    case MC_BLK_PARAMS:
        src = r->params[r->params_idx];
        n = MC_BLK_PARAMS_LEN;
        break;
    default:
        src = r->snap[r->snap_idx];
        n = MC_BLK_SNAPSHOT_LEN;
        break;
    }
    if (n > cap)
        n = cap;
    for (uint32_t k = 0; k < n; k++)
        out[k] = src[k];
    r->ptr = MC_BLK_SNAPSHOT;
    mc_irq_restore(m);
    return n;
}

static uint8_t result_of(int rc)
{
    switch (rc) {
    case MC_OK: return MC_RES_OK;
    case MC_ERR_RANGE: return MC_RES_RANGE;
    case MC_ERR_SHAPE: return MC_RES_SHAPE;
    default: return MC_RES_CONFIG;
    }
}

/* Validate and apply one write frame b[0..len): reg seq payload crc. */
static uint8_t apply(mc_regs_t *r, mc_cell_t *c, const uint8_t *b, uint32_t len,
                     const mc_quad_snap_t *qa, const mc_quad_snap_t *qb)
{
    uint8_t hdr = (uint8_t)(r->addr << 1);
    if (len < MC_WRITE_OVERHEAD || len > MC_WRITE_MAX_LEN)
        return MC_RES_LENGTH;
    if (mc_crc8_update(mc_crc8(&hdr, 1), b, len - 1) != b[len - 1])
        return MC_RES_CRC;
    int plen = mc_proto_reg_len(b[0]);
    if (plen < 0 || b[0] == MC_REG_POINTER)
        return MC_RES_REG;
    if (len != (uint32_t)plen + MC_WRITE_OVERHEAD)
        return MC_RES_LENGTH;
    const uint8_t *p = b + 2;
    mc_reaction_phys_t ph = r->phys;
    int rc;
    switch (b[0]) {
    case MC_REG_K_AB:
    case MC_REG_SIGMA:
    case MC_REG_K1:
    case MC_REG_K2:
    case MC_REG_ASTAR: {
        int32_t v = mc_get_i32(p);
        if (b[0] == MC_REG_K_AB)
            ph.k_ab_unm = v;
        else if (b[0] == MC_REG_SIGMA)
            ph.sigma_unm = v;
        else if (b[0] == MC_REG_K1)
            ph.k1_unm = v;
        else if (b[0] == MC_REG_K2)
            ph.k2_unm = v;
        else
            ph.astar_urad = v;
        rc = mc_cell_set_params(c, &ph);   /* validates the whole set; no change on error */
        if (rc == MC_OK) {
            r->phys = ph;
            publish_params(r, c);
        }
        return result_of(rc);
    }
    case MC_REG_ENABLE:
    case MC_REG_BEMF:
        if (p[0] > 1)
            return MC_RES_RANGE;
        if (b[0] == MC_REG_ENABLE)
            mc_cell_enable(c, p[0]);
        else
            mc_cell_set_bemf(c, p[0]);
        return MC_RES_OK;
    case MC_REG_PERTURB: {
        /* torque on the wire in units of MC_TORQUE_WIRE_UNM uN*m */
        int32_t t = mc_get_i16(p + MC_REG_PERTURB_TORQUE) * MC_TORQUE_WIRE_UNM;
        return result_of(mc_cell_perturb(c, p[MC_REG_PERTURB_CHAIN], t,
                                         mc_get_u16(p + MC_REG_PERTURB_TICKS)));
    }
    case MC_REG_ZERO:
        mc_cell_zero(c, qa->pos, qb->pos);
        return MC_RES_OK;
    case MC_REG_PWM_LIMIT: {
        int32_t v = mc_get_u16(p + MC_REG_PWM_LIMIT_TICKS);
        if (v > c->drive.pwm_top)
            return MC_RES_RANGE;
        mc_drive_set_limit(&c->drive, v);   /* clamped to the 5.86 V duty cap */
        publish_params(r, c);
        return MC_RES_OK;
    }
    case MC_REG_CLEAR_FAULTS:
        mc_cell_clear_faults(c);
        return MC_RES_OK;
    default:
        return MC_RES_REG;
    }
}

void mc_regs_apply(mc_regs_t *r, mc_cell_t *c, const mc_quad_snap_t *a, const mc_quad_snap_t *b)
{
    if (r->rx_full) {
        uint8_t buf[MC_WRITE_MAX_LEN];
        uint32_t len = r->rx_len;
        uint32_t n = len < MC_WRITE_MAX_LEN ? len : MC_WRITE_MAX_LEN;
        for (uint32_t k = 0; k < n; k++)
            buf[k] = r->rx[k];
        uint8_t res = apply(r, c, buf, len, a, b);
        r->last_seq = len >= 2 ? buf[1] : 0;
        r->last_result = res;
        if (res != MC_RES_OK)
            r->rejected++;
        r->rx_full = 0;   /* mailbox free only after the copy */
    }
}

void mc_regs_publish(mc_regs_t *r, const mc_cell_t *c, const mc_quad_snap_t *a,
                     const mc_quad_snap_t *b)
{
    publish_snapshot(r, c, a, b);
}

uint16_t mc_regs_tick(mc_regs_t *r, mc_cell_t *c, const mc_quad_snap_t *a,
                      const mc_quad_snap_t *b)
{
    mc_regs_apply(r, c, a, b);
    uint16_t faults = mc_cell_tick(c, a, b);
    publish_snapshot(r, c, a, b);
    return faults;
}
