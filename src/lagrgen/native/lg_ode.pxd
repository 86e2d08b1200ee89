# The C interface of lagrgen's native ODE core (lg_ode.h), for the Cython modules that call it.
# The model functions it takes have the one signature of a compiled model (runtime/abi.pxd).
from lagrgen.runtime.abi cimport lg_function


cdef extern from "lg_ode.h":
    ctypedef lg_function lg_rhs_fn
    ctypedef lg_function lg_jac_fn
    ctypedef lg_function lg_events_fn
    ctypedef int (*lg_sys_fn)(void *ctx, double t, const double *y, const double *u,
                              double *out) noexcept nogil
    ctypedef int (*lg_poll_fn)(void *ctx, double t) noexcept nogil
    enum:
        LG_RK23, LG_RK45, LG_DOP853, LG_RADAU, LG_BDF
        LG_STOP_NONE, LG_STOP_STEPS, LG_STOP_WALL, LG_STOP_POLL, LG_STOP_SAVED
    ctypedef struct lg_signal_t:
        int kind
        int m
        double value
        const double *ts
        const double *values
        const double *coef
    ctypedef struct lg_problem_t:
        int dim
        lg_rhs_fn rhs
        lg_jac_fn jacobian
        const double *p
        int n_inputs
        const lg_signal_t *inputs
        lg_events_fn events
        int n_events
        const double *event_max
        const double *event_direction
        lg_sys_fn sys_rhs
        lg_sys_fn sys_jac
        lg_sys_fn sys_events
        void *sys_ctx
    ctypedef struct lg_options_t:
        int method
        double t0, tf
        const double *y0
        double rtol
        double rtol_given
        const double *atol
        double max_step
        double first_step
        const double *t_eval
        int n_eval
        int dense
        int stop_on_nonfinite
        long max_steps
        double max_wall_time
        lg_poll_fn poll
        void *poll_ctx
        double poll_interval
        double save_budget
    ctypedef struct lg_buf_t:
        double *data
        size_t len, cap
    ctypedef struct lg_result_t:
        int status
        int stopped
        double t_reached
        char message[256]
        long nfev, njev, nlu
        long n_steps
        int model_failure
        double fail_t
        lg_buf_t t, y, seg, coef, ev, ev_y, fail_y
    int lg_solve(const lg_problem_t *, const lg_options_t *, lg_result_t *) nogil
    void lg_result_free(lg_result_t *) nogil
    double lg_signal_eval(const lg_signal_t *, double) nogil
