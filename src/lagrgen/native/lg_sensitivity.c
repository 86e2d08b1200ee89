/* The augmented system of forward sensitivities: see lg_sensitivity.h. */
#include "lg_sensitivity.h"

#include <string.h>

int lg_sens_rhs(void *ctx, double t, const double *z, const double *u, double *out)
{
    const lg_sens_ctx *c = (const lg_sens_ctx *)ctx;
    const int d = c->dim;
    if (c->rhs(t, z, c->p, u, out) || c->jacobian(t, z, c->p, u, c->J))
        return 1;
    if (c->n_params && c->parameter_jacobian(t, z, c->p, u, c->P))
        return 1;
    for (int s = 0; s < c->k; ++s) {
        const double *S = z + d * (s + 1);
        double *dS = out + d * (s + 1);
        const int j = c->param_index[s];
        for (int i = 0; i < d; ++i) {
            const double *Ji = c->J + (size_t)i * d;
            double acc = j >= 0 ? c->P[(size_t)i * c->n_params + j] : 0.0;
            for (int m = 0; m < d; ++m)
                acc += Ji[m] * S[m];
            dS[i] = acc;
        }
    }
    return 0;
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
