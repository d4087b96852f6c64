/* Host stand-in for the Arduino API used by src/ and the SERCOM2 I2C-master registers of the bus glue (syntax checks only). */
#pragma once
#include <stddef.h>
#include <stdint.h>
#define HIGH 1
#define LOW 0
#define OUTPUT 1
#define INPUT_PULLUP 2
#define LED_BUILTIN 13
#define PIN_WIRE_SDA 4
#define PIN_WIRE_SCL 5
void pinMode(uint32_t pin, uint32_t mode);
void digitalWrite(uint32_t pin, uint32_t value);
int digitalRead(uint32_t pin);
void delayMicroseconds(unsigned int us);
unsigned long millis(void);
unsigned long micros(void);
struct SerialStub {
    void begin(unsigned long baud);
    int available();
    int read();
    size_t print(const char *s);
    size_t write(const uint8_t *buf, size_t n);
    int availableForWrite();
};
extern SerialStub Serial;
/* field names as in the SAMD21 CMSIS header (component/sercom.h) */
struct SercomI2cmCtrlaStub { struct { uint32_t ENABLE : 1, LOWTOUTEN : 1, INACTOUT : 2; } bit; };
struct SercomI2cmSyncStub { struct { uint32_t SWRST : 1, ENABLE : 1, SYSOP : 1; } bit; };
struct SercomI2cmStatusStub { struct { uint16_t BUSERR : 1, ARBLOST : 1, RXNACK : 1, BUSSTATE : 2, LOWTOUT : 1; } bit; };
struct SercomI2cmStub {
    volatile SercomI2cmCtrlaStub CTRLA;
    volatile SercomI2cmSyncStub SYNCBUSY;
    volatile SercomI2cmStatusStub STATUS;
};
struct Sercom { SercomI2cmStub I2CM; };
extern Sercom *const SERCOM2;
