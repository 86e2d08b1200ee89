"""The discretization: the collocation points, where each variable sits in the decision vector, the
defects that tie neighbouring points, the quadrature of integrals, and interpolation between nodes.

Every point j carries z_j = [q, q̇, q̈, λ, u] (the accelerations and multipliers are variables, so
the defects are linear and all nonlinearity sits in the model's residual r(z) = 0 at each point);
the decision vector is x = [z_0, …, z_{P−1}, unknown parameters, T (free duration only)]. The
nodes sit at fractions τ_0 = 0 < τ_1 < … < τ_{N−1} = 1 of the duration T (equally spaced unless a
refined mesh places them); with h_k = T·(τ_{k+1} − τ_k), x = (q, q̇) and f = ẋ = (q̇, q̈) on the
interval k:

    trapezoidal      x_{k+1} − x_k − h_k/2·(f_k + f_{k+1}) = 0               points = nodes
    backward-euler   x_{k+1} − x_k − h_k·f_{k+1} = 0                           points = nodes
    hermite-simpson  x_e − x_s − h_k/6·(f_s + 4·f_m + f_e) = 0,               points = nodes and
                     x_m − (x_s + x_e)/2 − h_k/8·(f_s − f_e) = 0               midpoints

Each defect row is Σ c0·x_col + T·Σ c1·x_col (c1 holding the interval's fraction): linear for a
fixed duration, bilinear in (T, x) for a free one. Integrals are T·Σ_j w_j·L(z_j) with the scheme's
weights (trapezoid; right endpoint; Simpson), each holding its intervals' fractions. Between nodes
a state is the cubic Hermite interpolant of its node values and rates, an acceleration or input
linear (quadratic through the midpoint for Hermite–Simpson). With a free duration, a bounded
state's cubic on each Hermite–Simpson interval is held within its bounds by its inner Bernstein
coefficients x_s + h_k/3·f_s and x_e − h_k/3·f_e (`state_hulls`, bilinear in (T, x)).
"""
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import LagrgenError

SCHEMES = ("trapezoidal", "hermite-simpson", "backward-euler")
_ALIASES = {"trapezoid": "trapezoidal", "hs": "hermite-simpson", "simpson": "hermite-simpson",
            "euler": "backward-euler", "implicit-euler": "backward-euler"}
#: The point variables in order, and what each is called in names.
KINDS = ("q", "qd", "qdd", "lam", "u")


def variable_names(mod):
    """{kind: the names of its variables} of the built model `mod`."""
    coords = list(mod.coordinates)
    return {"q": coords, "qd": [f"{c}_dot" for c in coords], "qdd": [f"{c}_ddot" for c in coords],
            "lam": list(mod.constraint_names), "u": list(mod.inputs)}


def scheme_name(scheme):
    """The canonical name of a collocation scheme ("backward euler" → "backward-euler")."""
    if not isinstance(scheme, str):
        raise TypeError(f"scheme must be a string, got {type(scheme).__name__}")
    key = scheme.strip().lower().replace("_", "-").replace(" ", "-")
    key = _ALIASES.get(key, key)
    if key not in SCHEMES:
        raise LagrgenError(f"unknown collocation scheme {scheme!r}: use one of "
                           f"{', '.join(map(repr, SCHEMES))}")
    return key


@dataclass(frozen=True)
class Layout:
    """Where each variable lives in the decision vector x.

    n coordinates, m constraint multipliers, nu inputs; `unknown` the indices (in the model's
    parameter order) of the parameters that are variables; `free` whether T is a variable.
    """
    n: int
    m: int
    nu: int
    nodes: int
    scheme: str
    unknown: tuple
    free: bool
    T_scale: float = 1.0     # a free duration's variable is T/T_scale
    mesh: tuple = ()         # the nodes' fractions of the duration (increasing, 0 to 1); (): equal

    @property
    def points(self):
        return 2 * self.nodes - 1 if self.scheme == "hermite-simpson" else self.nodes

    @property
    def stride(self):
        """Points per node interval (2 with midpoints)."""
        return 2 if self.scheme == "hermite-simpson" else 1

    @property
    def nz(self):
        """Variables per point: q, q̇, q̈ (n each), λ (m), u (nu)."""
        return 3 * self.n + self.m + self.nu

    @property
    def ni(self):
        """Residual rows per point: n dynamics, m constraints at acceleration level."""
        return self.n + self.m

    def offset(self, kind):
        """The position of the first variable of `kind` (one of KINDS) within a point."""
        n, m = self.n, self.m
        return {"q": 0, "qd": n, "qdd": 2 * n, "lam": 3 * n, "u": 3 * n + m}[kind]

    @property
    def p_start(self):
        return self.points * self.nz

    @property
    def T_index(self):
        return self.p_start + len(self.unknown) if self.free else None

    @cached_property
    def node_fractions(self):
        """Each node's time as a fraction of the duration (read-only)."""
        out = np.array(self.mesh) if self.mesh else np.linspace(0.0, 1.0, self.nodes)
        out.setflags(write=False)
        return out

    @property
    def steps(self):
        """Each interval's length as a fraction of the duration."""
        return np.diff(self.node_fractions)

    def duration(self, x):
        """T at the decision vector x (a free duration's variable is T/T_scale)."""
        return self.T_scale * x[self.T_index]

    @property
    def size(self):
        return self.p_start + len(self.unknown) + int(self.free)

    @property
    def node_points(self):
        """The point index of each node."""
        return np.arange(self.nodes) * self.stride

    @property
    def fractions(self):
        """Each point's time as a fraction of the duration."""
        nodes = self.node_fractions
        if self.stride == 1:
            return nodes
        out = np.empty(self.points)
        out[0::2], out[1::2] = nodes, 0.5 * (nodes[:-1] + nodes[1:])
        return out

    def node_at(self, fraction):
        """The point index of the node at `fraction` of the duration, or None if none is there."""
        nodes = self.node_fractions
        k = int(np.argmin(np.abs(nodes - fraction)))
        return k * self.stride if abs(nodes[k] - fraction) <= 1e-12 else None

    def interval_of(self, s, duration):
        """(interval k, its length h, θ ∈ [0, 1]) of the times s ∈ [0, duration] after t0 (a
        number, or arrays for an array)."""
        times = duration * self.node_fractions
        k = np.clip(np.searchsorted(times, s, side="right") - 1, 0, self.nodes - 2)
        h = times[k + 1] - times[k]
        theta = np.clip((s - times[k]) / h, 0.0, 1.0)
        if np.ndim(s) == 0:
            return int(k), float(h), float(theta)
        return k, h, theta

    def index(self, point, kind, i):
        """The position in x of variable i of `kind` at `point`."""
        return point * self.nz + self.offset(kind) + i

    def point_block(self, x):
        """The (points, nz) view of x's point variables."""
        return x[:self.p_start].reshape(self.points, self.nz)


def defects(layout):
    """The defect rows as triplets (rows, cols, c0, c1) and their count: row = Σ (c0 + T·c1)·x
    (c1 holds the interval's fraction of the duration)."""
    n, nz, N = layout.n, layout.nz, layout.nodes
    comp = np.arange(n)
    rows, cols, c0, c1 = [], [], [], []
    per = defects_per_interval(layout)
    if layout.scheme == "hermite-simpson":
        start = np.arange(N - 1)[:, None] * 2                  # point of the interval's start
        base = np.arange(N - 1)[:, None] * per
        for block, (xk, fk) in enumerate((("q", "qd"), ("qd", "qdd"))):
            ox, of = layout.offset(xk), layout.offset(fk)
            simpson = base + block * n + comp                   # x_e − x_s − h/6 (f_s + 4f_m + f_e)
            hermite = base + 2 * n + block * n + comp   # x_m − (x_s + x_e)/2 − h/8 (f_s − f_e)
            s, mid, e = start * nz, (start + 1) * nz, (start + 2) * nz
            for row, col, a, b in (
                    (simpson, e + ox + comp, 1.0, 0.0), (simpson, s + ox + comp, -1.0, 0.0),
                    (simpson, s + of + comp, 0.0, -1 / 6), (simpson, mid + of + comp, 0.0, -4 / 6),
                    (simpson, e + of + comp, 0.0, -1 / 6),
                    (hermite, mid + ox + comp, 1.0, 0.0), (hermite, s + ox + comp, -0.5, 0.0),
                    (hermite, e + ox + comp, -0.5, 0.0), (hermite, s + of + comp, 0.0, -1 / 8),
                    (hermite, e + of + comp, 0.0, 1 / 8)):
                rows.append(row), cols.append(col)
                c0.append(np.full(row.shape, a)), c1.append(np.full(row.shape, b))
    else:
        k = np.arange(N - 1)[:, None]
        base = k * per
        for block, (xk, fk) in enumerate((("q", "qd"), ("qd", "qdd"))):
            ox, of = layout.offset(xk), layout.offset(fk)
            row = base + block * n + comp
            s, e = k * nz, (k + 1) * nz
            entries = [(e + ox + comp, 1.0, 0.0), (s + ox + comp, -1.0, 0.0)]
            if layout.scheme == "trapezoidal":
                entries += [(s + of + comp, 0.0, -0.5), (e + of + comp, 0.0, -0.5)]
            else:
                entries += [(e + of + comp, 0.0, -1.0)]
            for col, a, b in entries:
                rows.append(row), cols.append(col)
                c0.append(np.full(row.shape, a)), c1.append(np.full(row.shape, b))
    flat = [np.concatenate([a.ravel() for a in arrays]) for arrays in (rows, cols, c0, c1)]
    rows = flat[0].astype(np.int64)
    return rows, flat[1].astype(np.int64), flat[2], flat[3] * layout.steps[rows // per], \
        (N - 1) * per


def state_hulls(layout, bounded):
    """The inner Bernstein coefficients of each bounded state's cubic on each Hermite–Simpson
    interval as triplets (rows, cols, c0, c1) with row = Σ (c0 + T·c1)·x, and their count: for
    the state x with rate f, b1 = x_s + h/3·f_s and b2 = x_e − h/3·f_e (two rows an interval,
    in the order of `bounded`, a list of (kind, i) with kind "q" or "qd"). The cubic lies in the
    hull of x_s, b1, b2, x_e, so bounding b1 and b2 as the points bound x keeps all of it within
    the bounds."""
    rate = {"q": "qd", "qd": "qdd"}
    nz, K = layout.nz, layout.nodes - 1
    s, e = np.arange(K) * 2 * nz, (np.arange(K) * 2 + 2) * nz
    rows, cols, c0, c1 = [], [], [], []
    for b, (kind, i) in enumerate(bounded):
        ox, of = layout.offset(kind) + i, layout.offset(rate[kind]) + i
        first, second = (2 * b + np.arange(2)[:, None]) * K + np.arange(K)[None, :]
        for row, col, a, c in ((first, s + ox, 1.0, 0.0), (first, s + of, 0.0, 1 / 3),
                               (second, e + ox, 1.0, 0.0), (second, e + of, 0.0, -1 / 3)):
            rows.append(row), cols.append(col)
            c0.append(np.full(K, a)), c1.append(np.full(K, c) * layout.steps)
    if not rows:
        empty = np.zeros(0)
        return empty.astype(np.int64), empty.astype(np.int64), empty, empty, 0
    rows, cols, c0, c1 = (np.concatenate(arrays) for arrays in (rows, cols, c0, c1))
    return rows.astype(np.int64), cols.astype(np.int64), c0, c1, 2 * K * len(bounded)


def defect_intervals(layout):
    """The interval of each defect row."""
    return np.repeat(np.arange(layout.nodes - 1), defects_per_interval(layout))


def defects_per_interval(layout):
    """Defect rows per interval: x = (q, q̇) once (twice with the Hermite midpoint)."""
    return (4 if layout.scheme == "hermite-simpson" else 2) * layout.n


def quadrature(layout):
    """The weights w_j with ∫ L dt ≈ T·Σ_j w_j·L(z_j)."""
    P, steps = layout.points, layout.steps
    w = np.zeros(P)
    if layout.scheme == "trapezoidal":
        w[:-1] += steps / 2
        w[1:] += steps / 2
    elif layout.scheme == "backward-euler":
        w[1:] = steps
    else:
        w[0:-1:2] += steps / 6
        w[1::2] = 4 * steps / 6
        w[2::2] += steps / 6
    return w


def interpolation(layout, kind, i, s, duration):
    """(cols, coefficients) with variable i of `kind` at time s ∈ [0, duration] ≈ Σ c·x[cols].

    States (q, q̇) use the cubic Hermite interpolant of the two nodes' values and rates (the one
    Hermite–Simpson's midpoint defect imposes); accelerations and inputs are linear between nodes,
    quadratic through the midpoint for Hermite–Simpson."""
    k, h, theta = layout.interval_of(s, duration)
    stride = layout.stride
    start, end = k * stride, (k + 1) * stride
    if kind in ("q", "qd"):
        rate = "qd" if kind == "q" else "qdd"
        th2, th3 = theta * theta, theta ** 3
        entries = [(layout.index(start, kind, i), 2 * th3 - 3 * th2 + 1),
                   (layout.index(start, rate, i), h * (th3 - 2 * th2 + theta)),
                   (layout.index(end, kind, i), -2 * th3 + 3 * th2),
                   (layout.index(end, rate, i), h * (th3 - th2))]
    elif stride == 2:
        entries = [(layout.index(start, kind, i), 2 * (theta - 0.5) * (theta - 1)),
                   (layout.index(start + 1, kind, i), -4 * theta * (theta - 1)),
                   (layout.index(end, kind, i), 2 * theta * (theta - 0.5))]
    else:
        entries = [(layout.index(start, kind, i), 1 - theta), (layout.index(end, kind, i), theta)]
    entries = [(c, v) for c, v in entries if v != 0.0]
    return np.array([c for c, _ in entries], dtype=np.int64), np.array([v for _, v in entries])


def interpolate_rows(values_at_points, layout, kind, times, duration, rates=None):
    """Evaluate the interpolant of `interpolation` for one variable's point values (and, for a
    state, its rate's point values `rates`) at `times`; both arrays have one value per point."""
    k, h, theta = layout.interval_of(np.asarray(times, dtype=float), duration)
    a, b = k * layout.stride, (k + 1) * layout.stride
    v = np.asarray(values_at_points)
    if rates is not None:
        th2, th3 = theta * theta, theta ** 3
        return ((2 * th3 - 3 * th2 + 1) * v[a] + h * (th3 - 2 * th2 + theta) * rates[a]
                + (-2 * th3 + 3 * th2) * v[b] + h * (th3 - th2) * rates[b])
    if layout.stride == 2:
        return (2 * (theta - 0.5) * (theta - 1) * v[a] - 4 * theta * (theta - 1) * v[a + 1]
                + 2 * theta * (theta - 0.5) * v[b])
    return (1 - theta) * v[a] + theta * v[b]


@dataclass(frozen=True)
class ControlMesh:
    """The inputs' own intervals on a refined mesh: on each control interval [knots[c],
    knots[c+1]] (fractions of the duration, each a node of the mesh) an input is one polynomial
    of `degree` (1: linear, 2: quadratic), however many nodes of the states lie inside."""
    knots: tuple
    degree: int
    tied: frozenset = None

    def ties(self, layout, inputs):
        """Rows [(cols, coefficients)] with Σ c·x = 0 that put every point's value of each input
        in `inputs` (indices) that is `tied` (None: all) on the polynomial of its control
        interval: the first and last points of the interval (and, quadratic, the one nearest its
        middle) carry it, every other point inside equals their Lagrange interpolant."""
        fractions = layout.fractions
        inputs = [k for k in inputs if self.tied is None or k in self.tied]
        rows = []
        for a, b in zip(self.knots[:-1], self.knots[1:]):
            inside = np.flatnonzero((fractions >= a - 1e-12) & (fractions <= b + 1e-12))
            carriers = [inside[0], inside[-1]]
            if self.degree == 2:
                middle = inside[1:-1][np.argmin(np.abs(fractions[inside[1:-1]] - (a + b) / 2))]
                carriers.insert(1, middle)
            for j in inside:
                if j in carriers:
                    continue
                weights = lagrange_weights(fractions[carriers], fractions[j])
                for k in inputs:
                    cols = [layout.index(j, "u", k)] + [layout.index(c, "u", k) for c in carriers]
                    rows.append((cols, [1.0] + [-w for w in weights]))
        return rows


def lagrange_weights(nodes, s):
    """The weights w_i with p(s) = Σ w_i·p(nodes_i) for every polynomial p of degree
    len(nodes) − 1."""
    return [np.prod([(s - b) / (a - b) for j, b in enumerate(nodes) if j != i])
            for i, a in enumerate(nodes)]
