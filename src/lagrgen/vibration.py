"""Small oscillations about an operating point: equilibrium, modes, frequency response.

The linearization itself (`lagrgen.linearization`) is exact to first order about any point, on
the constraint manifold, in independent states x: δẋ = A·δx + B·δu. Where it has a second-order
form M·δq̈ + C·δq̇ + K·δq = B·δu with a symmetric C (dissipation, no gyroscopic coupling), the
modes are the classical ones: ω² the eigenvalues of K·φ = ω²·M·φ, mass-normalized shapes, and
damping ratios from the state matrix's eigenvalues matched to them. Otherwise — nonholonomic
models (a rolling wheel, a sleigh), steady motions with gyroscopic terms — the modes are those of
A: each conjugate pair s = −ζω ± iω√(1−ζ²), or real s, is one mode with ω = |s| and ζ = −Re s/|s|.
"""
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy.optimize import linear_sum_assignment, root

from .errors import LagrgenError, UnknownNameError
from .linearization import (ZERO_TOL, FrozenTimeWarning, Linearization,  # noqa: F401
                            ascending, check_positive_definite, linearize, operating_point,
                            real_part_tolerance, warn_frozen_time)
from .runtime.arguments import key_name


class EquilibriumError(LagrgenError, RuntimeError):
    """No equilibrium F(q, 0) = 0 was found near the guess."""


@dataclass
class Modes:
    """The modes of a linearization.

    `omega[i]` (rad/s, ascending) and `shapes[:, i]` (in all coordinates) of mode i;
    `damping_ratios[i]` = ζ_i and `omega_damped[i]` = ω_i·√(1 − ζ_i²) from the eigenvalues s of the
    state matrix, `eigenvalues` all of them (complex, ascending by real part), and `stable` whether
    none has a positive real part (Re s = 0 — undamped oscillation, rigid-body or
    ignorable-coordinate motion — counts as stable).

    Classical modes (`kind == "classical"`: a second-order form with symmetric C): ω_i = √λ_i for
    the eigenvalues λ = `omega_squared` of K·φ = λ·M·φ (0 for a rigid-body mode, NaN where
    λ < 0: an unstable equilibrium), φ_iᵀ·M·φ_i = 1 (and φᵀ·M·φ = I when K is symmetric; for a
    constrained model the independent modes drawn in all coordinates, T_q·φ).
    State-space modes (`kind == "state"`): one per conjugate pair or real eigenvalue s of A, with
    ω = abs(s), ζ = −Re(s)/abs(s) (ζ = −1 for a real s > 0), complex shapes scaled to a largest
    entry of 1.
    """

    omega: np.ndarray
    shapes: np.ndarray
    damping_ratios: np.ndarray
    omega_damped: np.ndarray
    eigenvalues: np.ndarray
    linearization: Linearization = field(repr=False, default=None)
    model: object = field(repr=False, default=None)   # the built model analysed (None: from a lin)
    omega_squared: np.ndarray = None
    kind: str = "classical"
    independent_shapes: np.ndarray = field(repr=False, default=None)  # classical: in lin.coordinates

    @property
    def frequencies_hz(self):
        """ω / 2π."""
        return self.omega / (2 * np.pi)

    @property
    def stable(self):
        """Whether no eigenvalue of the state matrix has a positive real part (beyond round-off:
        ZERO_TOL of the largest abs(s), more for a root of several that round-off split:
        `linearization.real_part_tolerance`)."""
        s = self.eigenvalues
        return np.bool_(not (s.size and np.any(s.real > real_part_tolerance(s))))

    def __len__(self):
        return len(self.omega)

    def animate(self, k, path=None, model=None, amplitude=None, periods=1, frames_per_period=36,
                fps=20, dpi=80, title=None):
        """Write the k-th mode (0-based: `omega[k]`, `shapes[:, k]`) moving on the mechanism to
        `path` (.gif with Pillow, .mp4 with ffmpeg): q(t) = q0 + a·φ_k·sin(ω_k·t) over `periods`
        periods, drawn like `simulate`'s animation, frequency and damping ratio in the title.

        Parameters
        ----------
        k : int, the mode
        path : str or pathlib.Path, ending in .gif or .mp4; None: return an animation that shows
            itself in a notebook (HTML/JavaScript frames, `.save(path)` later)
        model : the `lagrgen.Model` to draw (default: the one the analysed built model was built
            from)
        amplitude : a (default: the largest drawn displacement is ~18 % of the mechanism's size)
        periods, frames_per_period, fps, dpi, title : the animation

        Returns
        -------
        The path written, or the notebook animation (the amplitude used is kept as
        `last_amplitude`).
        """
        from .outputs.modeshapes import animate_mode
        model = self._drawing_model(model)
        path, self.last_amplitude = animate_mode(
            model, self, k, path, self.linearization.p, amplitude, periods, frames_per_period,
            fps, dpi, title)
        return path

    def _drawing_model(self, model):
        if model is not None:
            return model
        if self.model is None:
            raise LagrgenError(
                "these modes were computed from a Linearization and know no mechanism to draw: "
                "call lagrgen.modes(mod, q0) with the built model, or pass the description, "
                "result.animate(k, path, model=model)")
        source = getattr(self.model, "_source_model", None)
        if source is None:
            raise LagrgenError(
                f"the built model {self.model.name!r} was loaded, not built in this session, so "
                "its drawing is unknown: pass the lagrgen.Model, result.animate(k, path, "
                "model=model)")
        return source


def equilibrium(mod, q_guess, p=None, u=None, t=0.0, tol=1e-9):
    """The configuration q with F(q, 0, t, u) = 0 nearest `q_guess`, found by scipy.optimize.root.

    The analytic ∂F/∂q (from `mod.linear_terms`) is the Jacobian. Levenberg–Marquardt goes first,
    so a direction in which F vanishes identically (a rigid-body mode) keeps its guessed value;
    Powell's hybrid method is the fallback. Raises EquilibriumError unless the residual satisfies
    max|F_i| ≤ tol·max(1, max|∂F_i/∂q_j|).
    """
    q_guess, p, u = operating_point(mod, q_guess, "q_guess", p, u)
    warn_frozen_time(mod, t, "equilibrium")
    if mod.n_constraints:
        return _constrained_equilibrium(mod, q_guess, p, u, t, tol)
    zero = np.zeros_like(q_guess)

    def residual(q):
        return mod.forcing(q, zero, t, p, u)

    def jacobian(q):
        return mod.linear_terms(q, zero, t, p, u)[1]

    def converged(q):
        scale = max(1.0, np.abs(jacobian(q)).max())
        return np.all(np.isfinite(q)) and np.abs(residual(q)).max() <= tol * scale

    if converged(q_guess):
        return q_guess
    best = q_guess
    for method in ("lm", "hybr"):
        sol = root(residual, best, jac=jacobian, method=method)
        if np.all(np.isfinite(sol.x)) and converged(sol.x):
            return np.asarray(sol.x, dtype=float)
        if np.all(np.isfinite(sol.x)) and (np.abs(residual(sol.x)).max()
                                           < np.abs(residual(best)).max()):
            best = sol.x
    names = ", ".join(f"{c}={v:.6g}" for c, v in zip(mod.coordinates, q_guess))
    raise EquilibriumError(
        f"no equilibrium of model {mod.name!r} found near {names} "
        f"(|F| = {np.abs(residual(best)).max():.3g} at the best point reached): "
        "try another starting guess, or check that the model has a static equilibrium")


def _constrained_equilibrium(mod, q_guess, p, u, t, tol):
    """q on Φ(q, t) = 0 where the constrained q̈(q, q̇ = 0) vanishes: least squares on
    [q̈(q); Φ(q)] with the Jacobian [∂q̈/∂q; Φ_q] from `mod.jacobian`, from the projected guess."""
    from scipy.optimize import least_squares
    from .constraints import consistent_state, velocity_terms
    n = mod.n_coordinates
    y0 = consistent_state(mod, np.concatenate([q_guess, np.zeros(n)]), t, p, u)
    zero = np.zeros(n)

    def residual(q):
        y = np.concatenate([q, zero])
        phi = velocity_terms(mod, t, q, p, u)[0]
        return np.concatenate([mod.rhs(t, y, p, u)[n:], phi])

    def jacobian(q):
        y = np.concatenate([q, zero])
        _, A, _ = velocity_terms(mod, t, q, p, u)
        n_h = len(residual(q)) - n
        return np.vstack([mod.jacobian(t, y, p, u)[n:, :n], A[:n_h]])

    def converged(q):
        scale = max(1.0, np.abs(jacobian(q)).max())
        return np.all(np.isfinite(q)) and np.abs(residual(q)).max() <= tol * scale

    q = y0[:n]
    if not converged(q):
        sol = least_squares(residual, q, jac=jacobian, method="lm", xtol=1e-15, ftol=1e-15,
                            gtol=1e-15)
        q = sol.x
    if converged(q):
        return np.asarray(q, dtype=float)
    names = ", ".join(f"{c}={v:.6g}" for c, v in zip(mod.coordinates, q_guess))
    raise EquilibriumError(
        f"no equilibrium of the constrained model {mod.name!r} found near {names} "
        f"(|q̈, Φ| = {np.abs(residual(q)).max():.3g} at the best point reached): try another "
        "starting guess")


def as_linearization(mod_or_lin, q0=None, qd0=None, p=None, u=None, t=0.0, dependent=None):
    """A Linearization as given, or the built model linearized at (q0, qd0) (q0 None: the
    equilibrium near 0) at time t."""
    if isinstance(mod_or_lin, Linearization):
        return mod_or_lin
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FrozenTimeWarning)   # modes warns once, below
        if q0 is None:
            q0 = equilibrium(mod_or_lin, np.zeros(mod_or_lin.n_coordinates), p=p, u=u, t=t)
        return linearize(mod_or_lin, q0, qd0, t=t, p=p, u=u, dependent=dependent)


class NotAnEquilibriumWarning(UserWarning):
    """Modes at an operating point that is neither an equilibrium nor a steady motion: the
    linearization holds for that instant only, and its frequencies and stability say nothing
    about the motion (which leaves the point)."""


#: Relative size, against what the model's linear terms produce at the operating point
#: (`acceleration_yardstick`), above which an acceleration there, or its change along the rates,
#: is not zero.
STEADY_TOL = 1e-6


def state_values(lin):
    """The operating point in the independent states of `lin`: q0 of each coordinate state,
    q̇0 of each rate state."""
    names = list(lin.model_coordinates)
    return np.array([lin.q0[names.index(x)] if x in names else lin.qd0[names.index(x[:-4])]
                     for x in lin.states])


def acceleration_yardstick(lin):
    """Per coordinate, the size of the accelerations the model's terms produce at the operating
    point: abs(M⁻¹·F) (the accelerations without constraint forces) + abs(A)·abs(x0) +
    abs(B)·abs(u) mapped by the basis (ω²·abs(q0) for one oscillator). A change of a
    coordinate's unit scales it as it scales q̈0."""
    n = len(lin.model_coordinates)
    size = np.abs(lin.A) @ np.abs(state_values(lin))
    if lin.u is not None and np.size(lin.u) and np.size(lin.B_state):
        size = size + np.abs(lin.B_state) @ np.abs(np.asarray(lin.u, dtype=float))
    out = (np.abs(lin.basis) @ size)[n:]
    if lin.M_full is not None and lin.F_full is not None:
        out = out + np.abs(np.linalg.solve(lin.M_full, lin.F_full))
    return out


def significant(values, yardstick, weights):
    """The entries of `values` (one per coordinate) that are not zero against `yardstick`: none
    when their kinetic-energy norm √(Σ M_ii·v_i²) is within STEADY_TOL times the yardstick's,
    else those whose own term is beyond it. The norm weighs every coordinate in the same unit
    (M_ii carries the inverse square of its unit), so no choice of units changes the answer."""
    bound = STEADY_TOL * np.sqrt(weights @ yardstick ** 2)
    if not np.sqrt(weights @ values ** 2) > bound:
        return np.zeros(len(values), dtype=bool)
    return np.sqrt(weights) * np.abs(values) > bound


def unsteady_reasons(lin):
    """Why the operating point of `lin` is neither an equilibrium nor a steady motion, as text
    (empty when it is one): accelerations q̈0 ≠ 0, or rates along which the accelerations change
    (A·[q̇0, 0] ≠ 0 in the independent states). A steady motion y0 + t·[q̇0, 0] solves the
    linearized equations: a wheel's spin, a heading, a free body drifting. Both are measured
    against the model's own terms (`acceleration_yardstick`, and abs(A)·abs([q̇0, 0])) in the
    kinetic-energy norm (`significant`), so that no choice of units changes the answer."""
    names = lin.model_coordinates
    n = len(names)
    weights = np.ones(n) if lin.M_full is None else np.abs(np.diag(lin.M_full))
    reasons = []
    if lin.qdd0 is not None:
        off = significant(lin.qdd0, acceleration_yardstick(lin), weights)
        if off.any():
            reasons.append("its accelerations are not zero (" + ", ".join(
                f"{c}_ddot = {a:.4g}" for c, a, o in zip(names, lin.qdd0, off) if o) + ")")
    rates = np.array([lin.qd0[names.index(x)] if x in names else 0.0 for x in lin.states])
    change = lin.basis @ (lin.A @ rates)
    size = np.abs(lin.basis) @ (np.abs(lin.A) @ np.abs(rates))
    if any(significant(change[half], size[half], weights).any()
           for half in (slice(0, n), slice(n, 2 * n))):
        reasons.append("the accelerations change along its rates (" + ", ".join(
            f"{c}_dot = {v:.4g}" for c, v in zip(names, lin.qd0) if v) + ")")
    return " and ".join(reasons)


def warn_not_equilibrium(lin, reasons):
    """Warn (NotAnEquilibriumWarning) that modes are asked at a point that is neither an
    equilibrium nor a steady motion, for `reasons`."""
    choice = (" For a constrained model they also depend on which coordinates are dependent "
              "(dependent=...)." if len(lin.states) < 2 * len(lin.model_coordinates) else "")
    warnings.warn(
        f"model {lin.name!r}: the operating point is not an equilibrium or a steady motion: "
        f"{reasons}. These modes linearize that instant only; their frequencies and `stable` do "
        f"not describe the motion, which leaves the point.{choice} Find an equilibrium with "
        "lagrgen.equilibrium (or give the rates of a steady motion).",
        NotAnEquilibriumWarning, stacklevel=3)


def _is_symmetric(A):
    return np.abs(A - A.T).max() <= ZERO_TOL * max(np.abs(A).max(), np.finfo(float).tiny)


def _mass_normalize(shapes, M):
    """Scale each column φ so that φᴴ·M·φ = 1 and its largest entry is real and positive."""
    out = np.array(shapes)
    for i in range(out.shape[1]):
        phi = out[:, i]
        phi = phi / np.sqrt(np.real(np.conj(phi) @ M @ phi))
        big = phi[np.argmax(np.abs(phi))]
        out[:, i] = phi * (np.abs(big) / big)
    if np.iscomplexobj(out) and np.abs(out.imag).max() <= ZERO_TOL * np.abs(out).max():
        out = out.real.copy()
    return out


def undamped_modes(M, K):
    """Eigenvalues λ = ω² (ascending by real part) and mass-normalized shapes of K·φ = λ·M·φ.

    Symmetric K: scipy.linalg.eigh, so Φᵀ·M·Φ = I. Otherwise (circulatory forces) the general
    eigenproblem; λ may then be complex (flutter) and the shapes are only normalized one by one.
    """
    if _is_symmetric(K):
        lam, shapes = scipy.linalg.eigh((K + K.T) / 2, M)
    else:
        lam, shapes = scipy.linalg.eig(K, M)
        if np.abs(lam.imag).max() <= ZERO_TOL * max(np.abs(lam).max(), 1e-300):
            lam, shapes = lam.real, shapes.real
        order = ascending(lam)
        lam, shapes = lam[order], shapes[:, order]
    scale = max(np.abs(lam).max(), np.finfo(float).tiny)
    lam = np.where(np.abs(lam) <= ZERO_TOL * scale, 0.0, lam)
    return lam, _mass_normalize(shapes, M)


def decoupled_in_damping(lam, shapes, M, C):
    """M-orthonormal `shapes` with each group of a repeated λ (equal to ZERO_TOL of the largest)
    rotated to diagonalize its block Φ_gᵀ·C·Φ_g: a repeated frequency leaves any basis of its
    shapes, the damping picks the one whose modes it damps separately (to first order in C)."""
    if not np.any(C):
        return shapes
    out = np.array(shapes)
    tol = ZERO_TOL * max(np.abs(lam).max(initial=0.0), np.finfo(float).tiny)
    start = 0
    while start < len(lam):
        stop = start + 1
        while stop < len(lam) and abs(lam[stop] - lam[start]) <= tol:
            stop += 1
        if stop - start > 1:
            group = out[:, start:stop]
            block = group.T @ C @ group
            _, rotation = np.linalg.eigh((block + block.T) / 2)
            out[:, start:stop] = _mass_normalize(group @ rotation, M)
        start = stop
    return out


def state_matrix(M, C, K):
    """A = [[0, I], [−M⁻¹K, −M⁻¹C]], so that ẋ = A·x for x = [δq, δq̇]."""
    n = M.shape[0]
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -np.linalg.solve(M, K)
    A[n:, n:] = -np.linalg.solve(M, C)
    return A


def _assign(shapes, M, vectors):
    """Index of the undamped mode each damped eigenvector belongs to (two per mode).

    Maximizes the total mass-weighted modal assurance criterion
    MAC = |φᴴMψ|² / ((φᴴMφ)(ψᴴMψ)) with each mode taking exactly two eigenvalues.
    """
    n = shapes.shape[1]
    psi = vectors[:n]
    cross = np.abs(np.conj(shapes).T @ M @ psi) ** 2
    norm_phi = np.real(np.einsum("ij,ik,kj->j", np.conj(shapes), M, shapes))
    norm_psi = np.real(np.einsum("ij,ik,kj->j", np.conj(psi), M, psi))
    mac = cross / np.outer(norm_phi, np.maximum(norm_psi, np.finfo(float).tiny))
    rows, cols = linear_sum_assignment(-np.vstack([mac, mac]))
    mode_of = np.empty(2 * n, dtype=int)
    mode_of[cols] = rows % n
    return mode_of


def _ratio(pair, omega_n, scale):
    """(ζ, ω_d) of one mode from its two state-space eigenvalues s1, s2.

    A pair s = −ζω_n ± iω_d gives ζ = −Re s/|s|; two real ones (overdamped) give ω_n² = s1·s2 and
    ζ = −(s1 + s2)/(2√(s1·s2)). A rigid-body mode (ω_n = 0) has ζ = 0 when both s vanish — to
    √ε of the state matrix's eigenvalues `scale`, the accuracy of a defective double root — and
    is undefined (NaN) otherwise.
    """
    s1, s2 = pair
    size = max(abs(s1), abs(s2), np.finfo(float).tiny)
    if omega_n == 0 and size <= np.sqrt(np.finfo(float).eps) * scale:
        return 0.0, 0.0
    if abs(s1.imag) > ZERO_TOL * size:
        s = s1 if s1.imag > 0 else s2
        return -s.real / abs(s), abs(s.imag)
    a, b = s1.real, s2.real
    if omega_n == 0 or a * b <= 0:
        return np.nan, 0.0
    return -(a + b) / (2 * np.sqrt(a * b)), 0.0


def damping(M, C, K, shapes, omega):
    """Damping ratios ζ_i and damped frequencies ω_d,i from the eigenvalues of the state matrix."""
    n = M.shape[0]
    if not np.any(C):
        return np.zeros(n), np.array(omega)
    s, vectors = np.linalg.eig(state_matrix(M, C, K))
    mode_of = _assign(shapes, M, vectors)
    scale = max(1.0, np.abs(s).max())
    zeta, omega_d = np.zeros(n), np.zeros(n)
    for i in range(n):
        zeta[i], omega_d[i] = _ratio(s[mode_of == i], omega[i], scale)
    return zeta, omega_d


def modes(mod_or_lin, q0=None, qd0=None, p=None, u=None, t=0.0, dependent=None):
    """The modes of a linearization (see `Modes`): classical where there is a second-order form
    with symmetric C, else those of the state matrix A.

    Modes describe small motions about an equilibrium or a steady motion. At any other point
    (accelerations q̈0 ≠ 0, or rates along which they change) the linearization holds for that
    instant only, its frequencies and `stable` say nothing about the motion, and a
    NotAnEquilibriumWarning says so.

    Parameters
    ----------
    mod_or_lin : a built model, or a `Linearization`
    q0, qd0 : the operating point (q0 None: the equilibrium found near q = 0; qd0 None: at rest)
    p, u : parameters and constant inputs
    t : for a model that depends explicitly on t, the frozen time (FrozenTimeWarning)
    dependent : a constrained model's dependent coordinates and `<coordinate>_dot` rates, as for
        `linearize` (default: chosen by pivoted QR)

    Returns
    -------
    Modes: omega, frequencies_hz, shapes, damping_ratios, omega_damped, eigenvalues, stable.
    """
    if isinstance(mod_or_lin, Linearization):
        if dependent is not None:
            raise LagrgenError(
                "modes(lin, dependent=...): a Linearization has its independent states already "
                f"({', '.join(mod_or_lin.states)}); pass dependent= to lagrgen.linearize, or "
                "call lagrgen.modes(mod, q0, dependent=...) with the built model")
        refuse_point("modes", q0=q0, qd0=qd0, p=p, u=u, t=None if t == 0.0 else t)
    else:
        warn_frozen_time(mod_or_lin, t, "modal analysis")
    lin = as_linearization(mod_or_lin, q0, qd0, p, u, t, dependent)
    unsteady = unsteady_reasons(lin)
    if unsteady:
        warn_not_equilibrium(lin, unsteady)
    model = None if isinstance(mod_or_lin, Linearization) else mod_or_lin
    if lin.has_second_order_form and _is_symmetric(lin.C):
        result = classical_modes(lin, model)
        if not unsteady:
            warn_unstable_classical(result, lin.name)
        return result
    return state_modes(lin, model)


class UnstableModeWarning(UserWarning):
    """A classical mode has ω² < 0 (an unstable equilibrium): its ω and ζ are NaN."""


def warn_unstable_classical(result, name):
    """Warn (UnstableModeWarning) when classical modes have no real ω (ω² < 0)."""
    unstable = np.flatnonzero(np.isnan(result.omega))
    if unstable.size:
        warnings.warn(
            f"model {name!r}: {unstable.size} of {len(result.omega)} modes have ω² < 0 "
            f"(ω² = {', '.join(f'{w:.6g}' for w in np.real(result.omega_squared[unstable]))}): the "
            f"operating point is an unstable equilibrium, so their omega and damping_ratios are NaN; "
            f"read omega_squared and eigenvalues (stable is False)", UnstableModeWarning,
            stacklevel=3)


def classical_modes(lin, model=None):
    """Modes of M·δq̈ + C·δq̇ + K·δq = 0 with symmetric C: undamped ω and shapes of (K, M),
    damping ratios from the state matrix's eigenvalues assigned to them."""
    check_positive_definite(lin.name, lin.M, lin.t, lin.q0)
    lam, shapes = undamped_modes(lin.M, lin.K)
    if _is_symmetric(lin.K):
        shapes = decoupled_in_damping(lam, shapes, lin.M, lin.C)
    lam_real = np.real(lam)
    omega = np.full(lin.n, np.nan)
    omega[lam_real >= 0] = np.sqrt(lam_real[lam_real >= 0])
    zeta, omega_d = damping(lin.M, lin.C, lin.K, shapes, np.nan_to_num(omega))
    return Modes(omega=omega, shapes=lin.to_coordinates(shapes), damping_ratios=zeta,
                 omega_damped=omega_d, eigenvalues=lin.eigenvalues, linearization=lin,
                 model=model, omega_squared=lam, kind="classical", independent_shapes=shapes)


def state_modes(lin, model=None):
    """Modes of δẋ = A·δx: one per conjugate pair (the s with Im s > 0) or real eigenvalue s,
    ω = abs(s), ζ = −Re(s)/abs(s), ascending by ω; shapes are the coordinate part of basis·v."""
    s, vectors = np.linalg.eig(lin.A) if lin.A.size else (np.zeros(0), np.zeros((0, 0)))
    scale = max(1.0, np.abs(s).max(initial=0.0))
    keep = [i for i in range(len(s)) if s[i].imag > ZERO_TOL * scale
            or abs(s[i].imag) <= ZERO_TOL * scale]
    s, vectors = s[keep], vectors[:, keep]
    real = np.abs(s.imag) <= ZERO_TOL * scale
    s = np.where(real, s.real + 0j, s)
    omega = np.abs(s)
    order = np.lexsort((s.real, omega))
    s, vectors, omega = s[order], vectors[:, order], omega[order]
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(omega > ZERO_TOL * scale, -s.real / omega, 0.0) + 0.0   # no −0
    shapes = (lin.basis @ vectors)[:len(lin.q0)]
    for i in range(shapes.shape[1]):
        big = shapes[np.argmax(np.abs(shapes[:, i])), i]
        if big != 0:
            shapes[:, i] /= big
    if shapes.size and np.abs(shapes.imag).max() == 0:
        shapes = shapes.real
    return Modes(omega=omega, shapes=shapes, damping_ratios=zeta, omega_damped=np.abs(s.imag),
                 eigenvalues=lin.eigenvalues, linearization=lin, model=model, kind="state")


def input_index(names, input, model_name=""):
    """The position of `input` among the input `names`, or a clear error."""
    names = tuple(names)
    input = key_name(input)
    if not names:
        raise LagrgenError(
            f"model {model_name!r} has no inputs: declare one with model.inputs('F') to compute a "
            "frequency response")
    if input not in names:
        raise UnknownNameError(
            f"unknown input name {input!r}: the inputs of model {model_name!r} are {', '.join(names)}")
    return names.index(input)


def refuse_point(function, **given):
    """TypeError for the point and parameter arguments (those not None) of `function` called on
    a Linearization, which is taken at its own point and parameters."""
    named = [name for name, value in given.items() if value is not None]
    if named:
        raise TypeError(f"{function}(lin, {', '.join(f'{g}=...' for g in named)}): a "
                        "Linearization is taken at its own point and parameters; linearize "
                        "again (lagrgen.linearize(mod, q0, p=..., u=...)) or call "
                        f"lagrgen.{function}(mod, q0, p=..., u=...) with the built model")


def frequency_response(mod, q0, freqs_hz, input="F", p=None, u=None, qd0=None):
    """δq/δu at the frequencies `freqs_hz`, shape (len(freqs_hz), n), complex: with a
    second-order form H(f) = T_q·(K − ω²M + iωC)⁻¹·B[:, input] for ω = 2πf, else the coordinate
    rows of basis·(iωI − A)⁻¹·B[:, input].

    `mod` is a built model (linearized at (q0, qd0)) or a Linearization (then q0 None: it is
    taken at its own point and parameters; a TypeError for any of q0, qd0, p, u). Where the
    dynamic stiffness is singular (ω = 0 with a rigid-body mode, an undamped resonance) H is
    infinite.
    """
    lin = mod if isinstance(mod, Linearization) else None
    if lin is not None:
        refuse_point("frequency_response", q0=q0, qd0=qd0, p=p, u=u)
    names = lin.inputs if lin is not None else mod.inputs
    name = lin.name if lin is not None else mod.name
    j = input_index(names, input, name)
    if lin is None:
        lin = linearize(mod, q0, qd0, p=p, u=u)
    freqs = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if freqs.ndim != 1:
        raise ValueError(f"freqs_hz must be a 1-D array of frequencies, got shape {freqs.shape}")
    if not np.all(np.isfinite(freqs)):
        raise ValueError(f"freqs_hz must be finite, got {np.array2string(freqs, precision=6)}")
    second = lin.has_second_order_form
    b = lin.B[:, j] if second else lin.B_state[:, j]
    size = lin.n if second else len(lin.states)
    H = np.empty((len(freqs), size), dtype=complex)
    for k, w in enumerate(2 * np.pi * freqs):
        Z = (lin.K - w * w * lin.M + 1j * w * lin.C) if second else 1j * w * np.eye(size) - lin.A
        try:
            H[k] = np.linalg.solve(Z, b)
        except np.linalg.LinAlgError:
            H[k] = np.inf
    basis = lin.coordinate_basis if second else lin.basis[:len(lin.q0)]
    if basis.shape[0] == basis.shape[1] and np.array_equal(basis, np.eye(len(basis))):
        return H
    singular = ~np.all(np.isfinite(H), axis=1)
    with np.errstate(invalid="ignore"):
        out = np.where(singular[:, None], np.inf, np.nan_to_num(H) @ basis.T)
    return out
