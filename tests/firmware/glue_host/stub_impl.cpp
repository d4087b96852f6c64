/* Host definitions of the Arduino/SAMD21 stand-ins: register memory, open-drain line model, clock, USB serial, Wire. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "Arduino.h"
#include "Wire.h"
#include "stub_state.h"
#include "common/samd21_sys.h"

static Sercom g_sercom2;
Sercom *const SERCOM2 = &g_sercom2;
static PortStub g_port;
PortStub *const PORT = &g_port;
PortStub *const PORT_IOBUS = &g_port;   /* the same PORT registers through the single-cycle bus */
static PmStub g_pm;
PmStub *const PM = &g_pm;
static GclkStub g_gclk;
GclkStub *const GCLK = &g_gclk;
static WdtStub g_wdt;
WdtStub *const WDT = &g_wdt;
static TccStub g_tcc0;
TccStub *const TCC0 = &g_tcc0;
static TcStub g_tc3;
TcStub *const TC3 = &g_tc3;
/* Seeed XIAO_m0 variant: D0..D10 */
PinDescription g_APinDescription[] = {{0, 2}, {0, 4}, {0, 10}, {0, 11}, {0, 8}, {0, 9},
                                            {1, 8}, {1, 9}, {0, 7},  {0, 5},  {0, 6}};

stub_state_t stub;
/* the fault record: a fixed RAM address on the target (platformio.ini), plain memory here */
volatile sys_fault_record_t mc_fault_record;

static void line_event(uint32_t pin)
{
    if (pin != PIN_WIRE_SDA && pin != PIN_WIRE_SCL)
        return;
    stub_pin_t &p = stub.pin[pin];
    if (p.mode == OUTPUT && p.out)
        stub.driven_high++;   /* an I2C line must never be driven high */
    int sda = stub.pin[PIN_WIRE_SDA].mode == OUTPUT ? stub.pin[PIN_WIRE_SDA].out : 1;
    int scl = stub.pin[PIN_WIRE_SCL].mode == OUTPUT ? stub.pin[PIN_WIRE_SCL].out : 1;
    if (sda == stub.sda && scl == stub.scl)
        return;
    if (scl && stub.scl && sda != stub.sda) {
        if (sda)
            stub.stops++;
        else
            stub.starts++;
    }
    if (!scl && stub.scl)
        stub.scl_falls++;
    stub.sda = sda;
    stub.scl = scl;
    if (stub.n_log < (int)sizeof(stub.log))
        stub.log[stub.n_log++] = (char)('0' + (scl << 1 | sda));
}

void pinMode(uint32_t pin, uint32_t mode)
{
    if (pin >= 32)
        return;
    stub.pin[pin].mode = (int)mode;
    if (mode == INPUT_PULLUP)
        stub.pin[pin].out = 1;   /* SAMD: OUT selects the pull direction */
    line_event(pin);
}

void digitalWrite(uint32_t pin, uint32_t value)
{
    if (pin >= 32)
        return;
    stub.pin[pin].out = value ? 1 : 0;
    line_event(pin);
}

int digitalRead(uint32_t pin) { return pin < 32 ? stub.pin[pin].out : 0; }

unsigned long micros(void)
{
    stub.now_us += 1;
    if (stub.on_micros)
        stub.on_micros();
    return stub.now_us;
}
void delayMicroseconds(unsigned int us) { stub.now_us += us; }
unsigned long millis(void) { return stub.now_us / 1000u; }
void stub_edge(uint32_t pin)
{
    const PinDescription &d = g_APinDescription[pin];
    PORT->Group[d.ulPort].IN.reg ^= 1u << d.ulPin;
    if (!stub.isr[pin])
        return;   /* not on the EIC yet: nothing latches the edge */
    if (stub.irq_off)
        stub.pending |= 1u << pin;
    else
        stub.isr[pin]();
}

void noInterrupts(void) { stub.irq_off = 1; }
void interrupts(void)
{
    stub.irq_off = 0;
    for (uint32_t pin = 0; pin < 32; pin++)
        if (stub.pending & (1u << pin)) {
            stub.pending &= ~(1u << pin);
            stub.isr[pin]();
        }
}

void attachInterrupt(uint32_t pin, void (*isr)(void), uint32_t mode)
{
    (void)mode;
    int first = !stub.attached;
    if (first)
        stub.prio[EIC_IRQn] = 0;   /* the core's first attachInterrupt: EIC at priority 0 */
    if (pin < 32) {
        stub.attached |= 1u << pin;
        stub.isr[pin] = isr;
    }
    if (first && stub.edge_on_first_attach > 0)
        stub_edge((uint32_t)stub.edge_on_first_attach);
}
void NVIC_SetPriority(IRQn_Type irq, uint32_t prio)
{
    if ((unsigned)irq < 32)
        stub.prio[irq] = (int)prio;
}
void NVIC_ClearPendingIRQ(IRQn_Type) {}
void NVIC_EnableIRQ(IRQn_Type) {}
void NVIC_DisableIRQ(IRQn_Type) {}
void NVIC_SystemReset(void)
{
    stub.resets++;
    longjmp(stub.reset, 1);
}

SerialStub Serial;
void SerialStub::begin(unsigned long) {}
int SerialStub::available() { return stub.flood || stub.in_pos < stub.in_len; }
int SerialStub::read()
{
    if (++stub.reads > 100000) {
        printf("starved=1\n");   /* one pass of loop() never ends while the host keeps sending */
        fflush(stdout);
        exit(3);
    }
    if (stub.flood)
        return 'x';
    return stub.in_pos < stub.in_len ? (uint8_t)stub.in[stub.in_pos++] : -1;
}
void stub_usb_host_reads(void)
{
    if (stub.usb_blocked || !stub.bank_ready)
        return;
    stub.usb_delivered += stub.bank_bytes;   /* data, or the zero-length packet after a timeout */
    stub.bank_bytes = 0;
    stub.bank_ready = false;
}

/* USBCore.cpp USBDeviceClass::send for one packet: wait for the armed bank to be read (70 ms,
 * or at once after an earlier timeout), on timeout zero its byte count and fail; else arm. */
size_t SerialStub::write(const uint8_t *buf, size_t n)
{
    (void)buf;
    stub.usb_tried += n;
    stub.usb_writes++;
    if (n > stub.usb_max_write)
        stub.usb_max_write = n;
    stub_usb_host_reads();
    if (stub.bank_ready) {
        if (!stub.timed_out)
            stub.now_us += 70000;   /* the core's TX_TIMEOUT_MS wait */
        stub.timed_out = true;
        stub.usb_zeroed += stub.bank_bytes;
        stub.bank_bytes = 0;   /* "set byte count to zero, so that ZLP is sent" */
        return (size_t)-1;
    }
    stub.timed_out = false;
    stub.bank_ready = true;
    stub.bank_bytes = n;
    stub.usb_sent += n;
    stub_usb_host_reads();   /* a reading host takes it at once */
    return n;
}
size_t SerialStub::print(const char *s) { return write((const uint8_t *)s, strlen(s)); }
int SerialStub::availableForWrite() { return 63; }
bool SerialStub::dtr() { return stub.dtr; }

TwoWire Wire;
/* The core's Wire (SERCOM.cpp): initClockNVIC puts SERCOM2 at SERCOM_NVIC_PRIORITY = 3, resetWIRE
 * clears CTRLA, initMasterWIRE sets BAUD = F_CPU / (2 f) - 5 - 3 (125 ns rise) with BAUDLOW 0. */
static void core_init_wire(uint32_t mode)
{
    stub.prio[SERCOM2_IRQn] = 3;
    SERCOM2->I2CM.CTRLA.reg = 0;
    SERCOM2->I2CM.CTRLA.bit.MODE = mode;
}
static void core_master_baud(uint32_t hz)
{
    if (hz) /* a scenario that never called primary_hw_begin recovers with hz 0 */
        SERCOM2->I2CM.BAUD.reg = (uint32_t)(F_CPU / (2 * hz) - 5 - 3);
}
void TwoWire::begin()
{
    stub.wire_begins++;
    core_init_wire(5);
    core_master_baud(100000);   /* TWI_CLOCK */
    SERCOM2->I2CM.CTRLA.bit.ENABLE = 1;
}
void TwoWire::begin(uint8_t)
{
    stub.wire_begins++;
    core_init_wire(4);
    SERCOM2->I2CM.CTRLA.bit.ENABLE = 1;
}
void TwoWire::end() { stub.wire_ends++; }
void TwoWire::setClock(uint32_t hz)
{
    SERCOM2->I2CM.CTRLA.bit.ENABLE = 0;
    core_init_wire(5);
    core_master_baud(hz);
    SERCOM2->I2CM.CTRLA.bit.ENABLE = 1;
}
void TwoWire::onReceive(void (*)(int)) {}
void TwoWire::onRequest(void (*)(void)) {}
int TwoWire::available() { return (int)stub.wire_rx; }
int TwoWire::read()
{
    if (!stub.wire_rx)
        return -1;
    stub.wire_rx--;
    stub.wire_reads++;
    return 0x55;
}
size_t TwoWire::write(const uint8_t *, size_t n) { return n; }
void TwoWire::beginTransmission(uint8_t) {}
uint8_t TwoWire::endTransmission(bool) { return 4; }
uint8_t TwoWire::requestFrom(uint8_t, size_t, bool) { return 0; }
