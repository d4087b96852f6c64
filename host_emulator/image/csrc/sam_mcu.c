/* A board's life cycle: its memory, CPU and peripherals created and freed, resets (power-on, system, requested). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sam_core.h"
#include "sam_vendor_gen.h"

int sam_init_fail(sam_mcu_t *m, const char *what, uc_err e)
{
    snprintf(m->errmsg, sizeof m->errmsg, "creating the CPU: %s failed (%s)", what, uc_strerror(e));
    return -1;
}

int sam_mcu_init(sam_mcu_t *m, sam_world_t *w, int id)
{
    memset(m, 0, sizeof *m);
    m->w = w;
    m->id = id;
    snprintf(m->name, sizeof m->name, "board %d", id);
    if (sam_regtab_check(m->errmsg, sizeof m->errmsg))
        return -1;
    sam_index_init();
    m->flash = calloc(1, SAM_FLASH_SIZE);
    m->ram = calloc(1, SAM_RAM_SIZE);
    m->nvm = calloc(1, SAM_NVM_SIZE);
    m->ff.snap_ram = calloc(1, SAM_RAM_SIZE);
    m->cont_pc = 0xFFFFFFFFu;
    m->touch = calloc(2 * (size_t)sam_nregs, sizeof(uint32_t));
    m->notes = malloc(SAM_BOARD_NOTES);
    if (!m->flash || !m->ram || !m->nvm || !m->ff.snap_ram || !m->touch || !m->notes)
        return -1;
    if (sam_cpu_open(m))
        return -1;
    /* peripherals: storage, models, offset maps */
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        m->model[pi] = sam_model_for(p->type);
        if (!strcmp(p->name, "PORT_IOBUS")) {
            m->regs[pi] = m->regs[sam_idx.port];   /* the IOBUS is another door to the same registers */
        } else {
            m->regs[pi] = calloc(1, p->size + 4u);
            if (!m->regs[pi])
                return -1;
        }
        for (unsigned v = 0; v <= p->nviews && v < 5; v++) {
            m->omap[pi][v] = malloc(p->size * sizeof(int16_t));
            if (!m->omap[pi][v])
                return -1;
            for (unsigned o = 0; o < p->size; o++)
                m->omap[pi][v][o] = -1;
            for (unsigned ri = p->reg0; ri < p->reg1; ri++) {
                const sam_reg_t *r = &sam_regs[ri];
                if (r->view == 0 || r->view == v)
                    for (unsigned b = 0; b < r->size; b++)
                        m->omap[pi][v][r->offset + b] = (int16_t)ri;
            }
        }
    }
    if (sam_mmio_map(m) || sam_cpu_hooks(m))
        return -1;
    for (int s = 0; s < SAM_NSLOTS; s++)
        m->slot[s] = SAM_NEVER;
    m->slot_live = 0;
    m->next_ev = SAM_NEVER;
    return 0;
}

void sam_mcu_free(sam_mcu_t *m)
{
    if (m->uc)
        uc_close(m->uc);
    sam_mmio_free(m);
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        if ((int)pi != sam_idx.iobus)
            free(m->regs[pi]);
        free(m->pst[pi]);
        for (int v = 0; v < 5; v++)
            free(m->omap[pi][v]);
    }
    free(m->flash);
    free(m->ram);
    free(m->nvm);
    free(m->ff.snap_ram);
    free(m->touch);
    free(m->prof);
    free(m->notes);
}

/* Every peripheral to its reset state, the core to the application's entry (direct boot simulates the bootloader's
 * hand-off: VTOR at the application's vector table, SP and PC from it) or, with a bootloader loaded (m->boot), to
 * the reset vector at 0 as the chip does. RAM is kept (a power-on reset clears it first). */
void sam_do_reset(sam_mcu_t *m, uint8_t cause)
{
    m->t_blk = m->t;
    sam_world_pins_will_change(m);
    m->reset_cause = cause;
    m->resets++;
    m->lockup = 0;
    m->in_reset = 0;
    m->irq_check = m->primask_wait = 0;
    memset(&m->nvic, 0, sizeof m->nvic);
    memset(&m->systick, 0, sizeof m->systick);
    m->nvic.vtor = m->boot ? 0u : SAM_APP_BASE;
    for (int s = 0; s < SAM_SLOT_SOURCE0; s++)   /* the chip's events; the world's sources keep theirs */
        m->slot[s] = SAM_NEVER;
    m->slot_live &= ~((1ull << SAM_SLOT_SOURCE0) - 1u);
    sam_next_event(m);
    m->rws = 0;
    m->cyc_tu = (uint32_t)(SAM_TU_HZ / 1000000u);   /* GCLK0 = OSC8M / 8 = 1 MHz after reset */
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        if (strcmp(p->name, "PORT_IOBUS"))
            memset(m->regs[pi], 0, p->size);
        for (unsigned ri = p->reg0; ri < p->reg1; ri++)
            if (sam_regs[ri].reset && sam_regs[ri].kind == SAM_KIND_PLAIN)
                sam_reg_put(m, (int)ri, sam_regs[ri].reset);
    }
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        const sam_periph_t *p = &sam_periphs[pi];
        /* the default view's reset values win where views share an offset */
        int v = m->model[pi] && m->model[pi]->view ? m->model[pi]->view(m, (int)pi) : 0;
        for (unsigned ri = p->reg0; ri < p->reg1; ri++)
            if (sam_regs[ri].view == v && sam_regs[ri].kind == SAM_KIND_PLAIN)
                sam_reg_put(m, (int)ri, sam_regs[ri].reset);
        if (m->model[pi] && m->model[pi]->reset)
            m->model[pi]->reset(m, (int)pi);
    }
    uint32_t zero = 0, lr = 0xFFFFFFFFu;
    for (int i = 0; i < 13; i++)
        uc_reg_write(m->uc, sam_core_regs[i], &zero);
    sam_cpu_set(m, UC_ARM_REG_PRIMASK, 0);
    sam_cpu_set(m, UC_ARM_REG_CONTROL, 0);
    sam_cpu_set(m, UC_ARM_REG_IPSR, 0);
    sam_cpu_rebuild_hflags(m);
    sam_cpu_set(m, UC_ARM_REG_LR, lr);
    if (m->boot) {   /* from the vector table at 0, as the chip does: the bootloader starts the application */
        sam_cpu_set(m, UC_ARM_REG_SP, sam_mem_read32(m, 0, NULL));
        sam_cpu_set(m, UC_ARM_REG_PC, sam_mem_read32(m, 4, NULL) | 1u);
    } else {
        sam_cpu_set(m, UC_ARM_REG_SP, m->entry_sp);
        sam_cpu_set(m, UC_ARM_REG_PC, m->entry_pc | 1u);
    }
    m->prev_end = 0xFFFFFFFFu;
    m->cont_pc = 0xFFFFFFFFu;
    sam_ff_ram_written(m);   /* (a reset keeps SRAM, but ends what the protection's reference point was) */
    memset(m->cache_tag, 0, sizeof m->cache_tag);
    m->ff.snap_valid = 0;
    m->ff.regs_valid = 0;
    m->ff.parked = 0;
    m->ff.resumed = 0;
    m->ff.head = m->ff.loop_pc;
    m->ff.horizon = SAM_NEVER;
    m->act++;
    sam_world_pins_changed(m);
}

void sam_mcu_power_on_reset(sam_mcu_t *m)
{
    memset(m->ram, 0, SAM_RAM_SIZE);
    m->halted = 0;
    sam_do_reset(m, PM_RCAUSE_POR);
}

void sam_request_reset(sam_mcu_t *m, uint8_t cause)
{
    m->in_reset = 0x100 | cause;
    uc_emu_stop(m->uc);
}

void sam_mcu_system_reset(sam_mcu_t *m, uint8_t cause) { sam_request_reset(m, cause); }
