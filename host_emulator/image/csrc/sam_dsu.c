/* DSU: only the device identification (DID) is read, a SAMD21G18A's; anything else is an error. */
#include <string.h>
#include "sam.h"

static int dsu_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    if (!strcmp(sam_regs[ri].name + strlen(sam_periphs[pi].name) + 1, "DID")) {
        *v = 0x10010305u;
        return SAM_DONE;
    }
    return SAM_UNCOVERED;
}

static int dsu_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)m;
    (void)pi;
    (void)ri;
    (void)v;
    (void)mask;
    return SAM_UNCOVERED;
}

const sam_model_t sam_model_dsu = {"Dsu", NULL, NULL, dsu_read, dsu_write, NULL};
