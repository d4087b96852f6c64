/* SAMD21 (Seeeduino XIAO) register-level layer: TCC0 PWM, DIR/nSLEEP, EIC encoders, TC3 tick. */
#include <Arduino.h>
#include "samd21_hw.h"
#include "cell_config.h"

/*
 * Port/bit of every pin the fast paths touch (Seeed variant XIAO_m0, docs/hardware.md).
 * hw_check_pins() compares them with the variant's g_APinDescription at start-up,
 * so a different variant stops the program instead of driving the wrong pins.
 */
#define PA 0u
#define PB 1u
struct pin_fact { uint8_t arduino, port, bit; };
static const pin_fact k_pins[] = {
    {CELL_PIN_NSLEEP, PA, 2},   {CELL_PIN_DIR_A, PA, 4},    {CELL_PIN_PWM_A, PA, 10},
    {CELL_PIN_PWM_B, PA, 11},   {CELL_PIN_DIR_B, PB, 8},    {CELL_PIN_ENC_A_A, PB, 9},
    {CELL_PIN_ENC_A_B, PA, 7},  {CELL_PIN_ENC_B_A, PA, 5},  {CELL_PIN_ENC_B_B, PA, 6},
};
#define NSLEEP_MASK (1ul << 2)   /* PA02 */
#define DIR_A_MASK (1ul << 4)    /* PA04 */
#define DIR_B_MASK (1ul << 8)    /* PB08 */
#define ENC_AA_BIT 9             /* PB09: alpha A */
#define ENC_AB_BIT 7             /* PA07: alpha B */
#define ENC_BA_BIT 5             /* PA05: beta A */
#define ENC_BB_BIT 6             /* PA06: beta B */
#define PWM_CC_A 2               /* PA10 = TCC0/WO[2] -> CC[2] (peripheral function F) */
#define PWM_CC_B 3               /* PA11 = TCC0/WO[3] -> CC[3] */

int hw_check_pins(void)
{
    for (unsigned i = 0; i < sizeof(k_pins) / sizeof(k_pins[0]); i++) {
        const PinDescription &d = g_APinDescription[k_pins[i].arduino];
        if ((unsigned)d.ulPort != k_pins[i].port || d.ulPin != k_pins[i].bit)
            return k_pins[i].arduino;
    }
    return 0;
}

void hw_drivers_init(void)
{
    /* Low first, then output: no glitch to high on the driver inputs. */
    PORT->Group[PA].OUTCLR.reg = NSLEEP_MASK | DIR_A_MASK;
    PORT->Group[PB].OUTCLR.reg = DIR_B_MASK;
    PORT->Group[PA].DIRSET.reg = NSLEEP_MASK | DIR_A_MASK;
    PORT->Group[PB].DIRSET.reg = DIR_B_MASK;
    /* EN pins stay GPIO inputs (DRV8874 pulls EN low) until hw_pwm_init muxes them. */
#if MC_PIN_NFAULT >= 0
    pinMode(MC_PIN_NFAULT, INPUT_PULLUP);
#endif
}

static void tcc0_sync(uint32_t mask)
{
    while (TCC0->SYNCBUSY.reg & mask) {
    }
}

void hw_pwm_init(uint16_t top)
{
    /* GCLK0 (48 MHz DFLL) -> TCC0/TCC1; APB clock of TCC0 on. */
    GCLK->CLKCTRL.reg = GCLK_CLKCTRL_CLKEN | GCLK_CLKCTRL_GEN_GCLK0 | GCLK_CLKCTRL_ID_TCC0_TCC1;
    while (GCLK->STATUS.bit.SYNCBUSY) {
    }
    PM->APBCMASK.reg |= PM_APBCMASK_TCC0;

    TCC0->CTRLA.reg &= ~TCC_CTRLA_ENABLE;
    tcc0_sync(TCC_SYNCBUSY_ENABLE);
    TCC0->CTRLA.reg = TCC_CTRLA_SWRST;
    tcc0_sync(TCC_SYNCBUSY_SWRST);

    /* Normal (single-slope) PWM: counter 0..PER, output high while COUNT < CC,
     * so duty = CC / (PER + 1) = CC / top; CC = 0 is off, CC >= top fully on. */
    TCC0->CTRLA.reg = TCC_CTRLA_PRESCALER_DIV1;
    TCC0->WAVE.reg = TCC_WAVE_WAVEGEN_NPWM;
    tcc0_sync(TCC_SYNCBUSY_WAVE);
    TCC0->PER.reg = (uint32_t)top - 1u;
    tcc0_sync(TCC_SYNCBUSY_PER);
    TCC0->CC[PWM_CC_A].reg = 0;
    TCC0->CC[PWM_CC_B].reg = 0;
    tcc0_sync(TCC_SYNCBUSY_CC2 | TCC_SYNCBUSY_CC3);
    TCC0->CTRLA.reg |= TCC_CTRLA_ENABLE;
    tcc0_sync(TCC_SYNCBUSY_ENABLE);

    /* PA10/PA11 to peripheral function F (TCC0/WO[2], WO[3]); PMUX[5] holds the
     * even (PA10) and odd (PA11) nibble. */
    PORT->Group[PA].PINCFG[10].reg |= PORT_PINCFG_PMUXEN;
    PORT->Group[PA].PINCFG[11].reg |= PORT_PINCFG_PMUXEN;
    PORT->Group[PA].PMUX[10 >> 1].reg = PORT_PMUX_PMUXE_F | PORT_PMUX_PMUXO_F;
}

void hw_apply(const mc_drive_out_t *a, const mc_drive_out_t *b)
{
    uint32_t da = a->enable ? a->duty : 0u;
    uint32_t db = b->enable ? b->duty : 0u;
    /* Buffered compare: the new duty starts with the next PWM period (no glitch). */
    tcc0_sync(TCC_SYNCBUSY_CCB2 | TCC_SYNCBUSY_CCB3);
    TCC0->CCB[PWM_CC_A].reg = da;
    TCC0->CCB[PWM_CC_B].reg = db;
    if (a->enable | b->enable) {
        if (a->dir)
            PORT_IOBUS->Group[PA].OUTSET.reg = DIR_A_MASK;
        else
            PORT_IOBUS->Group[PA].OUTCLR.reg = DIR_A_MASK;
        if (b->dir)
            PORT_IOBUS->Group[PB].OUTSET.reg = DIR_B_MASK;
        else
            PORT_IOBUS->Group[PB].OUTCLR.reg = DIR_B_MASK;
        PORT_IOBUS->Group[PA].OUTSET.reg = NSLEEP_MASK;
    } else {
        /* Off: nSLEEP low puts both drivers' outputs in high impedance at once,
         * without waiting for the buffered duty 0. */
        PORT_IOBUS->Group[PA].OUTCLR.reg = NSLEEP_MASK | DIR_A_MASK;
        PORT_IOBUS->Group[PB].OUTCLR.reg = DIR_B_MASK;
    }
}

void hw_drivers_off(void)
{
    /* nSLEEP low: both drivers' outputs high-impedance at once, whatever TCC0 still drives */
    PORT_IOBUS->Group[PA].OUTCLR.reg = NSLEEP_MASK | DIR_A_MASK;
    PORT_IOBUS->Group[PB].OUTCLR.reg = DIR_B_MASK;
}

/* ---- encoders -------------------------------------------------------------- */

static mc_quad_t *s_quad[2];

/* (A << 1) | B of each encoder straight from the single-cycle IOBUS IN registers. */
static inline uint8_t read_alpha(void)
{
    uint32_t pa = PORT_IOBUS->Group[PA].IN.reg;
    uint32_t pb = PORT_IOBUS->Group[PB].IN.reg;
    return (uint8_t)((((pb >> ENC_AA_BIT) & 1u) << 1) | ((pa >> ENC_AB_BIT) & 1u));
}

static inline uint8_t read_beta(void)
{
    uint32_t pa = PORT_IOBUS->Group[PA].IN.reg;
    return (uint8_t)((((pa >> ENC_BA_BIT) & 1u) << 1) | ((pa >> ENC_BB_BIT) & 1u));
}

/* Either channel of an encoder changed: sample both, let the table decide. */
extern "C" void hw_isr_encoder_alpha(void) { mc_quad_update(s_quad[MC_ALPHA], read_alpha()); }
extern "C" void hw_isr_encoder_beta(void) { mc_quad_update(s_quad[MC_BETA], read_beta()); }

static void attach_encoder_pin(uint8_t pin, void (*isr)(void))
{
    attachInterrupt(digitalPinToInterrupt(pin), isr, CHANGE);
    /* attachInterrupt muxes the pin to the EIC; keep the input buffer on so the
     * IN register still reads the level. */
    const PinDescription &d = g_APinDescription[pin];
    PORT->Group[d.ulPort].PINCFG[d.ulPin].reg |= PORT_PINCFG_INEN;
}

/*
 * PORT CTRL.SAMPLING: the IOBUS reads IN in one cycle, but with on-demand sampling
 * (the reset state) a pin's input synchroniser only runs when the APB reads it, so
 * an IOBUS read may return a level from the last APB read: a stale level makes the
 * decoder see a skipped state (a false illegal transition, a latched fault). The
 * datasheet asks for continuous sampling of every pin read through the IOBUS.
 */
#define ENC_SAMPLE_PA ((1ul << ENC_AB_BIT) | (1ul << ENC_BA_BIT) | (1ul << ENC_BB_BIT))
#define ENC_SAMPLE_PB (1ul << ENC_AA_BIT)

void hw_encoders_init(mc_quad_t *alpha, mc_quad_t *beta)
{
    static const uint8_t pins[] = {CELL_PIN_ENC_A_A, CELL_PIN_ENC_A_B, CELL_PIN_ENC_B_A,
                                   CELL_PIN_ENC_B_B};
    for (unsigned i = 0; i < sizeof(pins); i++)
        pinMode(pins[i], INPUT_PULLUP);
    PORT->Group[PA].CTRL.reg |= ENC_SAMPLE_PA;   /* continuous sampling: PA05, PA06, PA07 */
    PORT->Group[PB].CTRL.reg |= ENC_SAMPLE_PB;   /* and PB09 */
    delayMicroseconds(20);   /* let the pull-ups settle before the first sample */
    s_quad[MC_ALPHA] = alpha;
    s_quad[MC_BETA] = beta;
    /*
     * Attach first, sample after, all with interrupts off. Once a pin is on the EIC every
     * edge latches its flag: an edge after the sample runs the handler when interrupts come
     * back (it samples again; the same state twice counts 0), an edge before it is in the
     * sample. Sampling first lost an edge that came before its pin was attached: the decoder
     * started from a stale state and the next edge looked illegal.
     */
    noInterrupts();
    attach_encoder_pin(CELL_PIN_ENC_A_A, hw_isr_encoder_alpha);
    attach_encoder_pin(CELL_PIN_ENC_A_B, hw_isr_encoder_alpha);
    attach_encoder_pin(CELL_PIN_ENC_B_A, hw_isr_encoder_beta);
    attach_encoder_pin(CELL_PIN_ENC_B_B, hw_isr_encoder_beta);
    mc_quad_init(alpha, read_alpha());
    mc_quad_init(beta, read_beta());
    interrupts();
}

/* ---- control tick (TC3) ------------------------------------------------------ */

extern "C" void TC3_Handler(void)
{
    TC3->COUNT16.INTFLAG.reg = TC_INTFLAG_OVF;
    hw_tick_handler();
}

static void tc3_sync(void)
{
    while (TC3->COUNT16.STATUS.bit.SYNCBUSY) {
    }
}

uint32_t hw_tick_start(uint32_t rate_hz)
{
    /* Smallest prescaler whose period fits the 16-bit counter. Configuration
     * only: the divisions here run once, never in the tick. */
    static const uint16_t presc[] = {1, 2, 4, 8, 16, 64, 256, 1024};
    static const uint32_t presc_bits[] = {
        TC_CTRLA_PRESCALER_DIV1,  TC_CTRLA_PRESCALER_DIV2,   TC_CTRLA_PRESCALER_DIV4,
        TC_CTRLA_PRESCALER_DIV8,  TC_CTRLA_PRESCALER_DIV16,  TC_CTRLA_PRESCALER_DIV64,
        TC_CTRLA_PRESCALER_DIV256, TC_CTRLA_PRESCALER_DIV1024};
    if (rate_hz == 0)
        return 0;
    unsigned i = 0;
    uint32_t period = 0;
    for (; i < sizeof(presc) / sizeof(presc[0]); i++) {
        uint32_t clk = F_CPU / presc[i];
        period = (clk + rate_hz / 2u) / rate_hz;
        if (period <= 65536u)
            break;
    }
    if (i == sizeof(presc) / sizeof(presc[0]) || period < 2u)
        return 0;

    GCLK->CLKCTRL.reg = GCLK_CLKCTRL_CLKEN | GCLK_CLKCTRL_GEN_GCLK0 | GCLK_CLKCTRL_ID_TCC2_TC3;
    while (GCLK->STATUS.bit.SYNCBUSY) {
    }
    PM->APBCMASK.reg |= PM_APBCMASK_TC3;

    TC3->COUNT16.CTRLA.reg &= ~TC_CTRLA_ENABLE;
    tc3_sync();
    TC3->COUNT16.CTRLA.reg = TC_CTRLA_SWRST;
    while (TC3->COUNT16.CTRLA.bit.SWRST) {
    }
    /* Match-frequency mode: counts 0..CC0 and wraps, OVF once per period. */
    TC3->COUNT16.CTRLA.reg = TC_CTRLA_MODE_COUNT16 | TC_CTRLA_WAVEGEN_MFRQ |
                             presc_bits[i] | TC_CTRLA_PRESCSYNC_PRESC;
    tc3_sync();
    TC3->COUNT16.CC[0].reg = (uint16_t)(period - 1u);
    tc3_sync();
    TC3->COUNT16.INTENSET.reg = TC_INTENSET_OVF;

    NVIC_SetPriority(TC3_IRQn, 1);
    NVIC_ClearPendingIRQ(TC3_IRQn);
    NVIC_EnableIRQ(TC3_IRQn);
    TC3->COUNT16.CTRLA.reg |= TC_CTRLA_ENABLE;
    tc3_sync();
    return period;
}

/* ---- interrupt priorities ----------------------------------------------------- */

/*
 * NVIC priorities of the cell, 0 = most urgent (the Cortex-M0+ has four levels, and an
 * interrupt cannot pre-empt one of equal priority). The core leaves USB at 0 (USBCore.cpp
 * init) beside the EIC (WInterrupts.c), and its USB handler busy-waits on the host during
 * control transfers (sendControl/recvControl -> armRecvCtrlOUT), e.g. when the flash tool
 * opens the port. At full speed encoder edges are 27-54 us apart: an edge held off that long
 * lets both channels change before the handler samples them, an illegal transition to the
 * decoder, a count slip of 2 and, in a burst, a latched MC_FAULT_ENCODER. So:
 *   EIC 0      encoder edges pre-empt everything that can wait
 *   TC3 1      the control tick (34 us worst case, every 500 us)
 *   SERCOM2 2  the I2C secondary: it stretches SCL until its handler has run, so it stays
 *              above USB (the core's Wire.begin sets it to 3)
 *   USB 3      host traffic waits; its deadlines are milliseconds
 * SysTick stays at the core's 2 (millis/micros). fwcheck reads this table from the linked
 * image (docs/hardware.md, "Interrupt priorities").
 */
extern "C" const uint8_t hw_irq_priority[HW_IRQ_PRIORITIES][2] = {
    {EIC_IRQn, 0},
    {TC3_IRQn, 1},
    {SERCOM2_IRQn, 2},
    {USB_IRQn, 3},
};

void hw_irq_priorities(void)
{
    for (unsigned i = 0; i < HW_IRQ_PRIORITIES; i++)
        NVIC_SetPriority((IRQn_Type)hw_irq_priority[i][0], hw_irq_priority[i][1]);
}

void hw_tick_mask(void) { NVIC_DisableIRQ(TC3_IRQn); }
void hw_tick_unmask(void) { NVIC_EnableIRQ(TC3_IRQn); }

int hw_nfault_active(void)
{
#if MC_PIN_NFAULT >= 0
    return digitalRead(MC_PIN_NFAULT) == LOW;
#else
    return 0;
#endif
}

/* ---- I2C secondary -------------------------------------------------------------- */

void hw_i2c_secondary_timing(void)
{
    /* SDA hold 300-600 ns after SCL falls, as on the primary (docs/hardware.md, "Bus timing");
     * the core's Wire.begin(addr) leaves 0. CTRLA is enable-protected: disable, set, enable. */
    SERCOM2->I2CS.CTRLA.bit.ENABLE = 0;
    while (SERCOM2->I2CS.SYNCBUSY.bit.ENABLE) {
    }
    SERCOM2->I2CS.CTRLA.bit.SDAHOLD = 2;
    SERCOM2->I2CS.CTRLA.bit.ENABLE = 1;
    while (SERCOM2->I2CS.SYNCBUSY.bit.ENABLE) {
    }
}
