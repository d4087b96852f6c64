/* Types of the SAMD21 register table that host_emulator/image/regtable.py generates from the vendor's headers. */
#ifndef SAM_REGTAB_H
#define SAM_REGTAB_H

#include <stdint.h>

/* Access of a register (from the header's R/W comment) and the kind its name implies (regtable.Register.kind). */
enum { SAM_ACC_R = 1, SAM_ACC_W = 2, SAM_ACC_RW = 3 };
enum { SAM_KIND_PLAIN = 0, SAM_KIND_W1C = 1, SAM_KIND_SET = 2, SAM_KIND_CLR = 3, SAM_KIND_TGL = 4 };

typedef struct {
    const char *name;    /* "TC3.COUNT16.CC[0]" */
    uint16_t offset;     /* from the instance base */
    uint32_t reset;      /* <REG>_RESETVALUE */
    uint8_t periph;      /* index into sam_periphs */
    uint8_t view;        /* 0: every view; k: the k-th mode view of the instance (sam_periph_t.views) */
    uint8_t size;        /* bytes */
    uint8_t access;      /* SAM_ACC_* */
    uint8_t kind;        /* SAM_KIND_* */
    uint16_t alias;      /* register a SET/CLR/TGL alias acts on (itself when it holds the value) */
    uint16_t field0;     /* first of its fields in sam_fields */
    uint8_t nfields;
} sam_reg_t;

typedef struct {
    const char *name;    /* "SWRST" */
    uint16_t reg;        /* index into sam_regs */
    uint8_t pos, width;
} sam_field_t;

typedef struct {
    const char *name;    /* "TC3", "PORT_IOBUS", "SCB" */
    const char *type;    /* the vendor's struct: "Tc", "Port", "SCB_Type" */
    const char *views;   /* "COUNT8|COUNT16|COUNT32" or "" */
    uint32_t base;
    uint32_t size;       /* bytes of the register window */
    int8_t irq;          /* NVIC line, -1 for none */
    uint8_t nviews;
    uint16_t reg0, reg1; /* its registers: sam_regs[reg0 .. reg1) */
    int8_t pac;          /* ID_<name>: bit pac % 32 of PAC<pac / 32>'s write-protection mask, -1 for none */
} sam_periph_t;

/* A pin's peripheral function (PORT PMUX letter A..H = 0..7) from the header's PIN_P<x><n><F>_<PERIPH>_<SIGNAL>. */
typedef struct {
    uint8_t pin;         /* 0..31 PA, 32..63 PB */
    uint8_t func;        /* 0 = A .. 7 = H */
    const char *periph;  /* "TCC0" */
    const char *signal;  /* "WO2" */
} sam_pinmux_t;

extern const sam_reg_t sam_regs[];
extern const unsigned sam_nregs;
extern const sam_field_t sam_fields[];
extern const unsigned sam_nfields;
extern const sam_periph_t sam_periphs[];
extern const unsigned sam_nperiphs;
extern const sam_pinmux_t sam_pinmux[];
extern const unsigned sam_npinmux;

#endif /* SAM_REGTAB_H */
