/* Host stand-in for the SAMD core's TwoWire API (declarations; tests/firmware/glue_host.cpp defines them). */
#pragma once
#include "Arduino.h"
struct TwoWire {
    void begin();
    void begin(uint8_t address);
    void end();
    void setClock(uint32_t hz);
    void onReceive(void (*cb)(int));
    void onRequest(void (*cb)(void));
    int available();
    int read();
    size_t write(const uint8_t *data, size_t n);
    void beginTransmission(uint8_t address);
    uint8_t endTransmission(bool stop);
    uint8_t requestFrom(uint8_t address, size_t quantity, bool stop);
};
extern TwoWire Wire;
