/* lagrgen's native ODE core: see lg_ode.h. A line-by-line port of SciPy 1.17's
 * scipy/integrate/_ivp (BSD-3-Clause, Copyright (c) 2001-2002 Enthought, Inc. 2003, SciPy
 * Developers); each function names the SciPy function it ports. Operations are kept in SciPy's
 * order so that the step-size decisions, and hence the steps, are the same as solve_ivp's.
 */
#define _POSIX_C_SOURCE 200809L   /* clock_gettime under -std=c99 */
#include "lg_ode.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "lg_ode_tables.h"

#define EPS DBL_EPSILON
#define SAFETY 0.9
#define MIN_FACTOR 0.2
#define MAX_FACTOR 10.0
#define RADAU_NEWTON_MAXITER 6
#define BDF_NEWTON_MAXITER 4
#define BDF_MAX_ORDER 5
#define DOP_N_STAGES 12
#define DOP_N_EXTENDED 16

static const char MSG_TOO_SMALL[] = "Required step size is less than spacing between numbers.";

/* ------------------------------------------------------------------------------------------ */
/* Growable buffers                                                                            */

static int buf_reserve(lg_buf_t *b, size_t extra)
{
    if (b->len + extra <= b->cap)
        return 0;
    size_t cap = b->cap ? b->cap : 64;
    while (cap < b->len + extra)
        cap *= 2;
    double *d = (double *)realloc(b->data, cap * sizeof(double));
    if (!d)
        return -1;
    b->data = d;
    b->cap = cap;
    return 0;
}

int lg_buf_push(lg_buf_t *b, const double *x, size_t k)
{
    if (buf_reserve(b, k))
        return -1;
    memcpy(b->data + b->len, x, k * sizeof(double));
    b->len += k;
    return 0;
}

static int buf_push1(lg_buf_t *b, double x) { return lg_buf_push(b, &x, 1); }

void lg_result_free(lg_result_t *r)
{
    lg_buf_t *bufs[] = {&r->t, &r->y, &r->seg, &r->coef, &r->ev, &r->ev_y, &r->fail_y};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; ++i) {
        free(bufs[i]->data);
        bufs[i]->data = NULL;
        bufs[i]->len = bufs[i]->cap = 0;
    }
}

/* ------------------------------------------------------------------------------------------ */
/* Inputs                                                                                      */

/* The k with ts[k] <= t < ts[k+1] (searchsorted(ts, t, 'right') - 1), clipped to [lo, hi]. */
static int segment_of(const double *ts, int m, double t, int lo, int hi)
{
    int a = 0, b = m; /* first index with ts[i] > t lies in [a, b] */
    while (a < b) {
        int mid = (a + b) / 2;
        if (ts[mid] <= t)
            a = mid + 1;
        else
            b = mid;
    }
    int k = a - 1;
    return k < lo ? lo : (k > hi ? hi : k);
}

double lg_signal_eval(const lg_signal_t *s, double t)
{
    switch (s->kind) {
    case LG_SIGNAL_LINEAR: {
        /* numpy.interp: end values outside [ts[0], ts[m-1]], slope*(t - x_k) + f_k inside */
        if (!(t > s->ts[0]))
            return t == s->ts[0] || t < s->ts[0] ? s->values[0] : NAN;
        if (t >= s->ts[s->m - 1])
            return s->values[s->m - 1];
        int k = segment_of(s->ts, s->m, t, 0, s->m - 2);
        double slope = (s->values[k + 1] - s->values[k]) / (s->ts[k + 1] - s->ts[k]);
        return slope * (t - s->ts[k]) + s->values[k];
    }
    case LG_SIGNAL_PREVIOUS: {
        if (t < s->ts[0])
            return s->values[0];
        return s->values[segment_of(s->ts, s->m, t, 0, s->m - 1)];
    }
    case LG_SIGNAL_CUBIC: {
        /* scipy PPoly: the piece k with ts[k] <= t < ts[k+1], end pieces extrapolate */
        int k = segment_of(s->ts, s->m, t, 0, s->m - 2);
        const double *c = s->coef + 4 * k;
        double x = t - s->ts[k];
        return ((c[0] * x + c[1]) * x + c[2]) * x + c[3];
    }
    default:
        return s->value;
    }
}

/* A divisor b = br + i·bi prepared for Smith's quotient (1962): which part leads, the ratio r of
 * the other to it and the denominator d, so that dividing many numbers by one b (the diagonal
 * of U in the solves) takes two independent divisions each, bit for bit as cdiv. */
typedef struct {
    double r, d;
    int real_leads;     /* |br| >= |bi| */
} cdivisor_t;

/* ------------------------------------------------------------------------------------------ */
/* The solver state (one per solve; owned by lg_solve's stack frame and heap blocks)            */

typedef struct {
    const lg_problem_t *pb;
    const lg_options_t *op;
    int dim, method;
    double t, t_old, t_bound, direction, h_abs, max_step, rtol, newton_tol;
    const double *atol;
    double *y, *y_old, *y_new, *f, *u, *scale, *tmp, *tmp2, *ev_y, *acc;
    int model_error;     /* 1: rhs/jacobian returned nonzero at error_t, error_y */
    double error_t, *error_y;
    const char *fail_message;
    long nfev, njev, nlu;
    /* explicit Runge-Kutta */
    int n_stages, n_interp, lda;  /* stages; columns of P; row stride of A */
    const double *A, *B, *C, *E, *P;
    double error_exponent, h_previous;
    double *K;               /* (n_stages + 1) rows (16 for DOP853) of dim */
    /* dense output of the last step */
    int dense_ready;
    double *Q;               /* RK: dim x n_interp; DOP853: 7 x dim; Radau: dim x 3 */
    double dense_h;          /* BDF: h of the interpolant */
    int dense_order;         /* BDF: its order */
    double *dense_D;         /* BDF: (order + 1) x dim */
    /* implicit methods */
    double *J, *LU;          /* dim x dim */
    int *piv, *pivc;
    double *LUc;             /* complex: real parts, then imaginary parts */
    cdivisor_t *udiv;        /* the diagonal of LUc's U, prepared for division */
    int have_lu, current_jac;
    int half;                /* n when J = [[0, I], [A, B]] (second_order_half), else 0 */
    int lu_half;             /* n when LU (and LUc) hold the reduced factors, else 0 */
    double lu_alpha, lu_beta;        /* LU factors alpha I - beta J */
    double luc_re, luc_im;           /* LUc factors sigma I - J, sigma = luc_re + i luc_im */
    cdivisor_t sigma_div;            /* sigma, prepared for division */
    double h_abs_old, error_norm_old;
    int has_old;             /* Radau: h_abs_old / error_norm_old are not None */
    double *Z, *W, *dW, *F3, *Z0;   /* Radau: 3 x dim each */
    int have_sol;            /* Radau: self.sol is not None */
    double *D;               /* BDF: (MAX_ORDER + 3) x dim */
    int order, n_equal_steps;
    double alpha[6], gamma[6], error_const[6];
} solver_t;

static void eval_inputs(solver_t *s, double t)
{
    for (int i = 0; i < s->pb->n_inputs; ++i)
        s->u[i] = lg_signal_eval(&s->pb->inputs[i], t);
}

/* self.fun: one counted rhs evaluation. Returns nonzero (and records t) on a model failure. */
static int fun(solver_t *s, double t, const double *y, double *out)
{
    s->nfev++;
    eval_inputs(s, t);
    const lg_problem_t *pb = s->pb;
    int bad = (pb->sys_rhs ? pb->sys_rhs(pb->sys_ctx, t, y, s->u, out)
                           : pb->rhs(t, y, pb->p, s->u, out)) ? 1 : 0;
    if (!bad && s->op->stop_on_nonfinite) {
        double sum = 0.0;   /* NaN or inf anywhere makes the sum non-finite */
        for (int i = 0; i < s->dim; ++i)
            sum += out[i];
        if (!isfinite(sum))
            bad = 3;
    }
    if (bad) {
        s->model_error = bad;
        s->error_t = t;
        memcpy(s->error_y, y, s->dim * sizeof(double));
        return 1;
    }
    return 0;
}

static int second_order_half(const double *J, int dim);

/* self.jac: one counted analytic Jacobian evaluation into s->J (and s->half from its rows). */
static int jac(solver_t *s, double t, const double *y)
{
    s->njev++;
    eval_inputs(s, t);
    const lg_problem_t *pb = s->pb;
    if (pb->sys_jac ? pb->sys_jac(pb->sys_ctx, t, y, s->u, s->J)
                    : pb->jacobian(t, y, pb->p, s->u, s->J)) {
        s->model_error = 1;
        s->error_t = t;
        memcpy(s->error_y, y, s->dim * sizeof(double));
        return 1;
    }
    s->half = second_order_half(s->J, s->dim);
    return 0;
}

/* common.norm: RMS norm of x / scale, sqrt(sum x^2) / sqrt(n). */
static double rms_scaled(const double *x, const double *scale, int n)
{
    double s = 0.0;
    for (int i = 0; i < n; ++i) {
        double v = x[i] / scale[i];
        s += v * v;
    }
    return sqrt(s) / sqrt((double)n);
}

static double min_step_at(double t, double direction)
{
    return 10 * fabs(nextafter(t, direction * INFINITY) - t);
}

/* common.select_initial_step (Hairer, Norsett, Wanner I, II.4). */
static int select_initial_step(solver_t *s, double order, double *h_out)
{
    int n = s->dim;
    double interval = fabs(s->t_bound - s->t);
    if (n == 0) {
        *h_out = INFINITY;
        return 0;
    }
    if (interval == 0.0) {
        *h_out = 0.0;
        return 0;
    }
    double *scale = s->scale, *y1 = s->tmp, *f1 = s->tmp2;
    double d0 = 0, d1 = 0;
    for (int i = 0; i < n; ++i) {
        scale[i] = s->atol[i] + fabs(s->y[i]) * s->rtol;
        d0 += (s->y[i] / scale[i]) * (s->y[i] / scale[i]);
        d1 += (s->f[i] / scale[i]) * (s->f[i] / scale[i]);
    }
    d0 = sqrt(d0) / sqrt((double)n);
    d1 = sqrt(d1) / sqrt((double)n);
    double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    h0 = fmin(h0, interval);
    for (int i = 0; i < n; ++i)
        y1[i] = s->y[i] + h0 * s->direction * s->f[i];
    if (fun(s, s->t + h0 * s->direction, y1, f1))
        return 1;
    double d2 = 0;
    for (int i = 0; i < n; ++i) {
        double v = (f1[i] - s->f[i]) / scale[i];
        d2 += v * v;
    }
    d2 = sqrt(d2) / sqrt((double)n) / h0;
    double h1;
    if (d1 <= 1e-15 && d2 <= 1e-15)
        h1 = fmax(1e-6, h0 * 1e-3);
    else
        h1 = pow(0.01 / fmax(d1, d2), 1.0 / (order + 1));
    *h_out = fmin(fmin(100 * h0, h1), fmin(interval, s->max_step));
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* Dense LU with partial pivoting in LAPACK's column order (getf2: the first largest |a| for real,
 * the first largest |re| + |im| for complex, then a rank-1 update column by column that skips a
 * zero multiplier a_kj; getrs/trsv: every b[i] takes its updates in the order j = 0, 1, ...).
 * The matrices are stored column-major (a[i + j·n] = A_ij) so that every update runs down a
 * contiguous column; a complex matrix as its real part then its imaginary part (each n × n,
 * column-major) and a complex vector as n real parts then n imaginary parts.                   */

/* y[i] -= alpha·x[i], i < len */
static inline void axpy_sub(double *restrict y, const double *restrict x, double alpha, int len)
{
    for (int i = 0; i < len; ++i)
        y[i] -= alpha * x[i];
}

/* Swap rows k and p of the n × n column-major matrix a. */
static void swap_rows(double *a, int n, int k, int p)
{
    for (int j = 0; j < n; ++j) {
        double t = a[k + (size_t)j * n];
        a[k + (size_t)j * n] = a[p + (size_t)j * n];
        a[p + (size_t)j * n] = t;
    }
}

static int lu_real(double *a, int *piv, int n)
{
    int info = 0;
    for (int k = 0; k < n; ++k) {
        double *ak = a + (size_t)k * n;
        int p = k;
        double best = fabs(ak[k]);
        for (int i = k + 1; i < n; ++i)
            if (fabs(ak[i]) > best) {
                best = fabs(ak[i]);
                p = i;
            }
        piv[k] = p;
        if (ak[p] == 0.0) {
            if (!info)
                info = k + 1;
            continue;
        }
        if (p != k)
            swap_rows(a, n, k, p);
        double inv = 1.0 / ak[k];
        for (int i = k + 1; i < n; ++i)
            ak[i] *= inv;
        for (int j = k + 1; j < n; ++j) {
            double *aj = a + (size_t)j * n;
            if (aj[k] != 0.0)
                axpy_sub(aj + k + 1, ak + k + 1, aj[k], n - k - 1);
        }
    }
    return info;
}

static void lower_solve(const double *restrict a, int n, double *restrict b);
static void upper_solve(const double *restrict a, int n, double *restrict b);

/* Solve A x = b in place from the factors: row interchanges, then L (unit) and U column by
 * column. */
static void lu_solve_real(const double *a, const int *piv, int n, double *b)
{
    for (int k = 0; k < n; ++k)
        if (piv[k] != k) {
            double t = b[k];
            b[k] = b[piv[k]];
            b[piv[k]] = t;
        }
    lower_solve(a, n, b);
    upper_solve(a, n, b);
}

/* Complex numbers with the textbook product (as Fortran's complex multiply) and Smith's
 * quotient: no calls to the C runtime's NaN-checking __muldc3. */

static cdivisor_t cdivisor(double br, double bi)
{
    cdivisor_t q;
    q.real_leads = fabs(br) >= fabs(bi);
    q.r = q.real_leads ? bi / br : br / bi;
    q.d = q.real_leads ? br + bi * q.r : bi + br * q.r;
    return q;
}

/* (qr, qi) = (ar, ai) / b for b prepared by cdivisor. */
static inline void cdiv_by(double ar, double ai, const cdivisor_t *q, double *qr, double *qi)
{
    double re, im;
    if (q->real_leads) {
        re = (ar + ai * q->r) / q->d;
        im = (ai - ar * q->r) / q->d;
    } else {
        re = (ar * q->r + ai) / q->d;
        im = (ai * q->r - ar) / q->d;
    }
    *qr = re;
    *qi = im;
}

/* (qr, qi) = (ar, ai) / (br, bi) (Smith 1962) */
static void cdiv(double ar, double ai, double br, double bi, double *qr, double *qi)
{
    cdivisor_t q = cdivisor(br, bi);
    cdiv_by(ar, ai, &q, qr, qi);
}

/* (yr, yi)[i] -= (xr, xi)·(lr, li)[i], i < len: a complex axpy on split parts. */
static inline void caxpy_sub(double *restrict yr, double *restrict yi, const double *restrict lr,
                             const double *restrict li, double xr, double xi, int len)
{
    for (int i = 0; i < len; ++i) {
        yr[i] -= xr * lr[i] - xi * li[i];
        yi[i] -= xr * li[i] + xi * lr[i];
    }
}

/* Complex LU with partial pivoting; a holds the real then the imaginary part (see above). */
static int lu_complex(double *a, int *piv, int n)
{
    int info = 0;
    size_t nn = (size_t)n * n;
    double *re = a, *im = a + nn;
    for (int k = 0; k < n; ++k) {
        double *kr = re + (size_t)k * n, *ki = im + (size_t)k * n;
        int p = k;
        double best = fabs(kr[k]) + fabs(ki[k]);
        for (int i = k + 1; i < n; ++i)
            if (fabs(kr[i]) + fabs(ki[i]) > best) {
                best = fabs(kr[i]) + fabs(ki[i]);
                p = i;
            }
        piv[k] = p;
        if (kr[p] == 0.0 && ki[p] == 0.0) {
            if (!info)
                info = k + 1;
            continue;
        }
        if (p != k) {
            swap_rows(re, n, k, p);
            swap_rows(im, n, k, p);
        }
        double inv_r, inv_i;
        cdiv(1.0, 0.0, kr[k], ki[k], &inv_r, &inv_i);
        for (int i = k + 1; i < n; ++i) {
            double lr = kr[i] * inv_r - ki[i] * inv_i;
            double li = kr[i] * inv_i + ki[i] * inv_r;
            kr[i] = lr;
            ki[i] = li;
        }
        for (int j = k + 1; j < n; ++j) {
            double *jr = re + (size_t)j * n, *ji = im + (size_t)j * n;
            if (jr[k] != 0.0 || ji[k] != 0.0)
                caxpy_sub(jr + k + 1, ji + k + 1, kr + k + 1, ki + k + 1, jr[k], ji[k],
                          n - k - 1);
        }
    }
    return info;
}

/* The triangular solves of getrs for the real systems (BDF, Radau's error estimate; trsv's
 * column order: b[i] −= b[j]·L_ij for j = 0, 1, …, each column skipped where b[j] = 0; backward
 * b[j] /= U_jj then b[i] −= b[j]·U_ij for j = n−1, …, 0), four columns at a time: within a block
 * the four b[j] are finished first, then every other b[i] is held in a register through its four
 * updates, taken in the same order (sub_four). Each b[i] thus sees the very same operations as
 * column by column; a block with a zero b[j] goes column by column (to skip exactly what trsv
 * skips). */

/* b[i] −= x_0·col_0[i], then x_1·col_1[i], x_2·col_2[i], x_3·col_3[i], for i < len (each b[i] held
 * in a register through its four updates); a column whose z_c is 0 is skipped (then column by
 * column, as trsv). */
static inline void sub_four(double *restrict b, int len, const double *const col[4],
                            const double x[4], const int z[4])
{
    if (z[0] && z[1] && z[2] && z[3]) {
        const double *restrict c0 = col[0], *restrict c1 = col[1], *restrict c2 = col[2],
                               *restrict c3 = col[3];
        const double x0 = x[0], x1 = x[1], x2 = x[2], x3 = x[3];
        for (int i = 0; i < len; ++i) {
            double t = b[i];
            t -= x0 * c0[i];
            t -= x1 * c1[i];
            t -= x2 * c2[i];
            t -= x3 * c3[i];
            b[i] = t;
        }
    } else {
        for (int c = 0; c < 4; ++c)
            if (z[c])
                axpy_sub(b, col[c], x[c], len);
    }
}

/* b := L⁻¹·b, L the unit lower triangle of the column-major n × n a. */
static void lower_solve(const double *restrict a, int n, double *restrict b)
{
    int j = 0;
    for (; j + 4 <= n; j += 4) {
        const double *c0 = a + (size_t)j * n, *c1 = c0 + n, *c2 = c1 + n, *c3 = c2 + n;
        const double x0 = b[j];
        if (x0 != 0.0) {
            b[j + 1] -= x0 * c0[j + 1];
            b[j + 2] -= x0 * c0[j + 2];
            b[j + 3] -= x0 * c0[j + 3];
        }
        const double x1 = b[j + 1];
        if (x1 != 0.0) {
            b[j + 2] -= x1 * c1[j + 2];
            b[j + 3] -= x1 * c1[j + 3];
        }
        const double x2 = b[j + 2];
        if (x2 != 0.0)
            b[j + 3] -= x2 * c2[j + 3];
        const double x[4] = {x0, x1, x2, b[j + 3]};
        const int z[4] = {x0 != 0.0, x1 != 0.0, x2 != 0.0, x[3] != 0.0};
        const double *col[4] = {c0 + j + 4, c1 + j + 4, c2 + j + 4, c3 + j + 4};
        sub_four(b + j + 4, n - j - 4, col, x, z);
    }
    for (; j < n; ++j)
        if (b[j] != 0.0)
            axpy_sub(b + j + 1, a + (size_t)j * n + j + 1, b[j], n - j - 1);
}

/* b := U⁻¹·b, U the upper triangle (with its diagonal) of the column-major n × n a. */
static void upper_solve(const double *restrict a, int n, double *restrict b)
{
    int j = n - 1;
    for (; j >= 3; j -= 4) {
        const double *c0 = a + (size_t)j * n, *c1 = c0 - n, *c2 = c1 - n, *c3 = c2 - n;
        const int z0 = b[j] != 0.0;
        if (z0) {
            b[j] /= c0[j];
            b[j - 1] -= b[j] * c0[j - 1];
            b[j - 2] -= b[j] * c0[j - 2];
            b[j - 3] -= b[j] * c0[j - 3];
        }
        const int z1 = b[j - 1] != 0.0;
        if (z1) {
            b[j - 1] /= c1[j - 1];
            b[j - 2] -= b[j - 1] * c1[j - 2];
            b[j - 3] -= b[j - 1] * c1[j - 3];
        }
        const int z2 = b[j - 2] != 0.0;
        if (z2) {
            b[j - 2] /= c2[j - 2];
            b[j - 3] -= b[j - 2] * c2[j - 3];
        }
        const int z3 = b[j - 3] != 0.0;
        if (z3)
            b[j - 3] /= c3[j - 3];
        const double x[4] = {b[j], b[j - 1], b[j - 2], b[j - 3]};
        const int z[4] = {z0, z1, z2, z3};
        const double *col[4] = {c0, c1, c2, c3};
        sub_four(b, j - 3, col, x, z);
    }
    for (; j >= 0; --j)
        if (b[j] != 0.0) {
            b[j] /= a[j + (size_t)j * n];
            axpy_sub(b, a + (size_t)j * n, b[j], j);
        }
}

/* ------------------------------------------------------------------------------------------ */
/* The Newton iteration matrices of Radau and BDF: alpha I - beta J, factored and solved        */

/* Second-order systems. For y = [q, q̇] (dim = 2n) the Jacobian is J = [[0, I], [A, B]] (n × n
 * blocks), so that
 *     αI − βJ = [[αI, −βI], [−βA, αI − βB]].
 * Gaussian elimination of its first n columns with the pivots α (what getf2's partial pivoting
 * does when no |β·A_ik| exceeds |α|) leaves the multipliers L = −βA/α and the Schur complement
 * S = αI − βB − L·(−β) (det(αI − βJ) = αⁿ det S), and (αI − βJ)·[x1; x2] = [r1; r2] becomes
 *     S·x2 = r2 − L·r1,   x1 = (r1 + β·x2) / α:
 * one LU of n × n instead of 2n × 2n (8× fewer flops) and solves 2× cheaper. Each entry is
 * computed with the operations getf2 and getrs apply to it on the full matrix, in their order,
 * so the answers are the full path's bit for bit. BDF's I − cJ is α = 1, β = c; Radau's σI − J
 * is β = 1 with the real σ, and the complex one for its second system. The reduction is used when
 * the top rows of J are exactly [0 | I] (checked at every Jacobian: the models' jacobian writes
 * them so; an augmented system, such as the forward sensitivities, keeps the full matrices) and
 * partial pivoting keeps the first n pivots (checked at every factorization); otherwise the
 * 2n × 2n matrices are factored. With the reduction, LU holds S's factors (n × n, column-major)
 * then L (n × n), and LUc S's then L's real parts, then their imaginary parts. */

/* n when the top half of the row-major dim × dim J is exactly [0 | I] (dim = 2n), else 0. */
static int second_order_half(const double *J, int dim)
{
    if (dim % 2)
        return 0;
    int n = dim / 2;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < dim; ++j)
            if (J[(size_t)i * dim + j] != (j == n + i ? 1.0 : 0.0))
                return 0;
    return n;
}

/* Row i of the block A of J (row-major, 2n wide); row i of B follows it. */
static inline const double *block_A(const double *J, int n, int i)
{
    return J + (size_t)(n + i) * 2 * n;
}

/* S and L (column-major n × n) of αI − βJ; 0 when partial pivoting would leave the first n
 * pivots (a |β·A_ik| > |α|): then neither is usable. */
static int schur_real(const double *J, int n, double alpha, double beta, double *S, double *L)
{
    const double inv = 1.0 / alpha;
    for (int i = 0; i < n; ++i) {
        const double *A = block_A(J, n, i), *B = A + n;
        for (int k = 0; k < n; ++k) {
            size_t c = i + (size_t)k * n;
            double a = 0.0 - beta * A[k];
            if (!(fabs(a) <= fabs(alpha)))
                return 0;
            L[c] = a * inv;
            S[c] = ((i == k ? alpha : 0.0) - beta * B[k]) - (-beta) * L[c];
        }
    }
    return 1;
}

/* S and L of σI − J for σ = sr + i·si, each as its real then its imaginary part (LUc's layout);
 * 0 when partial pivoting would leave the first n pivots (an |A_ik| > |sr| + |si|). */
static int schur_complex(const double *J, int n, double sr, double si, double *S, double *L)
{
    const size_t nn = (size_t)n * n;
    double inv_r, inv_i;
    cdiv(1.0, 0.0, sr, si, &inv_r, &inv_i);
    for (int i = 0; i < n; ++i) {
        const double *A = block_A(J, n, i), *B = A + n;
        for (int k = 0; k < n; ++k) {
            size_t c = i + (size_t)k * n;
            double ar = 0.0 - A[k], ai = 0.0;
            if (!(fabs(ar) + fabs(ai) <= fabs(sr) + fabs(si)))
                return 0;
            double lr = ar * inv_r - ai * inv_i, li = ar * inv_i + ai * inv_r;
            L[c] = lr;
            L[nn + c] = li;
            /* minus U_k,n+k = −1 + 0i times the multiplier, as caxpy_sub */
            S[c] = ((i == k ? sr : 0.0) - B[k]) - (-1.0 * lr - 0.0 * li);
            S[nn + c] = (i == k ? si : 0.0) - (-1.0 * li + 0.0 * lr);
        }
    }
    return 1;
}

/* s->LU, s->piv := the LU of the full dim × dim αI − βJ (s->lu_half = 0). */
static void factor_real_full(solver_t *s, double alpha, double beta)
{
    int n = s->dim;
    s->lu_half = 0;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            s->LU[i + (size_t)j * n] = (i == j ? alpha : 0.0) - beta * s->J[i * n + j];
    lu_real(s->LU, s->piv, n);
}

/* s->LU, s->piv := the LU of αI − βJ, or S's and L (s->lu_half = n) where they apply. */
static void factor_real(solver_t *s, double alpha, double beta)
{
    int n = s->half;
    s->lu_alpha = alpha;
    s->lu_beta = beta;
    if (n && schur_real(s->J, n, alpha, beta, s->LU, s->LU + (size_t)n * n)) {
        s->lu_half = n;
        lu_real(s->LU, s->piv, n);
    } else {
        factor_real_full(s, alpha, beta);
    }
}

/* s->LUc, s->pivc := the LU of σI − J, or S's and L when the real system was reduced too
 * (solve_real_complex takes both alike). Radau's |σ| exceeds its real one's, so the second test
 * passes whenever the first did; should it not, both systems are factored in full. */
static void factor_complex(solver_t *s, double sr, double si)
{
    int n = s->lu_half;
    s->luc_re = sr;
    s->luc_im = si;
    s->sigma_div = cdivisor(sr, si);
    if (!(n && schur_complex(s->J, n, sr, si, s->LUc, s->LUc + 2 * (size_t)n * n))) {
        if (n)
            factor_real_full(s, s->lu_alpha, s->lu_beta);
        n = s->dim;
        size_t nn = (size_t)n * n;
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                size_t c = i + (size_t)j * n;
                s->LUc[c] = (i == j ? sr : 0.0) - s->J[i * n + j];
                s->LUc[nn + c] = i == j ? si : 0.0;
            }
    }
    lu_complex(s->LUc, s->pivc, n);
    for (int k = 0; k < n; ++k)
        s->udiv[k] = cdivisor(s->LUc[k + (size_t)k * n], s->LUc[(size_t)n * n + k + (size_t)k * n]);
}

/* b2 := b2 − L·b1, column by column (as the full lower solve's first n columns). */
static void eliminate_real(const double *L, int n, const double *b1, double *b2)
{
    for (int k = 0; k < n; ++k)
        if (b1[k] != 0.0)
            axpy_sub(b2, L + (size_t)k * n, b1[k], n);
}

/* Solve (αI − βJ)·x = b in place (b: dim values) with the factors of factor_real. */
static void solve_real(const solver_t *s, double *b)
{
    int n = s->lu_half;
    if (!n) {
        lu_solve_real(s->LU, s->piv, s->dim, b);
        return;
    }
    const double alpha = s->lu_alpha, beta = s->lu_beta;
    eliminate_real(s->LU + (size_t)n * n, n, b, b + n);
    lu_solve_real(s->LU, s->piv, n, b + n);
    for (int i = 0; i < n; ++i)
        b[i] = (b[i] + beta * b[n + i]) / alpha;
}

/* A real and a complex system from their factors (a, piv: real n × n; c, pivc, udiv: complex), each
 * solved like lu_solve_real (same arithmetic), with the two systems' sweeps interleaved column
 * by column so that their chains of dependent updates (each column waits for the previous one's
 * division) overlap in the processor. x: the real right-hand side; (br, bi): the complex one. */
static void lu_solve_pair(const double *a, const int *piv, const double *c, const int *pivc,
                          const cdivisor_t *udiv, int n, double *x, double *br, double *bi)
{
    size_t nn = (size_t)n * n;
    const double *re = c, *im = c + nn;
    for (int k = 0; k < n; ++k) {
        if (piv[k] != k) {
            double t = x[k];
            x[k] = x[piv[k]];
            x[piv[k]] = t;
        }
        if (pivc[k] != k) {
            int q = pivc[k];
            double tr = br[k], ti = bi[k];
            br[k] = br[q];
            bi[k] = bi[q];
            br[q] = tr;
            bi[q] = ti;
        }
    }
    for (int j = 0; j < n; ++j) {
        size_t o = (size_t)j * n + j + 1;
        if (x[j] != 0.0)
            axpy_sub(x + j + 1, a + o, x[j], n - j - 1);
        if (br[j] != 0.0 || bi[j] != 0.0)
            caxpy_sub(br + j + 1, bi + j + 1, re + o, im + o, br[j], bi[j], n - j - 1);
    }
    for (int j = n - 1; j >= 0; --j) {
        size_t o = (size_t)j * n;
        if (x[j] != 0.0) {
            x[j] /= a[o + j];
            axpy_sub(x, a + o, x[j], j);
        }
        if (br[j] != 0.0 || bi[j] != 0.0) {
            cdiv_by(br[j], bi[j], udiv + j, br + j, bi + j);
            caxpy_sub(br, bi, re + o, im + o, br[j], bi[j], j);
        }
    }
}

/* Solve (αI − βJ)·x = b and (σI − J)·z = d in place with the factors of factor_real and
 * factor_complex: b holds the real right-hand side (dim), then d's real and imaginary parts. */
static void solve_real_complex(const solver_t *s, double *b)
{
    int dim = s->dim, n = s->lu_half;
    double *x = b, *br = b + dim, *bi = b + 2 * dim;
    if (!n) {
        lu_solve_pair(s->LU, s->piv, s->LUc, s->pivc, s->udiv, dim, x, br, bi);
        return;
    }
    const size_t nn = (size_t)n * n;
    const double *Lr = s->LUc + 2 * nn, *Li = Lr + nn;
    eliminate_real(s->LU + nn, n, x, x + n);
    for (int k = 0; k < n; ++k)   /* d2 −= L·d1, as the full complex lower solve */
        if (br[k] != 0.0 || bi[k] != 0.0)
            caxpy_sub(br + n, bi + n, Lr + (size_t)k * n, Li + (size_t)k * n, br[k], bi[k], n);
    lu_solve_pair(s->LU, s->piv, s->LUc, s->pivc, s->udiv, n, x + n, br + n, bi + n);
    const double alpha = s->lu_alpha, beta = s->lu_beta;
    for (int i = 0; i < n; ++i) {
        x[i] = (x[i] + beta * x[n + i]) / alpha;
        cdiv_by(br[i] + br[n + i], bi[i] + bi[n + i], &s->sigma_div, br + i, bi + i);
    }
}

/* ------------------------------------------------------------------------------------------ */
/* Explicit Runge-Kutta: rk.py (RungeKutta, RK23, RK45, DOP853)                                */

/* acc[i] = sum_{j < m} K[j][i] c[j], summed from 0.0 in the order j = 0, 1, ... (as a dot
 * product over j for each i), eight i at a time held in registers (four independent chains of
 * two-lane vectors where GCC's vector extension is available). */
#if defined(__GNUC__)
typedef double lg_v2 __attribute__((vector_size(16)));

static inline lg_v2 load2(const double *x)
{
    lg_v2 v;
    memcpy(&v, x, sizeof v);
    return v;
}
#endif

static void combine(const double *restrict K, const double *restrict c, int m, int n,
                    double *restrict acc)
{
    int i = 0;
#if defined(__GNUC__)
    for (; i + 8 <= n; i += 8) {
        lg_v2 s0 = {0.0, 0.0}, s1 = s0, s2 = s0, s3 = s0;
        const double *Kj = K + i;
        for (int j = 0; j < m; ++j, Kj += n) {
            const lg_v2 cj = {c[j], c[j]};
            s0 += load2(Kj) * cj;
            s1 += load2(Kj + 2) * cj;
            s2 += load2(Kj + 4) * cj;
            s3 += load2(Kj + 6) * cj;
        }
        memcpy(acc + i, &s0, sizeof s0);
        memcpy(acc + i + 2, &s1, sizeof s1);
        memcpy(acc + i + 4, &s2, sizeof s2);
        memcpy(acc + i + 6, &s3, sizeof s3);
    }
#endif
    for (; i < n; ++i) {
        double s = 0.0;
        for (int j = 0; j < m; ++j)
            s += K[(size_t)j * n + i] * c[j];
        acc[i] = s;
    }
}

/* rk.rk_step: stages K[s] = f(t + c_s h, y + h sum_j a_sj K[j]); y_new = y + h sum_j b_j K[j];
 * K[n_stages] = f(t + h, y_new). */
static int rk_step(solver_t *s, double t, const double *y, double h, double *y_new)
{
    int n = s->dim, ns = s->n_stages;
    int lda = s->lda;
    double *K = s->K, *ys = s->tmp, *acc = s->acc;
    memcpy(K, s->f, n * sizeof(double));
    for (int st = 1; st < ns; ++st) {
        const double *a = s->A + st * lda;
        combine(K, a, st, n, acc);
        for (int i = 0; i < n; ++i)
            ys[i] = y[i] + acc[i] * h;
        if (fun(s, t + s->C[st] * h, ys, K + st * n))
            return 1;
    }
    combine(K, s->B, ns, n, acc);
    for (int i = 0; i < n; ++i)
        y_new[i] = y[i] + h * acc[i];
    return fun(s, t + h, y_new, K + ns * n);
}

/* RungeKutta._estimate_error_norm: RMS of h K^T E / scale (RK23, RK45). */
static double rk_error_norm(solver_t *s, double h)
{
    int n = s->dim, ns = s->n_stages;
    double acc = 0.0, *e = s->acc;
    combine(s->K, s->E, ns + 1, n, e);
    for (int i = 0; i < n; ++i) {
        double v = e[i] * h / s->scale[i];
        acc += v * v;
    }
    return sqrt(acc) / sqrt((double)n);
}

/* DOP853._estimate_error_norm: |h| |e5|^2 / sqrt((|e5|^2 + 0.01 |e3|^2) n). */
static double dop853_error_norm(solver_t *s, double h)
{
    int n = s->dim;
    double a5 = 0.0, a3 = 0.0, *e5 = s->acc, *e3 = s->tmp;
    combine(s->K, DOP_E5, DOP_N_STAGES + 1, n, e5);
    combine(s->K, DOP_E3, DOP_N_STAGES + 1, n, e3);
    for (int i = 0; i < n; ++i) {
        double v5 = e5[i] / s->scale[i], v3 = e3[i] / s->scale[i];
        a5 += v5 * v5;
        a3 += v3 * v3;
    }
    double n5 = sqrt(a5), n3 = sqrt(a3);
    double n5_2 = n5 * n5, n3_2 = n3 * n3;
    if (n5_2 == 0 && n3_2 == 0)
        return 0.0;
    double denom = n5_2 + 0.01 * n3_2;
    return fabs(h) * n5_2 / sqrt(denom * n);
}

/* RungeKutta._step_impl. Returns 0 ok, 1 step failure (fail_message), 2 model failure. */
static int rk_step_impl(solver_t *s)
{
    int n = s->dim;
    double t = s->t;
    double min_step = min_step_at(t, s->direction);
    double h_abs = s->h_abs > s->max_step ? s->max_step
                   : (s->h_abs < min_step ? min_step : s->h_abs);
    int accepted = 0, rejected = 0;
    double h = 0, t_new = t, *y_new = s->y_old; /* y_old's storage is reused for y_new */
    const double *y = s->y;   /* unchanged during the step: y_new goes to y_old's storage */
    while (!accepted) {
        if (h_abs < min_step) {
            s->fail_message = MSG_TOO_SMALL;
            return 1;
        }
        h = h_abs * s->direction;
        t_new = t + h;
        if (s->direction * (t_new - s->t_bound) > 0)
            t_new = s->t_bound;
        h = t_new - t;
        h_abs = fabs(h);
        if (rk_step(s, t, y, h, y_new))
            return 2;
        for (int i = 0; i < n; ++i)
            s->scale[i] = s->atol[i] + fmax(fabs(y[i]), fabs(y_new[i])) * s->rtol;
        double err = s->method == LG_DOP853 ? dop853_error_norm(s, h) : rk_error_norm(s, h);
        if (err < 1) {
            double factor = err == 0 ? MAX_FACTOR
                                     : fmin(MAX_FACTOR, SAFETY * pow(err, s->error_exponent));
            if (rejected)
                factor = fmin(1, factor);
            h_abs *= factor;
            accepted = 1;
        } else {
            h_abs *= fmax(MIN_FACTOR, SAFETY * pow(err, s->error_exponent));
            rejected = 1;
        }
    }
    s->h_previous = h;
    /* y_old <- y, y <- y_new (swap storage) */
    double *ynew = s->y_old;
    s->y_old = s->y;
    s->y = ynew;
    s->t = t_new;
    s->h_abs = h_abs;
    memcpy(s->f, s->K + s->n_stages * n, n * sizeof(double));
    return 0;
}

/* RungeKutta._dense_output_impl: Q = K^T P (dim x n_interp). DOP853: three more stages and
 * F (7 x dim) as in DOP853._dense_output_impl. */
static int rk_dense_prepare(solver_t *s)
{
    int n = s->dim;
    double *K = s->K;
    if (s->method != LG_DOP853) {
        int m = s->n_interp;
        for (int i = 0; i < n; ++i)
            for (int c = 0; c < m; ++c) {
                double acc = 0.0;
                for (int j = 0; j <= s->n_stages; ++j)
                    acc += K[j * n + i] * s->P[j * m + c];
                s->Q[i * m + c] = acc;
            }
        return 0;
    }
    double h = s->h_previous, *ys = s->tmp;
    for (int st = DOP_N_STAGES + 1; st < DOP_N_EXTENDED; ++st) {
        combine(K, DOP_A + st * DOP_N_EXTENDED, st, n, s->acc);
        for (int i = 0; i < n; ++i)
            ys[i] = s->y_old[i] + s->acc[i] * h;
        if (fun(s, s->t_old + DOP_C[st] * h, ys, K + st * n))
            return 1;
    }
    double *F = s->Q;
    for (int i = 0; i < n; ++i) {
        double dy = s->y[i] - s->y_old[i], f_old = K[i];
        F[0 * n + i] = dy;
        F[1 * n + i] = h * f_old - dy;
        F[2 * n + i] = 2 * dy - h * (s->f[i] + f_old);
    }
    for (int r = 0; r < 4; ++r) {
        double *Fr = F + (3 + r) * n;
        combine(K, DOP_D + r * DOP_N_EXTENDED, DOP_N_EXTENDED, n, Fr);
        for (int i = 0; i < n; ++i)
            Fr[i] *= h;
    }
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* Radau IIA order 5: radau.py                                                                 */

/* The iteration matrices MU_REAL/h I - J and MU_COMPLEX/h I - J, factored (self.lu twice). */
static void radau_factor(solver_t *s, double h)
{
    factor_real(s, RADAU_MU_REAL / h, 1.0);
    factor_complex(s, RADAU_MU_COMPLEX_RE / h, RADAU_MU_COMPLEX_IM / h);
    s->nlu += 2;
    s->have_lu = 1;
}

/* radau.solve_collocation_system: simplified Newton iterations in the transformed variables W.
 * Z0 is the initial guess (3 x dim). Returns converged; sets *n_iter, *rate, s->Z. Model
 * failure: returns -1. */
static int radau_collocation(solver_t *s, double t, const double *y, double h, double tol,
                             int *n_iter, double *rate_out, int *has_rate)
{
    int n = s->dim;
    double mr = RADAU_MU_REAL / h;
    double mcr = RADAU_MU_COMPLEX_RE / h, mci = RADAU_MU_COMPLEX_IM / h;
    double *W = s->W, *Z = s->Z, *F = s->F3, *dW = s->dW, *ys = s->tmp;
    /* W = TI Z0; Z = Z0 */
    for (int r = 0; r < 3; ++r)
        for (int i = 0; i < n; ++i)
            W[r * n + i] = RADAU_TI[r * 3 + 0] * s->Z0[i] + RADAU_TI[r * 3 + 1] * s->Z0[n + i]
                           + RADAU_TI[r * 3 + 2] * s->Z0[2 * n + i];
    memcpy(Z, s->Z0, 3 * n * sizeof(double));
    double dW_norm_old = 0, rate = 0;
    int has_old = 0, hr = 0, converged = 0, k;
    for (k = 0; k < RADAU_NEWTON_MAXITER; ++k) {
        int finite = 1;
        for (int r = 0; r < 3; ++r) {
            for (int i = 0; i < n; ++i)
                ys[i] = y[i] + Z[r * n + i];
            if (fun(s, t + h * RADAU_C[r], ys, F + r * n))
                return -1;
        }
        for (int i = 0; i < 3 * n; ++i)
            if (!isfinite(F[i]))
                finite = 0;
        if (!finite)
            break;
        /* f_real = F^T TI_REAL - M_real W0; f_complex = F^T TI_COMPLEX - M_complex (W1 + i W2)
         * with TI_COMPLEX = TI[1] + i TI[2]; solved in place in dW = [real, complex re, im] */
        double *fr = dW, *fcr = dW + n, *fci = dW + 2 * n;
        for (int i = 0; i < n; ++i) {
            double a0 = F[i], a1 = F[n + i], a2 = F[2 * n + i];
            fr[i] = (a0 * RADAU_TI[0] + a1 * RADAU_TI[1] + a2 * RADAU_TI[2]) - mr * W[i];
            double wr = W[n + i], wi = W[2 * n + i];
            fcr[i] = (a0 * RADAU_TI[3] + a1 * RADAU_TI[4] + a2 * RADAU_TI[5])
                     - (mcr * wr - mci * wi);
            fci[i] = (a0 * RADAU_TI[6] + a1 * RADAU_TI[7] + a2 * RADAU_TI[8])
                     - (mcr * wi + mci * wr);
        }
        solve_real_complex(s, dW);
        double acc = 0.0;
        for (int r = 0; r < 3; ++r)
            for (int i = 0; i < n; ++i) {
                double v = dW[r * n + i] / s->scale[i];
                acc += v * v;
            }
        double dW_norm = sqrt(acc) / sqrt((double)(3 * n));
        if (has_old) {
            rate = dW_norm / dW_norm_old;
            hr = 1;
        }
        if (hr && (rate >= 1 || pow(rate, RADAU_NEWTON_MAXITER - k) / (1 - rate) * dW_norm > tol))
            break;
        for (int i = 0; i < 3 * n; ++i)
            W[i] += dW[i];
        for (int r = 0; r < 3; ++r)
            for (int i = 0; i < n; ++i)
                Z[r * n + i] = RADAU_T[r * 3 + 0] * W[i] + RADAU_T[r * 3 + 1] * W[n + i]
                               + RADAU_T[r * 3 + 2] * W[2 * n + i];
        if (dW_norm == 0 || (hr && rate / (1 - rate) * dW_norm < tol)) {
            converged = 1;
            break;
        }
        dW_norm_old = dW_norm;
        has_old = 1;
    }
    *n_iter = (k < RADAU_NEWTON_MAXITER ? k : RADAU_NEWTON_MAXITER - 1) + 1;
    *rate_out = rate;
    *has_rate = hr;
    return converged;
}

/* radau.predict_factor (Hairer & Wanner II, IV.8). */
static double radau_predict_factor(double h_abs, double h_abs_old, double err, double err_old,
                                   int has_old)
{
    double mult = (!has_old || err == 0) ? 1.0 : h_abs / h_abs_old * pow(err_old / err, 0.25);
    return fmin(1, mult) * pow(err, -0.25);
}

/* RadauDenseOutput evaluation at t: y_old + Q x^k (k = 1..3), x = (t - t_old) / h. */
static void radau_dense_from(solver_t *s, double t_old, double t_new, const double *y_old,
                             double t, double *out)
{
    int n = s->dim;
    double x = (t - t_old) / (t_new - t_old);
    double p0 = x, p1 = p0 * x, p2 = p1 * x;
    for (int i = 0; i < n; ++i)
        out[i] = (s->Q[i * 3] * p0 + s->Q[i * 3 + 1] * p1 + s->Q[i * 3 + 2] * p2) + y_old[i];
}

/* Radau._compute_dense_output: Q = Z^T P (dim x 3). */
static void radau_compute_dense(solver_t *s)
{
    int n = s->dim;
    for (int i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c)
            s->Q[i * 3 + c] = s->Z[i] * RADAU_P[c] + s->Z[n + i] * RADAU_P[3 + c]
                              + s->Z[2 * n + i] * RADAU_P[6 + c];
}

/* Radau._step_impl. Returns 0 ok, 1 step failure, 2 model failure. */
static int radau_step_impl(solver_t *s)
{
    int n = s->dim;
    double t = s->t, *y = s->y;
    double min_step = min_step_at(t, s->direction);
    double h_abs, h_abs_old = s->h_abs_old, err_old = s->error_norm_old;
    int has_old = s->has_old;
    if (s->h_abs > s->max_step) {
        h_abs = s->max_step;
        has_old = 0;
    } else if (s->h_abs < min_step) {
        h_abs = min_step;
        has_old = 0;
    } else {
        h_abs = s->h_abs;
    }
    int current_jac = s->current_jac, rejected = 0, accepted = 0, n_iter = 0, has_rate = 0;
    double h = 0, t_new = t, rate = 0, err = 0, safety = 0;
    double *y_new = s->y_new, *ZE = s->tmp2, *error = s->ev_y;
    while (!accepted) {
        if (h_abs < min_step) {
            s->fail_message = MSG_TOO_SMALL;
            return 1;
        }
        h = h_abs * s->direction;
        t_new = t + h;
        if (s->direction * (t_new - s->t_bound) > 0)
            t_new = s->t_bound;
        h = t_new - t;
        h_abs = fabs(h);
        /* Z0 = sol(t + h C)^T - y from the previous step's interpolant, or zeros */
        if (!s->have_sol)
            memset(s->Z0, 0, 3 * n * sizeof(double));
        else
            for (int r = 0; r < 3; ++r) {
                radau_dense_from(s, s->t_old, s->t, s->y_old, t + h * RADAU_C[r], s->Z0 + r * n);
                for (int i = 0; i < n; ++i)
                    s->Z0[r * n + i] -= y[i];
            }
        for (int i = 0; i < n; ++i)
            s->scale[i] = s->atol[i] + fabs(y[i]) * s->rtol;
        int converged = 0;
        while (!converged) {
            if (!s->have_lu)
                radau_factor(s, h);
            converged = radau_collocation(s, t, y, h, s->newton_tol, &n_iter, &rate, &has_rate);
            if (converged < 0)
                return 2;
            if (!converged) {
                if (current_jac)
                    break;
                if (jac(s, t, y))
                    return 2;
                current_jac = 1;
                s->have_lu = 0;
            }
        }
        if (!converged) {
            h_abs *= 0.5;
            s->have_lu = 0;
            continue;
        }
        double *Z = s->Z;
        for (int i = 0; i < n; ++i) {
            y_new[i] = y[i] + Z[2 * n + i];
            ZE[i] = (Z[i] * RADAU_E[0] + Z[n + i] * RADAU_E[1] + Z[2 * n + i] * RADAU_E[2]) / h;
            error[i] = s->f[i] + ZE[i];
        }
        solve_real(s, error);
        for (int i = 0; i < n; ++i)
            s->scale[i] = s->atol[i] + fmax(fabs(y[i]), fabs(y_new[i])) * s->rtol;
        err = rms_scaled(error, s->scale, n);
        safety = 0.9 * (2 * RADAU_NEWTON_MAXITER + 1) / (2 * RADAU_NEWTON_MAXITER + n_iter);
        if (rejected && err > 1) {
            double *ye = s->tmp, *fe = s->K;
            for (int i = 0; i < n; ++i)
                ye[i] = y[i] + error[i];
            if (fun(s, t, ye, fe))
                return 2;
            for (int i = 0; i < n; ++i)
                error[i] = fe[i] + ZE[i];
            solve_real(s, error);
            err = rms_scaled(error, s->scale, n);
        }
        if (err > 1) {
            double factor = radau_predict_factor(h_abs, h_abs_old, err, err_old, has_old);
            h_abs *= fmax(MIN_FACTOR, safety * factor);
            s->have_lu = 0;
            rejected = 1;
        } else {
            accepted = 1;
        }
    }
    int recompute_jac = n_iter > 2 && has_rate && rate > 1e-3;
    double factor = radau_predict_factor(h_abs, h_abs_old, err, err_old, has_old);
    factor = fmin(MAX_FACTOR, safety * factor);
    if (!recompute_jac && factor < 1.2)
        factor = 1;
    else
        s->have_lu = 0;
    /* f_new; y_old <- y, y <- y_new (rotating the three buffers) */
    double *spare = s->y_old;
    s->y_old = s->y;
    s->y = y_new;
    s->y_new = spare;
    if (fun(s, t_new, s->y, s->f))
        return 2;
    if (recompute_jac) {
        if (jac(s, t_new, s->y))
            return 2;
        current_jac = 1;
    } else {
        current_jac = 0;
    }
    s->h_abs_old = s->h_abs;
    s->error_norm_old = err;
    s->has_old = 1;
    s->h_abs = h_abs * factor;
    s->t = t_new;
    s->current_jac = current_jac;
    s->t_old = t;
    radau_compute_dense(s);
    s->have_sol = 1;
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* Variable-order BDF: bdf.py                                                                  */

/* bdf.compute_R: R[i][j] = prod_{k=1..i} (k - 1 - factor j) / k (cumulative product of rows). */
static void bdf_compute_R(int order, double factor, double *R)
{
    int m = order + 1;
    double M[36];
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j)
            M[i * m + j] = i == 0 ? 1.0 : (j == 0 ? 0.0 : ((i - 1) - factor * j) / i);
    for (int j = 0; j < m; ++j) {
        R[j] = M[j];
        for (int i = 1; i < m; ++i)
            R[i * m + j] = R[(i - 1) * m + j] * M[i * m + j];
    }
}

/* bdf.change_D: D[:order+1] <- (R U)^T D[:order+1] for a step size change by factor. */
static void bdf_change_D(solver_t *s, int order, double factor)
{
    int n = s->dim, m = order + 1;
    double R[36], U[36], RU[36];
    bdf_compute_R(order, factor, R);
    bdf_compute_R(order, 1.0, U);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
            double acc = 0.0;
            for (int k = 0; k < m; ++k)
                acc += R[i * m + k] * U[k * m + j];
            RU[i * m + j] = acc;
        }
    /* D'[r][i] = sum_k RU[k][r] D[k][i], row by row into K (free in BDF beyond y_predict, psi) */
    double RUt[36], *Dn = s->K + 2 * n, *D = s->D;
    for (int r = 0; r < m; ++r)
        for (int k = 0; k < m; ++k)
            RUt[r * m + k] = RU[k * m + r];
    for (int r = 0; r < m; ++r)
        combine(D, RUt + r * m, m, n, Dn + (size_t)r * n);
    memcpy(D, Dn, (size_t)m * n * sizeof(double));
}

/* bdf.solve_bdf_system: Newton iterations for y = y_predict + d. Returns converged, -1 on a
 * model failure; y_new in s->y_old storage, d in s->Z. */
static int bdf_newton(solver_t *s, double t_new, const double *y_predict, double c,
                      const double *psi, double tol, int *n_iter)
{
    int n = s->dim, converged = 0, k, has_old = 0;
    double *y = s->y_old, *d = s->Z, *f = s->tmp, *dy = s->W;
    double dy_norm_old = 0;
    memcpy(y, y_predict, n * sizeof(double));
    memset(d, 0, n * sizeof(double));
    for (k = 0; k < BDF_NEWTON_MAXITER; ++k) {
        if (fun(s, t_new, y, f))
            return -1;
        int finite = 1;
        for (int i = 0; i < n; ++i)
            if (!isfinite(f[i]))
                finite = 0;
        if (!finite)
            break;
        for (int i = 0; i < n; ++i)
            dy[i] = c * f[i] - psi[i] - d[i];
        solve_real(s, dy);
        double dy_norm = rms_scaled(dy, s->scale, n), rate = 0;
        int hr = 0;
        if (has_old) {
            rate = dy_norm / dy_norm_old;
            hr = 1;
        }
        if (hr && (rate >= 1 || pow(rate, BDF_NEWTON_MAXITER - k) / (1 - rate) * dy_norm > tol))
            break;
        for (int i = 0; i < n; ++i) {
            y[i] += dy[i];
            d[i] += dy[i];
        }
        if (dy_norm == 0 || (hr && rate / (1 - rate) * dy_norm < tol)) {
            converged = 1;
            break;
        }
        dy_norm_old = dy_norm;
        has_old = 1;
    }
    *n_iter = (k < BDF_NEWTON_MAXITER ? k : BDF_NEWTON_MAXITER - 1) + 1;
    return converged;
}

/* The iteration matrix I - c J, factored (self.lu). */
static void bdf_factor(solver_t *s, double c)
{
    factor_real(s, 1.0, c);
    s->nlu++;
    s->have_lu = 1;
}

/* BDF._step_impl. Returns 0 ok, 1 step failure, 2 model failure. */
static int bdf_step_impl(solver_t *s)
{
    int n = s->dim;
    double t = s->t, *D = s->D;
    double min_step = min_step_at(t, s->direction), h_abs;
    if (s->h_abs > s->max_step) {
        h_abs = s->max_step;
        bdf_change_D(s, s->order, s->max_step / s->h_abs);
        s->n_equal_steps = 0;
    } else if (s->h_abs < min_step) {
        h_abs = min_step;
        bdf_change_D(s, s->order, min_step / s->h_abs);
        s->n_equal_steps = 0;
    } else {
        h_abs = s->h_abs;
    }
    int order = s->order, current_jac = 0, accepted = 0, n_iter = 0;
    double t_new = t, h, safety = 0, err = 0;
    double *y_predict = s->K, *psi = s->K + n, *y_new = s->y_old, *d = s->Z;
    while (!accepted) {
        if (h_abs < min_step) {
            s->fail_message = MSG_TOO_SMALL;
            return 1;
        }
        h = h_abs * s->direction;
        t_new = t + h;
        if (s->direction * (t_new - s->t_bound) > 0) {
            t_new = s->t_bound;
            bdf_change_D(s, order, fabs(t_new - t) / h_abs);
            s->n_equal_steps = 0;
            s->have_lu = 0;
        }
        h = t_new - t;
        h_abs = fabs(h);
        static const double ones[BDF_MAX_ORDER + 1] = {1, 1, 1, 1, 1, 1};
        combine(D, ones, order + 1, n, y_predict);       /* sum_k D[k], as x·1 = x */
        combine(D + n, s->gamma + 1, order, n, psi);
        for (int i = 0; i < n; ++i) {
            s->scale[i] = s->atol[i] + s->rtol * fabs(y_predict[i]);
            psi[i] /= s->alpha[order];
        }
        int converged = 0;
        double c = h / s->alpha[order];
        while (!converged) {
            if (!s->have_lu)
                bdf_factor(s, c);
            converged = bdf_newton(s, t_new, y_predict, c, psi, s->newton_tol, &n_iter);
            if (converged < 0)
                return 2;
            if (!converged) {
                if (current_jac)
                    break;
                if (jac(s, t_new, y_predict))
                    return 2;
                s->have_lu = 0;
                current_jac = 1;
            }
        }
        if (!converged) {
            h_abs *= 0.5;
            bdf_change_D(s, order, 0.5);
            s->n_equal_steps = 0;
            s->have_lu = 0;
            continue;
        }
        safety = 0.9 * (2 * BDF_NEWTON_MAXITER + 1) / (2 * BDF_NEWTON_MAXITER + n_iter);
        double acc = 0.0;
        for (int i = 0; i < n; ++i) {
            s->scale[i] = s->atol[i] + s->rtol * fabs(y_new[i]);
            double v = s->error_const[order] * d[i] / s->scale[i];
            acc += v * v;
        }
        err = sqrt(acc) / sqrt((double)n);
        if (err > 1) {
            double factor = fmax(MIN_FACTOR, safety * pow(err, -1.0 / (order + 1)));
            h_abs *= factor;
            bdf_change_D(s, order, factor);
            s->n_equal_steps = 0;
        } else {
            accepted = 1;
        }
    }
    s->n_equal_steps++;
    s->t_old = t;
    s->t = t_new;
    /* y <- y_new (keep the old y in y_old's place for symmetry with the RK code) */
    double *yold = s->y;
    s->y = y_new;
    s->y_old = yold;
    s->h_abs = h_abs;
    for (int i = 0; i < n; ++i) {
        D[(order + 2) * n + i] = d[i] - D[(order + 1) * n + i];
        D[(order + 1) * n + i] = d[i];
    }
    for (int k = order; k >= 0; --k)
        for (int i = 0; i < n; ++i)
            D[k * n + i] += D[(k + 1) * n + i];
    if (s->n_equal_steps < order + 1)
        return 0;
    double norms[3];
    if (order > 1) {
        double a = 0.0;
        for (int i = 0; i < n; ++i) {
            double v = s->error_const[order - 1] * D[order * n + i] / s->scale[i];
            a += v * v;
        }
        norms[0] = sqrt(a) / sqrt((double)n);
    } else {
        norms[0] = INFINITY;
    }
    norms[1] = err;
    if (order < BDF_MAX_ORDER) {
        double a = 0.0;
        for (int i = 0; i < n; ++i) {
            double v = s->error_const[order + 1] * D[(order + 2) * n + i] / s->scale[i];
            a += v * v;
        }
        norms[2] = sqrt(a) / sqrt((double)n);
    } else {
        norms[2] = INFINITY;
    }
    /* factors = norms ** (-1 / [order, order+1, order+2]); argmax takes the first maximum */
    double best = pow(norms[0], -1.0 / order);
    int arg = 0;
    for (int j = 1; j < 3; ++j) {
        double fj = pow(norms[j], -1.0 / (order + j));
        if (fj > best) {
            best = fj;
            arg = j;
        }
    }
    order += arg - 1;
    s->order = order;
    double factor = fmin(MAX_FACTOR, safety * best);
    s->h_abs *= factor;
    bdf_change_D(s, order, factor);
    s->n_equal_steps = 0;
    s->have_lu = 0;
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* Dense output of the last step                                                               */

/* OdeSolver.dense_output for the last step; DOP853 spends 3 rhs evaluations here. */
static int dense_prepare(solver_t *s)
{
    if (s->dense_ready)
        return 0;
    if (s->t != s->t_old) {
        if (s->method <= LG_DOP853) {
            if (rk_dense_prepare(s))
                return 1;
        } else if (s->method == LG_BDF) {
            int n = s->dim;
            s->dense_order = s->order;
            s->dense_h = s->h_abs * s->direction;
            memcpy(s->dense_D, s->D, (size_t)(s->order + 1) * n * sizeof(double));
        }
        /* Radau: Q was computed at the end of the step (Radau._compute_dense_output) */
    }
    s->dense_ready = 1;
    return 0;
}

/* sol(t) of the last step, into out. */
static void dense_eval(solver_t *s, double t, double *out)
{
    int n = s->dim;
    if (s->t == s->t_old) { /* ConstantDenseOutput */
        memcpy(out, s->y, n * sizeof(double));
        return;
    }
    if (s->method == LG_RADAU) {
        radau_dense_from(s, s->t_old, s->t, s->y_old, t, out);
    } else if (s->method == LG_DOP853) {
        /* Dop853DenseOutput: Horner-like in x and 1 - x over F reversed */
        double x = (t - s->t_old) / (s->t - s->t_old);
        for (int i = 0; i < n; ++i) {
            double y = 0.0;
            for (int k = 0; k < 7; ++k) {
                y += s->Q[(6 - k) * n + i];
                y *= (k % 2 == 0) ? x : 1 - x;
            }
            out[i] = y + s->y_old[i];
        }
    } else if (s->method == LG_BDF) {
        /* BdfDenseOutput: D0 + sum_k D_{k+1} prod_{j<=k} (t - (t_n - h j)) / (h (j + 1)) */
        int order = s->dense_order;
        double p[BDF_MAX_ORDER], acc = 1.0;
        for (int j = 0; j < order; ++j) {
            double shift = s->t - s->dense_h * j, denom = s->dense_h * (1 + j);
            acc *= (t - shift) / denom;
            p[j] = acc;
        }
        for (int i = 0; i < n; ++i) {
            double y = 0.0;
            for (int j = 0; j < order; ++j)
                y += s->dense_D[(j + 1) * n + i] * p[j];
            out[i] = y + s->dense_D[i];
        }
    } else {
        /* RkDenseOutput: y_old + h Q [x, x^2, ...] */
        double h = s->t - s->t_old, x = (t - s->t_old) / h, p[5], acc = 1.0;
        int m = s->n_interp;
        for (int k = 0; k < m; ++k) {
            acc *= x;
            p[k] = acc;
        }
        for (int i = 0; i < n; ++i) {
            double y = 0.0;
            for (int k = 0; k < m; ++k)
                y += s->Q[i * m + k] * p[k];
            out[i] = h * y + s->y_old[i];
        }
    }
}

/* Append the last step's interpolant to result->seg/coef:
 * seg row = (t_old, t, offset, order, h); coef block: RK/Radau: y_old then Q (dim x m);
 * DOP853: y_old then F (7 x dim); BDF: D (order + 1 rows of dim); constant: y. */
static int store_dense(solver_t *s, lg_result_t *r)
{
    int n = s->dim;
    double row[5] = {s->t_old, s->t, (double)r->coef.len, 0.0, 0.0};
    if (s->t == s->t_old) {
        row[3] = -1; /* ConstantDenseOutput */
        return lg_buf_push(&r->seg, row, 5) || lg_buf_push(&r->coef, s->y, n);
    }
    int err = 0;
    switch (s->method) {
    case LG_BDF:
        row[3] = s->dense_order;
        row[4] = s->dense_h;
        err = lg_buf_push(&r->coef, s->dense_D, (size_t)(s->dense_order + 1) * n);
        break;
    case LG_DOP853:
        row[3] = 7;
        err = lg_buf_push(&r->coef, s->y_old, n) || lg_buf_push(&r->coef, s->Q, (size_t)7 * n);
        break;
    case LG_RADAU:
        row[3] = 3;
        err = lg_buf_push(&r->coef, s->y_old, n) || lg_buf_push(&r->coef, s->Q, (size_t)3 * n);
        break;
    default:
        row[3] = s->n_interp;
        err = lg_buf_push(&r->coef, s->y_old, n)
              || lg_buf_push(&r->coef, s->Q, (size_t)s->n_interp * n);
    }
    return err || lg_buf_push(&r->seg, row, 5);
}

/* ------------------------------------------------------------------------------------------ */
/* Events: ivp.find_active_events, ivp.solve_event_equation (brentq), ivp.handle_events          */

static int eval_events(solver_t *s, double t, const double *y, double *g)
{
    eval_inputs(s, t);
    const lg_problem_t *pb = s->pb;
    if (pb->sys_events ? pb->sys_events(pb->sys_ctx, t, y, s->u, g)
                       : pb->events(t, y, pb->p, s->u, g)) {
        s->model_error = 2;
        s->error_t = t;
        memcpy(s->error_y, y, s->dim * sizeof(double));
        return 1;
    }
    return 0;
}

/* g_i(t, sol(t)) */
static int event_at(solver_t *s, int i, double t, double *value, double *g)
{
    dense_eval(s, t, s->ev_y);
    if (eval_events(s, t, s->ev_y, g))
        return 1;
    *value = g[i];
    return 0;
}

/* scipy.optimize.brentq (scipy/optimize/Zeros/brentq.c, Brent 1973) with xtol = rtol = 4 EPS,
 * maxiter 100, on g_i(t, sol(t)) over [xa, xb]. */
static int brentq(solver_t *s, int ev, double xa, double xb, double *g, double *root)
{
    const double xtol = 4 * EPS, rtol = 4 * EPS;
    double xpre = xa, xcur = xb, xblk = 0., fpre, fcur, fblk = 0., spre = 0., scur = 0.;
    if (event_at(s, ev, xpre, &fpre, g) || event_at(s, ev, xcur, &fcur, g))
        return 1;
    if (fpre == 0) {
        *root = xpre;
        return 0;
    }
    if (fcur == 0) {
        *root = xcur;
        return 0;
    }
    for (int i = 0; i < 100; ++i) {
        if (fpre != 0 && fcur != 0 && (signbit(fpre) != signbit(fcur))) {
            xblk = xpre;
            fblk = fpre;
            spre = scur = xcur - xpre;
        }
        if (fabs(fblk) < fabs(fcur)) {
            xpre = xcur;
            xcur = xblk;
            xblk = xpre;
            fpre = fcur;
            fcur = fblk;
            fblk = fpre;
        }
        double delta = (xtol + rtol * fabs(xcur)) / 2;
        double sbis = (xblk - xcur) / 2;
        if (fcur == 0 || fabs(sbis) < delta) {
            *root = xcur;
            return 0;
        }
        if (fabs(spre) > delta && fabs(fcur) < fabs(fpre)) {
            double stry;
            if (xpre == xblk) { /* interpolate */
                stry = -fcur * (xcur - xpre) / (fcur - fpre);
            } else {            /* extrapolate */
                double dpre = (fpre - fcur) / (xpre - xcur);
                double dblk = (fblk - fcur) / (xblk - xcur);
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre));
            }
            if (2 * fabs(stry) < fmin(fabs(spre), 3 * fabs(sbis) - delta)) {
                spre = scur; /* good short step */
                scur = stry;
            } else {
                spre = sbis; /* bisect */
                scur = sbis;
            }
        } else {
            spre = sbis;
            scur = sbis;
        }
        xpre = xcur;
        fpre = fcur;
        if (fabs(scur) > delta)
            xcur += scur;
        else
            xcur += (sbis > 0 ? delta : -delta);
        if (event_at(s, ev, xcur, &fcur, g))
            return 1;
    }
    *root = xcur;
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* Set-up and the solve_ivp loop                                                               */

static void set_message(lg_result_t *r, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(r->message, sizeof r->message, fmt, ap);
    va_end(ap);
}

static void solver_free(solver_t *s)
{
    void *blocks[] = {s->error_y, s->acc, s->y, s->y_old, s->y_new, s->f, s->u, s->scale, s->tmp, s->tmp2, s->ev_y, s->K,
                      s->Q, s->dense_D, s->J, s->LU, s->piv, s->pivc, s->LUc, s->udiv, s->Z,
                      s->W, s->dW, s->F3, s->Z0, s->D};
    for (size_t i = 0; i < sizeof blocks / sizeof blocks[0]; ++i)
        free(blocks[i]);
}

static int solver_alloc(solver_t *s)
{
    size_t n = (size_t)s->dim, nn = n * n, big = n > 8 ? n : 8;
    int implicit = s->method == LG_RADAU || s->method == LG_BDF;
    s->y = calloc(n + 1, sizeof(double));
    s->y_old = calloc(n + 1, sizeof(double));
    s->y_new = calloc(n + 1, sizeof(double));
    s->f = calloc(n + 1, sizeof(double));
    s->u = calloc((size_t)s->pb->n_inputs + 1, sizeof(double));
    s->scale = calloc(n + 1, sizeof(double));
    s->tmp = calloc(big + 1, sizeof(double));
    s->tmp2 = calloc(big + 1, sizeof(double));
    s->ev_y = calloc(n + 1, sizeof(double));
    s->acc = calloc(n + 1, sizeof(double));
    s->error_y = calloc(n + 1, sizeof(double));
    s->K = calloc((DOP_N_EXTENDED + 1) * n + 1, sizeof(double));
    s->Q = calloc(7 * n + 1, sizeof(double));
    s->dense_D = calloc((BDF_MAX_ORDER + 3) * n + 1, sizeof(double));
    int ok = s->error_y && s->acc && s->y && s->y_old && s->y_new && s->f && s->u && s->scale && s->tmp && s->tmp2 && s->ev_y
             && s->K && s->Q && s->dense_D;
    if (implicit) {
        s->J = calloc(nn + 1, sizeof(double));
        s->LU = calloc(nn + 1, sizeof(double));
        s->piv = calloc(n + 1, sizeof(int));
        s->pivc = calloc(n + 1, sizeof(int));
        s->LUc = calloc(2 * nn + 2, sizeof(double));
        s->udiv = calloc(n + 1, sizeof(cdivisor_t));
        s->Z = calloc(3 * n + 1, sizeof(double));
        s->W = calloc(3 * n + 1, sizeof(double));
        s->dW = calloc(3 * n + 1, sizeof(double));
        s->F3 = calloc(3 * n + 1, sizeof(double));
        s->Z0 = calloc(3 * n + 1, sizeof(double));
        s->D = calloc((BDF_MAX_ORDER + 3) * n + 1, sizeof(double));
        ok = ok && s->J && s->LU && s->piv && s->pivc && s->LUc && s->udiv && s->Z && s->W
             && s->dW && s->F3 && s->Z0 && s->D;
    }
    return ok ? 0 : -1;
}

/* The method's __init__: f(t0, y0), the first step, the Jacobian. 0 ok, 2 model failure. */
static int solver_init(solver_t *s)
{
    const lg_options_t *op = s->op;
    int n = s->dim;
    memcpy(s->y, op->y0, n * sizeof(double));
    if (fun(s, s->t, s->y, s->f))
        return 2;
    double err_order = 0;
    switch (s->method) {
    case LG_RK23:
        s->n_stages = 3, s->n_interp = 3, s->lda = 3, err_order = 2;
        s->A = RK23_A, s->B = RK23_B, s->C = RK23_C, s->E = RK23_E, s->P = RK23_P;
        break;
    case LG_RK45:
        s->n_stages = 6, s->n_interp = 4, s->lda = 5, err_order = 4;
        s->A = RK45_A, s->B = RK45_B, s->C = RK45_C, s->E = RK45_E, s->P = RK45_P;
        break;
    case LG_DOP853:
        s->n_stages = DOP_N_STAGES, s->n_interp = 7, s->lda = DOP_N_EXTENDED, err_order = 7;
        s->A = DOP_A, s->B = DOP_B, s->C = DOP_C, s->E = DOP_E5, s->P = NULL;
        break;
    case LG_RADAU:
        err_order = 3;
        break;
    default:
        err_order = 1;
    }
    s->error_exponent = -1.0 / (err_order + 1);
    if (op->first_step > 0)
        s->h_abs = op->first_step;
    else if (select_initial_step(s, err_order, &s->h_abs))
        return 2;
    if (s->method == LG_RADAU || s->method == LG_BDF) {
        /* max(10 EPS / rtol, min(0.03, rtol^0.5)) with the rtol as given, as SciPy does */
        double rg = op->rtol_given > 0 ? op->rtol_given : op->rtol;
        s->newton_tol = fmax(10 * EPS / rg, fmin(0.03, pow(rg, 0.5)));
        if (jac(s, s->t, s->y))
            return 2;
        s->current_jac = 1;
        s->have_lu = 0;
    }
    if (s->method == LG_BDF) {
        /* kappa, gamma = [0, cumsum(1/k)], alpha = (1 - kappa) gamma,
         * error_const = kappa gamma + 1/(k+1) */
        static const double kappa[6] = {0, -0.1850, -1.0 / 9, -0.0823, -0.0415, 0};
        double g = 0;
        s->gamma[0] = 0;
        for (int k = 1; k <= BDF_MAX_ORDER; ++k) {
            g += 1.0 / k;
            s->gamma[k] = g;
        }
        for (int k = 0; k <= BDF_MAX_ORDER; ++k) {
            s->alpha[k] = (1 - kappa[k]) * s->gamma[k];
            s->error_const[k] = kappa[k] * s->gamma[k] + 1.0 / (k + 1);
        }
        for (int i = 0; i < n; ++i) {
            s->D[i] = s->y[i];
            s->D[n + i] = s->f[i] * s->h_abs * s->direction;
        }
        s->order = 1;
        s->n_equal_steps = 0;
    }
    return 0;
}

/* OdeSolver.step: 0 running/finished, 1 failed (message), 2 model failure. Sets *finished. */
static int solver_step(solver_t *s, int *finished)
{
    s->dense_ready = 0;
    if (s->dim == 0 || s->t == s->t_bound) {
        s->t_old = s->t;
        s->t = s->t_bound;
        *finished = 1;
        return 0;
    }
    double t = s->t;
    int rc = s->method <= LG_DOP853 ? rk_step_impl(s)
             : s->method == LG_RADAU ? radau_step_impl(s)
                                     : bdf_step_impl(s);
    if (rc)
        return rc;
    s->t_old = t;
    *finished = s->direction * (s->t - s->t_bound) >= 0;
    return 0;
}

/* Record outputs at the t_eval points of this step (ivp.solve_ivp's t_eval branch). */
static int emit_t_eval(solver_t *s, lg_result_t *r, int *i_eval, double t_end)
{
    const lg_options_t *op = s->op;
    int start = *i_eval, stop = start;
    while (stop < op->n_eval && s->direction * (op->t_eval[stop] - t_end) <= 0)
        stop++;
    if (stop == start)
        return 0;
    if (dense_prepare(s))
        return 2;
    for (int k = start; k < stop; ++k) {
        dense_eval(s, op->t_eval[k], s->ev_y);
        if (buf_push1(&r->t, op->t_eval[k]) || lg_buf_push(&r->y, s->ev_y, s->dim))
            return -1;
    }
    *i_eval = stop;
    return 0;
}

/* Events of this step: returns 0, 2 model failure, -1 memory; *terminate and *t_term set. */
static int handle_step_events(solver_t *s, lg_result_t *r, double *g, double *g_new,
                              double *count, double *gtmp, int *terminate, double *t_term)
{
    const lg_problem_t *pb = s->pb;
    int ne = pb->n_events, n_active = 0;
    int active[LG_MAX_EVENTS];
    double roots[LG_MAX_EVENTS];
    *terminate = 0;
    if (eval_events(s, s->t, s->y, g_new))
        return 2;
    for (int i = 0; i < ne; ++i) {
        int up = g[i] <= 0 && g_new[i] >= 0, down = g[i] >= 0 && g_new[i] <= 0;
        double d = pb->event_direction[i];
        if ((up && d > 0) || (down && d < 0) || ((up || down) && d == 0))
            active[n_active++] = i;
    }
    if (n_active) {
        if (dense_prepare(s))
            return 2;
        for (int a = 0; a < n_active; ++a)
            count[active[a]] += 1;
        for (int a = 0; a < n_active; ++a)
            if (brentq(s, active[a], s->t_old, s->t, gtmp, &roots[a]))
                return 2;
        int any_terminal = 0;
        for (int a = 0; a < n_active; ++a)
            if (count[active[a]] >= pb->event_max[active[a]])
                any_terminal = 1;
        if (any_terminal) {
            /* order by time along the direction (stable), cut after the first terminal */
            for (int a = 1; a < n_active; ++a)
                for (int b = a; b > 0 && s->direction * (roots[b] - roots[b - 1]) < 0; --b) {
                    double tr = roots[b];
                    roots[b] = roots[b - 1];
                    roots[b - 1] = tr;
                    int ti = active[b];
                    active[b] = active[b - 1];
                    active[b - 1] = ti;
                }
            int cut = 0;
            while (count[active[cut]] < pb->event_max[active[cut]])
                cut++;
            n_active = cut + 1;
            *terminate = 1;
            *t_term = roots[n_active - 1];
        }
        for (int a = 0; a < n_active; ++a) {
            dense_eval(s, roots[a], s->ev_y);
            double row[2] = {(double)active[a], roots[a]};
            if (lg_buf_push(&r->ev, row, 2) || lg_buf_push(&r->ev_y, s->ev_y, s->dim))
                return -1;
        }
    }
    memcpy(g, g_new, ne * sizeof(double));
    return 0;
}

/* Seconds of a monotonic clock. */
static double wall_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The doubles a solve without max_steps and t_eval may save (0: none bound). */
static double save_budget(const lg_options_t *op)
{
    if (op->max_steps > 0 || op->t_eval || op->save_budget < 0)
        return 0;
    return op->save_budget > 0 ? op->save_budget : (double)LG_SAVE_BUDGET;
}

/* The guards after an accepted step: LG_STOP_* when the solve must end here, else 0. */
static int guard_stop(const lg_options_t *op, const lg_result_t *r, double t, double start,
                      double *next_poll)
{
    if (op->max_steps > 0 && r->n_steps >= op->max_steps)
        return LG_STOP_STEPS;
    double budget = save_budget(op);
    if (budget > 0 && (double)(r->t.len + r->y.len + r->seg.len + r->coef.len) > budget)
        return LG_STOP_SAVED;
    if (op->max_wall_time <= 0 && !op->poll)
        return 0;
    double now = wall_seconds();
    if (op->max_wall_time > 0 && now - start > op->max_wall_time)
        return LG_STOP_WALL;
    if (op->poll && now >= *next_poll) {
        *next_poll = now + (op->poll_interval > 0 ? op->poll_interval : 0.05);
        if (op->poll(op->poll_ctx, t))
            return LG_STOP_POLL;
    }
    return 0;
}

static void model_failure_message(solver_t *s, lg_result_t *r)
{
    if (s->model_error == 2)
        set_message(r, "the event function failed at t = %.17g", s->error_t);
    else if (s->model_error == 3)
        set_message(r, "the derivative is not finite at t = %.17g", s->error_t);
    else
        set_message(r, "the mass matrix is not positive definite at t = %.17g", s->error_t);
}

int lg_solve(const lg_problem_t *pb, const lg_options_t *op, lg_result_t *r)
{
    memset(r, 0, sizeof *r);
    if (op->method < LG_RK23 || op->method > LG_BDF || pb->dim < 0 || !(pb->rhs || pb->sys_rhs)
        || ((op->method == LG_RADAU || op->method == LG_BDF) && !(pb->jacobian || pb->sys_jac))
        || (pb->n_events > 0 && !(pb->events || pb->sys_events)) || pb->n_events > LG_MAX_EVENTS) {
        set_message(r, "invalid solver options");
        r->status = -1;
        return -1;
    }
    solver_t s;
    memset(&s, 0, sizeof s);
    s.pb = pb;
    s.op = op;
    s.dim = pb->dim;
    s.method = op->method;
    s.t = op->t0;
    s.t_bound = op->tf;
    s.direction = op->tf != op->t0 ? (op->tf > op->t0 ? 1.0 : -1.0) : 1.0;
    s.rtol = op->rtol;
    s.atol = op->atol;
    s.max_step = op->max_step;
    int n = s.dim, rc = 0, status = 0;
    double start = (op->max_wall_time > 0 || op->poll) ? wall_seconds() : 0.0;
    double next_poll = start + (op->poll_interval > 0 ? op->poll_interval : 0.05);
    double *g = NULL, *g_new = NULL, *count = NULL, *gtmp = NULL;
    if (solver_alloc(&s))
        goto nomem;
    if (pb->n_events) {
        g = calloc(pb->n_events, sizeof(double));
        g_new = calloc(pb->n_events, sizeof(double));
        count = calloc(pb->n_events, sizeof(double));
        gtmp = calloc(pb->n_events, sizeof(double));
        if (!g || !g_new || !count || !gtmp)
            goto nomem;
    }
    rc = solver_init(&s);
    if (rc == 2)
        goto model_failed;
    if (!op->t_eval && (buf_push1(&r->t, op->t0) || lg_buf_push(&r->y, op->y0, n)))
        goto nomem;
    if (pb->n_events && eval_events(&s, op->t0, op->y0, g))
        goto model_failed;
    int i_eval = 0, finished = 0;
    double far = fmax(fabs(op->t0), fabs(op->tf));
    double stall_step = 10 * fabs(nextafter(far, INFINITY) - far);
    long short_steps = 0;
    while (1) {
        rc = solver_step(&s, &finished);
        if (rc == 1) {
            status = -1;
            set_message(r, "%s", s.fail_message);
            break;
        }
        if (rc == 2)
            goto model_failed;
        if (finished)
            status = 0;
        r->n_steps++;
        short_steps = fabs(s.t - s.t_old) < stall_step ? short_steps + 1 : 0;
        double t_out = s.t;
        const double *y_out = s.y;
        if (op->dense) {
            if (dense_prepare(&s))
                goto model_failed;
            if (store_dense(&s, r))
                goto nomem;
        }
        int terminate = 0;
        if (pb->n_events) {
            double t_term = 0;
            rc = handle_step_events(&s, r, g, g_new, count, gtmp, &terminate, &t_term);
            if (rc == 2)
                goto model_failed;
            if (rc < 0)
                goto nomem;
            if (terminate) {
                status = 1;
                t_out = t_term;
                dense_eval(&s, t_term, s.ev_y);
                y_out = s.ev_y;
            }
        }
        if (!op->t_eval) {
            /* solve_ivp's donot_append case (a repeated time with dense output) */
            int repeat = op->dense && r->t.len > 1 && r->t.data[r->t.len - 1] == t_out;
            if (!repeat) {
                if (buf_push1(&r->t, t_out) || lg_buf_push(&r->y, y_out, n))
                    goto nomem;
            } else if (r->seg.len >= 5) {
                r->coef.len = (size_t)r->seg.data[r->seg.len - 3];
                r->seg.len -= 5;
            }
        } else {
            rc = emit_t_eval(&s, r, &i_eval, t_out);
            if (rc == 2)
                goto model_failed;
            if (rc < 0)
                goto nomem;
        }
        if (terminate || finished) {
            status = terminate ? 1 : 0;
            break;
        }
        if (short_steps >= LG_STALL_STEPS) {
            status = -1;
            set_message(r, "the step size collapsed: %ld steps in a row below %.3g (10 spacings "
                        "of doubles at %.6g), the last %.3g at t = %.6g: it cannot reach t = %.6g "
                        "(the model is too stiff for this method, or its parameters run away)",
                        short_steps, stall_step, far, fabs(s.t - s.t_old), s.t, op->tf);
            break;
        }
        r->stopped = guard_stop(op, r, s.t, start, &next_poll);
        if (r->stopped) {
            status = -1;
            r->t_reached = s.t;
            if (r->stopped == LG_STOP_STEPS)
                set_message(r, "the step limit max_steps=%ld was reached", op->max_steps);
            else if (r->stopped == LG_STOP_WALL)
                set_message(r, "the wall-time limit max_wall_time=%g s was reached",
                            op->max_wall_time);
            else if (r->stopped == LG_STOP_SAVED)
                set_message(r, "the results saved reached the default bound of %.0f doubles "
                            "(%ld steps) without t_eval or max_steps", save_budget(op),
                            r->n_steps);
            else
                set_message(r, "the solve was stopped at t = %.17g", s.t);
            break;
        }
    }
    if (status == 0)
        set_message(r, "The solver successfully reached the end of the integration interval.");
    else if (status == 1)
        set_message(r, "A termination event occurred.");
    r->status = status;
    goto done;
model_failed:
    r->status = -1;
    model_failure_message(&s, r);
    r->model_failure = s.model_error;
    r->fail_t = s.error_t;
    if (lg_buf_push(&r->fail_y, s.error_y, n))
        goto nomem;
    goto done;
nomem:
    r->status = -1;
    set_message(r, "out of memory");
    rc = -1;
done:
    r->nfev = s.nfev;
    r->njev = s.njev;
    r->nlu = s.nlu;
    solver_free(&s);
    free(g);
    free(g_new);
    free(count);
    free(gtmp);
    return rc < 0 ? -1 : 0;
}
