/* Torque to PWM/DIR command (control path; equations in mc_drive.h). */
#include "mc_drive.h"

void mc_drive_command(const mc_drive_t *d, int32_t tau, int32_t dtheta_w,
                      int bemf_on, mc_drive_out_t *out)
{
    mc_drive_command_inl(d, tau, mc_clamp_sym(dtheta_w, MC_VEL_DIFF_MAX), bemf_on, out);
}
