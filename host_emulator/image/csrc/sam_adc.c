/* ADC: configuration stored as the Arduino core's init() writes it; a conversion or an interrupt is an error. */
#include "sam.h"
#include "sam_vendor_gen.h"

/* The Arduino core configures the ADC in init() and the images never convert: its configuration registers are
 * stored; a conversion start or an interrupt enable is an error naming it. */
static int adc_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    if (sam_regs[ri].offset == ADC_STATUS_OFFSET) {
        *v = 0;
        return SAM_DONE;
    }
    if (sam_regs[ri].offset == ADC_RESULT_OFFSET)
        return SAM_UNCOVERED;
    return SAM_GENERIC;
}

static int adc_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset;
    if ((off == ADC_SWTRIG_OFFSET || off == ADC_INTENSET_OFFSET) && (v & mask)) {
        sam_fail(m, "ADC conversions are not modelled (%s = 0x%x)", sam_regs[ri].name, v & mask);
        return SAM_DONE;
    }
    if (off == ADC_CTRLA_OFFSET && (v & mask & ADC_CTRLA_ENABLE)) {
        sam_fail(m, "the ADC enabled: conversions are not modelled");
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

const sam_model_t sam_model_adc = {"Adc", NULL, NULL, adc_read, adc_write, NULL};
