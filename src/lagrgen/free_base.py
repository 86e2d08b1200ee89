"""A floating base without singularity: the recursion over a tree whose root is a "free" segment
(`lagrgen.from_urdf(..., base="free")`).

The model's coordinates are q = [p, ζ, θ]: the base frame's origin p (3), a quaternion
ζ = (q_x, q_y, q_z, q_w) (4) whose direction is its orientation (`lagrgen.frames`: R = R_h(ζ)/|ζ|²,
no singularity anywhere but ζ = 0) and the joints θ; the state is y = [q, q̇] as for every model.
ζ's length r = |ζ| moves nothing: it has an inertia J of its own (T += ½·J·ṙ², `records.Segment`),
which keeps M positive definite and r̈ = 0, so a motion started with |ζ| = 1 and ζ·ζ̇ = 0 stays
on the unit sphere (up to the integrator's error, which moves no body).

The recursion (`lagrgen.tree3d`, O(n)) needs one coordinate per node, each twist fixed in the body
above. It runs in the base's chart at the current orientation R0: c = [p, e, θ] with the
orientation R0·Rx(e_x)·Ry(e_y)·Rz(e_z), evaluated at e = 0, where its nodes are three prismatic
joints along the fixed axes, then three revolute joints about the base's own axes through p (the
last carrying the base's body), then the joints; there ė is the base's angular velocity in its own
axes, ω_b = 2·vec(ζ*⊗ζ̇)/|ζ|². With r added, Φ(e, r) = r·ζ̂0 ⊗ h(e) (h(e) = q_x(e_x)⊗q_y(e_y)⊗
q_z(e_z), the rotations' quaternions) maps the chart to q, and Lagrange's equations transform as
covectors: with D = ∂q/∂c at the point (block-diagonal, identity but for the 4×4 block of (e, r)),

    M_q = D⁻ᵀ·M̃_c·D⁻¹,   F_q = D⁻ᵀ·(F̃_c + M̃_c·D⁻¹·D²Φ[ċ, ċ]),   q̈ = D·c̈ + D²Φ[ċ, ċ],

with M̃_c, F̃_c the chart's (the recursion's, and J, 0 for r). The Jacobian pieces follow from the
chart's (the recursion's analytical derivatives) through D²Φ and D³Φ, which are quaternion products
of ζ and the derivatives of h at 0 (`lagrgen.runtime.free_base`, `codegen/templates/
free_base.c.in`): nothing is differentiated numerically. The generalized forces Q_q are the model's
(their slopes ∂Q/∂y in q); the nodes carry the chart's, Q_c = Dᵀ·Q_q.
"""
from dataclasses import dataclass

import symengine as se

from . import frames
from .errors import NotATree

#: The model's indices of the free base's coordinates: p, then ζ.
POSITION, QUATERNION = (0, 1, 2), (3, 4, 5, 6)
#: The recursion's (the chart's) base nodes: the fixed axes of the three prismatic joints.
AXES = ((1, 0, 0), (0, 1, 0), (0, 0, 1))


@dataclass(frozen=True)
class FreeBase:
    """What the code of a free base needs beside its tree: the inertia J of ζ's length."""
    radial: float


def is_free(record):
    """True if the articulation `record`'s root is a free segment."""
    return bool(record.segments) and record.segments[0].kind == "free"


def free_tree(eq, record, Q, world, joint_nodes):
    """(coordinate, parent, records, notes, poses) of the chart's nodes of an articulation whose
    segment 0 is free: the six base nodes, then the joints' (`joint_nodes(k)`: the coordinate
    (model index), twist multiplier of segment k ≥ 1). `Q` are the model's generalized forces,
    `world` the segments' frames (`lagrgen.frames`)."""
    names = eq.spec.coordinate_names
    if any(s.kind == "free" for s in record.segments[1:]) or record.segments[0].parent >= 0:
        raise NotATree("a free segment must be the root of its articulation")
    zero = se.Integer(0)
    gravity = [eq.collected.convert(g) for g in record.gravity]
    base = world[0]
    z = [eq.q[j] for j in QUATERNION]
    Qz = [Q[j] for j in QUATERNION]
    records, notes, poses = [], [], []
    identity = [se.Integer(int(i == j)) for i in range(3) for j in range(3)] + [zero] * 3
    for i, axis in enumerate(AXES):
        twist = [zero] * 3 + [se.Integer(a) for a in axis]
        support = [zero] * 3 + [-g for g in gravity] if i == 0 else [zero] * 6
        records.append(twist + [zero] * 10 + support + [Q[POSITION[i]]])
        notes.append(f"node {i}: free base, along the fixed {'xyz'[i]} axis ({names[i]})")
        poses.append(identity)
    for i in range(3):
        a = [base.R[r][i] for r in range(3)]
        twist = a + frames.cross(base.p, a)
        inertia = frames.world_inertia(base) if i == 2 else [zero] * 10
        force = se.Add(*(c * f for c, f in zip(chart_column(z, i), Qz))) / 2
        records.append(twist + inertia + [zero] * 6 + [force])
        notes.append(f"node {3 + i}: free base, about its own {'xyz'[i]} axis"
                     + (f"; carries link {record.segments[0].link}" if i == 2 else ""))
        poses.append([x for row in base.R for x in row] + list(base.p) if i == 2 else identity)
    coordinate = list(range(6))
    parent = [-1, 0, 1, 2, 3, 4]
    for k, (segment, frame) in enumerate(zip(record.segments[1:], world[1:]), start=1):
        j, multiplier = joint_nodes(k)
        if j < 7:
            raise NotATree(f"joint {segment.name!r} moves with a coordinate of the free base")
        coordinate.append(j - 1)
        parent.append(5 if segment.parent == 0 else segment.parent + 5)
        records.append([multiplier * x for x in frame.twist] + frames.world_inertia(frame)
                       + [zero] * 6 + [Q[j]])
        above = "the free base" if segment.parent == 0 else \
            names[coordinate[parent[-1]] + 1]
        notes.append(f"node {k + 5}: {segment.kind} joint {names[j]}, below {above}; carries "
                     f"{('link ' + segment.link) if segment.link else 'no body'}")
        poses.append([x for row in frame.R for x in row] + list(frame.p))
    if len(set(coordinate)) != len(coordinate):
        raise NotATree("joints follow another's coordinate (mimic) on a free base: read the file "
                       "with from_urdf(..., mimic=False)")
    return tuple(coordinate), tuple(parent), records, notes, poses


def chart_column(z, i):
    """ζ ⊗ a_i (a_i the unit quaternion of axis i): twice ∂ζ/∂e_i, so that the chart's
    generalized force of e_i is ½·(ζ ⊗ a_i)·Q_ζ."""
    unit = [se.Integer(int(i == k)) for k in range(3)] + [se.Integer(0)]
    return frames.quaternion_product(z, unit)


def link_node(segment):
    """The node of `free_base.link_tree` whose body is segment `segment` (−1: the fixed frame):
    the base's is node 6 (its last quaternion node), joint k's node k + 6."""
    return -1 if segment < 0 else segment + 6


def link_tree(z, nodes, parent, records):
    """(parent, coordinate, twists) of the tree of a free base's links in the model's coordinates
    (a `tree3d.LinkTree`): nodes 0–2 its position
    (the chart's prismatic nodes), nodes 3–6 its quaternion's components ζ_k, each with the
    twist Σ_i G_ik·s_i of the chart's rotation nodes s_i (ė = G·ζ̇, G_ik = 2·(ζ ⊗ a_i)_k/|ζ|²,
    the inverse of ∂ζ/∂e = ½·ζ ⊗ a_i on ζ's tangent space), then the joints' nodes (chart
    node m ≥ 6 is node m + 1): a chain from the position down, so that J·q̇ with q̇ ∋ ζ̇ is
    the link's [velocity; angular velocity]."""
    norm2 = se.Add(*(x * x for x in z))
    G = [[2 * x / norm2 for x in chart_column(z, i)] for i in range(3)]
    spins = [records[3 + i][:6] for i in range(3)]
    twists = [records[i][:6] for i in range(3)]
    twists += [[se.Add(*(G[i][k] * spins[i][r] for i in range(3))) for r in range(6)]
               for k in range(4)]
    twists += [record[:6] for record in records[6:]]
    link_parent = tuple(range(-1, 6)) + tuple(6 if parent[m] == 5 else parent[m] + 1
                                             for m in range(6, len(nodes)))
    coordinate = tuple(range(7)) + tuple(c + 1 for c in nodes[6:])
    return link_parent, coordinate, twists
