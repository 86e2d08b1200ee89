"""Rotation matrices for three-dimensional rigid bodies.

Convention: every matrix here is an *active*, right-handed rotation R that maps the components of a
vector in the body frame to its components in the fixed frame, r_fixed = R·r_body. The columns of R
are the body axes written in the fixed frame.

`x(angle)`, `y(angle)`, `z(angle)` are the elementary rotations about the (current) x, y, z axes.
Products compose in the order the rotations are applied to the body's own axes (intrinsic
sequences): ``z(psi) * x(theta) * z(phi)`` is the classical z-x-z Euler sequence (precession ψ,
nutation θ, spin φ) and ``z(yaw) * y(pitch) * x(roll)`` the z-y-x Tait–Bryan (aircraft) sequence.
Read the same product from right to left and it is the extrinsic sequence about the fixed axes.

Every three-angle sequence is singular somewhere (gimbal lock): a proper Euler sequence
(z-x-z, z-y-z, ...) where the middle angle is 0 or π, a Tait–Bryan sequence (z-y-x, x-y-z, ...)
where the middle angle is ±π/2. There the three angles no longer describe three independent
rotations and the mass matrix is singular; choose the sequence so that the motion stays away from
that configuration (e.g. a top that stands upright: z-y-x or x-y-z with the spin last, not z-x-z).
"""
import sympy as sp

__all__ = ["x", "y", "z", "sequence", "is_rotation", "Rotation"]

_AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


class Rotation(sp.MutableDenseMatrix):
    """A 3×3 SymPy Matrix that remembers the elementary rotations it is the product of.

    `factors` is a tuple of (axis letter, angle) in product order, or None when unknown (after
    any operation other than a product of two `Rotation` matrices). lagrgen uses the factors to write the
    angular velocity in closed form (ω_body = Σ_i (F_{i+1}·…·F_k)ᵀ·e_i·(d angle_i/dt)); a plain
    matrix works too, at the cost of a symbolic simplification.
    """
    factors = None

    def __mul__(self, other):
        result = sp.Matrix(self) * other
        if isinstance(other, Rotation) and self.factors is not None \
                and other.factors is not None:
            return _rotation(result, self.factors + other.factors)
        return result


def _rotation(matrix, factors):
    R = Rotation(matrix)
    R.factors = tuple(factors)
    return R


def elementary(axis, angle):
    """The elementary rotation about `axis` ('x', 'y' or 'z') by `angle`, as a `Rotation`."""
    c, s = sp.cos(angle), sp.sin(angle)
    rows = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]],
            "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
            "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
    return _rotation(rows, [(axis, sp.sympify(angle))])


def x(angle):
    """Rotation by `angle` about the x axis: R·e_x = e_x, R·e_y = cos·e_y + sin·e_z.

    Parameters: angle, a SymPy expression (a coordinate, an expression of t, a number).
    Returns: a 3×3 SymPy Matrix (a `Rotation`).
    """
    return elementary("x", angle)


def y(angle):
    """Rotation by `angle` about the y axis: R·e_z = cos·e_z + sin·e_x.

    Parameters: angle, a SymPy expression. Returns: a 3×3 SymPy Matrix (a `Rotation`).
    """
    return elementary("y", angle)


def z(angle):
    """Rotation by `angle` about the z axis: R·e_x = cos·e_x + sin·e_y.

    Parameters: angle, a SymPy expression. Returns: a 3×3 SymPy Matrix (a `Rotation`).
    """
    return elementary("z", angle)


def sequence(axes, angles):
    """The product of elementary rotations, e.g. ``sequence("zxz", (psi, theta, phi))`` =
    z(psi)·x(theta)·z(phi) (intrinsic: each rotation about the axes already rotated).

    Parameters: axes, a string of 'x', 'y', 'z'; angles, as many expressions.
    Returns: a 3×3 SymPy Matrix (a `Rotation`).
    """
    from .errors import ModelError
    axes = str(axes).lower()
    angles = list(angles)
    if not axes or set(axes) - set("xyz") or len(axes) != len(angles):
        raise ModelError(f"rotation sequence {axes!r} needs letters from 'xyz' and one angle "
                         f"each; got {len(angles)} angles")
    R = elementary(axes[0], angles[0])
    for axis, angle in zip(axes[1:], angles[1:]):
        R = R * elementary(axis, angle)
    return R


def is_rotation(R, tol=1e-9):
    """True if the numeric 3×3 matrix R satisfies RᵀR = I and det R = +1 within `tol`."""
    import numpy as np
    R = np.asarray(R, dtype=float)
    return (R.shape == (3, 3) and np.allclose(R.T @ R, np.eye(3), atol=tol)
            and abs(np.linalg.det(R) - 1.0) < tol)


def quaternion_matrix(z, homogeneous=False):
    """R = R_h(ζ)/|ζ|²: the rotation of the direction of the quaternion ζ = (x, y, z, w) (3×3
    lists; `homogeneous`: R_h(ζ) = |ζ|²·R, quadratic in ζ; any ring's symbols, SymPy's too)."""
    x, y, z_, w = z
    R = [[w * w + x * x - y * y - z_ * z_, 2 * (x * y - w * z_), 2 * (x * z_ + w * y)],
         [2 * (x * y + w * z_), w * w - x * x + y * y - z_ * z_, 2 * (y * z_ - w * x)],
         [2 * (x * z_ - w * y), 2 * (y * z_ + w * x), w * w - x * x - y * y + z_ * z_]]
    if homogeneous:
        return R
    n2 = x * x + y * y + z_ * z_ + w * w
    return [[e / n2 for e in row] for row in R]
