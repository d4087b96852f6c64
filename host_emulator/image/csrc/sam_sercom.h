/* The SERCOM's state and modes, shared by its model (sam_sercom.c), its I2C mode (sam_sercom_i2c*.c) and the bus. */
#ifndef SAM_SERCOM_H
#define SAM_SERCOM_H

#include "sam_world.h"

/* I2C: the slave's states, the flags and the bus states of STATUS.BUSSTATE */
enum { S_IDLE = 0, S_AMATCH, S_RX, S_RX_HOLD, S_TX_NEED, S_TX, S_TX_DONE, S_WAIT };
#define M_MB 0x01u
#define M_SB 0x02u
#define F_ERROR 0x80u
#define ST_BUSERR 0x01u
#define ST_ARBLOST 0x02u
#define S_PREC 0x01u
#define S_AMATCHF 0x02u
#define S_DRDY 0x04u
#define BUSSTATE_UNKNOWN 0u
#define BUSSTATE_IDLE 1u
#define BUSSTATE_OWNER 2u
#define BUSSTATE_BUSY 3u
#define LOWTOUT_S 25e-3

typedef struct {
    uint64_t sync_until;
    uint32_t sync_bits;
    int enabled, mode;
    uint64_t tbit;              /* SCL period of the transaction (tu): the master's, or the one its steps carry */
    /* master */
    uint8_t m_flags;
    uint16_t m_status;          /* BUSERR, ARBLOST, RXNACK, LOWTOUT, CLKHOLD (BUSSTATE kept apart) */
    uint32_t busstate;
    uint8_t m_data;
    int m_dir, sysop_stuck, stop_pending;
    int slave;                  /* the board that claimed the address, -1 */
    int awaiting, claims;       /* an address on the bus: claims until its NACK check */
    int pending_start;          /* ADDR written while SCL is held: the START waits for the release */
    uint32_t pending_addr;
    uint64_t t_inactive, t_lowtout;   /* time-outs of the stretch in the view, SAM_NEVER */
    /* slave */
    uint8_t s_flags;
    uint16_t s_status;          /* COLL, RXNACK, DIR, SR, CLKHOLD */
    uint8_t s_rx, s_tx;
    int s_state;
    int addressed, master;      /* addressed by this master (board index) since its ADDRESS, until STOP or a START */
    uint64_t stretch_start;
    int gclk_core, gclk_slow;   /* its generic clock channels (GCLK_SERCOMn_CORE, GCLK_SERCOMx_SLOW) */
} sam_sercom_t;

/* A mode of the SERCOM (CTRLA.MODE): the registers of its view, what enabling and disabling it does. */
typedef struct {
    int (*read)(sam_mcu_t *m, int pi, int ri, uint32_t *v);               /* SAM_DONE / SAM_GENERIC / SAM_UNCOVERED */
    int (*write)(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask);
    int (*enable)(sam_mcu_t *m, int pi, uint32_t ctrla);                  /* ENABLE set: 0, -1 after sam_fail */
    void (*disable)(sam_mcu_t *m, int pi);                                /* ENABLE cleared */
    void (*reset)(sam_mcu_t *m, int pi);                                  /* before a reset clears the state */
    void (*init)(sam_sercom_t *s);                                        /* after */
    uint8_t (*flags)(const sam_sercom_t *s);                              /* its interrupt flags */
} sam_sercom_mode_t;

/* ---- sam_sercom.c ---- */
static inline sam_sercom_t *sam_sercom_st(sam_mcu_t *m, int pi) { return m->pst[pi]; }
static inline uint32_t sam_sercom_reg32(sam_mcu_t *m, int pi, uint32_t off) { return sam_rd32(m->regs[pi] + off); }
void sam_sercom_irq(sam_mcu_t *m, int pi);                  /* the interrupt line from the mode's flags */
void sam_sercom_sync(sam_mcu_t *m, int pi, uint32_t bits);  /* a write that synchronises (SYNCBUSY bits) */

/* ---- sam_sercom_i2c.c: the I2C mode's registers (master and slave) ---- */
extern const sam_sercom_mode_t sam_sercom_i2c;
int sam_i2c_address_matches(sam_mcu_t *m, int pi, sam_sercom_t *s, uint8_t addr7);
void sam_i2c_restart(sam_mcu_t *m, int pi);                 /* the state machines restart: it lets go of the bus */

/* ---- sam_sercom_i2cm.c: the master ---- */
void sam_i2cm_addr(sam_mcu_t *m, int pi, uint32_t v);       /* ADDR written: a START */
void sam_i2cm_data(sam_mcu_t *m, int pi, uint8_t b);
void sam_i2cm_cmd(sam_mcu_t *m, int pi, uint32_t cmd, int nack);
void sam_i2cm_end(sam_sercom_t *s);                         /* the transaction is over */
void sam_i2cm_step(sam_mcu_t *m, int pi, sam_sercom_t *s, const sam_busev_t *e);   /* a bus step to the master */
int sam_i2cm_step_quiet(sam_mcu_t *m, int pi, const sam_sercom_t *s, int kind, int held);   /* one that changes nothing seen */
void sam_i2cm_bus_idle(sam_mcu_t *m, int pi, sam_sercom_t *s);   /* the bus state becomes IDLE: a waiting START goes */

/* ---- sam_sercom_i2c_timing.c: the master's SCL timing against the I2C-bus specification ---- */
int sam_i2cm_timing(sam_mcu_t *m, int pi, sam_i2c_timing_t *t);   /* from its registers now; -1: no clock */
int sam_i2cm_timing_check(sam_mcu_t *m, int pi);            /* SAM_I2C_VIOL_* of a START now; the first noted */

/* ---- sam_sercom_i2cs.c: the slave ---- */
void sam_i2cs_cmd(sam_mcu_t *m, int pi, uint32_t cmd, int nack);
void sam_i2cs_data(sam_mcu_t *m, int pi, uint8_t b);
void sam_i2cs_vanish(sam_mcu_t *m, sam_sercom_t *s, uint64_t t);    /* it lets go of the bus now */
int sam_i2cs_step(sam_mcu_t *m, sam_sercom_t *s, const sam_busev_t *e);   /* a bus step to a slave; 0: no effect */

#endif /* SAM_SERCOM_H */
