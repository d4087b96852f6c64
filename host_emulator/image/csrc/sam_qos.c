/* Bus quality-of-service registers the UF2 bootloader sets at start-up: SBMATRIX (HMATRIXB) and DMAC.QOSCTRL. */
#include <string.h>
#include "sam.h"

/*
 * The tier models no bus arbitration: these registers are storage, their values change nothing (DS40001882
 * "HMATRIXB": PRAS/PRBS priorities, SFR special function registers; "DMAC": QOSCTRL). The DMA controller itself is
 * not modelled: any other DMAC register is an error naming it.
 */

static int hmatrix_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    (void)ri;
    (void)v;
    return SAM_GENERIC;
}

static int hmatrix_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    (void)ri;
    (void)v;
    (void)mask;
    sam_activity(m);
    return SAM_GENERIC;
}

const sam_model_t sam_model_hmatrixb = {"Hmatrixb", NULL, NULL, hmatrix_read, hmatrix_write, NULL};

static int dmac_qos(int pi, int ri) { return !strcmp(sam_regs[ri].name + strlen(sam_periphs[pi].name) + 1, "QOSCTRL"); }

static int dmac_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)v;
    if (dmac_qos(pi, ri))
        return SAM_GENERIC;
    sam_fail(m, "read of %s: the DMA controller is not modelled (only DMAC.QOSCTRL is storage)", sam_regs[ri].name);
    return SAM_DONE;
}

static int dmac_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    if (dmac_qos(pi, ri)) {
        sam_activity(m);
        return SAM_GENERIC;
    }
    sam_fail(m, "write of 0x%x to %s: the DMA controller is not modelled (only DMAC.QOSCTRL is storage)", v & mask,
             sam_regs[ri].name);
    return SAM_DONE;
}

const sam_model_t sam_model_dmac = {"Dmac", NULL, NULL, dmac_read, dmac_write, NULL};
