/* ARM semihosting for the QEMU harness: open/write files on the host, exit with a status. */
#include "semihost.h"

#define SYS_OPEN 0x01
#define SYS_WRITE0 0x04
#define SYS_WRITE 0x05
#define SYS_EXIT 0x18
#define ADP_Stopped_ApplicationExit 0x20026
#define ADP_Stopped_RunTimeErrorUnknown 0x20023

static int sh_call(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

static uint32_t sh_strlen(const char *s)
{
    uint32_t n = 0;
    while (s[n])
        n++;
    return n;
}

int sh_open(const char *name, int mode)
{
    uint32_t a[3] = {(uint32_t)name, (uint32_t)mode, sh_strlen(name)};
    return sh_call(SYS_OPEN, a);
}

int sh_write(int fd, const void *buf, uint32_t n)
{
    uint32_t a[3] = {(uint32_t)fd, (uint32_t)buf, n};
    return sh_call(SYS_WRITE, a);
}

void sh_puts(const char *s) { sh_call(SYS_WRITE0, s); }

void sh_exit(int ok)
{
    /* AArch32: the parameter is the reason code itself */
    sh_call(SYS_EXIT, (const void *)(ok ? ADP_Stopped_ApplicationExit
                                         : ADP_Stopped_RunTimeErrorUnknown));
    for (;;) {
    }
}
