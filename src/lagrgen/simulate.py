"""`simulate`: running a built model (either backend) through SciPy's `solve_ivp`.

User arguments (params, inputs, y0) are converted once here, by `lagrgen.runtime.arguments`; the
functions handed to the solver take raw float64 arrays.
"""
import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.integrate._ivp.ivp import OdeResult

from .errors import MassMatrixError, NonFiniteError
from .runtime.arguments import (as_vector, key_name, named_vector, parameter_vector,
                                require_finite, state_vector, unknown_name)
from .methods import METHODS, STIFF_METHODS
from .native_engine import input_specs, native_reason, solve_native
from .solvers import SOLVERS


def parameters_from(mod, params):
    """The parameter vector for `params`: None, a dict (names or Symbols -> value) or an array."""
    return parameter_vector(params, tuple(mod.parameters), np.asarray(mod.defaults, dtype=float))


def input_function(mod, inputs):
    """Return (u, u_of_t): a constant input vector, or None and a function t -> input vector.

    `inputs` maps input names (or the functions `model.inputs` returned) to constants or callables
    of t; unnamed inputs are zero. A full array gives constant inputs in input order.
    """
    names = tuple(mod.inputs)
    if inputs is None:
        return np.zeros(len(names)), None
    if not isinstance(inputs, dict):
        return require_finite(as_vector(inputs, len(names), "inputs (the input vector)"), names,
                              "input"), None
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
        return u0, None

    def u_of_t(t):
        u = u0.copy()
        for i, f in varying:
            u[i] = f(t)
        return u
    return None, u_of_t


def simulate(mod, t_span, y0, method="RK45", params=None, inputs=None, rtol=1e-6, atol=1e-9,
             t_eval=None, dense_output=False, events=None, engine=None, **options):
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
    **options : passed to `solve_ivp` unchanged (max_step, first_step, ...)

    Returns
    -------
    SciPy's OdeResult, with also `coordinates` (names), `q` and `qd` (views of the rows of `y`).
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
    why_not = None if engine == "scipy" else native_reason(mod, method, inputs, events, options,
                                                            rtol)
    if engine == "native" and why_not:
        raise ValueError(f"the native engine cannot run this solve: {why_not}")
    u, u_of_t = input_function(mod, inputs)
    rhs, jacobian = mod.rhs, mod.jacobian
    if u_of_t is None:
        def fun(t, y):
            ydot = rhs(t, y, p, u)
            if not math.isfinite(ydot.sum()):
                raise NonFiniteError.at(mod.name, t, y)
            return ydot

        def jac(t, y):
            return jacobian(t, y, p, u)
    else:
        def fun(t, y):
            ydot = rhs(t, y, p, u_of_t(t))
            if not math.isfinite(ydot.sum()):
                raise NonFiniteError.at(mod.name, t, y)
            return ydot

        def jac(t, y):
            return jacobian(t, y, p, u_of_t(t))
    constrained = getattr(mod, "n_constraints", 0) > 0
    if constrained:
        from .constraints import check_state
        t0 = float(t_span[0])
        check_state(mod, t0, y0, p, u if u_of_t is None else u_of_t(t0))
    compiled_events = events is None and bool(getattr(mod, "event_definitions", ()))
    if engine != "scipy" and why_not is None:
        sol = solve_native(mod, t_span, y0, method, p, input_specs(mod, inputs), rtol, atol,
                           t_eval, dense_output, native_events(mod) if compiled_events else None,
                           stop_on_nonfinite=True, **options)
        raise_native_failure(mod, sol, p, u, u_of_t)
    else:
        if compiled_events:
            events = event_functions(mod, p, u, u_of_t)
        if getattr(method, "__name__", method) in STIFF_METHODS:
            options.setdefault("jac", jac)
        sol = solve_ivp(fun, t_span, y0, method=SOLVERS.get(method, method), rtol=rtol,
                        atol=atol, t_eval=t_eval, dense_output=dense_output, events=events,
                        **options)
        sol.engine = "scipy"
        if engine is None and why_not and "Python callable" in why_not:
            sol.message = f"{sol.message} (SciPy engine: {why_not})"
    sol = with_coordinates(sol, mod.coordinates, n, getattr(mod, "name", None))
    if compiled_events:
        sol.event_names = tuple(name for name, _, _ in mod.event_definitions)
    if constrained:
        from .constraints import along
        sol.constraint_forces, sol.constraint_residuals = along(mod, sol, p, u, u_of_t)
        sol.constraint_names = tuple(mod.constraint_names)
        sol.multipliers = dict(zip(sol.constraint_names, sol.constraint_forces))
    return sol


def native_events(mod):
    """(address of the model's C events function, terminal counts, directions)."""
    definitions = mod.event_definitions
    return (mod.compiled_model.function_address("events"),
            np.array([terminal for _, terminal, _ in definitions], dtype=np.intc),
            np.array([direction for _, _, direction in definitions], dtype=float))


def event_functions(mod, p, u, u_of_t):
    """The model's compiled events as solve_ivp event callables (one per event)."""
    functions = []
    for k, (name, terminal, direction) in enumerate(mod.event_definitions):
        def g(t, y, k=k):
            return mod.events(t, y, p, u if u_of_t is None else u_of_t(t))[k]
        g.__name__, g.terminal, g.direction = name, terminal, direction
        functions.append(g)
    return functions


def raise_native_failure(mod, sol, p, u, u_of_t):
    """Raise, for a native solve, the error the SciPy engine raises at the same point: the
    model's own error at the state where it failed, or NonFiniteError."""
    failure = getattr(sol, "mass_matrix_failure", None)
    if failure is not None:
        t, y = failure
        mod.rhs(t, y, p, u if u_of_t is None else u_of_t(t))
        raise MassMatrixError.at(mod.name, t, y[:mod.n_coordinates])
    failure = getattr(sol, "nonfinite_failure", None)
    if failure is not None:
        raise NonFiniteError.at(mod.name, *failure)


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
        return plot_time_history(self, self.coordinates, velocities=velocities, title=title)


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
