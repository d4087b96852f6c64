/* NVMCTRL: flash wait states and cache, and flash programming (page buffer, erase row, write page, lock and BOOTPROT). */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

/*
 * Programming (DS40001882, the NVMCTRL chapter, "NVM Write", "Page Buffer Clear", "Erase Row", "Lock Bits",
 * "Register Description"):
 * - Flash is written only through the controller. A CPU store to a flash address loads the 64-byte page buffer
 *   (16- or 32-bit stores; an 8-bit store is not allowed and causes a system exception: a HardFault here) and
 *   stores its address in ADDR (in 16-bit words); with CTRLB.MANW = 0 a store to the last location of a page
 *   writes the page (automatic page write). STATUS.LOAD tells the buffer was loaded.
 * - Commands by CTRLA with the key CMDEX = 0xA5 (another key: STATUS.PROGE): ER erases the row (256 bytes) at
 *   ADDR to 0xFF, WP programs the page at ADDR from the buffer (programming only clears bits: the page ANDs the
 *   buffer), then clears the buffer; PBC clears the buffer. A row in a locked region (LOCK bit 0) or in the
 *   bootloader section BOOTPROT protects is left as it is and STATUS.LOCKE is set. PROGE, LOCKE and NVME set
 *   INTFLAG.ERROR; they and ERROR are cleared by writing ones. The other commands (EAR, WAP, SF, WL, LR, UR, SPRM,
 *   CPRM, SSB, INVALL) and NVMCTRL interrupts are not modelled: an error naming them.
 * - LOCK and BOOTPROT are read from the NVM user row at reset (sam_nvm_load_fuses).
 * - Time: the CPU fetches from the flash being programmed, so it stalls until the NVM is ready; the board's clock
 *   moves on by the programming time at the command and INTFLAG.READY always reads 1. The times are TYPICAL
 *   values, not the datasheet's maxima (row erase 6 ms, page write 2.5 ms, "NVM Characteristics"): a public bossac
 *   log on a 64 KiB SAM R21 (same NVM) erased 224 rows in 0.190 s and wrote 60 pages in 0.023 s.
 */
#define NVM_T_ROW_ERASE_TYPICAL_S 0.85e-3
#define NVM_T_PAGE_WRITE_TYPICAL_S 0.35e-3
#define NVM_PAGE 64u
#define NVM_ROW 256u
#define NVM_KEY 0xA5u
#define NVM_REGION (SAM_FLASH_SIZE / 16u)   /* 16 lock regions */

typedef struct {
    uint8_t pb[NVM_PAGE];   /* the page buffer */
    uint16_t status;        /* STATUS: LOAD, PROGE, LOCKE, NVME */
    uint8_t error;          /* INTFLAG.ERROR */
    uint32_t boot_bytes;    /* flash the bootloader section protects (BOOTPROT) */
} nvm_t;

static uint32_t field_get(uint32_t v, uint32_t pos, uint32_t width) { return (v >> pos) & ((1u << width) - 1u); }

static uint32_t cpu_reg(sam_mcu_t *m, int id)
{
    uint32_t v = 0;
    uc_reg_read(m->uc, id, &v);
    return v;
}

static nvm_t *st(sam_mcu_t *m) { return m->pst[sam_idx.nvmctrl]; }
static int reg(const char *name) { return sam_reg_index(sam_idx.nvmctrl, name); }

/* BOOTPROT (user row bits 2:0) -> bytes protected (DS40001882 "Boot Loader Size") */
static const uint32_t BOOTPROT_BYTES[8] = {0x8000, 0x4000, 0x2000, 0x1000, 0x800, 0x400, 0x200, 0};

void sam_nvm_load_fuses(sam_mcu_t *m)
{
    nvm_t *n = st(m);
    if (!n)
        return;
    const uint8_t *user = m->nvm + (SAM_NVM_USER_ROW - SAM_NVM_BASE);
    n->boot_bytes = BOOTPROT_BYTES[user[0] & 7u];
    sam_reg_put(m, reg("LOCK"), (uint32_t)user[6] | (uint32_t)user[7] << 8);   /* user row bits 63:48 */
}

static void nvm_error(sam_mcu_t *m, uint16_t flag, const char *why, uint32_t addr)
{
    nvm_t *n = st(m);
    n->status |= flag;
    n->error = 1;
    sam_activity(m);
    sam_note(m, "%s: NVMCTRL %s at 0x%05x (STATUS 0x%x) at t = %.6f s", m->name, why, addr, n->status,
             (double)m->t / (double)SAM_TU_HZ);
}

/* 1 when the row/page at addr may be changed; else LOCKE */
static int nvm_writable(sam_mcu_t *m, uint32_t addr)
{
    if (addr < st(m)->boot_bytes) {
        nvm_error(m, NVMCTRL_STATUS_LOCKE, "command on the bootloader section (BOOTPROT) refused", addr);
        return 0;
    }
    if (!(sam_reg_get(m, reg("LOCK")) >> (addr / NVM_REGION) & 1u)) {
        nvm_error(m, NVMCTRL_STATUS_LOCKE, "command on a locked region refused", addr);
        return 0;
    }
    return 1;
}

static void nvm_stall(sam_mcu_t *m, double s) { m->t += (uint64_t)(s * (double)SAM_TU_HZ); }

static void buffer_clear(nvm_t *n)
{
    memset(n->pb, 0xFF, NVM_PAGE);
    n->status &= (uint16_t)~NVMCTRL_STATUS_LOAD;
}

static void write_page(sam_mcu_t *m, uint32_t addr)
{
    nvm_t *n = st(m);
    uint32_t page = addr & ~(NVM_PAGE - 1u);
    if (!nvm_writable(m, page))
        return;
    for (uint32_t k = 0; k < NVM_PAGE; k++)
        m->flash[page + k] &= n->pb[k];
    buffer_clear(n);
    m->nvm_writes++;
    sam_cpu_flash_changed(m, page, NVM_PAGE);
    nvm_stall(m, NVM_T_PAGE_WRITE_TYPICAL_S);
}

static void erase_row(sam_mcu_t *m, uint32_t addr)
{
    uint32_t row = addr & ~(NVM_ROW - 1u);
    if (!nvm_writable(m, row))
        return;
    memset(m->flash + row, 0xFF, NVM_ROW);
    m->nvm_erases++;
    sam_cpu_flash_changed(m, row, NVM_ROW);
    nvm_stall(m, NVM_T_ROW_ERASE_TYPICAL_S);
}

static void command(sam_mcu_t *m, uint32_t v)
{
    uint32_t cmd = v & 0x7Fu, key = (v >> 8) & 0xFFu;
    uint32_t addr = (sam_reg_get(m, reg("ADDR")) & 0x3FFFFFu) * 2u;
    sam_activity(m);
    if (key != NVM_KEY) {
        nvm_error(m, NVMCTRL_STATUS_PROGE, "command without the key (CMDEX != 0xA5)", addr);
        return;
    }
    switch (cmd) {
    case NVMCTRL_CTRLA_CMD_ER_Val:
    case NVMCTRL_CTRLA_CMD_WP_Val:
        if (addr >= SAM_FLASH_SIZE) {
            nvm_error(m, NVMCTRL_STATUS_PROGE, "erase or write outside the main array", addr);
            return;
        }
        if (cmd == NVMCTRL_CTRLA_CMD_ER_Val)
            erase_row(m, addr);
        else
            write_page(m, addr);
        return;
    case NVMCTRL_CTRLA_CMD_PBC_Val: buffer_clear(st(m)); return;
    case NVMCTRL_CTRLA_CMD_EAR_Val:
    case NVMCTRL_CTRLA_CMD_WAP_Val:
    case NVMCTRL_CTRLA_CMD_SF_Val:
    case NVMCTRL_CTRLA_CMD_WL_Val:
    case NVMCTRL_CTRLA_CMD_LR_Val:
    case NVMCTRL_CTRLA_CMD_UR_Val:
    case NVMCTRL_CTRLA_CMD_SPRM_Val:
    case NVMCTRL_CTRLA_CMD_CPRM_Val:
    case NVMCTRL_CTRLA_CMD_SSB_Val:
    case NVMCTRL_CTRLA_CMD_INVALL_Val:
        sam_fail(m, "NVM command 0x%x is not modelled (only ER, WP and PBC)", cmd);
        return;
    default: nvm_error(m, NVMCTRL_STATUS_PROGE, "invalid command", addr); return;
    }
}

/* A store of `size` bytes to flash address addr by the CPU: into the page buffer. 0: not allowed (a fault). */
static int buffer_store(sam_mcu_t *m, uint32_t addr, uint32_t size, uint32_t val)
{
    nvm_t *n = st(m);
    if (size == 1 || (addr & (size - 1u)) || addr > SAM_FLASH_SIZE - size)
        return 0;
    uint32_t off = addr & (NVM_PAGE - 1u);
    for (uint32_t k = 0; k < size; k++)
        n->pb[off + k] = (uint8_t)(val >> (8 * k));
    n->status |= NVMCTRL_STATUS_LOAD;
    sam_reg_put(m, reg("ADDR"), addr >> 1);
    if (!(sam_reg_get(m, reg("CTRLB")) & NVMCTRL_CTRLB_MANW) && off + size == NVM_PAGE)
        write_page(m, addr);   /* automatic page write: the last location of the page was written */
    return 1;
}

/*
 * The CPU stored to flash (Unicorn stopped at the store: flash is mapped read/execute). The store at PC is decoded
 * (STR/STRH immediate and register, STMIA) and goes to the page buffer; execution resumes after it. 1: done; 0: not
 * a store to flash the page buffer takes (an 8-bit or unaligned store): the caller raises the fault.
 */
int sam_nvm_cpu_store(sam_mcu_t *m)
{
    uint32_t pc = cpu_reg(m, UC_ARM_REG_PC) & ~1u;
    sam_store_t s;
    if (!st(m) || !sam_cpu_decode_store(m, pc, &s) || s.addr >= SAM_FLASH_SIZE)
        return 0;
    if (!s.list) {
        if (!buffer_store(m, s.addr, s.size, s.val))
            return 0;
    } else {
        uint32_t addr = s.addr;
        for (int k = 0; k < 8; k++)
            if (s.list >> k & 1u) {
                if (!buffer_store(m, addr, 4, s.r[k]))
                    return 0;
                addr += 4;
            }
        if (!(s.list >> s.rn & 1u))
            uc_reg_write(m->uc, UC_ARM_REG_R0 + (int)s.rn, &addr);   /* write-back */
    }
    sam_cpu_resume_after(m, pc + 2u);
    sam_activity(m);
    return 1;
}

static int nvm_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)pi;
    nvm_t *n = st(m);
    switch (sam_regs[ri].offset) {
    case NVMCTRL_PARAM_OFFSET: *v = NVMCTRL_PARAM_NVMP(4096) | NVMCTRL_PARAM_PSZ(3); return SAM_DONE;   /* 256 KiB */
    case NVMCTRL_INTFLAG_OFFSET: *v = NVMCTRL_INTFLAG_READY | (n->error ? NVMCTRL_INTFLAG_ERROR : 0u); return SAM_DONE;
    case NVMCTRL_STATUS_OFFSET: *v = n->status; return SAM_DONE;
    default: return SAM_GENERIC;
    }
}

static int nvm_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    nvm_t *n = st(m);
    uint32_t off = sam_regs[ri].offset;
    if (off == NVMCTRL_CTRLA_OFFSET) {
        if (v & mask)
            command(m, v & mask);
        return SAM_DONE;
    }
    if (off == NVMCTRL_STATUS_OFFSET) {   /* PROGE, LOCKE, NVME: write one to clear */
        uint16_t clr = (uint16_t)(v & mask & (NVMCTRL_STATUS_PROGE | NVMCTRL_STATUS_LOCKE | NVMCTRL_STATUS_NVME));
        if (n->status & clr)
            sam_activity(m);
        n->status &= (uint16_t)~clr;
        return SAM_DONE;
    }
    if (off == NVMCTRL_INTFLAG_OFFSET) {   /* ERROR: write one to clear; READY is read-only */
        if ((v & mask & NVMCTRL_INTFLAG_ERROR) && n->error) {
            n->error = 0;
            sam_activity(m);
        }
        return SAM_DONE;
    }
    if (off == NVMCTRL_LOCK_OFFSET)
        return SAM_UNCOVERED;   /* the lock bits change through LR/UR (not modelled) */
    if (off == NVMCTRL_CTRLB_OFFSET) {
        sam_reg_put(m, ri, (sam_reg_get(m, ri) & ~mask) | (v & mask));
        m->rws = field_get(sam_reg_get(m, ri), NVMCTRL_CTRLB_RWS_Pos, 4);
        if (sam_reg_get(m, ri) & NVMCTRL_CTRLB_CACHEDIS)
            sam_fail(m, "NVMCTRL.CTRLB.CACHEDIS: running without the NVM cache is not modelled");
        sam_activity(m);
        return SAM_DONE;
    }
    if (off == NVMCTRL_INTENSET_OFFSET && (v & mask)) {
        sam_fail(m, "NVMCTRL interrupts are not modelled");
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static void nvm_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(nvm_t));
    nvm_t *n = m->pst[pi];
    if (!n) {
        sam_fail(m, "NVMCTRL: out of memory");
        return;
    }
    memset(n, 0, sizeof *n);
    buffer_clear(n);
    m->rws = 0;
    sam_nvm_load_fuses(m);
}

const sam_model_t sam_model_nvmctrl = {"Nvmctrl", nvm_reset, NULL, nvm_read, nvm_write, NULL};
