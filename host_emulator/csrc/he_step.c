/* Stepper dispatch by id, the shared scratch and the final state check (methods in he_explicit.c, he_noh_bathe.c, he_imex.c, he_dop853.c). */
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include "he_step.h"

int he_state_check(int n2, const double *x, const double *v)
{
    for (int i = 0; i < n2; i++) {
        if (!isfinite(x[i]) || !isfinite(v[i]))
            return HE_ERR_NONFINITE;
        if (fabs(x[i]) > HE_ANGLE_LIMIT_RAD || fabs(v[i]) > HE_SPEED_LIMIT_RAD_S)
            return HE_ERR_DIVERGED;
    }
    return HE_OK;
}

void he_flush_tiny(int n2, double *x, double *v)
{
    for (int i = 0; i < n2; i++) {
        x[i] = fabs(x[i]) < HE_TINY_RAD ? 0.0 : x[i];
        v[i] = fabs(v[i]) < HE_TINY_RAD ? 0.0 : v[i];
    }
}

double he_step_limit(const he_plant_t *p, int stepper, int *limiting_chain)
{
    switch (stepper) {
    case HE_STEP_EULER:
    case HE_STEP_SYMPLECTIC:
    case HE_STEP_RK4:
        return he_explicit_limit(p, stepper, limiting_chain);
    case HE_STEP_NOH_BATHE:
        return he_noh_bathe_limit(p, stepper, limiting_chain);
    case HE_STEP_IMEX:
        return he_imex_limit(p, stepper, limiting_chain);
    case HE_STEP_DOP853:
        return he_dop853_limit(p, stepper, limiting_chain);
    default:
        return -1.0;
    }
}

int he_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double *t, double *x, double *v)
{
    int n = p->n, n2 = 2 * n;
    if (n < 1 || n > HE_MAX_CELLS || !(h > 0.0) || nsteps < 0)
        return HE_ERR_ARG;
    if (stepper < 0 || stepper >= HE_STEP_COUNT)
        return HE_ERR_STEPPER;
    /* scratch: the plant's (allocated once per model) or, without it, one allocation for this call */
    int64_t need = (int64_t)HE_WORK_PER_STATE * n2;
    double *work = p->work, *own = NULL;
    if (work == NULL || p->work_len < need) {
        own = malloc((size_t)need * sizeof(double));
        if (own == NULL)
            return HE_ERR_NOMEM;
        work = own;
    }
    double t0 = *t;
    int rc;
    switch (stepper) {
    case HE_STEP_NOH_BATHE:
        rc = he_noh_bathe_advance(p, stepper, h, nsteps, t0, x, v, work);
        break;
    case HE_STEP_IMEX:
        rc = he_imex_advance(p, stepper, h, nsteps, t0, x, v, work);
        break;
    case HE_STEP_DOP853:
        rc = he_dop853_advance(p, stepper, h, nsteps, t0, x, v, work);
        break;
    default:
        rc = he_explicit_advance(p, stepper, h, nsteps, t0, x, v, work);
        break;
    }
    free(own);
    if (rc != HE_OK)
        return rc;
    *t = t0 + (double)nsteps * h;
    rc = he_state_check(n2, x, v);
    return rc != HE_OK ? rc : he_plant_range_check(p, x, NULL);
}
