/* PORT: the pins' directions, outputs, pull and mux configuration, input sampling through the APB and the IOBUS. */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_world.h"
#include "sam_vendor_gen.h"

typedef struct {
    int8_t ext[64];        /* level the board drives onto the pin, -1: none */
    uint32_t lvl[2];       /* pad levels */
    uint32_t sampled[2];   /* IN as the last APB read sampled it (on-demand pins) */
} port_t;

static int port_pi = -1, iobus_pi = -1;

static void port_tables(void)
{
    if (port_pi >= 0)
        return;
    port_pi = sam_periph_index("PORT");
    iobus_pi = sam_periph_index("PORT_IOBUS");
}

static port_t *port_st(sam_mcu_t *m) { return m->pst[port_pi]; }
static uint8_t *grp(sam_mcu_t *m, int g) { return m->regs[port_pi] + 0x80 * g; }

static uint32_t port_dir(sam_mcu_t *m, int g) { return sam_rd32(grp(m, g) + PORT_DIR_OFFSET); }
static uint32_t port_out(sam_mcu_t *m, int g) { return sam_rd32(grp(m, g) + PORT_OUT_OFFSET); }
static uint32_t port_ctrl(sam_mcu_t *m, int g) { return sam_rd32(grp(m, g) + PORT_CTRL_OFFSET); }
static uint8_t port_pincfg(sam_mcu_t *m, int pin) { return grp(m, pin >> 5)[PORT_PINCFG_OFFSET + (pin & 31)]; }

int sam_pin_function(sam_mcu_t *m, int pin)
{
    port_tables();
    if (!(port_pincfg(m, pin) & PORT_PINCFG_PMUXEN))
        return -1;
    uint8_t pm = grp(m, pin >> 5)[PORT_PMUX_OFFSET + ((pin & 31) >> 1)];
    return pin & 1 ? pm >> 4 : pm & 15;
}

int sam_pin_out(sam_mcu_t *m, int pin, int *driven)
{
    port_tables();
    int g = pin >> 5, b = pin & 31;
    int gpio_out = !(port_pincfg(m, pin) & PORT_PINCFG_PMUXEN) && (port_dir(m, g) >> b & 1u);
    *driven = gpio_out;
    if (gpio_out)
        return (int)(port_out(m, g) >> b & 1u);
    if (port_pincfg(m, pin) & PORT_PINCFG_PULLEN)
        return (int)(port_out(m, g) >> b & 1u);   /* pull direction */
    return -1;
}

static int pad_level(sam_mcu_t *m, port_t *s, int pin)
{
    int driven;
    int o = sam_pin_out(m, pin, &driven);
    if (driven)
        return o;
    if (s->ext[pin] >= 0)
        return s->ext[pin];
    return o > 0 ? 1 : 0;   /* pull-up, pull-down, or floating (read as 0) */
}

int sam_pin_level(sam_mcu_t *m, int pin)
{
    port_tables();
    return (int)(port_st(m)->lvl[pin >> 5] >> (pin & 31) & 1u);
}


/* recompute a group's pad levels; tell the EIC about changes on its lines */
static void port_levels(sam_mcu_t *m, int g)
{
    port_t *s = port_st(m);
    uint32_t lv = 0;
    for (int b = 0; b < 32; b++)
        lv |= (uint32_t)pad_level(m, s, 32 * g + b) << b;
    uint32_t ch = lv ^ s->lvl[g];
    s->lvl[g] = lv;
    if (ch)
        sam_eic_lines_update(m);
}

void sam_pin_drive(sam_mcu_t *m, int pin, int level)
{
    port_tables();
    port_t *s = port_st(m);
    if (!s)
        return;
    if (level == 2)   /* toggle (a glitch of an edge storm) */
        level = s->ext[pin] > 0 ? 0 : 1;
    if (s->ext[pin] == level)
        return;
    s->ext[pin] = (int8_t)level;
    int g = pin >> 5, b = pin & 31;
    int nl = pad_level(m, s, pin);
    if ((int)(s->lvl[g] >> b & 1u) != nl) {
        s->lvl[g] ^= 1u << b;
        sam_eic_pin_input(m, pin, nl);
    }
}

static void port_reset(sam_mcu_t *m, int pi)
{
    port_tables();
    if (pi != port_pi)
        return;
    port_t *old = m->pst[pi];
    int8_t ext[64];
    if (old)
        memcpy(ext, old->ext, sizeof ext);   /* the board keeps driving its pins through a reset */
    else
        memset(ext, -1, sizeof ext);
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(port_t));
    port_t *s = m->pst[pi];
    memset(s, 0, sizeof *s);
    memcpy(s->ext, ext, sizeof ext);
    for (int g = 0; g < 2; g++)
        for (int b = 0; b < 32; b++)
            s->lvl[g] |= (uint32_t)pad_level(m, s, 32 * g + b) << b;
}

static int port_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    port_t *s = port_st(m);
    uint32_t off = sam_regs[ri].offset, g = off / 0x80, r = off % 0x80;
    if (r != PORT_IN_OFFSET)
        return SAM_GENERIC;
    uint32_t inen = 0;
    for (int b = 0; b < 32; b++)
        if (grp(m, (int)g)[PORT_PINCFG_OFFSET + b] & PORT_PINCFG_INEN)
            inen |= 1u << b;
    if (pi == iobus_pi) {
        /* the IOBUS reads the input synchronisers: live for pins sampled continuously (CTRL.SAMPLING), the value
         * of the last APB read for pins sampled on demand (the reset state) */
        uint32_t cont = port_ctrl(m, (int)g);
        *v = ((s->lvl[g] & cont) | (s->sampled[g] & ~cont)) & inen;
    } else {
        if (s->sampled[g] != s->lvl[g]) {
            s->sampled[g] = s->lvl[g];   /* an APB read clocks the on-demand synchronisers */
            sam_activity(m);
        }
        *v = s->lvl[g] & inen;
    }
    return SAM_DONE;
}

/* WRCONFIG: PINMASK selects pins of the half HWSEL names; WRPINCFG / WRPMUX update their PINCFG / PMUX. Whether a
 * byte of them differs from what it holds; `apply`: stored (else only compared) */
static int port_config_write(sam_mcu_t *m, int g, uint32_t wc, int apply)
{
    uint32_t mask = wc & 0xFFFFu, base = wc & PORT_WRCONFIG_HWSEL ? 16u : 0u;
    int changes = 0;
    for (uint32_t k = 0; k < 16; k++) {
        if (!(mask >> k & 1u))
            continue;
        uint32_t pin = base + k;
        uint8_t *cfg = &grp(m, g)[PORT_PINCFG_OFFSET + pin];
        if (wc & PORT_WRCONFIG_WRPINCFG) {
            uint8_t val = (uint8_t)(((wc & PORT_WRCONFIG_PMUXEN) ? PORT_PINCFG_PMUXEN : 0) |
                                    ((wc & PORT_WRCONFIG_INEN) ? PORT_PINCFG_INEN : 0) |
                                    ((wc & PORT_WRCONFIG_PULLEN) ? PORT_PINCFG_PULLEN : 0) |
                                    ((wc & PORT_WRCONFIG_DRVSTR) ? PORT_PINCFG_DRVSTR : 0));
            changes |= *cfg != val;
            if (apply)
                *cfg = val;
        }
        if (wc & PORT_WRCONFIG_WRPMUX) {
            uint8_t *pm = &grp(m, g)[PORT_PMUX_OFFSET + (pin >> 1)];
            uint8_t val = (uint8_t)((wc >> PORT_WRCONFIG_PMUX_Pos) & 15u);
            val = pin & 1 ? (uint8_t)((*pm & 0x0F) | val << 4) : (uint8_t)((*pm & 0xF0) | val);
            changes |= *pm != val;
            if (apply)
                *pm = val;
        }
    }
    return changes;
}

static int port_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset, g = off / 0x80, r = off % 0x80;
    int config = r >= PORT_PMUX_OFFSET || r == PORT_WRCONFIG_OFFSET;   /* the pins' mux or configuration */
    if (r == PORT_WRCONFIG_OFFSET ? !port_config_write(m, (int)g, v & mask, 0) : !sam_generic_changes(m, ri, v, mask)) {
        /* No byte of the group's registers changes (digitalWrite of a level the pin has): the pad levels are what
         * port_levels last found (every change of a register, a board's drive or a reset recomputes them), so the
         * EIC sees no edge; the motors integrate only where splitting their stretch here could change a bit
         * (sam_world_pins_unchanged). As before: WRCONFIG counts as activity, a mux or configuration write re-reads
         * the EIC's lines, and the bus lines are re-read (they also hold a slave's SCL and a stuck SDA). */
        if (r == PORT_WRCONFIG_OFFSET)
            sam_activity(m);
        sam_world_pins_unchanged(m);
        if (config)
            sam_eic_lines_update(m);
        sam_world_pins_changed(m);
        return SAM_DONE;
    }
    sam_world_pins_will_change(m);
    if (r == PORT_WRCONFIG_OFFSET) {
        port_config_write(m, (int)g, v & mask, 1);
        sam_activity(m);
    } else {
        sam_generic_write(m, ri, v, mask);
    }
    port_levels(m, (int)g);
    if (config)
        sam_eic_lines_update(m);
    sam_world_pins_changed(m);
    return SAM_DONE;
}

const sam_model_t sam_model_port = {"Port", port_reset, NULL, port_read, port_write, NULL};
