/* NVMCTRL: flash wait states (CTRLB.RWS, which the cycle model charges), the cache, and the controller's status. */
#include "sam.h"
#include "sam_vendor_gen.h"

static uint32_t field_get(uint32_t v, uint32_t pos, uint32_t width) { return (v >> pos) & ((1u << width) - 1u); }

static int nvm_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    switch (sam_regs[ri].offset) {
    case NVMCTRL_PARAM_OFFSET: *v = NVMCTRL_PARAM_NVMP(4096) | NVMCTRL_PARAM_PSZ(3); return SAM_DONE;   /* 256 KiB */
    case NVMCTRL_INTFLAG_OFFSET: *v = NVMCTRL_INTFLAG_READY; return SAM_DONE;
    case NVMCTRL_STATUS_OFFSET: *v = 0; return SAM_DONE;
    default: return SAM_GENERIC;
    }
}

static int nvm_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset;
    if (off == NVMCTRL_CTRLA_OFFSET && (v & mask)) {
        sam_fail(m, "NVM command 0x%x: programming the flash is not modelled", v & 0x7Fu);
        return SAM_DONE;
    }
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
    (void)pi;
    m->rws = 0;
}

const sam_model_t sam_model_nvmctrl = {"Nvmctrl", nvm_reset, NULL, nvm_read, nvm_write, NULL};
