/* lagrgen's hybrid driver: impacts, resting contact and Coulomb friction with sticking, a solve
 * as a sequence of smooth lg_solve segments with the switches between them (the C port of
 * lagrgen/hybrid.py: the same modes, events, impact law and switching rules).
 *
 * Reentrant: everything lives in the caller's lg_hybrid_t and lg_hybrid_result_t.
 */
#ifndef LG_HYBRID_H
#define LG_HYBRID_H

#include "lg_ode.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Transition kinds (lg_hybrid_result_t.transitions rows are (t, element, kind)). */
enum { LG_IMPACT = 0, LG_CONTACT = 1, LG_RELEASE = 2, LG_STICK = 3, LG_SLIP = 4 };
/* Why a hybrid solve failed (lg_hybrid_result_t.failure): the model's functions or the mode
 * equations (singular); a start inside an impact's surface (gap < -gap_tol); a restitution
 * outside [0, 1]; mu < 0; mu_static < mu (failed_element: the impact or friction, failed_value
 * and failed_other: the values); no progress (LG_HY_STALL_SEGMENTS segments in a row shorter
 * than ten spacings of doubles at the far end of the span). */
enum { LG_HY_OK = 0, LG_HY_MODEL = 1, LG_HY_INSIDE = 2, LG_HY_RESTITUTION = 3, LG_HY_MU = 4,
       LG_HY_MU_STATIC = 5, LG_HY_STALLED = 6 };
#define LG_HY_STALL_SEGMENTS 100
/* What a friction's normal force is: an expression, a constraint's or an impact's multiplier. */
enum { LG_NORMAL_EXPRESSION = 0, LG_NORMAL_CONSTRAINT = 1, LG_NORMAL_IMPACT = 2 };

typedef struct {
    int n, m, ni, nf;            /* coordinates, model constraints, impacts, frictions */
    lg_rhs_fn terms;             /* the model's hybrid_terms: M, F, A, γ, terms (lagrgen.nonsmooth) */
    const double *p;
    int n_inputs;
    const lg_signal_t *inputs;
    const int *normal_kind;      /* nf */
    const int *normal_index;     /* nf */
    double rest_velocity;        /* < 0: 1e-6 times the largest impact speed of the contact */
    double gap_tol;              /* a gap within it is closed; a slip velocity within 1000× is 0 */
    long max_transitions;
    int *contact;                /* ni + n_stops, in/out: 1 held */
    int *slip;                   /* nf, in/out: +1/-1 slipping that way, 0 sticking (a friction
                                  * on an open contact is inactive: N = 0, no force, no event) */
    /* Enforced limits (lagrgen.hybrid.HybridSystem.stop_rows): impacts ni … ni + n_stops − 1
     * after the model's, on gaps sign·(q_j − bound); 4 numbers each: j, sign, bound,
     * restitution. */
    int n_stops;
    const double *stops;
    /* Planar (isotropic) frictions, elements after the frictions: their normal forces as
     * normal_kind/normal_index; their mode (in/out): −1 inactive (their contact open), 0
     * sticking, 1 slipping along the unit anchor (2 numbers each) as it started. */
    int npf;
    const int *planar_kind;
    const int *planar_index;
    int *pmode;
    double *anchor;
    /* The model's own ẏ (its rhs; NULL: none), a free mode's right-hand side: no model
     * constraints, no contact closed, no friction acting (lagrgen.hybrid.HybridSystem.is_free;
     * its events the gaps alone, its forces 0). */
    lg_rhs_fn rhs;
} lg_hybrid_t;

typedef struct {
    int status;                  /* 0 reached tf, -1 failure or stopped */
    int stopped;                 /* 0, or LG_STOP_*: a guard (max_steps, max_wall_time of the
                                  * options, for the whole solve) or the poll ended it */
    double t_reached;            /* where it stopped */
    char message[256];
    long nfev, n_steps, n_segments;
    int failure;                 /* LG_HY_*: why status is -1 (0 when stopped or fine) */
    int failed_element;
    double failed_value, failed_other;
    lg_buf_t t, y;               /* output times and states */
    lg_buf_t forces;             /* per output time, in the mode of that time: λ of the model's
                                  * constraints (m), the contact forces (ni + n_stops, 0 while
                                  * open), the friction forces along the slip direction (nf: the
                                  * sticking multiplier, or −μ·|N|·s while slipping), the planar
                                  * frictions' two components (2·npf); NaN if singular */
    lg_buf_t transitions;        /* (t, element, kind) triples */
    double least_pivot;          /* the least |U_kk|/M_kk of M's factorizations (1 at most): M
                                  * nearly singular below ~1e-8 (Euler angles near gimbal lock) */
} lg_hybrid_result_t;

/* Run a hybrid solve from y0 over [t0, tf] (options: method, tolerances, max_step, t_eval; its
 * y0, t0, tf, dense and events are set per segment). The initial mode is classified as at any
 * switch (closed gaps closing struck; at rest, |ġ| <= √(2·gap_tol·|g̈|), held with ġ set to 0
 * by an inelastic impulse; opening free; frictions with v = 0 tried sticking). max_steps,
 * max_wall_time (and the default save budget) bound the whole solve,
 * max_transitions the switches. Returns 0 when it ran (the outcome in result->status and
 * result->failure), -1 when out of memory. Always free the result. */
int lg_hybrid_solve(lg_hybrid_t *h, const lg_options_t *options, lg_hybrid_result_t *result);
void lg_hybrid_result_free(lg_hybrid_result_t *result);

#ifdef __cplusplus
}
#endif
#endif
