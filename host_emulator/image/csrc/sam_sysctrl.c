/* SYSCTRL: the oscillators (OSC8M, OSC32K, OSCULP32K, XOSC32K with its start-up time, DFLL48M) and their ready bits. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

/* The board: a Seeeduino XIAO has a 32.768 kHz crystal on XIN32/XOUT32 (PA00, PA01) and no main crystal: XOSC32K
 * becomes ready after its STARTUP time, XOSC never does. The DFLL in closed loop runs at MUL x its reference; within
 * DFLL_NOMINAL_TOL of 48 MHz (1465 x 32768 Hz = 48.005 MHz, +107 ppm, is) it is taken as exactly 48 MHz: the boards'
 * clocks are nominal, oscillator tolerance and drift are not modelled. Open loop and USB clock recovery: 48 MHz. */
#define HZ_OSCULP32K 32768u
#define HZ_OSC32K 32768u
#define HZ_OSC8M 8000000u
#define HZ_DFLL_OPEN 48000000u
#define HZ_USB_SOF 1000u
#define HZ_DFLL_NOMINAL 48000000u
#define DFLL_NOMINAL_TOL 1e-3
/* XOSC32K start-up (SYSCTRL.XOSC32K.STARTUP): OSCULP32K cycles, plus 3 for synchronisation (DS40001882 table
 * "Start-Up Time for 32kHz External Crystal Oscillator": 0x6 is 65536 cycles, 2000092 us) */
static const uint32_t XOSC32K_STARTUP[8] = {1, 32, 2048, 4096, 16384, 32768, 65536, 131072};

static uint32_t field_get(uint32_t v, uint32_t pos, uint32_t width) { return (v >> pos) & ((1u << width) - 1u); }

static uint32_t sysctrl_get(sam_mcu_t *m, uint32_t off)
{
    const uint8_t *p = m->regs[sam_idx.sysctrl] + off;
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t sam_dfll_hz(sam_mcu_t *m)
{
    uint32_t ctrl = sysctrl_get(m, SYSCTRL_DFLLCTRL_OFFSET);
    if (!(ctrl & SYSCTRL_DFLLCTRL_ENABLE))
        return 0;
    if (!(ctrl & SYSCTRL_DFLLCTRL_MODE))
        return HZ_DFLL_OPEN;
    uint32_t mul = sysctrl_get(m, SYSCTRL_DFLLMUL_OFFSET) & 0xFFFFu;
    uint64_t hz = ctrl & SYSCTRL_DFLLCTRL_USBCRM ? (uint64_t)mul * HZ_USB_SOF
                                                 : (uint64_t)mul * sam_gclk_hz(m, SYSCTRL_GCLK_ID_DFLL48);
    if (fabs((double)hz - HZ_DFLL_NOMINAL) <= HZ_DFLL_NOMINAL * DFLL_NOMINAL_TOL)
        hz = HZ_DFLL_NOMINAL;
    return hz;
}

typedef struct {
    uint64_t xosc32k_ready;   /* when XOSC32K's start-up ends (SAM_NEVER: off) */
} sysctrl_t;

static void sysctrl_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(sysctrl_t));
    ((sysctrl_t *)m->pst[pi])->xosc32k_ready = SAM_NEVER;
}

static int sysctrl_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    sysctrl_t *s = m->pst[pi];
    if (sam_regs[ri].offset == SYSCTRL_PCLKSR_OFFSET) {
        uint32_t r = SYSCTRL_PCLKSR_DFLLRDY | SYSCTRL_PCLKSR_BOD33RDY | SYSCTRL_PCLKSR_B33SRDY;
        if (sam_now(m) >= s->xosc32k_ready)
            r |= SYSCTRL_PCLKSR_XOSC32KRDY;
        if (sysctrl_get(m, SYSCTRL_OSC32K_OFFSET) & SYSCTRL_OSC32K_ENABLE)
            r |= SYSCTRL_PCLKSR_OSC32KRDY;
        if (sysctrl_get(m, SYSCTRL_OSC8M_OFFSET) & SYSCTRL_OSC8M_ENABLE)
            r |= SYSCTRL_PCLKSR_OSC8MRDY;
        uint32_t dc = sysctrl_get(m, SYSCTRL_DFLLCTRL_OFFSET);
        if ((dc & SYSCTRL_DFLLCTRL_ENABLE) && (dc & SYSCTRL_DFLLCTRL_MODE))
            r |= SYSCTRL_PCLKSR_DFLLLCKF | SYSCTRL_PCLKSR_DFLLLCKC;
        *v = r;
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int sysctrl_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    uint32_t off = sam_regs[ri].offset;
    if (off == SYSCTRL_INTENSET_OFFSET && (v & mask)) {
        sam_fail(m, "SYSCTRL interrupts are not modelled (INTENSET = 0x%x)", v);
        return SAM_DONE;
    }
    if (off == SYSCTRL_DPLLCTRLA_OFFSET && (v & mask & SYSCTRL_DPLLCTRLA_ENABLE)) {
        sam_fail(m, "the FDPLL96M is not modelled");
        return SAM_DONE;
    }
    uint32_t old = sam_reg_get(m, ri);
    uint32_t nv = (old & ~mask) | (v & mask);
    if (sam_regs[ri].kind != SAM_KIND_PLAIN)
        return SAM_GENERIC;
    sam_reg_put(m, ri, nv);
    if (off == SYSCTRL_XOSC32K_OFFSET) {
        sysctrl_t *s = m->pst[pi];
        int on = (nv & (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN)) == (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN);
        if (on && !((old & (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN)) == (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN))) {
            uint32_t cyc = XOSC32K_STARTUP[(nv >> SYSCTRL_XOSC32K_STARTUP_Pos) & 7u] + 3u;
            s->xosc32k_ready = sam_now(m) + (uint64_t)cyc * (SAM_TU_HZ / HZ_OSCULP32K);
            sam_slot_set(m, pi, s->xosc32k_ready);   /* the ready bit changes then: an event */
        } else if (!on) {
            s->xosc32k_ready = SAM_NEVER;
        }
    }
    if (nv != old) {
        sam_activity(m);
        sam_set_cpu_clock(m);   /* a source of GCLK0 may have changed */
    }
    return SAM_DONE;
}

static void sysctrl_fire(sam_mcu_t *m, int pi)
{
    (void)m;
    (void)pi;   /* a start-up ended: the event itself is what matters (PCLKSR reads change now) */
}

const sam_model_t sam_model_sysctrl = {"Sysctrl", sysctrl_reset, NULL, sysctrl_read, sysctrl_write, sysctrl_fire};

/* The frequency of a generic clock generator's source SRC when it is one of SYSCTRL's oscillators (0: off, still
 * starting, or not an oscillator of this board). */
uint64_t sam_sysctrl_osc_hz(sam_mcu_t *m, uint32_t src)
{
    switch (src) {
    case GCLK_GENCTRL_SRC_OSCULP32K_Val: return HZ_OSCULP32K;
    case GCLK_GENCTRL_SRC_OSC32K_Val:
        return (sysctrl_get(m, SYSCTRL_OSC32K_OFFSET) & (SYSCTRL_OSC32K_ENABLE | SYSCTRL_OSC32K_EN32K)) ==
                       (SYSCTRL_OSC32K_ENABLE | SYSCTRL_OSC32K_EN32K)
                   ? HZ_OSC32K
                   : 0;
    case GCLK_GENCTRL_SRC_OSC8M_Val: {
        uint32_t o = sysctrl_get(m, SYSCTRL_OSC8M_OFFSET);
        return o & SYSCTRL_OSC8M_ENABLE ? HZ_OSC8M >> field_get(o, SYSCTRL_OSC8M_PRESC_Pos, 2) : 0;
    }
    case GCLK_GENCTRL_SRC_DFLL48M_Val: return sam_dfll_hz(m);
    case GCLK_GENCTRL_SRC_XOSC32K_Val: {
        uint32_t x = sysctrl_get(m, SYSCTRL_XOSC32K_OFFSET);
        sysctrl_t *s = m->pst[sam_idx.sysctrl];
        return (x & SYSCTRL_XOSC32K_EN32K) && s && sam_now(m) >= s->xosc32k_ready ? 32768u : 0;
    }
    default: return 0;   /* XOSC: not fitted on the XIAO; FDPLL96M: not modelled */
    }
}
