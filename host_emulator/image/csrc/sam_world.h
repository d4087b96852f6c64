/* The world of the image tier: boards, the plant they drive, encoders, the I2C bus and the USB host (internal). */
#ifndef SAM_WORLD_H
#define SAM_WORLD_H

#include <pthread.h>
#include "sam.h"

/* pin level changes the board (encoders, faults) applies to one board's pins, in time order */
typedef struct {
    uint64_t t;
    int8_t pin;
    int8_t level;   /* 0, 1; -1 released */
} sam_pinev_t;

#define SAM_PINQ 8192
typedef struct {
    sam_pinev_t ev[SAM_PINQ];
    unsigned head, n;
    int slot;             /* its event source on the board */
} sam_pinq_t;

#define SAM_MOTOR_PIECES 64
#define SAM_MOTOR_OFF 2
/* one DRV8874 + motor: the mean of V(t) and of "awake" over the current window, from the board's pins. The
 * integrals are exact integers (EN's high time in tu/top, tu awake), so where they are split cannot change a bit. */
typedef struct {
    int64_t hi;           /* signed integral of EN's level while awake (PH's sign), in tu / den */
    uint64_t den;         /* its denominator: the PWM period in counts (1 for a GPIO level) */
    double hi_other;      /* the part with another denominator (a PWM period changed inside the window), tu */
    uint64_t awake_tu;    /* time awake */
    uint64_t t_last;      /* integrated up to here (tu) */
    double volt, awake;   /* means of the last window (what the plant used) */
    /* the electrical model (cfg.motor_tau_s > 0): the window's drive as pieces of constant terminal voltage (+1, -1
     * supply, 0 braked, SAM_MOTOR_OFF asleep), adjacent equal pieces merged, so where the integration was split
     * cannot change a bit; at the window's end the current follows them */
    struct {
        int8_t v;
        uint64_t dt;      /* tu */
    } piece[SAM_MOTOR_PIECES];
    int npiece;
    double j;             /* R times the current (V) at the last window's end */
    double jint;          /* its integral over the window's awake time (V tu) */
} sam_motor_t;

/* ---- the I2C bus between the boards (link_i2c_bus.c) ----
 * Boards affect each other only through bus steps: timestamped messages into the receiver's queue, each at least
 * one SCL period T after its cause (link_i2c_bus.c lists them). No board reads another board's state. */
#define SAM_BUS_TMIN_S 2400e-9   /* 400 kHz with 4 % tolerance: Fast mode, the fastest SCL with CTRLA.SPEED = 0 */
enum { BUS_EV_NONE = 0,
       /* to slaves */
       BUS_EV_S_ADDRESS, BUS_EV_S_DRDY_RX, BUS_EV_S_DRDY_TX, BUS_EV_S_PREC, BUS_EV_S_RESET,
       /* to the master: from a slave */
       BUS_EV_M_CLAIM, BUS_EV_M_HOLD, BUS_EV_M_RELEASE, BUS_EV_M_MB, BUS_EV_M_SB,
       /* to the master: its own steps */
       BUS_EV_M_NACKCHECK, BUS_EV_M_IDLE, BUS_EV_M_ARBLOST, BUS_EV_M_TIMEOUT,
       /* to the master: a misplaced START/STOP it detects (a timing violation), SDA changed by a fault (arg: 1 low) */
       BUS_EV_M_BUSERR, BUS_EV_M_SDA,
       BUS_EV_COUNT };
typedef struct {
    uint64_t t;
    uint32_t tbit;                  /* the SCL period of the transaction it belongs to (tu) */
    uint8_t kind, arg, arg2, src;   /* src: the sending board */
} sam_busev_t;
#define SAM_BUSQ 64
typedef struct {
    sam_busev_t ev[SAM_BUSQ];
    int n;
} sam_busq_t;

/* what a master knows of the lines (not reset with its SERCOM: the lines are not its state) */
typedef struct {
    int held;             /* a slave holds SCL low: the master's view, from the slave's HOLD/CLAIM ... RELEASE */
    uint64_t hold_start;  /* when that slave began to hold (tu) */
    int gpio_sda, gpio_scl;   /* line levels while the master drives them as GPIO (1 released) */
} sam_lineview_t;

typedef struct {
    int pi;               /* the SERCOM on the bus (the board's wiring: cfg.bus_sercom), -1 none */
    uint8_t sda_funcs, scl_funcs;   /* the PMUX functions that put SDA on its PAD0, SCL on its PAD1 (bit f) */
    int slot[SAM_MAX_MCU];   /* its event source on each board */
    int sda_stuck;        /* fault (world level, changed only at a round boundary) */
    int timing_noted;     /* the master's SCL timing violation has been noted (once per bus) */
    sam_lineview_t view[SAM_MAX_MCU];
    sam_busq_t q[SAM_MAX_MCU];
    sam_bus_info_t info[SAM_MAX_MCU];   /* each board counts its own part; the sum is the bus's */
} sam_bus_t;

/* ---- the USB host on each board's port (link_usb_host.c) ---- */
#define SAM_USB_BUF 65536
#define SAM_USB_HQ 32
typedef struct {
    uint64_t t;
    int kind, arg;
} sam_hev_t;
typedef struct {
    sam_hev_t hq[SAM_USB_HQ];   /* the host's pending actions on this port, in time order */
    int hq_n;
    int slot;                   /* its event source on the board */
    int cdc_in, cdc_out;        /* the CDC data endpoints found in the configuration descriptor */
    int attached, enumerated, configured, dtr, no_read, error;
    int step;             /* position in the host's script (enumeration, control requests) */
    int busy;             /* a control transfer in progress: its stage */
    uint8_t setup[8];
    uint8_t ctl_data[256];
    uint32_t ctl_len, ctl_done;
    int ctl_queue_n;
    uint8_t ctl_queue[8][8 + 64];
    uint32_t ctl_queue_len[8];
    uint8_t addr;
    uint8_t out[SAM_USB_BUF];   /* bytes to send (bulk OUT) */
    uint32_t out_head, out_n;
    uint8_t in[SAM_USB_BUF];    /* bytes received (bulk IN) */
    uint32_t in_head, in_n;
    uint64_t in_dropped;
    uint64_t next_sof;
    sam_usb_info_t info;
    /* the enumeration profile and the laptop's line state (SAM_USB_PROFILE_*, sam_usb_set_line) */
    int profile, ep0_size, str_k;
    uint8_t istr[3];            /* iProduct, iManufacturer, iSerialNumber */
    uint16_t langid;
    uint32_t want_baud, sent_baud;
    int want_ctl, sent_ctl;     /* bit 0 DTR, bit 1 RTS */
    sam_usb_device_t dev;
} sam_usbhost_t;

/* ---- faults ---- */
#define SAM_MAX_FAULTS 256
#define SAM_FAULT_UNFIRED 0xFFFFFFFFFFFFFFFFull   /* sam_fault_t.t_fired of a fault that has not taken effect */
typedef struct {
    int kind, mcu, arg2, started, ended;
    uint64_t t0, t1;
    uint64_t t_fired;     /* when it took effect (SAM_FAULT_UNFIRED: not yet) */
    double arg;
    uint64_t next;        /* edge storm: next glitch; spin: next edge */
    int32_t leg, dir;     /* spin back and forth: counts into the current leg, its direction */
} sam_fault_t;

/* worker threads (sam_world_run.c) */
#define SAM_MAX_THREADS 16
typedef struct {
    int init, nworkers;
    pthread_t th[SAM_MAX_THREADS];
    pthread_mutex_t mu;
    pthread_cond_t cv;
    unsigned gen;         /* a new set of jobs */
    int quit, sleeping, busy, next, njobs;
    sam_mcu_t *job[SAM_MAX_MCU];
    uint64_t job_to[SAM_MAX_MCU];
} sam_pool_t;

struct sam_world {
    sam_world_cfg_t cfg;
    int nmcu;
    sam_mcu_t *mcu[SAM_MAX_MCU];
    int cell_mcu[16];     /* board index of cell j, -1 */
    int primary_mcu;
    uint64_t t;           /* every board is at or past this time */
    uint64_t window_tu, round_tu, next_window;
    uint64_t plant_start; /* SAM_NEVER: the plant rests */
    double plant_t;       /* the plant's own time (s) */
    double *xprev;        /* plant angles at the window start */
    sam_motor_t motor[16][2];
    int32_t count[16][2]; /* encoder counts */
    uint8_t enc_level[16][2][2];
    sam_pinq_t pinq[SAM_MAX_MCU];
    sam_bus_t bus;
    sam_usbhost_t usb[SAM_MAX_MCU];
    sam_fault_t fault[SAM_MAX_FAULTS];
    int nfault;
    int fault_slot[SAM_MAX_MCU];   /* the faults' event source on each board */
    sam_pool_t pool;
    char err[512];
    char notes[1 << 20];
    uint32_t notes_len;
};

/* ---- the world's files (sam_world.c, sam_world_plant.c, sam_world_faults.c, sam_world_run.c) ---- */
int he_gray(int32_t count);   /* he_hil.c: (A << 1) | B of an encoder count, the hil tier's own encoder */
int sam_world_fail(sam_world_t *w, const char *fmt, ...);   /* the world's error (sam_world_error); -1 */
void sam_world_collect_notes(sam_world_t *w);             /* the boards' notes, in board order */
int sam_world_pinq_push(sam_world_t *w, int mcu, uint64_t t, int pin, int level);
void sam_world_plant_init(void);                          /* the pins' TCC outputs, from the pin table */
void sam_world_pins_init(sam_mcu_t *m);                   /* the pins' event source on a board */
int sam_world_window(sam_world_t *w, uint64_t t0);        /* a plant window starts: motors' means, plant, edges */
void sam_world_faults_init(sam_mcu_t *m);                 /* the faults' event source on a board */
void sam_world_faults_apply(sam_world_t *w);              /* world-level faults that start or end now */
uint64_t sam_world_next_fault(const sam_world_t *w);      /* when the next one does */
int sam_world_pool_start(sam_world_t *w, int nthreads);
void sam_world_pool_stop(sam_world_t *w);

/* ---- link_i2c_bus.c: the bus ---- */
int sam_bus_init(sam_world_t *w);                         /* the wiring's SERCOM; -1: its pads are not SDA, SCL */
void sam_bus_port_init(sam_mcu_t *m);                     /* the bus's event source on a board */
uint64_t sam_bus_tmin(void);                              /* shortest SCL period modelled: every step takes >= it */
uint64_t sam_bus_eot_slave(sam_mcu_t *m);                 /* earliest effect of this slave on a master, SAM_NEVER */
uint64_t sam_bus_eot_master(sam_mcu_t *m);                /* earliest effect of this master on a slave, SAM_NEVER */
uint64_t sam_bus_next_loud(sam_mcu_t *m);                 /* its first queued step that is not quiet, SAM_NEVER */
void sam_bus_power_lost(sam_mcu_t *m);                    /* it lets go of the bus */
void sam_bus_lines_changed(sam_mcu_t *m);                 /* the primary's SDA/SCL pins or the SDA fault changed */
void sam_bus_sda_fault(sam_mcu_t *m, int stuck);          /* the SDA fault began or ended: the primary's monitor */
/* for the SERCOM's I2C mode */
int sam_bus_sercom(sam_mcu_t *m);                         /* peripheral index of the SERCOM on the bus, -1 */
int sam_bus_pins_connected(sam_mcu_t *m);                 /* SDA, SCL muxed to that SERCOM's PAD0, PAD1 */
void sam_bus_push(sam_mcu_t *from, int to, uint64_t t, int kind, int arg, int arg2, uint64_t T);   /* a step */
void sam_bus_drop_own(sam_mcu_t *m);                      /* its own pending steps are gone */
sam_bus_info_t *sam_bus_counts(sam_mcu_t *m);             /* the board's part of the bus's counters */
sam_lineview_t *sam_bus_view(sam_mcu_t *m);               /* what a master knows of the lines */

/* ---- link_usb_host.c: the USB host ---- */
void sam_usb_world_init(sam_world_t *w);
void sam_usb_port_init(sam_mcu_t *m);                     /* the host's event source on a board */

#endif /* SAM_WORLD_H */
