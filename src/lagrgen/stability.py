"""Stability across a parameter: the eigenvalues of the linearization followed branch by branch,
where a branch's real part changes sign, and the root locus.

At each value v the model is linearized about `operating_point(v)` (exactly to first order, on
the constraint manifold: `lagrgen.linearize`) and the eigenvalues of A are paired with those at
the previous value by continuity, never by sorting: the assignment (Hungarian algorithm)
minimizing Σ |s − s_predicted|/|s|_max + (1 − MAC(φ, φ_previous)), s predicted by linear
extrapolation of the last two values and MAC = |φᴴφ'|² the alignment of unit eigenvectors — so a
branch keeps its identity through crossings, and a root passing through a cluster (the zero
roots of ignorable coordinates) keeps its own mode. A stability boundary — a branch's real part
changing sign between neighbouring values — is located by Brent's method on that branch's real
part, evaluated on the compiled Jacobian.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, linear_sum_assignment

from .errors import LagrgenError
from .linearization import (ZERO_TOL, linearize, real_part_tolerance, spectrum,
                            structural_zeros)

#: Absolute tolerance (relative to the swept range) of a located crossing.
CROSSING_XTOL = 1e-12
#: Size (relative to the largest eigenvalue) to which a real part on the imaginary axis is
#: round-off: a crossing into a marginal value is where the real part comes this close to 0.
MARGINAL_ROUND_OFF = 1e3 * np.finfo(float).eps
#: Steps by which a branch is followed from a sampled value to a trial value of a crossing.
CONTINUATION_STEPS = 6


class Crossing(tuple):
    """Where branch `branch` of an eigenvalue sweep crosses the imaginary axis: the tuple
    (value, branch, kind), kind "stable->unstable" or "unstable->stable" read in the direction
    of increasing value, with `pair`, the branch of its complex conjugate that crosses with it
    (a Hopf crossing: the pair's real part changes sign with a nonzero frequency), or None for a
    real root."""

    def __new__(cls, value, branch, kind, pair=None):
        crossing = super().__new__(cls, (float(value), int(branch), kind))
        crossing.pair = None if pair is None else int(pair)
        return crossing

    def __getnewargs__(self):
        return (*self, self.pair)

    value = property(lambda self: self[0], doc="where the real part is zero")
    branch = property(lambda self: self[1], doc="the column of `eigenvalues` that crosses")
    kind = property(lambda self: self[2], doc='"stable->unstable" or "unstable->stable"')


@dataclass(eq=False)
class EigenvalueSweep:
    """The eigenvalues of a model's linearization across `values`: `eigenvalues[i, b]` is branch
    b at `values[i]` (branches followed by continuity), in the independent states `states`."""

    values: np.ndarray
    eigenvalues: np.ndarray
    states: tuple
    vectors: np.ndarray = field(repr=False, default=None)   # unit eigenvectors, per value
    model: object = field(repr=False, default=None)
    operating_point: object = field(repr=False, default=None)
    options: dict = field(repr=False, default_factory=dict)

    @property
    def stable(self):
        """(len(values),) bool: no eigenvalue with a positive real part at each value."""
        return ~np.any(self._signs() > 0, axis=1)

    def _tolerance(self):
        scale = np.abs(self.eigenvalues).max(initial=0.0)
        return ZERO_TOL * max(1.0, scale)

    def _signs(self):
        """−1, 0, +1 per value and branch: the sign of the real part beyond the tolerance (at
        least `_tolerance`; a root of several that round-off split at a value gets that value's
        `linearization.real_part_tolerance`)."""
        re = self.eigenvalues.real
        tol = np.maximum(self._tolerance(),
                         np.array([real_part_tolerance(row) for row in self.eigenvalues]))
        return np.where(re > tol, 1, np.where(re < -tol, -1, 0))

    @property
    def structural(self):
        """(len(values), branches) bool: the structural zeros, roots of ignorable states split
        off exactly (`linearization.spectrum`), which no parameter moves (none known without
        `vectors`)."""
        if self.vectors is None:
            return np.zeros(self.eigenvalues.shape, dtype=bool)
        return structural_zeros(self.eigenvalues, self.vectors)

    def leading_roots(self):
        """(len(values),) complex: at each value the root with the largest real part, structural
        zeros left out (0 when nothing else is left); of roots whose real parts tie within the
        tolerance, the one of the largest frequency abs(Im s)."""
        tol = self._tolerance()
        return np.array([_leading(row[~structural], tol)
                         for row, structural in zip(self.eigenvalues, self.structural)])

    def crossings(self):
        """Where a branch's real part changes sign between neighbouring values, located by root
        finding (to ~1e-12 of the range): a list of `Crossing`, each the tuple (value, branch,
        "stable->unstable" | "unstable->stable"), ordered by value; the two branches of a complex
        pair crossing together (a Hopf crossing) name each other as `pair`. A real part within
        ZERO_TOL of zero is marginal (stable); the boundary with it is where the real part
        itself is zero."""
        growing = self._signs() > 0
        changes = [(i, b) for b in range(self.eigenvalues.shape[1])
                   for i in np.flatnonzero(growing[1:, b] != growing[:-1, b])]
        partner = {(i, b): self._conjugate(i, b, changes) for i, b in changes}
        located, found = {}, []
        for i, b in changes:
            pair = partner[(i, b)]
            key = (i, min(b, pair)) if pair is not None else (i, b)
            if key not in located:
                located[key] = self._locate(i, b)
            found.append(Crossing(located[key], b, self._kind(growing[i + 1, b]), pair))
        return sorted(found, key=lambda c: (c[0], c[1]))

    def _kind(self, growing_after):
        """The kind of a crossing read in the direction of increasing value."""
        if self.values[-1] < self.values[0]:
            growing_after = not growing_after
        return "stable->unstable" if growing_after else "unstable->stable"

    def _conjugate(self, i, b, changes):
        """The branch that is branch b's complex conjugate at values[i] and values[i + 1] and
        changes sign with it there (a complex pair crossing the imaginary axis), else None."""
        s = self.eigenvalues[[i, i + 1]]
        tol = self._tolerance()
        if np.any(np.abs(s[:, b].imag) <= tol):
            return None
        for i_other, other in changes:
            if i_other == i and other != b and np.all(np.abs(s[:, other] - s[:, b].conj()) <= tol):
                return int(other)
        return None

    def _locate(self, i, b):
        """The value between values[i] and values[i + 1] where branch b's real part crosses 0.
        The branch is followed to each trial value by continuation in CONTINUATION_STEPS steps
        from the end where its sign is definite (from the marginal side a collision of two roots
        is ambiguous). Towards a marginal end (real part within ZERO_TOL of 0) the crossing is
        where the real part comes within round-off (MARGINAL_ROUND_OFF) of 0 — on the imaginary
        axis a pair's real part is round-off noise, whose sign means nothing — or that end
        itself when it stays further away."""
        v0, v1 = self.values[i], self.values[i + 1]
        signs = self._signs()[[i, i + 1], b]
        start = i if signs[0] != 0 else i + 1
        offset = 0.0
        if 0 in signs:
            offset = signs[start - i] * MARGINAL_ROUND_OFF * max(1.0, np.abs(self.eigenvalues).max())
            marginal = self.eigenvalues[2 * i + 1 - start, b].real
            if np.sign(marginal - offset) == signs[start - i]:
                return float(self.values[2 * i + 1 - start])

        def real_part(v):
            if v in (v0, v1):
                return self.eigenvalues[i if v == v0 else i + 1, b].real - offset
            return self._continued(start, v)[0][b].real - offset
        xtol = CROSSING_XTOL * max(1.0, abs(self.values[-1] - self.values[0]))
        return float(brentq(real_part, min(v0, v1), max(v0, v1), xtol=xtol,
                            rtol=4 * np.finfo(float).eps))

    def _continued(self, start, value):
        """The spectrum at `value` in the branch order of values[start], followed there in
        CONTINUATION_STEPS steps."""
        rows, vectors = [self.eigenvalues[start]], [self.vectors[start]]
        for x in np.linspace(self.values[start], value, CONTINUATION_STEPS + 1)[1:]:
            s, V = self._spectrum_at(x)
            s, V = paired(rows, vectors, s, V)
            rows.append(s)
            vectors.append(V)
        return rows[-1], vectors[-1]

    def _spectrum_at(self, value):
        return spectrum_at(self.model, self.operating_point, value, self.options, self.states)

    def plot(self, ax=None, stable_color="tab:green"):
        """The root locus: real parts (top) and imaginary parts (bottom) of every branch against
        the value, the stable ranges shaded and the crossings marked.

        Parameters
        ----------
        ax : None (a new figure), a pair of matplotlib Axes (real, imaginary), or one Axes (the
            real parts only)

        Returns
        -------
        The Axes drawn on (a pair, or the one given).
        """
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
        single = not isinstance(ax, (tuple, list, np.ndarray))
        ax_re, ax_im = (ax, None) if single else ax
        v = self.values
        axes = [a for a in (ax_re, ax_im) if a is not None]
        for b in range(self.eigenvalues.shape[1]):
            line, = ax_re.plot(v, self.eigenvalues[:, b].real, lw=1.4)
            if ax_im is not None:
                ax_im.plot(v, self.eigenvalues[:, b].imag, lw=1.4, color=line.get_color())
        crossings = self.crossings()

        def boundary(i, j):
            """Where stability changes between values i and j: a located crossing, else the
            midpoint."""
            lo, hi = sorted((v[i], v[j]))
            inside = [c[0] for c in crossings if lo <= c[0] <= hi]
            return inside[0] if inside else (v[i] + v[j]) / 2
        for start, stop in _runs(self.stable):
            lo = v[start] if start == 0 else boundary(start - 1, start)
            hi = v[stop] if stop == len(v) - 1 else boundary(stop, stop + 1)
            for a in axes:
                a.axvspan(lo, hi, color=stable_color, alpha=0.12, lw=0)
        for value in sorted({c[0] for c in crossings}):
            for a in axes:
                a.axvline(value, color="k", ls="--", lw=0.8)
            ax_re.annotate(f"{value:.6g}", (value, 0), xytext=(4, 4),
                           textcoords="offset points", fontsize=8)
        ax_re.axhline(0.0, color="k", lw=0.6)
        ax_re.set_ylabel("Re s [1/s]")
        axes[-1].set_xlabel(self.options.get("label", "value"))
        ax_re.set_title("eigenvalues (shaded: stable)")
        if ax_im is not None:
            ax_im.set_ylabel("Im s [rad/s]")
        return ax


def _leading(roots, tol):
    """The root with the largest real part (0 when there is none); of those within tol of it,
    the one of the largest abs(Im s)."""
    if not roots.size:
        return 0j
    ties = roots[roots.real >= roots.real.max() - tol]
    return complex(ties[np.argmax(np.abs(ties.imag))])


def _runs(mask):
    """(start, stop) index pairs of the runs of True in `mask`."""
    runs, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        if not m and start is not None:
            runs.append((start, i - 1))
            start = None
    if start is not None:
        runs.append((start, len(mask) - 1))
    return runs


def spectrum_at(mod, operating_point, value, options, states=None):
    """(eigenvalues, unit eigenvectors as columns) of the linearization about
    operating_point(value), in `states`' split."""
    q0, qd0, p = _point(operating_point, value)
    lin = linearize(mod, q0, qd0, p=p, **options.get("linearize", {}),
                    dependent=options.get("dependent"))
    if states is not None and tuple(lin.states) != tuple(states):
        raise LagrgenError(f"the independent states changed along the sweep at {value!r}")
    return spectrum(lin.A)


def branch_cost(predicted, previous, s, V, scale):
    """Cost of giving eigenvalue j (s_j, unit vector V[:, j]) to branch i predicted at
    predicted[i] with unit vector previous[:, i]: |Δs|/scale + 1 − MAC."""
    mac = np.abs(previous.conj().T @ V) ** 2
    return np.abs(predicted[:, None] - s[None, :]) / scale + (1.0 - mac)


def _point(operating_point, value):
    """operating_point(value) as (q0, qd0, p); LagrgenError when it returns anything else (its
    own errors pass through as they are)."""
    point = operating_point(value)
    if not (isinstance(point, (tuple, list)) and len(point) == 3):
        raise LagrgenError("operating_point(value) must return (q0, qd0, p): the coordinates, "
                           "their rates (None: at rest) and the parameters (a dict or None), "
                           f"got {type(point).__name__} at value {value!r}")
    return tuple(point)


def eigenvalue_sweep(mod, values, operating_point, t=0.0, u=None, dependent=None, label=None):
    """Follow the eigenvalues of the linearization of `mod` across `values`.

    Parameters
    ----------
    mod : a built model (either backend)
    values : 1-D array of at least two distinct values, increasing or decreasing
    operating_point : callable value -> (q0, qd0, p), p a dict of parameter values or None
    t, u : the frozen time and the constant inputs of every linearization
    dependent : the dependent coordinates and rates of a constrained model (default: those
        chosen at the first value, kept along the sweep)
    label : the value's name, for the plot

    Returns
    -------
    EigenvalueSweep: `values`, `eigenvalues` (len(values), len(states)), `stable`,
    `structural`, `crossings()` (a list of `Crossing`), `leading_roots()`, `plot()`.
    """
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or len(values) < 2 or not np.all(np.isfinite(values)):
        raise ValueError("values must be a 1-D array of at least two finite numbers")
    steps = np.diff(values)
    if not (np.all(steps > 0) or np.all(steps < 0)):
        raise ValueError("values must be strictly increasing or strictly decreasing")
    if not callable(operating_point):
        raise TypeError("operating_point must be a callable value -> (q0, qd0, p)")
    options = {"linearize": {"t": t, "u": u}, "label": label or "value"}
    q0, qd0, p = _point(operating_point, values[0])
    first = linearize(mod, q0, qd0, p=p, t=t, u=u, dependent=dependent)
    if mod.n_constraints:
        options["dependent"] = [name for name in
                                list(mod.coordinates) + [f"{c}_dot" for c in mod.coordinates]
                                if name not in first.states]
    s, V = spectrum(first.A)
    rows, vectors = [s], [V]
    for value in values[1:]:
        s, V = paired(rows, vectors, *spectrum_at(mod, operating_point, value, options,
                                                   first.states))
        rows.append(s)
        vectors.append(V)
    return EigenvalueSweep(values=values, eigenvalues=np.array(rows), states=first.states,
                           vectors=np.array(vectors), model=mod,
                           operating_point=operating_point, options=options)


def paired(rows, vectors, s, V):
    """(s, V) reordered to continue the branches whose eigenvalues so far are `rows` (the last
    one or two used to predict) and whose last unit vectors are vectors[-1]."""
    predicted = rows[-1] if len(rows) < 2 else 2 * rows[-1] - rows[-2]
    scale = max(1.0, np.abs(s).max(initial=0.0), np.abs(rows[-1]).max(initial=0.0))
    _, cols = linear_sum_assignment(branch_cost(predicted, vectors[-1], s, V, scale))
    return s[cols], V[:, cols]
