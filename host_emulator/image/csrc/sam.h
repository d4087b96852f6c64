/* Instruction-level SAMD21 boards (Unicorn Cortex-M0+ core, software NVIC, peripheral models) joined in a world. */
#ifndef SAM_H
#define SAM_H

#include <stddef.h>
#include <stdint.h>
#include <unicorn/unicorn.h>
#include "sam_api.h"
#include "sam_regtab.h"

/*
 * Time. Every board keeps its own clock t in time units (tu) of 1/SAM_TU_HZ s, chosen so that the clocks
 * the boards use are whole numbers of units: a 48 MHz CPU cycle is 32 tu, a 32.768 kHz cycle 46875, the 1 ms
 * SysTick 1.536e6 (uint64: 380 years).
 *
 * Execution. Unicorn translates the image into blocks; a block hook runs before each block executes and
 * charges its cycles (cycle model in sam_cycles.h). All register accesses of a block happen at its start
 * time t_blk. Events (timer overflows, pin edges, bus and USB steps) are due at a time; each is processed at
 * the first block boundary at or after its time, before that block runs, and so is every interrupt the event
 * raises. Where emulation happens to stop (the world's rounds, parking) never changes this: results do not
 * depend on the schedule nor on fast-forwarding (sam_world_run.c, tests/host_emulator/image).
 */
#define SAM_TU_HZ 1536000000ull
#define SAM_NEVER UINT64_MAX

#define SAM_FLASH_SIZE 0x40000u
#define SAM_RAM_BASE 0x20000000u
#define SAM_RAM_SIZE 0x8000u
#define SAM_NVM_BASE 0x00800000u   /* NVM user row, software calibration and serial number rows (read-only) */
#define SAM_NVM_SIZE 0x10000u
#define SAM_APP_BASE 0x2000u       /* the UF2 bootloader's application start (vector table) */
#define SAM_NVM_USER_ROW 0x00804000u   /* the NVM user row: BOOTPROT (bits 2:0), the region lock bits (63:48) */
/* BOOTPROT of the user row the boards start with: 7, no bootloader protection. The shipped XIAOs' fuse value is not
 * known; 7 is assumed (a forced upload at offset 0 then overwrites the bootloader, as issue 28 expects).
 * sam_world_set_user_row programs another. */
#define SAM_NVM_BOOTPROT_ASSUMED 7u

/*
 * Events. Every board has one slot per source of events, holding the time its next event is due (SAM_NEVER:
 * none): one per peripheral (its model's fire), SysTick, then the sources the world and the links between boards
 * register for the board (sam_source_add: the plant's pin edges, the I2C bus, the USB host, faults), in the order
 * they registered. Events due at the same time are taken in slot order.
 */
#define SAM_MAX_PERIPH 48
#define SAM_MAX_SOURCES 5
enum { SAM_SLOT_SYSTICK = SAM_MAX_PERIPH, SAM_SLOT_SOURCE0, SAM_NSLOTS = SAM_SLOT_SOURCE0 + SAM_MAX_SOURCES };

/* model read/write results */
enum { SAM_DONE = 0, SAM_GENERIC = 1, SAM_UNCOVERED = -1 };

typedef struct sam_mcu sam_mcu_t;

typedef struct sam_model {
    const char *type;                                                     /* vendor struct name, "Tc" */
    void (*reset)(sam_mcu_t *m, int pi);
    int (*view)(sam_mcu_t *m, int pi);                                    /* active mode view (1..), 0: none */
    int (*read)(sam_mcu_t *m, int pi, int ri, uint32_t *v);               /* SAM_DONE / SAM_GENERIC / SAM_UNCOVERED */
    int (*write)(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask);
    void (*fire)(sam_mcu_t *m, int pi);                                   /* its slot's time came */
} sam_model_t;

/* An event source registered for a board (sam_sched.c): it belongs to the world, not to the chip, so a reset of the
 * board leaves its slot alone. */
enum { SAM_SRC_UNPOWERED = 1 };   /* it also fires while the board has no power */
typedef struct {
    void (*fire)(sam_mcu_t *m, void *ctx);                    /* its slot's time came */
    void (*quiet)(sam_mcu_t *m, void *ctx, uint64_t t_end);   /* parked board: take now its events before t_end
                                                                 that cannot change the board (or NULL) */
    void *ctx;
    unsigned flags;
} sam_source_t;

/* Software NVIC (ARMv6-M): exception numbers 2 NMI, 3 HardFault, 11 SVCall, 14 PendSV, 15 SysTick, 16+n IRQ n */
typedef struct {
    uint32_t enabled;      /* ISER */
    uint32_t pending;      /* ISPR */
    uint32_t level;        /* peripheral request lines (level-sensitive) */
    uint32_t active;       /* external IRQs active */
    uint32_t sys_pending;  /* bit e for system exception e */
    uint32_t sys_active;
    uint8_t prio[32];      /* 0..3: the implemented top two bits of each IPR byte */
    uint8_t prio_svc, prio_pendsv, prio_systick;
    uint8_t entering;      /* the exception whose entry just ended, until its handler's first instruction runs: a
                              higher-priority one arriving meanwhile takes its place (late arrival) */
    uint32_t ipr[8];       /* IPR words as written (only bits 7:6 of each byte are implemented) */
    uint32_t vtor;
    uint32_t scr, shpr2, shpr3;
} sam_nvic_t;

typedef struct {
    uint32_t ctrl, load, val_at, countflag;
    uint64_t t0;           /* time of the last reload (tu) */
    uint64_t period;       /* (LOAD + 1) CPU cycles in tu */
} sam_systick_t;

/* a translated block's cost, memoised (the prefix-sum tables are large and cold) */
typedef struct {
    uint32_t addr;
    uint16_t size;
    uint8_t refund, pad;
    uint32_t core;
    uint16_t wait, lit;
} sam_blkcost_t;
#define SAM_MEMO 4096
/* Flash [addr, addr + len) was rewritten (NVMCTRL): the blocks costed from it are costed again from the new bytes,
 * and code the ELF's tables described is costed by the decoder from then on (sam_cost.c). */
void sam_cost_flash_written(sam_mcu_t *m, uint32_t addr, uint32_t len);

/* fast-forward of an idle main loop, and of a loop that polls a register or the time (sam_ff.c) */
#define SAM_FF_REC 32      /* register accesses of a pass recorded (a longer pass is never probed) */
#define SAM_FF_JCAP0 64u   /* passes the first probe at a polling loop may cover */
typedef struct {
    int enabled;
    int timed;             /* passes that read the time may be skipped (after a probe: sam_ff.c) */
    uint32_t loop_pc;      /* entry of loop() */
    uint32_t head;         /* the boundary passes are compared at: loop_pc, or a block of a polling loop */
    uint64_t q_act, q_t;   /* activity counter and time when the board last did something (or entered loop()) */
    int q_dead;            /* the polling head found in this quiet stretch was given up */
    int head_misses;       /* arrivals at a polling head with registers unlike the last */
    int regs_valid;        /* poll_regs holds the registers at the last arrival at the polling head */
    uint32_t poll_regs[20];
    uint32_t snap_head;    /* the boundary the snapshot was taken at */
    uint32_t known[2];     /* polling heads that parked: taken at once when the board reads a register there */
    uint64_t known_period[2];   /* their pass's length (tu) */
    uint64_t snap_tread;   /* time reads at the snapshot */
    uint64_t horizon;      /* a parked pass that read the time repeats up to here (SAM_NEVER: until an event) */
    uint32_t rec[SAM_FF_REC], cand[SAM_FF_REC];   /* register accesses of the pass (address << 4 | size << 1 | W) */
    uint32_t rec_n, cand_n, probe_n;
    int probing, probe_bad;   /* a speculative pass (the probe) runs; it went astray */
    uint64_t pr_t1, pr_c1, pr_stop, pr_act, pr_tread, pr_end;
    uint64_t jcap;         /* most passes one probe may cover (doubles on success, shrinks on failure) */
    uint64_t probes, probe_fails;
    int snap_valid;        /* a snapshot of the state at a loop() entry */
    uint64_t snap_act;     /* activity counter at the snapshot */
    uint64_t snap_t, snap_cycles;
    uint32_t snap_regs[20];
    uint32_t snap_cache[8];
    uint8_t *snap_ram;
    int mid_valid;         /* snap_ram holds all of RAM at the snapshot, also between the heap's break and SP */
    int idle;              /* the last pass compared parked (0 after a miss): the board looks idle */
    int parked;            /* stopped at a verified fixed point: state == snapshot at a loop() entry */
    int resumed;           /* just resumed at a loop() entry: that pass runs (its event is due inside it) */
    uint64_t anchor, period, period_cycles;
    uint64_t passes_skipped, cycles_skipped, parks, checks, misses;
    /* SRAM pages the CPU may not store to without notice: [prot_lo, prot_hi) (SRAM offsets, whole 1 KiB pages; empty
     * when lo == hi), read only in its TLB (hook_tlb), from the snapshot's reference point (sam_ff.c) */
    uint32_t prot_lo, prot_hi;
    uint32_t ref_lo, ref_hi;   /* the pages protected since the reference point, which the compares skip */
    int mid_dirty;         /* a store reached them since (the CPU's, stopped and let through; or one from C) */
    uint64_t traps;        /* stores the protection stopped */
} sam_ff_t;

struct sam_mcu {
    sam_world_t *w;
    int id;
    char name[24];
    uc_engine *uc;
    uc_hook hooks[6];
    uint8_t *flash, *ram, *nvm;
    /* image facts (from the ELF, Python side) */
    uint32_t entry_sp, entry_pc;
    const uint32_t *cost_core, *cost_wait;  /* prefix sums over halfwords of flash: core cycles, worst-case waits */
    const uint32_t *cost_lit;               /* prefix sums: PC-relative loads (a flash read each) */
    int cycle_model;                         /* SAM_CYCLES_CACHE / SAM_CYCLES_WORST */
    uint32_t cache_tag[8];                   /* NVM cache: 8 direct-mapped 64-bit lines (tag = address >> 6) */
    uint32_t clk_epoch;                      /* changes with every clock configuration write (cached frequencies) */
    const uint8_t *refund;                  /* per halfword: cycles a conditional branch there costs less untaken */
    uint32_t app_end;                       /* first address past the image's code */
    uint32_t heap_base;                     /* SRAM offset of the end of static data (the heap's start) */
    uint32_t brk_var;                       /* address of the heap's break pointer (sbrk's), 0: none known */
    sam_blkcost_t memo[SAM_MEMO];
    /* time */
    uint64_t t;            /* time of the next block boundary (tu) */
    uint64_t t_blk;        /* start of the executing block: the time of its register accesses */
    uint64_t stop_at;      /* the block hook stops before a block starting at or after this time, and takes no
                              event due at or after it (sam_stop_before lowers it during a run) */
    uint64_t pos;          /* the board has run to here: every event before it taken, every access before it made */
    int ev_quiet;          /* set by an event handler that changed nothing (sam_bus_fire): no activity */
    uint32_t cyc_tu;       /* tu per CPU cycle */
    uint32_t rws;          /* NVMCTRL.CTRLB.RWS: flash wait states */
    uint32_t prev_end;     /* end of the previous block, for the untaken-branch refund */
    uint32_t cont_pc;      /* a store to a protected SRAM page stopped the CPU here, inside a block charged whole: the
                              block starting here is its rest (sam_ff.c), 0xFFFFFFFF: none */
    uint8_t prev_refund;
    uint64_t cycles;       /* CPU cycles executed (for reports) */
    uint64_t *prof;        /* cycles charged per block start (halfword index), NULL: not profiling */
    uint64_t act;          /* activity counter (events, interrupts, state-changing register accesses) */
    uint64_t tread;        /* reads of a register that counts time (SysTick VAL): not activity (sam_ff.c) */
    uint32_t blk;          /* start of the block running (the block hook) */
    uint64_t ep_noted;     /* bit ri % 64: an enable-protected write to register ri was noted */
    uint64_t ep_writes;    /* writes to enable-protected fields while enabled (ignored, as on silicon) */
    /* events */
    uint64_t slot[SAM_NSLOTS];
    uint64_t slot_live;    /* bit s: slot[s] is set (not SAM_NEVER); the scans for the earliest walk these only */
    uint64_t next_ev;
    sam_source_t src[SAM_MAX_SOURCES];   /* slot SAM_SLOT_SOURCE0 + k */
    int nsrc;
    /* exceptions */
    sam_nvic_t nvic;
    sam_systick_t systick;
    int irq_check;         /* re-evaluate pending exceptions at the next block */
    int primask_wait;      /* an exception waits for PRIMASK to clear: check every block */
    int lockup;            /* a fault while in HardFault: the core stops (only a reset helps) */
    int halted;            /* powered off / held in reset by a fault injection */
    int in_reset;          /* a reset is pending (processed outside emulation) */
    uint8_t reset_cause;   /* PM.RCAUSE of the last reset */
    uint32_t resets;
    uint32_t hardfaults;
    uint32_t fault_addr;   /* address of the last bus fault */
    uint64_t wp_pages[3];  /* per APB bridge, its 1 KiB pages a store to stops the CPU (sam_pac.c) */
    /* peripherals */
    const sam_model_t *model[SAM_MAX_PERIPH];
    void *pst[SAM_MAX_PERIPH];             /* model state */
    uint8_t *regs[SAM_MAX_PERIPH];          /* register storage (the window's bytes, all views) */
    int16_t *omap[SAM_MAX_PERIPH][5];       /* offset -> register index per view */
    uint32_t *touch;                         /* [2 * sam_nregs]: reads, writes per register */
    uint64_t mmio_reads, mmio_writes;
    uint64_t runs;         /* emulation starts (uc_emu_start calls) */
    uint64_t tlb_fills;    /* Unicorn TLB refills (hook_tlb calls): each costs it a CPU-state restore */
    void *regions[8];      /* the peripheral regions mapped into Unicorn (sam_mmio.c) */
    /* fast-forward */
    sam_ff_t ff;
    /* notes (sam_note), collected by the world in board order */
    char *notes;
    uint32_t notes_len;
    /* errors */
    int err;
    char errmsg[320];
    /* board wiring (sam_world.c) */
    int role;              /* SAM_ROLE_CELL / SAM_ROLE_PRIMARY */
    int cell;              /* 0-based cell index, -1 for the primary */
    int boot;              /* 1: resets start from the vector table at 0 (a bootloader there); 0: at the image */
    uint32_t nvm_erases, nvm_writes;   /* rows erased and pages written by NVMCTRL */
    /* cycle costs (sam_cost.c): the ELF's tables hold [tab_lo, app_end) (NULL cost_core: none) */
    uint32_t tab_lo;
};

/* indices of the peripherals and registers the models name, found once in the generated table */
typedef struct {
    int pm, sysctrl, gclk, wdt, eic, nvmctrl, port, iobus, usb, tc3, tcc[3], nvic, scb, systick;
    int pm_cpusel, wdt_ctrl, wdt_config, tc3_count16_count;
} sam_index_t;
extern sam_index_t sam_idx;
void sam_index_init(void);
int sam_regtab_check(char *err, size_t cap);

/* ---- sam_mcu.c: a board's life cycle ---- */
int sam_mcu_init(sam_mcu_t *m, sam_world_t *w, int id);
void sam_mcu_free(sam_mcu_t *m);
void sam_mcu_power_on_reset(sam_mcu_t *m);
void sam_mcu_system_reset(sam_mcu_t *m, uint8_t cause);

/* ---- sam_sched.c: time, events, the run loop ---- */
int sam_mcu_run(sam_mcu_t *m, uint64_t t_end);
int sam_mcu_idle_to(sam_mcu_t *m, uint64_t t_end);   /* parked through t_end: 1, pos set */
void sam_slot_set(sam_mcu_t *m, int slot, uint64_t t);
/* Register an event source for the board (before it powers on): its slot, -1 when the table is full. */
int sam_source_add(sam_mcu_t *m, void (*fire)(sam_mcu_t *m, void *ctx),
                   void (*quiet)(sam_mcu_t *m, void *ctx, uint64_t t_end), void *ctx, unsigned flags);
static inline uint64_t sam_now(const sam_mcu_t *m) { return m->t_blk; }
_Static_assert(SAM_NSLOTS <= 64, "slot_live holds one bit per event slot");

/* The board's earliest event slot but `skip` (-1: none): its index, the lowest of equal times; -1 when none is set. */
static inline int sam_slot_first(const sam_mcu_t *m, int skip)
{
    uint64_t live = m->slot_live & ~(skip >= 0 ? 1ull << skip : 0ull);
    int best = -1;
    uint64_t bt = SAM_NEVER;
    while (live) {
        int s = __builtin_ctzll(live);
        live &= live - 1u;
        if (m->slot[s] < bt) {
            bt = m->slot[s];
            best = s;
        }
    }
    return best;
}

/* When that slot is due (SAM_NEVER: none is set). */
static inline uint64_t sam_slot_earliest(const sam_mcu_t *m, int skip)
{
    int s = sam_slot_first(m, skip);
    return s >= 0 ? m->slot[s] : SAM_NEVER;
}

static inline void sam_activity(sam_mcu_t *m) { m->act++; }

/* ---- sam_cpu.c: the CPU (Unicorn), cycle charging, memory ---- */
void sam_fail(sam_mcu_t *m, const char *fmt, ...);
uint32_t sam_mem_read32(sam_mcu_t *m, uint32_t addr, int *ok);
void sam_set_cpu_clock(sam_mcu_t *m);                     /* after GCLK0 or PM.CPUSEL changed */
int sam_cpu_flash_changed(sam_mcu_t *m, uint32_t addr, uint32_t len);   /* flash rewritten there (NVMCTRL, harness) */
void sam_cpu_resume_after(sam_mcu_t *m, uint32_t pc);    /* resume at pc inside the block charged (a flash store) */
void sam_ff_ram_written(sam_mcu_t *m);   /* SRAM written from C (exception frames, USB): the fast-forward's next
                                            compare a miss (sam_ff.c) */
/* The store instruction at pc, as the CPU stopped at it (ARMv6-M's 16-bit STR, STRH, STRB with an immediate or a
 * register offset, STMIA): 1 and *s, or 0 when it is none of them. */
typedef struct {
    uint32_t addr, size;   /* the first address, the width of each store (1, 2, 4) */
    uint32_t val;          /* what a single store stores (STR/STRH/STRB) */
    uint32_t list, rn;     /* STMIA: its register list (0: a single store) and base register */
    uint32_t r[8];         /* R0..R7 at the store */
} sam_store_t;
int sam_cpu_decode_store(sam_mcu_t *m, uint32_t pc, sam_store_t *s);
/* The store at pc took a bus error: HardFault (or lockup) with pc stacked, the note saying what; the store's cycles
 * stay charged, the rest of its block is refunded. */
void sam_cpu_bus_error(sam_mcu_t *m, uint32_t pc, const char *what);

/* ---- sam_nvmctrl.c: flash programming ---- */
int sam_nvm_cpu_store(sam_mcu_t *m);       /* the CPU stopped at a store to flash: to the page buffer (1) or fault (0) */
void sam_nvm_load_fuses(sam_mcu_t *m);     /* LOCK and BOOTPROT from the user row (at reset) */

/* ---- sam_pac.c: peripheral write protection ---- */
/* a store to address a stops the CPU: a page of a write-protected peripheral or of a PAC (the CPU's TLB hook) */
static inline int sam_pac_trapped(const sam_mcu_t *m, uint32_t a)
{
    uint32_t bridge = (a >> 24) - 0x40u, page = (a & 0xFFFFFFu) >> 10;
    return bridge < 3 && page < 64 && (m->wp_pages[bridge] >> page & 1u);
}
int sam_pac_store(sam_mcu_t *m);   /* the CPU stopped at a store there: carried out or a bus error (1), else 0 */

/* ---- sam_nvic.c: exceptions ---- */
void sam_irq_level(sam_mcu_t *m, int irq, int on);
void sam_irq_pend_sys(sam_mcu_t *m, int exc);

/* ---- sam_mmio.c: the register layer ---- */
const char *sam_reg_name(int ri);
const sam_field_t *sam_field(int ri, const char *name);
int sam_periph_index(const char *name);
int sam_reg_index(int pi, const char *name);
uint32_t sam_reg_get(sam_mcu_t *m, int ri);
void sam_reg_put(sam_mcu_t *m, int ri, uint32_t v);
void sam_generic_write(sam_mcu_t *m, int ri, uint32_t v, uint32_t mask);  /* the table's access rule */
int sam_generic_changes(sam_mcu_t *m, int ri, uint32_t v, uint32_t mask);  /* whether that write changes a bit */
int sam_mmio_store(sam_mcu_t *m, uint32_t addr, unsigned size, uint32_t v);   /* a CPU store carried out: 0, -1 */
/* sam_protect.c: v with the `protect` bits of register ri kept as they are when the peripheral is enabled (noted) */
uint32_t sam_enable_protected(sam_mcu_t *m, int ri, uint32_t v, uint32_t mask, uint32_t protect, int enabled);
int sam_reg_at(sam_mcu_t *m, int pi, uint32_t offset);   /* register at this offset in the active view, or -1 */
static inline uint32_t sam_rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* ---- sam_models.c: the models by the vendor's struct type of the peripherals they serve ---- */
const sam_model_t *sam_model_for(const char *type);

/* write-synchronisation of a peripheral: a few cycles of its generic clock (DS40001882 "Synchronization") */
#define SAM_SYNC_GCLK_CYCLES 3u

/* ---- clocks: sam_pm.c, sam_sysctrl.c, sam_gclk.c ---- */
int sam_apb_on(sam_mcu_t *m, int pi);                     /* the peripheral's bus clock is on in PM */
uint64_t sam_dfll_hz(sam_mcu_t *m);
uint64_t sam_sysctrl_osc_hz(sam_mcu_t *m, uint32_t src); /* a generator's source when a SYSCTRL oscillator */
uint64_t sam_gclk_hz(sam_mcu_t *m, int gclk_id);         /* frequency of a peripheral channel, 0 when off */
uint64_t sam_gen_hz(sam_mcu_t *m, int gen);
uint64_t sam_tu_per_tick(sam_mcu_t *m, uint64_t hz, uint32_t presc, const char *what);   /* 0: no clock */

/* ---- sam_port.c, sam_eic.c: pins ---- */
void sam_pin_drive(sam_mcu_t *m, int pin, int level);    /* the board drives a pin (-1: released) */
int sam_pin_level(sam_mcu_t *m, int pin);                 /* level on the pin (board, MCU output, pulls) */
int sam_pin_function(sam_mcu_t *m, int pin);              /* PMUX letter 0..7 when PMUXEN, else -1 */
int sam_pin_out(sam_mcu_t *m, int pin, int *driven);      /* GPIO output level and whether the MCU drives it */
void sam_eic_pin_input(sam_mcu_t *m, int pin, int level); /* a pin's level changed */
void sam_eic_lines_update(sam_mcu_t *m);                  /* the pins' mux changed */

/* ---- sam_tc.c, sam_tcc.c: timers ---- */
void sam_tc_stop_clock(sam_mcu_t *m, const char *name);   /* fault injection: the TC's clock is lost */
/* high time of WO[wo] over [t0, t1). waveform 0: the mean duty CC / (PER + 1) over the time, as an exact fraction:
 * returns the numerator in tu (counts high x tu), *top the denominator (the period in counts), *other the part (tu)
 * after a period change inside [t0, t1). waveform 1: the waveform's own high time, edge by edge: exact in tu
 * (*top = 1, *other = 0). */
uint64_t sam_tcc_high(sam_mcu_t *m, int tcc, int wo, uint64_t t0, uint64_t t1, int waveform, uint64_t *top,
                      double *other);
/* WO[wo] over [t0, t1) as constant pieces in time order: fn(ctx, level, duration in tu) */
typedef void (*sam_tcc_piece_fn)(void *ctx, int level, uint64_t dt);
void sam_tcc_pieces(sam_mcu_t *m, int tcc, int wo, uint64_t t0, uint64_t t1, sam_tcc_piece_fn fn, void *ctx);
int sam_tcc_state(sam_mcu_t *m, int tcc, uint64_t t, sam_tcc_info_t *out);   /* the counter at t; -1: none */
/* PER + 1 while the counter runs and no buffered PER is pending (the period holds until a write or event), 1 while it
 * is stopped or absent, 0 while a PERB waits for an UPDATE */
uint64_t sam_tcc_period_held(sam_mcu_t *m, int tcc);

/* A step to another board takes effect at t: this board stops before t + SAM_BUS_TMIN, when the other may answer. */
static inline void sam_stop_before(sam_mcu_t *m, uint64_t t)
{
    if (t < m->stop_at)
        m->stop_at = t;
}

/* ---- sam_world.c, sam_world_plant.c: what the boards do to the world ---- */
void sam_world_pins_will_change(sam_mcu_t *m);            /* before a pin's level or mux changes: motors integrate */
void sam_world_pins_changed(sam_mcu_t *m);                /* after: the bus lines are re-read */
void sam_world_pins_unchanged(sam_mcu_t *m);              /* a PORT write changed nothing: motors integrate if needed */
void sam_world_tcc_will_change(sam_mcu_t *m, int tcc);    /* before a TCC's duty changes (now or later) */
void sam_world_note(sam_world_t *w, const char *fmt, ...); /* a log line from the world, read by Python */
void sam_note(sam_mcu_t *m, const char *fmt, ...);         /* a log line from a board (resets, faults, traces) */
#define SAM_BOARD_NOTES (256u * 1024u)

#endif /* SAM_H */
