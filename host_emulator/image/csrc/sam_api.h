/* Interface of the image tier's runtime to Python (cffi): a world of SAMD21 boards running flashed images on a plant. */
#ifndef SAM_API_H
#define SAM_API_H

#include <stdint.h>
#ifndef MC_CDEF /* the FFI pass sees he_plant.h in the same umbrella */
#include "he_plant.h"
#endif

typedef struct sam_world sam_world_t;

enum { SAM_ROLE_CELL = 0, SAM_ROLE_PRIMARY = 1 };
enum { SAM_MAX_MCU = 17 };
enum { SAM_CYCLES_CACHE = 0, SAM_CYCLES_WORST = 1 };

/* Injectable faults (sam_world_fault): each active for [t0, t1) of world time. */
enum {
    SAM_FAULT_EDGE_STORM = 0,  /* arg Hz of glitch pairs (channel A toggles and back 1 us later) on arg2's encoder
                                  (0 alpha, 1 beta) of the cell */
    SAM_FAULT_STUCK_SDA = 1,   /* the bus's SDA line held low (a shorted or latched-up part) */
    SAM_FAULT_SILENT = 2,      /* the board loses power: pins released, no answer on the bus; power-on reset at t1 */
    SAM_FAULT_USB_NO_READ = 3, /* the USB host stops taking IN packets from the board */
    SAM_FAULT_HARDFAULT = 4,   /* a HardFault is raised on the board at t0 (as a bad pointer would) */
    SAM_FAULT_TICK_DEAD = 5,   /* the board's TC3 stops counting (its clock lost): the control tick dies */
    SAM_FAULT_SPIN = 6,        /* not a fault: the cell's encoder arg2 & 1 (0 alpha, 1 beta) turns at arg counts/s
                                  (< 0: backwards), back and forth by arg2 >> 1 counts when that is not 0: quadrature
                                  edges without the plant (for tests and benchmarks, with the plant at rest) */
    SAM_FAULT_RESET = 7,       /* not a fault: a system reset at t0 as NVIC_SystemReset does (cause SYST, RAM kept);
                                  the boards command's 1200-baud touch */
    SAM_FAULT_RESET_BUTTON = 8, /* the reset pin pulled low at t0 (an external reset: PM.RCAUSE.EXT; RAM kept) */
    SAM_FAULT_COUNT = 9
};

typedef struct {
    int32_t ncells;            /* cells on the bus, 1..16 */
    int32_t primary;           /* 1: a primary board polls the bus and speaks USB to the host */
    double window_s;           /* plant window: the plant steps once per window with each motor's mean voltage of the
                                  window before (a lag of one window) */
    int32_t substeps;          /* plant steps per window */
    int32_t stepper;           /* HE_STEP_* */
    double supply_v;           /* motor supply, V */
    double kt;                 /* motor torque constant, N*m/V */
    double counts_per_rad;     /* encoder counts per radian (400 / 2 pi) */
    double i2c_rise_ns;        /* SCL rise time: part of every SCL period */
    double usb_packet_us;      /* USB host: time to move one packet (full speed, with its scheduling) */
    int32_t ff;                /* 1: fast-forward provably idle loop() passes */
    int32_t ff_timed;          /* 1: also passes that read the time, after a probe (sam_ff.c) */
    int32_t cycle_model;       /* SAM_CYCLES_CACHE (flash waits on NVM cache misses) or SAM_CYCLES_WORST (the CPU
                                  budget's bound: a wait on every fetch and refill) */
    double round_s;            /* the longest stretch of time the world lets the boards run apart before it
                                  meets them again (0: the plant window); results do not depend on it */
    int32_t trace;             /* bit 0: log every I2C bus step in the notes; bit 2: every register access of the
                                  boards in trace_boards (bit b: board b); bit 3: their exception entries and returns;
                                  bit 5: every change of their state (a register access that changed something, an
                                  exception entry or return; time in tu): the same whatever the schedule and
                                  fast-forwarding */
    int32_t trace_boards;
    int32_t cyc_exc_entry, cyc_exc_exit, cyc_apb;   /* cycles of an exception entry, return, and of an access
                                  through the AHB-APB bridge (the CPU budget's CycleModel) */
    int32_t threads;           /* threads the boards run on (1..16): cells that cannot affect anyone for a while
                                  run at the same time; results do not depend on it */
    he_plant_t *plant;
    double *x, *v;             /* plant state (2n each), updated at window ends */
    /* board wiring, pins 0..31 = PA00..PA31, 32..63 = PB00..PB31 (docs/image-tier.md) */
    int32_t pin_nsleep;        /* DRV8874 nSLEEP of both drivers */
    int32_t pin_ph[2];         /* PH of the alpha and beta drivers */
    int32_t pin_en[2];         /* EN of the alpha and beta drivers */
    int32_t pin_enc[2][2];     /* encoder [alpha|beta][A|B] */
    int32_t pin_sda, pin_scl;  /* I2C bus */
    int32_t bus_sercom;        /* n of the SERCOMn whose PAD0, PAD1 carry SDA, SCL: the bus (image/board.py) */
    /* what the motors see of a PWM output (0 in both: the mean-duty path, every result before these existed) */
    int32_t pwm_waveform;      /* 0: a window sees the mean duty CC / (PER + 1) over its time; 1: the waveform's
                                  own high time, edge by edge (the counter's phase, prescaler and period) */
    double motor_tau_s;        /* pwm_waveform only: the motors' electrical time constant L / R (s; 0: none): the
                                  plant sees R times the window's mean current plus the back-EMF */
} sam_world_cfg_t;

typedef struct {
    uint32_t addr;             /* load (physical) address */
    uint32_t len;
    const uint8_t *data;
} sam_seg_t;

typedef struct {
    uint64_t t_tu;             /* board time (tu) */
    uint64_t cycles;           /* CPU cycles executed */
    uint64_t activity;
    uint32_t pc, sp, ipsr, primask;
    uint32_t resets, hardfaults;
    uint8_t reset_cause;       /* PM.RCAUSE bits of the last reset */
    int32_t lockup, halted;
    uint64_t ff_passes_skipped, ff_cycles_skipped, ff_parks, ff_checks, ff_misses;
    uint64_t ff_probes, ff_probe_fails;   /* probes of passes that read the time, and those that failed */
    uint64_t ff_traps;     /* stores to SRAM pages the fast-forward protected, stopped and let through */
    uint64_t mmio_reads, mmio_writes;
    uint64_t runs;             /* emulation starts: each costs the emulator a fixed overhead */
    uint64_t tlb_fills;        /* Unicorn TLB refills (a page not in its TLB nor victim TLB) */
    uint32_t nvic_enabled, nvic_pending, nvic_active;
    uint8_t nvic_prio[32];
    uint32_t nvm_erases, nvm_writes;   /* flash rows erased, pages written by NVMCTRL */
    uint32_t vtor;             /* SCB.VTOR: the vector table in use */
} sam_mcu_info_t;

typedef struct {
    uint64_t transactions, nacks, timeouts_seen, stretch_tu, busy_tu;
    uint64_t arblost, buserr, stops, gpio_stops;
    int32_t sda, scl;          /* line levels now */
} sam_bus_info_t;

typedef struct {
    int32_t attached, enumerated, configured, dtr;
    uint64_t in_bytes, out_bytes, in_packets, out_packets, control_transfers, sof;
    int32_t error;             /* 1 when a transfer failed (the message is in the notes) */
} sam_usb_info_t;

/* world */
int sam_world_new(sam_world_t **out, const sam_world_cfg_t *cfg);
void sam_world_free(sam_world_t *w);
const char *sam_world_error(const sam_world_t *w);
/* What the world needs of a board's image (elfimage.py reads it from the ELF). */
typedef struct {
    const sam_seg_t *segs;     /* load segments (flash) */
    int32_t nsegs;
    uint32_t entry_sp, entry_pc;   /* from the vector table at the application's start */
    /* the ELF's cycle tables (cycles.py), all four or none: prefix sums over the halfwords of flash, and per
     * halfword what a conditional branch there costs less when not taken; they hold [0x2000, code_end), and the
     * board's decoder (sam_cost.c) costs every other block, and all of them once that code is rewritten */
    const uint32_t *cost_core, *cost_wait, *cost_lit;
    const uint8_t *refund;
    uint32_t code_end;         /* first address past the code the tables hold (unused without them) */
    uint32_t loop_pc;          /* loop(): where idle passes are fast-forwarded (0: never) */
    uint32_t heap_base;        /* end of static data in SRAM (the heap starts there); 0: unknown */
    uint32_t brk_var;          /* address of the heap's break pointer; 0: none (the heap is unknown if it exists) */
    int32_t boot;              /* 0: direct boot (the bootloader's hand-off simulated: VTOR 0x2000, entry_sp/pc);
                                  1: from the reset vector at 0, as the chip does (a segment at 0 holds the
                                  bootloader; the decoder costs it) */
} sam_image_t;

/* Load a board (its role and cell index); it powers on now. */
int sam_world_load(sam_world_t *w, int mcu, const sam_image_t *img, const char *name, int32_t role, int32_t cell);
/* Run every board and the plant to world time t_end (tu); SAM_OK (0) or -1 (sam_world_error says why). */
int sam_world_run(sam_world_t *w, uint64_t t_end);
uint64_t sam_world_time(const sam_world_t *w);
uint64_t sam_tu_hz(void);
/* Start the plant clock: the plant's time is world time minus t_start (tu); before, the plant rests. */
void sam_world_start_plant(sam_world_t *w, uint64_t t_start);
int sam_world_fault(sam_world_t *w, int32_t kind, int32_t mcu, uint64_t t0, uint64_t t1, double arg, int32_t arg2);
/* A fault as it went (sam_world_fault_info, by the order injected: k < sam_world_nfaults; a full table reuses an ended
 * fault's place): fired, and t_fired when it took effect, later than t0 when its board was without power at t0 (it
 * takes effect at power-up). */
typedef struct {
    int32_t kind, mcu, fired, ended;
    uint64_t t0, t1, t_fired;
} sam_fault_info_t;
int sam_world_nfaults(const sam_world_t *w);
int sam_world_fault_info(const sam_world_t *w, int k, sam_fault_info_t *out);
/* Read a board's state; RAM (addr in 0x20000000..+32K); register access counters (2 * sam_nregs: reads, writes). */
int sam_world_mcu_info(const sam_world_t *w, int mcu, sam_mcu_info_t *out);
int sam_world_read_mem(const sam_world_t *w, int mcu, uint32_t addr, uint8_t *buf, uint32_t len);
/* Program a board's NVM user row (len bytes from its start: BOOTPROT, the region lock bits), as a programmer does
 * before power-up: NVMCTRL reloads LOCK and BOOTPROT from it now (the chip reads them at reset). */
int sam_world_set_user_row(sam_world_t *w, int mcu, const uint8_t *row, uint32_t len);
const uint32_t *sam_world_touch(const sam_world_t *w, int mcu);
uint32_t sam_world_nregs(void);
const char *sam_world_reg_name(uint32_t ri);
/* The stored value of register ri of a board (its storage: what the generic layer keeps; models may add state). */
int sam_world_reg_value(const sam_world_t *w, int mcu, uint32_t ri, uint32_t *value);
/* Start profiling a board (first call) and return its profile: CPU cycles charged per block, indexed by the
 * block's start address / 2 (SAM_FLASH_SIZE / 2 entries, cumulative; exception entry and return not included);
 * NULL if out of memory. */
const uint64_t *sam_world_profile(sam_world_t *w, int mcu);
int sam_world_bus_info(const sam_world_t *w, sam_bus_info_t *out);
/* The SCL timing a board's bus SERCOM (I2C master) sets now, from BAUD, BAUDLOW, CTRLA.SDAHOLD, its GCLK and the
 * bus's rise time (cfg.i2c_rise_ns), against the I2C-bus specification's limits for its mode
 * (sam_sercom_i2c_timing.c); -1 when there is no such board or bus, or its SERCOM has no clock. */
enum { SAM_I2C_STANDARD = 0, SAM_I2C_FAST = 1, SAM_I2C_FAST_PLUS = 2 };
enum { SAM_I2C_VIOL_LOW = 1, SAM_I2C_VIOL_HIGH = 2, SAM_I2C_VIOL_SETUP = 4, SAM_I2C_VIOL_SDA_IN_HIGH = 8 };
typedef struct {
    int32_t mode;              /* SAM_I2C_*: CTRLA.SPEED 1 Fast-mode Plus; SPEED 0 Standard up to 100 kHz, Fast above */
    uint32_t baud, baudlow, sdahold;   /* the register fields */
    double f_gclk_hz, f_scl_hz;
    double t_low_s, t_high_s, t_rise_s;
    double t_hold_min_s, t_hold_max_s;  /* SDA hold after SCL falls: CTRLA.SDAHOLD's range */
    double t_setup_s;          /* data setup before SCL rises: t_low - t_hold_max - t_rise */
    double min_low_s, min_high_s, min_setup_s;   /* the mode's limits */
    int32_t violations;        /* SAM_I2C_VIOL_* bits: T_LOW, T_HIGH, t_SU;DAT below the limit; SDA changing while
                                  SCL is released (t_hold_max >= t_low: false START/STOP conditions) */
} sam_i2c_timing_t;
int sam_world_i2c_timing(sam_world_t *w, int mcu, sam_i2c_timing_t *out);
/* Motor drive of a cell as the plant last saw it: mean voltage and awake fraction of the last window. */
int sam_world_motor(const sam_world_t *w, int cell, int chain, double *volt, double *awake);
/* A TCC of a board as it counts at the board's time (sam_world_tcc_info; tcc 0..2): the PWM frequency is
 * 1 / period_tu. */
typedef struct {
    int32_t running;
    uint32_t prescaler;        /* CTRLA.PRESCALER as a divisor: 1 .. 1024 */
    uint32_t per, top;         /* PER, and the current cycle's last count (MAX after PER was written below COUNT) */
    uint32_t cc[4];
    uint64_t tick_tu;          /* one count */
    uint64_t period_tu;        /* one PWM period, (PER + 1) counts; 0 while stopped */
    uint64_t cycle_start_tu;   /* when the current cycle began (COUNT was 0) */
} sam_tcc_info_t;
int sam_world_tcc_info(const sam_world_t *w, int mcu, int tcc, sam_tcc_info_t *out);
/* High time (tu) of TCCn/WO[wo] of a board over [t0, t1), edge by edge (the waveform path's figure); [t0, t1) within
 * the board's past since the counter's parameters last changed by a register write. */
uint64_t sam_world_tcc_high(const sam_world_t *w, int mcu, int tcc, int wo, uint64_t t0, uint64_t t1);
/* The mean path's figure over the same [t0, t1): the numerator of the mean high time, in tu x counts over *den (the
 * first stretch's period, PER + 1 counts), and *other (tu) for stretches with another period. */
uint64_t sam_world_tcc_mean(const sam_world_t *w, int mcu, int tcc, int wo, uint64_t t0, uint64_t t1, uint64_t *den,
                            double *other);
/* Log lines (resets, faults, USB errors) since the last call, '\n'-separated; returns bytes written. */
uint32_t sam_world_notes(sam_world_t *w, char *buf, uint32_t cap);
/* Change what is traced into the notes (sam_world_cfg_t.trace, .trace_boards) from now on. */
void sam_world_set_trace(sam_world_t *w, int32_t trace, int32_t boards);

/* USB host on a board's port. attach: plug in (bus reset, enumeration, SET_CONFIGURATION); open: line coding
 * 115200 8N1 and DTR (the laptop opening the port), close: DTR dropped. Bytes written are sent as bulk OUT
 * packets; bytes the board sends arrive in a buffer read by sam_usb_read. */
int sam_usb_attach(sam_world_t *w, int mcu);
int sam_usb_set_dtr(sam_world_t *w, int mcu, int32_t dtr);
int sam_usb_write(sam_world_t *w, int mcu, const uint8_t *data, uint32_t n);
uint32_t sam_usb_read(sam_world_t *w, int mcu, uint8_t *buf, uint32_t cap);
int sam_usb_info(const sam_world_t *w, int mcu, sam_usb_info_t *out);
/* A control transfer from the host (for tests): setup packet, data for OUT stages; completes asynchronously. */
int sam_usb_control(sam_world_t *w, int mcu, const uint8_t setup[8], const uint8_t *data, uint32_t n);

/* ---- register-level harness (sam_harness.c): a board loaded with a stub program instead of an image ---- */
typedef struct {
    int32_t level;             /* the pad's level */
    int32_t out;               /* what the MCU puts on it: 0, 1 (GPIO output or pull direction), -1 nothing */
    int32_t driven;            /* 1: a GPIO output drives it */
    int32_t function;          /* PMUX letter 0..7 when PINCFG.PMUXEN, else -1 */
} sam_pin_info_t;

typedef struct {
    uint32_t enabled, pending, active, level;   /* external IRQs: ISER, ISPR, active, request lines */
    uint32_t sys_pending, sys_active;           /* bit e: system exception e */
    uint32_t cyc_tu;                            /* tu per CPU cycle now */
} sam_nvic_info_t;

/* The board's time (tu): past the world's by the accesses made since the world last ran. */
uint64_t sam_harness_now(const sam_world_t *w, int mcu);
/* The board's error message, NULL while it has none. */
const char *sam_harness_error(const sam_world_t *w, int mcu);
/* Run the board's CPU through a routine of its stub from pc to done_pc with R0 = r0 and R1 = *r1 (out: R1 at
 * done_pc), from the world's time on; the context is restored. *t_start: when the routine began (its access). */
int sam_harness_call(sam_world_t *w, int mcu, uint32_t pc, uint32_t done_pc, uint32_t r0, uint32_t *r1,
                     uint64_t *t_start);
/* Rewrite flash bytes as NVMCTRL would leave them (translated code and its memoised costs forgotten). */
int sam_harness_flash(sam_world_t *w, int mcu, uint32_t addr, const uint8_t *data, uint32_t n);
/* Drive a pin from outside the board (0, 1; -1 released) from the board's time on. */
int sam_harness_pin(sam_world_t *w, int mcu, int32_t pin, int32_t level);
int sam_harness_pin_state(const sam_world_t *w, int mcu, int32_t pin, sam_pin_info_t *out);
int sam_harness_nvic(const sam_world_t *w, int mcu, sam_nvic_info_t *out);

/* ---- the USB host's enumeration profile, what the device said, and the laptop's line state (link_usb_host.c) ---- */
enum {
    SAM_USB_PROFILE_SCRIPT = 0, /* the tier's script (default): device, address, device, configuration, SET_CONFIGURATION */
    SAM_USB_PROFILE_LINUX = 1   /* as Linux enumerates and cdc_acm probes: also BOS (bcdUSB >= 2.01), strings 0,
                                   iProduct, iManufacturer, iSerialNumber; then line coding 9600 8N1 */
};
typedef struct {
    int32_t profile;
    int32_t described;         /* 1 once the device descriptor was read in this enumeration */
    uint16_t vid, pid, bcd_usb, bcd_device;
    char manufacturer[64], product[64], serial[64];   /* the strings as read (ASCII, others '?'); "" if not read */
    int32_t comm_if, data_in, data_out;   /* CDC comm interface (wIndex of class requests), data endpoints */
    uint32_t enumerations;     /* times the device was configured */
    uint32_t detaches;         /* times it left the bus (a reset, DETACH) after it had been seen */
    uint32_t baud;             /* the line coding last sent to the device (0: none in this enumeration) */
    int32_t dtr, rts;          /* the control line state last sent */
} sam_usb_device_t;
/* Choose the port's profile before sam_usb_attach (-1 after it or for an unknown profile). */
int sam_usb_set_profile(sam_world_t *w, int mcu, int32_t profile);
/* The laptop's line state as cdc_acm sends it: SET_LINE_CODING (baud, 8N1) when the speed changes (baud 0: keep),
 * SET_CONTROL_LINE_STATE when DTR or RTS change; while the device is not configured it is kept for the next
 * enumeration (a re-enumeration starts again from 9600 baud, DTR and RTS low: a new tty). */
int sam_usb_set_line(sam_world_t *w, int mcu, uint32_t baud, int32_t dtr, int32_t rts);
int sam_usb_device(const sam_world_t *w, int mcu, sam_usb_device_t *out);
/* The host's reading of a configuration descriptor (for tests): CDC comm interface, data IN and OUT endpoints;
 * -1 when it has no bulk pair. */
int sam_usb_parse_config(const uint8_t *d, uint32_t n, int32_t *comm_if, int32_t *in, int32_t *out);

/* ---- cycle costs of any flash content (sam_cost.c): the cycle model's decode table, the tests' view ---- */
enum { SAM_COST_TIMED = 0, SAM_COST_NO_TIME = 1, SAM_COST_UNDEFINED = 2 };
typedef struct {
    uint8_t size, core, wait, lit, refund;   /* as the ELF tables hold them (cycles.insn_cost) */
    int32_t status;            /* SAM_COST_TIMED; SAM_COST_NO_TIME: the model has no time for it (WFI, SVC, ...);
                                  SAM_COST_UNDEFINED: not an ARMv6-M instruction */
    const char *text;          /* the decode table's representative instruction */
} sam_insn_cost_t;
/* The cost of the instruction whose first halfword is hw1 (hw2: the next one): 0, 1 (no time), -1 (undefined). */
int sam_cost_insn(uint16_t hw1, uint16_t hw2, sam_insn_cost_t *out);

#endif /* SAM_API_H */
