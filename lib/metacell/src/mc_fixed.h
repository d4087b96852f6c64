/* Fixed-point primitives shared by the cell library: formats, saturation, IRQ save. */
#ifndef MC_FIXED_H
#define MC_FIXED_H

#include <stdint.h>
#include "mc_units.h" /* generated from protocol/definition.py: MC_COUNTS_PER_REV, wire units, limits */

/*
 * Units and formats used throughout the library (all integer, no float):
 *
 *   angle   int32  encoder counts, MC_COUNTS_PER_REV (400) per revolution (1 count = 2*pi/400 rad).
 *                  Decoder positions saturate at INT32_MIN/INT32_MAX, never wrap.
 *                  The tick limits its angles to +-runaway_counts <= MC_ANGLE_CLAMP;
 *                  the public law functions clamp to +-MC_ANGLE_CLAMP.
 *   torque  int32  "TU" = 2^-5 uN*m = 31.25 nN*m (MC_TORQUE_FRAC_BITS = 5).
 *   gain    int32  TU per count (so Q5 uN*m per count); |gain| <= MC_GAIN_MAX.
 *                  1 N*m/rad = 1e6 * (2*pi/400) * 32 TU/count = 502654.8 TU/count.
 *   astar   int32  Q4 counts (1/16 count = 2*pi/6400 rad).
 *   duty    int32  sixteenths of a PWM timer tick inside the drive, then timer
 *                  ticks 0..duty_limit (see drivers/mc_drive.h).
 */
#define MC_TORQUE_FRAC_BITS   5
#define MC_ASTAR_FRAC_BITS    4
#define MC_ANGLE_CLAMP        2048          /* counts: 5.12 rev */
#define MC_GAIN_MAX           131071        /* 2^17 - 1 TU/count = 0.2608 N*m/rad */
#define MC_TORQUE_CLAMP       4194304       /* 2^22 TU = 0.131 N*m */

#ifndef MC_CDEF /* inline helpers are invisible to the host FFI */

/* Force inlining of the control-path helpers (GCC/Clang); plain inline elsewhere. */
#if defined(__GNUC__)
#define MC_INLINE static inline __attribute__((always_inline))
#define MC_NOINLINE static __attribute__((noinline))
#else
#define MC_INLINE static inline
#define MC_NOINLINE static
#endif

/* clamp(x, -lim, +lim) for 0 <= lim <= 2^30; one compare on the common path:
 * (uint32)(x + lim) > 2*lim  <=>  x outside [-lim, lim]. */
MC_INLINE int32_t mc_clamp_sym(int32_t x, int32_t lim)
{
    if ((uint32_t)x + (uint32_t)lim > 2u * (uint32_t)lim)
        x = x < 0 ? -lim : lim;
    return x;
}

static inline int32_t mc_clamp_i32(int32_t x, int32_t lo, int32_t hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

/* Interrupt mask save/restore: the one per-architecture piece of the library.
 * On the Cortex-M0+ it masks PRIMASK; on the host (single-threaded emulator) it
 * is a no-op. Keep the section between them to a few loads and stores. */
#if defined(__arm__) && defined(__thumb__)
static inline uint32_t mc_irq_save(void)
{
    uint32_t primask;
    __asm volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask)::"memory");
    return primask;
}
static inline void mc_irq_restore(uint32_t primask)
{
    __asm volatile("msr primask, %0" ::"r"(primask) : "memory");
}
#else
static inline uint32_t mc_irq_save(void) { return 0; }
static inline void mc_irq_restore(uint32_t primask) { (void)primask; }
#endif

#endif /* MC_CDEF */

#endif /* MC_FIXED_H */
