/* The augmented system of forward sensitivities: see lg_sensitivity.h. */
#include "lg_sensitivity.h"

#include <string.h>

int lg_sens_rhs(void *ctx, double t, const double *z, const double *u, double *out)
{
    const lg_sens_ctx *c = (const lg_sens_ctx *)ctx;
    return c->directional(t, z, c->p, u, c->k, z + c->dim, c->P, out);
}

int lg_sens_jac(void *ctx, double t, const double *z, const double *u, double *out)
{
    const lg_sens_ctx *c = (const lg_sens_ctx *)ctx;
    const int d = c->dim, D = d * (c->k + 1);
    if (c->jacobian(t, z, c->p, u, c->J))
        return 1;
    memset(out, 0, (size_t)D * D * sizeof(double));
    for (int b = 0; b <= c->k; ++b)
        for (int i = 0; i < d; ++i)
            memcpy(out + (size_t)(b * d + i) * D + b * d, c->J + (size_t)i * d,
                   (size_t)d * sizeof(double));
    return 0;
}
