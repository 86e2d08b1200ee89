"""`simulate`: one run of a built model (either backend): arguments checked once, the engine
chosen, the run, and the result built.

The engines are `lagrgen.native.engine` (the whole solve in C) and `lagrgen.scipy_engine`
(`solve_ivp`); user arguments (params, inputs, y0) are converted by `lagrgen.runtime.arguments`.
"""
import numpy as np

from .errors import warn_near_singular
from .functions import POWER_TERMS
from .hybrid import check_within_stops, is_hybrid
from .methods import METHODS
from .native.engine import native_reason, simulate_native
from .options import SWITCHING_OPTIONS, check_run_options as checked_options
from .progress import ProgressBar
from .results import Outputs, with_coordinates
from .runtime.arguments import input_function, parameters_from, state_vector, unknown_name
from .runtime.free_base import check_quaternion
from .scipy_engine import solve_scipy

ENGINES = (None, "native", "scipy")


def simulate(mod, t_span, y0=None, method="RK45", params=None, inputs=None, rtol=1e-6, atol=1e-9,
             t_eval=None, dense_output=False, events=None, engine=None, max_steps=None,
             max_wall_time=None, progress=False, sensitivities=None, **options):
    """Integrate ẏ = mod.rhs(t, y) over `t_span` from `y0` = [q0, q̇0], natively in C or with
    SciPy's `solve_ivp` (the same steps either way).

    Parameters
    ----------
    mod : a built model (either backend)
    t_span : (t0, t1)
    y0 : array of 2n numbers, or a dict of coordinate and `<coordinate>_dot` names (missing: 0);
        None: the model's `initial_state` (declared with `model.initial_state`, else zeros)
    method : one of METHODS or a solver class; the stiff ones get the analytic `mod.jacobian`
        (Radau and BDF run as `lagrgen.solvers` classes: SciPy's, with direct LAPACK LU)
    params : dict of parameter names (or the model's Symbols) -> value, or a full array
    inputs : dict of input names (or the model's functions) -> constant, `lagrgen.Signal` or
        callable of t
    events : Python event callables for solve_ivp (None: the model's compiled events)
    engine : None runs the whole solve in C (`lagrgen.native.engine`, no Python per step, the
        GIL released) when the model is compiled, the method is RK23/RK45/DOP853/Radau/BDF, the
        inputs are constants or Signals and there are no Python events; otherwise SciPy's
        `solve_ivp` (a callable input says so in `result.message`). "native" insists (ValueError
        saying why not); "scipy" always uses `solve_ivp`. `result.engine` says which ran.
    max_steps, max_wall_time : a guard for long integrations (None: no limit), on both engines.
        When either is reached the integration stops there: the result holds the solution up to
        that time, with `success` False, `status` −1, `guard` and `message` saying which limit
        was hit. Ctrl-C ends a native solve within a fraction of a second (KeyboardInterrupt).
    progress : False, True, or "auto" (on a terminal, once the run takes longer than a second):
        a progress bar of the simulated time on stderr
    sensitivities : parameter names (and `y0:<state>` names) whose forward sensitivities
        ∂y(t)/∂p_j are integrated with the state (`lagrgen.sensitivity`; in C on the native
        engine); the result then has `sensitivities`, (k, 2n, len(t))
    A model with impacts or frictions (`model.impact`, `model.friction`) runs as a hybrid solve
    (`lagrgen.hybrid`, the guide's "Impacts, contact and dry friction"): its result also has
    `transitions` [(t, name, kind)], `mode` and `n_segments`; options `rest_velocity`,
    `gap_tol`, `max_transitions`; no dense_output.
    **options : passed to `solve_ivp` unchanged (max_step, first_step, min_step, jac_sparsity,
        lband, uband); any other keyword is a TypeError

    Returns
    -------
    SciPy's OdeResult (a `SimulationResult`), with also `coordinates` (names), `q` and `qd`
    (views of the rows of `y`), `engine`, `params` and `inputs` (the values used; see
    `evaluate_outputs`) and `guard` (None, or why the guard stopped the integration).
    A constrained model's result also has `constraint_forces` (λ, n_constraints × len(t), with
    M·q̈ = F + Aᵀλ) and `constraint_residuals` (Φ then A·q̇ + b, (n_holonomic + n_constraints) ×
    len(t)), `constraint_names` and `multipliers` ({name: λ row}, the reaction asked for by
    the constraint's name). A model with impacts or frictions also has `contact_names` and
    `contact_forces` (each impact's contact force, 0 while open, then each friction's force along
    its slip velocity: the sticking force, or −μ·N·sign(v) while slipping), which
    `multipliers` holds by name too. Its initial state should satisfy the constraints (see
    `lagrgen.consistent_state`; Baumgarte stabilization pulls a small violation back, and one
    above 1e-6 of the state's size warns ConstraintWarning).

    Raises
    ------
    NonFiniteError when the derivative becomes NaN or infinite (naming t and the state),
    MassMatrixError when M is not positive definite, ConstraintError when the constraints are
    redundant at the initial state or become dependent during the run.
    """
    check_run_options(method, engine, options)
    t_span = time_span(t_span)
    rtol, atol, t_eval, max_steps, max_wall_time, options = checked_options(
        rtol, atol, t_span, t_eval, max_steps, max_wall_time, options)
    refuse_switching_options(mod, options)
    y0 = state_vector(mod.initial_state if y0 is None else y0, tuple(mod.coordinates))
    check_quaternion(mod.coordinates, y0)
    p = parameters_from(mod, params)
    u_at = input_function(mod, inputs)
    if sensitivities is not None:
        if is_hybrid(mod):
            check_within_stops(mod, np.reshape(y0, (-1, 1)))
        return finished_result(mod, run_sensitivities(mod, t_span, y0, method, p, u_at, rtol,
                                                      atol, sensitivities, events, max_steps,
                                                      max_wall_time, inputs=inputs, engine=engine,
                                                      t_eval=t_eval, dense_output=dense_output,
                                                      **options),
                               p, u_at, method)
    if is_hybrid(mod):
        from .hybrid import simulate_nonsmooth
        mod.pivot_record()
        sol = simulate_nonsmooth(mod, t_span, y0, method, p, inputs, u_at, rtol, atol, t_eval,
                                 dense_output, events, engine, progress, options, max_steps,
                                 max_wall_time)
        return finished_result(mod, sol, p, u_at, method)
    why_not = None if engine == "scipy" else native_reason(mod, method, inputs, events, options,
                                                            rtol)
    if engine == "native" and why_not:
        raise ValueError(f"the native engine cannot run this solve: {why_not}")
    if mod.n_constraints:
        from .constraints import check_state, warn_off_constraints
        check_state(mod, t_span[0], y0, p, u_at(t_span[0]))
        warn_off_constraints(mod, t_span[0], y0, p, u_at(t_span[0]))
    bar = ProgressBar(*t_span, show=progress) if progress else None
    run = dict(t_eval=t_eval, dense_output=dense_output, max_steps=max_steps,
               max_wall_time=max_wall_time, progress=bar, **options)
    mod.pivot_record()                   # the record of this thread starts with the solve
    try:
        if engine != "scipy" and why_not is None:
            sol = simulate_native(mod, t_span, y0, method, p, inputs, u_at, rtol, atol, **run)
        else:
            sol = solve_scipy(mod, t_span, y0, method, p, u_at, rtol, atol, events=events, **run)
            if engine is None and why_not and "Python callable" in why_not:
                sol.message = f"{sol.message} (SciPy engine: {why_not})"
        if bar is not None and len(sol.t):
            bar(sol.t[-1])
    finally:
        if bar is not None:
            bar.close()
    warn_near_singular(mod, mod.pivot_record(), rtol)
    return finished_result(mod, sol, p, u_at, method)


#: The keyword options a SciPy solver takes (`solve_ivp`'s and its methods'): simulate passes
#: them on; a solver class given as `method` may take others.
SOLVER_OPTIONS = ("first_step", "max_step", "min_step", "jac_sparsity", "lband", "uband")
#: What a keyword no solver takes likely meant: another argument, or nothing.
MEANT = {**{k: f"give it as {v}=..." for k, v in (
    ("u", "inputs"), ("p", "params"), ("parameters", "params"), ("x0", "y0"), ("q0", "y0"),
    ("t_end", "t_span"), ("tspan", "t_span"), ("solver", "method"))},
    "vectorized": "the model's rhs takes one state at a time: leave it out"}


def check_run_options(method, engine, options, caller="simulate", own=()):
    """TypeError/ValueError for arguments no engine takes, before any work is done (the numeric
    options: `lagrgen.options.check_run_options`); `own` the caller's keyword options besides
    the solvers' (a keyword no solver takes was passed to SciPy, which only warned, and a
    mistyped u= left the inputs at 0)."""
    if "args" in options:
        raise TypeError(f"{caller}() takes no 'args': pass parameters as params={{name: value}} "
                        "(or a full parameter array) and inputs as inputs={name: value or f(t)}")
    if not isinstance(method, type):
        known = set(SOLVER_OPTIONS) | set(SWITCHING_OPTIONS) | set(own)
        for name in options:
            if name not in known:
                raise TypeError(f"{caller}() got an unexpected keyword argument {name!r}: "
                                + _meant(name, known))
    if not (method in METHODS or isinstance(method, type)):
        raise ValueError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")
    if engine not in ENGINES:
        raise ValueError(f"engine must be None, 'native' or 'scipy', not {engine!r}")


def _meant(name, known):
    """What a keyword no solver takes was likely meant as: `MEANT`'s hint, else the closest of
    the solvers' options and simulate's own arguments."""
    import difflib
    import inspect
    if name in MEANT:
        return MEANT[name]
    own = [a for a in inspect.signature(simulate).parameters if a not in ("mod", "options")]
    close = difflib.get_close_matches(name, sorted(known) + own, n=1)
    return (f"did you mean {close[0]!r}?" if close else
            "the options passed on to the solver are " + ", ".join(SOLVER_OPTIONS))


def refuse_switching_options(mod, options):
    """ValueError for rest_velocity, gap_tol or max_transitions given for a smooth model."""
    given = [k for k in SWITCHING_OPTIONS if k in options]
    if given and not is_hybrid(mod):
        raise ValueError(f"{given[0]} applies to a model with impacts or frictions "
                         "(model.impact, model.friction); this model has none")


def run_sensitivities(mod, t_span, y0, method, p, u_at, rtol, atol, names, events, max_steps,
                      max_wall_time, **options):
    """`simulate` with forward sensitivities (see `lagrgen.sensitivity`)."""
    from .sensitivity import checked_names, solve_sensitivities
    checked_names(mod, names, events)
    if mod.n_constraints:
        from .constraints import check_state
        check_state(mod, t_span[0], y0, p, u_at(t_span[0]))
    return solve_sensitivities(mod, t_span, y0, method, p, u_at, rtol, atol, names,
                               max_steps=max_steps, max_wall_time=max_wall_time, **options)


def time_span(t_span):
    """(t0, t1) as two finite floats; ValueError saying what a time span is otherwise."""
    try:
        t0, t1 = (float(t) for t in t_span)
    except (TypeError, ValueError):
        raise ValueError(f"t_span must be two numbers (t0, t1), got {t_span!r}") from None
    if not (np.isfinite(t0) and np.isfinite(t1)):
        raise ValueError(f"t_span must be finite, got ({t0}, {t1})")
    return t0, t1


def finished_result(mod, sol, p, u_at, method=None):
    """The solver's OdeResult as the SimulationResult of `simulate`: names, the values used,
    event names and, for a constrained model, its multipliers and residuals along the run."""
    sol.params = p
    sol.inputs = u_at
    sol = with_coordinates(sol, mod.coordinates, mod.n_coordinates, mod.name)
    sol.__dict__["_units"] = dict(mod.units)
    sol.__dict__.update(_built=mod, _method=getattr(method, "__name__", method))   # for display
    if mod.event_definitions:
        sol.event_names = tuple(name for name, _, _ in mod.event_definitions)
    if mod.n_constraints:
        from .constraints import along
        hybrid = is_hybrid(mod)
        sol.constraint_forces, sol.constraint_residuals = along(mod, sol, p, u_at, not hybrid)
        if hybrid:                         # with the contacts held: the hybrid solve's λ
            sol.constraint_forces = sol.hybrid_constraint_forces
        sol.constraint_names = tuple(mod.constraint_names)
        sol.multipliers = dict(zip(sol.constraint_names, sol.constraint_forces))
    if is_hybrid(mod) and "contact_names" not in sol:     # a smooth run with sensitivities
        check_within_stops(mod, sol.y)
    elif is_hybrid(mod):
        sol.multipliers = {**(sol.multipliers if mod.n_constraints else {}),
                           **dict(zip(sol.contact_names, sol.contact_forces))}
    return sol


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
    return Outputs(out, tuple(mod.output_names) + POWER_TERMS, mod.units)


def output_event(mod, name, params=None, inputs=None, terminal=False, direction=0):
    """A solve_ivp event function whose root is where the output `name` crosses zero.

    Declare a switching surface (a slip velocity, a gap) as an output and pass this as
    ``simulate(..., events=[...])``: the solver then locates the switch instead of stepping over it.
    """
    names = tuple(mod.output_names)
    if name not in names:
        raise unknown_name("output", name, names)
    k = names.index(name)
    p = parameters_from(mod, params)
    u_at = input_function(mod, inputs)
    outputs = mod.outputs

    def event(t, y):
        return outputs(t, y, p, u_at(t))[k]
    event.terminal, event.direction = terminal, direction
    return event
