/* The per-chip layer of the cell program (SAMD21 / XIAO): PWM, DIR, sleep, encoders, tick. */
#ifndef SAMD21_HW_H
#define SAMD21_HW_H

#include <stdint.h>
#include "metacell.h"

/*
 * Everything register-level lives in samd21_hw.cpp; main.cpp only calls these.
 * Porting to another chip means rewriting that one file behind this interface.
 */

/* Check the variant's pin table against the port/bit constants the fast paths
 * assume. Returns 0, or the Arduino pin number that does not match. */
int hw_check_pins(void);
/* DIR and nSLEEP as outputs, low (drivers asleep, outputs off). */
void hw_drivers_init(void);
/* TCC0 normal PWM on D2 (WO[2]) and D3 (WO[3]) from GCLK0 = 48 MHz, period `top`
 * ticks (f = 48 MHz / top), both duties 0. */
void hw_pwm_init(uint16_t top);
/* Apply both drivers' commands: PH levels, EN duties (TCC0 CCB, takes effect at the
 * next PWM period), nSLEEP = a.enable || b.enable (one pin for both drivers). */
void hw_apply(const mc_drive_out_t *a, const mc_drive_out_t *b);
/* Both drivers asleep now (nSLEEP and PH low): the fault handler's safe state. Register
 * writes only, safe from any context. */
void hw_drivers_off(void);
/* Attach the pin interrupts, then sample both encoders and initialise the decoders from the
 * levels, with interrupts off throughout (on again at the end): no edge is lost between the
 * sample and the attach. The handlers attached are the encoders'
 * pin-change interrupts (EIC, both edges) that call mc_quad_update. */
void hw_encoders_init(mc_quad_t *alpha, mc_quad_t *beta);
/* Start TC3 calling hw_tick_handler() at rate_hz (MFRQ mode, NVIC priority 1:
 * below the pin interrupts, above the I2C SERCOM and USB). Returns the timer
 * period in timer clocks (rate error < 1 / period), or 0 if rate_hz cannot be
 * reached. */
uint32_t hw_tick_start(uint32_t rate_hz);
/* Set the NVIC priorities of hw_irq_priority[] (EIC 0, TC3 1, SERCOM2 2, USB 3). Call at the
 * end of setup(), after everything that sets a priority of its own (USB init before setup(),
 * attachInterrupt, hw_tick_start, Wire.begin in bus_setup). */
#define HW_IRQ_PRIORITIES 4
#ifdef __cplusplus
extern "C" {
#endif
extern const uint8_t hw_irq_priority[HW_IRQ_PRIORITIES][2];   /* {IRQn, priority 0..3} */
#ifdef __cplusplus
}
#endif
void hw_irq_priorities(void);
/* Hold off / release the control tick (for commands that touch the cell state). */
void hw_tick_mask(void);
void hw_tick_unmask(void);
/*
 * Interrupt entry points, all direct calls (no function pointers) so that
 * `python -m metacell_tools.fwcheck lint` can follow the whole control path from them:
 *   TC3_Handler -> hw_tick_handler (provided by the program: main.cpp)
 *   EIC (Arduino core) -> hw_isr_encoder_alpha / _beta -> mc_quad_update
 */
#ifdef __cplusplus
extern "C" {
#endif
void hw_tick_handler(void);
void hw_isr_encoder_alpha(void);
void hw_isr_encoder_beta(void);
#ifdef __cplusplus
}
#endif

/* 1 when the drivers' nFAULT line is low (0 when MC_PIN_NFAULT is not wired). */
int hw_nfault_active(void);

/* SERCOM2 as I2C secondary: SDA hold 300-600 ns (call after Wire.begin(addr)). */
void hw_i2c_secondary_timing(void);

#endif /* SAMD21_HW_H */
