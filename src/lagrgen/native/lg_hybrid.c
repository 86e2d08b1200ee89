/* lagrgen's hybrid driver (see lg_hybrid.h): the C port of lagrgen/hybrid.py. The mode equations
 *
 *     M·q̈ = F + Σ_slip (−μ_j·|N_j|·s_j)·w_jᵀ + Rᵀ·λ,    R·q̈ = γ_R
 *
 * (R: the model's constraints, the held contacts' W_i, the sticking frictions' w_j; a planar
 * friction slips with −μ·|N|·(û1·w1 + û2·w2), û its unit slip direction) are solved through the
 * Delassus matrix D = R·M⁻¹·B (B = Rᵀ with the slipping frictions' forces per unit normal force
 * added to their normal rows' columns): D·λ = γ_R − R·M⁻¹·F, the contact rows regularized and the
 * result refined (hy_saddle: the least-norm forces of redundant contacts); a segment is one
 * lg_solve with terminal events (all falling through zero); between segments the impact law
 * (generalized Newton with Coulomb's disks for planar frictions, projected Gauss–Seidel on the
 * Delassus matrix) and the switching rules. The model's functions keep their signature
 * f(t, y, p, u, out); the segment's rhs, Jacobian and events are lg_solve's system hooks
 * (sys_rhs, sys_jac, sys_events) with this driver's context.
 */
#define _POSIX_C_SOURCE 200809L   /* clock_gettime under -std=c99 */
#include "lg_hybrid.h"

#include <math.h>
#include <time.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define IMPACT_FIELDS 4
#define FRICTION_FIELDS 5
#define PLANAR_FIELDS 7
#define REST_FACTOR 1e-6
/* lagrgen.hybrid.PGS_SWEEPS, PGS_RELAXATION, DISK_NEWTON, DISK_FLAT. */
#define PGS_SWEEPS 1000
#define PGS_RELAXATION 0.5
#define DISK_NEWTON 60
#define DISK_FLAT 1e-12
/* lagrgen.hybrid.REGULARIZATION, REFINEMENTS, PLANAR_BLEND, TOUCH_OFFSET. */
#define REGULARIZATION 1e-7
#define REFINEMENTS 3
#define PLANAR_BLEND 1e-7
#define TOUCH_OFFSET 1e-3

typedef struct {
    lg_hybrid_t *h;
    int n, m, ni, nf, npf, rmax;   /* ni: the model's impacts and the stops */
    double *terms;                 /* hybrid_terms output */
    double *stop_rows;             /* the stops' impact rows */
    double *K, *x, *R, *rhs, *sigma, *force;
    double *XB, *Dl, *Kd, *res;    /* hy_saddle: M⁻¹·[B | force], D, D + ε, a residual */
    int *piv, *pivd, *reg;
    double *lam_i, *lam_f, *normal, *qdd;
    double *lam_p, *normal_p, *dir_p;   /* planar: force (2 each), N, slip direction (2 each) */
    double *vel_p;                 /* planar slip velocities at a switch (2 each) */
    double *u;                     /* inputs at a switching time */
    double *P, *Minv, *work, *D, *WP, *impulse, *after, *target, *before, *e, *Wrow;
    int *row_of_impact, *row_of_friction, *row_of_planar, *involved, *closing, *resting;
    int *bounced, *held, *cone;
    int *opened;                   /* ni zeros: every contact open */
    int *unset;                    /* npf × −1: every planar friction inactive */
    int n_bounced;
    double *gap_offset;            /* of the impact events (hy_touching) */
    double *slip_offset;           /* of the slipping frictions' events (hy_touching), then
                                      of the planar ones' */
    int cached;                    /* the solution at hand is the segment's at (cached_t, _y) */
    double cached_t, *cached_y;
    int *activated;                /* planar frictions that began to act in hy_settle */
    int *sticking;                 /* planar frictions sticking as the switch began */
    int *rested;                   /* planar frictions hy_start_from_rest has set at rest */
    int *slid;                     /* held contacts hy_slide has tried */
    int *planars;                  /* a list of planar frictions (hy_zero_rates) */
    double *fastest, *fy, *fy2, *yp, *force_row;
    double *rest_speed;            /* per impact at the start: √(2·gap_tol·|g̈|) */
    const int *contact, *slip, *pmode;   /* the mode of the current evaluation */
    int free;                      /* that mode is free (hy_is_free): ẏ from the model's rhs */
    const double *anchor;
    lg_hybrid_result_t *result;
} hy_ctx;

/* -- buffers -------------------------------------------------------------------------------- */
void lg_hybrid_result_free(lg_hybrid_result_t *r)
{
    free(r->t.data);
    free(r->y.data);
    free(r->transitions.data);
    free(r->forces.data);
    memset(&r->forces, 0, sizeof r->forces);
    memset(&r->t, 0, sizeof r->t);
    memset(&r->y, 0, sizeof r->y);
    memset(&r->transitions, 0, sizeof r->transitions);
}

/* -- linear algebra ------------------------------------------------------------------------- */
/* K = P·L·U in place (k×k, row-major, partial pivoting, the row swaps in piv); 1 when K is
 * singular. */
static int hy_lu_factor(double *K, int *piv, int k)
{
    for (int c = 0; c < k; ++c) {
        int p = c;
        for (int r = c + 1; r < k; ++r)
            if (fabs(K[r * k + c]) > fabs(K[p * k + c]))
                p = r;
        piv[c] = p;
        if (!(fabs(K[p * k + c]) > 0))
            return 1;
        if (p != c)
            for (int j = 0; j < k; ++j) {
                double s = K[c * k + j];
                K[c * k + j] = K[p * k + j];
                K[p * k + j] = s;
            }
        for (int r = c + 1; r < k; ++r) {
            double f = K[r * k + c] /= K[c * k + c];
            if (f != 0)
                for (int j = c + 1; j < k; ++j)
                    K[r * k + j] -= f * K[c * k + j];
        }
    }
    return 0;
}

/* b := K⁻¹·b with the factor of hy_lu_factor, for `ncols` columns of b (row stride ncols):
 * the row swaps first (the multipliers moved with their rows), then L, then U. */
static void hy_lu_apply(const double *K, const int *piv, double *b, int k, int ncols)
{
    for (int c = 0; c < k; ++c)
        if (piv[c] != c)
            for (int j = 0; j < ncols; ++j) {
                double s = b[c * ncols + j];
                b[c * ncols + j] = b[piv[c] * ncols + j];
                b[piv[c] * ncols + j] = s;
            }
    for (int c = 0; c < k; ++c) {
        for (int r = c + 1; r < k; ++r) {
            double f = K[r * k + c];
            if (f != 0)
                for (int j = 0; j < ncols; ++j)
                    b[r * ncols + j] -= f * b[c * ncols + j];
        }
    }
    for (int r = k - 1; r >= 0; --r)
        for (int j = 0; j < ncols; ++j) {
            double s = b[r * ncols + j];
            for (int c = r + 1; c < k; ++c)
                s -= K[r * k + c] * b[c * ncols + j];
            b[r * ncols + j] = s / K[r * k + r];
        }
}

/* Solve K·x = b (k×k, row-major, overwritten) in place in b; 1 when K is singular. */
static int hy_lu_solve(double *K, double *b, int k)
{
    int piv[64], *p = k <= 64 ? piv : malloc((size_t)k * sizeof(int));
    if (!p)
        return 1;
    int singular = hy_lu_factor(K, p, k);
    if (!singular)
        hy_lu_apply(K, p, b, k, 1);
    if (p != piv)
        free(p);
    return singular;
}

/* λ with D·λ = b (r×r, row-major; D kept), least-norm where D is singular on the rows
 * reg[q] != 0: ε = REGULARIZATION·(their largest diagonal entry) added to their diagonal
 * entries, then REFINEMENTS steps λ += (D + ε)⁻¹·(b − D·λ) (lagrgen.hybrid.regularized_solve).
 * 1 when D + ε is singular. Uses c->Kd, c->pivd, c->res. */
static int hy_regularized_solve(hy_ctx *c, const double *D, const double *b, const int *reg,
                                int r, double *lam)
{
    double scale = 0.0;
    for (int q = 0; q < r; ++q)
        if (reg[q])
            scale = fmax(scale, fabs(D[q * r + q]));
    if (!(scale > 0))
        scale = 1.0;
    memcpy(c->Kd, D, (size_t)r * r * sizeof(double));
    for (int q = 0; q < r; ++q)
        if (reg[q])
            c->Kd[q * r + q] += REGULARIZATION * scale;
    if (hy_lu_factor(c->Kd, c->pivd, r))
        return 1;
    memcpy(lam, b, r * sizeof(double));
    hy_lu_apply(c->Kd, c->pivd, lam, r, 1);
    for (int it = 0; it < REFINEMENTS; ++it) {
        for (int q = 0; q < r; ++q) {
            double s = b[q];
            for (int l = 0; l < r; ++l)
                s -= D[q * r + l] * lam[l];
            c->res[q] = s;
        }
        hy_lu_apply(c->Kd, c->pivd, c->res, r, 1);
        for (int q = 0; q < r; ++q)
            lam[q] += c->res[q];
    }
    return 0;
}

/* -- the model's terms ---------------------------------------------------------------------- */
#define M_(c) ((c)->terms)
#define F_(c) ((c)->terms + (c)->n * (c)->n)
#define A_(c) ((c)->terms + (c)->n * (c)->n + (c)->n)
#define G_(c) ((c)->terms + (c)->n * (c)->n + (c)->n + (c)->m * (c)->n)
#define MODEL_IMP(c, i) ((c)->terms + (c)->n * (c)->n + (c)->n + (c)->m * (c)->n + (c)->m \
                         + (size_t)(i) * (IMPACT_FIELDS + (c)->n))
/* Impact i: the model's, then the stops' rows. */
#define IMP(c, i) ((i) < (c)->h->ni ? MODEL_IMP(c, i) \
                   : (c)->stop_rows + (size_t)((i) - (c)->h->ni) * (IMPACT_FIELDS + (c)->n))
#define FR(c, j) (MODEL_IMP(c, (c)->h->ni) + (size_t)(j) * (FRICTION_FIELDS + (c)->n))
#define PF(c, k) (FR(c, (c)->nf) + (size_t)(k) * (PLANAR_FIELDS + 2 * (c)->n))

/* The stops' impact rows at y (lagrgen.hybrid.HybridSystem.stop_rows). */
static void hy_stop_rows(hy_ctx *c, const double *y)
{
    int n = c->n;
    for (int s = 0; s < c->h->n_stops; ++s) {
        const double *stop = c->h->stops + 4 * s;
        const int j = (int)stop[0];
        double *row = c->stop_rows + (size_t)s * (IMPACT_FIELDS + n);
        memset(row, 0, (IMPACT_FIELDS + n) * sizeof(double));
        row[0] = stop[1] * (y[j] - stop[2]);
        row[1] = stop[1] * y[n + j];
        row[3] = stop[3];
        row[IMPACT_FIELDS + j] = stop[1];
    }
}

static int hy_terms(hy_ctx *c, double t, const double *y, const double *u)
{
    c->cached = 0;                   /* the terms at hand are no longer the cached solution's */
    if (c->h->terms(t, y, c->h->p, u, c->terms))
        return 1;
    hy_stop_rows(c, y);
    return 0;
}

/* The row of R whose multiplier is the normal force of kind/index, or −1. */
static int hy_row_of(const hy_ctx *c, int kind, int k)
{
    if (kind == LG_NORMAL_CONSTRAINT)
        return k;
    if (kind == LG_NORMAL_IMPACT)
        return c->row_of_impact[k];
    return -1;
}

static int hy_normal_row(const hy_ctx *c, int j)
{
    return hy_row_of(c, c->h->normal_kind[j], c->h->normal_index[j]);
}

/* Whether a friction whose normal force is (kind, index) acts in a mode with these contacts: not
 * while it is the multiplier of an open contact (N = 0: no force, no sticking, no events); one
 * rule for the frictions and the planar frictions (lagrgen.hybrid.acts). */
static int hy_acts(int kind, int index, const int *contact)
{
    return kind != LG_NORMAL_IMPACT || contact[index];
}

static int hy_active(const hy_ctx *c, int j, const int *contact)
{
    return hy_acts(c->h->normal_kind[j], c->h->normal_index[j], contact);
}

static int hy_planar_active(const hy_ctx *c, int k, const int *contact)
{
    return hy_acts(c->h->planar_kind[k], c->h->planar_index[k], contact);
}

/* The unit slip direction (v + b·d)/‖v + b·d‖ of planar friction k (b = PLANAR_BLEND). */
static void hy_slip_direction(const double *v, const double *anchor, double *out)
{
    double a = v[0] + PLANAR_BLEND * anchor[0], b = v[1] + PLANAR_BLEND * anchor[1];
    double norm = hypot(a, b);
    out[0] = norm > 0 ? a / norm : anchor[0];
    out[1] = norm > 0 ? b / norm : anchor[1];
}

/* The least relative pivot |U_kk|/M_kk of M's factor in c->K into the result's least_pivot. */
static void hy_note_pivots(hy_ctx *c, int n)
{
    const double *M = M_(c);
    for (int k = 0; k < n; ++k) {
        double ratio = fabs(c->K[k * n + k]) / fabs(M[k * n + k]);
        if (ratio < c->result->least_pivot)
            c->result->least_pivot = ratio;
    }
}

/* (q̈, λ) of M·q̈ = force + B·λ, R·q̈ = rhs with B = Rᵀ plus c->Wrow's columns (the slipping
 * frictions' forces per unit normal force, scaled by c->sigma) through D = R·M⁻¹·B (see the top);
 * into c->qdd and c->x + n. `nlinked` columns in c->Wrow (n each) at rows c->cone[0..). */
static int hy_saddle(hy_ctx *c, int r, int nlinked)
{
    int n = c->n, w = r + 1;
    /* XB = M⁻¹·[B | force] (n × (r + 1)) */
    for (int a = 0; a < n; ++a) {
        for (int q = 0; q < r; ++q)
            c->XB[a * w + q] = c->R[q * n + a];
        c->XB[a * w + r] = c->force[a];
    }
    for (int l = 0; l < nlinked; ++l) {
        int row = c->cone[l];
        for (int a = 0; a < n; ++a)
            c->XB[a * w + row] += c->sigma[row] * c->Wrow[(size_t)l * n + a];
    }
    memcpy(c->K, M_(c), (size_t)n * n * sizeof(double));
    if (hy_lu_factor(c->K, c->piv, n))
        return 1;
    hy_note_pivots(c, n);
    hy_lu_apply(c->K, c->piv, c->XB, n, w);
    if (!r) {
        for (int a = 0; a < n; ++a)
            c->qdd[a] = c->XB[a * w];
        return 0;
    }
    for (int q = 0; q < r; ++q) {
        double sb = c->rhs[q];
        for (int a = 0; a < n; ++a)
            sb -= c->R[q * n + a] * c->XB[a * w + r];
        c->force_row[q] = sb;
        for (int l = 0; l < r; ++l) {
            double s = 0;
            for (int a = 0; a < n; ++a)
                s += c->R[q * n + a] * c->XB[a * w + l];
            c->Dl[q * r + l] = s;
        }
    }
    if (hy_regularized_solve(c, c->Dl, c->force_row, c->reg, r, c->x + n))
        return 1;
    for (int a = 0; a < n; ++a) {
        double s = c->XB[a * w + r];
        for (int q = 0; q < r; ++q)
            s += c->XB[a * w + q] * c->x[n + q];
        c->qdd[a] = s;
    }
    return 0;
}

/* q̈, the contact and sticking multipliers and the normal forces in the mode (contact, slip,
 * pmode, anchor), into c->qdd, lam_i, lam_f, normal, lam_p, normal_p (and λ at c->x + n); the
 * terms stay in c->terms. 1: singular or model failure. */
static int hy_solve(hy_ctx *c, double t, const double *y, const double *u, const int *contact,
                    const int *slip, const int *pmode, const double *anchor)
{
    int n = c->n, m = c->m;
    if (hy_terms(c, t, y, u))
        return 1;
    int r = 0;
    for (int k = 0; k < m; ++k, ++r) {
        memcpy(c->R + (size_t)r * n, A_(c) + (size_t)k * n, n * sizeof(double));
        c->rhs[r] = G_(c)[k];
        c->reg[r] = 0;
    }
    for (int i = 0; i < c->ni; ++i) {
        c->row_of_impact[i] = -1;
        if (contact[i]) {
            c->row_of_impact[i] = r;
            memcpy(c->R + (size_t)r * n, IMP(c, i) + IMPACT_FIELDS, n * sizeof(double));
            c->reg[r] = 1;
            c->rhs[r++] = IMP(c, i)[2];
        }
    }
    for (int j = 0; j < c->nf; ++j) {
        c->row_of_friction[j] = -1;
        if (slip[j] == 0 && hy_active(c, j, contact)) {
            c->row_of_friction[j] = r;
            memcpy(c->R + (size_t)r * n, FR(c, j) + FRICTION_FIELDS, n * sizeof(double));
            c->reg[r] = 1;
            c->rhs[r++] = FR(c, j)[1];
        }
    }
    for (int k = 0; k < c->npf; ++k) {
        c->row_of_planar[k] = -1;
        if (pmode[k] == 0) {
            c->row_of_planar[k] = r;
            for (int d = 0; d < 2; ++d) {
                memcpy(c->R + (size_t)r * n, PF(c, k) + PLANAR_FIELDS + d * n,
                       n * sizeof(double));
                c->reg[r] = 1;
                c->rhs[r++] = PF(c, k)[2 + d];
            }
        }
    }
    memcpy(c->force, F_(c), n * sizeof(double));
    int nlinked = 0;
    for (int j = 0; j < c->nf; ++j) {
        if (slip[j] == 0)
            continue;
        double f = -FR(c, j)[2] * slip[j];
        int row = hy_normal_row(c, j);
        if (row >= 0) {
            for (int a = 0; a < n; ++a)
                c->Wrow[(size_t)nlinked * n + a] = f * FR(c, j)[FRICTION_FIELDS + a];
            c->cone[nlinked++] = row;
        } else if (c->h->normal_kind[j] == LG_NORMAL_EXPRESSION) {
            f *= fabs(FR(c, j)[4]);
            for (int a = 0; a < n; ++a)
                c->force[a] += f * FR(c, j)[FRICTION_FIELDS + a];
        }
    }
    for (int k = 0; k < c->npf; ++k) {
        double *dir = c->dir_p + 2 * k;
        dir[0] = dir[1] = 0.0;
        if (pmode[k] != 1)
            continue;
        const double *pf = PF(c, k), *w1 = pf + PLANAR_FIELDS, *w2 = w1 + n;
        hy_slip_direction(pf, anchor + 2 * k, dir);
        int row = hy_row_of(c, c->h->planar_kind[k], c->h->planar_index[k]);
        double scale = row >= 0 ? 1.0 : (c->h->planar_kind[k] == LG_NORMAL_EXPRESSION
                                         ? fabs(pf[6]) : 0.0);
        double *target = row >= 0 ? c->Wrow + (size_t)nlinked * n : c->force;
        for (int a = 0; a < n; ++a) {
            double f = -pf[4] * scale * (dir[0] * w1[a] + dir[1] * w2[a]);
            target[a] = row >= 0 ? f : target[a] + f;
        }
        if (row >= 0)
            c->cone[nlinked++] = row;
    }
    for (int a = 0; a < r; ++a)
        c->sigma[a] = 1.0;
    for (int iter = 0; iter < 4; ++iter) {
        if (hy_saddle(c, r, nlinked))
            return 1;
        int same = 1;
        for (int l = 0; l < nlinked; ++l) {
            int row = c->cone[l];
            double s = c->x[n + row] < 0 ? -1.0 : 1.0;
            if (s != c->sigma[row]) {
                c->sigma[row] = s;
                same = 0;
            }
        }
        if (same)
            break;
    }
    for (int i = 0; i < c->ni; ++i)
        c->lam_i[i] = c->row_of_impact[i] >= 0 ? c->x[n + c->row_of_impact[i]] : 0.0;
    for (int j = 0; j < c->nf; ++j) {
        c->lam_f[j] = c->row_of_friction[j] >= 0 ? c->x[n + c->row_of_friction[j]] : 0.0;
        int row = hy_normal_row(c, j);
        c->normal[j] = row >= 0 ? fabs(c->x[n + row])
                       : (c->h->normal_kind[j] == LG_NORMAL_EXPRESSION ? fabs(FR(c, j)[4]) : 0.0);
    }
    for (int k = 0; k < c->npf; ++k) {
        int row = hy_row_of(c, c->h->planar_kind[k], c->h->planar_index[k]);
        double N = row >= 0 ? fabs(c->x[n + row])
                   : (c->h->planar_kind[k] == LG_NORMAL_EXPRESSION ? fabs(PF(c, k)[6]) : 0.0);
        c->normal_p[k] = N;
        for (int d = 0; d < 2; ++d)
            c->lam_p[2 * k + d] = c->row_of_planar[k] >= 0 ? c->x[n + c->row_of_planar[k] + d]
                                  : -PF(c, k)[4] * N * c->dir_p[2 * k + d];
    }
    return 0;
}

/* 1 when the mode (contact, pmode) is free and the model's own rhs is at hand: no model
 * constraints, no contact closed, no friction of either kind acting (lagrgen.hybrid.
 * HybridSystem.is_free). The mode equations are then M·q̈ = F, which the rhs solves by the
 * model's own method; the events need only the gaps, the forces are 0. */
static int hy_is_free(const hy_ctx *c, const int *contact, const int *pmode)
{
    if (!c->h->rhs || c->m)
        return 0;
    for (int i = 0; i < c->ni; ++i)
        if (contact[i])
            return 0;
    for (int j = 0; j < c->nf; ++j)
        if (hy_active(c, j, contact))
            return 0;
    for (int k = 0; k < c->npf; ++k)
        if (pmode[k] >= 0)
            return 0;
    return 1;
}

/* -- the segment's functions (p is the context) --------------------------------------------- */
/* hy_solve in the segment's mode, unless the last solve was at this very (t, y) in it (the
 * events at the point of the step's last stage): 1 on failure. */
static int hy_solve_segment(hy_ctx *c, double t, const double *y, const double *u)
{
    size_t bytes = 2 * (size_t)c->n * sizeof(double);
    if (c->cached && t == c->cached_t && memcmp(y, c->cached_y, bytes) == 0)
        return 0;
    if (hy_solve(c, t, y, u, c->contact, c->slip, c->pmode, c->anchor))
        return 1;
    c->cached = 1;
    c->cached_t = t;
    memcpy(c->cached_y, y, bytes);
    return 0;
}

static int hy_rhs(void *ctx, double t, const double *y, const double *u, double *ydot)
{
    hy_ctx *c = (hy_ctx *)ctx;
    if (c->free)
        return c->h->rhs(t, y, c->h->p, u, ydot);
    if (hy_solve_segment(c, t, y, u))
        return 1;
    memcpy(ydot, y + c->n, c->n * sizeof(double));
    memcpy(ydot + c->n, c->qdd, c->n * sizeof(double));
    return 0;
}

/* ∂ẏ/∂y by forward differences (the stiff methods' Jacobian in a mode). */
static int hy_jacobian(void *ctx, double t, const double *y, const double *u, double *J)
{
    hy_ctx *c = (hy_ctx *)ctx;
    int dim = 2 * c->n;
    if (hy_rhs(ctx, t, y, u, c->fy))
        return 1;
    memcpy(c->yp, y, dim * sizeof(double));
    for (int k = 0; k < dim; ++k) {
        double step = 1.4901161193847656e-08 * fmax(1.0, fabs(y[k]));
        c->yp[k] = y[k] + step;
        if (hy_rhs(ctx, t, c->yp, u, c->fy2))
            return 1;
        for (int a = 0; a < dim; ++a)
            J[a * dim + k] = (c->fy2[a] - c->fy[a]) / step;
        c->yp[k] = y[k];
    }
    return 0;
}

/* The event values of the mode (lagrgen.hybrid.HybridSystem.events): an open gap plus its
 * offset (hy_touching). */
static void hy_event_values(hy_ctx *c, const int *contact, const int *slip, const int *pmode,
                            const double *anchor, double *values)
{
    for (int i = 0; i < c->ni; ++i)
        values[i] = contact[i] ? c->lam_i[i] : IMP(c, i)[0] + c->gap_offset[i];
    for (int j = 0; j < c->nf; ++j)
        values[c->ni + j] = !hy_active(c, j, contact) ? 1.0
                            : slip[j] == 0 ? FR(c, j)[3] * c->normal[j] - fabs(c->lam_f[j])
                                           : slip[j] * FR(c, j)[0] + c->slip_offset[j];
    for (int k = 0; k < c->npf; ++k) {
        const double *pf = PF(c, k);
        values[c->ni + c->nf + k] =
            pmode[k] < 0 ? 1.0
            : pmode[k] == 0 ? pf[5] * c->normal_p[k] - hypot(c->lam_p[2 * k], c->lam_p[2 * k + 1])
                            : anchor[2 * k] * pf[0] + anchor[2 * k + 1] * pf[1]
                                  + c->slip_offset[c->nf + k];
    }
}

static int hy_events(void *ctx, double t, const double *y, const double *u, double *values)
{
    hy_ctx *c = (hy_ctx *)ctx;
    if (!c->free) {
        if (hy_solve_segment(c, t, y, u))
            return 1;
    } else if (c->h->ni) {         /* a free mode's events are the gaps alone */
        if (hy_terms(c, t, y, u))
            return 1;
    } else {
        hy_stop_rows(c, y);
    }
    hy_event_values(c, c->contact, c->slip, c->pmode, c->anchor, values);
    return 0;
}

/* -- the impact law ------------------------------------------------------------------------- */
/* P = M⁻¹ − M⁻¹Aᵀ(AM⁻¹Aᵀ)⁻¹AM⁻¹ into c->P (terms at the state already in c->terms). */
static int hy_inverse_mass(hy_ctx *c)
{
    int n = c->n, m = c->m;
    for (int col = 0; col < n; ++col) {
        memcpy(c->work, M_(c), (size_t)n * n * sizeof(double));
        for (int a = 0; a < n; ++a)
            c->x[a] = a == col;
        if (hy_lu_solve(c->work, c->x, n))
            return 1;
        for (int a = 0; a < n; ++a)
            c->Minv[a * n + col] = c->x[a];
    }
    memcpy(c->P, c->Minv, (size_t)n * n * sizeof(double));
    if (!m)
        return 0;
    /* X = M⁻¹Aᵀ (n×m) in WP, S = A·X (m×m); P −= X·S⁻¹·Xᵀ */
    const double *A = A_(c);
    for (int a = 0; a < n; ++a)
        for (int k = 0; k < m; ++k) {
            double s = 0;
            for (int b = 0; b < n; ++b)
                s += c->Minv[a * n + b] * A[k * n + b];
            c->WP[a * m + k] = s;
        }
    for (int col = 0; col < n; ++col) {      /* z = S⁻¹·Xᵀ[:, col] */
        for (int k = 0; k < m; ++k)
            for (int l = 0; l < m; ++l) {
                double s = 0;
                for (int b = 0; b < n; ++b)
                    s += A[k * n + b] * c->WP[b * m + l];
                c->work[k * m + l] = s;
            }
        for (int k = 0; k < m; ++k)
            c->x[k] = c->WP[col * m + k];
        if (hy_lu_solve(c->work, c->x, m))
            return 1;
        for (int a = 0; a < n; ++a) {
            double s = 0;
            for (int k = 0; k < m; ++k)
                s += c->WP[a * m + k] * c->x[k];
            c->P[a * n + col] -= s;
        }
    }
    return 0;
}

/* For k gradient rows (n each) in c->Wrow at the state whose terms and P are at hand:
 * WP = P·Wᵀ (n×k), D = W·P·Wᵀ (k×k): an impulse Λ along W changes q̇ by WP·Λ and the rows'
 * rates by D·Λ. */
static void hy_delassus_rows(hy_ctx *c, int k)
{
    int n = c->n;
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < k; ++q) {
            double s = 0;
            const double *W = c->Wrow + (size_t)q * n;
            for (int b = 0; b < n; ++b)
                s += c->P[a * n + b] * W[b];
            c->WP[a * k + q] = s;
        }
    for (int q = 0; q < k; ++q) {
        const double *W = c->Wrow + (size_t)q * n;
        for (int l = 0; l < k; ++l) {
            double s = 0;
            for (int b = 0; b < n; ++b)
                s += W[b] * c->WP[b * k + l];
            c->D[q * k + l] = s;
        }
    }
}

/* q̇ += WP·Λ: the impulses c->impulse[0..k) along the rows of the last hy_delassus. */
static void hy_apply_impulse(hy_ctx *c, double *y, int k)
{
    int n = c->n;
    for (int a = 0; a < n; ++a) {
        double s = 0;
        for (int q = 0; q < k; ++q)
            s += c->WP[a * k + q] * c->impulse[q];
        y[n + a] += s;
    }
}

/* Move impulse q to `value` (lagrgen.hybrid.projected_gauss_seidel); its change times D_qq. */
static double hy_pgs_move(hy_ctx *c, int k, int q, double value)
{
    double delta = value - c->impulse[q];
    if (delta == 0)
        return 0.0;
    for (int l = 0; l < k; ++l)
        c->after[l] += c->D[l * k + q] * delta;
    c->impulse[q] = value;
    return fabs(delta) * c->D[q * k + q];
}

/* ν > 0 with ‖(cc_i/(l_i + ν))‖ = radius (l_i >= 0; lagrgen.hybrid.rim_shift): Newton steps
 * on 1/‖x(ν)‖ − 1/radius, bisection where a step leaves the bracket [0, ‖cc‖/radius]. */
static double hy_rim_shift(const double *l, const double *cc, double radius)
{
    double lo = 0.0, hi = hypot(cc[0], cc[1]) / radius, nu = hi;
    for (int it = 0; it < DISK_NEWTON; ++it) {
        double e0 = l[0] + nu, e1 = l[1] + nu;
        if ((e0 <= 0 && cc[0] != 0) || (e1 <= 0 && cc[1] != 0)) {
            lo = nu;
            nu = 0.5 * (nu + hi);
            continue;
        }
        double x0 = cc[0] != 0 ? cc[0] / e0 : 0.0, x1 = cc[1] != 0 ? cc[1] / e1 : 0.0;
        double size = hypot(x0, x1), phi = 1.0 / size - 1.0 / radius;
        if (phi < 0)
            lo = nu;
        else
            hi = nu;
        double slope = ((cc[0] != 0 ? cc[0] * cc[0] / (e0 * e0 * e0) : 0.0)
                        + (cc[1] != 0 ? cc[1] * cc[1] / (e1 * e1 * e1) : 0.0))
                       / (size * size * size);
        double step = slope > 0 ? nu - phi / slope : 0.5 * (lo + hi);
        double next = lo < step && step < hi ? step : 0.5 * (lo + hi);
        if (fabs(next - nu) <= 1e-15 * nu)
            return next;
        nu = next;
    }
    return nu;
}

/* x minimizing ½·xᵀ·B·x + gᵀ·x over the disk ‖x‖ <= radius, B = [[B0, B1], [B1, B2]] symmetric
 * positive semi-definite (lagrgen.hybrid.disk_step): −B⁻¹·g inside, else on the rim
 * x(ν) = −(B + ν·I)⁻¹·g (hy_rim_shift) in B's eigenbasis; a flat direction of B (eigenvalue
 * <= DISK_FLAT times the largest) with no part of g takes none. */
static void hy_disk_step(const double *B, const double *g, double radius, double *x)
{
    x[0] = x[1] = 0.0;
    if (!(radius > 0))
        return;
    double mean = 0.5 * (B[0] + B[2]), half = 0.5 * (B[0] - B[2]);
    double root = hypot(half, B[1]), l[2] = {fmax(mean - root, 0.0), fmax(mean + root, 0.0)};
    double v0[2];                         /* the eigenvector of l[0]; l[1]'s is (−v0[1], v0[0]) */
    if (root == 0) {
        v0[0] = 1.0;
        v0[1] = 0.0;
    } else if (half <= 0) {
        double s = hypot(root - half, B[1]);
        v0[0] = (root - half) / s;
        v0[1] = -B[1] / s;
    } else {
        double s = hypot(B[1], root + half);
        v0[0] = B[1] / s;
        v0[1] = -(root + half) / s;
    }
    double cc[2] = {v0[0] * g[0] + v0[1] * g[1], -v0[1] * g[0] + v0[0] * g[1]}, z[2];
    double ccmax = fmax(fabs(cc[0]), fabs(cc[1]));
    int unbounded = 0;
    for (int d = 0; d < 2; ++d) {
        int flat = l[d] <= DISK_FLAT * l[1];
        if (flat && fabs(cc[d]) <= DISK_FLAT * ccmax)
            cc[d] = 0.0;
        unbounded |= flat && cc[d] != 0;
        z[d] = flat ? 0.0 : -cc[d] / l[d];
    }
    if (unbounded || hypot(z[0], z[1]) > radius) {
        double nu = hy_rim_shift(l, cc, radius);
        for (int d = 0; d < 2; ++d)
            z[d] = cc[d] != 0 ? -cc[d] / (l[d] + nu) : 0.0;
    }
    x[0] = v0[0] * z[0] - v0[1] * z[1];
    x[1] = v0[1] * z[0] + v0[0] * z[1];
}

/* q̇⁺ by the generalized Newton law for the closing impacts (closing[0..nc), restitution e[]
 * per closing one) and the held ones (e = 0), with Coulomb's disks for the planar frictions
 * whose normal force is one of them (their tangential impulses within μ times the normal one,
 * aiming at v = 0); y updated in place; before[] gets ġ⁻. */
static int hy_impact(hy_ctx *c, double t, double *y, const double *u, const int *closing, int nc,
                     const double *e)
{
    int k = 0, n = c->n, ncones = 0;
    if (hy_terms(c, t, y, u) || hy_inverse_mass(c))
        return 1;
    for (int a = 0; a < nc; ++a)
        c->involved[k++] = closing[a];
    for (int i = 0; i < c->ni; ++i) {
        int in = 0;
        for (int a = 0; a < nc; ++a)
            in |= closing[a] == i;
        if (c->h->contact[i] && !in)
            c->involved[k++] = i;
    }
    int ninvolved = k;
    for (int q = 0; q < ninvolved; ++q) {
        memcpy(c->Wrow + (size_t)q * n, IMP(c, c->involved[q]) + IMPACT_FIELDS,
               n * sizeof(double));
        c->before[q] = IMP(c, c->involved[q])[1];
        c->target[q] = q < nc ? -e[q] * fmin(c->before[q], 0.0) : 0.0;
    }
    for (int p = 0; p < c->npf; ++p) {
        if (c->h->planar_kind[p] != LG_NORMAL_IMPACT)
            continue;
        int normal = -1;
        for (int q = 0; q < ninvolved; ++q)
            if (c->involved[q] == c->h->planar_index[p])
                normal = q;
        if (normal < 0)
            continue;
        for (int d = 0; d < 2; ++d) {
            memcpy(c->Wrow + (size_t)k * n, PF(c, p) + PLANAR_FIELDS + d * n, n * sizeof(double));
            c->before[k] = PF(c, p)[d];
            c->target[k++] = 0.0;
        }
        c->cone[2 * ncones] = normal;
        c->cone[2 * ncones + 1] = p;
        ++ncones;
    }
    hy_delassus_rows(c, k);
    double scale = 1.0;
    for (int q = 0; q < k; ++q) {
        c->after[q] = c->before[q];
        c->impulse[q] = 0.0;
        scale = fmax(scale, fabs(c->before[q]));
    }
    double relax = ncones ? PGS_RELAXATION : 1.0;
    for (int sweep = 0; sweep < PGS_SWEEPS; ++sweep) {
        double change = 0;
        for (int q = 0; q < ninvolved; ++q) {
            double d = c->D[q * k + q];
            if (d <= 0)
                continue;
            change = fmax(change, hy_pgs_move(c, k, q, fmax(0.0, c->impulse[q]
                                                       - relax * (c->after[q] - c->target[q]) / d)));
        }
        for (int cn = 0; cn < ncones; ++cn) {
            int a = ninvolved + 2 * cn, b = a + 1, normal = c->cone[2 * cn];
            double B[3] = {c->D[a * k + a], c->D[a * k + b], c->D[b * k + b]}, g[2], x[2];
            g[0] = c->after[a] - c->target[a] - B[0] * c->impulse[a] - B[1] * c->impulse[b];
            g[1] = c->after[b] - c->target[b] - B[1] * c->impulse[a] - B[2] * c->impulse[b];
            hy_disk_step(B, g, PF(c, c->cone[2 * cn + 1])[4] * c->impulse[normal], x);
            change = fmax(change, hy_pgs_move(c, k, a, x[0]));
            change = fmax(change, hy_pgs_move(c, k, b, x[1]));
        }
        if (change <= 1e-15 * scale)
            break;
    }
    hy_apply_impulse(c, y, k);
    return 0;
}

/* -- the switching rules -------------------------------------------------------------------- */
static int hy_record(hy_ctx *c, double t, int element, int kind)
{
    double row[3] = {t, (double)element, (double)kind};
    return lg_buf_push(&c->result->transitions, row, 3);
}

static void hy_inputs(hy_ctx *c, double t)
{
    for (int k = 0; k < c->h->n_inputs; ++k)
        c->u[k] = lg_signal_eval(&c->h->inputs[k], t);
}

static int hy_solve_mode(hy_ctx *c, double t, const double *y)
{
    return hy_solve(c, t, y, c->u, c->h->contact, c->h->slip, c->h->pmode, c->h->anchor);
}

/* The tangential acceleration a = (w1·q̈ − γ1, w2·q̈ − γ2) of planar friction k in the solution
 * at hand. */
static void hy_planar_acceleration(const hy_ctx *c, int k, double *a)
{
    const double *pf = PF(c, k);
    for (int d = 0; d < 2; ++d) {
        a[d] = -pf[2 + d];
        for (int b = 0; b < c->n; ++b)
            a[d] += pf[PLANAR_FIELDS + d * c->n + b] * c->qdd[b];
    }
}

/* The gap offsets of the impact events (lagrgen.hybrid.Switching._touching): −g where an open
 * gap g is below 0, plus TOUCH_OFFSET·gap_tol for an open contact at rest at its surface
 * (g <= gap_tol, ġ² <= 2·gap_tol·|g̈| and g̈ >= −1000·gap_tol, not one that has just bounced);
 * and TOUCH_OFFSET·gap_tol on the event of a friction slipping at rest that nothing moves
 * (|v|, |v̇| <= 1000·gap_tol); the solution of the settled mode at the state is at hand. */
static void hy_touching(hy_ctx *c)
{
    for (int i = 0; i < c->ni; ++i) {
        const double *imp = IMP(c, i);
        double gdd = -imp[2];
        int bounced = 0;
        for (int a = 0; a < c->n_bounced; ++a)
            bounced |= c->bounced[a] == i;
        for (int b = 0; b < c->n; ++b)
            gdd += imp[IMPACT_FIELDS + b] * c->qdd[b];
        c->gap_offset[i] = c->h->contact[i] ? 0.0 : fmax(0.0, -imp[0])
                           + (!bounced && imp[0] <= c->h->gap_tol
                                      && imp[1] * imp[1] <= 2 * c->h->gap_tol * fabs(gdd)
                                      && gdd >= -1e3 * c->h->gap_tol
                                  ? TOUCH_OFFSET * c->h->gap_tol : 0.0);
    }
    for (int j = 0; j < c->nf; ++j) {       /* a friction slipping at rest that nothing moves */
        const double *fr = FR(c, j);
        double vdd = -fr[1];
        for (int b = 0; b < c->n; ++b)
            vdd += fr[FRICTION_FIELDS + b] * c->qdd[b];
        c->slip_offset[j] = c->h->slip[j] != 0 && hy_active(c, j, c->h->contact)
                            && fabs(fr[0]) <= 1e3 * c->h->gap_tol
                            && fabs(vdd) <= 1e3 * c->h->gap_tol
                                ? TOUCH_OFFSET * c->h->gap_tol : 0.0;
    }
    for (int k = 0; k < c->npf; ++k) {
        const double *pf = PF(c, k);
        double a[2];
        hy_planar_acceleration(c, k, a);
        c->slip_offset[c->nf + k] = c->h->pmode[k] == 1
                                    && hypot(pf[0], pf[1]) <= 1e3 * c->h->gap_tol
                                    && hypot(a[0], a[1]) <= 1e3 * c->h->gap_tol
                                        ? TOUCH_OFFSET * c->h->gap_tol : 0.0;
    }
}

/* anchor := v/‖v‖ (kept where v is 0). */
static void hy_set_anchor(double *anchor, double v0, double v1)
{
    double norm = hypot(v0, v1);
    if (norm > 0) {
        anchor[0] = v0 / norm;
        anchor[1] = v1 / norm;
    }
}

/* Planar friction k at v = 0: stick if its holding force is within μ_s·|N| in norm, else slip
 * away from it (recorded when `record`). */
static int hy_try_stick_planar(hy_ctx *c, double t, const double *y, int k, int record)
{
    lg_hybrid_t *h = c->h;
    h->pmode[k] = 0;
    if (hy_solve_mode(c, t, y))
        return 1;
    double f0 = c->lam_p[2 * k], f1 = c->lam_p[2 * k + 1];
    int kind = LG_STICK;
    if (hypot(f0, f1) > PF(c, k)[5] * c->normal_p[k]) {
        h->pmode[k] = 1;
        hy_set_anchor(h->anchor + 2 * k, -f0, -f1);
        kind = LG_SLIP;
    }
    return record && hy_record(c, t, c->ni + c->nf + k, kind) ? -1 : 0;
}

/* d·a: the tangential acceleration of planar friction k along its anchor d in the solution at
 * hand (> 0: a friction slipping from rest moves off along its anchor). */
static double hy_anchor_rate(const hy_ctx *c, int k)
{
    double a[2];
    hy_planar_acceleration(c, k, a);
    return c->h->anchor[2 * k] * a[0] + c->h->anchor[2 * k + 1] * a[1];
}

/* The planar frictions' part of hy_settle on the solution at hand (lagrgen.hybrid.Switching.
 * _settle_planar): those that have just begun to act are marked 1 in c->activated (all
 * together: sticking where abs(v) <= 1000·gap_tol, else slipping along v), slipping ones that
 * the others have stopped (abs(v) <= 1000·gap_tol, and not moving off along their anchors) try
 * sticking once (2; 3 when they slip on);
 * the others that begin to slip are recorded when `record`. 1 if a mode changed, 0, or -1 when
 * out of memory. */
static int hy_settle_planar(hy_ctx *c, double t, int record)
{
    lg_hybrid_t *h = c->h;
    int changed = 0;
    for (int k = 0; k < c->npf; ++k) {
        const double *pf = PF(c, k);
        double v0 = pf[0], v1 = pf[1];
        int moving = hypot(v0, v1) > 1e3 * h->gap_tol;
        if (!hy_planar_active(c, k, h->contact)) {
            changed |= h->pmode[k] != -1;
            h->pmode[k] = -1;
            c->activated[k] = 0;
        } else if (h->pmode[k] == -1) {
            changed = 1;
            c->activated[k] = 1;
            h->pmode[k] = moving;
            if (moving)
                hy_set_anchor(h->anchor + 2 * k, v0, v1);
        } else if (h->pmode[k] == 0 && (moving || hypot(c->lam_p[2 * k], c->lam_p[2 * k + 1])
                                                  > pf[5] * c->normal_p[k])) {
            changed = 1;
            h->pmode[k] = 1;
            if (moving)
                hy_set_anchor(h->anchor + 2 * k, v0, v1);
            else
                hy_set_anchor(h->anchor + 2 * k, -c->lam_p[2 * k], -c->lam_p[2 * k + 1]);
            if (c->activated[k] == 2)
                c->activated[k] = 3;                    /* tried sticking: slips on */
            else if (record && !c->activated[k]
                     && hy_record(c, t, c->ni + c->nf + k, LG_SLIP))
                return -1;
        } else if (h->pmode[k] == 1 && moving) {
            hy_set_anchor(h->anchor + 2 * k, v0, v1);
        } else if (h->pmode[k] == 1 && c->activated[k] == 0 && hy_anchor_rate(c, k) <= 0) {
                                                                   /* stopped by the others */
            h->pmode[k] = 0;
            c->activated[k] = 2;
            changed = 1;
        }
    }
    return changed;
}

/* The inelastic impulses that set ġ = 0 for the held contacts rows[0..k) and v = 0 for the
 * planar frictions planars[0..kp) (D·Λ = −(ġ, v), the least-norm impulses of redundant rows,
 * q̇ += P·Wᵀ·Λ; lagrgen.hybrid.HybridSystem.hold); y changes in place, c->before[0..k) keeps ġ.
 * 1: model failure or D singular. */
static int hy_zero_rates(hy_ctx *c, double t, double *y, const int *rows, int k,
                         const int *planars, int kp)
{
    int moving = 0, n = c->n, all = k + 2 * kp;
    if (hy_terms(c, t, y, c->u) || hy_inverse_mass(c))
        return 1;
    for (int q = 0; q < k; ++q) {
        memcpy(c->Wrow + (size_t)q * n, IMP(c, rows[q]) + IMPACT_FIELDS, n * sizeof(double));
        c->before[q] = IMP(c, rows[q])[1];
    }
    for (int a = 0; a < kp; ++a)
        for (int d = 0; d < 2; ++d) {
            int q = k + 2 * a + d;
            memcpy(c->Wrow + (size_t)q * n, PF(c, planars[a]) + PLANAR_FIELDS + d * n,
                   n * sizeof(double));
            c->before[q] = PF(c, planars[a])[d];
        }
    hy_delassus_rows(c, all);
    for (int q = 0; q < all; ++q) {
        c->target[q] = -c->before[q];
        c->reg[q] = 1;
        moving |= c->before[q] != 0;
    }
    if (!moving)
        return 0;
    if (hy_regularized_solve(c, c->D, c->target, c->reg, all, c->impulse))
        return 1;
    hy_apply_impulse(c, y, all);
    return 0;
}

/* hy_zero_rates for the held contacts rows[0..k), with a "contact" transition for each whose ġ
 * was not 0 (when `record`); 1: model failure or D singular, -1: out of memory. */
static int hy_hold(hy_ctx *c, double t, double *y, const int *rows, int k, int record)
{
    if (hy_zero_rates(c, t, y, rows, k, NULL, 0))
        return 1;
    for (int q = 0; q < k; ++q)
        if (record && c->before[q] != 0 && hy_record(c, t, rows[q], LG_CONTACT))
            return -1;
    return 0;
}

/* Planar frictions that begin to slip at this switch from sticking (c->sticking) or from their
 * contact's closing (c->activated 1), with 0 < ‖v‖ <= 1000·gap_tol (the drift of their
 * sticking), start at v = 0 along their anchors: hy_zero_rates on every held row (held contacts,
 * sticking planar frictions and these); each at most once per settle (c->rested). Then the
 * solution of the mode at y is at hand (lagrgen.hybrid.Switching._start_from_rest). */
static int hy_start_from_rest(hy_ctx *c, double t, double *y)
{
    lg_hybrid_t *h = c->h;
    int kp = 0, nh = 0, starting = 0;
    for (int k = 0; k < c->npf; ++k) {
        double speed = hypot(PF(c, k)[0], PF(c, k)[1]);
        int now = h->pmode[k] == 1 && !c->rested[k] && (c->sticking[k] || c->activated[k] == 1)
                  && speed > 0 && speed <= 1e3 * h->gap_tol;
        if (now)
            c->rested[k] = starting = 1;
        if (now || h->pmode[k] == 0)
            c->planars[kp++] = k;
    }
    if (!starting)
        return 0;
    for (int i = 0; i < c->ni; ++i)
        if (h->contact[i])
            c->held[nh++] = i;
    if (hy_zero_rates(c, t, y, c->held, nh, c->planars, kp))
        return 1;
    return hy_solve_mode(c, t, y);
}

/* A held contact i whose force is negative with its frictions sticking: those slip instead, away
 * from their sticking forces (lagrgen.hybrid.Switching._slide), on the solution at hand; 1 if
 * one did, 0, or -1 when out of memory. */
static int hy_slide(hy_ctx *c, double t, int i, int record)
{
    lg_hybrid_t *h = c->h;
    int slid = 0;
    for (int j = 0; j < c->nf; ++j) {
        if (h->slip[j] != 0 || h->normal_kind[j] != LG_NORMAL_IMPACT || h->normal_index[j] != i)
            continue;
        h->slip[j] = c->lam_f[j] > 0 ? -1 : 1;
        slid = 1;
        if (record && hy_record(c, t, c->ni + j, LG_SLIP))
            return -1;
    }
    for (int k = 0; k < c->npf; ++k) {
        if (h->pmode[k] != 0 || h->planar_kind[k] != LG_NORMAL_IMPACT
            || h->planar_index[k] != i)
            continue;
        h->pmode[k] = 1;
        hy_set_anchor(h->anchor + 2 * k, -c->lam_p[2 * k], -c->lam_p[2 * k + 1]);
        slid = 1;
        if (c->activated[k] == 2)
            c->activated[k] = 3;
        else if (record && !c->activated[k] && hy_record(c, t, c->ni + c->nf + k, LG_SLIP))
            return -1;
    }
    return slid;
}

/* Make the mode consistent (lagrgen.hybrid.Switching.settle): no negative contact force, no
 * open contact at rest at its surface that the mode drives into it (held, its ġ set to 0), no
 * sticking force beyond its limit, no sticking friction with v != 0; then the gap offsets of the
 * contacts left at their surface. y may change. */
static int hy_settle(hy_ctx *c, double t, double *y, int record)
{
    lg_hybrid_t *h = c->h;
    int settled = 0;
    memset(c->activated, 0, (c->npf + 1) * sizeof(int));
    memset(c->rested, 0, (c->npf + 1) * sizeof(int));
    memset(c->slid, 0, (c->ni + 1) * sizeof(int));
    for (int it = 0; it < 2 * (c->ni + c->nf + c->npf) + 2 && !settled; ++it) {
        if (hy_solve_mode(c, t, y) || hy_start_from_rest(c, t, y))
            return 1;
        int changed = 0, npressed = 0, moving = 0;
        for (int i = 0; i < c->ni; ++i)
            if (h->contact[i] && c->lam_i[i] < 0) {
                if (!c->slid[i]) {
                    c->slid[i] = 1;
                    int slid = hy_slide(c, t, i, record);
                    if (slid < 0)
                        return -1;
                    if (slid) {
                        changed = 1;
                        continue;
                    }
                }
                h->contact[i] = 0;
                changed = 1;
                if (record && hy_record(c, t, i, LG_RELEASE))
                    return -1;
            }
        for (int i = 0; i < c->ni; ++i) {       /* lagrgen.hybrid.Switching.pressed */
            const double *imp = IMP(c, i);
            int bounced = 0;
            for (int a = 0; a < c->n_bounced; ++a)
                bounced |= c->bounced[a] == i;
            if (h->contact[i] || bounced || !(imp[0] <= h->gap_tol))
                continue;
            double gdd = -imp[2];
            for (int b = 0; b < c->n; ++b)
                gdd += imp[IMPACT_FIELDS + b] * c->qdd[b];
            if (gdd < -1e3 * h->gap_tol && imp[1] * imp[1] <= 2 * h->gap_tol * fabs(gdd)
                && (h->rest_velocity < 0 || imp[3] * fabs(imp[1]) <= h->rest_velocity))
                c->closing[npressed++] = i;
        }
        for (int a = 0; a < npressed; ++a) {
            h->contact[c->closing[a]] = 1;
            moving |= IMP(c, c->closing[a])[1] != 0;
            if (record && hy_record(c, t, c->closing[a], LG_CONTACT))
                return -1;
        }
        if (npressed) {
            int nh = 0, err;
            changed = 1;
            for (int i = 0; i < c->ni; ++i)
                if (h->contact[i])
                    c->held[nh++] = i;
            if (moving && (err = hy_hold(c, t, y, c->held, nh, 0)))
                return err;
        }
        for (int j = 0; j < c->nf; ++j) {
            if (h->slip[j] != 0 || !hy_active(c, j, h->contact))
                continue;
            double v = FR(c, j)[0];
            int moving = fabs(v) > 1e3 * h->gap_tol;
            if (moving || fabs(c->lam_f[j]) > FR(c, j)[3] * c->normal[j]) {
                h->slip[j] = moving ? (v > 0 ? 1 : -1) : (c->lam_f[j] > 0 ? -1 : 1);
                changed = 1;
                if (record && hy_record(c, t, c->ni + j, LG_SLIP))
                    return -1;
            }
        }
        int planar = hy_settle_planar(c, t, record);
        if (planar < 0)
            return -1;
        settled = !changed && !planar;    /* then the solution of the mode is at hand */
    }
    for (int k = 0; k < c->npf; ++k)     /* the planar frictions that began to act, as they end */
        if (record && c->activated[k] == 1
            && hy_record(c, t, c->ni + c->nf + k, h->pmode[k] == 0 ? LG_STICK : LG_SLIP))
            return -1;
    for (int k = 0; k < c->npf; ++k)     /* and those that stuck, stopped by the others */
        if (record && c->activated[k] == 2 && h->pmode[k] == 0
            && hy_record(c, t, c->ni + c->nf + k, LG_STICK))
            return -1;
    if (!settled && hy_solve_mode(c, t, y))
        return 1;
    hy_touching(c);
    return 0;
}

/* 2 (result->failure set) when a restitution is outside [0, 1] or a friction coefficient out
 * of range in the terms at hand (NaN is out of every range), else 0; a planar friction k is
 * element nf + k of the frictions. */
static int hy_check_coefficients(hy_ctx *c)
{
    lg_hybrid_result_t *r = c->result;
    for (int i = 0; i < c->ni; ++i)
        if (!(IMP(c, i)[3] >= 0.0 && IMP(c, i)[3] <= 1.0)) {
            r->failure = LG_HY_RESTITUTION;
            r->failed_element = i;
            r->failed_value = IMP(c, i)[3];
            return 2;
        }
    for (int j = 0; j < c->nf + c->npf; ++j) {
        const double *mus = j < c->nf ? FR(c, j) + 2 : PF(c, j - c->nf) + 4;
        double mu = mus[0], mu_s = mus[1];
        if (!(mu >= 0.0) || !(mu_s >= mu)) {
            r->failure = mu >= 0.0 ? LG_HY_MU_STATIC : LG_HY_MU;
            r->failed_element = j;
            r->failed_value = mu >= 0.0 ? mu_s : mu;
            r->failed_other = mu;
            return 2;
        }
    }
    return 0;
}

static int hy_impacts(hy_ctx *c, double t, double *y, int nc);

/* The initial mode. A closed gap (g <= gap_tol) is at rest when |ġ| is at most the speed of a
 * fall through gap_tol, √(2·gap_tol·|g̈|) (g̈ with every contact open): it is held if its force
 * is then >= 0, with ġ set to 0 (hy_hold); one closing faster is struck; any other is free.
 * Frictions with |v| <= 1000·gap_tol try sticking. A gap below -gap_tol is a start inside the
 * surface (2, failure LG_HY_INSIDE). y changes when held or struck. */
static int hy_start(hy_ctx *c, double t, double *y)
{
    lg_hybrid_t *h = c->h;
    int nc = 0, nh = 0, closed = 0, err;
    hy_inputs(c, t);
    if (hy_terms(c, t, y, c->u))
        return 1;
    if (hy_check_coefficients(c))
        return 2;
    for (int i = 0; i < c->ni; ++i) {
        double g = IMP(c, i)[0];
        if (!(g >= -h->gap_tol)) {
            c->result->failure = LG_HY_INSIDE;
            c->result->failed_element = i;
            c->result->failed_value = g;
            return 2;
        }
        closed |= g <= h->gap_tol;
    }
    for (int j = 0; j < c->nf; ++j) {
        double v = FR(c, j)[0];
        h->slip[j] = fabs(v) <= 1e3 * h->gap_tol ? 0 : (v > 0 ? 1 : -1);
    }
    if (!closed)
        return hy_settle(c, t, y, 0);
    if (hy_solve(c, t, y, c->u, c->opened, h->slip, c->unset, h->anchor))
        return 1;
    for (int i = 0; i < c->ni; ++i) {
        double gdd = -IMP(c, i)[2];
        for (int b = 0; b < c->n; ++b)
            gdd += IMP(c, i)[IMPACT_FIELDS + b] * c->qdd[b];
        c->rest_speed[i] = sqrt(2.0 * h->gap_tol * fabs(gdd));
        h->contact[i] = IMP(c, i)[0] <= h->gap_tol && fabs(IMP(c, i)[1]) <= c->rest_speed[i];
    }
    if ((err = hy_settle(c, t, y, 0)))
        return err;
    for (int i = 0; i < c->ni; ++i)
        if (h->contact[i])
            c->held[nh++] = i;
    if (nh && (err = hy_hold(c, t, y, c->held, nh, 1)))
        return err;
    if (hy_terms(c, t, y, c->u))
        return 1;
    for (int i = 0; i < c->ni; ++i)
        if (IMP(c, i)[0] <= h->gap_tol && !h->contact[i] && IMP(c, i)[1] < -c->rest_speed[i])
            c->closing[nc++] = i;
    if (nc && (err = hy_impacts(c, t, y, nc)))
        return err;
    return hy_settle(c, t, y, 0);
}

static int hy_try_stick(hy_ctx *c, double t, const double *y, int j);

/* Slip direction sign(v), or 0 (|v| <= 1000·gap_tol), for the frictions on impact i (inactive
 * while it was open); terms at the state in c->terms. */
static void hy_classify_frictions(hy_ctx *c, int i)
{
    for (int j = 0; j < c->nf; ++j)
        if (c->h->normal_kind[j] == LG_NORMAL_IMPACT && c->h->normal_index[j] == i) {
            double v = FR(c, j)[0];
            c->h->slip[j] = fabs(v) <= 1e3 * c->h->gap_tol ? 0 : (v > 0 ? 1 : -1);
        }
}

/* The frictions on impact i, just held, start acting: those at v = 0 stick or slip by the
 * holding force (hy_try_stick), the others slip (recorded). */
static int hy_engage(hy_ctx *c, double t, const double *y, int i)
{
    int err;
    if (hy_terms(c, t, y, c->u))
        return 1;
    hy_classify_frictions(c, i);
    for (int j = 0; j < c->nf; ++j) {
        if (c->h->normal_kind[j] != LG_NORMAL_IMPACT || c->h->normal_index[j] != i)
            continue;
        if (c->h->slip[j] == 0) {
            if ((err = hy_try_stick(c, t, y, j)))
                return err;
        } else if (hy_record(c, t, c->ni + j, LG_SLIP)) {
            return -1;
        }
    }
    return 0;
}

static int hy_impacts(hy_ctx *c, double t, double *y, int nc)
{
    lg_hybrid_t *h = c->h;
    for (int a = 0; a < nc; ++a) {
        int i = c->closing[a];
        double speed = -IMP(c, i)[1];
        c->fastest[i] = fmax(c->fastest[i], speed);
        double rest = h->rest_velocity >= 0 ? h->rest_velocity : REST_FACTOR * c->fastest[i];
        c->e[a] = IMP(c, i)[3];
        c->resting[a] = c->e[a] * speed <= rest;
        if (c->resting[a])
            c->e[a] = 0.0;
    }
    if (hy_impact(c, t, y, c->u, c->closing, nc, c->e) || hy_terms(c, t, y, c->u))
        return 1;
    for (int i = 0; i < c->ni; ++i) {      /* held contacts the impulses lifted off */
        int in = 0;
        for (int a = 0; a < nc; ++a)
            in |= c->closing[a] == i;
        if (h->contact[i] && !in && IMP(c, i)[1] > 1e3 * h->gap_tol) {
            h->contact[i] = 0;
            if (hy_record(c, t, i, LG_RELEASE))
                return -1;
            c->bounced[c->n_bounced++] = i;
        }
    }
    for (int a = 0; a < nc; ++a) {
        int i = c->closing[a];
        if (c->resting[a]) {
            h->contact[i] = 1;
            if (hy_terms(c, t, y, c->u))
                return 1;
            hy_classify_frictions(c, i);
            if (hy_solve_mode(c, t, y))
                return 1;
            if (c->lam_i[i] >= 0) {
                if (hy_record(c, t, i, LG_CONTACT))
                    return -1;
                continue;
            }
            h->contact[i] = 0;
            c->resting[a] = 0;
        }
        if (hy_record(c, t, i, LG_IMPACT))
            return -1;
        c->bounced[c->n_bounced++] = i;
    }
    for (int a = 0, err; a < nc; ++a)
        if (c->resting[a] && (err = hy_engage(c, t, y, c->closing[a])))
            return err;
    return 0;
}

static int hy_try_stick(hy_ctx *c, double t, const double *y, int j)
{
    lg_hybrid_t *h = c->h;
    h->slip[j] = 0;
    if (hy_solve_mode(c, t, y))
        return 1;
    if (fabs(c->lam_f[j]) <= FR(c, j)[3] * c->normal[j])
        return hy_record(c, t, c->ni + j, LG_STICK) ? -1 : 0;
    h->slip[j] = c->lam_f[j] > 0 ? -1 : 1;
    return hy_record(c, t, c->ni + j, LG_SLIP) ? -1 : 0;
}

/* Planar friction k's event (lagrgen.hybrid.Switching._planar_event): sticking, its force
 * reached μ_s·|N| (it slips, away from the force); slipping, v reached 0 (it tries to stick)
 * or turned across its anchor (a new anchor along v). */
static int hy_planar_event(hy_ctx *c, double t, const double *y, int k, double v0, double v1)
{
    lg_hybrid_t *h = c->h;
    if (h->pmode[k] < 0)
        return 0;
    if (h->pmode[k] == 0) {
        if (hy_solve_mode(c, t, y))
            return 1;
        h->pmode[k] = 1;
        hy_set_anchor(h->anchor + 2 * k, -c->lam_p[2 * k], -c->lam_p[2 * k + 1]);
        return hy_record(c, t, c->ni + c->nf + k, LG_SLIP) ? -1 : 0;
    }
    if (hypot(v0, v1) <= 1e3 * h->gap_tol)
        return hy_try_stick_planar(c, t, y, k, 1);
    hy_set_anchor(h->anchor + 2 * k, v0, v1);
    return 0;
}

/* The switch after a segment ended at (t, y) on the events fired[0..nfired). */
static int hy_switch(hy_ctx *c, double t, double *y, int *fired, int nfired)
{
    lg_hybrid_t *h = c->h;
    int nc = 0, err;
    for (int k = 0; k < c->npf; ++k)
        c->sticking[k] = h->pmode[k] == 0;
    hy_inputs(c, t);
    if (hy_terms(c, t, y, c->u))
        return 1;
    if (hy_check_coefficients(c))
        return 2;
    for (int i = 0; i < c->ni; ++i) {
        int hit = 0;
        for (int a = 0; a < nfired; ++a)
            hit |= fired[a] == i;
        if (!h->contact[i] && (hit || IMP(c, i)[0] <= h->gap_tol) && IMP(c, i)[1] < 0)
            c->closing[nc++] = i;
    }
    if (nc && (err = hy_impacts(c, t, y, nc)))
        return err;
    for (int a = 0; a < nfired; ++a) {
        int i = fired[a], was_closing = 0;
        for (int b = 0; b < nc; ++b)
            was_closing |= c->closing[b] == i;
        if (i < c->ni && h->contact[i] && !was_closing) {
            h->contact[i] = 0;
            if (hy_record(c, t, i, LG_RELEASE))
                return -1;
        }
    }
    if (hy_terms(c, t, y, c->u))
        return 1;
    for (int j = 0; j < c->nf; ++j) {        /* slip velocities at zero with the one that fired */
        int in = 0;
        for (int a = 0; a < nfired; ++a)
            in |= fired[a] == c->ni + j;
        if (!in && h->slip[j] != 0 && fabs(FR(c, j)[0]) <= 1e3 * h->gap_tol)
            fired[nfired++] = c->ni + j;
    }
    for (int k = 0; k < c->npf; ++k) {
        int in = 0, e = c->ni + c->nf + k;
        for (int a = 0; a < nfired; ++a)
            in |= fired[a] == e;
        if (!in && h->pmode[k] == 1 && hypot(PF(c, k)[0], PF(c, k)[1]) <= 1e3 * h->gap_tol)
            fired[nfired++] = e;
    }
    for (int k = 0; k < c->npf; ++k) {   /* the planar slip velocities at this state */
        c->vel_p[2 * k] = PF(c, k)[0];
        c->vel_p[2 * k + 1] = PF(c, k)[1];
    }
    for (int a = 0; a < nfired; ++a) {
        int j = fired[a] - c->ni;
        if (j < 0 || !hy_active(c, j, h->contact))
            continue;
        if (j >= c->nf) {
            int k = j - c->nf;
            if ((err = hy_planar_event(c, t, y, k, c->vel_p[2 * k], c->vel_p[2 * k + 1])))
                return err;
        } else if (h->slip[j] == 0) {
            if (hy_solve_mode(c, t, y))
                return 1;
            h->slip[j] = c->lam_f[j] > 0 ? -1 : 1;
            if (hy_record(c, t, fired[a], LG_SLIP))
                return -1;
        } else if ((err = hy_try_stick(c, t, y, j))) {
            return err;
        }
    }
    return hy_settle(c, t, y, 1);
}

/* The forces (lg_hybrid_result_t.forces) of the output rows saved since the last call, all in
 * the mode (contact, slip, pmode, anchor); 0, or -1 when out of memory. */
static int hy_forces_since(hy_ctx *c, const int *contact, const int *slip, const int *pmode,
                           const double *anchor)
{
    lg_hybrid_result_t *res = c->result;
    int n = c->n, k = c->m + c->ni + c->nf + 2 * c->npf;
    double *row = c->force_row;
    int free = hy_is_free(c, contact, pmode);
    for (size_t r = k ? res->forces.len / k : res->t.len; r < res->t.len; ++r) {
        double t = res->t.data[r];
        hy_inputs(c, t);
        if (free) {                                    /* every stop open: no force */
            memset(row, 0, k * sizeof(double));
        } else if (hy_solve(c, t, res->y.data + r * 2 * n, c->u, contact, slip, pmode, anchor)) {
            for (int a = 0; a < k; ++a)
                row[a] = NAN;
        } else {
            for (int q = 0; q < c->m; ++q)
                row[q] = c->x[n + q];
            for (int i = 0; i < c->ni; ++i)
                row[c->m + i] = c->lam_i[i];
            for (int j = 0; j < c->nf; ++j)
                row[c->m + c->ni + j] = slip[j] == 0 ? c->lam_f[j]
                                        : -FR(c, j)[2] * slip[j] * c->normal[j];
            memcpy(row + c->m + c->ni + c->nf, c->lam_p, 2 * c->npf * sizeof(double));
        }
        if (k && lg_buf_push(&res->forces, row, k))
            return -1;
    }
    return 0;
}

/* Half the predicted flight of a contact that just bounced (inf when none). */
static double hy_lift_off(hy_ctx *c, double t, const double *y)
{
    int nb = c->n_bounced;
    c->n_bounced = 0;
    if (!nb)
        return INFINITY;
    hy_inputs(c, t);
    if (hy_solve_mode(c, t, y))
        return INFINITY;
    double shortest = INFINITY;
    for (int a = 0; a < nb; ++a) {
        int i = c->bounced[a];
        if (c->h->contact[i] || IMP(c, i)[1] <= 0)
            continue;
        double gdd = -IMP(c, i)[2];
        for (int b = 0; b < c->n; ++b)
            gdd += IMP(c, i)[IMPACT_FIELDS + b] * c->qdd[b];
        if (gdd < 0)
            shortest = fmin(shortest, IMP(c, i)[1] / -gdd);
    }
    return shortest;
}
/* -- the driver ----------------------------------------------------------------------------- */
static double hy_wall_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Count a segment that ended at t without progress (`short_segment`); 1 (status, failure and
 * message set) once LG_HY_STALL_SEGMENTS did so in a row, else 0. */
static int hy_stalled(lg_hybrid_result_t *res, double t, int short_segment, long *no_progress)
{
    *no_progress = short_segment ? *no_progress + 1 : 0;
    if (*no_progress < LG_HY_STALL_SEGMENTS)
        return 0;
    res->status = -1;
    res->failure = LG_HY_STALLED;
    res->t_reached = t;
    snprintf(res->message, sizeof res->message, "no progress at t = %.9g", t);
    return 1;
}

static void *hy_alloc(void **list, int *count, size_t bytes)
{
    void *p = calloc(1, bytes ? bytes : 1);
    list[(*count)++] = p;
    return p;
}

int lg_hybrid_solve(lg_hybrid_t *h, const lg_options_t *options, lg_hybrid_result_t *res)
{
    memset(res, 0, sizeof *res);
    res->least_pivot = 1.0;
    hy_ctx c;
    memset(&c, 0, sizeof c);
    c.h = h;
    c.result = res;
    c.n = h->n;
    c.m = h->m;
    c.ni = h->ni + h->n_stops;
    c.nf = h->nf;
    c.npf = h->npf;
    int n = h->n, dim = 2 * n, ni = c.ni, npf = h->npf, ne = ni + h->nf + npf;
    int rmax = h->m + ni + h->nf + 2 * npf, kmax = n + rmax, big = kmax > ne ? kmax : ne;
    int kimp = ni + 2 * npf, nw = kimp > h->nf + npf ? kimp : h->nf + npf;
    c.rmax = rmax;
    size_t nterms = (size_t)n * n + n + (size_t)h->m * n + h->m
                    + (size_t)h->ni * (IMPACT_FIELDS + n) + (size_t)h->nf * (FRICTION_FIELDS + n)
                    + (size_t)npf * (PLANAR_FIELDS + 2 * n);
    void *blocks[96];
    int nb = 0, rc = 0;
    size_t D = sizeof(double);
    size_t sq = (size_t)(big > n ? big : n);
    c.terms = hy_alloc(blocks, &nb, nterms * D);
    c.stop_rows = hy_alloc(blocks, &nb, ((size_t)h->n_stops * (IMPACT_FIELDS + n) + 1) * D);
    c.XB = hy_alloc(blocks, &nb, (size_t)n * (rmax + 1) * D);
    c.Dl = hy_alloc(blocks, &nb, ((size_t)rmax * rmax + 1) * D);
    c.Kd = hy_alloc(blocks, &nb, ((size_t)rmax * rmax + 1) * D);
    c.res = hy_alloc(blocks, &nb, (rmax + 1) * D);
    c.piv = hy_alloc(blocks, &nb, (n + 1) * sizeof(int));
    c.pivd = hy_alloc(blocks, &nb, (rmax + 1) * sizeof(int));
    c.reg = hy_alloc(blocks, &nb, (rmax + 1) * sizeof(int));
    c.lam_p = hy_alloc(blocks, &nb, (2 * npf + 1) * D);
    c.normal_p = hy_alloc(blocks, &nb, (npf + 1) * D);
    c.dir_p = hy_alloc(blocks, &nb, (2 * npf + 1) * D);
    c.vel_p = hy_alloc(blocks, &nb, (2 * npf + 1) * D);
    c.Wrow = hy_alloc(blocks, &nb, ((size_t)n * nw + 1) * D);
    c.row_of_planar = hy_alloc(blocks, &nb, (npf + 1) * sizeof(int));
    c.cone = hy_alloc(blocks, &nb, (2 * npf + h->nf + 1) * sizeof(int));
    c.gap_offset = hy_alloc(blocks, &nb, (ni + 1) * D);
    c.slip_offset = hy_alloc(blocks, &nb, (h->nf + npf + 1) * D);
    c.cached_y = hy_alloc(blocks, &nb, dim * D);
    c.activated = hy_alloc(blocks, &nb, (npf + 1) * sizeof(int));
    c.sticking = hy_alloc(blocks, &nb, (npf + 1) * sizeof(int));
    c.rested = hy_alloc(blocks, &nb, (npf + 1) * sizeof(int));
    c.slid = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    c.planars = hy_alloc(blocks, &nb, (npf + 1) * sizeof(int));
    int *unset = c.unset = hy_alloc(blocks, &nb, (npf + 1) * sizeof(int));
    c.K = hy_alloc(blocks, &nb, (size_t)kmax * kmax * D);
    c.x = hy_alloc(blocks, &nb, (sq + 1) * D);
    c.R = hy_alloc(blocks, &nb, ((size_t)rmax * n + 1) * D);
    c.rhs = hy_alloc(blocks, &nb, (rmax + 1) * D);
    c.sigma = hy_alloc(blocks, &nb, (rmax + 1) * D);
    c.force = hy_alloc(blocks, &nb, n * D);
    c.lam_i = hy_alloc(blocks, &nb, (ni + 1) * D);
    c.lam_f = hy_alloc(blocks, &nb, (h->nf + 1) * D);
    c.normal = hy_alloc(blocks, &nb, (h->nf + 1) * D);
    c.qdd = hy_alloc(blocks, &nb, n * D);
    c.u = hy_alloc(blocks, &nb, (h->n_inputs + 1) * D);
    c.P = hy_alloc(blocks, &nb, (size_t)n * n * D);
    c.Minv = hy_alloc(blocks, &nb, (size_t)n * n * D);
    c.work = hy_alloc(blocks, &nb, sq * sq * D);
    c.D = hy_alloc(blocks, &nb, ((size_t)kimp * kimp + 1) * D);
    c.WP = hy_alloc(blocks, &nb, ((size_t)n * (kimp > h->m ? kimp : h->m) + 1) * D);
    c.impulse = hy_alloc(blocks, &nb, (kimp + 1) * D);
    c.after = hy_alloc(blocks, &nb, (kimp + 1) * D);
    c.target = hy_alloc(blocks, &nb, (kimp + 1) * D);
    c.before = hy_alloc(blocks, &nb, (kimp + 1) * D);
    c.e = hy_alloc(blocks, &nb, (ni + 1) * D);
    c.fastest = hy_alloc(blocks, &nb, (ni + 1) * D);
    c.rest_speed = hy_alloc(blocks, &nb, (ni + 1) * D);
    c.fy = hy_alloc(blocks, &nb, dim * D);
    c.fy2 = hy_alloc(blocks, &nb, dim * D);
    c.yp = hy_alloc(blocks, &nb, dim * D);
    c.row_of_impact = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    c.row_of_friction = hy_alloc(blocks, &nb, (h->nf + 1) * sizeof(int));
    c.involved = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    c.closing = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    c.resting = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    c.bounced = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    c.held = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    c.force_row = hy_alloc(blocks, &nb, (rmax + 1) * D);
    int *opened = c.opened = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    double *y = hy_alloc(blocks, &nb, dim * D);
    double *emax = hy_alloc(blocks, &nb, (ne + 1) * D);
    double *edir = hy_alloc(blocks, &nb, (ne + 1) * D);
    int *fired = hy_alloc(blocks, &nb, (ne + 1) * sizeof(int));
    int *mode_c = hy_alloc(blocks, &nb, (ni + 1) * sizeof(int));
    int *mode_s = hy_alloc(blocks, &nb, (h->nf + 1) * sizeof(int));
    int *mode_p = hy_alloc(blocks, &nb, (npf + 1) * sizeof(int));
    double *mode_a = hy_alloc(blocks, &nb, (2 * npf + 1) * D);
    for (int k = 0; k < nb; ++k)
        if (!blocks[k])
            rc = -1;
    double *te_buf = hy_alloc(blocks, &nb, ((options->t_eval ? options->n_eval : 0) + 1) * D);
    for (int k = 0; k < nb; ++k)
        if (!blocks[k])
            rc = -1;
    if (rc) {
        snprintf(res->message, sizeof res->message, "out of memory");
        rc = -1;
        goto done;
    }
    for (int k = 0; k < ne; ++k) {
        emax[k] = 1.0;
        edir[k] = -1.0;
    }
    for (int k = 0; k < npf; ++k)
        unset[k] = -1;
    memcpy(y, options->y0, dim * D);
    double t = options->t0, tf = options->tf;
    int err = hy_start(&c, t, y);
    if (err) {
        res->status = -1;
        if (err == 1)
            res->failure = LG_HY_MODEL;
        snprintf(res->message, sizeof res->message, err < 0 ? "out of memory" : err == 2 ?
                 "the initial state or coefficients are invalid" :
                 "the model failed at the initial state (mass matrix or mode equations singular)");
        rc = err < 0 ? -1 : 0;
        goto done;
    }
    if (!options->t_eval && res->transitions.len       /* struck at the start: before, after */
        && (lg_buf_push(&res->t, &t, 1) || lg_buf_push(&res->y, options->y0, dim)
            || hy_forces_since(&c, opened, h->slip, unset, h->anchor))) {
        rc = -1;
        goto done;
    }
    if (!options->t_eval && (lg_buf_push(&res->t, &t, 1) || lg_buf_push(&res->y, y, dim))) {
        rc = -1;
        goto done;
    }
    int eval_i = 0;
    while (options->t_eval && eval_i < options->n_eval && options->t_eval[eval_i] <= t) {
        if (lg_buf_push(&res->t, &options->t_eval[eval_i], 1) || lg_buf_push(&res->y, y, dim)) {
            rc = -1;
            goto done;
        }
        ++eval_i;
    }
    if (hy_forces_since(&c, h->contact, h->slip, h->pmode, h->anchor)) {
        rc = -1;
        goto done;
    }
    snprintf(res->message, sizeof res->message, "The solver successfully reached the end.");
    double interval = options->poll_interval > 0 ? options->poll_interval : 0.05;
    double started = hy_wall_seconds(), next_poll = started + interval;
    double far = fmax(fabs(options->t0), fabs(tf));
    double least = 10 * fabs(nextafter(far, INFINITY) - far);   /* as lg_solve's stall test */
    double budget = options->max_steps > 0 || options->t_eval || options->save_budget < 0 ? 0
                    : (options->save_budget > 0 ? options->save_budget : (double)LG_SAVE_BUDGET);
    long no_progress = 0;
    while (t < tf) {
        double t_start = t;
        int stop = 0;                                   /* the guards hold between segments too */
        if (options->max_steps > 0 && res->n_steps >= options->max_steps)
            stop = LG_STOP_STEPS;
        else if (options->max_wall_time > 0
                 && hy_wall_seconds() - started > options->max_wall_time)
            stop = LG_STOP_WALL;
        else if (budget > 0 && (double)(res->t.len + res->y.len) > budget)
            stop = LG_STOP_SAVED;
        else if (options->poll && hy_wall_seconds() >= next_poll) {
            next_poll = hy_wall_seconds() + interval;
            if (options->poll(options->poll_ctx, t))
                stop = LG_STOP_POLL;
        }
        if (stop) {
            res->status = -1;
            res->stopped = stop;
            res->t_reached = t;
            snprintf(res->message, sizeof res->message, "stopped at t = %.9g", t);
            break;
        }
        memcpy(mode_c, h->contact, (ni + 1) * sizeof(int));
        memcpy(mode_s, h->slip, (h->nf + 1) * sizeof(int));
        memcpy(mode_p, h->pmode, npf * sizeof(int));
        memcpy(mode_a, h->anchor, 2 * npf * D);
        c.contact = mode_c;
        c.slip = mode_s;
        c.pmode = mode_p;
        c.anchor = mode_a;
        c.free = hy_is_free(&c, mode_c, mode_p);
        double piece = hy_lift_off(&c, t, y);
        double t_end = isfinite(piece) ? fmin(tf, t + 0.5 * piece) : tf;
        if (!(t_end > t))
            t_end = tf;
        lg_problem_t pb;
        memset(&pb, 0, sizeof pb);
        pb.dim = dim;
        pb.sys_rhs = hy_rhs;
        pb.sys_jac = hy_jacobian;
        pb.sys_events = ne ? hy_events : NULL;
        pb.sys_ctx = &c;
        pb.p = h->p;
        pb.n_inputs = h->n_inputs;
        pb.inputs = h->inputs;
        pb.n_events = ne;
        pb.event_max = emax;
        pb.event_direction = edir;
        lg_options_t op = *options;
        if (options->max_steps > 0)                     /* the guards hold for the whole solve */
            op.max_steps = options->max_steps - res->n_steps > 0
                               ? options->max_steps - res->n_steps : 1;
        if (options->max_wall_time > 0)
            op.max_wall_time = fmax(options->max_wall_time - (hy_wall_seconds() - started),
                                    1e-9);
        if (budget > 0)
            op.save_budget = fmax(budget - (double)(res->t.len + res->y.len), 1.0);
        op.t0 = t;
        op.tf = t_end;
        op.y0 = y;
        op.dense = 0;
        int first = eval_i, last = eval_i, extra = 0;
        if (options->t_eval) {
            /* the t_eval points of the piece, then t_end (dropped after: the next start) */
            while (last < options->n_eval && options->t_eval[last] <= t_end)
                ++last;
            memcpy(te_buf, options->t_eval + first, (size_t)(last - first) * D);
            if (last == first || te_buf[last - first - 1] < t_end) {
                te_buf[last - first] = t_end;
                extra = 1;
            }
            op.t_eval = te_buf;
            op.n_eval = last - first + extra;
        }
        lg_result_t seg;
        memset(&seg, 0, sizeof seg);
        if (lg_solve(&pb, &op, &seg) < 0) {
            snprintf(res->message, sizeof res->message, "%s", seg.message);
            lg_result_free(&seg);
            rc = -1;
            goto done;
        }
        res->nfev += seg.nfev;
        res->n_steps += seg.n_steps;
        res->n_segments += 1;
        if (seg.stopped) {
            res->status = -1;
            res->stopped = seg.stopped;
            res->t_reached = seg.t_reached;
            snprintf(res->message, sizeof res->message, "stopped at t = %.9g", seg.t_reached);
            /* the steps (or the t_eval points) up to the cut; not the start, nor t_end */
            size_t from = options->t_eval ? 0 : 1, keep = seg.t.len;
            if (extra && keep && seg.t.data[keep - 1] == t_end)
                --keep;
            if (keep > from
                && (lg_buf_push(&res->t, seg.t.data + from, keep - from)
                    || lg_buf_push(&res->y, seg.y.data + from * dim, (keep - from) * dim))) {
                lg_result_free(&seg);
                rc = -1;
                goto done;
            }
            lg_result_free(&seg);
            if (hy_forces_since(&c, mode_c, mode_s, mode_p, mode_a))
                rc = -1;
            break;
        }
        if (seg.status < 0) {
            res->status = -1;
            snprintf(res->message, sizeof res->message, "at t = %.9g: %s", seg.t.len ?
                     seg.t.data[seg.t.len - 1] : t, seg.message);
            lg_result_free(&seg);
            break;
        }
        size_t rows = seg.t.len;
        if (options->t_eval) {
            size_t keep = rows;
            if (extra && seg.status == 0)
                --keep;                                   /* t_end, not asked for */
            if (lg_buf_push(&res->t, seg.t.data, keep) || lg_buf_push(&res->y, seg.y.data, keep * dim)) {
                lg_result_free(&seg);
                rc = -1;
                goto done;
            }
            eval_i = first + (int)keep;
        } else if (rows > 1 && (lg_buf_push(&res->t, seg.t.data + 1, rows - 1)
                                || lg_buf_push(&res->y, seg.y.data + dim, (rows - 1) * dim))) {
            lg_result_free(&seg);
            rc = -1;
            goto done;
        }
        if (hy_forces_since(&c, mode_c, mode_s, mode_p, mode_a)) {
            lg_result_free(&seg);
            rc = -1;
            goto done;
        }
        if (seg.status == 0) {
            memcpy(y, seg.y.data + (rows - 1) * dim, dim * D);
            t = t_end;
            lg_result_free(&seg);
            if (hy_stalled(res, t, t - t_start < least, &no_progress))
                break;
            continue;
        }
        /* terminal event(s): the earliest time, every event found there */
        size_t nev = seg.ev.len / 2;
        double t_hit = INFINITY;
        for (size_t a = 0; a < nev; ++a)
            t_hit = fmin(t_hit, seg.ev.data[2 * a + 1]);
        int nfired = 0;
        for (size_t a = 0; a < nev; ++a)
            if (seg.ev.data[2 * a + 1] == t_hit) {
                if (nfired == 0)
                    memcpy(y, seg.ev_y.data + a * dim, dim * D);
                fired[nfired++] = (int)seg.ev.data[2 * a];
            }
        lg_result_free(&seg);
        t = t_hit;
        err = hy_switch(&c, t, y, fired, nfired);
        if (err) {
            res->status = -1;
            res->t_reached = t;
            if (err == 1)
                res->failure = LG_HY_MODEL;
            snprintf(res->message, sizeof res->message, err < 0 ? "out of memory" :
                     "at t = %.9g the model failed while switching modes", t);
            rc = err < 0 ? -1 : 0;
            break;
        }
        if ((long)(res->transitions.len / 3) > h->max_transitions) {
            res->status = -1;
            snprintf(res->message, sizeof res->message,
                     "more than %ld mode switches by t = %.9g: the contacts or frictions chatter "
                     "(raise max_transitions, or check the model)", h->max_transitions, t);
            break;
        }
        if (!options->t_eval && (lg_buf_push(&res->t, &t, 1) || lg_buf_push(&res->y, y, dim)
                                 || hy_forces_since(&c, h->contact, h->slip, h->pmode,
                                                    h->anchor))) {
            rc = -1;
            goto done;
        }
        if (hy_stalled(res, t, t - t_start < least, &no_progress))
            break;
    }
done:
    for (int k = 0; k < nb; ++k)
        free(blocks[k]);
    return rc;
}
