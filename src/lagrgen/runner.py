"""Running a built model (either backend) through SciPy's `solve_ivp`."""
import numpy as np
from scipy.integrate import solve_ivp

from .arguments import as_vector, named_vector, parameter_vector
from .errors import MassMatrixError, UnknownNameError
from .native_engine import input_specs, native_reason, solve_native
from .solvers import SOLVERS

METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")
STIFF_METHODS = ("Radau", "BDF", "LSODA")


def parameters_from(mod, params):
    """The parameter vector for `params`: None, a dict name -> value, or a full array."""
    return parameter_vector(params, tuple(mod.parameters), np.asarray(mod.defaults, dtype=float))


def input_function(mod, inputs):
    """Return (u, u_of_t): a constant input vector, or None and a function t -> input vector.

    `inputs` maps input names to constants or callables of t; unnamed inputs are zero.
    """
    names = tuple(mod.inputs)
    if inputs is None:
        return np.zeros(len(names)), None
    if not isinstance(inputs, dict):
        return as_vector(inputs, len(names), "inputs"), None
    unknown = [k for k in inputs if k not in names]
    if unknown:
        raise UnknownNameError(
            f"unknown input name {unknown[0]!r}: the model's inputs are {', '.join(names) or 'none'}")
    constants = {k: v for k, v in inputs.items() if not callable(v)}
    u0 = named_vector(constants, names, np.zeros(len(names)), "input")
    varying = [(names.index(k), f) for k, f in inputs.items() if callable(f)]
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
    """Integrate ẏ = mod.rhs(t, y) over `t_span` from `y0` = [q0, q̇0] with `solve_ivp`.

    The stiff methods (Radau, BDF, LSODA) get the analytic `mod.jacobian`; Radau and BDF run as
    `lagrgen.solvers` classes (SciPy's, with direct LAPACK LU). Returns SciPy's OdeResult.
    Extra keyword options (max_step, first_step, ...) go to `solve_ivp` unchanged.

    `engine`: None runs the whole solve natively in C (`lagrgen.native_engine`, the same steps as
    solve_ivp) when the model is compiled, the method is RK23/RK45/DOP853/Radau/BDF, the inputs
    are constants or `lagrgen.Signal`s and there are no Python events; otherwise SciPy's.
    "native" insists (ValueError saying why not), "scipy" always uses `solve_ivp`. The result's
    `engine` says which ran. A mass matrix that is not positive definite raises MassMatrixError on
    both engines (`native_engine.solve_native` itself returns status -1 instead).
    """
    if not (method in METHODS or isinstance(method, type)):
        raise ValueError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")
    n = mod.n_coordinates
    y0 = as_vector(y0, 2 * n, f"y0 (= [q0, qd0] for coordinates {', '.join(mod.coordinates)})")
    p = parameters_from(mod, params)
    # --- native engine (issue 10) ---
    if engine not in (None, "native", "scipy"):
        raise ValueError(f"engine must be None, 'native' or 'scipy', not {engine!r}")
    why_not = native_reason(mod, method, inputs, events, options, rtol) if engine != "scipy" else None
    if engine == "native" and why_not:
        raise ValueError(f"the native engine cannot run this solve: {why_not}")
    if engine != "scipy" and why_not is None:
        result = solve_native(mod, t_span, y0, method, p, input_specs(mod, inputs), rtol, atol,
                              t_eval, dense_output, None, **options)
        if result.mass_matrix_failure is not None:   # as the SciPy engine: mod.rhs raises
            t_fail, y_fail = result.mass_matrix_failure
            raise MassMatrixError.at(mod.name, t_fail, y_fail[:n])
        return result
    # --- SciPy engine ---
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
    result = solve_ivp(fun, t_span, y0, method=SOLVERS.get(method, method), rtol=rtol, atol=atol,
                       t_eval=t_eval, dense_output=dense_output, events=events, **options)
    result.engine = "scipy"
    if engine is None and why_not and "Python callable" in why_not:
        result.message = f"{result.message} (SciPy engine: {why_not})"
    return result
