/* Internals the board core's files share (CPU, NVIC, SCS, MMIO, scheduling, fast-forward, life cycle); not for models. */
#ifndef SAM_CORE_H
#define SAM_CORE_H

#include "sam.h"
#include "sam_world.h"

/* exception entry and return, an access through the AHB-APB bridge: the CPU budget's cycle model (sam_world_cfg_t,
 * from metacell_tools.fwcheck.cpubudget.CycleModel) */
#define EXC_ENTRY_CYCLES ((uint64_t)m->w->cfg.cyc_exc_entry)
#define EXC_EXIT_CYCLES ((uint64_t)m->w->cfg.cyc_exc_exit)
#define APB_EXTRA_CYCLES ((uint64_t)m->w->cfg.cyc_apb)
#define TAIL_CHAIN_CYCLES 11  /* ARMv6-M tail-chaining: no unstacking, a new vector fetch */

#define EXC_RETURN_THREAD 0xFFFFFFF9u
#define EXC_RETURN_HANDLER 0xFFFFFFF1u

/* the core registers a fast-forward snapshot compares (the first 13, R0..R12, are zeroed by a reset), in this order:
 * R0..R12, SP, LR, PC, XPSR, PRIMASK, CONTROL (SAM_CORE_R12, _SP, _LR and _XPSR index the ones the exception entry
 * stacks) */
#define SAM_NCORE_REGS 19
#define SAM_CORE_R12 12
#define SAM_CORE_SP 13
#define SAM_CORE_LR 14
#define SAM_CORE_XPSR 16
extern const int sam_core_regs[SAM_NCORE_REGS];

/* ---- sam_cpu.c ---- */
uint32_t sam_cpu_reg(sam_mcu_t *m, int id);
void sam_cpu_core_read(sam_mcu_t *m, uint32_t *regs);   /* the SAM_NCORE_REGS core registers, in their order */
void sam_cpu_set(sam_mcu_t *m, int id, uint32_t v);
void sam_cpu_rebuild_hflags(sam_mcu_t *m);
void sam_cpu_lockup(sam_mcu_t *m, const char *why);
int sam_cpu_open(sam_mcu_t *m);                    /* Unicorn, the CPU model, flash, SRAM and NVM rows */
int sam_cpu_hooks(sam_mcu_t *m);                   /* the block, exception, memory-fault and TLB hooks */
int sam_cpu_ram_write32(sam_mcu_t *m, uint32_t addr, uint32_t v);
void sam_cpu_enter_fault(sam_mcu_t *m, uc_err e);  /* the memory system faulted: HardFault (or lockup) */

/* ---- sam_cost.c ---- */
/* A block's cost into *bc: the ELF's tables where they hold it, else decoded from flash; -1: the board halted (an
 * instruction the cycle model cannot time, a note names it). */
int sam_cost_block(sam_mcu_t *m, uint32_t addr, uint32_t size, sam_blkcost_t *bc);
/* What [pc, end) of a block charged whole cost (its core cycles and the waits the flash model charged for it
 * beyond the cache's lines: all in the worst case, the PC-relative loads with the cache), from the same source as
 * the block; 0 when it cannot be costed. */
uint64_t sam_cost_tail(const sam_mcu_t *m, uint32_t pc, uint32_t end);

/* ---- sam_nvic.c ---- */
int sam_nvic_best_pending(const sam_mcu_t *m, int *prio);
int sam_nvic_exec_prio(const sam_mcu_t *m);              /* of the active exceptions (4: none), before PRIMASK */
int sam_nvic_enter(sam_mcu_t *m, int e, uint32_t ret);   /* stack a frame and enter exception e; 1 on success */
int sam_nvic_take(sam_mcu_t *m, uint32_t ret);           /* take the best pending exception if it may pre-empt */
void sam_nvic_return(sam_mcu_t *m);                      /* an exception return (EXC_RETURN in handler mode) */

/* ---- sam_scs.c ---- */
extern const sam_model_t sam_model_scs;
void sam_systick_fire(sam_mcu_t *m);
void sam_systick_reclock(sam_mcu_t *m, uint32_t old_cyc_tu);

/* ---- sam_mmio.c ---- */
int sam_mmio_map(sam_mcu_t *m);                   /* the peripheral regions, through the models */
void sam_mmio_free(sam_mcu_t *m);

/* ---- sam_sched.c ---- */
void sam_next_event(sam_mcu_t *m);
uint64_t sam_next_loud(sam_mcu_t *m);             /* the next event that may change what its software sees */
void sam_process_events(sam_mcu_t *m);            /* every event due at or before the current block boundary */

/* ---- sam_ff.c ---- */
void sam_ff_loop_entry(sam_mcu_t *m);             /* loop() entered: its entry is the boundary again */
int sam_ff_boundary(sam_mcu_t *m);                /* at the boundary: 1 when parked (the pass repeats exactly) */
void sam_ff_access(sam_mcu_t *m, uint32_t key);   /* a register access (address << 4 | size << 1 | write) */
int sam_ff_probe_access(sam_mcu_t *m, uint32_t key);   /* in a probe: 0 when the access must not happen */
int sam_ff_probe_end(sam_mcu_t *m, int at_head, int stopped);   /* the probe ends: 1 when parked */
int sam_ff_ram_trap(sam_mcu_t *m);   /* the CPU stopped at a store to a protected SRAM page: 1 when it was that */
void sam_ff_resume(sam_mcu_t *m);                 /* leave the park at the last loop() entry before the next event */

/* ---- sam_mcu.c ---- */
int sam_init_fail(sam_mcu_t *m, const char *what, uc_err e);
void sam_request_reset(sam_mcu_t *m, uint8_t cause);   /* processed outside emulation */
void sam_do_reset(sam_mcu_t *m, uint8_t cause);

#endif /* SAM_CORE_H */
