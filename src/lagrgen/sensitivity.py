"""Forward sensitivities: S(t) = ∂y(t)/∂p_j integrated with the state.

The augmented system is y' = f(t, y, p, u), S_j' = J·S_j + ∂f/∂p_j with S_j(0) = 0 (or a unit
vector for an initial state y0:<state>), J = ∂f/∂y the model's analytic Jacobian and ∂f/∂p its
analytic parameter Jacobian: the k products come from one call of the model's
`directional_derivatives` (forward mode on its kernels, J never formed). The error control
covers the sensitivities as well as the state
(as CVODES with errconS set). For Radau and BDF the augmented Jacobian is taken block-diagonal,
diag(J, …, J): the term ∂(J·S)/∂y only enters the Newton iteration matrix, which needs to be
approximate. On a compiled model the augmented system runs in C (the native engine with the
hooks of native/lg_sensitivity.c, no Python per step) whenever the native engine can run the
solve; otherwise through SciPy's solve_ivp (the SciPy engine). `result.engine` says which.
"""
import numpy as np
from scipy.integrate import solve_ivp

from .errors import NonFiniteError
from .methods import STIFF_METHODS
from .runtime.arguments import key_names, unknown_name
from .solvers import SOLVERS


def sensitivity_columns(mod, names):
    """[(kind, index)] for `names`: ("p", j) for a parameter, ("y0", i) for `y0:<state>`."""
    names = key_names(names)
    states = list(mod.coordinates) + [f"{c}_dot" for c in mod.coordinates]
    columns = []
    for name in names:
        if isinstance(name, str) and name.startswith("y0:"):
            state = name[3:]
            if state not in states:
                raise unknown_name("state", state, tuple(states))
            columns.append(("y0", states.index(state)))
        elif name in mod.parameters:
            columns.append(("p", list(mod.parameters).index(name)))
        else:
            raise unknown_name("parameter", name, tuple(mod.parameters))
    if not columns:
        raise ValueError("sensitivities needs at least one parameter name (or y0:<state>)")
    return columns


def checked_names(mod, names, events=None):
    """The sensitivity `names` as a tuple, after checking them (`sensitivity_columns`) and that
    the model is smooth and has no events (ValueError: sensitivities do not cross switches)."""
    sensitivity_columns(mod, names)
    if mod.nonsmooth_definitions or events is not None or mod.event_definitions:
        raise ValueError("sensitivities are computed for smooth models without events: this "
                         "model has impacts, friction or events")
    return (names,) if isinstance(names, str) else tuple(names)


def augmented_functions(mod, p, u_at, columns):
    """(rhs, jacobian) of the augmented state z = [y, S_1, …, S_k] for solve_ivp."""
    dim, k = 2 * mod.n_coordinates, len(columns)
    P = unit_rows(columns, "p", len(mod.parameters))
    directional, jacobian = mod.directional_derivatives, mod.jacobian

    def fun(t, z):
        y = z[:dim]
        ydot, dS = directional(t, y, z[dim:].reshape(k, dim), P, p, u_at(t))
        out = np.concatenate([ydot, dS.ravel()])
        if not np.isfinite(out.sum()):
            raise NonFiniteError.at(mod.name, t, y)
        return out

    def jac(t, z):
        return np.kron(np.eye(k + 1), jacobian(t, z[:dim], p, u_at(t)))

    return fun, jac


def unit_rows(columns, kind, width):
    """(k, width): row c the unit vector e_i of column c = (kind, i), zeros for the other kind.
    Of kind "p": the parameter directions; of kind "y0": S(0)."""
    rows = np.zeros((len(columns), width))
    for c, (of, i) in enumerate(columns):
        if of == kind:
            rows[c, i] = 1.0
    return rows


def solve_sensitivities(mod, t_span, y0, method, p, u_at, rtol, atol, names, inputs=None,
                        engine=None, t_eval=None, dense_output=False, max_steps=None,
                        max_wall_time=None, **options):
    """The augmented system, natively in C when the engine can run it (`engine` as simulate's),
    else by solve_ivp; returns SciPy's OdeResult with `y` the states, `sensitivities`
    (k, 2n, len(t)), `engine` and `guard` (why max_steps or max_wall_time stopped it, or None)."""
    from .native.engine import native_reason, raise_native_failure, report_guard, solve_native
    from .scipy_engine import Guard, drop_guard_event
    from .runtime.arguments import input_specs
    dim = 2 * mod.n_coordinates
    columns = sensitivity_columns(mod, names)
    z0 = np.concatenate([y0, unit_rows(columns, "y0", dim).ravel()])
    why_not = None if engine == "scipy" else native_reason(mod, method, inputs, None, options,
                                                            rtol)
    if engine == "native" and why_not:
        raise ValueError(f"the native engine cannot run this solve: {why_not}")
    if engine != "scipy" and why_not is None:
        index = [j if kind == "p" else -1 for kind, j in columns]
        sol = solve_native(mod, t_span, z0, method, p, input_specs(mod, inputs), rtol, atol,
                           t_eval, dense_output, stop_on_nonfinite=True, sensitivity_index=index,
                           max_steps=max_steps, max_wall_time=max_wall_time, **options)
        raise_native_failure(mod, sol, p, u_at)
        report_guard(sol, t_span, max_steps, max_wall_time)
    else:
        fun, jac = augmented_functions(mod, p, u_at, columns)
        if getattr(method, "__name__", method) in STIFF_METHODS:
            options.setdefault("jac", jac)
        guard = None
        if max_steps is not None or max_wall_time is not None:
            guard = Guard(max_steps, max_wall_time)
            options["events"] = [guard]
        sol = solve_ivp(fun, t_span, z0, method=SOLVERS.get(method, method), rtol=rtol,
                        atol=atol, t_eval=t_eval, dense_output=dense_output, **options)
        sol.engine, sol.guard = "scipy", None
        if guard is not None:
            drop_guard_event(sol, guard, t_span)
    sol.sensitivities = sol.y[dim:].reshape(len(columns), dim, -1)
    sol.y = sol.y[:dim]
    if getattr(sol, "sol", None) is not None:
        sol.sol = StatesOnly(sol.sol, dim)
    sol.sensitivity_names = tuple(names if not isinstance(names, str) else [names])
    return sol


class StatesOnly:
    """The dense output of a run with sensitivities, as `sol.sol(t)` of any run gives it: the
    states y(t) (its first `dim` rows); `sensitivities(t)` the (k, dim) or (k, dim, len(t))
    ∂y(t)/∂p_j."""

    def __init__(self, dense, dim):
        self.dense, self.dim = dense, dim

    def __call__(self, t):
        return self.dense(t)[:self.dim]

    def sensitivities(self, t):
        z = np.asarray(self.dense(t))
        return z[self.dim:].reshape((-1, self.dim) + z.shape[1:])
