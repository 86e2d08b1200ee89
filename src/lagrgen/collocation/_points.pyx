# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# cython: embedsignature=True
"""The collocation NLP's loops over points, in C with the GIL released: the model's residual and
its derivatives through the model's function table, and the kernels of compiled units.

Functions are passed as integer addresses (`function_address` of a built model, `Unit.address`);
a point's variables are the row z_j = [q, q̇, q̈, λ, u] of a C-contiguous (points, nz) array, so a
model function reads y = [q, q̇, q̈, λ] and u from it without a copy.
"""
import numpy as np
cimport numpy as cnp
from libc.stdlib cimport free, malloc

from lagrgen.runtime.abi cimport lg_function

cnp.import_array()

ctypedef void (*lgc_kernel)(double t, const double *q, const double *qd, const double *a,
                            const double *p, const double *u, const double *mu,
                            double *out) noexcept nogil

cdef double ZERO[1]
ZERO[0] = 0.0


def residual_rows(size_t terms, size_t parameter_jacobian, const double[::1] t,
                  const double[:, ::1] Z, const double[::1] p, int n, int m, int nu, int n_params,
                  const cnp.int64_t[::1] pick, double[:, ::1] r, double[:, ::1] jac):
    """r[j] = the residual at point j, jac[j, k] = entry pick[k] of the concatenated outputs of
    `residual_terms` and (when its address is not 0) `residual_parameter_jacobian` there.
    Returns the number of points whose model function reported failure."""
    cdef lg_function fterms = <lg_function>terms
    cdef lg_function fparams = <lg_function>parameter_jacobian
    cdef int ni = n + m
    cdef Py_ssize_t size1 = ni + ni * 2 * n + ni * ni + ni * nu
    cdef Py_ssize_t size = size1 + (ni * n_params if parameter_jacobian else 0)
    cdef Py_ssize_t P = Z.shape[0], K = pick.shape[0], j, k
    cdef int failed = 0
    cdef const double *u
    cdef double *buf = <double *>malloc(max(size, 1) * sizeof(double))
    if buf == NULL:
        raise MemoryError()
    try:
        with nogil:
            for j in range(P):
                u = &Z[j, 3 * n + m] if nu else ZERO
                if fterms(t[j], &Z[j, 0], &p[0], u, buf):
                    failed += 1
                if parameter_jacobian and fparams(t[j], &Z[j, 0], &p[0], u, buf + size1):
                    failed += 1
                for k in range(ni):
                    r[j, k] = buf[k]
                for k in range(K):
                    jac[j, k] = buf[pick[k]]
    finally:
        free(buf)
    return failed


def kernel_rows(size_t address, const double[::1] t, const double[:, ::1] Z,
                const double[::1] p, int n, int m, int nu, const double[:, ::1] W,
                double[:, ::1] out):
    """out[j] = kernel(t[j], z_j, p, W[j]) for every point j (W with no columns: no weights)."""
    cdef lgc_kernel f = <lgc_kernel>address
    cdef Py_ssize_t P = Z.shape[0], j
    cdef const double *u
    cdef const double *w
    cdef bint weighted = W.shape[1] > 0
    with nogil:
        for j in range(P):
            u = &Z[j, 3 * n + m] if nu else ZERO
            w = &W[j, 0] if weighted else ZERO
            f(t[j], &Z[j, 0], &Z[j, n], &Z[j, 2 * n], &p[0], u, w, &out[j, 0])
    return None


def state_rows(size_t address, const double[::1] t, const double[:, ::1] Y, const double[::1] p,
               const double[:, ::1] U, double[:, ::1] out):
    """out[j] = f(t[j], Y[j], p, U[j]) for every row j, f a model function of the state
    (`rhs`: ẏ). Returns the number of rows where it reported failure."""
    cdef lg_function f = <lg_function>address
    cdef Py_ssize_t B = Y.shape[0], j
    cdef int failed = 0
    cdef bint has_inputs = U.shape[1] > 0
    with nogil:
        for j in range(B):
            if f(t[j], &Y[j, 0], &p[0], &U[j, 0] if has_inputs else ZERO, &out[j, 0]):
                failed += 1
    return failed


def weighted_rows(size_t function, const double[::1] t, const double[:, ::1] Z,
                  const double[::1] p, int n, int m, int nu, const double[:, ::1] W,
                  const cnp.int64_t[::1] pick, double[:, ::1] out):
    """out[j, k] = entry pick[k] of f(t[j], [q, q̇, a, W[j]], p, u) at every point j, f a model
    function of the call style "weighted" (`residual_hessian`: a full (3n + m + nu)² matrix).
    Returns the number of points where it reported failure."""
    cdef lg_function f = <lg_function>function
    cdef int ni = n + m, width = 3 * n + m + nu
    cdef Py_ssize_t P = Z.shape[0], K = pick.shape[0], j, k
    cdef int failed = 0
    cdef const double *u
    cdef double *y = <double *>malloc((2 * n + 2 * ni) * sizeof(double))
    cdef double *buf = <double *>malloc(max(width * width, 1) * sizeof(double))
    if y == NULL or buf == NULL:
        free(y)
        free(buf)
        raise MemoryError()
    try:
        with nogil:
            for j in range(P):
                for k in range(2 * n + ni):
                    y[k] = Z[j, k]
                for k in range(ni):
                    y[2 * n + ni + k] = W[j, k]
                u = &Z[j, 3 * n + m] if nu else ZERO
                if f(t[j], y, &p[0], u, buf):
                    failed += 1
                for k in range(K):
                    out[j, k] = buf[pick[k]]
    finally:
        free(y)
        free(buf)
    return failed
