/* SLCAN (Lawicel serial-line CAN) line parser and frame encoder, as python-can's slcan interface and slcand speak it. */
#ifndef MC_SLCAN_H
#define MC_SLCAN_H

#include <stdint.h>

/*
 * Lines end in '\r' ('\n' bytes are ignored). Accepted commands:
 *   O / L        open (L: listen only)              -> "\r"
 *   C            close                              -> "\r"
 *   Sn (n 0..8)  bit rate (stored, not used)        -> "\r"
 *   sXXXX        BTR0/BTR1 (stored, not used)       -> "\r"
 *   V / v / N    version / serial number            -> "V0101\r" / "v0101\r" / "NMC01\r"
 *   F            status flags                       -> "F00\r"
 *   Z0 / Z1      timestamps off/on                  -> "\r"
 *   Mxxxxxxxx / mxxxxxxxx  acceptance code/mask (ignored) -> "\r"
 *   tIIIL<2L hex>  TIIIIIIIIL<2L hex>  rIIIL  RIIIIIIIIL   frames (channel open,
 *                not listen-only)                  -> "z\r" / "Z\r"
 *   "" (empty line)                                 -> nothing
 * Anything else (unknown command, bad hex, id out of range, DLC > 8, wrong
 * length, line longer than MC_SLCAN_LINE_MAX, non-printable bytes) -> "\a",
 * the error counter increments and nothing else changes.
 * Outgoing frames: t/T/r/R as above plus, with Z1, four hex digits of the
 * millisecond clock modulo 60000 (Lawicel), then '\r'.
 */
#define MC_SLCAN_LINE_MAX 32     /* longest valid line: T + 8 + 1 + 16 = 26 */
#define MC_SLCAN_REPLY_MAX 8
#define MC_SLCAN_FRAME_MAX 32    /* longest encoded frame incl. timestamp and '\r' */

enum {
    MC_SLCAN_EV_NONE = 0,    /* line not complete yet, or empty line */
    MC_SLCAN_EV_REPLY = 1,   /* command handled; send reply */
    MC_SLCAN_EV_FRAME = 2,   /* frame parsed into *frame; send reply */
    MC_SLCAN_EV_ERROR = 3,   /* malformed; reply is "\a" */
};

#define MC_CAN_EFF 0x80000000u   /* id flag: 29-bit id */
#define MC_CAN_RTR 0x40000000u   /* id flag: remote frame */
#define MC_CAN_ID_MASK 0x1FFFFFFFu

typedef struct {
    uint32_t id;       /* 11 or 29 bit id | MC_CAN_EFF | MC_CAN_RTR */
    uint8_t dlc;       /* 0..8 */
    uint8_t data[8];
} mc_can_frame_t;

typedef struct {
    char line[MC_SLCAN_LINE_MAX];
    uint8_t len;
    uint8_t bad;          /* current line overflowed or held a non-printable byte */
    uint8_t open;         /* channel open (O or L) */
    uint8_t listen_only;
    uint8_t timestamps;   /* Z1 */
    uint8_t bitrate;      /* last Sn */
    uint16_t errors;      /* malformed lines (wraps) */
} mc_slcan_t;

void mc_slcan_init(mc_slcan_t *s);
/* Feed one byte. Returns an MC_SLCAN_EV_*; reply[] gets a 0-terminated answer. */
int mc_slcan_rx(mc_slcan_t *s, uint8_t byte, mc_can_frame_t *frame, char *reply);
/* Parse one complete line (no terminator); same results as mc_slcan_rx. */
int mc_slcan_line(mc_slcan_t *s, const char *line, uint32_t len, mc_can_frame_t *frame,
                  char *reply);
/* Encode a frame; returns the byte count (0 if the frame is invalid). out needs
 * MC_SLCAN_FRAME_MAX bytes; ts_ms is used with timestamps on. */
uint32_t mc_slcan_encode(const mc_slcan_t *s, const mc_can_frame_t *f, uint32_t ts_ms, char *out);

#endif /* MC_SLCAN_H */
