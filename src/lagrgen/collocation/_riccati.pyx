# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# cython: cdivision=True, embedsignature=True
"""The Riccati recursion of a discrete-time optimal control QP, in C: the stage-structured solver
of `lagrgen.collocation.sqp`.

The QP over the stage variables X_k (k = 0 … K) and inputs v_k (k < K) is

    min Σ_k [½·[X; v]ᵀ·[[Qxx, Qxv], [Qxvᵀ, Qvv]]·[X; v] + qxᵀ·X + qvᵀ·v] + ½·X_Kᵀ·P_K·X_K + p_Kᵀ·X_K
    s.t. X_{k+1} = A_k·X_k + B_k·v_k + b_k

with the cost-to-go V_k(X) = ½·Xᵀ·P_k·X + p_kᵀ·X computed backwards: H = Q + [A B]ᵀ·P_{k+1}·[A B],
v_k = gain_k·X + ff_k with gain = −Hvv⁻¹·Hvx, ff = −Hvv⁻¹·hv (Hvv by its Cholesky factor: the
QP must be convex along the inputs), P_k = Hxx + Hxv·gain, p_k = hx + Hxv·ff. The matrices'
pass (`factor`) is separate from the vectors' (`vectors`): a QP whose gradient alone changed
reuses the factor. Stacked arrays, C-contiguous float64, stage first.

The factor's products and triangular solves run on the BLAS SciPy links (its `cython_blas`
functions, taken from their capsules at import: SciPy is needed to run, not to build).
"""
import numpy as np
cimport numpy as cnp
from cpython.pycapsule cimport PyCapsule_GetName, PyCapsule_GetPointer
from libc.math cimport sqrt
from libc.stdlib cimport free, malloc
from libc.string cimport memcpy

cnp.import_array()

ctypedef void (*dgemm_t)(char *transa, char *transb, int *m, int *n, int *k, double *alpha,
                         double *a, int *lda, double *b, int *ldb, double *beta, double *c,
                         int *ldc) noexcept nogil
ctypedef void (*dtrsm_t)(char *side, char *uplo, char *transa, char *diag, int *m, int *n,
                         double *alpha, double *a, int *lda, double *b, int *ldb) noexcept nogil
ctypedef void (*dgemv_t)(char *trans, int *m, int *n, double *alpha, double *a, int *lda,
                         double *x, int *incx, double *beta, double *y, int *incy) noexcept nogil


cdef void *_blas(name) except NULL:
    """The function `name` of scipy.linalg.cython_blas."""
    from scipy.linalg import cython_blas
    capsule = cython_blas.__pyx_capi__[name]
    return PyCapsule_GetPointer(capsule, PyCapsule_GetName(capsule))


cdef dgemm_t dgemm = <dgemm_t>_blas("dgemm")
cdef dtrsm_t dtrsm = <dtrsm_t>_blas("dtrsm")
cdef dgemv_t dgemv = <dgemv_t>_blas("dgemv")


cdef inline void gemm(const double *A, const double *B, double *C, int m, int k, int n,
                      bint ta, bint add) noexcept nogil:
    """Row-major C (m×n) = op(A)·B (op: transpose when ta; A is m×k or k×m, B k×n), or C += it
    when add."""
    gemm_ld(A, m if ta else k, B, n, C, n, m, k, n, ta, add)


cdef inline void gemm_ld(const double *A, int lda, const double *B, int ldb, double *C, int ldc,
                         int m, int k, int n, bint ta, bint add) noexcept nogil:
    """`gemm` on blocks of row-major matrices, each row `ld` apart: BLAS's column-major
    Cᵀ = Bᵀ·op(A)ᵀ."""
    cdef char no = b'N', tr = b'T'
    cdef double one = 1.0, beta = 1.0 if add else 0.0
    cdef int i, j
    if m == 0 or n == 0 or k == 0:         # BLAS refuses a leading dimension of 0
        if not add:
            for i in range(m):
                for j in range(n):
                    C[i * ldc + j] = 0.0
        return
    dgemm(&no, &tr if ta else &no, &n, &m, &k, &one, <double *>B, &ldb, <double *>A, &lda,
          &beta, C, &ldc)


cdef double *scratch(Py_ssize_t count) except NULL:
    """A work array of `count` doubles (at least one), to free; a kernel's several work arrays
    are parts of one."""
    cdef double *out = <double *>malloc((count + 1) * sizeof(double))
    if out == NULL:
        raise MemoryError()
    return out


cdef inline void add_block(double *C, int ldc, const double *A, int lda, int m,
                           int n) noexcept nogil:
    """C += A for m×n blocks of row-major matrices, each row `ld` apart (a stage's identity
    block of inputs, applied without multiplying by it)."""
    cdef int i, j
    for i in range(m):
        for j in range(n):
            C[i * ldc + j] += A[i * lda + j]


cdef inline void cho_solve_rows(const double *L, double *X, int n, int ncols) noexcept nogil:
    """Row-major X (n×ncols) := (L·Lᵀ)⁻¹·X for L (n×n) row-major lower: in BLAS's column-major
    terms Xᵀ := Xᵀ·U⁻¹·U⁻ᵀ with U = Lᵀ (L's memory read column-major)."""
    cdef char right = b'R', upper = b'U', no = b'N', tr = b'T', nonunit = b'N'
    cdef double one = 1.0
    if n == 0 or ncols == 0:
        return
    dtrsm(&right, &upper, &no, &nonunit, &ncols, &n, &one, <double *>L, &n, X, &ncols)
    dtrsm(&right, &upper, &tr, &nonunit, &ncols, &n, &one, <double *>L, &n, X, &ncols)


cdef inline void matmul(const double *A, const double *B, double *C, int m, int k, int n,
                        bint ta, bint tb, bint add) noexcept nogil:
    """C (m×n) = op(A)·op(B) (op: transpose when ta/tb; A is m×k or k×m, B k×n or n×k), or
    C += it when add. A product with a vector (n = 1) is BLAS's; otherwise the inner loops run
    along rows of C and B (contiguous: vectorized)."""
    cdef int i, j, l, one_step = 1
    cdef double a, s, one = 1.0, beta = 1.0 if add else 0.0
    cdef char no = b'N', tr = b'T'
    if n == 1 and not tb and m > 0 and k > 0:
        if ta:      # A (k×m) row-major is BLAS's m×k: y = A_blas·x
            dgemv(&no, &m, &k, &one, <double *>A, &m, <double *>B, &one_step, &beta, C,
                  &one_step)
        else:       # A (m×k) row-major is BLAS's k×m: y = A_blasᵀ·x
            dgemv(&tr, &k, &m, &one, <double *>A, &k, <double *>B, &one_step, &beta, C,
                  &one_step)
        return
    if not add:
        for i in range(m * n):
            C[i] = 0.0
    if tb:
        for i in range(m):
            for j in range(n):
                s = 0.0
                if ta:
                    for l in range(k):
                        s += A[l * m + i] * B[j * k + l]
                else:
                    for l in range(k):
                        s += A[i * k + l] * B[j * k + l]
                C[i * n + j] += s
        return
    if ta:
        for l in range(k):
            for i in range(m):
                a = A[l * m + i]
                for j in range(n):
                    C[i * n + j] += a * B[l * n + j]
    else:
        for i in range(m):
            for l in range(k):
                a = A[i * k + l]
                for j in range(n):
                    C[i * n + j] += a * B[l * n + j]


cdef inline int cholesky(double *L, int n) noexcept nogil:
    """L (n×n, symmetric) := its lower Cholesky factor in place (upper part zeroed); 1 when not
    positive definite."""
    cdef int i, j, l
    cdef double s
    for j in range(n):
        s = L[j * n + j]
        for l in range(j):
            s -= L[j * n + l] * L[j * n + l]
        if not (s > 1e-14 * (1.0 + abs(L[j * n + j]))):
            return 1
        s = sqrt(s)
        L[j * n + j] = s
        for i in range(j + 1, n):
            L[i * n + j] = (L[i * n + j] - _dot(&L[i * n], &L[j * n], j)) / s
        for i in range(j):
            L[i * n + j] = 0.0
    return 0


cdef inline double _dot(const double *x, const double *y, int n) noexcept nogil:
    cdef double s = 0.0
    cdef int i
    for i in range(n):
        s += x[i] * y[i]
    return s


cdef inline void cho_solve(const double *L, double *X, int n, int ncols) noexcept nogil:
    """X (n×ncols) := (L·Lᵀ)⁻¹·X."""
    cdef int i, l, c
    cdef double s
    for c in range(ncols):
        for i in range(n):
            s = X[i * ncols + c]
            for l in range(i):
                s -= L[i * n + l] * X[l * ncols + c]
            X[i * ncols + c] = s / L[i * n + i]
        for i in range(n - 1, -1, -1):
            s = X[i * ncols + c]
            for l in range(i + 1, n):
                s -= L[l * n + i] * X[l * ncols + c]
            X[i * ncols + c] = s / L[i * n + i]


def point_hessians(const double[:, :, ::1] T, const double[:, :, ::1] W, double[:, :, ::1] G):
    """G_j = T_jᵀ·W_j·T_j of every point j: its Hessian block W (P, nz, nz) in the variables
    y = [dx, du] that T (P, nz, ny) maps to its step dz = T·y + t."""
    cdef int count = T.shape[0], nz = T.shape[1], ny = T.shape[2], j
    cdef double *WT = scratch(nz * ny)
    with nogil:
        for j in range(count):
            gemm(&W[j, 0, 0], &T[j, 0, 0], WT, nz, nz, ny, False, False)
            gemm(&T[j, 0, 0], WT, &G[j, 0, 0], ny, nz, ny, True, False)
    free(WT)
    return None


def diagonal_hessians(const double[:, :, ::1] G0, const double[:, :, ::1] T,
                      const double[:, ::1] add, int n, double[:, :, ::1] G):
    """G_j = G0_j + T_jᵀ·diag(add_j)·T_j of every point j, for the T of `point_hessians` whose
    rows other than the accelerations' [2n, 3n) are an identity's (y's states and inputs): add
    on G0's diagonal, plus Ta_jᵀ·diag(a_j)·Ta_j over the acceleration rows whose a is not 0."""
    cdef int ny = T.shape[2]
    cdef double *S = scratch(2 * n * ny)
    with nogil:
        _diagonal_hessians(G0, T, add, n, G, S, S + n * ny)
    free(S)
    return None


cdef void _diagonal_hessians(const double[:, :, ::1] G0, const double[:, :, ::1] T,
                             const double[:, ::1] add, int n, double[:, :, ::1] G, double *S,
                             double *Ta) noexcept nogil:
    """`diagonal_hessians` with its scratch S and Ta (n × ny each)."""
    cdef int count = T.shape[0], ny = T.shape[2], j, i, r, rank
    cdef double a
    for j in range(count):
        memcpy(&G[j, 0, 0], &G0[j, 0, 0], ny * ny * sizeof(double))
        for i in range(2 * n):
            G[j, i, i] += add[j, i]
        for i in range(2 * n, ny):
            G[j, i, i] += add[j, n + i]
        rank = 0
        for r in range(n):
            a = add[j, 2 * n + r]
            if a != 0.0:
                for i in range(ny):
                    Ta[rank * ny + i] = T[j, 2 * n + r, i]
                    S[rank * ny + i] = a * T[j, 2 * n + r, i]
                rank += 1
        if rank:
            gemm(Ta, S, &G[j, 0, 0], ny, rank, ny, True, True)


def stage_hessians(const double[:, :, ::1] G, const cnp.int64_t[:, ::1] points,
                   const double[:, :, :, ::1] C, const double[:, :, :, ::1] E,
                   double[:, :, ::1] Qxx, double[:, :, ::1] Qxv, double[:, :, ::1] Qvv,
                   int states=-1):
    """Each stage's Hessian in (X, v) from its points' Hessians G (P, ny, ny) in y: the start's
    (points[k, 0]) and each inner point's (points[k, p + 1], y = C[p, k]·X + E[p, k]·v + ·):
    Qxx = G_s + Σ Cᵀ·G·C, Qxv = Σ Cᵀ·G·E, Qvv = Σ Eᵀ·G·E (K stages, Qxx (K, ny, ny), Qxv (K,
    ny, nv), Qvv (K, nv, nv)). `states` s ≥ 0: C's rows from s on are 0 and E's are an
    identity's rows (y's inputs are the inner point's own, v's block p), as `factor`'s A and B."""
    cdef int K = Qxx.shape[0], ny = Qxx.shape[1], nv = Qvv.shape[1], inner = C.shape[0], k, p
    cdef int s = ny if states < 0 else states, m = ny - s
    cdef const double *Gp
    cdef double *GC = scratch(ny * ny + ny * nv)
    cdef double *GE = GC + ny * ny
    with nogil:
        for k in range(K):
            memcpy(&Qxx[k, 0, 0], &G[points[k, 0], 0, 0], ny * ny * sizeof(double))
            for p in range(inner):
                Gp = &G[points[k, p + 1], 0, 0]
                gemm_ld(Gp, ny, &C[p, k, 0, 0], ny, GC, ny, s, s, ny, False, False)
                gemm_ld(Gp, ny, &E[p, k, 0, 0], nv, GE, nv, ny, s, nv, False, False)
                add_block(GE + p * m, nv, Gp + s, ny, ny, m)
                gemm_ld(&C[p, k, 0, 0], ny, GC, ny, &Qxx[k, 0, 0], ny, ny, s, ny, True, True)
                gemm_ld(&C[p, k, 0, 0], ny, GE, nv, &Qxv[k, 0, 0], nv, ny, s, nv, True, p > 0)
                gemm_ld(&E[p, k, 0, 0], nv, GE, nv, &Qvv[k, 0, 0], nv, nv, s, nv, True, p > 0)
                add_block(&Qvv[k, 0, 0] + p * m * nv, nv, GE + s * nv, nv, m, nv)
    free(GC)
    return None


def stage_gradients(const double[:, :, ::1] G, const double[:, ::1] gamma,
                    const cnp.int64_t[:, ::1] points, const double[:, :, :, ::1] C,
                    const double[:, :, :, ::1] E, const double[:, :, ::1] e,
                    double[:, ::1] qx, double[:, ::1] qv, int states=-1):
    """Each stage's gradient in (X, v) from its points' Hessians G (symmetric) and gradients γ
    in y (the `stage_hessians` arrangement, y = C·X + E·v + e at an inner point):
    qx = γ_s + Σ Cᵀ·(G·e + γ), qv = Σ Eᵀ·(G·e + γ). `states` s ≥ 0: as `stage_hessians`', and
    e's rows from s on are 0."""
    cdef int K = qx.shape[0], ny = qx.shape[1], nv = qv.shape[1], inner = C.shape[0], k, p, i
    cdef int s = ny if states < 0 else states, m = ny - s
    cdef double *lin = scratch(ny)
    with nogil:
        for k in range(K):
            memcpy(&qx[k, 0], &gamma[points[k, 0], 0], ny * sizeof(double))
            for i in range(nv):
                qv[k, i] = 0.0
            for p in range(inner):
                memcpy(lin, &gamma[points[k, p + 1], 0], ny * sizeof(double))
                matmul(&G[points[k, p + 1], 0, 0], &e[p, k, 0], lin, ny, s, 1, True, False,
                       True)
                matmul(&C[p, k, 0, 0], lin, &qx[k, 0], ny, s, 1, True, False, True)
                matmul(&E[p, k, 0, 0], lin, &qv[k, 0], nv, s, 1, True, False, True)
                for i in range(m):
                    qv[k, p * m + i] += lin[s + i]
    free(lin)
    return None


def factor(const double[:, :, ::1] Qxx, const double[:, :, ::1] Qxv,
           const double[:, :, ::1] Qvv, const double[:, :, ::1] A, const double[:, :, ::1] B,
           const double[:, ::1] P_end, double regularize, double[:, :, ::1] P,
           double[:, :, ::1] Hxv, double[:, :, ::1] chol, double[:, :, ::1] gain,
           int states=-1):
    """The backward pass of the matrices: P (K+1, nx, nx), and per stage Hxv (K, nx, nv), the
    Cholesky factor of Hvv (K, nv, nv) and gain (K, nv, nx). Returns 0, or k + 1 when stage k's
    Hvv (+ regularize·1) is not positive definite. `states` s ≥ 0: A's rows from s on are 0 and
    B's are [0 1] (X_{k+1}'s last nx − s entries are v_k's last: a collocation stage's inputs),
    and the products skip them."""
    cdef int K = Qxx.shape[0], nx = Qxx.shape[1], nv = Qvv.shape[1], k, i, j
    cdef int s = nx if states < 0 else states, m = nx - s
    cdef double *PA = scratch(2 * nx * nx + 2 * nx * nv)
    cdef double *PB = PA + nx * nx
    cdef double *Hxx = PB + nx * nv
    cdef double *T = Hxx + nx * nx
    cdef int status = 0
    with nogil:
        for i in range(nx):
            for j in range(nx):
                P[K, i, j] = P_end[i, j]
        for k in range(K - 1, -1, -1):
            # PA = P·A and PB = P·B, of which Aᵀ·PA, Aᵀ·PB and Bᵀ·PB read the rows below s
            # only through B's identity block
            gemm_ld(&P[k + 1, 0, 0], nx, &A[k, 0, 0], nx, PA, nx, s, s, nx, False, False)
            gemm_ld(&P[k + 1, 0, 0], nx, &B[k, 0, 0], nv, PB, nv, nx, s, nv, False, False)
            add_block(PB + nv - m, nv, &P[k + 1, 0, 0] + s, nx, nx, m)
            memcpy(Hxx, &Qxx[k, 0, 0], nx * nx * sizeof(double))
            gemm_ld(&A[k, 0, 0], nx, PA, nx, Hxx, nx, nx, s, nx, True, True)
            memcpy(&Hxv[k, 0, 0], &Qxv[k, 0, 0], nx * nv * sizeof(double))
            gemm_ld(&A[k, 0, 0], nx, PB, nv, &Hxv[k, 0, 0], nv, nx, s, nv, True, True)
            memcpy(&chol[k, 0, 0], &Qvv[k, 0, 0], nv * nv * sizeof(double))
            gemm_ld(&B[k, 0, 0], nv, PB, nv, &chol[k, 0, 0], nv, nv, s, nv, True, True)
            add_block(&chol[k, 0, 0] + (nv - m) * nv, nv, PB + s * nv, nv, m, nv)
            for i in range(nv):
                for j in range(i):
                    chol[k, i, j] = 0.5 * (chol[k, i, j] + chol[k, j, i])
                    chol[k, j, i] = chol[k, i, j]
                chol[k, i, i] += regularize
            if cholesky(&chol[k, 0, 0], nv):
                status = k + 1
                break
            for i in range(nv):
                for j in range(nx):
                    T[i * nx + j] = -Hxv[k, j, i]
            cho_solve_rows(&chol[k, 0, 0], T, nv, nx)
            memcpy(&gain[k, 0, 0], T, nv * nx * sizeof(double))
            gemm(&Hxv[k, 0, 0], T, Hxx, nx, nv, nx, False, True)
            for i in range(nx):
                for j in range(nx):
                    P[k, i, j] = 0.5 * (Hxx[i * nx + j] + Hxx[j * nx + i])
    free(PA)
    return status


def vectors(const double[:, ::1] qx, const double[:, ::1] qv, const double[:, :, ::1] A,
            const double[:, :, ::1] B, const double[:, ::1] b, const double[::1] p_end,
            const double[:, :, ::1] P, const double[:, :, ::1] Hxv,
            const double[:, :, ::1] chol, double[:, ::1] p, double[:, ::1] ff, int states=-1):
    """The backward pass of the vectors after `factor`: p (K+1, nx), ff (K, nv). `states` s ≥ 0:
    as `factor`'s, and b's rows from s on are 0 (P, symmetric, read by its first s rows)."""
    cdef int K = qx.shape[0], nx = qx.shape[1], nv = qv.shape[1], k, i
    cdef int s = nx if states < 0 else states, m = nx - s
    cdef double *lin = scratch(2 * nx + nv)
    cdef double *h = lin + nx
    with nogil:
        for i in range(nx):
            p[K, i] = p_end[i]
        for k in range(K - 1, -1, -1):
            matmul(&P[k + 1, 0, 0], &b[k, 0], lin, nx, s, 1, True, False, False)
            for i in range(nx):
                lin[i] += p[k + 1, i]
            for i in range(nx):
                h[i] = qx[k, i]
            for i in range(nv):
                h[nx + i] = qv[k, i]
            matmul(&A[k, 0, 0], lin, h, nx, s, 1, True, False, True)
            matmul(&B[k, 0, 0], lin, h + nx, nv, s, 1, True, False, True)
            for i in range(m):
                h[nx + nv - m + i] += lin[s + i]
            for i in range(nv):
                ff[k, i] = -h[nx + i]
            cho_solve(&chol[k, 0, 0], &ff[k, 0], nv, 1)
            matmul(&Hxv[k, 0, 0], &ff[k, 0], h, nx, nv, 1, False, False, True)
            for i in range(nx):
                p[k, i] = h[i]
    free(lin)
    return None


def forward(const double[::1] X0, const double[:, :, ::1] A, const double[:, :, ::1] B,
            const double[:, ::1] b, const double[:, :, ::1] gain, const double[:, ::1] ff,
            double[:, ::1] X, double[:, ::1] v, int states=-1):
    """The forward pass from X_0: v_k = gain_k·X_k + ff_k, X_{k+1} = A_k·X_k + B_k·v_k + b_k.
    `states` s ≥ 0: as `factor`'s, and b's rows from s on are 0."""
    cdef int K = A.shape[0], nx = A.shape[1], nv = B.shape[2], k, i
    cdef int s = nx if states < 0 else states, m = nx - s
    with nogil:
        for i in range(nx):
            X[0, i] = X0[i]
        for k in range(K):
            for i in range(nv):
                v[k, i] = ff[k, i]
            matmul(&gain[k, 0, 0], &X[k, 0], &v[k, 0], nv, nx, 1, False, False, True)
            for i in range(s):
                X[k + 1, i] = b[k, i]
            matmul(&A[k, 0, 0], &X[k, 0], &X[k + 1, 0], s, nx, 1, False, False, True)
            matmul(&B[k, 0, 0], &v[k, 0], &X[k + 1, 0], s, nv, 1, False, False, True)
            for i in range(m):
                X[k + 1, s + i] = v[k, nv - m + i]
    return None
