/* The CPU: Unicorn's Cortex-M0 with flash, SRAM and the NVM rows, the block hook that charges cycles, memory faults. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam_core.h"

const int sam_core_regs[SAM_NCORE_REGS] = {
    UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2,  UC_ARM_REG_R3,  UC_ARM_REG_R4,  UC_ARM_REG_R5,   UC_ARM_REG_R6,
    UC_ARM_REG_R7, UC_ARM_REG_R8, UC_ARM_REG_R9,  UC_ARM_REG_R10, UC_ARM_REG_R11, UC_ARM_REG_R12,  UC_ARM_REG_SP,
    UC_ARM_REG_LR, UC_ARM_REG_PC, UC_ARM_REG_XPSR, UC_ARM_REG_PRIMASK, UC_ARM_REG_CONTROL};

/* ---------------------------------------------------------------- errors */

void sam_fail(sam_mcu_t *m, const char *fmt, ...)
{
    if (m->err)
        return;
    uint32_t pc = 0;
    uc_reg_read(m->uc, UC_ARM_REG_PC, &pc);
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    snprintf(m->errmsg, sizeof m->errmsg, "%s: %s (pc 0x%05x, t = %.6f s)", m->name, msg, pc,
             (double)m->t / (double)SAM_TU_HZ);
    m->err = 1;
    uc_emu_stop(m->uc);
}

/* ---------------------------------------------------------------- memory */

uint32_t sam_mem_read32(sam_mcu_t *m, uint32_t addr, int *ok)
{
    const uint8_t *p = NULL;
    if (addr <= SAM_FLASH_SIZE - 4)
        p = m->flash + addr;
    else if (addr >= SAM_RAM_BASE && addr - SAM_RAM_BASE <= SAM_RAM_SIZE - 4)
        p = m->ram + (addr - SAM_RAM_BASE);
    if (!p || (addr & 3)) {
        if (ok)
            *ok = 0;
        return 0;
    }
    if (ok)
        *ok = 1;
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

int sam_cpu_ram_write32(sam_mcu_t *m, uint32_t addr, uint32_t v)
{
    if (addr < SAM_RAM_BASE || addr - SAM_RAM_BASE > SAM_RAM_SIZE - 4 || (addr & 3))
        return 0;
    uint8_t *p = m->ram + (addr - SAM_RAM_BASE);
    sam_ff_ram_written(m);
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
    return 1;
}

/* ---------------------------------------------------------------- registers of the core, its clock */

uint32_t sam_cpu_reg(sam_mcu_t *m, int id)
{
    uint32_t v = 0;
    uc_reg_read(m->uc, id, &v);
    return v;
}

void sam_cpu_set(sam_mcu_t *m, int id, uint32_t v) { uc_reg_write(m->uc, id, &v); }

/* The core registers (sam_core_regs' order) in one call where the library has it (the tier's own build,
 * ucpatches/0007: the same values, without a dispatch per register), else as a batch (the released library). */
void sam_cpu_core_read(sam_mcu_t *m, uint32_t *regs)
{
#ifdef UC_ARM_M_CORE_NREGS
    _Static_assert(UC_ARM_M_CORE_NREGS == SAM_NCORE_REGS, "the library's core registers are the snapshot's");
    if (uc_arm_m_core_read(m->uc, regs) == UC_ERR_OK)
        return;
#endif
    void *ptrs[SAM_NCORE_REGS];
    for (int i = 0; i < SAM_NCORE_REGS; i++)
        ptrs[i] = &regs[i];
    uc_reg_read_batch(m->uc, (int *)sam_core_regs, ptrs, SAM_NCORE_REGS);
}

/* Unicorn caches the handler-mode flag of the TB state (hflags); an IPSR/XPSR write does not rebuild it, a write
 * of APSR's NZCV does (and changes nothing when it writes the flags back as they are). */
void sam_cpu_rebuild_hflags(sam_mcu_t *m)
{
    uint32_t nzcv = sam_cpu_reg(m, UC_ARM_REG_APSR_NZCV);
    sam_cpu_set(m, UC_ARM_REG_APSR_NZCV, nzcv);
}

void sam_cpu_lockup(sam_mcu_t *m, const char *why)
{
    if (!m->lockup)
        sam_note(m, "%s: core lockup (%s) at t = %.6f s; only a reset ends it", m->name, why,
                       (double)m->t / (double)SAM_TU_HZ);
    m->lockup = 1;
    uc_emu_stop(m->uc);
}

void sam_set_cpu_clock(sam_mcu_t *m)
{
    uint64_t hz = sam_gen_hz(m, 0);
    int sel = (int)(sam_reg_get(m, sam_idx.pm_cpusel) & 7u);
    m->clk_epoch++;
    hz >>= sel;
    if (hz == 0) {
        sam_fail(m, "the CPU clock (GCLK0) stopped");
        return;
    }
    if (SAM_TU_HZ % hz) {
        sam_fail(m, "CPU clock %llu Hz is not modelled (the time unit must divide it)", (unsigned long long)hz);
        return;
    }
    uint32_t old = m->cyc_tu;
    m->cyc_tu = (uint32_t)(SAM_TU_HZ / hz);
    if (old != m->cyc_tu)
        sam_systick_reclock(m, old);
}

/* HardFault for a fault the image caused at pc (the exception returns there); a fault while HardFault (or NMI)
 * is active locks the core up (ARMv6-M B1.5.13 Lockup). */
static void hardfault(sam_mcu_t *m, uint32_t pc, const char *what)
{
    uint32_t ipsr = sam_cpu_reg(m, UC_ARM_REG_XPSR) & 0x3Fu;
    sam_note(m, "%s: HardFault (%s, pc 0x%05x) at t = %.6f s", m->name, what, pc, (double)m->t / (double)SAM_TU_HZ);
    if (ipsr == 3 || ipsr == 2) {
        sam_cpu_lockup(m, "fault in the HardFault handler");
        return;
    }
    m->nvic.sys_pending |= 1u << 3;
    sam_nvic_enter(m, 3, pc);
}

/* A fault of the memory system (the run loop: Unicorn stopped with an error): HardFault, or lockup in it. */
void sam_cpu_enter_fault(sam_mcu_t *m, uc_err e)
{
    char what[96];
    snprintf(what, sizeof what, "%s at 0x%08x", uc_strerror(e), m->fault_addr);
    hardfault(m, sam_cpu_reg(m, UC_ARM_REG_PC), what);
}

/* ---------------------------------------------------------------- hooks */

/* Unicorn's exception numbers (QEMU's target/arm/cpu.h EXCP_*): what the hook below receives. */
#define EXCP_UDEF 1             /* UDF, and any encoding ARMv6-M does not define: PC at the instruction */
#define EXCP_SWI 2              /* SVC: PC after the instruction */
#define EXCP_PREFETCH_ABORT 3
#define EXCP_DATA_ABORT 4
#define EXCP_BKPT 7             /* BKPT: PC at the instruction */
#define EXCP_EXCEPTION_EXIT 8   /* a branch to EXC_RETURN in handler mode */
#define EXCP_INVSTATE 18        /* a branch with bit 0 clear (T = 0) */
#define EXCP_UNALIGNED 22       /* an unaligned LDR/STR where QEMU raises it apart (ARMv6-M traps every one) */

/* The instructions that raise an exception on ARMv6-M (B1.5 "ARMv6-M exception model"): SVC takes SVCall when its
 * priority is above the execution priority, else HardFault (escalation); UDF, BKPT without a debugger, an
 * unaligned access, an interworking branch to ARM state and a bus error all take HardFault. The block the
 * instruction ended was charged whole: what did not run of it is refunded. */
static void hook_intr(uc_engine *uc, uint32_t intno, void *ud)
{
    sam_mcu_t *m = ud;
    (void)uc;
    if (m->ff.probing) {   /* the speculative pass went astray: nothing of it is kept (sam_ff.c) */
        m->ff.probe_bad = 1;
        uc_emu_stop(m->uc);
        return;
    }
    if (intno == EXCP_EXCEPTION_EXIT) {
        sam_nvic_return(m);
        return;
    }
    uint32_t pc = sam_cpu_reg(m, UC_ARM_REG_PC) & ~1u;
    m->fault_addr = pc;
    const char *what = NULL;
    switch (intno) {
    case EXCP_SWI:
        sam_cpu_resume_after(m, pc);   /* the SVC ran: the rest of its block did not */
        if (m->nvic.prio_svc < sam_nvic_exec_prio(m) && !(sam_cpu_reg(m, UC_ARM_REG_PRIMASK) & 1u)) {
            m->nvic.sys_pending |= 1u << 11;
            sam_nvic_enter(m, 11, pc);
        } else {
            hardfault(m, pc, "SVC with SVCall's priority not above the execution priority");
        }
        return;
    case EXCP_UDEF: what = "UDF or an undefined instruction"; break;
    case EXCP_BKPT: what = "BKPT with no debugger attached"; break;
    case EXCP_UNALIGNED: what = "unaligned access"; break;
    /* QEMU raises an M-profile alignment fault as a data abort: only its FSR, which Unicorn's API does not show,
     * tells the two apart */
    case EXCP_DATA_ABORT: what = "an unaligned access or a bus error"; break;
    case EXCP_PREFETCH_ABORT: what = "bus error"; break;
    case EXCP_INVSTATE: what = "a branch to ARM state (bit 0 clear)"; break;
    default: break;
    }
    if (!what) {
        sam_fail(m, "CPU exception %u (an instruction the model does not execute: WFI, WFE)", intno);
        return;
    }
    sam_cpu_resume_after(m, pc);
    hardfault(m, pc, what);
}

/* ---------------------------------------------------------------- faults from the memory system */

static bool hook_badmem(uc_engine *uc, uc_mem_type type, uint64_t address, int size, int64_t value, void *ud)
{
    sam_mcu_t *m = ud;
    (void)uc;
    (void)type;
    (void)size;
    (void)value;
    m->fault_addr = (uint32_t)address;
    return false;   /* the emulation stops with an error; the run loop enters HardFault */
}


/* The TLB entry of a page (Unicorn's virtual TLB): flash read and execute, SRAM read and write (but the pages the
 * fast-forward protects, read only: sam_ff.c), the NVM rows
 * read only, peripherals read and write but the pages the PAC traps, read only (sam_pac.c); anywhere else the
 * memory system reports the fault. SRAM is not executable: Unicorn then lets stores to it take the fast path (it
 * keeps pages that could hold code on a slow path for every store), and code there has no cycle model anyway. */
static bool hook_tlb(uc_engine *uc, uint64_t vaddr, uc_mem_type type, uc_tlb_entry *e, void *ud)
{
    (void)uc;
    (void)type;
    sam_mcu_t *m = ud;
    uint32_t a = (uint32_t)vaddr;
    m->tlb_fills++;
    e->paddr = vaddr;
    if (a < SAM_FLASH_SIZE)
        e->perms = UC_PROT_READ | UC_PROT_EXEC;
    else if (a >= SAM_RAM_BASE && a < SAM_RAM_BASE + SAM_RAM_SIZE)   /* but the fast-forward's protected pages */
        e->perms = a - SAM_RAM_BASE >= m->ff.prot_lo && a - SAM_RAM_BASE < m->ff.prot_hi ? UC_PROT_READ
                                                                                       : UC_PROT_READ | UC_PROT_WRITE;
    else if (a >= SAM_NVM_BASE && a < SAM_NVM_BASE + SAM_NVM_SIZE)
        e->perms = UC_PROT_READ;
    else if (a >= 0x40000000u && a < 0x60000000u)
        e->perms = sam_pac_trapped(m, a) ? UC_PROT_READ : UC_PROT_READ | UC_PROT_WRITE;
    else
        e->perms = UC_PROT_ALL;
    return true;
}

/* ---------------------------------------------------------------- the block hook */

/* The block charged whole ran only up to pc (its rest runs as a block of its own, charged then): the rest's cycles
 * refunded (costed as the block was: the ELF's tables or the decoder), and no untaken-branch refund after it. */
static void refund_rest(sam_mcu_t *m, uint32_t pc)
{
    uint32_t end = m->prev_end;
    if (end != 0xFFFFFFFFu && pc < end) {
        uint64_t back = sam_cost_tail(m, pc, end);
        m->t -= back * m->cyc_tu;
        m->cycles -= back;
    }
    m->prev_end = 0xFFFFFFFFu;
}

/* A block's cycles by the cycle model (its memoised cost; with the cache model the NVM cache's lines it fetches,
 * filled). */
static inline uint64_t block_cycles(sam_mcu_t *m, uint32_t addr, uint32_t size, const sam_blkcost_t *bc)
{
    uint64_t cyc = bc->core;
    if (m->cycle_model == SAM_CYCLES_WORST) {
        cyc += (uint64_t)m->rws * bc->wait;
    } else if (m->rws) {
        /* the NVM cache: a fetch of a 64-bit line that is not cached waits RWS cycles and fills its line */
        uint32_t waits = bc->lit;
        for (uint32_t a = addr & ~7u; a < addr + size; a += 8) {
            uint32_t idx = (a >> 3) & 7u, tag = (a >> 6) | 0x80000000u;
            if (m->cache_tag[idx] != tag) {
                m->cache_tag[idx] = tag;
                waits++;
            }
        }
        cyc += (uint64_t)m->rws * waits;
    }
    return cyc;
}

/* The block starting at addr runs now: its cycles charged (its register accesses are at its start, t_blk), and its
 * end kept for the untaken-branch refund. Its cycles. */
static inline uint64_t charge(sam_mcu_t *m, uint32_t addr, uint32_t size, const sam_blkcost_t *bc)
{
    uint64_t cyc = block_cycles(m, addr, size, bc);
    m->t_blk = m->t;
    m->t += cyc * m->cyc_tu;
    m->cycles += cyc;
    m->prev_end = addr + size;
    m->prev_refund = bc->refund;
    return cyc;
}

/* Stop the CPU at the start of the block the hook runs for (addr): the block does not run. Unicorn would otherwise
 * find the PC again from the translated code when it stops (a search of its blocks by host address, then a walk of
 * the block's instruction starts: about as much as a hundred hooked blocks); the PC written here is that block's
 * start, which Unicorn synced before the hook, and a PC written from a hook spares that search (Unicorn 2.1:
 * skip_sync_pc_on_exit). */
static void stop_at_block(uc_engine *uc, sam_mcu_t *m, uint32_t addr)
{
    uc_emu_stop(uc);
    sam_cpu_set(m, UC_ARM_REG_PC, addr | 1u);
}

/* The block hook's whole work after the untaken-branch refund (hook_block takes the common case itself). Kept out
 * of it: its calls would give every block their frame. */
__attribute__((noinline)) static void hook_rest(uc_engine *uc, uint32_t addr, uint32_t size, sam_mcu_t *m)
{
    if (m->t >= m->next_ev && m->cont_pc != 0xFFFFFFFFu) {   /* (next_ev is held at 0 meanwhile: sam_next_event) */
        uint32_t cont = m->cont_pc;
        m->cont_pc = 0xFFFFFFFFu;
        sam_next_event(m);
        if (addr == cont && addr + size == m->prev_end)
            return;   /* the rest of the block a store to a protected page stopped (sam_ff.c): charged with it */
        if (addr == cont)
            refund_rest(m, addr);   /* translated otherwise: this block charged as it is */
    }
    m->prev_end = 0xFFFFFFFFu;
    if (m->t >= m->next_ev) {
        if (m->ff.probing) {
            /* a speculative pass (sam_ff.c, which holds next_ev at 0 meanwhile): back at its boundary, astray, or
             * past its time; no event can be due in it */
            int at_head = addr == m->ff.head;
            if (at_head || m->ff.probe_bad || m->t >= m->ff.pr_end || (m->irq_check | m->primask_wait) || m->err ||
                m->in_reset || m->lockup) {
                sam_ff_probe_end(m, at_head, 0);   /* parked, or undone by the run loop once stopped */
                stop_at_block(uc, m, addr);
                return;
            }
            goto charge;
        }
        sam_process_events(m);   /* those due before stop_at; an answer they send may lower stop_at */
    }
    if (m->err || m->in_reset || m->lockup || m->t >= m->stop_at) {
        stop_at_block(uc, m, addr);
        return;
    }
    if ((m->irq_check | m->primask_wait) && sam_nvic_take(m, addr))
        return;   /* the PC moved to the handler: this block does not run now */
    m->nvic.entering = 0;   /* a handler's first instruction runs: its entry can no longer be overtaken */
    m->blk = addr;
    if (addr == m->ff.head && m->ff.enabled) {   /* (loop() entered while a polling loop is the boundary: sam_ff.c) */
        if (addr == m->ff.loop_pc)
            sam_ff_loop_entry(m);
        if (sam_ff_boundary(m)) {
            stop_at_block(uc, m, addr);
            return;
        }
    }
charge:
    if (size == 0)
        return;
    /* the block's cost (sam_cost.c: the ELF's tables or the flash decoded), memoised per block start */
    sam_blkcost_t *bc = &m->memo[(addr >> 1) & (SAM_MEMO - 1)];
    if ((bc->addr != addr || bc->size != size) && sam_cost_block(m, addr, size, bc))
        return;   /* no cycle model for an instruction of it: the board halted */
    uint64_t cyc = charge(m, addr, size, bc);
    if (m->prof && !m->ff.probing)
        m->prof[addr >> 1] += cyc;
}

/* The block hook: the refund of an untaken branch, then the common case charged here (no event due, nothing to stop
 * for or to take, not the fast-forward's boundary, the block's cost memoised, no profile: what hook_rest would do
 * then), anything else in hook_rest. */
static void hook_block(uc_engine *uc, uint64_t address, uint32_t size, void *ud)
{
    sam_mcu_t *m = ud;
    uint32_t addr = (uint32_t)address;
    if (addr == m->prev_end) {   /* the previous block ended in a conditional branch that was not taken */
        uint32_t back = (m->prev_refund & 15u) + (m->cycle_model == SAM_CYCLES_WORST ? m->rws * (m->prev_refund >> 4) : 0u);
        m->t -= (uint64_t)back * m->cyc_tu;
        m->cycles -= back;
    }
    const sam_blkcost_t *bc = &m->memo[(addr >> 1) & (SAM_MEMO - 1)];
    if (m->t >= m->next_ev || m->t >= m->stop_at ||
        (m->err | m->in_reset | m->lockup | m->irq_check | m->primask_wait) || addr == m->ff.head ||
        bc->addr != addr || bc->size != size || size == 0 || m->prof) {
        hook_rest(uc, addr, size, m);
        return;
    }
    m->nvic.entering = 0;
    m->blk = addr;
    charge(m, addr, size, bc);
}

/* ---------------------------------------------------------------- flash rewritten by NVMCTRL (sam_nvmctrl.c) */

/* Code translated from the old contents is dropped (Unicorn does not see writes to the flash it maps from our
 * buffer), and so are the block costs memoised from it (and the ELF's tables, if it rewrote their code:
 * sam_cost_flash_written), the NVM cache's lines and the fast-forward's snapshot. The one path for every writer of
 * flash (NVMCTRL, the harness). */
int sam_cpu_flash_changed(sam_mcu_t *m, uint32_t addr, uint32_t len)
{
    uc_err ue = uc_ctl_remove_cache(m->uc, addr, addr + len);
    sam_cost_flash_written(m, addr, len);
    memset(m->cache_tag, 0, sizeof m->cache_tag);
    m->ff.snap_valid = 0;
    m->ff.known[0] = m->ff.known[1] = 0;   /* polling loops found in the old code */
    sam_activity(m);
    return ue == UC_ERR_OK ? 0 : -1;
}

/* Execution resumes at pc inside the block the hook charged whole (a store to flash stopped it there): the rest of
 * the block, which runs again as a block of its own and is charged again, is refunded (costed as the block was:
 * the ELF's tables or the decoder). */
void sam_cpu_resume_after(sam_mcu_t *m, uint32_t pc)
{
    refund_rest(m, pc);
    sam_cpu_set(m, UC_ARM_REG_PC, pc | 1u);
}

/* ---------------------------------------------------------------- stores the run loop carries out or refuses */

int sam_cpu_decode_store(sam_mcu_t *m, uint32_t pc, sam_store_t *s)
{
    if (pc > SAM_FLASH_SIZE - 2)
        return 0;
    for (int i = 0; i < 8; i++)
        s->r[i] = sam_cpu_reg(m, UC_ARM_REG_R0 + i);
    uint32_t op = (uint32_t)m->flash[pc] | (uint32_t)m->flash[pc + 1] << 8;
    uint32_t rn = (op >> 3) & 7u, rt = op & 7u, rm = (op >> 6) & 7u, imm = (op >> 6) & 31u;
    const uint32_t *r = s->r;
    s->list = 0;
    if ((op & 0xF800) == 0x6000) { s->addr = r[rn] + imm * 4u; s->size = 4; }            /* STR imm */
    else if ((op & 0xF800) == 0x8000) { s->addr = r[rn] + imm * 2u; s->size = 2; }       /* STRH imm */
    else if ((op & 0xF800) == 0x7000) { s->addr = r[rn] + imm; s->size = 1; }            /* STRB imm */
    else if ((op & 0xFE00) == 0x5000) { s->addr = r[rn] + r[rm]; s->size = 4; }          /* STR reg */
    else if ((op & 0xFE00) == 0x5200) { s->addr = r[rn] + r[rm]; s->size = 2; }          /* STRH reg */
    else if ((op & 0xFE00) == 0x5400) { s->addr = r[rn] + r[rm]; s->size = 1; }          /* STRB reg */
    else if ((op & 0xF800) == 0xC000) {                                                   /* STMIA */
        rn = (op >> 8) & 7u;
        s->addr = r[rn];
        s->size = 4;
        s->list = op & 0xFFu;
    } else
        return 0;
    s->rn = rn;
    s->val = s->size == 4 ? r[rt] : r[rt] & ((1u << (8 * s->size)) - 1u);
    return 1;
}

void sam_cpu_bus_error(sam_mcu_t *m, uint32_t pc, const char *what)
{
    sam_cpu_resume_after(m, pc + 2u);
    hardfault(m, pc, what);
}

/* ---------------------------------------------------------------- set-up */

/* uc_hook_add takes its callback as void *, a conversion ISO C does not define for function pointers: the
 * pointer's bytes are copied instead (the platforms Unicorn runs on give both the same representation). */
typedef void (*any_fn)(void);
static void *hook_fn(any_fn f)
{
    void *p;
    _Static_assert(sizeof(void *) == sizeof(any_fn), "function and object pointers differ in size");
    memcpy(&p, &f, sizeof p);
    return p;
}

int sam_cpu_open(sam_mcu_t *m)
{
    uc_err ue;
    /* not UC_MODE_MCLASS: with it Unicorn 2.1.4 builds a Cortex-M33 whatever model is set below (ARMv8-M: Thumb-2,
     * unaligned accesses, the security extension's checks at every return); the Cortex-M0 model is ARMv6-M, as the
     * SAMD21's M0+ (tests/host_emulator/image/peripherals/test_core_faults.py) */
    if ((ue = uc_open(UC_ARCH_ARM, UC_MODE_THUMB, &m->uc)) != UC_ERR_OK)
        return sam_init_fail(m, "uc_open", ue);
    if ((ue = uc_ctl_set_cpu_model(m->uc, UC_CPU_ARM_CORTEX_M0)) != UC_ERR_OK)
        return sam_init_fail(m, "the Cortex-M0 CPU model", ue);
    if ((ue = uc_mem_map_ptr(m->uc, 0, SAM_FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, m->flash)) ||
        (ue = uc_mem_map_ptr(m->uc, SAM_RAM_BASE, SAM_RAM_SIZE, UC_PROT_READ | UC_PROT_WRITE, m->ram)) ||
        (ue = uc_mem_map_ptr(m->uc, SAM_NVM_BASE, SAM_NVM_SIZE, UC_PROT_READ, m->nvm)))
        return sam_init_fail(m, "mapping flash, SRAM and the NVM rows", ue);
    return 0;
}

int sam_cpu_hooks(sam_mcu_t *m)
{
    uc_err ue;
    if ((ue = uc_hook_add(m->uc, &m->hooks[0], UC_HOOK_BLOCK, hook_fn((any_fn)hook_block), m, 0, SAM_FLASH_SIZE - 1)))
        return sam_init_fail(m, "the block hook", ue);
    if ((ue = uc_hook_add(m->uc, &m->hooks[1], UC_HOOK_INTR, hook_fn((any_fn)hook_intr), m, 1, 0)))
        return sam_init_fail(m, "the exception hook", ue);
    /* Memory fault hooks everywhere but SRAM: Unicorn sends every store to a page a memory hook covers down its
     * slow path. SRAM cannot fault but for a fetch (it is mapped without execute: code there has no cycle model),
     * which the run loop reports. */
    if ((ue = uc_hook_add(m->uc, &m->hooks[2], UC_HOOK_MEM_UNMAPPED | UC_HOOK_MEM_PROT, hook_fn((any_fn)hook_badmem),
                          m, 0, SAM_RAM_BASE - 1)) ||
        (ue = uc_hook_add(m->uc, &m->hooks[3], UC_HOOK_MEM_UNMAPPED | UC_HOOK_MEM_PROT, hook_fn((any_fn)hook_badmem),
                          m, SAM_RAM_BASE + SAM_RAM_SIZE, 0xFFFFFFFFu)))
        return sam_init_fail(m, "the memory fault hook", ue);
    if ((ue = uc_ctl_tlb_mode(m->uc, UC_TLB_VIRTUAL)) != UC_ERR_OK ||
        (ue = uc_hook_add(m->uc, &m->hooks[4], UC_HOOK_TLB_FILL, hook_fn((any_fn)hook_tlb), m, 1, 0)) != UC_ERR_OK)
        return sam_init_fail(m, "the TLB", ue);
    if ((ue = uc_ctl_exits_enable(m->uc)) != UC_ERR_OK)
        return sam_init_fail(m, "exits mode", ue);
    return 0;
}
