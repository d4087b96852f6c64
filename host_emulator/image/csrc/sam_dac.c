/* DAC: configuration stored as the Arduino core's init() writes it; enabling the output is an error. */
#include "sam.h"
#include "sam_vendor_gen.h"

static int dac_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    if (sam_regs[ri].offset == DAC_STATUS_OFFSET) {
        *v = 0;
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int dac_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset;
    if ((off == DAC_CTRLA_OFFSET && (v & mask & DAC_CTRLA_ENABLE)) || (off == DAC_INTENSET_OFFSET && (v & mask))) {
        sam_fail(m, "the DAC output is not modelled (%s = 0x%x)", sam_regs[ri].name, v & mask);
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

const sam_model_t sam_model_dac = {"Dac", NULL, NULL, dac_read, dac_write, NULL};
