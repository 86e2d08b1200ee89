/* lagrgen's native ODE core: a C port of SciPy 1.17's scipy/integrate/_ivp (BSD-3-Clause,
 * Copyright (c) 2001-2002 Enthought, Inc. 2003, SciPy Developers) that takes the same steps as
 * solve_ivp: RK23, RK45, DOP853 (rk.py), Radau IIA 5 (radau.py), variable-order BDF (bdf.py),
 * select_initial_step and norm (common.py), and solve_ivp's loop with t_eval, dense output and
 * events (ivp.py).
 *
 * Reentrant: no global mutable state. Everything a solve needs lives in the structs the caller
 * owns (lg_problem_t, lg_options_t) and in the lg_result_t that lg_solve fills; lg_solve may be
 * called from any thread, with the GIL released, concurrently with other solves.
 */
#ifndef LG_ODE_H
#define LG_ODE_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The model: y' = rhs(t, y), J = d rhs / d y (row-major dim x dim). Return 0, or 1 when the
 * mass matrix is not positive definite (the solve then stops with status -1). */
typedef int (*lg_rhs_fn)(double t, const double *y, const double *p, const double *u,
                         double *ydot);
typedef int (*lg_jac_fn)(double t, const double *y, const double *p, const double *u,
                         double *J);
/* The most events a solve locates (the hybrid driver's impacts, stops and frictions). */
#define LG_MAX_EVENTS 1024
/* n_events event values g_i(t, y); return 0 (nonzero stops the solve with status -1). */
typedef int (*lg_events_fn)(double t, const double *y, const double *p, const double *u,
                            double *values);
/* Optional system hooks: when set, the engine evaluates the system through them (with sys_ctx)
 * instead of the model's rhs / jacobian / events; y is the engine's state of length dim and u the
 * inputs at t. Same return convention as the model functions. */
typedef int (*lg_sys_fn)(void *ctx, double t, const double *y, const double *u, double *out);
/* Called about every poll_interval seconds of wall time during a solve (after an accepted step);
 * nonzero stops the solve (status -1, stopped = LG_STOP_POLL) keeping the result so far. */
typedef int (*lg_poll_fn)(void *ctx, double t);

enum { LG_RK23 = 0, LG_RK45 = 1, LG_DOP853 = 2, LG_RADAU = 3, LG_BDF = 4 };
/* Why a solve stopped before tf (lg_result_t.stopped). LG_STOP_SAVED: the default bound on the
 * results a solve saves per step (save_budget) was reached. */
enum { LG_STOP_NONE = 0, LG_STOP_STEPS = 1, LG_STOP_WALL = 2, LG_STOP_POLL = 3,
       LG_STOP_SAVED = 4 };
/* Without max_steps and t_eval a solve saves every step: it stops (LG_STOP_SAVED) once that
 * would exceed this many doubles (t, y and dense coefficients: 1 GiB), so that a run whose step
 * size collapses cannot take the machine's memory. */
#define LG_SAVE_BUDGET ((size_t)1 << 27)
/* A solve fails (status -1) after this many accepted steps in a row shorter than ten spacings of
 * doubles at the far end of its span (10·|nextafter(T, ±inf) − T|, T = max(|t0|, |tf|), SciPy's
 * smallest step there): at that pace it could not reach tf in 10^14 steps. */
#define LG_STALL_STEPS 1000
enum { LG_SIGNAL_CONSTANT = 0, LG_SIGNAL_LINEAR = 1, LG_SIGNAL_CUBIC = 2,
       LG_SIGNAL_PREVIOUS = 3 };

/* One input u_i(t). CONSTANT: value. LINEAR: numpy.interp(t, ts, values) (end values held).
 * PREVIOUS: values[k] for ts[k] <= t < ts[k+1] (values[0] before ts[0], values[m-1] after).
 * CUBIC: piecewise cubic with coefficients coef[4*k + j] = c[j, k] of scipy's CubicSpline
 * (u = sum_j c[j,k] (t - ts[k])^(3-j)), extrapolated with the end pieces as CubicSpline does. */
typedef struct {
    int kind;
    int m;                 /* number of samples (>= 2 unless CONSTANT) */
    double value;          /* CONSTANT */
    const double *ts;      /* m strictly increasing times */
    const double *values;  /* m values (LINEAR, PREVIOUS) */
    const double *coef;    /* 4*(m-1) (CUBIC) */
} lg_signal_t;

typedef struct {
    int dim;                    /* state dimension (2n) */
    lg_rhs_fn rhs;
    lg_jac_fn jacobian;         /* required by Radau and BDF */
    const double *p;            /* parameters, passed through */
    int n_inputs;
    const lg_signal_t *inputs;  /* n_inputs signals, evaluated into a per-solve u buffer */
    lg_events_fn events;        /* NULL: no events */
    int n_events;
    const double *event_max;    /* per event: count that terminates (INFINITY: never) */
    const double *event_direction; /* per event: >0 rising, <0 falling, 0 both */
    lg_sys_fn sys_rhs;          /* NULL: rhs */
    lg_sys_fn sys_jac;          /* NULL: jacobian */
    lg_sys_fn sys_events;       /* NULL: events */
    void *sys_ctx;
} lg_problem_t;

typedef struct {
    int method;
    double t0, tf;
    const double *y0;           /* dim */
    double rtol;                /* >= 100 EPS (common.validate_tol) */
    double rtol_given;          /* the rtol the user gave: Radau/BDF's Newton tolerance uses it */
    const double *atol;         /* dim */
    double max_step;            /* INFINITY for none */
    double first_step;          /* 0: select_initial_step */
    const double *t_eval;       /* NULL, or n_eval times in the direction of integration */
    int n_eval;
    int dense;                  /* keep the per-step interpolant coefficients */
    int stop_on_nonfinite;      /* 1: a NaN/inf derivative ends the solve (model_failure 3) */
    long max_steps;             /* > 0: stop after this many accepted steps (LG_STOP_STEPS) */
    double max_wall_time;       /* > 0: stop after this many seconds (LG_STOP_WALL) */
    lg_poll_fn poll;            /* NULL: never called */
    void *poll_ctx;
    double poll_interval;       /* seconds between polls (<= 0: 0.05) */
    double save_budget;         /* doubles a solve without max_steps and t_eval may save
                                 * (0: LG_SAVE_BUDGET, < 0: no bound) */
} lg_options_t;

/* A growable array of doubles. */
typedef struct {
    double *data;
    size_t len, cap;
} lg_buf_t;

typedef struct {
    int status;                 /* 0 reached tf, 1 terminal event, -1 failure or stopped */
    int stopped;                /* LG_STOP_*: a guard or the poll ended the solve at t_reached */
    double t_reached;           /* the time of the last accepted step when stopped */
    char message[256];
    long nfev, njev, nlu;
    long n_steps;               /* accepted steps */
    int model_failure;          /* 1: rhs/jacobian reported M not positive definite, 2: events
                                 * failed, 3: a non-finite derivative (stop_on_nonfinite);
                                 * at fail_t with the state in fail_y */
    double fail_t;
    lg_buf_t fail_y;
    lg_buf_t t, y;              /* output times and states (len(t) rows of dim) */
    /* Dense output, one segment per step: seg[5*k..] = (t_old, t, offset into coef, order,
     * h) and coef[offset..] the method's coefficient block (see lg_ode.c, store_dense). */
    lg_buf_t seg, coef;
    /* Events: (index, t) pairs in ev, states in ev_y (dim each), in the order found. */
    lg_buf_t ev, ev_y;
} lg_result_t;

/* Zero-initialise lg_problem_t and lg_options_t (memset) so that fields not set are off.
 * Run one solve. Returns 0 when it ran (the outcome is in result->status), -1 when out of
 * memory or given invalid options (result->message says which). Always free the result. */
int lg_solve(const lg_problem_t *problem, const lg_options_t *options, lg_result_t *result);
void lg_result_free(lg_result_t *result);

/* Append k doubles to a growable buffer (0, or -1 when out of memory). */
int lg_buf_push(lg_buf_t *b, const double *x, size_t k);

/* u_i(t) of one signal (also used by the tests through the Python wrapper). */
double lg_signal_eval(const lg_signal_t *s, double t);

#ifdef __cplusplus
}
#endif
#endif
