/* SERCOM in I2C modes: the registers of the master (I2CM) and slave (I2CS) views, enabling, address matching. */
#include <string.h>
#include "sam_sercom.h"
#include "sam_vendor_gen.h"

/* A pin's name for messages: 8 -> "PA08", 41 -> "PB09". */
static const char *pin_name(int pin, char buf[8])
{
    buf[0] = 'P';
    buf[1] = pin < 32 ? 'A' : 'B';
    buf[2] = (char)('0' + (pin & 31) / 10);
    buf[3] = (char)('0' + (pin & 31) % 10);
    buf[4] = 0;
    return buf;
}

/* A received 7-bit address selects this slave. DS40001882 28.6.3.1 "Address Match and Mask" with CTRLB.AMODE
 * (28.10.2): 0 MASK, ADDR.ADDR compared in the bits ADDR.ADDRMASK leaves clear; 1 2_ADDRS, ADDR.ADDR or ADDR.ADDRMASK
 * as the second address; 2 RANGE, "the range of addresses between and including ADDR.ADDR and ADDR.ADDRMASK ...
 * with ADDR.ADDR acting as the upper limit and ADDR.ADDRMASK acting as the lower limit" (the family's SERCOM text,
 * Microchip online docs "Address Match and Mask"; a lower limit above the upper one matches nothing here). ADDR.GENCEN
 * adds the general call address 0 in every mode (28.10.9). Seven-bit addresses: the low 7 bits of both 10-bit fields
 * (ADDR.TENBITEN is refused, i2c_write). AMODE 3 (reserved) is refused when written. */
int sam_i2c_address_matches(sam_mcu_t *m, int pi, sam_sercom_t *s, uint8_t addr7)
{
    if (m->halted || !s->enabled || s->mode != 4 || !sam_bus_pins_connected(m))
        return 0;
    uint32_t a = sam_sercom_reg32(m, pi, SERCOM_I2CS_ADDR_OFFSET);
    uint32_t amode = (sam_sercom_reg32(m, pi, SERCOM_I2CS_CTRLB_OFFSET) & SERCOM_I2CS_CTRLB_AMODE_Msk) >>
                     SERCOM_I2CS_CTRLB_AMODE_Pos;
    uint32_t sa = (a >> SERCOM_I2CS_ADDR_ADDR_Pos) & 0x7Fu, second = (a >> SERCOM_I2CS_ADDR_ADDRMASK_Pos) & 0x7Fu;
    if (addr7 == 0 && (a & SERCOM_I2CS_ADDR_GENCEN))
        return 1;
    if (amode == 1)
        return addr7 == sa || addr7 == second;
    if (amode == 2)
        return second <= addr7 && addr7 <= sa;
    return ((sa ^ addr7) & ~second) == 0;
}

/* The slave's address settings the model does not cover: an error naming the field (0: none). */
static int i2cs_settings_refused(sam_mcu_t *m, int pi, uint32_t ctrlb, uint32_t addr)
{
    if ((ctrlb & SERCOM_I2CS_CTRLB_AMODE_Msk) == SERCOM_I2CS_CTRLB_AMODE(3)) {
        sam_fail(m, "%s.I2CS.CTRLB.AMODE 3 is reserved (0 mask, 1 two addresses, 2 range)", sam_periphs[pi].name);
        return -1;
    }
    if (addr & SERCOM_I2CS_ADDR_TENBITEN) {
        sam_fail(m, "%s.I2CS.ADDR.TENBITEN: 10-bit slave addresses are not modelled", sam_periphs[pi].name);
        return -1;
    }
    return 0;
}

/* The SERCOM's state machines restart (SWRST, disable, the chip's reset): a slave lets go of the bus; a master's
 * own pending steps are gone (what it learns of the lines stays). */
void sam_i2c_restart(sam_mcu_t *m, int pi)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    sam_i2cs_vanish(m, s, sam_now(m));
    sam_bus_drop_own(m);
    s->busstate = BUSSTATE_UNKNOWN;
    s->m_flags = 0;
    s->stop_pending = s->sysop_stuck = s->pending_start = 0;
    s->t_inactive = s->t_lowtout = SAM_NEVER;
    sam_i2cm_end(s);
}

static int is_bus(sam_mcu_t *m, int pi) { return m->w && pi == sam_bus_sercom(m); }

static void i2c_reset(sam_mcu_t *m, int pi)
{
    if (is_bus(m, pi))
        sam_i2c_restart(m, pi);
}

static void i2c_init(sam_sercom_t *s)
{
    s->slave = s->master = -1;
    s->t_inactive = s->t_lowtout = SAM_NEVER;
}

static uint8_t i2c_flags(const sam_sercom_t *s) { return s->mode == 5 ? s->m_flags : s->s_flags; }

static int i2c_enable(sam_mcu_t *m, int pi, uint32_t nv)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    if (nv & (SERCOM_I2CM_CTRLA_SCLSM | SERCOM_I2CM_CTRLA_SPEED_Msk | SERCOM_I2CM_CTRLA_MEXTTOEN |
              SERCOM_I2CM_CTRLA_SEXTTOEN | SERCOM_I2CM_CTRLA_PINOUT)) {
        sam_fail(m, "%s.CTRLA = 0x%08x: SCL stretch after ACK, Fm+/Hs speeds, extend time-outs and 4-wire "
                 "operation are not modelled", sam_periphs[pi].name, nv);
        return -1;
    }
    if (!is_bus(m, pi)) {
        int bus = m->w ? sam_bus_sercom(m) : -1;
        char sda[8], scl[8];
        sam_fail(m, "%s enabled in I2C mode: only %s is wired to the bus (%s, %s)", sam_periphs[pi].name,
                 bus >= 0 ? sam_periphs[bus].name : "no SERCOM", m->w ? pin_name(m->w->cfg.pin_sda, sda) : "-",
                 m->w ? pin_name(m->w->cfg.pin_scl, scl) : "-");
        return -1;
    }
    if (s->mode == 5 && m->role != SAM_ROLE_PRIMARY) {
        sam_fail(m, "%s enabled as I2C master on a cell: only the primary masters the bus in this model",
                 sam_periphs[pi].name);
        return -1;
    }
    if (s->mode == 4 && i2cs_settings_refused(m, pi, sam_sercom_reg32(m, pi, SERCOM_I2CS_CTRLB_OFFSET),
                                              sam_sercom_reg32(m, pi, SERCOM_I2CS_ADDR_OFFSET)))
        return -1;
    if (s->mode == 5)
        s->busstate = BUSSTATE_UNKNOWN;
    return 0;
}

static void i2c_disable(sam_mcu_t *m, int pi)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    if (is_bus(m, pi))
        sam_i2c_restart(m, pi);
    s->busstate = BUSSTATE_UNKNOWN;
    s->s_state = S_IDLE;
    s->sysop_stuck = 0;
}

static int i2c_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint32_t off = sam_regs[ri].offset;
    if (off == SERCOM_I2CM_INTFLAG_OFFSET) {
        *v = s->mode == 5 ? s->m_flags : s->s_flags;
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_STATUS_OFFSET) {
        *v = s->mode == 5 ? (uint32_t)s->m_status | s->busstate << 4 : s->s_status;
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_DATA_OFFSET) {
        *v = s->mode == 5 ? s->m_data : s->s_rx;
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int i2c_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    sam_sercom_t *s = sam_sercom_st(m, pi);
    uint32_t off = sam_regs[ri].offset;
    if (off == SERCOM_I2CM_CTRLB_OFFSET) {
        if (v & SERCOM_I2CM_CTRLB_SMEN) {
            sam_fail(m, "I2C smart mode (CTRLB.SMEN) is not modelled");
            return SAM_DONE;
        }
        if (s->mode == 4 && i2cs_settings_refused(m, pi, (sam_sercom_reg32(m, pi, off) & ~mask) | (v & mask), 0))
            return SAM_DONE;
        uint32_t cmd = (v >> 16) & 3u;
        int nack = (v & SERCOM_I2CM_CTRLB_ACKACT) != 0;
        sam_reg_put(m, ri, (sam_reg_get(m, ri) & ~mask) | (v & ~SERCOM_I2CM_CTRLB_CMD_Msk));
        if (cmd && s->enabled) {
            if (s->mode == 5) {
                sam_sercom_sync(m, pi, 4u);
                sam_i2cm_cmd(m, pi, cmd, nack);
            } else {
                sam_i2cs_cmd(m, pi, cmd, nack);
            }
            sam_sercom_irq(m, pi);
        }
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_INTFLAG_OFFSET) {
        if (s->mode == 5) {
            s->m_flags &= (uint8_t)~v;
        } else {
            uint8_t st_before = (uint8_t)s->s_state;
            if ((v & S_AMATCHF) && st_before == S_AMATCH)
                sam_i2cs_cmd(m, pi, 3, (sam_sercom_reg32(m, pi, SERCOM_I2CS_CTRLB_OFFSET) & SERCOM_I2CS_CTRLB_ACKACT) != 0);
            else if ((v & S_DRDY) && st_before == S_RX_HOLD)
                sam_i2cs_cmd(m, pi, 3, (sam_sercom_reg32(m, pi, SERCOM_I2CS_CTRLB_OFFSET) & SERCOM_I2CS_CTRLB_ACKACT) != 0);
            else
                s->s_flags &= (uint8_t)~v;
        }
        sam_sercom_irq(m, pi);
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_STATUS_OFFSET) {
        if (s->mode == 5) {
            s->m_status &= (uint16_t)~(v & 0x43u);   /* BUSERR, ARBLOST, LOWTOUT: write 1 to clear */
            if (((v >> 4) & 3u) == BUSSTATE_IDLE && s->busstate == BUSSTATE_UNKNOWN) {
                sam_sercom_sync(m, pi, 4u);   /* forced IDLE: only from UNKNOWN (28.10.8) */
                sam_i2cm_bus_idle(m, pi, s);
            }
        } else {
            s->s_status &= (uint16_t)~(v & 0x43u);
        }
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_ADDR_OFFSET) {
        if (s->mode == 4 && i2cs_settings_refused(m, pi, 0, (sam_sercom_reg32(m, pi, off) & ~mask) | (v & mask)))
            return SAM_DONE;
        sam_generic_write(m, ri, v, mask);
        if (s->mode == 5 && s->enabled) {
            sam_sercom_sync(m, pi, 4u);
            sam_i2cm_addr(m, pi, sam_sercom_reg32(m, pi, SERCOM_I2CM_ADDR_OFFSET));
            sam_sercom_irq(m, pi);
        }
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_DATA_OFFSET) {
        if (s->mode == 5) {
            if (s->enabled)
                sam_i2cm_data(m, pi, (uint8_t)v);
        } else if (s->enabled) {
            sam_i2cs_data(m, pi, (uint8_t)v);
        }
        sam_sercom_irq(m, pi);
        return SAM_DONE;
    }
    if (off == SERCOM_I2CM_BAUD_OFFSET && s->mode == 5)   /* the master's BAUD: enable-protected (sam_protect.c) */
        v = sam_enable_protected(m, ri, v, mask, 0xFFFFFFFFu, s->enabled);
    if (off == SERCOM_I2CM_BAUD_OFFSET || off == SERCOM_I2CM_INTENSET_OFFSET || off == SERCOM_I2CM_INTENCLR_OFFSET ||
        off == SERCOM_I2CM_DBGCTRL_OFFSET) {
        sam_generic_write(m, ri, v, mask);
        sam_sercom_irq(m, pi);
        return SAM_DONE;
    }
    return SAM_UNCOVERED;
}

const sam_sercom_mode_t sam_sercom_i2c = {i2c_read, i2c_write, i2c_enable, i2c_disable, i2c_reset, i2c_init, i2c_flags};
