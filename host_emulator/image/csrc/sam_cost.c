/* A translated block's cycle cost: from the ELF's tables where they hold, else decoded from the flash bytes. */
#include <string.h>
#include "sam_core.h"

/* One row of the cycle model's decode table (costtable.py): the encodings hw1 << 16 | hw2 with (key & mask) ==
 * value cost core (+ one per register of r0-r7 in the first halfword's low byte with SAM_COST_REGLIST) cycles,
 * wait waited flash accesses in the worst-case model, lit PC-relative loads, and refund (low nibble core, high
 * nibble waits) when a conditional branch falls through; SAM_COST_UNSUPPORTED: the model has no time for it. */
typedef struct {
    uint32_t mask, value;
    uint8_t core, wait, lit, refund, flags;
    const char *text;
} sam_cost_row_t;
#define SAM_COST_REGLIST 1u
#define SAM_COST_UNSUPPORTED 2u
#define SAM_COST_WIDE 4u          /* a 32-bit instruction's row */
#define SAM_COST_UNDEFINED_ROW 8u /* these encodings are not ARMv6-M instructions */
#include "sam_cost_gen.h"   /* generated into the build directory (runtime.py) */

static unsigned popcount8(unsigned v)
{
    unsigned n = 0;
    for (; v; v &= v - 1)
        n++;
    return n;
}

int sam_cost_insn(uint16_t hw1, uint16_t hw2, sam_insn_cost_t *out)
{
    int wide = (hw1 >> 11) >= 0x1Du;
    uint32_t key = (uint32_t)hw1 << 16 | (wide ? hw2 : 0u);
    memset(out, 0, sizeof *out);
    out->size = wide ? 4 : 2;
    for (int k = 0; k < SAM_COST_NROWS; k++) {
        const sam_cost_row_t *r = &sam_cost_rows[k];
        if ((key & r->mask) != r->value || wide != !!(r->flags & SAM_COST_WIDE))
            continue;
        if (r->flags & SAM_COST_UNDEFINED_ROW)
            break;
        out->core = (uint8_t)(r->core + (r->flags & SAM_COST_REGLIST ? popcount8(hw1 & 0xFFu) : 0u));
        out->wait = r->wait;
        out->lit = r->lit;
        out->refund = r->refund;
        out->text = r->text;
        if (r->flags & SAM_COST_UNSUPPORTED) {
            out->status = SAM_COST_NO_TIME;
            return 1;
        }
        return 0;
    }
    out->status = SAM_COST_UNDEFINED;
    out->text = "an encoding ARMv6-M does not define";
    return -1;
}

/* The board stops for good (a reset ends it) when it would run code the model cannot time. */
static void halt_untimed(sam_mcu_t *m, uint32_t a, const sam_insn_cost_t *ic)
{
    if (!m->lockup)
        sam_note(m, "%s: halted at t = %.6f s: no cycle model for `%s` at 0x%05x; only a reset ends it", m->name,
                 (double)m->t / (double)SAM_TU_HZ, ic->text, a);
    m->lockup = 1;
    uc_emu_stop(m->uc);
}

/* The cost of the instructions in [addr, end) into *bc: the ELF's tables where they hold them, else decoded from the
 * flash bytes as they are now; -1 (and *bad, at) when an instruction there has no time in the model. */
static int cost_span(const sam_mcu_t *m, uint32_t addr, uint32_t end, sam_blkcost_t *bc, sam_insn_cost_t *bad,
                     uint32_t *at)
{
    if (end < addr || end > SAM_FLASH_SIZE) {   /* a block outside the flash (the hooks cover only the flash) */
        bad->text = "a block outside the flash";
        *at = addr;
        return -1;
    }
    bc->addr = addr;
    bc->size = (uint16_t)(end - addr);
    if (m->cost_core && addr >= m->tab_lo && end <= m->app_end) {
        /* the ELF's tables: prefix sums over the halfwords */
        uint32_t h0 = addr >> 1, h1 = end >> 1;
        bc->core = m->cost_core[h1] - m->cost_core[h0];
        bc->wait = (uint16_t)(m->cost_wait[h1] - m->cost_wait[h0]);
        bc->lit = (uint16_t)(m->cost_lit[h1] - m->cost_lit[h0]);
        bc->refund = m->refund[h1 - 1];
        return 0;
    }
    uint32_t core = 0, wait = 0, lit = 0;
    uint8_t refund = 0;
    sam_insn_cost_t ic;
    for (uint32_t a = addr; a < end; a += ic.size) {
        if (end - a < 2) {
            bad->text = "an instruction across the block's end";
            *at = a;
            return -1;
        }
        uint16_t hw1 = (uint16_t)(m->flash[a] | m->flash[a + 1] << 8), hw2 = 0;
        if (SAM_FLASH_SIZE - a >= 4)
            hw2 = (uint16_t)(m->flash[a + 2] | m->flash[a + 3] << 8);
        if (sam_cost_insn(hw1, hw2, &ic) || ic.size > end - a) {
            if (ic.size > end - a)
                ic.text = "an instruction across the block's end";
            *bad = ic;
            *at = a;
            return -1;
        }
        core += ic.core;
        wait += ic.wait;
        lit += ic.lit;
        refund = ic.refund;
    }
    bc->core = core;
    bc->wait = (uint16_t)wait;
    bc->lit = (uint16_t)lit;
    bc->refund = refund;
    return 0;
}

int sam_cost_block(sam_mcu_t *m, uint32_t addr, uint32_t size, sam_blkcost_t *bc)
{
    sam_insn_cost_t bad;
    uint32_t at;
    if (cost_span(m, addr, addr + size, bc, &bad, &at) == 0)
        return 0;
    bc->addr = 0;
    bc->size = 0;
    halt_untimed(m, at, &bad);
    return -1;
}

uint64_t sam_cost_tail(const sam_mcu_t *m, uint32_t pc, uint32_t end)
{
    sam_blkcost_t bc;
    sam_insn_cost_t bad;
    uint32_t at;
    if (pc >= end || end > SAM_FLASH_SIZE || cost_span(m, pc, end, &bc, &bad, &at))
        return 0;
    return bc.core + (uint64_t)m->rws * (m->cycle_model == SAM_CYCLES_WORST ? bc.wait : bc.lit);
}

void sam_cost_flash_written(sam_mcu_t *m, uint32_t addr, uint32_t len)
{
    uint32_t end = addr + len;
    /* the ELF's tables describe what was loaded: once its code is rewritten, the decoder costs all of it */
    if (m->cost_core && addr < m->app_end && end > m->tab_lo)
        m->cost_core = NULL;
    for (int k = 0; k < SAM_MEMO; k++) {
        sam_blkcost_t *bc = &m->memo[k];
        if (bc->size && bc->addr < end && bc->addr + bc->size > addr) {
            bc->addr = 0;
            bc->size = 0;
        }
    }
}
