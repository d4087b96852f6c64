/* Minimal Cortex-M0 start-up for the QEMU harness: vectors, .data/.bss init, libc bits. */
#include <stddef.h>
#include <stdint.h>
#include "semihost.h"

extern uint32_t _stack_top, _data_load, _data_start, _data_end, _bss_start, _bss_end;
int main(void);
void reset_handler(void);
void fault_handler(void);

/* One word per entry: the initial stack pointer (data) or a handler (code); a union keeps both
 * kinds without converting between object and function pointers (ISO C has no such conversion). */
typedef union {
    void (*handler)(void);
    const uint32_t *sp;
} vector_t;

#define H(f) { .handler = (f) }
__attribute__((section(".vectors"), used)) static const vector_t vectors[16] = {
    { .sp = &_stack_top }, H(reset_handler), H(fault_handler), H(fault_handler),
    H(0), H(0), H(0), H(0), H(0), H(0), H(0),
    H(fault_handler), H(0), H(0), H(fault_handler), H(fault_handler),
};
#undef H

void fault_handler(void)
{
    sh_puts("fwcheck: HardFault/NMI on the target\n");
    sh_exit(0);
}

void reset_handler(void)
{
    uint32_t *src = &_data_load, *dst = &_data_start;
    while (dst < &_data_end)
        *dst++ = *src++;
    for (dst = &_bss_start; dst < &_bss_end; dst++)
        *dst = 0;
    sh_exit(main() == 0);
}

/* The compiler may emit calls to these for struct copies and clears
 * (this file is built with -fno-builtin -fno-tree-loop-distribute-patterns). */
void *memcpy(void *d, const void *s, size_t n)
{
    uint8_t *a = d;
    const uint8_t *b = s;
    while (n--)
        *a++ = *b++;
    return d;
}

void *memmove(void *d, const void *s, size_t n)
{
    uint8_t *a = d;
    const uint8_t *b = s;
    if (a < b) {
        while (n--)
            *a++ = *b++;
    } else {
        while (n--)
            a[n] = b[n];
    }
    return d;
}

void *memset(void *d, int c, size_t n)
{
    uint8_t *a = d;
    while (n--)
        *a++ = (uint8_t)c;
    return d;
}

int memcmp(const void *x, const void *y, size_t n)
{
    const uint8_t *a = x, *b = y;
    for (; n; n--, a++, b++)
        if (*a != *b)
            return *a < *b ? -1 : 1;
    return 0;
}
