/* Primary program placeholder: answers the USB identity request; issue 4 adds the bus and SLCAN. */
#include <Arduino.h>
extern "C" {
#include "mc_cell.h"    /* MC_FW_VERSION: one release number for cell and primary */
#include "../common/mc_ident.h"
}

/*
 * HOOK for issue 4: the primary's USB CDC port will carry SLCAN (python-can).
 * Whatever parses those lines must keep answering a line "ID?" with the identity
 * reply below (SLCAN has no command starting with 'I', so the two do not clash);
 * tools/flash verifies every board with it after upload.
 */
static mc_ident_rx_t g_rx;

void setup()
{
    Serial.begin(115200);   /* USB CDC: the rate is ignored, never 1200 */
    mc_ident_rx_init(&g_rx);
}

void loop()
{
    while (Serial.available() > 0) {
        if (mc_ident_rx_feed(&g_rx, (uint8_t)Serial.read())) {
            char line[MC_IDENT_LINE_MAX];
            int n = mc_ident_format(line, sizeof(line), MC_IDENT_ROLE_PRIMARY, 0, 0,
                                    MC_FW_VERSION);
            if (n > 0)
                Serial.write((const uint8_t *)line, (size_t)n);
        }
    }
}
