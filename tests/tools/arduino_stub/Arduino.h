/* Minimal stand-in for the Arduino API used by src/ (host syntax check of the glue, no registers). */
#pragma once
#include <stddef.h>
#include <stdint.h>
#define HIGH 1
#define LOW 0
#define OUTPUT 1
#define INPUT_PULLUP 2
#define LED_BUILTIN 13
void pinMode(uint32_t pin, uint32_t mode);
void digitalWrite(uint32_t pin, uint32_t value);
int digitalRead(uint32_t pin);
unsigned long millis(void);
struct SerialStub {
    void begin(unsigned long baud);
    int available();
    int read();
    size_t print(const char *s);
    size_t write(const uint8_t *buf, size_t n);
};
extern SerialStub Serial;
