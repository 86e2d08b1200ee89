# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# cython: embedsignature=True
"""One native solve (lagrgen/native/lg_ode.c) with the GIL released, returning plain arrays.

The model's C functions are passed as integer addresses (see CompiledModel.function_address);
nothing here imports SciPy. `lagrgen.native.engine` builds the user-facing OdeResult.
"""
import numpy as np
cimport numpy as cnp
from libc.stdint cimport uintptr_t
from libc.stdlib cimport calloc, free
from libc.string cimport memcpy, memset
from libc.math cimport NAN
from cpython.exc cimport PyErr_CheckSignals

cnp.import_array()

from lagrgen.native.lg_ode cimport *
from lagrgen.runtime.abi cimport lg_directions_fn
from lagrgen.methods import BY_NAME, NATIVE_CODES as METHOD_CODES

cdef extern from "lg_sensitivity.h":
    ctypedef struct lg_sens_ctx:
        lg_directions_fn directional
        lg_jac_fn jacobian
        const double *p
        int dim, k
        const double *P
        double *J
    int lg_sens_rhs(void *ctx, double t, const double *z, const double *u, double *out) noexcept nogil
    int lg_sens_jac(void *ctx, double t, const double *z, const double *u, double *out) noexcept nogil


SIGNAL_CODES = {"constant": 0, "linear": 1, "cubic": 2, "previous": 3}


cdef cnp.ndarray f64(obj):
    return np.ascontiguousarray(obj, dtype=np.float64)


cdef cnp.ndarray buf_array(lg_buf_t *b, Py_ssize_t width):
    """A new (len/width, width) array holding a copy of the buffer (width 0: 1-D)."""
    cdef Py_ssize_t count = <Py_ssize_t>b.len
    if width == 0:
        out = np.empty(count)
    else:
        out = np.empty((count // width, width))
    cdef double[::1] flat = out.reshape(-1)
    if count:
        memcpy(&flat[0], b.data, count * sizeof(double))
    return out


cdef int fill_signals(list inputs, lg_signal_t *sig, list keep) except -1:
    """Fill sig[i] from (kind, value, ts, values, coef) tuples, keeping the arrays alive."""
    cdef cnp.ndarray ts, vs, cf
    for i, (kind, value, ts_, vs_, cf_) in enumerate(inputs):
        ts, vs, cf = f64(ts_), f64(vs_), f64(cf_)
        keep.extend((ts, vs, cf))
        if kind not in SIGNAL_CODES:
            raise ValueError(f"unknown input kind {kind!r}")
        if kind == "cubic" and cf.shape[0] != 4 * (ts.shape[0] - 1):
            raise ValueError("a cubic signal needs 4 coefficients per interval")
        if kind in ("linear", "previous") and vs.shape[0] != ts.shape[0]:
            raise ValueError("a signal needs one value per sample time")
        sig[i].kind = SIGNAL_CODES[kind]
        sig[i].value = value
        sig[i].m = ts.shape[0]
        if sig[i].kind != 0 and sig[i].m < 2:
            raise ValueError("a signal needs at least 2 samples")
        sig[i].ts = <const double *>cnp.PyArray_DATA(ts)
        sig[i].values = <const double *>cnp.PyArray_DATA(vs)
        sig[i].coef = <const double *>cnp.PyArray_DATA(cf)
    return 0


def signal_values(tuple spec, t):
    """Evaluate one input spec (kind, value, ts, values, coef) at the times t with the C code."""
    cdef lg_signal_t sig
    keep = []
    fill_signals([spec], &sig, keep)
    cdef cnp.ndarray tt = f64(np.atleast_1d(t))
    cdef cnp.ndarray out = np.empty(tt.shape[0])
    cdef double[::1] tv = tt, ov = out
    cdef Py_ssize_t i
    for i in range(tv.shape[0]):
        ov[i] = lg_signal_eval(&sig, tv[i])
    return out


cdef class Poll:
    """What a native solve does about every `interval` seconds of wall time: run pending signal
    handlers (Ctrl-C raises KeyboardInterrupt there, in the main thread), stop when `stop` (an
    object with is_set(), e.g. threading.Event) is set, and call `progress(t)`. An exception is
    kept in `error` and ends the solve; the caller re-raises it."""
    cdef public object progress, stop, error
    cdef public double interval

    def __init__(self, progress=None, stop=None, double interval=0.05):
        self.progress, self.stop, self.error, self.interval = progress, stop, None, interval

    cdef int check(self, double t) noexcept:
        try:
            PyErr_CheckSignals()
            if self.stop is not None and self.stop.is_set():
                return 1
            if self.progress is not None:
                self.progress(t)
        except BaseException as exc:
            self.error = exc
            return 1
        return 0


cdef int poll_callback(void *ctx, double t) noexcept nogil:
    with gil:
        return (<Poll>ctx).check(t)


cdef void set_options(lg_options_t *op, str method, double t0, double tf, double rtol,
                      const double *atol, double max_step, double first_step,
                      const double *t_eval, int n_eval, bint dense, bint stop_on_nonfinite,
                      long max_steps, double max_wall_time):
    """The solver options every native solve fills the same way (op zeroed first; rtol clipped
    to 100 EPS as SciPy's validate_tol, the Newton tolerance keeping the rtol given)."""
    memset(op, 0, sizeof(lg_options_t))
    op.method = METHOD_CODES[method]
    op.t0 = t0
    op.tf = tf
    op.rtol = max(rtol, 100 * 2.220446049250313e-16)
    op.rtol_given = rtol
    op.atol = atol
    op.max_step = max_step
    op.first_step = first_step
    op.t_eval = t_eval
    op.n_eval = n_eval
    op.dense = dense
    op.stop_on_nonfinite = stop_on_nonfinite
    op.max_steps = max_steps
    op.max_wall_time = max_wall_time


cdef void set_poll(lg_options_t *op, Poll poll):
    """Let `poll` (None: nothing) run about every poll.interval seconds of the solve."""
    if poll is not None:
        op.poll = poll_callback
        op.poll_ctx = <void *>poll
        op.poll_interval = poll.interval


def solve(str method, uintptr_t rhs, uintptr_t jacobian, int dim, p, list inputs, double t0,
          double tf, y0, double rtol, atol, double max_step, double first_step, t_eval,
          bint dense, uintptr_t events=0, event_max=None, event_direction=None,
          bint stop_on_nonfinite=False, long max_steps=0, double max_wall_time=0.0,
          Poll poll=None, uintptr_t directional=0, sensitivity_index=None,
          double save_budget=0.0):
    """Run one solve in C without the GIL.

    Parameters
    ----------
    method : str
        RK23, RK45, DOP853, Radau or BDF.
    rhs, jacobian, events : int
        Addresses of the C functions (jacobian: 0 for the explicit methods; events: 0 for none).
    dim : int
        State dimension.
    p : array of float
        Parameter vector passed to the model functions.
    inputs : list of tuple
        One (kind, value, ts, values, coef) per model input (see lagrgen.signals).
    t0, tf, y0, rtol, atol, max_step, first_step :
        As solve_ivp (atol an array of dim; first_step 0 for automatic).
    t_eval : array or None
        Output times in the direction of integration.
    dense : bool
        Return each step's interpolant coefficients.
    event_max, event_direction : arrays
        Per event: the count that terminates (inf: never), and the direction.
    stop_on_nonfinite : bool
        End the solve at the first NaN/inf derivative (model_failure 3) instead of letting the
        method react to it as SciPy's do (rejected steps, Newton failures).
    max_steps, max_wall_time : int, float
        Stop after this many accepted steps / seconds (0: no limit); `stopped` says which.
    save_budget : float
        Without max_steps and t_eval: the doubles the solve may save (0: lg_ode.h's
        LG_SAVE_BUDGET, < 0: no bound); beyond it the solve stops (stopped 4).
    poll : Poll or None
        Called about every poll.interval seconds; its exception (KeyboardInterrupt on Ctrl-C) is
        raised here after the solve has stopped and freed its memory.
    directional, sensitivity_index :
        With a sensitivity_index (k ints: a parameter index, or -1 for an initial state), the
        solve is of the augmented system [y, S_1..S_k] of native/lg_sensitivity.h: `dim` is
        then (k + 1)·2n, and `jacobian` and `directional` (the address of the model's
        directional_derivatives) are required.

    Returns
    -------
    dict
        t, y (len(t), dim), status, stopped (0, or 1/2/3/4: max_steps, max_wall_time, poll,
        the save budget),
        t_reached (when stopped), message, nfev, njev, nlu, n_steps, seg (steps, 5),
        coef (1-D), ev (k, 2) of (index, t), ev_y (k, dim), model_failure (0, 1 mass matrix
        not positive definite, 2 events function, 3 non-finite derivative), fail_t, fail_y (the
        state of that call).
    """
    if method not in METHOD_CODES:
        raise ValueError(f"method {method!r} has no native implementation")
    if rhs == 0 or (BY_NAME[method].stiff and jacobian == 0):
        raise ValueError("a null model function address")
    cdef cnp.ndarray pa = f64(p if len(p) else [0.0])
    cdef cnp.ndarray y0a = f64(y0), atola = f64(atol)
    if y0a.shape[0] != dim or atola.shape[0] != dim:
        raise ValueError(f"y0 and atol must have {dim} values")
    cdef cnp.ndarray te = None if t_eval is None else f64(t_eval)
    cdef int n_events = 0 if event_max is None else len(event_max)
    if n_events and events == 0:
        raise ValueError("event counts given without an events function")
    cdef cnp.ndarray emax = f64(event_max if n_events else [0.0])
    cdef cnp.ndarray edir = f64(event_direction if n_events else [0.0])
    cdef lg_problem_t pb
    cdef lg_options_t op
    cdef lg_result_t res
    memset(&pb, 0, sizeof(pb))
    memset(&op, 0, sizeof(op))
    cdef lg_sens_ctx sens
    cdef cnp.ndarray sens_P, sens_J
    cdef int k, n_params = len(p)
    if sensitivity_index is not None:
        index = np.asarray(sensitivity_index, dtype=np.intp)
        k = index.shape[0]
        if jacobian == 0 or directional == 0 or dim % (k + 1):
            raise ValueError("sensitivities need the jacobian and directional_derivatives "
                             "addresses and dim = (k + 1)·2n")
        sens_P = np.zeros((k, max(n_params, 1)))
        for c in range(k):
            if index[c] >= 0:
                sens_P[c, index[c]] = 1.0
        sens.directional = <lg_directions_fn>directional
        sens.jacobian = <lg_jac_fn>jacobian
        sens.p = <const double *>cnp.PyArray_DATA(pa)
        sens.k = k
        sens.dim = dim // (k + 1)
        sens.P = <const double *>cnp.PyArray_DATA(sens_P)
        sens_J = np.empty(sens.dim * sens.dim)
        sens.J = <double *>cnp.PyArray_DATA(sens_J)
        pb.sys_rhs = lg_sens_rhs
        pb.sys_jac = lg_sens_jac
        pb.sys_ctx = <void *>&sens
    cdef lg_signal_t *sig = <lg_signal_t *>calloc(len(inputs) + 1, sizeof(lg_signal_t))
    if sig == NULL:
        raise MemoryError()
    keep = []
    cdef int rc
    try:
        fill_signals(inputs, sig, keep)
        pb.dim = dim
        pb.rhs = <lg_rhs_fn>rhs
        pb.jacobian = <lg_jac_fn>jacobian
        pb.p = <const double *>cnp.PyArray_DATA(pa)
        pb.n_inputs = len(inputs)
        pb.inputs = sig
        pb.events = <lg_events_fn>events
        pb.n_events = n_events
        pb.event_max = <const double *>cnp.PyArray_DATA(emax)
        pb.event_direction = <const double *>cnp.PyArray_DATA(edir)
        set_options(&op, method, t0, tf, rtol, <const double *>cnp.PyArray_DATA(atola),
                    max_step, first_step,
                    NULL if te is None else <const double *>cnp.PyArray_DATA(te),
                    0 if te is None else te.shape[0], dense, stop_on_nonfinite, max_steps,
                    max_wall_time)
        op.y0 = <const double *>cnp.PyArray_DATA(y0a)
        op.save_budget = save_budget
        set_poll(&op, poll)
        with nogil:
            rc = lg_solve(&pb, &op, &res)
        try:
            if rc < 0:
                raise MemoryError(res.message.decode())
            if poll is not None and poll.error is not None:
                raise poll.error
            return dict(t=buf_array(&res.t, 0), y=buf_array(&res.y, dim), status=res.status,
                        stopped=res.stopped, t_reached=res.t_reached,
                        message=res.message.decode(), nfev=res.nfev, njev=res.njev,
                        nlu=res.nlu, n_steps=res.n_steps, seg=buf_array(&res.seg, 5),
                        coef=buf_array(&res.coef, 0), ev=buf_array(&res.ev, 2),
                        ev_y=buf_array(&res.ev_y, dim), model_failure=res.model_failure,
                        fail_t=res.fail_t, fail_y=buf_array(&res.fail_y, 0))
        finally:
            lg_result_free(&res)
    finally:
        free(sig)


ctypedef int (*lg_state_fn)(double, const double *, const double *, const double *,
                            double *) noexcept nogil


cdef void save_states(const lg_result_t *res, int dim, Py_ssize_t k, double *y_run) noexcept nogil:
    """y_run (dim, k), row-major, from the solve's saved states; NaN after the last saved time."""
    cdef Py_ssize_t saved = <Py_ssize_t>(res.t.len), j, d
    for d in range(dim):
        for j in range(k):
            y_run[d * k + j] = res.y.data[j * dim + d] if j < saved else NAN


cdef void evaluate_along(lg_state_fn fn, int width, const lg_result_t *res, int dim, Py_ssize_t k,
                         const double *p, const lg_signal_t *sig, int n_inputs, double *u,
                         double *tmp, double *out) noexcept nogil:
    """out (width, k), row-major: fn(t_j, y_j, p, u(t_j)) at every saved time (NaN after the last
    one, and where fn reports a failure)."""
    cdef Py_ssize_t saved = <Py_ssize_t>(res.t.len), j, c
    cdef int i, rc
    for j in range(k):
        rc = 1
        if j < saved:
            for i in range(n_inputs):
                u[i] = lg_signal_eval(&sig[i], res.t.data[j])
            rc = fn(res.t.data[j], &res.y.data[j * dim], p, u, tmp)
        for c in range(width):
            out[c * k + j] = tmp[c] if rc == 0 else NAN


cdef int stop_flag_set(void *ctx, double t) noexcept nogil:
    """The poll of a batch: nonzero (stop) once the shared flag is set; needs no GIL."""
    return (<volatile int *>ctx)[0]


def solve_batch(str method, uintptr_t rhs, uintptr_t jacobian, int dim, const double[:, ::1] Y0,
                const double[:, ::1] P, list inputs, const double[:, ::1] U, double t0, double tf,
                double rtol, const double[::1] atol, double max_step, double first_step,
                const double[::1] t_eval, uintptr_t events, event_max, event_direction,
                bint stop_on_nonfinite, list extras, double[:, :, ::1] y_out,
                int[::1] status, long[::1] nfev, int[::1] stop, long max_steps=0,
                double max_wall_time=0.0, uintptr_t pivot_record=0, double[::1] pivots=None):
    """Solve runs i = 0..len(Y0)-1 one after another in C, without the GIL and without Python
    between runs, each from Y0[i] with parameters P[i], saving its states at t_eval.

    Parameters
    ----------
    method, rhs, jacobian, dim, rtol, atol, max_step, first_step, events, event_max,
    event_direction, stop_on_nonfinite :
        As for `solve` (rtol a float; atol an array of dim).
    Y0 : (runs, dim) initial states;  P : (runs, n_params) parameters (n_params >= 1 columns)
    inputs : one (kind, value, ts, values, coef) spec per input, shared by the runs, except that
        the value of each "constant" input is taken from U
    U : (runs, max(n_inputs, 1)) per-run values of the constant inputs
    t_eval : (k,) output times (required)
    extras : list of (address, width, out): a model function f(t, y, p, u, out) with `width`
        outputs evaluated at every saved state into out (runs, width, k) (NaN past the last one)
    y_out : (runs, dim, k) states (NaN after the last saved time)
    status, nfev : (runs,) filled per run (status 0 reached tf, 1 terminal event, -1 failure,
        -2 not run because `stop[0]` was set)
    stop : (1,) a flag read before every run and about every 0.05 s within one: nonzero stops the
        batch (set it from another thread; the run under way ends with status -2)
    max_steps, max_wall_time : per-run guards (0: none); a guarded run ends with status -1
    pivot_record, pivots : the model's `pivot_record` function (0: none) and (runs,) the least
        relative pivot of M each run's factorizations reached (read and reset around each run,
        on the thread that runs the batch)

    Returns
    -------
    int : the number of runs solved
    """
    if method not in METHOD_CODES:
        raise ValueError(f"method {method!r} has no native implementation")
    if rhs == 0 or (BY_NAME[method].stiff and jacobian == 0):
        raise ValueError("a null model function address")
    cdef Py_ssize_t runs = Y0.shape[0], k = t_eval.shape[0], i
    cdef int n_inputs = len(inputs), n_extra = len(extras), e, done = 0
    if Y0.shape[1] != dim or atol.shape[0] != dim or P.shape[0] != runs or U.shape[0] != runs \
            or U.shape[1] < n_inputs or y_out.shape[0] != runs or y_out.shape[1] != dim \
            or y_out.shape[2] != k or status.shape[0] != runs or nfev.shape[0] != runs \
            or k == 0 or P.shape[1] == 0 or stop.shape[0] != 1:
        raise ValueError("solve_batch: inconsistent array shapes")
    cdef int n_events = 0 if event_max is None else len(event_max)
    if n_events and events == 0:
        raise ValueError("event counts given without an events function")
    cdef cnp.ndarray emax = f64(event_max if n_events else [0.0])
    cdef cnp.ndarray edir = f64(event_direction if n_events else [0.0])
    cdef double[:, :, ::1] view
    keep = []
    cdef lg_signal_t *shared = <lg_signal_t *>calloc(n_inputs + 1, sizeof(lg_signal_t))
    cdef lg_signal_t *sig = <lg_signal_t *>calloc(n_inputs + 1, sizeof(lg_signal_t))
    cdef lg_state_fn *fns = <lg_state_fn *>calloc(n_extra + 1, sizeof(lg_state_fn))
    cdef int *widths = <int *>calloc(n_extra + 1, sizeof(int))
    cdef double **outs = <double **>calloc(n_extra + 1, sizeof(double *))
    cdef double *u = <double *>calloc(n_inputs + 1, sizeof(double))
    cdef int max_width = 1
    for address, width, out in extras:
        max_width = max(max_width, int(width))
    cdef double *tmp = <double *>calloc(max_width, sizeof(double))
    cdef lg_problem_t pb
    cdef lg_options_t op
    cdef lg_result_t res
    cdef int rc = 0, ok = 1
    cdef int *stop_flag = &stop[0]
    cdef lg_state_fn record = <lg_state_fn>pivot_record
    cdef double *least = NULL
    cdef double scratch = 1.0
    if record != NULL:
        if pivots is None or pivots.shape[0] != runs:
            raise ValueError("solve_batch: pivots must have one entry per run")
        least = &pivots[0]
    try:
        if not (shared and sig and fns and widths and outs and u and tmp):
            raise MemoryError()
        fill_signals(inputs, shared, keep)
        for e, (address, width, out) in enumerate(extras):
            view = out
            if address == 0 or view.shape[0] != runs or view.shape[1] != width or \
                    view.shape[2] != k:
                raise ValueError("solve_batch: an extra function's output has the wrong shape")
            fns[e] = <lg_state_fn><uintptr_t>address
            widths[e] = width
            outs[e] = &view[0, 0, 0]
        memset(&pb, 0, sizeof(pb))
        memset(&op, 0, sizeof(op))
        pb.dim = dim
        pb.rhs = <lg_rhs_fn>rhs
        pb.jacobian = <lg_jac_fn>jacobian
        pb.n_inputs = n_inputs
        pb.inputs = sig
        pb.events = <lg_events_fn>events
        pb.n_events = n_events
        pb.event_max = <const double *>cnp.PyArray_DATA(emax)
        pb.event_direction = <const double *>cnp.PyArray_DATA(edir)
        set_options(&op, method, t0, tf, rtol, &atol[0], max_step, first_step, &t_eval[0],
                    <int>k, False, stop_on_nonfinite, max_steps, max_wall_time)
        op.poll = stop_flag_set
        op.poll_ctx = <void *>stop_flag
        op.poll_interval = 0.05
        with nogil:
            for i in range(runs):
                if (<volatile int *>stop_flag)[0]:
                    status[i] = -2
                    nfev[i] = 0
                    continue
                memcpy(sig, shared, (n_inputs + 1) * sizeof(lg_signal_t))
                for e in range(n_inputs):
                    if sig[e].kind == 0:
                        sig[e].value = U[i, e]
                pb.p = &P[i, 0]
                op.y0 = &Y0[i, 0]
                memset(&res, 0, sizeof(res))
                if record != NULL:
                    record(t0, NULL, NULL, NULL, &scratch)
                rc = lg_solve(&pb, &op, &res)
                if record != NULL:
                    record(t0, NULL, NULL, NULL, &least[i])
                if rc < 0:
                    lg_result_free(&res)
                    ok = 0
                    break
                status[i] = -2 if res.stopped == LG_STOP_POLL else \
                    (-1 if res.stopped != LG_STOP_NONE else res.status)
                nfev[i] = res.nfev
                save_states(&res, dim, k, &y_out[i, 0, 0])
                for e in range(n_extra):
                    evaluate_along(fns[e], widths[e], &res, dim, k, &P[i, 0], sig, n_inputs, u,
                                   tmp, outs[e] + i * widths[e] * k)
                lg_result_free(&res)
                done += 1
        if not ok:
            raise MemoryError("the native engine ran out of memory (or was given invalid options)")
        return done
    finally:
        free(shared)
        free(sig)
        free(fns)
        free(widths)
        free(outs)
        free(u)
        free(tmp)


cdef extern from "lg_hybrid.h":
    ctypedef struct lg_hybrid_t:
        int n, m, ni, nf
        lg_rhs_fn terms
        const double *p
        int n_inputs
        const lg_signal_t *inputs
        const int *normal_kind
        const int *normal_index
        double rest_velocity
        double gap_tol
        long max_transitions
        int *contact
        int *slip
        int n_stops
        const double *stops
        int npf
        const int *planar_kind
        const int *planar_index
        int *pmode
        double *anchor
        lg_rhs_fn rhs
    ctypedef struct lg_hybrid_result_t:
        int status
        int stopped
        double t_reached
        char message[256]
        long nfev, n_steps, n_segments
        int failure, failed_element
        double failed_value, failed_other
        lg_buf_t t, y, forces, transitions
        double least_pivot
    int lg_hybrid_solve(lg_hybrid_t *, const lg_options_t *, lg_hybrid_result_t *) nogil
    void lg_hybrid_result_free(lg_hybrid_result_t *) nogil


def solve_hybrid(str method, uintptr_t terms, int n, int m, int ni, int nf, normal_kind,
                 normal_index, p, list inputs, double t0, double tf, y0, double rtol, atol,
                 double max_step, double first_step, t_eval, double rest_velocity,
                 double gap_tol, long max_transitions, Poll poll=None, long max_steps=0,
                 double max_wall_time=0.0, double save_budget=0.0, stops=(), planar_kind=(),
                 planar_index=(), uintptr_t rhs=0):
    """Run a hybrid solve (lagrgen/native/lg_hybrid.c) in C without the GIL.

    Parameters
    ----------
    terms : int
        Address of the model's C hybrid_terms function.
    n, m, ni, nf : int
        Coordinates, model constraints, impacts, frictions.
    normal_kind, normal_index : arrays of int (nf)
        Per friction: 0 expression, 1 constraint k, 2 impact k (the index).
    rest_velocity : float
        < 0: the relative default. Other arguments as `solve` (poll: Ctrl-C, progress, stop).
    stops : (k, 4) numbers: the enforced limits (coordinate, sign, bound, restitution), impacts
        after the model's ni
    planar_kind, planar_index : arrays of int (npf): the planar frictions' normal forces
    rhs : int
        Address of the model's C rhs (0: none): a free mode's ẏ (lg_hybrid.h).

    Returns
    -------
    dict
        t, y (len(t), 2n), forces (len(t), m + ni + k + nf + 2·npf) (lg_hybrid_result_t.forces),
        transitions (k, 3) of (t, element, kind code), contact (ni + k),
        slip (nf), pmode (npf), anchor (npf, 2), status, message, nfev, n_segments, failure (an LG_HY_* code of
        lg_hybrid.h) with failed_element, failed_value, failed_other.
    """
    if method not in METHOD_CODES:
        raise ValueError(f"method {method!r} has no native implementation")
    if terms == 0:
        raise ValueError("a null model function address")
    cdef int dim = 2 * n
    cdef cnp.ndarray pa = f64(p if len(p) else [0.0])
    cdef cnp.ndarray y0a = f64(y0), atola = f64(atol)
    if y0a.shape[0] != dim or atola.shape[0] != dim:
        raise ValueError(f"y0 and atol must have {dim} values")
    cdef cnp.ndarray te = None if t_eval is None else f64(t_eval)
    cdef cnp.ndarray nk = np.ascontiguousarray(list(normal_kind) + [0], dtype=np.intc)
    cdef cnp.ndarray nx = np.ascontiguousarray(list(normal_index) + [0], dtype=np.intc)
    cdef cnp.ndarray st = f64(np.asarray(stops, dtype=float).ravel().tolist() + [0.0])
    cdef int n_stops = (st.shape[0] - 1) // 4
    cdef int npf = len(planar_kind)
    cdef cnp.ndarray pk = np.ascontiguousarray(list(planar_kind) + [0], dtype=np.intc)
    cdef cnp.ndarray px = np.ascontiguousarray(list(planar_index) + [0], dtype=np.intc)
    cdef cnp.ndarray pmode = np.full(npf + 1, -1, dtype=np.intc)
    cdef cnp.ndarray anchor = np.zeros(2 * npf + 2)
    anchor[::2] = 1.0
    cdef cnp.ndarray contact = np.zeros(ni + n_stops + 1, dtype=np.intc)
    cdef cnp.ndarray slip = np.ones(nf + 1, dtype=np.intc)
    cdef lg_hybrid_t hy
    cdef lg_options_t op
    cdef lg_hybrid_result_t res
    memset(&hy, 0, sizeof(hy))
    memset(&op, 0, sizeof(op))
    memset(&res, 0, sizeof(res))
    cdef lg_signal_t *sig = <lg_signal_t *>calloc(len(inputs) + 1, sizeof(lg_signal_t))
    if sig == NULL:
        raise MemoryError()
    keep = []
    cdef int rc
    try:
        fill_signals(inputs, sig, keep)
        hy.n, hy.m, hy.ni, hy.nf = n, m, ni, nf
        hy.terms = <lg_rhs_fn>terms
        hy.p = <const double *>cnp.PyArray_DATA(pa)
        hy.n_inputs = len(inputs)
        hy.inputs = sig
        hy.normal_kind = <const int *>cnp.PyArray_DATA(nk)
        hy.normal_index = <const int *>cnp.PyArray_DATA(nx)
        hy.rest_velocity = rest_velocity
        hy.gap_tol = gap_tol
        hy.max_transitions = max_transitions
        hy.contact = <int *>cnp.PyArray_DATA(contact)
        hy.slip = <int *>cnp.PyArray_DATA(slip)
        hy.n_stops = n_stops
        hy.stops = <const double *>cnp.PyArray_DATA(st)
        hy.npf = npf
        hy.planar_kind = <const int *>cnp.PyArray_DATA(pk)
        hy.planar_index = <const int *>cnp.PyArray_DATA(px)
        hy.pmode = <int *>cnp.PyArray_DATA(pmode)
        hy.anchor = <double *>cnp.PyArray_DATA(anchor)
        hy.rhs = <lg_rhs_fn>rhs
        set_options(&op, method, t0, tf, rtol, <const double *>cnp.PyArray_DATA(atola),
                    max_step, first_step,
                    NULL if te is None else <const double *>cnp.PyArray_DATA(te),
                    0 if te is None else te.shape[0], False, True, max_steps, max_wall_time)
        op.y0 = <const double *>cnp.PyArray_DATA(y0a)
        op.save_budget = save_budget
        set_poll(&op, poll)
        with nogil:
            rc = lg_hybrid_solve(&hy, &op, &res)
        try:
            if rc < 0:
                raise MemoryError(res.message.decode())
            if poll is not None and poll.error is not None:
                raise poll.error
            return dict(t=buf_array(&res.t, 0), y=buf_array(&res.y, dim), status=res.status,
                        message=res.message.decode(), nfev=res.nfev, n_steps=res.n_steps,
                        stopped=res.stopped, t_reached=res.t_reached,
                        n_segments=res.n_segments, transitions=buf_array(&res.transitions, 3),
                        forces=buf_array(&res.forces, m + ni + n_stops + nf + 2 * npf),
                        contact=contact[:ni + n_stops].copy(), slip=slip[:nf].copy(),
                        pmode=pmode[:npf].copy(), anchor=anchor[:2 * npf].reshape(npf, 2),
                        failure=res.failure, failed_element=res.failed_element,
                        failed_value=res.failed_value, failed_other=res.failed_other,
                        least_pivot=res.least_pivot)
        finally:
            lg_hybrid_result_free(&res)
    finally:
        free(sig)
