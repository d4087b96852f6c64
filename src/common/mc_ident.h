/* Board identity over USB CDC: the `ID?` request matcher and the one-line reply. */
#ifndef MC_IDENT_H
#define MC_IDENT_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/*
 * Wire format (ASCII, the single definition; metacell_tools/flash/identity.py parses it and
 * tests/tools/test_flash.py checks the parser against this formatter):
 *
 *   request:  "ID?" then CR or LF (any mix of CR/LF; other lines are ignored)
 *   reply:    "MC role=cell addr=0x10 cell=1 fw=1.0\r\n"     addressed cell
 *             "MC role=cell addr=none cell=0 fw=1.0\r\n"     unaddressed image
 *             "MC role=primary fw=1.0\r\n"                   primary
 *
 * addr is the 7-bit I2C address as 0x%02x (lower-case hex), cell the decimal cell
 * number 1..16, fw = major.minor of MC_FW_VERSION (major = v >> 8, minor = v & 0xff,
 * both decimal). The USB CDC port ignores the baud rate; never open it at 1200 baud
 * (that resets the XIAO into its bootloader).
 */
#define MC_IDENT_LINE_MAX 48   /* reply length bound incl. CRLF and NUL */
#define MC_IDENT_ROLE_CELL 1
#define MC_IDENT_ROLE_PRIMARY 2
#define MC_IDENT_CELL_MAX 16

typedef struct {
    uint8_t len;        /* bytes of the current line kept in buf */
    uint8_t overflow;   /* current line longer than buf: cannot be "ID?" */
    char buf[4];
} mc_ident_rx_t;

void mc_ident_rx_init(mc_ident_rx_t *rx);
/* Feed one received byte; returns 1 when it ends a line that was exactly "ID?". */
int mc_ident_rx_feed(mc_ident_rx_t *rx, uint8_t byte);
/* Write the reply line (CRLF, NUL-terminated) into buf[size]. Returns its length
 * without the NUL, or -1 (buf untouched) for a bad role, cell outside 0..16, addr
 * outside 0x08..0x77 for cell >= 1 (must be 0 for cell 0), or size too small. */
int mc_ident_format(char *buf, int size, int role, int cell, int addr, uint16_t fw);

#ifdef __cplusplus
}
#endif

#endif /* MC_IDENT_H */
