/* CRC-8 (poly 0x07, init 0, SMBus PEC) and little-endian byte packing for the wire formats. */
#ifndef MC_CRC8_H
#define MC_CRC8_H

#include <stdint.h>

/*
 * crc = MC_CRC8_INIT; for each byte b: crc = T[crc ^ b]
 * with T[i] = i shifted through x^8 + x^2 + x + 1 eight times (MSB first).
 * Table-driven: one load per byte (a snapshot costs ~100 cycles on the M0+).
 */
uint8_t mc_crc8_update(uint8_t crc, const uint8_t *data, uint32_t len);
uint8_t mc_crc8(const uint8_t *data, uint32_t len);

#ifndef MC_CDEF
static inline void mc_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static inline void mc_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}
static inline uint16_t mc_get_u16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}
static inline uint32_t mc_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
/* Two's complement reinterpretation without implementation-defined conversion. */
static inline int32_t mc_get_i32(const uint8_t *p)
{
    uint32_t u = mc_get_u32(p);
    return u & 0x80000000u ? -(int32_t)(~u) - 1 : (int32_t)u;
}
static inline int32_t mc_get_i16(const uint8_t *p)
{
    int32_t u = mc_get_u16(p);
    return u >= 0x8000 ? u - 0x10000 : u;
}
#endif /* MC_CDEF */

#endif /* MC_CRC8_H */
