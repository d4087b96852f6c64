/* Host stand-in for the Arduino API and the SAMD21 registers the glue touches (plain memory; field names as in the CMSIS headers). */
#pragma once
#include <stddef.h>
#include <stdint.h>
#define HIGH 1
#define LOW 0
#define INPUT 0
#define OUTPUT 1
#define INPUT_PULLUP 2
#define CHANGE 2
#define PIN_WIRE_SDA 4
#define PIN_WIRE_SCL 5
#define LED_BUILTIN 13
#define F_CPU 48000000ul
void pinMode(uint32_t pin, uint32_t mode);
void digitalWrite(uint32_t pin, uint32_t value);
int digitalRead(uint32_t pin);
void delayMicroseconds(unsigned int us);
unsigned long micros(void);
unsigned long millis(void);
#define digitalPinToInterrupt(p) (p)
void attachInterrupt(uint32_t pin, void (*isr)(void), uint32_t mode);
void noInterrupts(void);   /* the core's macros for __disable_irq / __enable_irq */
void interrupts(void);
struct SerialStub {
    void begin(unsigned long baud);
    int available();
    int read();
    size_t write(const uint8_t *buf, size_t n);
    size_t print(const char *s);
    int availableForWrite();
    bool dtr();
};
extern SerialStub Serial;

/* one register: the whole word or its bits (bits named as the glue uses them) */
#define REG(name, type, ...) union { type reg; struct { __VA_ARGS__ } bit; } name
struct SercomI2cmStub {
    volatile REG(CTRLA, uint32_t, uint32_t SWRST : 1, ENABLE : 1, MODE : 3, : 15, SDAHOLD : 2, : 6, INACTOUT : 2,
                 LOWTOUTEN : 1, : 1;);
    volatile REG(BAUD, uint32_t, uint32_t BAUD : 8, BAUDLOW : 8, HSBAUD : 8, HSBAUDLOW : 8;);
    volatile REG(CTRLB, uint32_t, uint32_t : 16, CMD : 2, ACKACT : 1, : 13;);
    volatile REG(SYNCBUSY, uint32_t, uint32_t SWRST : 1, ENABLE : 1, SYSOP : 1, : 29;);
    volatile REG(STATUS, uint16_t, uint16_t BUSERR : 1, ARBLOST : 1, RXNACK : 1, : 1, BUSSTATE : 2, LOWTOUT : 1, : 9;);
    volatile REG(INTFLAG, uint8_t, uint8_t MB : 1, SB : 1, : 5, ERROR : 1;);
    volatile REG(ADDR, uint32_t, uint32_t ADDR : 11, : 21;);
    volatile REG(DATA, uint8_t, uint8_t DATA : 8;);
};
union Sercom {   /* master and secondary views of the same registers, as in the CMSIS header */
    SercomI2cmStub I2CM;
    SercomI2cmStub I2CS;
};
extern Sercom *const SERCOM2;
#define SERCOM_I2CM_STATUS_BUSERR (1u << 0)
#define SERCOM_I2CM_STATUS_ARBLOST (1u << 1)
#define SERCOM_I2CM_STATUS_RXNACK (1u << 2)
#define SERCOM_I2CM_STATUS_LOWTOUT (1u << 6)
#define SERCOM_I2CM_INTFLAG_MB (1u << 0)
#define SERCOM_I2CM_INTFLAG_SB (1u << 1)
#define SERCOM_I2CM_CTRLB_CMD_Msk (3u << 16)
#define SERCOM_I2CM_CTRLB_CMD(v) (((uint32_t)(v) << 16) & SERCOM_I2CM_CTRLB_CMD_Msk)
#define SERCOM_I2CM_CTRLB_ACKACT (1u << 18)
#define SERCOM_I2CM_BAUD_BAUD(v) ((uint32_t)(v) & 0xFFu)
#define SERCOM_I2CM_BAUD_BAUDLOW(v) (((uint32_t)(v) & 0xFFu) << 8)

struct PortGroupStub {
    volatile REG(DIRSET, uint32_t, uint32_t b : 32;);
    volatile REG(OUTCLR, uint32_t, uint32_t b : 32;);
    volatile REG(OUTSET, uint32_t, uint32_t b : 32;);
    volatile REG(IN, uint32_t, uint32_t b : 32;);
    volatile REG(CTRL, uint32_t, uint32_t SAMPLING : 32;);
    volatile REG(PMUX[16], uint8_t, uint8_t PMUXE : 4, PMUXO : 4;);
    volatile REG(PINCFG[32], uint8_t, uint8_t PMUXEN : 1, INEN : 1, PULLEN : 1, : 5;);
};
struct PortStub { PortGroupStub Group[2]; };
extern PortStub *const PORT;
extern PortStub *const PORT_IOBUS;
#define PORT_PINCFG_PMUXEN 0x01u
#define PORT_PINCFG_INEN 0x02u
#define PORT_PMUX_PMUXE_F 0x05u
#define PORT_PMUX_PMUXO_F 0x50u
struct PinDescription { uint32_t ulPort, ulPin; };
extern PinDescription g_APinDescription[];   /* const in the core; writable here so a test can spoil it */

struct PmStub {
    volatile REG(APBCMASK, uint32_t, uint32_t b : 32;);
    volatile REG(RCAUSE, uint8_t, uint8_t POR : 1, BOD12 : 1, BOD33 : 1, : 1, EXT : 1, WDT : 1, SYST : 1, : 1;);
};
extern PmStub *const PM;
#define PM_RCAUSE_POR 0x01u
#define PM_RCAUSE_BOD12 0x02u
#define PM_RCAUSE_BOD33 0x04u
#define PM_RCAUSE_EXT 0x10u
#define PM_RCAUSE_WDT 0x20u
#define PM_RCAUSE_SYST 0x40u
#define PM_APBCMASK_TCC0 (1u << 8)
#define PM_APBCMASK_TC3 (1u << 11)

struct GclkStub {
    volatile REG(STATUS, uint8_t, uint8_t : 7, SYNCBUSY : 1;);
    volatile REG(CLKCTRL, uint16_t, uint16_t b : 16;);
    volatile REG(GENCTRL, uint32_t, uint32_t b : 32;);
    volatile REG(GENDIV, uint32_t, uint32_t b : 32;);
};
extern GclkStub *const GCLK;
#define GCLK_GENDIV_ID(v) ((uint32_t)(v))
#define GCLK_GENDIV_DIV(v) ((uint32_t)(v) << 8)
#define GCLK_GENCTRL_ID(v) ((uint32_t)(v))
#define GCLK_GENCTRL_SRC_OSCULP32K (3u << 8)
#define GCLK_GENCTRL_GENEN (1u << 16)
#define GCLK_GENCTRL_DIVSEL (1u << 20)
#define GCLK_CLKCTRL_ID_WDT 0x03u
#define GCLK_CLKCTRL_ID_TCC0_TCC1 0x1Au
#define GCLK_CLKCTRL_ID_TCC2_TC3 0x1Bu
#define GCLK_CLKCTRL_CLKEN (1u << 14)
#define GCLK_CLKCTRL_GEN_GCLK0 (0u << 8)
#define GCLK_CLKCTRL_GEN_GCLK2 (2u << 8)

struct WdtStub {
    volatile REG(CTRL, uint8_t, uint8_t : 1, ENABLE : 1, : 6;);
    volatile REG(CONFIG, uint8_t, uint8_t PER : 4, WINDOW : 4;);
    volatile REG(STATUS, uint8_t, uint8_t : 7, SYNCBUSY : 1;);
    volatile REG(CLEAR, uint8_t, uint8_t CLEAR : 8;);
};
extern WdtStub *const WDT;
#define WDT_CTRL_ENABLE 0x02u
#define WDT_CONFIG_PER_1K 0x07u
#define WDT_CLEAR_CLEAR_KEY 0xA5u

struct TccStub {
    volatile REG(CTRLA, uint32_t, uint32_t b : 32;);
    volatile REG(SYNCBUSY, uint32_t, uint32_t b : 32;);
    volatile REG(WAVE, uint32_t, uint32_t b : 32;);
    volatile REG(PER, uint32_t, uint32_t b : 32;);
    volatile REG(CC[4], uint32_t, uint32_t b : 32;);
    volatile REG(CCB[4], uint32_t, uint32_t b : 32;);
};
extern TccStub *const TCC0;
#define TCC_CTRLA_ENABLE 0x02u
#define TCC_CTRLA_SWRST 0x01u
#define TCC_CTRLA_PRESCALER_DIV1 0u
#define TCC_WAVE_WAVEGEN_NPWM 2u
#define TCC_SYNCBUSY_SWRST 0x01u
#define TCC_SYNCBUSY_ENABLE 0x02u
#define TCC_SYNCBUSY_WAVE 0x40u
#define TCC_SYNCBUSY_PER 0x80u
#define TCC_SYNCBUSY_CC2 0x400u
#define TCC_SYNCBUSY_CC3 0x800u
#define TCC_SYNCBUSY_CCB2 0x40000u
#define TCC_SYNCBUSY_CCB3 0x80000u
struct TcCount16Stub {
    /* SWRST sits outside reg, so it reads 0: a software reset completes at once */
    volatile REG(CTRLA, uint16_t, uint16_t : 16; uint16_t SWRST : 1, ENABLE : 1, : 14;);
    volatile REG(STATUS, uint8_t, uint8_t : 7, SYNCBUSY : 1;);
    volatile REG(INTFLAG, uint8_t, uint8_t b : 8;);
    volatile REG(INTENSET, uint8_t, uint8_t b : 8;);
    volatile REG(CC[2], uint16_t, uint16_t b : 16;);
};
struct TcStub { TcCount16Stub COUNT16; };
extern TcStub *const TC3;
#define TC_CTRLA_ENABLE 0x02u
#define TC_CTRLA_SWRST 0x01u
#define TC_CTRLA_MODE_COUNT16 0u
#define TC_CTRLA_WAVEGEN_MFRQ (1u << 5)
#define TC_CTRLA_PRESCSYNC_PRESC (1u << 12)
#define TC_CTRLA_PRESCALER_DIV1 (0u << 8)
#define TC_CTRLA_PRESCALER_DIV2 (1u << 8)
#define TC_CTRLA_PRESCALER_DIV4 (2u << 8)
#define TC_CTRLA_PRESCALER_DIV8 (3u << 8)
#define TC_CTRLA_PRESCALER_DIV16 (4u << 8)
#define TC_CTRLA_PRESCALER_DIV64 (5u << 8)
#define TC_CTRLA_PRESCALER_DIV256 (6u << 8)
#define TC_CTRLA_PRESCALER_DIV1024 (7u << 8)
#define TC_INTFLAG_OVF 0x01u
#define TC_INTENSET_OVF 0x01u
enum IRQn_Type { EIC_IRQn = 4, USB_IRQn = 7, SERCOM2_IRQn = 11, TC3_IRQn = 18 };
void NVIC_SetPriority(IRQn_Type irq, uint32_t prio);
void NVIC_ClearPendingIRQ(IRQn_Type irq);
void NVIC_EnableIRQ(IRQn_Type irq);
void NVIC_DisableIRQ(IRQn_Type irq);
[[noreturn]] void NVIC_SystemReset(void);   /* the driver's reset hook (longjmp back to its boot) */
