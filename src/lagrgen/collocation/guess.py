"""Starting points of a collocation problem: the default start (a smooth motion between the
instance values with the inputs it needs, or the model's own motion), an earlier result (a warm
start on any grid), a simulation, or named values.

The default start was chosen on the problems of the guide, the examples and
benchmarks/collocation.py. Straight lines between the end values with the inputs at rest (what
opty and this package used to start from) leave every residual violated; on opty's swing-up
(|T| ≤ 2 N·m, 501 nodes, backward Euler) IPOPT stops at a local infeasibility, objective 39.9.
A cubic between the end states (end rates as given, else the chord's slope) satisfies the defects
of every scheme to its order, and the inputs that make it a motion of the model (least squares of
the residual at each point, with the multipliers of a constrained model) satisfy the residual
wherever the inputs can; on the benchmark's chain of 10 links (51 nodes) it reaches a lower
optimum than the straight lines (1186 against 1305). When those inputs exceed their bounds the
motion is one the inputs cannot produce, and IPOPT stalls far from feasible (the swing-up: 37.8);
the model's own motion from the initial state, the inputs held at their middle (or 0), is then a
motion that satisfies everything but the final values — on the swing-up the pendulum at rest,
from which IPOPT finds opty's optimum 15.641554 in 55 iterations. An identification starts the
coordinates its data sample on the data.
"""
import warnings
from types import SimpleNamespace

import numpy as np

from ..errors import LagrgenError
from ..runtime.arguments import key_name
from .grid import KINDS, interpolate_rows


def initial_guess(problem, tr, guess, shift=0.0):
    """The decision vector to start from (see `Collocation.solve`); an earlier result shifted by
    `shift` seconds (its first `shift` dropped, its end held: `Collocation.resolve`)."""
    from .result import CollocationResult
    L = tr.layout
    if guess is None:
        return default_guess(problem, tr)
    if isinstance(guess, CollocationResult):
        return on_controls(tr, from_result(problem, tr, guess, shift))
    if hasattr(guess, "t") and hasattr(guess, "y"):    # a simulation (an OdeResult is a dict)
        return from_simulation(problem, tr, guess)
    if isinstance(guess, dict):
        return from_values(problem, tr, guess)
    x = np.asarray(guess, dtype=float)
    if x.shape != (L.size,):
        raise LagrgenError(f"guess: a decision vector has {L.size} entries, got shape {x.shape}; "
                           "or pass a CollocationResult, a simulation result or a dict of names")
    if not np.all(np.isfinite(x)):
        raise LagrgenError("guess: the decision vector must be finite")
    return x


def _start_value(lo, hi):
    if np.isfinite(lo) and np.isfinite(hi):
        return 0.5 * (lo + hi)
    if np.isfinite(lo):
        return max(lo, 0.0)
    if np.isfinite(hi):
        return min(hi, 0.0)
    return 0.0


def _duration_guess(problem):
    lo, hi = problem.duration_bounds
    return 0.5 * (lo + hi) if problem.free_duration else lo


def base_guess(problem, tr):
    """Each variable linear between its initial and final instance values (constant when one is
    given, the middle of its bounds or 0 when none), except that a coordinate's rate follows its
    coordinate's line between the ends; parameters at their current values."""
    L = tr.layout
    x = np.zeros(L.size)
    Z = L.point_block(x)
    tau = L.fractions
    T = _duration_guess(problem)
    slopes = {}
    for kind in KINDS:
        for i in range(_count(L, kind)):
            col = L.offset(kind) + i
            a, b = _ends(problem, kind, i)
            if kind == "qd" and i in slopes:
                Z[:, col] = slopes[i]
            elif a is None and b is None:
                Z[:, col] = _start_value(tr.lo[col], tr.hi[col])
            else:
                a = b if a is None else a
                b = a if b is None else b
                Z[:, col] = a + (b - a) * tau
                if kind == "q":
                    slopes[i] = (b - a) / T
    for k, j in enumerate(L.unknown):
        value = problem.params[j]
        if not np.isfinite(value):
            value = _start_value(tr.lo[L.p_start + k], tr.hi[L.p_start + k]) or 1.0
        x[L.p_start + k] = value
    if L.free:
        x[L.T_index] = T / L.T_scale
    return np.clip(x, tr.lo, tr.hi)


def default_guess(problem, tr):
    """The start when none is given (see the module): the smooth motion between the end values
    with the inputs it needs, unless those exceed the inputs' bounds; then the model's own
    motion from the initial state (if the initial state is given in full)."""
    x, needed = smooth_motion(problem, tr)
    if not needed:
        return x
    natural = natural_motion(problem, tr)
    return x if natural is None else natural


def smooth_motion(problem, tr):
    """(x, whether the inputs it needs exceed their bounds): each coordinate with end values on
    the cubic through them (end rates as given, else the chord's slope), a coordinate a track
    samples on its data (linear between samples), rates and accelerations those of these
    curves; then the free inputs and the multipliers that make it a motion of the model
    (`needed_inputs`)."""
    L = tr.layout
    x = base_guess(problem, tr)
    Z = L.point_block(x)
    T = L.duration(x) if L.free else problem.duration_bounds[0]
    tracked = _tracked_coordinates(problem, T * L.fractions)
    for i in range(L.n):
        path = _cubic(problem, i, T, L.fractions)
        if i in tracked:
            path = _derivatives(tracked[i], T * L.fractions)
        if path is not None:
            for kind, values in zip(("q", "qd", "qdd"), path):
                Z[:, L.offset(kind) + i] = values
    return needed_inputs(problem, tr, np.clip(x, tr.lo, tr.hi), T)


def needed_inputs(problem, tr, x, T, points=None):
    """(x with its free inputs and multipliers those of least squares on the residual at each
    point (of `points`, default all), clipped to their bounds; whether the least-squares values
    exceed the bounds)."""
    L, mod = tr.layout, problem.mod
    Z = L.point_block(x)
    free = [L.offset("lam") + k for k in range(L.m)] + \
        [L.offset("u") + k for k in range(L.nu) if k not in problem._given]
    if not free:
        return x, False
    times = tr.point_times(T)
    p = tr._state(x)[1]
    lo, hi = L.point_block(tr.lo), L.point_block(tr.hi)
    exceeded = False
    for j in range(L.points) if points is None else points:
        q, qd, a = Z[j, :L.n], Z[j, L.n:2 * L.n], Z[j, 2 * L.n:3 * L.n + L.m]
        u = Z[j, L.offset("u"):]
        try:
            r, _, dr_da, dr_du = mod.residual_terms(q, qd, a, times[j], p, u if L.nu else None)
        except Exception:     # a point where the model cannot be evaluated: keep the base
            continue
        columns = np.hstack([dr_da[:, L.n:], dr_du])[:, np.subtract(free, L.offset("lam"))]
        step = np.linalg.lstsq(columns, -r, rcond=None)[0]
        wanted = Z[j, free] + step
        band = 1e-6 * np.maximum(1.0, hi[j, free] - lo[j, free])
        exceeded |= bool(np.any((wanted < lo[j, free] - band) | (wanted > hi[j, free] + band)))
        Z[j, free] = np.clip(wanted, lo[j, free], hi[j, free])
    return x, exceeded


def _tracked_coordinates(problem, times):
    """{coordinate: its tracked samples interpolated linearly at `times` (after t0)}."""
    out = {}
    for sample_times, data, rows, _, present, _ in problem._tracks:
        for r, (kind, i) in enumerate(rows):
            keep = present[r]
            if kind == "q" and i not in out and keep.sum() >= 2:
                order = np.argsort(sample_times[keep])
                out[i] = np.interp(times, sample_times[keep][order], data[r, keep][order])
    return out


def _derivatives(values, times):
    """(values, rate, acceleration) of a curve sampled at `times`, by finite differences."""
    rate = np.gradient(values, times)
    return values, rate, np.gradient(rate, times)


def _cubic(problem, i, T, tau):
    """(q, q̇, q̈) at the fractions tau of coordinate i on the cubic between its end values and
    rates, or None when neither end value is given."""
    a, b = _ends(problem, "q", i)
    if a is None and b is None:
        return None
    a = b if a is None else a
    b = a if b is None else b
    va, vb = _ends(problem, "qd", i)
    chord = (b - a) / T
    va, vb = chord if va is None else va, chord if vb is None else vb
    s = tau
    q = (2 * s**3 - 3 * s**2 + 1) * a + (s**3 - 2 * s**2 + s) * T * va \
        + (-2 * s**3 + 3 * s**2) * b + (s**3 - s**2) * T * vb
    qd = (6 * s**2 - 6 * s) * (a - b) / T + (3 * s**2 - 4 * s + 1) * va + (3 * s**2 - 2 * s) * vb
    qdd = (12 * s - 6) * (a - b) / T**2 + ((6 * s - 4) * va + (6 * s - 2) * vb) / T
    return q, qd, qdd


def natural_motion(problem, tr):
    """The model's own motion from the initial state (given in full) over the guessed duration,
    the free inputs at their middle (or 0) and the given ones as given (a simulation, `guess`
    from it); None when the initial state is not given in full or the simulation fails at once."""
    from ..signals import Signal
    from ..simulate import simulate
    L, mod = tr.layout, problem.mod
    y0 = [_ends(problem, kind, i)[0] for kind in ("q", "qd") for i in range(L.n)]
    if any(v is None for v in y0):
        return None
    base = base_guess(problem, tr)
    T = L.duration(base) if L.free else problem.duration_bounds[0]
    if T <= 0:
        return None
    times = tr.point_times(T)
    held = L.point_block(base)[:, L.offset("u"):L.offset("u") + L.nu]
    inputs = {name: Signal(times, held[:, k], kind="linear") if k in problem._given
              else float(held[0, k]) for k, name in enumerate(mod.inputs)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sol = simulate(mod, (times[0], times[-1]), y0, params=tr._state(base)[1],
                           inputs=inputs, t_eval=times, rtol=1e-6, atol=1e-9, max_steps=100_000)
    except Exception:      # a model the simulation cannot start: no natural motion
        return None
    if len(sol.t) < 2:
        return None
    held_last = np.repeat(sol.y[:, -1:], times.size - len(sol.t), axis=1)
    return from_simulation(problem, tr, SimpleNamespace(t=times, y=np.hstack([sol.y, held_last])))


def _ends(problem, kind, i):
    """(initial, final) instance values of variable i of `kind`, None where not given."""
    return problem._fixed.get((0.0, kind, i)), problem._fixed.get((1.0, kind, i))


def _count(L, kind):
    return {"q": L.n, "qd": L.n, "qdd": L.n, "lam": L.m, "u": L.nu}[kind]


def from_result(problem, tr, result, shift=0.0):
    """An earlier result on this grid or another: its point values interpolated (states by their
    Hermite interpolant) at this problem's points (`shift` seconds later, the end held), its
    duration and parameter estimates."""
    L, old = tr.layout, result._layout
    if (old.n, old.m, old.nu) != (L.n, L.m, L.nu):
        raise LagrgenError("guess: the result is of a model with other sizes")
    x = base_guess(problem, tr)
    if old == L and result.x.size == L.size and not shift:
        x = np.array(result.x)
    else:
        Zold = old.point_block(result.x)
        T = result.duration
        if L.free:
            x[L.T_index] = T / L.T_scale
        times = L.fractions * T + shift    # the same fractions of the earlier duration
        Z = L.point_block(x)
        for kind in KINDS:
            rate = {"q": "qd", "qd": "qdd"}.get(kind)
            for i in range(_count(L, kind)):
                values = Zold[:, old.offset(kind) + i]
                rates = Zold[:, old.offset(rate) + i] if rate else None
                Z[:, L.offset(kind) + i] = interpolate_rows(values, old, kind,
                                                            np.minimum(times, T), T, rates)
        beyond = np.flatnonzero(times > T * (1 + 1e-12))
        if beyond.size:
            x = _held_end(problem, tr, x, T, beyond, times[beyond] - T, Zold[-1])
        names = list(problem.mod.parameters)
        for k, j in enumerate(L.unknown):
            if names[j] in result.params:
                x[L.p_start + k] = result.params[names[j]]
    return np.clip(x, tr.lo, tr.hi)


def on_controls(tr, x):
    """x with every tied input's value at the points inside a control interval set to the
    polynomial through the interval's carriers (the transcription's rows `ties`), then clipped
    to the bounds: a refined mesh that ties an input the last mesh left free starts on its ties
    (the Panda's least-time move: 26 N·m off them otherwise)."""
    if not tr.ties:
        return x
    x = np.array(x)
    for cols, coefficients in tr.ties:
        x[cols[0]] = -np.dot(coefficients[1:], x[cols[1:]])
    return np.clip(x, tr.lo, tr.hi)


def _held_end(problem, tr, x, T, points, after, end):
    """x with the `points` that lie `after` seconds past the end of the motion it continues
    (whose last point's variables are `end`) moving on at the end's rates (q̈ = 0: at rest when
    the end is) with the inputs that make that a motion of the model."""
    L = tr.layout
    Z = L.point_block(x)
    n = L.n
    Z[points, :n] = end[:n] + np.outer(after, end[n:2 * n])
    Z[points, n:2 * n] = end[n:2 * n]
    Z[points, 2 * n:3 * n] = 0.0
    return needed_inputs(problem, tr, x, T, points)[0]


def warm_multipliers(tr, guess, shift=0.0):
    """(λ, z) of an earlier result on the same mesh (its constraints' and bounds' multipliers,
    `shift` seconds later: nodes from nodes, midpoints from midpoints, defects from intervals;
    with a shift, the points' residual multipliers 0: their weights on the inverse dynamics'
    second derivatives, carried over to a start whose end is held, took the Panda's re-plans
    by the SQP 8-13 iterations where they take 6 without them), else (None, None)."""
    from .result import CollocationResult
    L = tr.layout
    if not isinstance(guess, CollocationResult) or guess._layout != L \
            or guess._lam.size != tr.n_constraints or guess._z.size != L.size:
        return None, None
    lam, z = np.array(guess._lam), np.array(guess._z)
    if not shift:
        return lam, z
    T = guess.duration
    P, ni = L.points, L.ni
    times = L.fractions * T
    later = np.minimum(times + shift, T)
    zp = z[:L.p_start].reshape(P, L.nz)
    for kind in range(L.stride):           # nodes, then midpoints
        own = np.arange(kind, P, L.stride)
        zp[own] = _interpolated(zp[own], times[own], later[own])
    lam[:P * ni] = 0.0
    z[:L.p_start] = zp.ravel()
    base, per = tr.defect_row, tr.n_defects // (L.nodes - 1)
    middles = 0.5 * (L.node_fractions[:-1] + L.node_fractions[1:]) * T
    rows = lam[base:base + tr.n_defects].reshape(-1, per)
    lam[base:base + tr.n_defects] = _interpolated(
        rows, middles, np.minimum(middles + shift, T)).ravel()
    return lam, z


def refined_multipliers(tr, guess):
    """(λ, z) for the transcription `tr` of a finer mesh from an earlier result `guess` of the
    same fixed duration on a coarser one, else None. Every multiplier there is a density times
    its row's share of the duration (a point's quadrature weight, an interval's length: the
    defects are Δx/h − f, the objective h·Σ w·L): the densities are interpolated in time and
    multiplied by the new shares; rows the coarse mesh lacks (input ties) start at 0."""
    from .grid import quadrature
    from .result import CollocationResult
    L = tr.layout
    if not isinstance(guess, CollocationResult):
        return None
    old = guess._layout
    if L.free or old.free or (old.stride, old.nz, old.ni) != (L.stride, L.nz, L.ni) \
            or guess._lam.size == 0 or guess._z.size != old.size:
        return None
    lam_old, z_old = np.asarray(guess._lam), np.asarray(guess._z)
    per_point = L.ni + tr.n_path
    fixed = tr.n_cons + tr.n_term
    per, bounded = tr.n_defects // (L.nodes - 1), tr.n_envelope // (L.nodes - 1)
    if lam_old.size < old.points * per_point + fixed + (old.nodes - 1) * (per + bounded):
        return None
    lam, z = np.zeros(tr.n_constraints), np.zeros(L.size)
    w_old, w_new = quadrature(old), quadrature(L)
    lam[:L.points * per_point] = _rescaled(
        lam_old[:old.points * per_point].reshape(old.points, per_point), old.fractions, w_old,
        L.fractions, w_new).ravel()
    z_points = np.array(z_old[:old.p_start].reshape(old.points, old.nz))
    pinned = (tr.lo == tr.hi)[:L.p_start].reshape(L.points, L.nz)[[0, -1]]
    ends = np.where(pinned, z_points[[0, -1]], 0.0)     # an end value's multiplier: no density
    z_points[[0, -1]] -= ends
    zp = _rescaled(z_points, old.fractions, w_old, L.fractions, w_new)
    zp[[0, -1]] += ends
    z[:L.p_start] = zp.ravel()
    z[L.p_start:] = z_old[old.p_start:]
    start_old = old.points * per_point
    lam[L.points * per_point:tr.defect_row] = lam_old[start_old:start_old + fixed]
    h_old, h_new = np.diff(old.node_fractions), np.diff(L.node_fractions)
    mid_old = 0.5 * (old.node_fractions[:-1] + old.node_fractions[1:])
    mid_new = 0.5 * (L.node_fractions[:-1] + L.node_fractions[1:])
    d0 = start_old + fixed
    defects = lam_old[d0:d0 + (old.nodes - 1) * per].reshape(-1, per)
    simpson = per if L.stride == 1 else per // 2
    lam[tr.defect_row:tr.defect_row + tr.n_defects] = np.hstack([
        _rescaled(defects[:, :simpson], mid_old, h_old, mid_new, h_new),
        _rescaled(defects[:, simpson:], mid_old, h_old ** 2, mid_new, h_new ** 2)]).ravel()
    if bounded:
        env_old = lam_old[lam_old.size - bounded * (old.nodes - 1):]
        lam[tr.hull_row - tr.n_envelope:tr.hull_row] = _rescaled(
            env_old.reshape(bounded, -1).T, mid_old, h_old, mid_new, h_new).T.ravel()
    return lam, z


def _rescaled(rows, at, share, to, new_share):
    """Rows of multipliers at the times `at`, each a density times its `share`, as the same
    densities at the times `to` (linear between and beyond the times `at`) times `new_share`."""
    density = rows / share[:, None]
    if at.size > 1:
        ends = (to[:1] if to[0] < at[0] else at[:0], to[-1:] if to[-1] > at[-1] else at[:0])
        slopes = ((density[1] - density[0]) / (at[1] - at[0]),
                  (density[-1] - density[-2]) / (at[-1] - at[-2]))
        density = np.vstack([density[0] + (ends[0][:, None] - at[0]) * slopes[0], density,
                             density[-1] + (ends[1][:, None] - at[-1]) * slopes[1]])
        at = np.concatenate([ends[0], at, ends[1]])
    return _interpolated(density, at, to) * new_share[:, None]


def _interpolated(rows, at, to):
    """Rows of values at the times `at`, linearly interpolated at the times `to` (each column
    held at its end values beyond `at`)."""
    return np.array([np.interp(to, at, column) for column in rows.T]).T


def from_simulation(problem, tr, sol):
    """States of a simulation (sol.t, sol.y) interpolated at the points; accelerations and
    multipliers from the model at those states (inputs at their guessed values)."""
    L, mod = tr.layout, problem.mod
    x = base_guess(problem, tr)
    t_sim, y = np.asarray(sol.t, dtype=float), np.asarray(sol.y, dtype=float)
    if y.ndim != 2 or y.shape[0] != 2 * L.n or y.shape[1] != t_sim.size:
        raise LagrgenError(f"guess: a simulation of this model has y of shape (2n, len(t)) = "
                           f"({2 * L.n}, {t_sim.size}), got {y.shape}")
    Z = L.point_block(x)
    times = tr.point_times(L.duration(x) if L.free else problem.duration_bounds[0])
    states = np.array([np.interp(times, t_sim, row) for row in y])
    Z[:, :2 * L.n] = states.T
    p = np.array(problem.params)
    p[list(L.unknown)] = x[L.p_start:L.p_start + len(L.unknown)]
    for j, t in enumerate(times):
        u = Z[j, L.offset("u"):] if L.nu else None
        try:
            Z[j, L.offset("qdd"):L.offset("qdd") + L.n] = mod.rhs(t, states[:, j], p, u)[L.n:]
            if L.m:
                Z[j, L.offset("lam"):L.offset("u")] = mod.constraint_forces(t, states[:, j], p, u)
        except Exception:   # a state the model cannot evaluate (M singular): keep the default
            pass
    return np.clip(x, tr.lo, tr.hi)


def from_values(problem, tr, values):
    """The default guess with the named variables replaced: a number, one value per node or per
    point, or a callable of t; "params" (a dict) and "duration" set those."""
    L = tr.layout
    x = base_guess(problem, tr)
    Z = L.point_block(x)
    values = dict(values)
    if "duration" in values:
        T = float(values.pop("duration"))
        if L.free:
            x[L.T_index] = T / L.T_scale
    for name, value in dict(values.pop("params", {})).items():
        kind, k = problem.variable(key_name(name))
        if kind != "p":
            raise LagrgenError(f"guess['params']: {name!r} is not an unknown parameter")
        x[L.p_start + k] = float(value)
    times = tr.point_times(L.duration(x) if L.free else problem.duration_bounds[0])
    for name, value in values.items():
        kind, i = problem._point_variable(name, "guess")
        col = L.offset(kind) + i
        if callable(value):
            Z[:, col] = [float(value(t)) for t in times]
            continue
        arr = np.asarray(value, dtype=float)
        if arr.ndim == 0:
            Z[:, col] = float(arr)
        elif arr.shape == (L.nodes,):
            Z[:, col] = np.interp(times, times[L.node_points], arr)
        elif arr.shape == (L.points,):
            Z[:, col] = arr
        else:
            raise LagrgenError(f"guess[{name!r}]: give a number, a callable of t or one value per "
                               f"node ({L.nodes}), got shape {arr.shape}")
    if not np.all(np.isfinite(x)):
        raise LagrgenError("guess: the values must be finite")
    return np.clip(x, tr.lo, tr.hi)
