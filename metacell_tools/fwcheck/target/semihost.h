/* ARM semihosting calls (BKPT 0xAB) used by the QEMU harness programs. */
#ifndef FW_SEMIHOST_H
#define FW_SEMIHOST_H

#include <stdint.h>

int sh_open(const char *name, int mode);        /* SYS_OPEN; mode 5 = "wb" */
int sh_write(int fd, const void *buf, uint32_t n); /* SYS_WRITE; 0 = all written */
void sh_puts(const char *s);                    /* SYS_WRITE0 to the console */
void sh_exit(int ok) __attribute__((noreturn)); /* SYS_EXIT: 0 status if ok */

#endif
