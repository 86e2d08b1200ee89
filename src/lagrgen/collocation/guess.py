"""Starting points of a collocation problem: by interpolation between the instance values, from an
earlier result (a warm start on any grid), from a simulation, or from named values."""
import numpy as np

from ..errors import LagrgenError
from ..runtime.arguments import key_name
from .grid import KINDS, interpolate_rows


def initial_guess(problem, tr, guess):
    """The decision vector to start IPOPT from (see `Collocation.solve`)."""
    from .result import CollocationResult
    L = problem.layout
    if guess is None:
        return default_guess(problem, tr)
    if isinstance(guess, CollocationResult):
        return from_result(problem, tr, guess)
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


def default_guess(problem, tr):
    """Each variable linear between its initial and final instance values (constant when one is
    given, the middle of its bounds or 0 when none), except that a coordinate's rate follows its
    coordinate's line between the ends; parameters at their current values."""
    L = problem.layout
    x = np.zeros(L.size)
    Z = L.point_block(x)
    tau = L.fractions
    T = _duration_guess(problem)
    last = L.points - 1
    slopes = {}
    for kind in KINDS:
        count = {"q": L.n, "qd": L.n, "qdd": L.n, "lam": L.m, "u": L.nu}[kind]
        for i in range(count):
            col = L.offset(kind) + i
            a, b = problem._fixed.get((0, kind, i)), problem._fixed.get((last, kind, i))
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


def from_result(problem, tr, result):
    """An earlier result on this grid or another: its point values interpolated (states by their
    Hermite interpolant) at this problem's points, its duration and parameter estimates."""
    L, old = problem.layout, result._layout
    if (old.n, old.m, old.nu) != (L.n, L.m, L.nu):
        raise LagrgenError("guess: the result is of a model with other sizes")
    x = default_guess(problem, tr)
    if old == L and result.x.size == L.size:
        x = np.array(result.x)
    else:
        Zold = old.point_block(result.x)
        T = result.duration
        if L.free:
            x[L.T_index] = T / L.T_scale
        times = L.fractions * T          # the same fractions of the earlier duration
        Z = L.point_block(x)
        for kind in KINDS:
            count = {"q": L.n, "qd": L.n, "qdd": L.n, "lam": L.m, "u": L.nu}[kind]
            rate = {"q": "qd", "qd": "qdd"}.get(kind)
            for i in range(count):
                values = Zold[:, old.offset(kind) + i]
                rates = Zold[:, old.offset(rate) + i] if rate else None
                Z[:, L.offset(kind) + i] = interpolate_rows(values, old, kind, times, T, rates)
        names = list(problem.mod.parameters)
        for k, j in enumerate(L.unknown):
            if names[j] in result.params:
                x[L.p_start + k] = result.params[names[j]]
    return np.clip(x, tr.lo, tr.hi)


def from_simulation(problem, tr, sol):
    """States of a simulation (sol.t, sol.y) interpolated at the points; accelerations and
    multipliers from the model at those states (inputs at their guessed values)."""
    L, mod = problem.layout, problem.mod
    x = default_guess(problem, tr)
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
    L = problem.layout
    x = default_guess(problem, tr)
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
