/* Forward sensitivities for lagrgen's native engine: the augmented system
 *     z = [y, S_1, ..., S_k],  y' = f(t, y),  S_c' = J(t, y)·S_c + ∂f/∂p·P_c
 * as system hooks of lg_ode.h (lg_problem_t.sys_rhs / sys_jac with an lg_sens_ctx). P_c is the
 * unit vector of column c's parameter, or zero for the sensitivity to an initial state. The rhs
 * hook is one call of the model's directional_derivatives (ẏ and the k products J·S_c + ∂f/∂p·P_c
 * by forward mode on its kernels, J never formed); the Jacobian hook gives diag(J, ..., J): the
 * Newton matrix of Radau and BDF may be approximate. */
#ifndef LG_SENSITIVITY_H
#define LG_SENSITIVITY_H

#include "lg_ode.h"
#include "lagrgen_model.h"

typedef struct {
    lg_directions_fn directional;   /* the model's directional_derivatives */
    lg_jac_fn jacobian;
    const double *p;
    int dim;                 /* the model's state dimension 2n */
    int k;                   /* sensitivity columns */
    const double *P;         /* k × n_params: the parameter direction of each column */
    double *J;               /* work: dim × dim (one solve's, not shared) */
} lg_sens_ctx;

int lg_sens_rhs(void *ctx, double t, const double *z, const double *u, double *out);
int lg_sens_jac(void *ctx, double t, const double *z, const double *u, double *out);

#endif
