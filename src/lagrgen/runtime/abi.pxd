# The C interface of a compiled model module (codegen/templates/lagrgen_model.h), for every
# Cython module of lagrgen that calls model functions.
cdef extern from "lagrgen_model.h":
    int LG_ABI_VERSION
    const char *LG_CAPSULE_NAME
    ctypedef int (*lg_function)(double t, const double *y, const double *p, const double *u,
                                double *out) noexcept nogil
    ctypedef int (*lg_directions_fn)(double t, const double *y, const double *p, const double *u,
                                     int k, const double *dy, const double *dp,
                                     double *out) noexcept nogil
    ctypedef struct lg_entry_t:
        const char *name
        lg_function fn
    ctypedef struct lg_model_t:
        int abi_version
        int n
        int n_params
        int n_inputs
        const char *metadata
        int n_functions
        const lg_entry_t *functions
