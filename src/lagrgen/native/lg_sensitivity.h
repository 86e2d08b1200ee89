/* Forward sensitivities for lagrgen's native engine: the augmented system
 *     z = [y, S_1, ..., S_k],  y' = f(t, y),  S_c' = J(t, y)·S_c + ∂f/∂p_{j_c}
 * as system hooks of lg_ode.h (lg_problem_t.sys_rhs / sys_jac with an lg_sens_ctx). A column
 * whose parameter index is negative is the sensitivity to an initial state (no ∂f/∂p term).
 * The Jacobian hook gives diag(J, ..., J): the Newton matrix of Radau and BDF may be approximate. */
#ifndef LG_SENSITIVITY_H
#define LG_SENSITIVITY_H

#include "lg_ode.h"

typedef struct {
    lg_rhs_fn rhs, jacobian, parameter_jacobian;
    const double *p;
    int dim;                 /* the model's state dimension 2n */
    int k;                   /* sensitivity columns */
    int n_params;
    const int *param_index;  /* k entries: the parameter of each column, or -1 */
    double *J, *P;           /* work: dim×dim and dim×n_params (one solve's, not shared) */
} lg_sens_ctx;

int lg_sens_rhs(void *ctx, double t, const double *z, const double *u, double *out);
int lg_sens_jac(void *ctx, double t, const double *z, const double *u, double *out);

#endif
