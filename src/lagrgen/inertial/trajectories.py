"""Exciting trajectories: periodic finite Fourier series of the joints (Swevers et al. 1997) whose
stacked base regressor is well conditioned within the joints' limits."""
import math
from dataclasses import dataclass, field

import numpy as np

from .base import base_parameters
from .limits import _limit_arrays
from .regressor import _regressor_function, _stack


@dataclass
class ExcitingTrajectory:
    """A periodic joint motion of finite Fourier series (Swevers et al. 1997), per joint i:

        q_i(t) = q0_i + Σ_l a_il/(ω_f·l)·sin(ω_f·l·t) − b_il/(ω_f·l)·cos(ω_f·l·t),  l = 1…L

    with ω_f = 2π/period. `q`, `qd` and `qdd` take a time or an array of times: (n,) or
    (n, len(t)).

    Attributes
    ----------
    coordinates : the joints, in row order
    period : the period (the duration asked for)
    q0 : (n,) the offsets; a, b : (n, L) the coefficients
    condition : the condition number of the stacked base regressor reached
    initial_condition : that of the best random start (what the optimization improved on)
    times : the sample times the condition number is computed at
    """
    coordinates: tuple
    period: float
    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    condition: float = np.nan
    initial_condition: float = np.nan
    times: np.ndarray = field(default=None, repr=False)

    @property
    def omega(self):
        """The fundamental frequency ω_f = 2π/period (rad/s)."""
        return 2 * np.pi / self.period

    def _motion(self, t):
        t = np.asarray(t, dtype=float)
        return _series(self.a, self.b, *_basis(self.omega, self.a.shape[1], t))

    def q(self, t):
        """Positions at t: (n,) or (n, len(t))."""
        dq = self._motion(t)[0]
        return dq + self.q0.reshape((-1,) + (1,) * (dq.ndim - 1))

    def qd(self, t):
        """Velocities at t: (n,) or (n, len(t))."""
        return self._motion(t)[1]

    def qdd(self, t):
        """Accelerations at t: (n,) or (n, len(t))."""
        return self._motion(t)[2]


def _basis(omega, harmonics, t):
    """(ω_l, sin(ω_l·t), cos(ω_l·t)) of the harmonics ω_l = l·ω, l = 1…L; (L,) + t.shape."""
    wl = omega * np.arange(1, harmonics + 1)
    phase = np.multiply.outer(wl, t)
    return wl, np.sin(phase), np.cos(phase)


def _series(a, b, wl, sin, cos):
    """(q − q0, q̇, q̈) of the series with coefficients a, b (n, L) on a basis of `_basis`."""
    return ((a / wl) @ sin - (b / wl) @ cos, a @ cos + b @ sin,
            (b * wl) @ cos - (a * wl) @ sin)


def exciting_trajectory(mod, duration, harmonics=5, limits=None, q0=None, samples=None, seed=0,
                        starts=8, max_iterations=100, base=None):
    """A periodic motion whose stacked base regressor is well conditioned (Swevers et al. 1997).

    Each joint follows a finite Fourier series of `harmonics` harmonics of ω_f = 2π/duration
    about q0 (`ExcitingTrajectory`), periodic in position, velocity and acceleration. The
    coefficients minimize log cond(W_b), W_b the base regressor stacked over `samples` evenly
    spaced times of a period, under the joints' limits: each joint's coefficients are scaled by
    the largest factor that keeps its motion within its position range about q0, its velocity
    and its acceleration limits (checked on a grid of 64 points per period of the highest
    harmonic while optimizing, of 2048 at the end, with a margin of 1e-4), so the search itself
    is unconstrained: the best of `starts` seeded random coefficients, then L-BFGS-B with
    finite-difference gradients until log cond changes by less than 1e-4.

    Parameters
    ----------
    mod : a built model whose inertial parameters are parameters (a URDF read with
        parameters="inertial", or parameters named m_<link>, mx_<link>, ...)
    duration : the period of the motion (s)
    harmonics : the number of harmonics L
    limits : dict coordinate -> (lower, upper, velocity, acceleration), None where absent;
        what is not given (a coordinate, or a None in its entry) is taken from the model's
        `limits` (lower, upper, velocity) when it has them, so `{c: (None, None, None, 10.0)}`
        adds an acceleration limit to a URDF's. Every joint needs at least one finite limit.
    q0 : the offsets (dict or array; None: the middle of each joint's position range, else 0)
    samples : the number of times the condition number is computed at (None: enough for 3
        times the rows the base parameters need, and 2 per harmonic)
    seed, starts, max_iterations : the random starts and the optimizer's iteration limit
    base : the BaseParameters (None: `base_parameters(mod)`)

    Returns
    -------
    ExcitingTrajectory (q(t), qd(t), qdd(t), condition, q0, a, b)
    """
    from scipy.optimize import minimize
    duration = float(duration)
    if not (np.isfinite(duration) and duration > 0) or int(harmonics) != harmonics \
            or harmonics < 1:
        raise ValueError("duration must be a positive time and harmonics a positive integer")
    base = base or base_parameters(mod)
    n, L = mod.n_coordinates, int(harmonics)
    lower, upper, velocity, acceleration = _limit_arrays(mod, limits)
    unbounded = [c for c, *row in zip(mod.coordinates, lower, upper, velocity, acceleration)
                 if np.all(np.isinf(row))]
    if unbounded:
        raise ValueError(f"joint {unbounded[0]!r} has no position, velocity or acceleration "
                         "limit: give limits={coordinate: (lower, upper, velocity, "
                         "acceleration)} (None where absent)")
    offsets = _offsets(mod, q0, lower, upper)
    bounds = (lower - offsets, upper - offsets, velocity, acceleration)
    samples = samples or max(2 * (2 * L + 1), math.ceil(3 * len(base.names) / n))
    times = duration * np.arange(samples) / samples
    omega = 2 * np.pi / duration
    at_times = _basis(omega, L, times)
    on_grid = _basis(omega, L, duration * np.arange(64 * L) / (64 * L))
    condition = _conditioning(mod, base)

    def scaled(x, grid=on_grid, margin=0.0):
        a, b = x[:n * L].reshape(n, L), x[n * L:].reshape(n, L)
        scale = (1 - margin) * _largest_scale(_series(a, b, *grid), *bounds)
        return a * scale[:, None], b * scale[:, None]

    def objective(x):
        dq, qd, qdd = _series(*scaled(x), *at_times)
        return np.log(condition(offsets[:, None] + dq, qd, qdd))

    rng = np.random.default_rng(seed)
    candidates = [rng.standard_normal(2 * n * L) / np.tile(np.arange(1, L + 1), 2 * n)
                  for _ in range(max(1, int(starts)))]
    scores = [objective(x) for x in candidates]
    best = candidates[int(np.argmin(scores))]
    result = minimize(objective, best, method="L-BFGS-B",
                      options={"maxiter": int(max_iterations), "ftol": 1e-4})
    x = result.x if result.fun < min(scores) else best
    a, b = scaled(x, _basis(omega, L, duration * np.arange(2048 * L) / (2048 * L)), 1e-4)
    final = ExcitingTrajectory(tuple(mod.coordinates), duration, offsets, a, b, times=times,
                               initial_condition=float(np.exp(min(scores))))
    final.condition = condition(final.q(times), final.qd(times), final.qdd(times))
    return final


def _offsets(mod, q0, lower, upper):
    """The motion's centre: q0 (dict or array), else the middle of each finite range, else 0."""
    from ..runtime.arguments import named_vector
    bounded = np.isfinite(lower) & np.isfinite(upper)
    middle = np.where(bounded, 0.5 * (np.where(bounded, lower, 0) + np.where(bounded, upper, 0)),
                      0.0)
    if q0 is None:
        offsets = middle
    elif isinstance(q0, dict):
        offsets = named_vector(q0, tuple(mod.coordinates), middle, "coordinate")
    else:
        offsets = np.asarray(q0, dtype=float).reshape(-1)
    if offsets.shape != middle.shape or np.any(offsets <= lower) or np.any(offsets >= upper):
        raise ValueError(f"q0 must give the {middle.size} joints' centres strictly within their "
                         "position limits (a joint with one position limit needs its q0 given)")
    return offsets


def _largest_scale(motion, low, high, velocity, acceleration):
    """Per joint, the largest factor s with s·(q − q0) within [low, high] and s·|q̇|, s·|q̈|
    within the velocity and acceleration limits, for a motion (q − q0, q̇, q̈) on a grid."""
    dq, v, acc = motion
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.stack([high / dq.max(1).clip(min=1e-300), low / dq.min(1).clip(max=-1e-300),
                           velocity / np.abs(v).max(1), acceleration / np.abs(acc).max(1)])
    return np.nanmin(np.where(ratios > 0, ratios, np.inf), axis=0)


def _conditioning(mod, base):
    """A function (q, qd, qdd), each (n, m), -> cond of the base regressor stacked over the m
    samples."""
    one = _regressor_function(mod)
    columns = list(base.columns)

    def condition(q, qd, qdd):
        W = _stack(one, q.T, qd.T, qdd.T)[:, :, columns].reshape(-1, len(columns))
        s = np.linalg.svd(W, compute_uv=False)
        return float(s[0] / s[-1]) if s[-1] > 0 else np.inf
    return condition
