/* PAC: peripheral access control, stored; setting write protection is an error (the images never do). */
#include <string.h>
#include "sam.h"

static int pac_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    if (!strcmp(sam_regs[ri].name + strlen(sam_periphs[pi].name) + 1, "WPSET") && (v & mask)) {
        sam_fail(m, "peripheral write protection (%s = 0x%x) is not modelled", sam_regs[ri].name, v & mask);
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

const sam_model_t sam_model_pac = {"Pac", NULL, NULL, NULL, pac_write, NULL};
