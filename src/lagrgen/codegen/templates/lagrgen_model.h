/* The interface between a compiled model module and lagrgen's runtime (lagrgen.runtime).
 * A model module exports one lg_model_t through a PyCapsule named LG_CAPSULE_NAME: its sizes, its
 * metadata (JSON) and a table of its model functions, each with the one signature lg_function.
 * The functions and their outputs are declared in lagrgen/functions.py. */
#ifndef LAGRGEN_MODEL_H
#define LAGRGEN_MODEL_H

#define LG_ABI_VERSION 2
#define LG_CAPSULE_NAME "lagrgen.lg_model_t"

/* out = f(t, y = [q, qd], p, u), row-major; 0 on success, 1 when M is not positive definite or
 * (constrained models) A·M⁻¹·Aᵀ is singular: dependent constraints. */
typedef int (*lg_function)(double t, const double *y, const double *p, const double *u,
                           double *out);

/* A function of call style "directions" (lagrgen/functions.py: DIRECTIONS_SIGNATURE) takes k
 * directions (dy_s: 2n doubles each, then dp_s: n_params each); it is listed in the table cast to
 * lg_function and must be cast back to lg_directions_fn before it is called. */
typedef int (*lg_directions_fn)(double t, const double *y, const double *p, const double *u,
                                int k, const double *dy, const double *dp, double *out);

typedef struct {
    const char *name;     /* the name in lagrgen/functions.py */
    lg_function fn;
} lg_entry_t;

typedef struct {
    int abi_version;
    int n;                /* generalized coordinates */
    int n_params;
    int n_inputs;
    const char *metadata; /* JSON: name, coordinates, parameters, inputs, defaults, hash, version */
    int n_functions;
    const lg_entry_t *functions;
} lg_model_t;

#endif
