/* The interface between a generated model module and lagrgen's runtime (lagrgen._runtime).
 * A model module exports one lg_model_t through a PyCapsule named LG_CAPSULE_NAME.
 * Arrays are row-major; y = [q, qd]; every function writes only to its output arguments.
 * Functions returning int return 0 on success and 1 when M is not positive definite. */
#ifndef LAGRGEN_MODEL_H
#define LAGRGEN_MODEL_H

#define LG_ABI_VERSION 1
#define LG_CAPSULE_NAME "lagrgen.lg_model_t"

typedef struct {
    int abi_version;
    int n;                /* generalized coordinates */
    int n_params;
    int n_inputs;
    const char *metadata; /* JSON: name, coordinates, parameters, inputs, defaults, hash, version */
    /* M(q, t), n*n */
    void (*mass_matrix)(double t, const double *q, const double *p, double *M);
    /* F(q, qd, t, u), n */
    void (*forcing)(double t, const double *q, const double *qd, const double *p, const double *u,
                    double *F);
    /* ydot = [qd, M^-1 F], 2n */
    int (*rhs)(double t, const double *y, const double *p, const double *u, double *ydot);
    /* d ydot / d y, 2n*2n */
    int (*jacobian)(double t, const double *y, const double *p, const double *u, double *J);
    /* M, dF/dq, dF/dqd (n*n each), dF/du (n*n_inputs) */
    void (*linear_terms)(double t, const double *q, const double *qd, const double *p,
                         const double *u, double *M, double *dF_dq, double *dF_dqd, double *dF_du);
} lg_model_t;

#endif
