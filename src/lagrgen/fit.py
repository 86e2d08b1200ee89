"""Identification: parameters (and initial states) from measured responses, and model updating
from measured natural frequencies.

`fit` minimizes Σ (w·(y_model(t_i; θ) − data_i))² with `scipy.optimize.least_squares`, its
Jacobian the forward sensitivities ∂y/∂θ (`lagrgen.sensitivity`) — one simulation per iteration
instead of 2k for finite differences; the covariance of the estimates is s²·(JᵀJ)⁻¹ with
s² = Σr²/(m − rank J). A direction of the parameters that the Jacobian does not see (its singular
value, columns scaled to unit norm, below the Jacobian's own accuracy) gets an infinite variance
and an `IdentifiabilityWarning` (a `FitWarning`) naming it, never the zero variance of a
pseudo-inverse; an estimate on its bound is flagged (`lagrgen.identifiability`). `fit_modes`
matches natural frequencies with the eigenvalue sensitivities
∂λ/∂p = φᵀ(∂K/∂p − λ·∂M/∂p)φ of mass-normalized modes φ (λ = ω²).
"""
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .errors import LagrgenError
from .identifiability import (FitWarning, covariance, on_bounds, unseen_directions,  # noqa: F401
                              warn_unseen)
from .runtime.arguments import key_name, key_names, parameters_from, state_vector, \
    unknown_name
from .sensitivity import sensitivity_columns
from .simulate import simulate
from .vibration import UnstableModeWarning, equilibrium, linearize, modes


@dataclass
class FitResult:
    """Estimates of a least-squares fit.

    Attributes
    ----------
    params, stderr : dict name -> value, and its standard error
    cov : (k, k) covariance of the estimates, in the order of `names`
    names : the fitted names (parameters, `y0:<state>`)
    success, cost, nfev, message : as scipy.optimize.least_squares reports them (cost = ½Σr²)
    residuals : the weighted residuals at the estimates, shaped like the data
    unidentified : the names the data do not determine (infinite standard error)
    unseen : the unseen directions δθ, each a dict name -> component (largest 1)
    at_bounds : the names whose estimate sits on one of its bounds (its standard error assumes
        it is free)
    """
    params: dict
    stderr: dict
    cov: np.ndarray
    names: tuple
    success: bool
    cost: float
    nfev: int
    message: str
    residuals: np.ndarray = field(repr=False)
    unidentified: tuple = ()
    unseen: list = field(default_factory=list, repr=False)
    at_bounds: tuple = ()


def measured_rows(mod, measured):
    """[(kind, index)] of the measured names: ("y", i) for a coordinate or `<coordinate>_dot`,
    ("output", k) for an output."""
    states = list(mod.coordinates) + [f"{c}_dot" for c in mod.coordinates]
    names = list(mod.coordinates) if measured is None else key_names(measured)
    rows = []
    for name in names:
        if name in states:
            rows.append(("y", states.index(name)))
        elif name in mod.output_names:
            rows.append(("output", list(mod.output_names).index(name)))
        else:
            raise unknown_name("measured", name, tuple(states) + tuple(mod.output_names))
    return names, rows


def _as_data(data, n_rows, n_times):
    data = np.asarray(data, dtype=float)
    if data.ndim == 1 and n_rows == 1:
        data = data[None, :]
    if data.shape != (n_rows, n_times):
        raise ValueError(f"data must have shape (len(measured), len(t)) = ({n_rows}, {n_times}), "
                         f"got {data.shape}")
    if not np.all(np.isfinite(data)):
        raise ValueError("data must be finite (drop or interpolate missing samples)")
    return data


def _weights(weights, shape):
    if weights is None:
        return np.ones(shape)
    w = np.asarray(weights, dtype=float)
    if w.ndim == 1 and w.size == shape[0]:
        w = w[:, None]
    try:
        w = np.broadcast_to(w, shape).copy()
    except ValueError:
        raise ValueError(f"weights must be a number, one per measured name, or of the data's "
                         f"shape {shape}, got shape {w.shape}") from None
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weights must be finite and non-negative")
    if not np.any(w):
        raise ValueError("every weight is zero: no sample is fitted (give positive weights to "
                         "the samples that count)")
    return w


def distinct_names(names, what="params"):
    """`names` as a list of distinct names; ValueError naming a repeated one."""
    names = key_names(names)
    seen = set()
    for name in names:
        if name in seen:
            raise ValueError(f"{what} names {name!r} twice: each fitted name once")
        seen.add(name)
    return names


def sample_times(t):
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("t must be a 1-D array of at least two finite, increasing sample times")
    return t


def _output_derivatives(mod, t, y, p, u, k, columns, h=1e-7):
    """(∂o_k/∂y, [∂o_k/∂θ_c]) of the output k at one point, by central differences."""
    def out(yy, pp):
        return mod.outputs(t, yy, pp, u)[k]
    dy = np.zeros(len(y))
    for i in range(len(y)):
        e = np.zeros(len(y))
        e[i] = h * max(1.0, abs(y[i]))
        dy[i] = (out(y + e, p) - out(y - e, p)) / (2 * e[i])
    dp = []
    for kind, j in columns:
        if kind != "p":
            dp.append(0.0)
            continue
        e = np.zeros(len(p))
        e[j] = h * parameter_scale(p[j])
        dp.append((out(y, p + e) - out(y, p - e)) / (2 * e[j]))
    return dy, np.array(dp)


def fit(mod, t, data, params, y0, measured=None, initial=None, bounds=None, weights=None,
        method="Radau", p=None, **simulate_options):
    """Least-squares estimates of the parameters `params` (and initial states `y0:<state>`)
    from samples `data` of the measured coordinates, velocities or outputs at times `t`.

    Parameters
    ----------
    mod : a built model (either backend)
    t : (m,) increasing sample times; the simulation starts at t[0] from `y0`
    data : (len(measured), m) samples
    params : names to fit: parameters, or `y0:<state>` for an initial state
    y0 : the initial state (array of 2n or dict); fitted entries start from it
    measured : the measured names (coordinates, `<coordinate>_dot`, outputs); None: all
        coordinates
    initial : dict name -> start value (default: the model's defaults, y0)
    bounds : dict name -> (low, high)
    weights : a number, one per measured name, or an array of the data's shape
    method, **simulate_options : passed to `lagrgen.simulate` (rtol, atol, inputs, ...)
    p : the values of the parameters that are not fitted (a dict by name or Symbol, or a full
        vector; default the model's defaults)

    Returns
    -------
    FitResult (params, stderr, cov, success, cost, nfev, residuals)
    """
    names = distinct_names(params)
    columns = sensitivity_columns(mod, names)
    t = sample_times(t)
    measured_names, rows = measured_rows(mod, measured)
    data = _as_data(data, len(rows), t.size)
    w = _weights(weights, data.shape)
    base_p = parameters_from(mod, p)
    base_y0 = state_vector(y0, tuple(mod.coordinates))
    theta0, low, high = _start_and_bounds(mod, names, columns, base_p, base_y0, initial, bounds)
    cache = {}

    def evaluate(theta):
        key = theta.tobytes()
        if key not in cache:
            cache.clear()
            p, y_start = _apply(theta, columns, base_p, base_y0)
            try:
                sol = simulate(mod, (t[0], t[-1]), y_start, method=method, params=p, t_eval=t,
                               sensitivities=names, **simulate_options)
            except LagrgenError as error:
                raise type(error)(f"{at_trial(names, theta)}: {error}") from None
            if not sol.success:
                raise LagrgenError(f"{at_trial(names, theta)}: {sol.message}")
            cache[key] = _model_rows(mod, sol, rows, p, columns)
        return cache[key]

    def residuals(theta):
        return (w * (evaluate(theta)[0] - data)).ravel()

    def jacobian(theta):
        return (w[:, :, None] * evaluate(theta)[1]).reshape(-1, len(names))

    result = scaled_least_squares(residuals, jacobian, theta0, low, high,
                                  residual_scale(w * data))
    J = result.jac[w.ravel() != 0]
    accuracy = float(np.max(simulate_options.get("rtol", 1e-6)))
    rank = unseen_directions(J, names, accuracy)[0]
    dof = J.shape[0] - rank
    s2 = 2 * result.cost / dof if dof > 0 else np.nan
    cov, unidentified, directions = covariance(J, s2, names, accuracy)
    if directions:
        warn_unseen(directions, rank, len(names))
    if dof <= 0:
        warnings.warn(f"{J.shape[0]} weighted samples for {rank} determined names leave no "
                      "residual to estimate the noise: the standard errors are NaN",
                      FitWarning, stacklevel=2)
    stderr = np.sqrt(np.diag(cov))
    return FitResult(params=dict(zip(names, map(float, result.x))),
                     stderr=dict(zip(names, map(float, stderr))), cov=cov, names=tuple(names),
                     success=bool(result.success), cost=float(result.cost),
                     nfev=int(result.nfev), message=str(result.message),
                     residuals=result.fun.reshape(data.shape), unidentified=unidentified,
                     unseen=directions, at_bounds=on_bounds(result.x, low, high, names))


def at_trial(names, theta):
    """What a failure at a trial point of the fit says first: where, and what to do."""
    values = ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, theta))
    return (f"the simulation failed at the trial point {values} (bound the fitted names to "
            "where the model is valid with bounds={name: (low, high)})")


def _by_name(given, what):
    """fit's `initial` or `bounds`, a dict keyed by name or Symbol, keyed by name."""
    if given is None:
        return {}
    if not isinstance(given, dict):
        entry = "start value" if what == "initial" else "(low, high)"
        raise TypeError(f"{what} must be a dict of the fitted names (or Symbols) to their "
                        f"{entry}, got {type(given).__name__}")
    return {key_name(key): value for key, value in given.items()}


def _start_and_bounds(mod, names, columns, p, y0, initial, bounds):
    initial, bounds = (_by_name(given, what) for given, what in ((initial, "initial"),
                                                                 (bounds, "bounds")))
    for given, what in ((initial, "initial"), (bounds, "bounds")):
        unknown = [k for k in given if k not in names]
        if unknown:
            raise unknown_name(f"{what} (fitted)", unknown[0], tuple(names))
    theta0 = np.array([initial.get(name, p[j] if kind == "p" else y0[j])
                       for name, (kind, j) in zip(names, columns)], dtype=float)
    pairs = [bound_pair(name, bounds.get(name)) for name in names]
    low = np.array([pair[0] for pair in pairs], dtype=float)
    high = np.array([pair[1] for pair in pairs], dtype=float)
    if np.any(~np.isfinite(theta0)):
        raise ValueError("every fitted name needs a finite start value (give initial={...})")
    if np.any(low >= high) or np.any(theta0 < low) or np.any(theta0 > high):
        raise ValueError("bounds must satisfy low < high and hold the start values")
    return theta0, low, high


def bound_pair(name, given):
    """(low, high) of a fitted name from its `bounds` entry: a pair whose None side is open
    (±inf); no entry: (−inf, inf)."""
    if given is None:
        return -np.inf, np.inf
    try:
        low, high = given
    except (TypeError, ValueError):
        raise ValueError(f"bounds[{name!r}] must be a pair (low, high), None for an open side; "
                         f"got {given!r}") from None
    return (-np.inf if low is None else float(low)), (np.inf if high is None else float(high))


def _apply(theta, columns, p, y0):
    p, y0 = p.copy(), y0.copy()
    for value, (kind, j) in zip(theta, columns):
        (p if kind == "p" else y0)[j] = value
    return p, y0


def _model_rows(mod, sol, rows, p, columns):
    """(values (rows, m), derivatives (rows, m, k)) of the measured rows along a solution."""
    values = np.empty((len(rows), sol.t.size))
    derivs = np.empty((len(rows), sol.t.size, len(columns)))
    for r, (kind, i) in enumerate(rows):
        if kind == "y":
            values[r] = sol.y[i]
            derivs[r] = sol.sensitivities[:, i, :].T
            continue
        for m, ti in enumerate(sol.t):
            y = np.ascontiguousarray(sol.y[:, m])
            u = sol.inputs(ti)
            values[r, m] = mod.outputs(ti, y, p, u)[i]
            dy, dp = _output_derivatives(mod, ti, y, p, u, i, columns)
            derivs[r, m] = sol.sensitivities[:, :, m] @ dy + dp
    return values, derivs


@dataclass
class ModalUpdate:
    """Parameters updated to match measured natural frequencies.

    Attributes
    ----------
    params : dict name -> value
    frequencies_hz : the model's natural frequencies at the estimates, paired with the measured
    pairing : the model mode index paired with each measured frequency
    success, cost, nfev : as scipy.optimize.least_squares reports them
    unidentified, unseen, at_bounds : as for `FitResult`: the names the frequencies do not
        determine, the directions they do not see, the estimates on their bounds
    """
    params: dict
    frequencies_hz: np.ndarray
    pairing: tuple
    success: bool
    cost: float
    nfev: int
    unidentified: tuple = ()
    unseen: list = field(default_factory=list, repr=False)
    at_bounds: tuple = ()


def fit_modes(mod, q0, measured_hz, params, initial=None, bounds=None, shapes=None, p=None,
              h=1e-6):
    """Update `params` so that the natural frequencies of the linearization about `q0` match
    `measured_hz` (relative residuals), with the analytic eigenvalue sensitivities
    ∂λ/∂p = φᵀ(∂K/∂p − λ·∂M/∂p)φ (∂K/∂p and ∂M/∂p by central differences of the linearization).
    Measured mode k is paired with the model mode of largest MAC with `shapes[:, k]` when given,
    else with the k-th lowest elastic mode (rigid-body modes, at 0 Hz, left out).

    Returns
    -------
    ModalUpdate (params, frequencies_hz, pairing, success, cost, nfev)
    """
    names = distinct_names(params)
    for name in names:
        if name not in mod.parameters:
            raise unknown_name("parameter", name, tuple(mod.parameters))
    target = np.atleast_1d(np.asarray(measured_hz, dtype=float))
    n = mod.n_coordinates
    if target.ndim != 1 or not 0 < target.size <= n or not np.all(np.isfinite(target)) \
            or np.any(target <= 0):
        raise ValueError(f"measured_hz must be 1 to {n} finite positive frequencies, got "
                         f"{np.array2string(target, precision=6)}")
    if shapes is None and np.any(np.diff(target) < 0):
        raise ValueError(f"measured_hz {np.array2string(target, precision=6)} are paired with "
                         "the model's modes in order, the lowest first: give them in ascending "
                         "order (or give shapes, to pair them by their mode shapes)")
    if shapes is not None:
        shapes = np.asarray(shapes, dtype=float).reshape(n, -1)
        if shapes.shape[1] != target.size:
            raise ValueError("shapes must have one column (of n entries) per measured frequency")
    base = parameters_from(mod, p)
    index = [list(mod.parameters).index(name) for name in names]
    theta0, low, high = _start_and_bounds(mod, names, [("p", j) for j in index], base,
                                          np.zeros(2 * n), initial, bounds)

    def with_theta(theta):
        out = base.copy()
        out[index] = theta
        return out
    dependent = None
    if mod.n_constraints:
        first = linearize(mod, equilibrium(mod, q0, p=with_theta(theta0)), p=with_theta(theta0))
        dependent = [name for name in first.model_coordinates
                     + tuple(f"{c}_dot" for c in first.model_coordinates)
                     if name not in first.states]

    def linearized(p_vector):
        """The linearization at these parameters, about q0 (a constrained model: about its
        equilibrium near q0, which moves with them), in the same independent coordinates."""
        q = equilibrium(mod, q0, p=p_vector) if mod.n_constraints else q0
        return linearize(mod, q, p=p_vector, dependent=dependent)

    def eigen(theta, trial=True):
        with warnings.catch_warnings():
            if trial:                       # a trial point may be unstable; the answer warns
                warnings.simplefilter("ignore", UnstableModeWarning)
            res = modes(linearized(with_theta(theta)))
        if res.kind != "classical":
            raise LagrgenError(
                f"fit_modes needs the classical modes of a second-order form with symmetric C; "
                f"the linearization of model {mod.name!r} here has none (velocity constraints "
                "or gyroscopic terms): fit its eigenvalues with lagrgen.fit on responses instead")
        order = _pairing(res.shapes, shapes, target.size, res.frequencies_hz)
        return res, order

    def residuals(theta):
        res, order = eigen(theta)
        return res.frequencies_hz[list(order)] / target - 1.0

    def jacobian(theta):
        res, order = eigen(theta)
        lam = res.omega ** 2
        J = np.empty((target.size, len(names)))
        for c, j in enumerate(index):
            step = h * parameter_scale(theta[c])
            plus, minus = with_theta(theta), with_theta(theta)
            plus[j] += step
            minus[j] -= step
            up, down = linearized(plus), linearized(minus)
            dK, dM = (up.K - down.K) / (2 * step), (up.M - down.M) / (2 * step)
            for r, mode in enumerate(order):
                phi = res.independent_shapes[:, mode]
                dlam = phi @ (dK - lam[mode] * dM) @ phi
                J[r, c] = dlam / (4 * np.pi * res.omega[mode]) / target[r]
        return J

    result = scaled_least_squares(residuals, jacobian, theta0, low, high, 1.0)
    res, order = eigen(result.x, trial=False)
    rank, directions = unseen_directions(result.jac, names, h)[:2]
    if directions:
        warn_unseen(directions, rank, len(names), "their estimates are one point of a family "
                     "that matches the frequencies as well")
    unidentified = tuple(n for n in names if any(n in d for d in directions))
    shared = shared_pairs(order)
    if shared:
        warnings.warn(f"measured modes {shared} are paired with the same model mode (by their "
                      "shapes' MAC): one model frequency cannot match both; give shapes that "
                      "tell those modes apart", FitWarning, stacklevel=2)
    return ModalUpdate(params=dict(zip(names, map(float, result.x))),
                       frequencies_hz=res.frequencies_hz[list(order)], pairing=tuple(order),
                       success=bool(result.success) and not shared, cost=float(result.cost),
                       nfev=int(result.nfev), unidentified=unidentified, unseen=directions,
                       at_bounds=on_bounds(result.x, low, high, names))


def parameter_scale(value):
    """The size of a parameter for its difference steps and its scaling: abs(value), or 1 at 0
    (a stiffness of 6e7 N/m and a compliance of 2e-8 m/N alike)."""
    return abs(value) if value != 0 else 1.0


def residual_scale(weighted_data):
    """The root mean square of the weighted data (1 where it is 0 or missing): the unit of the
    residuals the solver sees."""
    finite = weighted_data[np.isfinite(weighted_data)]
    rms = float(np.sqrt(np.mean(finite ** 2))) if finite.size else 0.0
    return rms if rms > 0 else 1.0


def scaled_least_squares(residuals, jacobian, theta0, low, high, unit):
    """`scipy.optimize.least_squares` on θ = s·x (s = `parameter_scale` of each start value) and
    residuals r/unit, so that its absolute tolerances (gtol on the gradient Jᵀr) mean the same for
    a stiffness of 6e7 N/m fitted to micrometres as for one of 40 N/m fitted to centimetres (in SI
    units the gradient was below gtol at the start: the fit returned its start, with success).
    Returns the solver's result in θ and the model's units: x, fun, jac, cost, and its status
    (fun, jac and cost scaled back, not evaluated again)."""
    s = np.array([parameter_scale(v) for v in theta0])
    result = least_squares(lambda x: residuals(s * x) / unit,
                           theta0 / s, jac=lambda x: jacobian(s * x) * s / unit,
                           bounds=(low / s, high / s), x_scale="jac")
    result.x = s * result.x
    result.fun = result.fun * unit
    result.jac = result.jac * unit / s
    result.cost = result.cost * unit ** 2
    return result


def _pairing(model_shapes, measured_shapes, k, frequencies):
    """The model mode paired with each measured mode: largest MAC, or the k lowest elastic
    modes in order (a free-free structure's rigid-body modes, at 0 Hz, are not measured
    natural frequencies)."""
    if measured_shapes is None:
        frequencies = np.asarray(frequencies, dtype=float)
        top = np.max(frequencies[np.isfinite(frequencies)], initial=0.0)
        elastic = [i for i, f in enumerate(frequencies) if not (np.isfinite(f)
                                                                and f <= RIGID * top)]
        if len(elastic) < k:
            raise LagrgenError(f"the model has {len(elastic)} elastic modes (above "
                               f"{RIGID:g} of its highest frequency) for {k} measured "
                               "frequencies: measure fewer, or give shapes to pair them")
        return tuple(elastic[:k])
    num = (measured_shapes.T @ model_shapes) ** 2
    den = np.outer((measured_shapes ** 2).sum(0), (model_shapes ** 2).sum(0))
    return tuple(int(i) for i in np.argmax(num / den, axis=1))


def shared_pairs(order):
    """The measured modes (numbered from 0, as a text) paired with a model mode another one is
    paired with too; '' when every pairing is its own."""
    shared = [k for k, mode in enumerate(order) if list(order).count(mode) > 1]
    return " and ".join(map(str, shared))


#: A mode below this fraction of the highest frequency counts as a rigid-body mode (`_pairing`).
RIGID = 1e-6
