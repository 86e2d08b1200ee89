"""`simulate`: running a built model (either backend) through SciPy's `solve_ivp`.

User arguments (params, inputs, y0) are converted once here, by `lagrgen.runtime.arguments`; the
functions handed to the solver take raw float64 arrays.
"""
import math
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.integrate._ivp.ivp import OdeResult

from .errors import MassMatrixError, NonFiniteError
from .runtime.arguments import (as_vector, key_name, named_vector, parameter_vector,
                                require_finite, state_vector, unknown_name)
from .functions import POWER_TERMS
from .methods import METHODS, STIFF_METHODS
from .native_engine import input_specs, native_reason, solve_native
from .solvers import SOLVERS


def parameters_from(mod, params):
    """The parameter vector for `params`: None, a dict (names or Symbols -> value) or an array."""
    return parameter_vector(params, tuple(mod.parameters), np.asarray(mod.defaults, dtype=float))


def input_function(mod, inputs):
    """A function t -> the input vector u(t), in input order.

    `inputs` maps input names (or the functions `model.inputs` returned) to constants or callables
    of t; unnamed inputs are zero. A full array gives constant inputs in input order. Constant
    inputs give one read-only vector, the same for every t.
    """
    names = tuple(mod.inputs)
    if inputs is None or not isinstance(inputs, dict):
        u0 = np.zeros(len(names)) if inputs is None else require_finite(
            as_vector(inputs, len(names), "inputs (the input vector)"), names, "input")
        return constant(u0)
    by_name = {}
    for key, value in inputs.items():
        name = key_name(key)
        if name not in names:
            raise unknown_name("input", name, names)
        by_name[name] = value
    constants = {k: v for k, v in by_name.items() if not callable(v)}
    u0 = require_finite(named_vector(constants, names, np.zeros(len(names)), "input"), names,
                        "input")
    varying = [(names.index(k), f) for k, f in by_name.items() if callable(f)]
    if not varying:
        return constant(u0)

    def u_at(t):
        u = u0.copy()
        for i, f in varying:
            u[i] = f(t)
        return u
    return u_at


def constant(u0):
    """t -> u0 for every t (u0 made read-only: every call shares it)."""
    u0.setflags(write=False)

    def u_at(t):
        return u0
    return u_at


class _Guard:
    """A terminal solve_ivp event that ends the integration after `max_steps` steps or
    `max_wall_time` seconds: solve_ivp evaluates it once per accepted step, so it counts steps; once
    tripped it changes sign just after the last step taken, where the solver then stops (keeping
    the result up to there)."""

    terminal = True
    direction = 0

    def __init__(self, max_steps, max_wall_time):
        if max_steps is not None and not (int(max_steps) == max_steps and max_steps > 0):
            raise ValueError(f"max_steps must be a positive integer, got {max_steps!r}")
        if max_wall_time is not None and not max_wall_time > 0:
            raise ValueError(f"max_wall_time must be a positive number of seconds, got "
                             f"{max_wall_time!r}")
        self.max_steps, self.max_wall_time = max_steps, max_wall_time
        self.steps, self.start = -1, time.monotonic()
        self.last_t, self.tripped_at, self.reason = None, None, None

    def __call__(self, t, y):
        if self.tripped_at is not None:
            return -1.0 if t > self.tripped_at else 1.0
        self.steps += 1
        if self.max_steps is not None and self.steps > self.max_steps:
            self.reason = f"the step limit max_steps={self.max_steps} was reached"
        elif self.max_wall_time is not None and \
                time.monotonic() - self.start > self.max_wall_time:
            self.reason = f"the wall-time limit max_wall_time={self.max_wall_time:g} s was reached"
        if self.reason is None or self.last_t is None:
            self.last_t = t
            return 1.0
        self.tripped_at = self.last_t
        return -1.0


def simulate(mod, t_span, y0, method="RK45", params=None, inputs=None, rtol=1e-6, atol=1e-9,
             t_eval=None, dense_output=False, events=None, engine=None, max_steps=None,
             max_wall_time=None, **options):
    """Integrate ẏ = mod.rhs(t, y) over `t_span` from `y0` = [q0, q̇0], natively in C or with
    SciPy's `solve_ivp` (the same steps either way).

    Parameters
    ----------
    mod : a built model (either backend)
    t_span : (t0, t1)
    y0 : array of 2n numbers, or a dict of coordinate and `<coordinate>_dot` names (missing: 0)
    method : one of METHODS or a solver class; the stiff ones get the analytic `mod.jacobian`
        (Radau and BDF run as `lagrgen.solvers` classes: SciPy's, with direct LAPACK LU)
    params : dict of parameter names (or the model's Symbols) -> value, or a full array
    inputs : dict of input names (or the model's functions) -> constant, `lagrgen.Signal` or
        callable of t
    engine : None runs the whole solve in C (`lagrgen.native_engine`, no Python per step, the
        GIL released) when the model is compiled, the method is RK23/RK45/DOP853/Radau/BDF, the
        inputs are constants or Signals and there are no Python events; otherwise SciPy's
        `solve_ivp` (a callable input says so in `result.message`). "native" insists (ValueError
        saying why not); "scipy" always uses `solve_ivp`. `result.engine` says which ran.
    max_steps, max_wall_time : a guard for long integrations (None: no limit). When either is
        reached the integration stops there: the result holds the solution up to that time, with
        `success` False, `status` −1, `guard` and `message` saying which limit was hit. (The guard
        is a Python event, so a guarded solve runs on the SciPy engine.)
    **options : passed to `solve_ivp` unchanged (max_step, first_step, ...)

    Returns
    -------
    SciPy's OdeResult, with also `coordinates` (names), `q` and `qd` (views of the rows of `y`),
    `params` and `inputs` (the values used; see `evaluate_outputs`) and `guard` (None, or why the
    guard stopped the integration).
    A constrained model's result also has `constraint_forces` (λ, n_constraints × len(t), with
    M·q̈ = F + Aᵀλ) and `constraint_residuals` (Φ then A·q̇ + b, (n_holonomic + n_constraints) ×
    len(t)), `constraint_names` and `multipliers` ({name: λ row}, the reaction asked for by
    the constraint's name). Its initial state should satisfy the constraints (see `lagrgen.consistent_state`;
    Baumgarte stabilization pulls a small violation back).

    Raises
    ------
    NonFiniteError when the derivative becomes NaN or infinite (naming t and the state),
    MassMatrixError when M is not positive definite, ConstraintError when the constraints are
    redundant at the initial state or become dependent during the run.
    """
    if "args" in options:
        raise TypeError("simulate() takes no 'args': pass parameters as params={name: value} "
                        "(or a full parameter array) and inputs as inputs={name: value or f(t)}")
    if not (method in METHODS or isinstance(method, type)):
        raise ValueError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")
    if engine not in (None, "native", "scipy"):
        raise ValueError(f"engine must be None, 'native' or 'scipy', not {engine!r}")
    n = mod.n_coordinates
    y0 = state_vector(y0, tuple(mod.coordinates))
    p = parameters_from(mod, params)
    if getattr(mod, "nonsmooth_definitions", ()):
        return simulate_nonsmooth(mod, t_span, y0, method, p, inputs, rtol, atol, t_eval,
                                  dense_output, events, engine, options)
    guard = None
    compiled_events = events is None and bool(getattr(mod, "event_definitions", ()))
    if max_steps is not None or max_wall_time is not None:
        guard = _Guard(max_steps, max_wall_time)
        events = ([] if events is None else (list(events) if isinstance(events, (list, tuple))
                                              else [events])) + [guard]
    why_not = None if engine == "scipy" else native_reason(mod, method, inputs, events, options,
                                                            rtol)
    if engine == "native" and why_not:
        raise ValueError(f"the native engine cannot run this solve: {why_not}")
    u_at = input_function(mod, inputs)
    rhs, jacobian = mod.rhs, mod.jacobian

    def fun(t, y):
        ydot = rhs(t, y, p, u_at(t))
        if not math.isfinite(ydot.sum()):
            raise NonFiniteError.at(mod.name, t, y)
        return ydot

    def jac(t, y):
        return jacobian(t, y, p, u_at(t))
    constrained = getattr(mod, "n_constraints", 0) > 0
    if constrained:
        from .constraints import check_state
        t0 = float(t_span[0])
        check_state(mod, t0, y0, p, u_at(t0))
    if engine != "scipy" and why_not is None:
        sol = solve_native(mod, t_span, y0, method, p, input_specs(mod, inputs), rtol, atol,
                           t_eval, dense_output, native_events(mod) if compiled_events else None,
                           stop_on_nonfinite=True, **options)
        raise_native_failure(mod, sol, p, u_at)
    else:
        if compiled_events:
            events = event_functions(mod, p, u_at) + ([guard] if guard else [])
        if getattr(method, "__name__", method) in STIFF_METHODS:
            options.setdefault("jac", jac)
        sol = solve_ivp(fun, t_span, y0, method=SOLVERS.get(method, method), rtol=rtol,
                        atol=atol, t_eval=t_eval, dense_output=dense_output, events=events,
                        **options)
        sol.engine = "scipy"
        if engine is None and why_not and "Python callable" in why_not:
            sol.message = f"{sol.message} (SciPy engine: {why_not})"
    sol.guard = None
    if guard is not None:
        finish_guarded(sol, guard, t_span)
    sol.params = p
    sol.inputs = u_at
    sol = with_coordinates(sol, mod.coordinates, n, getattr(mod, "name", None))
    sol.__dict__["_units"] = dict(getattr(mod, "units", {}))
    if compiled_events:
        sol.event_names = tuple(name for name, _, _ in mod.event_definitions)
    if constrained:
        from .constraints import along
        sol.constraint_forces, sol.constraint_residuals = along(mod, sol, p, u_at)
        sol.constraint_names = tuple(mod.constraint_names)
        sol.multipliers = dict(zip(sol.constraint_names, sol.constraint_forces))
    return sol


def simulate_nonsmooth(mod, t_span, y0, method, p, inputs, rtol, atol, t_eval, dense_output,
                       events, engine, options):
    """`simulate` for a model with impacts or frictions (`lagrgen.hybrid`): smooth segments with
    the switches between them, natively in C or with `solve_ivp`; the result also has
    `transitions` [(t, name, kind)] and `mode` {name: mode at the end}."""
    from . import hybrid
    if events is not None:
        raise ValueError("a model with impacts or frictions takes no Python events: declare them "
                         "with model.event")
    if not isinstance(method, str) or method not in ("RK23", "RK45", "DOP853", "Radau", "BDF",
                                                      "LSODA"):
        raise ValueError(f"a model with impacts or frictions runs with RK23, RK45, DOP853, Radau "
                         f"or BDF, not {getattr(method, '__name__', method)!r}")
    if dense_output:
        raise ValueError("dense_output is not available for a model with impacts or frictions: "
                         "give t_eval")
    switching = {k: options.pop(k) for k in ("rest_velocity", "gap_tol", "max_transitions")
                 if k in options}
    why_not = None if engine == "scipy" else native_reason(mod, method, inputs, None, options,
                                                            rtol)
    if engine == "native" and why_not:
        raise ValueError(f"the native engine cannot run this solve: {why_not}")
    u_at = input_function(mod, inputs)
    if t_eval is not None:
        from .native_engine import _t_eval
        t_eval = _t_eval(t_eval, *map(float, t_span))
    if engine != "scipy" and why_not is None:
        out = hybrid.solve_hybrid_native(mod, t_span, y0, method, p, input_specs(mod, inputs),
                                         rtol, atol, t_eval, **switching, **options)
        engine_name = "native"
    else:
        out = hybrid.simulate_hybrid(mod, t_span, y0, method, p, u_at, rtol, atol, t_eval,
                                     **switching, **options)
        engine_name = "scipy"
    sol = OdeResult(t=out["t"], y=out["y"], sol=None, t_events=None, y_events=None,
                    nfev=out["nfev"], njev=0, nlu=0, status=out["status"],
                    message=out["message"], success=out["status"] >= 0)
    sol.engine = engine_name
    sol.transitions = out["transitions"]
    sol.mode = out["mode"]
    sol.n_segments = out["n_segments"]
    sol.guard = None
    sol.params = p
    sol.inputs = u_at
    sol = with_coordinates(sol, mod.coordinates, mod.n_coordinates, getattr(mod, "name", None))
    sol.__dict__["_units"] = dict(getattr(mod, "units", {}))
    return sol


def native_events(mod):
    """(address of the model's C events function, terminal counts, directions)."""
    definitions = mod.event_definitions
    return (mod.compiled_model.function_address("events"),
            np.array([terminal for _, terminal, _ in definitions], dtype=np.intc),
            np.array([direction for _, _, direction in definitions], dtype=float))


def event_functions(mod, p, u_at):
    """The model's compiled events as solve_ivp event callables (one per event)."""
    functions = []
    for k, (name, terminal, direction) in enumerate(mod.event_definitions):
        def g(t, y, k=k):
            return mod.events(t, y, p, u_at(t))[k]
        g.__name__, g.terminal, g.direction = name, terminal, direction
        functions.append(g)
    return functions


def raise_native_failure(mod, sol, p, u_at):
    """Raise, for a native solve, the error the SciPy engine raises at the same point: the
    model's own error at the state where it failed, or NonFiniteError."""
    failure = getattr(sol, "mass_matrix_failure", None)
    if failure is not None:
        t, y = failure
        mod.rhs(t, y, p, u_at(t))
        raise MassMatrixError.at(mod.name, t, y[:mod.n_coordinates])
    failure = getattr(sol, "nonfinite_failure", None)
    if failure is not None:
        raise NonFiniteError.at(mod.name, *failure)


def finish_guarded(sol, guard, t_span):
    """Drop the guard's event from `sol` and, if it stopped the run, say so (status −1)."""
    sol.t_events, sol.y_events = sol.t_events[:-1], sol.y_events[:-1]
    if not sol.t_events:        # the guard was the only event: as solve_ivp without events
        sol.t_events = sol.y_events = None
    if guard.reason is not None and len(sol.t) and sol.status == 1 and \
            guard.tripped_at is not None:
        sol.guard = guard.reason
        sol.success, sol.status = False, -1
        sol.message = (f"the integration was stopped at t = {guard.tripped_at:.6g} "
                       f"(of {t_span[1]:g}) after {guard.steps - 1} steps: {guard.reason}; "
                       "the result holds the solution up to there. A discontinuous force "
                       "(sign, Heaviside, a stop) can make an explicit solver crawl: try "
                       "method='Radau', events on the switching surfaces, or a smooth "
                       "approximation such as tanh(v/eps)")


def evaluate_outputs(mod, sol, params=None, inputs=None):
    """The outputs y_k(t_i, y_i) of `mod` at every saved time of a solution.

    Parameters
    ----------
    mod : a built model (either backend)
    sol : the result of `simulate` (or any object with `t` and `y`)
    params, inputs : as for `simulate`; by default the values `simulate` stored on `sol`

    Returns
    -------
    An `Outputs` table: a (len(mod.output_names) + 2, len(sol.t)) float64 array with `names`
    (the outputs, then "input_power" and "rayleigh_dissipation") and `units`;
    `table["total_energy"]` is one row.
    """
    p = getattr(sol, "params", None) if params is None else parameters_from(mod, params)
    p = parameters_from(mod, None) if p is None else p
    held = getattr(sol, "inputs", None)
    u_at = held if inputs is None and callable(held) else input_function(mod, inputs)
    t, y = np.asarray(sol.t, dtype=float), np.asarray(sol.y, dtype=float)
    k = len(mod.output_names)
    out = np.empty((k + len(POWER_TERMS), len(t)))
    for i, ti in enumerate(t):
        yi = np.ascontiguousarray(y[:, i])
        out[:k, i] = mod.outputs(ti, yi, p, u_at(ti))
        out[k:, i] = mod.power_terms(ti, yi, p, u_at(ti))
    return Outputs(out, tuple(mod.output_names) + POWER_TERMS, getattr(mod, "units", {}))


class Outputs(np.ndarray):
    """A (n_outputs, n_times) array of output histories that also answers `table[name]`."""

    def __new__(cls, values, names, units):
        obj = np.asarray(values, dtype=float).view(cls)
        obj.names, obj.units = tuple(names), dict(units)
        return obj

    def __array_finalize__(self, obj):
        self.names = getattr(obj, "names", ())
        self.units = getattr(obj, "units", {})

    def __getitem__(self, key):
        if isinstance(key, str):
            if key not in self.names:
                raise KeyError(f"no output {key!r}: the outputs are {', '.join(self.names)}")
            return np.asarray(self)[self.names.index(key)]
        return np.asarray(self)[key]


def output_event(mod, name, params=None, inputs=None, terminal=False, direction=0):
    """A solve_ivp event function whose root is where the output `name` crosses zero.

    Declare a switching surface (a slip velocity, a gap) as an output and pass this as
    ``simulate(..., events=[...])``: the solver then locates the switch instead of stepping over it.
    """
    names = tuple(mod.output_names)
    if name not in names:
        from .runtime.arguments import unknown_name
        raise unknown_name("output", name, names)
    k = names.index(name)
    p = parameters_from(mod, params)
    u_at = input_function(mod, inputs)
    outputs = mod.outputs

    def event(t, y):
        return outputs(t, y, p, u_at(t))[k]
    event.terminal, event.direction = terminal, direction
    return event


class SimulationResult(OdeResult):
    """SciPy's OdeResult (the same fields: t, y, nfev, ..., coordinates, q, qd) that can also plot
    itself."""

    def plot(self, velocities=True, title=None):
        """q_i(t) (and q̇_i(t) in a second panel), labelled with the model's coordinate names.

        Parameters
        ----------
        velocities : bool
            Also plot the rates q̇_i(t).
        title : str, optional
            The figure's title (default: the model's name).

        Returns
        -------
        matplotlib.figure.Figure
        """
        from .outputs.plotting import plot_time_history
        if title is None:
            title = self.__dict__.get("_model_name")
        return plot_time_history(self, self.coordinates, velocities=velocities, title=title,
                                 units=self.__dict__.get("_units"))


def with_coordinates(sol, coordinates, n, model_name=None):
    """`sol` as a SimulationResult with also `coordinates`, `q` (n × len(t)) and `qd`
    (n × len(t)), views of the rows of `y`."""
    result = sol if isinstance(sol, SimulationResult) else SimulationResult(sol)
    result.coordinates = tuple(coordinates)
    result.q = result.y[:n]
    result.qd = result.y[n:]
    if model_name is not None:
        result.__dict__["_model_name"] = model_name   # not a field: only the plot's title
    return result
