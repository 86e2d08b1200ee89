"""The native integration engine: a whole solve in C (`lagrgen.native._ode`) without the GIL.

`solve_native` takes the same steps as `scipy.integrate.solve_ivp` (the C core is a port of
SciPy 1.17's _ivp) and returns SciPy's `OdeResult`, with `sol.sol` rebuilt from SciPy's own
DenseOutput classes. LSODA has no native implementation: `lagrgen.simulate` runs it on the SciPy
engine.
"""
import warnings

import numpy as np
from scipy.integrate import OdeSolution
from scipy.integrate._ivp.base import ConstantDenseOutput
from scipy.integrate._ivp.bdf import BdfDenseOutput
from scipy.integrate._ivp.ivp import OdeResult
from scipy.integrate._ivp.radau import RadauDenseOutput
from scipy.integrate._ivp.rk import Dop853DenseOutput, RkDenseOutput

from ..errors import MassMatrixError, NonFiniteError
from ..methods import BY_NAME, NATIVE_METHODS

#: The most events a native solve locates (LG_MAX_EVENTS of lg_ode.h).
MAX_EVENTS = 1024
from ..options import (absolute_tolerance, count, first_step as checked_first_step,
                       max_step as checked_max_step, output_times, relative_tolerance, seconds)
from ..results import stopped_by_guard
from ..runtime.arguments import input_specs, python_callable_inputs

NATIVE_OPTIONS = ("max_step", "first_step")
EPS = np.finfo(float).eps


def native_reason(mod, method, inputs, events, options, rtol=0.0):
    """Why the native engine cannot run this solve (a str), or None when it can.

    Parameters
    ----------
    mod : built model
    method : str or class
    inputs : None, dict or array
    events : None or anything solve_ivp accepts (Python events)
    options : dict of extra solve_ivp options
    rtol : float or array

    Returns
    -------
    str or None
    """
    if mod.backend != "c":
        return "the model is not compiled (backend 'c')"
    if any(type(getattr(mod, f, None)).__module__ != "lagrgen.runtime._compiled"
           for f in ("rhs", "jacobian")):
        return "the model's rhs or jacobian is not its compiled C function (a wrapper?)"
    if not isinstance(method, str) or method not in NATIVE_METHODS:
        return f"method {getattr(method, '__name__', method)!r} has no native implementation"
    if events is not None:
        return "Python-callable events need the SciPy engine"
    callables = python_callable_inputs(inputs)
    if callables:
        return (f"input {callables[0]!r} is a Python callable; use a constant or a "
                "lagrgen.Signal for the native engine")
    if np.ndim(rtol) != 0:
        return "an array rtol is only supported by the SciPy engine"
    other = [k for k in options if k not in NATIVE_OPTIONS]
    if other:
        return f"option {other[0]!r} is only supported by the SciPy engine"
    events = len(mod.event_definitions) + len(mod.nonsmooth_definitions) + \
        len(mod.info.limit_stops)
    if events > MAX_EVENTS:
        return f"it has {events} events, impacts, frictions and stops (the native engine " \
               f"locates at most {MAX_EVENTS})"
    return None


def simulate_native(mod, t_span, y0, method, p, inputs, u_at, rtol, atol, t_eval=None,
                    dense_output=False, max_steps=None, max_wall_time=None, progress=None,
                    **options):
    """One `simulate` run on the native engine: the model's compiled events, Ctrl-C and the
    guards handled in C, failures raised as the SciPy engine raises them. Returns the OdeResult
    with `guard` (None, or why a guard stopped it)."""
    from ._ode import Poll
    events = native_events(mod) if mod.event_definitions else None
    sol = solve_native(mod, t_span, y0, method, p, input_specs(mod, inputs), rtol, atol, t_eval,
                       dense_output, events, stop_on_nonfinite=True, max_steps=max_steps,
                       max_wall_time=max_wall_time, poll=Poll(progress), **options)
    raise_native_failure(mod, sol, p, u_at)
    report_guard(sol, t_span, max_steps, max_wall_time)
    return sol


def report_guard(sol, t_span, max_steps, max_wall_time):
    """Set `sol.guard` (None, or why max_steps / max_wall_time stopped the native solve) and say
    so in its message."""
    sol.guard = None
    if sol.stopped in ("max_steps", "max_wall_time", "saved"):
        stopped_by_guard(sol, guard_reason(sol.stopped, max_steps, max_wall_time),
                         sol.t_reached, float(t_span[1]), sol.n_steps)


def guard_reason(stopped, max_steps, max_wall_time):
    """Why a native solve stopped: `stopped` is a name of STOPPED."""
    if stopped == "saved":
        return (f"the native engine saves at most {SAVE_BUDGET_GIB:g} GiB of steps without "
                "t_eval or max_steps (give t_eval for the times you need, or max_steps to allow "
                "more)")
    limit = max_steps if stopped == "max_steps" else f"{max_wall_time:g} s"
    what = "step" if stopped == "max_steps" else "wall-time"
    return f"the {what} limit {stopped}={limit} was reached"


def native_events(mod):
    """(address of the model's C events function, terminal counts, directions)."""
    definitions = mod.event_definitions
    return (mod.compiled_model.function_address("events"),
            np.array([terminal for _, terminal, _ in definitions], dtype=np.intc),
            np.array([direction for _, _, direction in definitions], dtype=float))


def raise_native_failure(mod, sol, p, u_at):
    """Raise, for a native solve, the error the SciPy engine raises at the same point: the
    model's own error at the state where it failed, or NonFiniteError. The state is the model's
    own (2n) part of an augmented one (sensitivities)."""
    dim = 2 * mod.n_coordinates
    if sol.mass_matrix_failure is not None:
        t, y = sol.mass_matrix_failure
        mod.rhs(t, y[:dim], p, u_at(t))
        raise MassMatrixError.at(mod.name, t, y[:mod.n_coordinates])
    if sol.nonfinite_failure is not None:
        t, y = sol.nonfinite_failure
        raise NonFiniteError.at(mod.name, t, y[:dim])


def _tolerances(rtol, atol, dim):
    """common.validate_tol: rtol clipped to 100 EPS (with SciPy's warning), atol an array."""
    if np.any(np.asarray(rtol) < 100 * EPS):
        warnings.warn("At least one element of `rtol` is too small. "
                      f"Setting `rtol = np.maximum(rtol, {100 * EPS})`.", stacklevel=3)
    if np.ndim(rtol) != 0:
        raise ValueError("the native engine takes a scalar rtol")
    rtol = relative_tolerance(rtol)  # _ode clips it to 100 EPS; Radau/BDF's Newton uses it
    atol = np.asarray(absolute_tolerance(atol), dtype=float)
    if atol.ndim > 0 and atol.shape != (dim,):
        raise ValueError(f"atol must be one number or {dim} (one per state), got {atol.size}")
    return rtol, np.ascontiguousarray(np.broadcast_to(atol, (dim,)), dtype=float)


def _t_eval(t_eval, t0, tf):
    """t_eval checked as every engine checks it (`lagrgen.options.output_times`)."""
    return output_times(t_eval, t0, tf)


def _event_arrays(events):
    """(address, max counts, directions) from events = (address, terminal, direction)."""
    if events is None:
        return 0, None, None
    address, terminal, direction = events
    terminal = list(terminal)
    emax = []
    for term in terminal:
        if term is None or term is False or term == 0:
            emax.append(np.inf)
        elif int(term) == term and term > 0:
            emax.append(float(term))
        else:
            raise ValueError("The `terminal` attribute of each event must be a boolean or "
                             "positive integer.")
    direction = np.asarray(direction, dtype=float).reshape(-1)
    if len(emax) > MAX_EVENTS:
        raise ValueError(f"the native engine locates at most {MAX_EVENTS} events")
    if direction.size != len(emax) or not emax:
        raise ValueError("events need one terminal flag and one direction per event")
    if not address:
        raise ValueError("events need the address of a C events function")
    return int(address), np.array(emax), direction


def _interpolant(dense, row, coef, dim):
    """SciPy's DenseOutput of one native step: `dense` is the method's kind (methods.TABLE), `row`
    the step's (t_old, t, offset, order, h) and coef[offset:] its coefficient block."""
    t_old, t, off, order, h = row
    off, order = int(off), int(order)
    if order < 0:
        return ConstantDenseOutput(t_old, t, coef[off:off + dim].copy())
    if dense == "bdf":
        D = coef[off:off + (order + 1) * dim].reshape(order + 1, dim).copy()
        return BdfDenseOutput(t_old, t, h, order, D)
    y_old = coef[off:off + dim].copy()
    block = coef[off + dim:off + dim + order * dim]
    if dense == "dop853":
        return Dop853DenseOutput(t_old, t, y_old, block.reshape(7, dim).copy())
    if dense == "radau":
        return RadauDenseOutput(t_old, t, y_old, block.reshape(dim, 3).copy())
    return RkDenseOutput(t_old, t, y_old, block.reshape(dim, order).copy())


def solve_native(mod, t_span, y0, method="RK45", p=None, u_spec=None, rtol=1e-3, atol=1e-6,
                 t_eval=None, dense_output=False, events=None, max_step=np.inf,
                 first_step=None, stop_on_nonfinite=False, max_steps=None, max_wall_time=None,
                 poll=None, sensitivity_index=None, save_budget=0.0):
    """Integrate a compiled model entirely in C, step for step as `solve_ivp`.

    Parameters
    ----------
    mod : compiled model (backend "c")
    t_span : (t0, tf)
    y0 : array_like, shape (2n,)
    method : {"RK23", "RK45", "DOP853", "Radau", "BDF"}
    p : array_like, shape (n_params,), optional
        Parameter vector (None: the model's defaults).
    u_spec : list, optional
        One description per input (`input_specs`); None: all inputs 0.
    rtol, atol, t_eval, dense_output, max_step, first_step :
        As `solve_ivp`.
    events : tuple, optional
        (address of a C function ``int events(t, y, p, u, values)``, terminal per event,
        direction per event), located as solve_ivp locates events.
    stop_on_nonfinite : bool
        End the solve (status -1, `nonfinite_failure` = (t, y)) at the first derivative with a
        NaN or infinity, as `simulate` on the SciPy engine raises NonFiniteError there; False
        lets the method react to it as SciPy's solvers do.

    Returns
    -------
    OdeResult
        t, y, sol, t_events, y_events, nfev, njev, nlu, status, message, success,
        engine = "native", n_steps, and mass_matrix_failure: None, or (t, y) of the model
        call that found M not positive definite (the solve then has status -1), and
        nonfinite_failure: None or (t, y) (with stop_on_nonfinite).
    max_steps, max_wall_time : int, float, optional
        Stop after this many accepted steps or seconds of wall time (None: no limit): the result
        then holds the solution up to there, with status -1 and `stopped` naming the limit
        ("max_steps" or "max_wall_time"; None otherwise) and `t_reached` the time reached.
    sensitivity_index : sequence of int, optional
        Integrate the forward sensitivities with the state (native/lg_sensitivity.h): one entry
        per column, a parameter index or −1 for an initial state; y0 (and atol, the results)
        are then of the augmented state [y, S_1, …, S_k].
    save_budget : float
        Without max_steps and t_eval, the doubles (t, y, dense coefficients) the solve may
        save before it stops (`stopped` "saved"): 0 the default 2^27 (1 GiB), < 0 no bound.
    poll : lagrgen.native._ode.Poll, optional
        Run about every 0.05 s of wall time (signals, progress, a stop flag); its exception
        (KeyboardInterrupt on Ctrl-C) ends the solve and is raised.
    """
    from . import _ode
    if method not in NATIVE_METHODS:
        raise ValueError(f"method {method!r} has no native implementation: use one of "
                         f"{', '.join(NATIVE_METHODS)} (LSODA runs on the SciPy engine)")
    cm = mod.compiled_model
    dim = 2 * mod.n_coordinates * (1 + (0 if sensitivity_index is None else len(sensitivity_index)))
    t0, tf = map(float, t_span)
    if not (np.isfinite(t0) and np.isfinite(tf)):
        raise ValueError("t_span must be finite")
    y0 = np.ascontiguousarray(y0, dtype=float).reshape(-1)
    if y0.shape != (dim,):
        raise ValueError(f"y0 must have {dim} values, got {y0.size}")
    if not np.all(np.isfinite(y0)):
        raise ValueError("y0 must be finite")
    p = np.array(mod.defaults if p is None else p, dtype=float).reshape(-1)
    if p.size != len(mod.parameters):
        raise ValueError(f"p must have {len(mod.parameters)} values, got {p.size}")
    if np.any(np.isnan(p)):
        raise ValueError("the parameter vector contains NaN (a parameter without a default?)")
    if u_spec is None:
        u_spec = input_specs(mod, None)
    if len(u_spec) != len(mod.inputs):
        raise ValueError(f"{len(mod.inputs)} input descriptions needed, got {len(u_spec)}")
    rtol, atol = _tolerances(rtol, atol, dim)
    max_step = checked_max_step(max_step)
    first = checked_first_step(first_step, (t0, tf)) or 0.0
    te = _t_eval(t_eval, t0, tf)
    ev_addr, ev_max, ev_dir = _event_arrays(events)
    sensitive = sensitivity_index is not None
    jac = cm.function_address("jacobian") if BY_NAME[method].stiff or sensitive else 0
    directional = cm.function_address("directional_derivatives") if sensitive else 0
    out = _ode.solve(method, cm.function_address("rhs"), jac, dim, p, list(u_spec), t0, tf,
                     y0, rtol, atol, max_step, first, te, bool(dense_output), ev_addr,
                     ev_max, ev_dir, bool(stop_on_nonfinite), _limit(max_steps, "max_steps"),
                     _limit(max_wall_time, "max_wall_time"), poll, directional, sensitivity_index,
                     float(save_budget))
    ts, ys = out["t"], out["y"].T.copy()
    sol = None
    if dense_output:
        interps = [_interpolant(BY_NAME[method].dense, row, out["coef"], dim)
                   for row in out["seg"]]
        if te is None:
            breaks = ts
        else:
            breaks = np.concatenate(([t0], out["seg"][:, 1]))
        if interps:
            sol = OdeSolution(breaks, interps, alt_segment=method == "BDF")
    t_events = y_events = None
    if events is not None:
        n_ev = len(ev_max)
        idx = out["ev"][:, 0].astype(int)
        t_events = [out["ev"][idx == i, 1].copy() for i in range(n_ev)]
        y_events = [out["ev_y"][idx == i].copy() for i in range(n_ev)]
    status = out["status"]
    failure = (out["fail_t"], out["fail_y"].copy())
    mass_failure = failure if out["model_failure"] == 1 else None
    nonfinite_failure = failure if out["model_failure"] == 3 else None
    return OdeResult(t=ts, y=ys, sol=sol, t_events=t_events, y_events=y_events,
                     nfev=out["nfev"], njev=out["njev"], nlu=out["nlu"], status=status,
                     message=out["message"], success=status >= 0, engine="native",
                     n_steps=out["n_steps"], mass_matrix_failure=mass_failure,
                     nonfinite_failure=nonfinite_failure, stopped=STOPPED[out["stopped"]],
                     t_reached=out["t_reached"] if out["stopped"] else None)


#: lg_result_t.stopped -> the name of the limit that ended the solve.
STOPPED = {0: None, 1: "max_steps", 2: "max_wall_time", 3: "poll", 4: "saved"}
#: lg_ode.h's LG_SAVE_BUDGET (2^27 doubles) in GiB.
SAVE_BUDGET_GIB = 2 ** 27 * 8 / 2 ** 30


def _limit(value, name):
    """A guard for the C core: None -> 0 (no limit); otherwise checked by `lagrgen.options`."""
    if name == "max_steps":
        return count(value, name) or 0
    return seconds(value, name) or 0.0
