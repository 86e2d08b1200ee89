"""The links of a model of three-dimensional bodies and where they are: each link's frame in the
fixed frame as SymPy expressions of the coordinates (`Model.link_position`, `Model.link_rotation`).

A robot read from a URDF file (an `Articulation`) has one link per `<link>` of the file: a segment's
frame is R_k = R_λ·P_k·J_k (P_k its placement's rotation, J_k the rotation of a revolute joint by its
motion θ about its unit axis a; the identity for a prismatic one), its origin
p_k = p_λ + R_λ·(o_k + P_k·a·θ) (the last term for a prismatic joint only), and a link fixed in
segment k at (R_l, o_l) has the frame (R_k·R_l, p_k + R_k·o_l); a free base is placed by its
coordinates, its origin and the direction of its quaternion ζ (R = R_h(ζ)/|ζ|², `frames`). A hand-written `rigid_body_3d` is a
link whose frame is its own: its orientation at its centre of mass, named by `name=` or `body<k>`
(k counting the 3-D bodies in declaration order). The expressions stay nested (not expanded), as
the composition gives them.
"""
import symengine as se
import sympy as sp

from .errors import UnknownNameError
from .records import Articulation, Body3D
from .rotation import quaternion_matrix

_AXES = {(1.0, 0.0, 0.0): "x", (0.0, 1.0, 0.0): "y", (0.0, 0.0, 1.0): "z"}


def links(physics):
    """{link name: its record (a `LinkFrame` with its Articulation, or a Body3D)} of the physics
    records, in order."""
    out, bodies = {}, 0
    for record in physics:
        if isinstance(record, Articulation):
            out.update((frame.name, (frame, record)) for frame in record.links)
        elif isinstance(record, Body3D):
            out[record.name if record.name is not None else f"body{bodies}"] = (record, None)
            bodies += 1
    return out


def link_names(physics):
    """The names of the links of the physics records, in order."""
    return tuple(links(physics))


def find(physics, link, model_name):
    """The record of `link`; UnknownNameError listing the links otherwise."""
    found = links(physics)
    if not found:
        raise UnknownNameError(f"model {model_name!r} has no links: link kinematics need a robot "
                               "from a URDF file (lagrgen.from_urdf) or rigid_body_3d bodies")
    if not isinstance(link, str) or link not in found:
        raise UnknownNameError(f"{link!r} is not a link of model {model_name!r}; its links are "
                               f"{', '.join(found)}")
    return found[link]


def pose(physics, link, model_name):
    """(R (3×3), p (3×1)): the frame of `link` in the fixed frame, SymPy Matrices."""
    record, articulation = find(physics, link, model_name)
    if articulation is None:
        return sp.Matrix(record.orientation), sp.Matrix(record.position)
    R, p = segment_pose(articulation.segments, record.segment)
    return R * sp.Matrix(record.rotation), p + R * sp.Matrix(record.offset)


def velocity(x, t):
    """ẋ = dx/dt of a point's position x (SymPy, the coordinates functions of t): Σ ∂x/∂q_j·q̇_j,
    by SymEngine's chain rule (about 9× faster than SymPy's through the nested frames)."""
    return sp.Matrix(sp.sympify(se.sympify(x).diff(se.sympify(t))))


def segment_pose(segments, k):
    """(R_k, p_k) of segment k (k = −1: the fixed frame), composed from the root down."""
    chain = []
    while k >= 0:
        chain.append(segments[k])
        k = segments[k].parent
    R, p = sp.eye(3), sp.zeros(3, 1)
    for segment in reversed(chain):
        P, o = sp.Matrix(segment.rotation), sp.Matrix(segment.offset)
        if segment.kind == "free":
            position, quaternion = list(segment.motion[:3]), list(segment.motion[3:])
            R, p = sp.Matrix(quaternion_matrix(quaternion)), sp.Matrix(position)
        elif segment.kind == "revolute":
            R, p = R * P * axis_rotation(segment.axis, segment.motion), p + R * o
        else:
            direction = P * sp.Matrix([_number(a) for a in segment.axis])
            R, p = R * P, p + R * (o + direction * segment.motion)
    return R, p


def axis_rotation(axis, angle):
    """The rotation by `angle` about the unit `axis` (3 numbers): the elementary one about ±x, ±y,
    ±z, else I + sin θ·[a]× + (1 − cos θ)·[a]×²."""
    key = tuple(abs(float(a)) for a in axis)
    if key in _AXES:
        from .rotation import elementary
        sign = 1 if sum(axis) > 0 else -1
        return sp.Matrix(elementary(_AXES[key], sign * angle))
    a = [_number(x) for x in axis]
    K = sp.Matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return sp.eye(3) + sp.sin(angle) * K + (1 - sp.cos(angle)) * K * K


def _number(x):
    return sp.Integer(int(x)) if float(x).is_integer() else sp.Float(x)
