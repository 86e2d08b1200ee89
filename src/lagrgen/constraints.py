"""Constraints at run time: projecting a state onto them, checking they are independent, and the
multipliers and residuals along a solution.

A constrained model (the guide's "Constraints") satisfies M·q̈ = F + Aᵀ·λ, A·q̈ = γ with
A = [Φ_q; A_v]; its `constraint_residuals(t, y)` are Φ(q, t) (holonomic) followed by
c = A·q̇ + b (all constraints).
Since c is affine in q̇, A is read off c exactly: column j is c(q, e_j) − c(q, 0).
"""
import warnings

import numpy as np

from .errors import ConstraintError
from .runtime.arguments import input_vector, state_vector
from .runtime.arguments import parameters_from

#: Relative singular value below which A counts as rank-deficient (dependent constraints).
RANK_TOL = 1e-10


def velocity_terms(mod, t, q, p, u=None):
    """(Φ, A, b): the holonomic residuals Φ(q, t), and A (m×n), b (m) of c = A·q̇ + b at (q, t)."""
    n, m = mod.n_coordinates, mod.n_constraints
    y = np.concatenate([q, np.zeros(n)])
    r0 = mod.constraint_residuals(t, y, p, u)
    n_h = len(r0) - m
    b = r0[n_h:]
    A = np.empty((m, n))
    for j in range(n):
        y[n + j] = 1.0
        A[:, j] = mod.constraint_residuals(t, y, p, u)[n_h:] - b
        y[n + j] = 0.0
    return r0[:n_h], A, b


def check_independent(mod, t, y, A, what="state"):
    """Raise ConstraintError naming the state unless A (m×n) has full row rank."""
    s = np.linalg.svd(A, compute_uv=False) if A.size else np.zeros(0)
    if A.shape[0] > A.shape[1] or (s.size and not s[-1] > RANK_TOL * max(s[0], 1e-300)):
        n = mod.n_coordinates
        rank = int(np.sum(s > RANK_TOL * max(s[0], 1e-300))) if s.size else 0
        names = ", ".join(f"{c}={v:.6g}" for c, v in zip(mod.coordinates, y[:n]))
        raise ConstraintError(
            f"the {A.shape[0]} constraints of model {mod.name!r} are redundant at the {what} "
            f"t={t!r}, {names}: the constraint Jacobian A = [Φ_q; A_v] has rank {rank} < "
            f"{A.shape[0]}. Remove the dependent constraint(s), or start away from this singular "
            "configuration")


def consistent_state(mod, y_guess, t=0.0, p=None, u=None, tol=1e-12, max_iter=50):
    """Project y_guess = [q, q̇] onto the constraints: q onto Φ(q, t) = 0 by Newton's method with
    minimum-norm steps δq = −Φ_qᵀ(Φ_q·Φ_qᵀ)⁻¹·Φ (the least change, to first order), then q̇ onto
    A·q̇ + b = 0 by the least-change q̇ − Aᵀ(A·Aᵀ)⁻¹(A·q̇ + b).

    Parameters
    ----------
    mod : a built model (either backend); an unconstrained one returns y_guess unchanged
    y_guess : 2n numbers, or a dict of coordinate and `<coordinate>_dot` names
    t : float, the time (rheonomic constraints)
    p : parameters (dict or array; None: defaults); u : inputs (None: zeros)
    tol : ‖Φ‖ and ‖A·q̇ + b‖ at the result are at most tol·max(1, ‖q‖) (resp. max(1, ‖q̇‖))

    Returns
    -------
    y : float64 array (2n,) satisfying the constraints.

    Raises ConstraintError when the constraints are redundant at the state or Newton's method
    does not converge (no nearby configuration satisfies them).
    """
    n = mod.n_coordinates
    y = np.array(state_vector(y_guess, tuple(mod.coordinates), "y_guess"), dtype=float)
    if not np.all(np.isfinite(y)):
        raise ValueError(f"y_guess must be finite, got {y}")
    if not mod.n_constraints:
        return y
    p = parameters_from(mod, p)
    u = input_vector(u, tuple(mod.inputs))
    t = float(t)
    q = y[:n]
    for _ in range(max_iter):
        phi, A, _ = velocity_terms(mod, t, q, p, u)
        if np.abs(phi).max(initial=0.0) <= tol * max(1.0, np.abs(q).max()):
            break
        check_independent(mod, t, np.concatenate([q, y[n:]]), A[:len(phi)])
        Ah = A[:len(phi)]
        q = q - Ah.T @ np.linalg.solve(Ah @ Ah.T, phi)
        if not np.all(np.isfinite(q)):
            break
    else:
        q = None
    if q is None or not np.all(np.isfinite(q)):
        names = ", ".join(f"{c}={v:.6g}" for c, v in zip(mod.coordinates, y[:n]))
        raise ConstraintError(
            f"cannot satisfy the constraints of model {mod.name!r} near {names} at t={t!r}: "
            f"Newton's method did not converge in {max_iter} steps; give a closer guess")
    y[:n] = q
    _, A, b = velocity_terms(mod, t, q, p, u)
    check_independent(mod, t, y, A)
    qd = y[n:]
    y[n:] = qd - A.T @ np.linalg.solve(A @ A.T, A @ qd + b)
    return y


def check_state(mod, t, y, p, u=None):
    """Raise ConstraintError if the constraints of `mod` are redundant at (t, y)."""
    if mod.n_constraints:
        _, A, _ = velocity_terms(mod, float(t), np.asarray(y[:mod.n_coordinates]), p, u)
        check_independent(mod, t, y, A, "initial state")


class ConstraintWarning(UserWarning):
    """A simulation starts from a state that violates the model's constraints."""


#: Relative size of the constraint residuals of an initial state above which `simulate` warns.
START_TOL = 1e-6


def warn_off_constraints(mod, t, y, p, u=None, stacklevel=3):
    """Warn ConstraintWarning where the state y violates the constraints (residuals Φ and
    A·q̇ + b) by more than START_TOL of max(1, |y|): Baumgarte's stabilization then pulls the
    motion onto them through a transient that is no motion of the system (a pendulum started
    at |r| = 1.27 for L = 1 ran with success True and no word)."""
    if not mod.n_constraints:
        return
    r = np.abs(mod.constraint_residuals(float(t), np.asarray(y, dtype=float), p, u))
    if r.max(initial=0.0) > START_TOL * max(1.0, np.abs(y).max()):
        names, n_h = tuple(mod.info.constraint_names), mod.info.n_holonomic
        worst = int(np.argmax(r))
        which = f"of {names[worst]!r}" if worst < n_h else \
            f"of the rate of {names[worst - n_h]!r}"
        warnings.warn(f"the initial state of model {mod.name!r} violates its constraints (largest "
                      f"residual {r.max():.3g}, {which}): the stabilization pulls the motion "
                      "onto them through a transient that is no motion of the system; start "
                      "from lagrgen.consistent_state(mod, y0)", ConstraintWarning,
                      stacklevel=stacklevel)


def along(mod, sol, p, u_at, forces=True):
    """(λ, residuals) at every output time of `sol`: arrays (m, len(t)) and (n_h + m, len(t));
    λ None without `forces` (a hybrid solve brings its own, with its contacts held)."""
    lam = np.empty((mod.n_constraints, len(sol.t))) if forces else None
    res = np.empty((mod.dimensions["n_residuals"], len(sol.t)))
    for k, t in enumerate(sol.t):
        uk = u_at(t)
        if forces:
            lam[:, k] = mod.constraint_forces(t, sol.y[:, k], p, uk)
        res[:, k] = mod.constraint_residuals(t, sol.y[:, k], p, uk)
    return lam, res
