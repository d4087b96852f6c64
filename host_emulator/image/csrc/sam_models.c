/* The registry of peripheral models: the vendor's struct type of a peripheral -> the model of its registers. */
#include <string.h>
#include "sam_core.h"

/* each defined in its own file, sam_<peripheral>.c (the system control space's in sam_scs.c) */
extern const sam_model_t sam_model_pm, sam_model_sysctrl, sam_model_gclk, sam_model_nvmctrl, sam_model_wdt,
    sam_model_port, sam_model_eic, sam_model_tc, sam_model_tcc, sam_model_sercom, sam_model_usb, sam_model_adc,
    sam_model_dac, sam_model_pac, sam_model_dsu, sam_model_hmatrixb, sam_model_dmac;

/* Every instance of a type gets its model (TC3..TC7 are "Tc"); a type not listed has no model, and an access to
 * its registers is an error naming the peripheral. */
static const struct {
    const char *type;            /* sam_periph_t.type: the vendor's struct name */
    const sam_model_t *model;
} MODELS[] = {
    {"Pm", &sam_model_pm},
    {"Sysctrl", &sam_model_sysctrl},
    {"Gclk", &sam_model_gclk},
    {"Nvmctrl", &sam_model_nvmctrl},
    {"Wdt", &sam_model_wdt},
    {"Port", &sam_model_port},        /* both doors: PORT (APB) and PORT_IOBUS */
    {"Eic", &sam_model_eic},
    {"Tc", &sam_model_tc},
    {"Tcc", &sam_model_tcc},
    {"Sercom", &sam_model_sercom},
    {"Usb", &sam_model_usb},
    {"Adc", &sam_model_adc},
    {"Dac", &sam_model_dac},
    {"Pac", &sam_model_pac},
    {"Dsu", &sam_model_dsu},
    {"Hmatrixb", &sam_model_hmatrixb},   /* SBMATRIX: QoS storage (sam_qos.c) */
    {"Dmac", &sam_model_dmac},           /* QOSCTRL storage only */
    {"NVIC_Type", &sam_model_scs},
    {"SCB_Type", &sam_model_scs},
    {"SysTick_Type", &sam_model_scs},
};

const sam_model_t *sam_model_for(const char *type)
{
    for (size_t i = 0; i < sizeof MODELS / sizeof MODELS[0]; i++)
        if (!strcmp(MODELS[i].type, type))
            return MODELS[i].model;
    return NULL;
}
