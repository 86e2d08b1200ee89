"""Small oscillations about an operating point: equilibrium, linearization, modes, frequency response.

About an operating point (q0, q̇0, u0) the equations M(q, t)·q̈ = F(q, q̇, t, u) become

    M·δq̈ + C·δq̇ + K·δq = B·δu,   M = M(q0),  K = −∂F/∂q,  C = −∂F/∂q̇,  B = ∂F/∂u,

with the derivatives taken analytically by the built model's `linear_terms` (either backend).
The term (∂M/∂q·q̈0)·δq is absent, so the linearization is exact to first order at an equilibrium
(q̈0 = 0), which is where modes and frequency responses are meant to be computed.

A constrained model (M·q̈ = F + Aᵀλ, A·q̈ = γ) is linearized in its independent directions:
δq = N·ξ with N an orthonormal basis of the null space of A(q0), and

    M_r = NᵀMN,  C_r = NᵀCN,  K_r = Nᵀ(K − ∂(Aᵀλ0)/∂q)N,  B_r = NᵀB,

λ0 the multipliers at the operating point (the term ∂(Aᵀλ0)/∂q is the stiffness the constraint
forces add, e.g. the tension of a pendulum's rod). This is exact to first order for holonomic
constraints; velocity constraints are imposed on δq the same way (motions that satisfy them to
first order). The linearization's `basis` is N; mode shapes are returned in the full
coordinates, N·φ.
"""
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy.optimize import linear_sum_assignment, root

from .runtime.arguments import as_vector, input_vector
from .errors import LagrgenError, MassMatrixError, NonFiniteError, UnknownNameError
from .runtime.arguments import parameters_from

#: Relative size below which an eigenvalue ω² (or an imaginary part, an asymmetry) counts as zero.
ZERO_TOL = 1e-9


class EquilibriumError(LagrgenError, RuntimeError):
    """No equilibrium F(q, 0) = 0 was found near the guess."""


class FrozenTimeWarning(UserWarning):
    """The model depends explicitly on t: a result holds only at the one frozen time t given."""


def warn_frozen_time(mod, t, what):
    """Warn (FrozenTimeWarning) that `what` of a rheonomic model `mod` holds only at time t."""
    if mod.explicit_time:
        warnings.warn(
            f"model {mod.name!r} depends explicitly on t: this {what} is for the frozen time "
            f"t = {float(t):g} only (the system has no static equilibrium in general; pass t= to "
            "choose the instant)", FrozenTimeWarning, stacklevel=3)


@dataclass
class Linearization:
    """M·δq̈ + C·δq̇ + K·δq = B·δu about (q0, qd0, t, p, u); arrays (n,n),(n,n),(n,n),(n,n_inputs)."""

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    B: np.ndarray
    q0: np.ndarray
    qd0: np.ndarray
    t: float = 0.0
    p: np.ndarray = None
    u: np.ndarray = None
    coordinates: tuple = ()
    inputs: tuple = ()
    name: str = ""
    basis: np.ndarray = None   # constrained models: N (n×k), δq = N·ξ; M, C, K, B are in ξ
    constraint_forces: np.ndarray = None  # constrained models: λ0 at the operating point

    @property
    def n(self):
        """The number of independent coordinates (rows of M)."""
        return self.M.shape[0]

    def to_coordinates(self, xi):
        """Vectors or columns in the reduced coordinates ξ as δq = N·ξ (unchanged without
        constraints)."""
        return xi if self.basis is None else self.basis @ xi

    @property
    def names(self):
        """The coordinate names, in the order of the rows and columns of M, C, K."""
        return self.coordinates

    def state_matrices(self):
        """(A, B, C, D) of ẋ = A·x + B·δu, y = C·x + D·δu with x = [δq, δq̇], y = x:
        A = [[0, I], [−M⁻¹K, −M⁻¹C]], B = [[0], [M⁻¹B]], C = I (2n), D = 0."""
        n, k = self.n, self.B.shape[1]
        A = state_matrix(self.M, self.C, self.K)
        B = np.zeros((2 * n, k))
        if k:
            B[n:] = np.linalg.solve(self.M, self.B)
        return A, B, np.eye(2 * n), np.zeros((2 * n, k))

    def state_space(self):
        """This linearization as `scipy.signal.StateSpace` (x = [δq, δq̇], u = δu, y = x); a model
        without inputs gets one zero input column (SciPy needs at least one)."""
        from scipy.signal import StateSpace
        A, B, C, D = self.state_matrices()
        if B.shape[1] == 0:
            B, D = np.zeros((A.shape[0], 1)), np.zeros((A.shape[0], 1))
        return StateSpace(A, B, C, D)

    @property
    def state_names(self):
        """Names of the states x = [δq, δq̇]: the coordinates, then `<coordinate>_dot`."""
        return tuple(self.coordinates) + tuple(f"{c}_dot" for c in self.coordinates)


@dataclass
class Modes:
    """Natural frequencies, mass-normalized mode shapes and damping ratios of a Linearization.

    `omega[i]` = √λ_i for the eigenvalues λ_i of K·φ = λ·M·φ in ascending order (rad/s; 0 for a
    rigid-body mode, NaN where λ < 0: an unstable equilibrium); `shapes[:, i]` = φ_i with
    φ_iᵀ·M·φ_i = 1 (and φᵀ·M·φ = I when K is symmetric; for a constrained model the k
    independent modes in the full coordinates, n×k, N·φ with (Nφ)ᵀ·M·(Nφ) = I);
    `damping_ratios[i]` = ζ_i of the
    eigenvalues s = −ζω_n ± iω_n√(1−ζ²) of the state-space matrix matched to mode i.
    """

    omega: np.ndarray
    shapes: np.ndarray
    damping_ratios: np.ndarray
    omega_damped: np.ndarray
    eigenvalues: np.ndarray
    linearization: Linearization = field(repr=False, default=None)
    model: object = field(repr=False, default=None)   # the built model analysed (None: from a lin)

    @property
    def frequencies_hz(self):
        """ω / 2π."""
        return self.omega / (2 * np.pi)

    @property
    def stable(self):
        """True for each mode whose ω² is not negative."""
        return ~np.isnan(self.omega)

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


def _operating_point(mod, q, name, p, u):
    n = mod.n_coordinates
    q = as_vector(q, n, f"{name} (one value per coordinate {', '.join(mod.coordinates)})")
    return q, parameters_from(mod, p), input_vector(u, tuple(mod.inputs))


def equilibrium(mod, q_guess, p=None, u=None, t=0.0, tol=1e-9):
    """The configuration q with F(q, 0, t, u) = 0 nearest `q_guess`, found by scipy.optimize.root.

    The analytic ∂F/∂q (from `mod.linear_terms`) is the Jacobian. Levenberg–Marquardt goes first,
    so a direction in which F vanishes identically (a rigid-body mode) keeps its guessed value;
    Powell's hybrid method is the fallback. Raises EquilibriumError unless the residual satisfies
    max|F_i| ≤ tol·max(1, max|∂F_i/∂q_j|).
    """
    q_guess, p, u = _operating_point(mod, q_guess, "q_guess", p, u)
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


def _reduce(mod, lin):
    """`lin` of a constrained model restricted to δq = N·ξ, N = null space of A(q0) (see the
    module docstring)."""
    from .constraints import check_independent
    A, lam, H = mod.constraint_terms(lin.q0, lin.qd0, lin.t, lin.p, lin.u)
    check_independent(mod, lin.t, np.concatenate([lin.q0, lin.qd0]), A, "operating point")
    N = scipy.linalg.null_space(A)
    if N.shape[1] == 0:
        raise LagrgenError(
            f"model {mod.name!r} has no independent directions at q0: its {A.shape[0]} "
            f"constraints fix all {A.shape[1]} coordinates, so it has no modes")
    K = lin.K - H
    lin.M, lin.C, lin.K, lin.B = N.T @ lin.M @ N, N.T @ lin.C @ N, N.T @ K @ N, N.T @ lin.B
    lin.basis, lin.constraint_forces = N, lam
    lin.coordinates = tuple(f"xi{i + 1}" for i in range(N.shape[1]))
    return lin


def check_mass_matrix(lin):
    """Raise MassMatrixError unless lin.M is symmetric positive definite (NonFiniteError when
    an entry overflowed)."""
    if not np.isfinite(lin.M).all() and np.isfinite(lin.q0).all():
        raise NonFiniteError.in_mass_matrix(lin.name, lin.t, lin.q0)
    try:
        np.linalg.cholesky(lin.M)
    except np.linalg.LinAlgError:
        raise MassMatrixError.at(lin.name, lin.t, lin.q0) from None


def linearize(mod, q0, qd0=None, t=0.0, p=None, u=None):
    """M·δq̈ + C·δq̇ + K·δq = B·δu about (q0, qd0): M(q0), K = −∂F/∂q, C = −∂F/∂q̇, B = ∂F/∂u.

    Parameters
    ----------
    mod : a built model; q0, qd0 : the operating point (qd0 None: at rest)
    t : the time at which a model that depends explicitly on t is frozen (FrozenTimeWarning)
    p, u : parameters and constant inputs at the operating point

    Returns
    -------
    A `Linearization` (see also `Linearization.state_space`).
    """
    q0, p, u = _operating_point(mod, q0, "q0", p, u)
    warn_frozen_time(mod, t, "linearization")
    n = mod.n_coordinates
    qd0 = np.zeros(n) if qd0 is None else as_vector(qd0, n, "qd0")
    M, dF_dq, dF_dqd, dF_du = mod.linear_terms(q0, qd0, float(t), p, u)
    lin = Linearization(M=M, C=-dF_dqd, K=-dF_dq, B=dF_du, q0=q0, qd0=qd0, t=float(t), p=p, u=u,
                        coordinates=tuple(mod.coordinates), inputs=tuple(mod.inputs),
                        name=mod.name)
    if mod.n_constraints:
        lin = _reduce(mod, lin)
    check_mass_matrix(lin)
    return lin


def as_linearization(mod_or_lin, q0=None, p=None, u=None, t=0.0):
    """A Linearization as given, or the built model linearized at q0 (None: the equilibrium near 0)
    at time t."""
    if isinstance(mod_or_lin, Linearization):
        return mod_or_lin
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FrozenTimeWarning)   # modes warns once, below
        if q0 is None:
            q0 = equilibrium(mod_or_lin, np.zeros(mod_or_lin.n_coordinates), p=p, u=u, t=t)
        return linearize(mod_or_lin, q0, t=t, p=p, u=u)


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
        order = np.argsort(lam.real, kind="stable")
        lam, shapes = lam[order], shapes[:, order]
    scale = max(np.abs(lam).max(), np.finfo(float).tiny)
    lam = np.where(np.abs(lam) <= ZERO_TOL * scale, 0.0, lam)
    return lam, _mass_normalize(shapes, M)


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


def _ratio(pair, omega_n):
    """(ζ, ω_d) of one mode from its two state-space eigenvalues s1, s2.

    A pair s = −ζω_n ± iω_d gives ζ = −Re s/|s|; two real ones (overdamped) give ω_n² = s1·s2 and
    ζ = −(s1 + s2)/(2√(s1·s2)). A rigid-body mode (ω_n = 0) has ζ = 0 when both s vanish and is
    undefined (NaN) otherwise.
    """
    s1, s2 = pair
    scale = max(abs(s1), abs(s2), np.finfo(float).tiny)
    if abs(s1.imag) > ZERO_TOL * scale:
        s = s1 if s1.imag > 0 else s2
        return -s.real / abs(s), abs(s.imag)
    a, b = s1.real, s2.real
    if omega_n == 0 or a * b <= 0:
        return (0.0 if scale <= ZERO_TOL * max(1.0, omega_n) else np.nan), 0.0
    return -(a + b) / (2 * np.sqrt(a * b)), 0.0


def damping(M, C, K, shapes, omega):
    """Damping ratios ζ_i and damped frequencies ω_d,i from the eigenvalues of the state matrix."""
    n = M.shape[0]
    if not np.any(C):
        return np.zeros(n), np.array(omega)
    s, vectors = np.linalg.eig(state_matrix(M, C, K))
    mode_of = _assign(shapes, M, vectors)
    zeta, omega_d = np.zeros(n), np.zeros(n)
    for i in range(n):
        zeta[i], omega_d[i] = _ratio(s[mode_of == i], omega[i])
    return zeta, omega_d


def modes(mod_or_lin, q0=None, p=None, u=None, t=0.0):
    """Natural frequencies, mass-normalized mode shapes and damping ratios (see `Modes`).

    `mod_or_lin` is a built model, linearized at q0 (None: the equilibrium found near q = 0) at
    time t (for a model that depends explicitly on t: the frozen time, with a FrozenTimeWarning),
    or a `Linearization`.
    """
    if not isinstance(mod_or_lin, Linearization):
        warn_frozen_time(mod_or_lin, t, "modal analysis")
    lin = as_linearization(mod_or_lin, q0, p, u, t)
    check_mass_matrix(lin)
    lam, shapes = undamped_modes(lin.M, lin.K)
    lam_real = np.real(lam)
    omega = np.full(lin.n, np.nan)
    omega[lam_real >= 0] = np.sqrt(lam_real[lam_real >= 0])
    zeta, omega_d = damping(lin.M, lin.C, lin.K, shapes, np.nan_to_num(omega))
    shapes = lin.to_coordinates(shapes)
    return Modes(omega=omega, shapes=shapes, damping_ratios=zeta, omega_damped=omega_d,
                 eigenvalues=lam, linearization=lin,
                 model=None if isinstance(mod_or_lin, Linearization) else mod_or_lin)


def input_index(names, input, model_name=""):
    """The position of `input` among the input `names`, or a clear error."""
    names = tuple(names)
    if not names:
        raise LagrgenError(
            f"model {model_name!r} has no inputs: declare one with model.inputs('F') to compute a "
            "frequency response")
    if input not in names:
        raise UnknownNameError(
            f"unknown input name {input!r}: the inputs of model {model_name!r} are {', '.join(names)}")
    return names.index(input)


def frequency_response(mod, q0, freqs_hz, input="F", p=None, u=None):
    """H(f) = (K − ω²M + iωC)⁻¹·B[:, input] for ω = 2πf: δq/δu, shape (len(freqs_hz), n), complex.

    `mod` is a built model (linearized at q0) or a Linearization (q0 ignored). Where the dynamic
    stiffness is singular (ω = 0 with a rigid-body mode, an undamped resonance) H is infinite.
    """
    lin = mod if isinstance(mod, Linearization) else None
    names = lin.inputs if lin is not None else mod.inputs
    name = lin.name if lin is not None else mod.name
    j = input_index(names, input, name)
    if lin is None:
        lin = linearize(mod, q0, p=p, u=u)
    freqs = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if freqs.ndim != 1:
        raise ValueError(f"freqs_hz must be a 1-D array of frequencies, got shape {freqs.shape}")
    b = lin.B[:, j]
    H = np.empty((len(freqs), lin.n), dtype=complex)  # in ξ for a constrained model
    for k, w in enumerate(2 * np.pi * freqs):
        Z = lin.K - w * w * lin.M + 1j * w * lin.C
        try:
            H[k] = np.linalg.solve(Z, b)
        except np.linalg.LinAlgError:
            H[k] = np.inf
    return H if lin.basis is None else H @ lin.basis.T
