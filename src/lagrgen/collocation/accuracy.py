"""The discretization error of a collocation solution, interval by interval.

On each interval [t_k, t_k+1] the collocation polynomial x(t) (the cubic Hermite interpolant of the
states and their rates at the two nodes, what `CollocationResult.state_at` reports) is compared
with an accurate integration x̃(t) of the model's dynamics from x(t_k), driven by the inputs the
scheme implies on that interval (quadratic through node, midpoint and node for Hermite–Simpson,
linear for the trapezoidal rule, the next node's value held for backward Euler: the signals of
`CollocationResult.input_signals`). The error of the interval is relative to the size of each state,
as in Betts' SOCS and GPOPS-II (Patterson, Hager & Rao 2015):

    e_k = max_i max_θ abs(x_i(θ) − x̃_i(θ)) / (1 + max_j abs(x_i(t_j))),   θ ∈ {¼, ½, ¾, 1},

j over every point of the motion. x̃ comes from the classical Runge–Kutta method on all intervals at
once (the model's `rhs` called from C for a batch of states), each interval's steps halved until two
integrations agree to a hundredth of max(tolerance, e_k) (Richardson's estimate for fourth order).
"""
import warnings

import numpy as np

from ._points import state_rows

#: The default tolerance of the relative dynamics error (`Collocation.solve(mesh_tol=...)`).
DEFAULT_MESH_TOL = 1e-6


class DiscretizationWarning(UserWarning):
    """A solution's dynamics error is larger than the default tolerance."""


#: The fractions of an interval where the polynomial and the integration are compared.
SAMPLES = np.array([0.25, 0.5, 0.75, 1.0])
#: Steps per interval of the first integration, and the most any interval gets.
FIRST_STEPS, MOST_STEPS = 4, 4096
#: An integration is accurate enough when its estimated error is below this share of what it
#: measures (the larger of the tolerance and the interval's error).
INTEGRATION_SHARE = 0.01


def warn_if_coarse(error, intervals, stacklevel):
    """A DiscretizationWarning for a solution on the grid as given (mesh_tol None) whose
    dynamics error exceeds DEFAULT_MESH_TOL."""
    if error > DEFAULT_MESH_TOL:
        warnings.warn(f"the dynamics error of this solution is {error:.2g} (relative, largest "
                      f"over its {intervals} intervals): solve with mesh_tol="
                      f"{DEFAULT_MESH_TOL:g} (the default) to refine the grid until it is "
                      "within that", DiscretizationWarning, stacklevel=stacklevel)


def interval_errors(result, tol=1e-6):
    """The relative discretization error e_k of each interval of `result` (see the module);
    inf where the dynamics cannot be integrated (a failing model or a blow-up)."""
    motion = Motion(result)
    starts = motion.node_states[:-1]
    steps = np.full(motion.intervals, FIRST_STEPS)
    coarse = motion.integrate(np.arange(motion.intervals), starts, steps)
    errors = np.full(motion.intervals, np.inf)
    pending = np.arange(motion.intervals)
    while pending.size:
        steps[pending] *= 2
        fine = motion.integrate(pending, starts[pending], steps[pending])
        estimate = motion.relative(np.abs(fine - coarse[pending]) / 15.0)
        measured = motion.relative(np.abs(fine - motion.polynomial(pending)))
        done = (estimate <= INTEGRATION_SHARE * np.maximum(tol, measured)) | \
            (steps[pending] >= MOST_STEPS) | ~np.isfinite(measured)
        errors[pending[done]] = np.where(np.isfinite(measured[done]), measured[done], np.inf)
        coarse[pending] = fine
        pending = pending[~done]
    return errors


class Motion:
    """What the error of a result needs: its intervals, node states and rates, the inputs on each
    interval as the scheme implies them, the parameters, and the model's rhs in C."""

    def __init__(self, result):
        L, mod = result._layout, result._problem.mod
        Z = L.point_block(result.x)
        n, nu = L.n, L.nu
        nodes = L.node_points
        self.n, self.nu, self.scheme = n, nu, L.scheme
        self.intervals = L.nodes - 1
        self.node_states = np.ascontiguousarray(Z[nodes, :2 * n])
        self.node_rates = np.ascontiguousarray(np.hstack([Z[nodes, n:2 * n],
                                                          Z[nodes, 2 * n:3 * n]]))
        times = result.t_points[nodes]
        self.t0, self.h = times[:-1], np.diff(times)
        u = Z[:, L.offset("u"):L.offset("u") + nu]
        stride = L.stride
        self.u_start, self.u_end = u[0:-1:stride][:self.intervals], u[stride::stride]
        self.u_mid = u[1::2] if stride == 2 else None
        self.p = np.ascontiguousarray(result._full_params, dtype=float)
        self.scale = 1.0 + np.abs(Z[:, :2 * n]).max(axis=0)
        self.rhs = mod.function_address("rhs")

    def inputs(self, which, theta):
        """(len(which), nu) inputs of the intervals `which` at the fractions `theta` of each."""
        a, b = self.u_start[which], self.u_end[which]
        th = theta[:, None]
        if self.scheme == "hermite-simpson":
            m = self.u_mid[which]
            return 2 * (th - 0.5) * (th - 1) * a - 4 * th * (th - 1) * m + 2 * th * (th - 0.5) * b
        if self.scheme == "trapezoidal":
            return (1 - th) * a + th * b
        return b

    def f(self, which, theta, y):
        """ẏ of the intervals `which` at their fractions `theta` and states y (rows)."""
        t = np.ascontiguousarray(self.t0[which] + theta * self.h[which])
        u = np.ascontiguousarray(self.inputs(which, theta)) if self.nu else np.zeros((len(y), 0))
        out = np.empty_like(y)
        with np.errstate(all="ignore"):
            failed = state_rows(self.rhs, t, np.ascontiguousarray(y), self.p, u, out)
        if failed:
            out[:] = np.nan       # the model could not be evaluated: the caller sees a NaN
        return out

    def integrate(self, which, start, steps):
        """(len(which), len(SAMPLES), 2n): the states at SAMPLES of each interval `which`, from
        `start` with `steps` classical Runge–Kutta steps (a multiple of len(SAMPLES))."""
        out = np.empty((len(which), len(SAMPLES), 2 * self.n))
        for group in np.unique(steps):
            rows = np.flatnonzero(steps == group)
            out[rows] = self._runge_kutta(which[rows], start[rows], int(group))
        return out

    def _runge_kutta(self, which, y, steps):
        y = np.array(y, dtype=float)
        d = 1.0 / steps
        h = self.h[which][:, None] * d
        every = steps // len(SAMPLES)
        out = []
        with np.errstate(all="ignore"):
            for s in range(steps):
                theta = np.full(len(which), s * d)
                k1 = self.f(which, theta, y)
                k2 = self.f(which, theta + d / 2, y + h / 2 * k1)
                k3 = self.f(which, theta + d / 2, y + h / 2 * k2)
                k4 = self.f(which, theta + d, y + h * k3)
                y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                if (s + 1) % every == 0:
                    out.append(y.copy())
        return np.stack(out, axis=1)

    def polynomial(self, which):
        """(len(which), len(SAMPLES), 2n): the collocation polynomial at SAMPLES."""
        th = SAMPLES[None, :, None]
        h = self.h[which][:, None, None]
        xs, xe = self.node_states[which][:, None], self.node_states[which + 1][:, None]
        fs, fe = self.node_rates[which][:, None], self.node_rates[which + 1][:, None]
        th2, th3 = th * th, th ** 3
        return ((2 * th3 - 3 * th2 + 1) * xs + h * (th3 - 2 * th2 + th) * fs
                + (-2 * th3 + 3 * th2) * xe + h * (th3 - th2) * fe)

    def relative(self, deviation):
        """The largest deviation of each interval over samples and states, each state's relative
        to its size (NaN counts as infinite)."""
        scaled = np.nan_to_num(deviation / self.scale, nan=np.inf)
        return scaled.max(axis=(1, 2))
