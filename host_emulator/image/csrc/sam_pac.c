/* PAC: peripheral write protection (WPSET/WPCLR of PAC0..2): a store to a protected peripheral takes a bus error. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

/*
 * DS40001882 11.6 "PAC - Peripheral Access Controller" (11.6.1 Functional Description, 11.6.2 Register
 * Description), with every number from the vendor's headers:
 * - Each APB bridge has a PAC at its base (PAC0 on bridge A, PAC1 on B, PAC2 on C). Bit n of its mask protects the
 *   peripheral whose ID_<name> (samd21g18a.h) is 32 x bridge + n: the generated table's sam_periph_t.pac. Bit 0 is
 *   the PAC itself and is reserved (PAC_WPSET_WP_Msk: the WP field is bits 31:1): a PAC's own registers are never
 *   write-protected, a one written there is ignored.
 * - Writing one to a bit of WPSET sets the protection, of WPCLR clears it; both read the mask (the generic layer:
 *   WPCLR is the CLR alias of WPSET, which holds it). The reset masks are PACn_WPROT_DEFAULT_VAL (instance/pacN.h):
 *   PAC1's has bit 1 set, so the DSU is protected from reset; PAC2's sets bit 23, no peripheral of this part.
 * - A write to a protected peripheral is not done and the CPU takes an access error, a bus error: HardFault here,
 *   at the store, which is stacked as the return address. Reads are not affected.
 * - A one written to a bit of WPSET that is already set, or of WPCLR that is already clear (double protection or
 *   double unprotection), is an error too: the store takes a bus error. The datasheet does not say whether the
 *   other bits of such a write take effect: here none does (the write is refused whole).
 * How: the CPU's TLB hook (sam_cpu.c) gives the 1 KiB pages (Unicorn's for the Cortex-M0) of the protected
 * peripherals, and those of the PACs themselves, read only (board->wp_pages, one 64-bit mask per bridge). A store
 * there is refused by the TLB fill: Unicorn stops with UC_ERR_EXCEPTION, PC at the store, no address (the memory
 * fault hooks are not called), as for a store to flash. The run loop then calls sam_pac_store, which decodes the
 * store: one to a PAC is carried out through the register layer and execution resumes after it, the TLB flushed
 * when the mask changed, so the very next instruction, in the same block or not, sees the new protection; one to a
 * protected peripheral enters HardFault. A PAC write thus stops the CPU once (none of the shipped images writes a
 * PAC); SRAM, flash and unprotected peripherals keep their permissions. Not modelled: the registers the datasheet
 * exempts from PAC protection in some peripherals' chapters (their "PAC Write-Protection" property, not in the
 * headers) are protected like the others here; the IOBUS door to PORT (0x60000000) does not pass the APB bridge
 * and is never refused.
 */

enum { NBRIDGE = 3 };
static const uint32_t BRIDGE_BASE[NBRIDGE] = {0x40000000u, 0x41000000u, 0x42000000u};
static const uint32_t WPROT_RESET[NBRIDGE] = {PAC0_WPROT_DEFAULT_VAL, PAC1_WPROT_DEFAULT_VAL, PAC2_WPROT_DEFAULT_VAL};

typedef struct {
    uint32_t again;   /* the bits the last write set again (WPSET) or cleared again (WPCLR): a bus error */
} pac_t;

static uint32_t cpu_pc(sam_mcu_t *m)
{
    uint32_t v = 0;
    uc_reg_read(m->uc, UC_ARM_REG_PC, &v);
    return v & ~1u;
}

static int bridge_of(int pi) { return sam_periphs[pi].pac / 32; }

/* WPSET's storage: the mask of the PAC of bridge b, or 0 when the table has no such PAC */
static uint32_t mask_of(sam_mcu_t *m, int b)
{
    for (unsigned pi = 0; pi < sam_nperiphs; pi++)
        if (sam_periphs[pi].pac == 32 * b)
            return sam_reg_get(m, sam_reg_index((int)pi, "WPSET"));
    return 0;
}

/* The pages a store to stops the CPU: every protected peripheral's and each PAC's own; the TLB is flushed when they
 * changed, so that no translation made with the old permissions is used again. */
static void pac_pages(sam_mcu_t *m)
{
    uint64_t pages[NBRIDGE] = {0};
    uint32_t mask[NBRIDGE];
    for (int b = 0; b < NBRIDGE; b++)
        mask[b] = mask_of(m, b);
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        if (p->pac < 0 || p->pac >= 32 * NBRIDGE || (p->pac % 32 && !(mask[p->pac / 32] >> (p->pac % 32) & 1u)))
            continue;
        int b = p->pac / 32;
        for (uint32_t a = p->base & ~0x3FFu; a < p->base + p->size; a += 0x400u)
            pages[b] |= 1ull << ((a - BRIDGE_BASE[b]) >> 10);
    }
    if (memcmp(pages, m->wp_pages, sizeof pages)) {
        memcpy(m->wp_pages, pages, sizeof pages);
        uc_ctl_flush_tlb(m->uc);
    }
}

static void pac_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(pac_t));
    if (m->pst[pi])
        memset(m->pst[pi], 0, sizeof(pac_t));
    sam_reg_put(m, sam_reg_index(pi, "WPSET"), WPROT_RESET[bridge_of(pi)] & PAC_WPSET_WP_Msk);
    pac_pages(m);
}

static int pac_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    pac_t *s = m->pst[pi];
    int hold = sam_regs[ri].alias;   /* WPSET, for both */
    int set = sam_regs[ri].offset == PAC_WPSET_OFFSET;
    uint32_t old = sam_reg_get(m, hold), bits = v & mask & PAC_WPSET_WP_Msk;
    uint32_t again = set ? bits & old : bits & ~old;
    if (again) {
        if (s)
            s->again = again;
        return SAM_DONE;
    }
    uint32_t nv = set ? old | bits : old & ~bits;
    if (nv != old) {
        sam_reg_put(m, hold, nv);
        sam_activity(m);
        pac_pages(m);
    }
    return SAM_DONE;
}

/* the instance whose window holds addr, or -1 */
static int periph_at(uint32_t addr)
{
    for (unsigned pi = 0; pi < sam_nperiphs; pi++)
        if (addr - sam_periphs[pi].base < (sam_periphs[pi].size + 0x3FFu) / 0x400u * 0x400u)
            return (int)pi;
    return -1;
}

/* the name of peripheral ID n (a PAC's bit), or NULL */
static const char *name_of_id(int id)
{
    for (unsigned pi = 0; pi < sam_nperiphs; pi++)
        if (sam_periphs[pi].pac == id)
            return sam_periphs[pi].name;
    return NULL;
}

/* The first address of the store *st on a page the PAC traps (the TLB refused it: Unicorn reports no address), or 0 */
static uint32_t trapped_address(const sam_mcu_t *m, const sam_store_t *st)
{
    uint32_t n = st->list ? 0 : 1;   /* the words it stores */
    for (int k = 0; k < 8; k++)
        n += st->list >> k & 1u;
    for (uint32_t k = 0; k < n; k++)
        if (sam_pac_trapped(m, st->addr + 4u * k))
            return st->addr + 4u * k;
    return 0;
}

int sam_pac_store(sam_mcu_t *m)
{
    uint32_t pc = cpu_pc(m), a;
    sam_store_t st;
    int pi;
    if (!sam_cpu_decode_store(m, pc, &st) || !(a = trapped_address(m, &st)) || (pi = periph_at(a)) < 0 ||
        sam_periphs[pi].pac < 0)
        return 0;
    m->fault_addr = a;
    const sam_periph_t *p = &sam_periphs[pi];
    char what[160];
    if (p->pac % 32) {   /* a protected peripheral */
        snprintf(what, sizeof what, "bus error: write to %s + 0x%x, write-protected by PAC%d", p->name, a - p->base,
                 p->pac / 32);
        sam_cpu_bus_error(m, pc, what);
        return 1;
    }
    if (st.list) {
        sam_fail(m, "STMIA to %s: not modelled (only STR, STRH and STRB)", p->name);
        return 1;
    }
    pac_t *s = m->pst[pi];
    if (s)
        s->again = 0;
    if (sam_mmio_store(m, st.addr, st.size, st.val))
        return 1;   /* an error (sam_fail) */
    if (s && s->again) {
        int bit = 0;
        while (!(s->again >> bit & 1u))
            bit++;
        const char *n = name_of_id(p->pac + bit);
        int set = st.addr - p->base >= PAC_WPSET_OFFSET;
        snprintf(what, sizeof what, "bus error: %s.%s of bit %d (%s), already %s", p->name, set ? "WPSET" : "WPCLR",
                 bit, n ? n : "no peripheral", set ? "set" : "clear");
        s->again = 0;
        sam_cpu_bus_error(m, pc, what);
        return 1;
    }
    sam_cpu_resume_after(m, pc + 2u);
    return 1;
}

const sam_model_t sam_model_pac = {"Pac", pac_reset, NULL, NULL, pac_write, NULL};
