"""`simulate`: running a built model (either backend) through SciPy's `solve_ivp`.

User arguments (params, inputs, y0) are converted once here, by `lagrgen.runtime.arguments`; the
functions handed to the solver take raw float64 arrays.
"""
import numpy as np
from scipy.integrate import solve_ivp
from scipy.integrate._ivp.ivp import OdeResult

from .runtime.arguments import (as_vector, key_name, named_vector, parameter_vector,
                                require_finite, state_vector, unknown_name)
from .solvers import SOLVERS

METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")
STIFF_METHODS = ("Radau", "BDF", "LSODA")


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
             t_eval=None, dense_output=False, events=None, **options):
    """Integrate ẏ = mod.rhs(t, y) over `t_span` from `y0` = [q0, q̇0] with `solve_ivp`.

    Parameters
    ----------
    mod : a built model (either backend)
    t_span : (t0, t1)
    y0 : array of 2n numbers, or a dict of coordinate and `<coordinate>_dot` names (missing: 0)
    method : one of METHODS or a solver class; the stiff ones get the analytic `mod.jacobian`
        (Radau and BDF run as `lagrgen.solvers` classes: SciPy's, with direct LAPACK LU)
    params : dict of parameter names (or the model's Symbols) -> value, or a full array
    inputs : dict of input names (or the model's functions) -> constant or callable of t
    **options : passed to `solve_ivp` unchanged (max_step, first_step, ...)

    Returns
    -------
    SciPy's OdeResult, with also `coordinates` (names), `q` and `qd` (views of the rows of `y`).
    """
    if "args" in options:
        raise TypeError("simulate() takes no 'args': pass parameters as params={name: value} "
                        "(or a full parameter array) and inputs as inputs={name: value or f(t)}")
    if not (method in METHODS or isinstance(method, type)):
        raise ValueError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")
    n = mod.n_coordinates
    y0 = state_vector(y0, tuple(mod.coordinates))
    p = parameters_from(mod, params)
    u, u_of_t = input_function(mod, inputs)
    rhs, jacobian = mod.rhs, mod.jacobian
    if u_of_t is None:
        def fun(t, y):
            return rhs(t, y, p, u)

        def jac(t, y):
            return jacobian(t, y, p, u)
    else:
        def fun(t, y):
            return rhs(t, y, p, u_of_t(t))

        def jac(t, y):
            return jacobian(t, y, p, u_of_t(t))
    if getattr(method, "__name__", method) in STIFF_METHODS:
        options.setdefault("jac", jac)
    sol = solve_ivp(fun, t_span, y0, method=SOLVERS.get(method, method), rtol=rtol, atol=atol,
                    t_eval=t_eval, dense_output=dense_output, events=events, **options)
    return with_coordinates(sol, mod.coordinates, n, getattr(mod, "name", None))


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
