"""Kinematics of three-dimensional rigid bodies: angular velocity from an orientation matrix.

For an orientation R(q, t) (body → fixed components), the body-frame angular velocity is the
vector of the skew matrix ω̃ = Rᵀ·Ṙ with Ṙ = Σ_j ∂R/∂q_j·q̇_j + ∂R/∂t, so ω = W(q, t)·q̇ + w₀(q, t)
with column j of W the vector of Rᵀ·∂R/∂q_j and w₀ that of Rᵀ·∂R/∂t; each entry is simplified
once (it is a polynomial in the sines and cosines of the angles that collapses with sin² + cos² = 1).
"""
import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef

from .errors import ModelError


def vee(S):
    """The vector s of a 3×3 skew matrix S = s̃ (S·v = s × v)."""
    return sp.Matrix([S[2, 1], S[0, 2], S[1, 0]])


def _simplify(expr):
    """A compact form of one angular-velocity coefficient (trigonometric identities)."""
    if expr == 0:
        return expr
    expr = sp.expand(expr)
    return sp.factor_terms(sp.trigsimp(expr))


class Kinematics:
    """W, w₀ (body frame) and their fixed-frame versions for one orientation R(q, t).

    Attributes (SymPy, in the model's symbols q_i(t) and t): `R`, `W` (3×n), `w0` (3×1),
    `omega` = W·q̇ + w₀ (body frame, contains dq_i/dt), `W_fixed` = R·W, `w0_fixed` = R·w₀.

    For a `lagrgen.rotation.Rotation` R = F_1·…·F_k of elementary rotations about axes e_i by
    angles α_i the angular velocities compose: ω_body = Σ_i (F_{i+1}·…·F_k)ᵀ·e_i·α̇_i and
    ω_fixed = Σ_i (F_1·…·F_{i−1})·e_i·α̇_i, with α̇_i = Σ_j ∂α_i/∂q_j·q̇_j + ∂α_i/∂t. Any other 3×3
    matrix goes through ω̃ = Rᵀ·Ṙ with each coefficient simplified.
    """

    def __init__(self, R, q, t):
        self.R = sp.Matrix(R)
        plain = sp.symbols(f"_lg_q0:{len(q)}")
        variables = list(plain) + [t]
        to_plain, back = dict(zip(q, plain)), dict(zip(plain, q))
        factors = getattr(R, "factors", None)
        if factors is not None and not _is_product(R, factors):
            factors = None              # changed in place after it was built: use the matrix
        if factors is not None:
            body, fixed = _composed(factors, to_plain, variables)
        else:
            body, fixed = _general(self.R.xreplace(to_plain), variables)
        self.W = sp.Matrix.hstack(*body[:-1]).xreplace(back) if q else sp.zeros(3, 0)
        self.w0 = body[-1].xreplace(back)
        self.W_fixed = sp.Matrix.hstack(*fixed[:-1]).xreplace(back) if q else sp.zeros(3, 0)
        self.w0_fixed = fixed[-1].xreplace(back)
        qd = sp.Matrix([c.diff(t) for c in q])
        self.omega = self.W * qd + self.w0 if q else self.w0
        self.omega_fixed = self.W_fixed * qd + self.w0_fixed if q else self.w0_fixed


def _is_product(R, factors):
    """True if R is (still) the product of its recorded elementary rotations (compared at a
    random point: products grouped differently are equal but not identical expressions)."""
    from .rotation import elementary
    P = sp.Matrix(elementary(*factors[0]))
    for f in factors[1:]:
        P = P * sp.Matrix(elementary(*f))
    R = sp.Matrix(R)
    symbols = sorted(R.free_symbols | P.free_symbols | R.atoms(AppliedUndef)
                     | P.atoms(AppliedUndef), key=str)
    values = dict(zip(symbols, np.random.default_rng(7).uniform(-1.3, 1.3, len(symbols))))
    try:
        diff = np.array((R - P).xreplace(values).evalf(), dtype=float)
    except (TypeError, ValueError):
        return False
    return bool(np.abs(diff).max() < 1e-12)


def _composed(factors, to_plain, variables):
    """Body- and fixed-frame coefficient columns (one per variable) from the factor rotations."""
    from .rotation import _AXES, elementary
    mats = [sp.Matrix(elementary(axis, angle.xreplace(to_plain))) for axis, angle in factors]
    body = [sp.zeros(3, 1) for _ in variables]
    fixed = [sp.zeros(3, 1) for _ in variables]
    for i, (axis, angle) in enumerate(factors):
        angle = angle.xreplace(to_plain)
        rates = [angle.diff(v) for v in variables]
        if not any(r != 0 for r in rates):
            continue
        e = sp.Matrix(_AXES[axis])
        vb = e
        for F in mats[i + 1:]:
            vb = F.T * vb
        vf = e
        for F in reversed(mats[:i]):
            vf = F * vf
        for k, r in enumerate(rates):
            if r != 0:
                body[k] += vb * r
                fixed[k] += vf * r
    return body, fixed


def _general(Rp, variables):
    """Coefficient columns vee(Rᵀ·∂R/∂v) and vee(∂R/∂v·Rᵀ) of a plain matrix, simplified."""
    Rt = Rp.T
    body, fixed = [], []
    for v in variables:
        dR = Rp.diff(v)
        if dR == sp.zeros(3, 3):
            body.append(sp.zeros(3, 1))
            fixed.append(sp.zeros(3, 1))
            continue
        body.append(vee(Rt * dR).applyfunc(_simplify))
        fixed.append(vee(dR * Rt).applyfunc(_simplify))
    return body, fixed


def check_rotation(R, symbols, where, rng=None):
    """Raise ModelError unless R, evaluated at a random point of `symbols`, is a rotation."""
    rng = rng or np.random.default_rng(12345)
    values = {s: sp.Float(v) for s, v in zip(symbols, rng.uniform(-1.3, 1.3, len(symbols)))}
    try:
        Rn = np.array(R.xreplace(values).evalf(), dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{where}: cannot evaluate the orientation numerically") from None
    err = np.abs(Rn.T @ Rn - np.eye(3)).max()
    if not np.isfinite(err) or err > 1e-9:
        raise ModelError(
            f"{where}: the orientation is not a rotation matrix (RᵀR − I has an entry of {err:.3g} "
            "at a random point); build it from lagrgen.rotation.x/y/z")
    if np.linalg.det(Rn) < 0:
        raise ModelError(f"{where}: the orientation has determinant −1 (a reflection, not a "
                         "rotation); build it from lagrgen.rotation.x/y/z")


def body_inertia(model, inertia):
    """The 3×3 inertia matrix (SymPy) from a 3×3 matrix or 3 principal moments, checked."""
    where = "rigid_body_3d inertia"
    if isinstance(inertia, sp.MatrixBase):
        I = sp.Matrix(inertia)
        if I.shape == (3, 1) or I.shape == (1, 3):
            I = sp.diag(*I)
    elif isinstance(inertia, (list, tuple)):
        if len(inertia) == 3 and all(not isinstance(e, (list, tuple)) for e in inertia):
            I = sp.diag(*[sp.sympify(e) for e in inertia])
        else:
            try:
                I = sp.Matrix(inertia)
            except Exception:
                raise ModelError(f"{where} must be a 3×3 matrix or 3 principal moments, "
                                 f"got {inertia!r}") from None
    else:
        raise ModelError(f"{where} must be a 3×3 matrix or a list/tuple of 3 principal moments, "
                         f"got {type(inertia).__name__}")
    if I.shape != (3, 3):
        raise ModelError(f"{where} must be a 3×3 matrix or 3 principal moments, got shape "
                         f"{I.shape}")
    model._check(I, where, velocities=False, inputs=False, vector=True)
    moving = set(model.q) | {model.t}
    if any(e.has(*moving) for e in I):
        raise ModelError(f"{where} must be constant (numbers and parameters) in body axes; it "
                         "depends on the coordinates or t")
    if any(sp.simplify(I[i, j] - I[j, i]) != 0 for i in range(3) for j in range(i)):
        raise ModelError(f"{where} must be symmetric, got {I.tolist()}")
    defaults = {s: d for s, d in zip(model.parameter_symbols, model.parameter_defaults)
                if d is not None}
    numeric = I.xreplace({s: sp.Float(v) for s, v in defaults.items()})
    if not numeric.free_symbols:
        eig = np.linalg.eigvalsh(np.array(numeric.evalf(), dtype=float))
        if eig.min() < -1e-12 * max(1.0, abs(eig).max()):
            raise ModelError(f"{where} must be positive semi-definite (principal moments ≥ 0); "
                             f"its eigenvalues are {eig}")
        if eig[2] > eig[0] + eig[1] + 1e-9 * max(1e-3, abs(eig).max()):
            raise ModelError(f"{where} breaks the triangle inequality: its principal moments "
                             f"{eig} have the largest above the sum of the other two, which no "
                             "mass distribution gives (a thin rod's are (I, I, 0), a flat plate's "
                             "(a, b, a + b))")
    return I


def rotational_kinetic_energy(model):
    """Σ ½·ωᵀ·I·ω over the model's `rigid_body_3d`s (SymPy, in the model's symbols): the part of T
    that is not in its particles and kinetic-energy terms (for energy outputs)."""
    return sum(((w.T * I * w)[0] / 2 for I, w in model.spec().bodies_3d), sp.Integer(0))
