"""World frames of an `Articulation`'s segments (SymEngine, internal symbols), composed from the
parent's down the tree, as nested (not expanded) expressions.

Segment k's frame has the orientation R_k = R_λ·P_k·J_k (P_k its placement's rotation, J_k the
rotation of a revolute joint by its motion θ_k about the unit axis a: I + sin θ·[a]× +
(1 − cos θ)·[a]×²; the identity for a prismatic one) and the origin p_k = p_λ + R_λ·(o_k + P_k·a·θ_k)
(the last term for a prismatic joint only). Its angular velocity is ω_k = ω_λ + R_λ·P_k·a·θ̇_k
(revolute), its origin's velocity ṗ_k = ṗ_λ + ω_λ × (p_k − p_λ) + R_λ·P_k·a·θ̇_k (prismatic); the
joint's twist per unit rate, in Plücker coordinates at the fixed origin O, is
s_k = [ω_a; p_k × ω_a] with ω_a = R_λ·P_k·a (revolute) or [0; R_λ·P_k·a] (prismatic).

A body of dynamic parameters (m, h = m·c, I_O) about its frame's origin, in its axes, has at O in
fixed axes the parameters (m, h_w, Ī) with h_w = m·p + R·h and
Ī = R·I_O·Rᵀ + m·((p·p)·1 − p·pᵀ) + 2·(p·h')·1 − p·h'ᵀ − h'·pᵀ (h' = R·h): the spatial inertia
[[Ī, [h_w]×], [[h_w]×ᵀ, m·1]].

A "free" segment (a floating base without singularity) is placed by its coordinates
(x, y, z, q_x, q_y, q_z, q_w): the origin p = (x, y, z) and the quaternion ζ = (q_x, q_y, q_z, q_w)
of any nonzero length, whose direction is the orientation: R = R_h(ζ)/|ζ|² with R_h the rotation
matrix of a unit quaternion written homogeneously (degree 2), and ω = 2·vec(ζ̇ ⊗ ζ*)/|ζ|² in
fixed axes, 2·vec(ζ* ⊗ ζ̇)/|ζ|² in its own (Hamilton's product, `quaternion_product`).
"""
from dataclasses import dataclass

import symengine as se

from .calculus import rate
from .rotation import quaternion_matrix

ZERO = se.Integer(0)


@dataclass
class Frame:
    """One segment's world frame: R (3×3 lists), p, omega (ω), velocity (ṗ), twist (6: the
    joint's s_k), motion (θ_k) and inertia (the body's 10 parameters about its origin, its axes),
    all SymEngine."""
    R: list
    p: list
    omega: list
    velocity: list
    twist: list
    motion: object
    inertia: list


def matmul(A, B):
    return [[se.Add(*(A[i][k] * B[k][j] for k in range(3))) for j in range(3)] for i in range(3)]


def apply(A, v):
    return [se.Add(*(A[i][k] * v[k] for k in range(3))) for i in range(3)]


def transpose(A):
    return [[A[j][i] for j in range(3)] for i in range(3)]


def cross(a, b):
    """a × b of 3-lists."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def skew(a):
    return [[ZERO, -a[2], a[1]], [a[2], ZERO, -a[0]], [-a[1], a[0], ZERO]]


def number(x):
    """A SymEngine number of the float x: an integer where it is one (so that 0 and ±1 fold)."""
    return se.Integer(int(x)) if float(x).is_integer() else se.Float(x)


def axis_rotation(axis, angle):
    """The rotation by `angle` about the unit `axis` (numbers): the elementary rotation about
    ±x, ±y or ±z, else Rodrigues' I + s·[a]× + (1 − c)·[a]×²."""
    a = [number(x) for x in axis]
    s, c = se.sin(angle), se.cos(angle)
    if sorted(abs(float(x)) for x in axis) == [0.0, 0.0, 1.0]:
        i = next(k for k, x in enumerate(axis) if x)
        sign = a[i]
        j, k = (i + 1) % 3, (i + 2) % 3
        R = [[se.Integer(0)] * 3 for _ in range(3)]
        R[i][i] = se.Integer(1)
        R[j][j] = R[k][k] = c
        R[k][j], R[j][k] = sign * s, -sign * s
        return R
    K = skew(a)
    K2 = matmul(K, K)
    return [[(1 if i == j else 0) + s * K[i][j] + (1 - c) * K2[i][j] for j in range(3)]
            for i in range(3)]


def rodrigues(axis, theta):
    """The rotations by the angles `theta` (array) about the unit `axis`, (len(theta), 3, 3), in
    NumPy: I + sin θ·[a]× + (1 − cos θ)·[a]×²."""
    import numpy as np
    a = np.asarray(axis, dtype=float)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    theta = np.asarray(theta, dtype=float)[..., None, None]
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * (K @ K)


def quaternion_product(a, b):
    """a ⊗ b of two quaternions (x, y, z, w) (4-lists): [a_w·b_v + b_w·a_v + a_v × b_v;
    a_w·b_w − a_v·b_v]."""
    c = cross(a[:3], b[:3])
    return [a[3] * y + b[3] * x + z for x, y, z in zip(a[:3], b[:3], c)] + \
        [a[3] * b[3] - se.Add(*(x * y for x, y in zip(a[:3], b[:3])))]


def conjugate(a):
    """ζ* = (−x, −y, −z, w)."""
    return [-a[0], -a[1], -a[2], a[3]]


def quaternion_rate(z, zd, body=False):
    """The angular velocity of the direction of ζ moving at ζ̇: 2·vec(ζ̇ ⊗ ζ*)/|ζ|² in fixed axes,
    2·vec(ζ* ⊗ ζ̇)/|ζ|² in its own (`body`)."""
    n2 = se.Add(*(x * x for x in z))
    product = quaternion_product(conjugate(z), zd) if body else \
        quaternion_product(zd, conjugate(z))
    return [2 * e / n2 for e in product[:3]]


def free_motion(segment, convert, q, qd, t):
    """(p, ζ, ṗ, ζ̇) of a free segment's coordinates (internal symbols)."""
    x = [convert(e) for e in segment.motion]
    return x[:3], x[3:], [rate(e, q, qd, t) for e in x[:3]], [rate(e, q, qd, t) for e in x[3:]]


def frames(record, convert, q, qd, t):
    """The `Frame` of every segment of the Articulation `record`, in segment order."""
    out = []
    eye = [[se.Integer(int(i == j)) for j in range(3)] for i in range(3)]
    zero3 = [ZERO] * 3
    for segment in record.segments:
        if segment.kind == "free":
            p, z, pd, zd = free_motion(segment, convert, q, qd, t)
            out.append(Frame(quaternion_matrix(z), p, quaternion_rate(z, zd), pd, None, None,
                             [convert(x) for x in segment.inertia]))
            continue
        parent = out[segment.parent] if segment.parent >= 0 else \
            Frame(eye, zero3, zero3, zero3, None, None, None)
        P = [[convert(x) for x in row] for row in segment.rotation.tolist()]
        o = [convert(x) for x in segment.offset]
        theta = convert(segment.motion)
        theta_rate = rate(theta, q, qd, t)
        RP = matmul(parent.R, P)
        direction = apply(RP, [number(x) for x in segment.axis])
        if segment.kind == "revolute":
            R = matmul(RP, axis_rotation(segment.axis, theta))
            p = [a + b for a, b in zip(parent.p, apply(parent.R, o))]
            omega = [a + d * theta_rate for a, d in zip(parent.omega, direction)]
            velocity = [a + b for a, b in zip(parent.velocity,
                                             cross(parent.omega, apply(parent.R, o)))]
            twist = direction + cross(p, direction)
        else:
            R = RP
            arm = apply(parent.R, o)
            arm = [a + d * theta for a, d in zip(arm, direction)]
            p = [a + b for a, b in zip(parent.p, arm)]
            omega = list(parent.omega)
            velocity = [a + b + d * theta_rate for a, b, d in
                        zip(parent.velocity, cross(parent.omega, arm), direction)]
            twist = [ZERO] * 3 + direction
        out.append(Frame(R, p, omega, velocity, twist, theta,
                         [convert(x) for x in segment.inertia]))
    return out


def cross6(a, b):
    """a × b of two motions [ω; v] (6-lists): [ω_a × ω_b; ω_a × v_b + v_a × ω_b]."""
    w = cross(a[:3], b[:3])
    v = [x + y for x, y in zip(cross(a[:3], b[3:]), cross(a[3:], b[:3]))]
    return w + v


def diff(expr, symbol):
    """∂expr/∂symbol (0 for a symbol it does not hold)."""
    return expr.diff(symbol) if symbol in expr.free_symbols else ZERO


def centre_inertia(body):
    """(m, h, Ī) at the fixed origin of a body of mass m at its centre p with the inertia I
    (about the centre, body axes) turned by R: h = m·p, Ī = R·I·Rᵀ + m·((p·p)·1 − p·pᵀ) (a
    particle: I = 0)."""
    m, p = body.mass, body.p
    I = matmul(matmul(body.R, body.inertia), transpose(body.R)) if body.R is not None \
        else [[ZERO] * 3 for _ in range(3)]
    pp = se.Add(*(x * x for x in p))
    Ibar = [[I[i][j] + m * ((pp if i == j else 0) - p[i] * p[j]) for j in range(3)]
            for i in range(3)]
    return [m] + [m * x for x in p] + [Ibar[0][0], Ibar[0][1], Ibar[1][1], Ibar[0][2],
                                        Ibar[1][2], Ibar[2][2]]


def symmetric(six):
    """The 3×3 lists of a symmetric matrix given as (xx, xy, yy, xz, yz, zz)."""
    xx, xy, yy, xz, yz, zz = six
    return [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]


def world_inertia(frame):
    """(m, h_w (3), Ī (xx, xy, yy, xz, yz, zz)): the body's spatial inertia at the fixed origin in
    fixed axes (see the module's docstring)."""
    m, h, I_O = frame.inertia[0], frame.inertia[1:4], symmetric(frame.inertia[4:])
    R, p = frame.R, frame.p
    hr = apply(R, h)
    I = matmul(matmul(R, I_O), transpose(R))
    pp, ph = se.Add(*(x * x for x in p)), se.Add(*(x * y for x, y in zip(p, hr)))
    Ibar = [[I[i][j] + m * ((pp if i == j else 0) - p[i] * p[j])
             + ((2 * ph) if i == j else 0) - p[i] * hr[j] - hr[i] * p[j]
             for j in range(3)] for i in range(3)]
    hw = [m * x + y for x, y in zip(p, hr)]
    return [m] + hw + [Ibar[0][0], Ibar[0][1], Ibar[1][1], Ibar[0][2], Ibar[1][2], Ibar[2][2]]


def kinetic_energy(frame):
    """T = ½·m·ṗ·ṗ + ṗ·(ω × R·h) + ½·ωᵀ·(R·I_O·Rᵀ)·ω of the frame's body."""
    m, h, I_O = frame.inertia[0], frame.inertia[1:4], symmetric(frame.inertia[4:])
    if all(x == 0 for x in frame.inertia):
        return ZERO
    R, v, w = frame.R, frame.velocity, frame.omega
    wb = apply(transpose(R), w)
    T = m * se.Add(*(x * x for x in v)) / 2
    T += se.Add(*(a * b for a, b in zip(v, cross(w, apply(R, h)))))
    T += se.Add(*(wb[i] * I_O[i][j] * wb[j] for i in range(3) for j in range(3))) / 2
    return T


def potential_energy(frame, gravity):
    """V = −g·(m·p + R·h) of the frame's body in the uniform gravity g."""
    m, h = frame.inertia[0], frame.inertia[1:4]
    centre = [m * x + y for x, y in zip(frame.p, apply(frame.R, h))]
    return -se.Add(*(g * c for g, c in zip(gravity, centre)))


def body_omega(record, convert, q, qd, t):
    """Each segment's angular velocity in its own axes, ω_k = (P_k·J_k)ᵀ·ω_λ + a·θ̇_k (revolute)."""
    out = []
    for segment in record.segments:
        if segment.kind == "free":
            _, z, _, zd = free_motion(segment, convert, q, qd, t)
            out.append(quaternion_rate(z, zd, body=True))
            continue
        parent = out[segment.parent] if segment.parent >= 0 else [ZERO] * 3
        P = [[convert(x) for x in row] for row in segment.rotation.tolist()]
        theta = convert(segment.motion)
        if segment.kind == "revolute":
            PJ = matmul(P, axis_rotation(segment.axis, theta))
            w = apply(transpose(PJ), parent)
            w = [x + number(a) * rate(theta, q, qd, t) for x, a in zip(w, segment.axis)]
        else:
            w = apply(transpose(P), parent)
        out.append(w)
    return out
