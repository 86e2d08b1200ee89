"""Three-dimensional kinematic trees: the recursive formulation of rigid bodies joined by
revolute and prismatic joints (a robot from `lagrgen.from_urdf`), in spatial (6-D) vectors.

Every quantity is written in the fixed frame, in Plücker coordinates at the fixed origin O: a
motion [ω; v_O], a force [n_O; f]. Node k (one per coordinate, parents first) carries

    s_k    the twist of its joint per unit rate (revolute about an axis through p: [a; p × a];
           prismatic along a: [0; a]), fixed in the parent body,
    Y_k    the spatial inertia of the body it carries, [[Ī, [h]×], [[h]×ᵀ, m·1]] as the ten
           numbers (m, h, Ī) (`lagrgen.frames.world_inertia`),
    base   for a root, the acceleration [0; −g] of its support (gravity enters as the fixed
           frame accelerating upwards), zero otherwise,
    Q      the generalized force of everything else on its coordinate (inputs, damping, springs,
           applied forces: −∂V/∂q − ∂R/∂q̇ + Q).

so that the body of node k moves with the twist v_k = v_parent + s_k·q̇_k. The recursions over
them (`lagrgen/codegen/templates/tree3d.c.in`, `lagrgen.runtime.tree3d`) are the
articulated-body algorithm for q̈ (O(n)), the composite-rigid-body algorithm for M, the
recursive Newton–Euler algorithm for F and the inverse dynamics, and the analytical derivatives
of the latter by q and q̇ (Carpentier & Mansard 2018, in the fixed frame: O(n·depth)), which
need no derivative of the node terms: moving q_j moves every body below j rigidly by s_j.

The tree of a `from_urdf` model is its structure (an `Articulation` record); nothing else may add
kinetic energy beside it, and a joint that mimics another (one coordinate in two branches) leaves
the model to the dense formulation.
"""
import math
from dataclasses import dataclass, field
from functools import cached_property

import symengine as se

from . import frames, free_base
from .contributions import APPLIED, generalized_forces
from .errors import NotATree
from .records import Articulation, Body3D, Particle, PotentialEnergy

#: Layout of one node's record in the tree_nodes kernel: (name, width).
FIELDS = (("s", 6), ("Y", 10), ("base", 6), ("Q", 1))


@dataclass(frozen=True)
class LinkTree:
    """The tree a link's frame Jacobian is read from: node i's `parent` (−1: a root), the model
    coordinate whose rate it moves with (`coordinate`), and its twist per unit rate [ω_i; v_i]
    (Plücker coordinates at the fixed origin, `twists[i]`, 6 expressions)."""
    parent: tuple
    coordinate: tuple
    twists: list


@dataclass(eq=False)
class SpatialTree:
    """A model's three-dimensional kinematic tree and its nodes' terms (internal symbols).

    Nodes are in preorder (a parent before its children, every subtree contiguous):
    `coordinate[k]` is node k's coordinate, `parent[k]` its parent node (−1: a root), `end[k]`
    one past the last node of its subtree; `Q` the generalized forces in coordinate order;
    `terms()` gives (records, poses), formed on first use (`records`, `poses`): `records[k]` the
    node's FIELDS (SymEngine), `poses[k]` the node's frame in the fixed one (R row-major, then
    its origin: 12 expressions), the frame its body's inertial parameters are about. The tree of
    an articulation (`articulated`) has its `joints` (`Joints`: the numbers the records follow
    from, None when a segment's values are not numbers or parameters) and `gravity`.
    A tree whose root is a free base (`lagrgen.free_base`) has nodes in the base's chart, one
    coordinate fewer than the model (`coordinate` indexes the chart's), its Q in the model's
    coordinates and `free` its `FreeBase`. `links` are the model's links (`lagrgen.links`) as
    (name, the node whose body carries it or −1 for the fixed frame), `link_poses` their
    frames (R row-major then origin, 12 expressions each), formed on first use
    (`link_terms()`). The links' Jacobian walks `link_tree` (`LinkTree`): the node tree itself,
    or for a free base one node per model coordinate of the base (`free_base.link_tree`).
    """
    coordinate: tuple
    parent: tuple
    end: tuple
    terms: object
    Q: list
    notes: list = field(default_factory=list)
    articulated: bool = False    # the bodies of an Articulation: energies from the records
    joints: object = None
    gravity: list = field(default_factory=list)
    free: object = None
    links: tuple = ()
    link_terms: object = tuple
    link_nodes: object = None
    kind = "spatial"
    fields = FIELDS

    @cached_property
    def _formed(self):
        return self.terms()

    @property
    def records(self):
        return self._formed[0]

    @property
    def poses(self):
        return self._formed[1]

    @cached_property
    def link_poses(self):
        return self.link_terms()

    @cached_property
    def link_tree(self):
        """The `LinkTree` the links' Jacobian walks: the node tree, unless `link_nodes()` gives
        one of its own."""
        if self.link_nodes is not None:
            return self.link_nodes()
        return LinkTree(self.parent, self.coordinate,
                        [record[:6] for record in self.records])

    @property
    def n(self):
        return len(self.coordinate)

    @property
    def width(self):
        return sum(w for _, w in FIELDS)

    @property
    def depth(self):
        """The number of nodes on the longest root-to-leaf path."""
        level = []
        for p in self.parent:
            level.append(1 if p < 0 else level[p] + 1)
        return max(level)

    def node_records(self):
        """The tree_nodes kernel's output: each node's record, in node order."""
        return [x for record in self.records for x in record]


@dataclass(frozen=True)
class Joints:
    """The numbers of an articulation's joints, node by node, from which its node records follow
    (`lagrgen/codegen/templates/tree3d.c.in`'s lg_tree_nodes, `lagrgen.runtime.tree3d`):
    `prismatic` (0 or 1), the unit `axis` (3), the placement in the parent's frame
    (`placement`: its rotation row-major, then its origin: 12), the joint's `motion`
    (multiplier, offset: θ = multiplier·q + offset) and the body's ten inertial parameters about
    the joint's frame (`inertia`: numbers, 0 where `inertia_parameter` names a parameter's index,
    −1 elsewhere)."""
    prismatic: tuple
    axis: tuple
    placement: tuple
    motion: tuple
    inertia: tuple
    inertia_parameter: tuple

    def table(self):
        """The tables as plain Python values (lists; `lagrgen.codegen.tree_code.layout`)."""
        return {name: [list(row) if isinstance(row, tuple) else row for row in getattr(self, name)]
                for name in ("prismatic", "axis", "placement", "motion", "inertia",
                             "inertia_parameter")}


def is_spatial(spec):
    """True if the model's bodies are three-dimensional (an articulation or 3-D rigid bodies):
    the recursion over its tree, if any, is this module's."""
    return any(isinstance(r, (Articulation, Body3D)) for r in spec.physics)


def spatial_tree(eq):
    """The `SpatialTree` of the `Equations` eq; NotATree saying why it has none."""
    spec = eq.spec
    if eq.m:
        raise NotATree("it has constraints")
    articulations = [r for r in spec.physics if isinstance(r, Articulation)]
    if not articulations:
        return _from_bodies(eq)
    if len(articulations) > 1:
        raise NotATree("it has two articulations")
    record = articulations[0]
    others = [r for r in spec.physics if r is not record]
    extra = [r for r in others if not isinstance(r, APPLIED)]
    if extra:
        raise NotATree(f"it has kinetic energy beside its articulation "
                       f"({type(extra[0]).__name__})")
    return _from_articulation(eq, record, others)


def _from_articulation(eq, record, others):
    """The tree of an Articulation: its segments in order, one coordinate each (a free base:
    `lagrgen.free_base`)."""
    q, names = eq.q, eq.spec.coordinate_names
    convert = eq.collected.convert
    coordinate, multiplier = [], []
    free = free_base.is_free(record)
    for segment in record.segments[1:] if free else record.segments:
        motion = convert(segment.motion)
        used = [j for j, qj in enumerate(q) if qj in motion.free_symbols]
        scale = frames.diff(motion, q[used[0]]) if len(used) == 1 else None
        if scale is None or scale.free_symbols or scale == 0:
            raise NotATree(f"the motion of joint {segment.name!r} is not a multiple of one "
                           "coordinate")
        coordinate.append(used[0])
        multiplier.append(scale)
    if set(coordinate) | set(free_base.POSITION + free_base.QUATERNION if free else ()) \
            != set(range(len(q))):
        raise NotATree("a coordinate moves no joint")
    if free:
        world = frames.frames(record, convert, q, eq.qd, eq.t)
        Q = generalized_forces(others, convert, q, eq.qd, eq.t)
        nodes, parent, records, notes, poses = free_base.free_tree(
            eq, record, Q, world, lambda k: (coordinate[k - 1], multiplier[k - 1]))
        return SpatialTree(nodes, parent, _subtree_ends(parent), lambda: (records, poses), Q,
                           notes, free=free_base.FreeBase(float(record.segments[0].radial)),
                           links=tuple((frame.name, free_base.link_node(frame.segment))
                                       for frame in record.links),
                           link_terms=lambda: [_placed_pose(world, frame, convert)
                                               for frame in record.links],
                           link_nodes=lambda: LinkTree(*free_base.link_tree(
                               [eq.q[j] for j in free_base.QUATERNION], nodes, parent, records)))
    parent = tuple(s.parent for s in record.segments)
    end = _subtree_ends(parent)
    gravity = [convert(g) for g in record.gravity]
    Q = generalized_forces(others, convert, q, eq.qd, eq.t)
    notes = []
    for k, segment in enumerate(record.segments):
        above = (f", below {names[coordinate[parent[k]]]}" if parent[k] >= 0
                 else ", a root")
        notes.append(f"node {k}: {segment.kind} joint {names[coordinate[k]]}{above}; carries "
                     f"{('link ' + segment.link) if segment.link else 'no body'}")

    def terms():
        world = eq.collected.sums.frames_of(record)
        zero = se.Integer(0)
        records, poses = [], []
        for k, frame in enumerate(world):
            poses.append([x for row in frame.R for x in row] + list(frame.p))
            base = [zero] * 3 + [-g for g in gravity] if parent[k] < 0 else [zero] * 6
            records.append([multiplier[k] * x for x in frame.twist] + frames.world_inertia(frame)
                           + base + [Q[coordinate[k]]])
        return records, poses

    joints = _joints(eq, record, coordinate, multiplier)
    def link_terms():
        world = eq.collected.sums.frames_of(record)
        return [_placed_pose(world, frame, convert) for frame in record.links]

    return SpatialTree(tuple(coordinate), parent, end, terms, Q, notes, articulated=True,
                       joints=joints, gravity=gravity,
                       links=tuple((frame.name, frame.segment) for frame in record.links),
                       link_terms=link_terms)


def _joints(eq, record, coordinate, multiplier):
    """The articulation's `Joints`, or None when a segment's motion offset or inertial values are
    not numbers (or, for the inertial values, parameters)."""
    convert, q = eq.collected.convert, eq.q
    parameter_index = {p: j for j, p in enumerate(eq.p)}
    prismatic, axis, placement, motion, inertia, inertia_parameter = [], [], [], [], [], []
    for k, segment in enumerate(record.segments):
        offset = convert(segment.motion).xreplace({q[coordinate[k]]: se.Integer(0)})
        if not offset.is_Number or not multiplier[k].is_Number:
            return None
        values, index = [], []
        for x in segment.inertia:
            x = convert(x)
            if x.is_Number:
                values.append(float(x))
                index.append(-1)
            elif x in parameter_index:
                values.append(0.0)
                index.append(parameter_index[x])
            else:
                return None
        prismatic.append(int(segment.kind == "prismatic"))
        axis.append(tuple(float(a) for a in segment.axis))
        placement.append(tuple(float(x) for x in segment.rotation) +
                         tuple(float(x) for x in segment.offset))
        motion.append((float(multiplier[k]), float(offset)))
        inertia.append(tuple(values))
        inertia_parameter.append(tuple(index))
    return Joints(tuple(prismatic), tuple(axis), tuple(placement), tuple(motion), tuple(inertia),
                  tuple(inertia_parameter))


def _placed_pose(world, frame, convert):
    """The 12 pose expressions (R row-major, origin) of a link fixed in a segment's frame."""
    R0 = [[convert(x) for x in row] for row in frame.rotation.tolist()]
    o = [convert(x) for x in frame.offset]
    if frame.segment < 0:
        return [x for row in R0 for x in row] + o
    carrier = world[frame.segment]
    R = frames.matmul(carrier.R, R0)
    p = [a + b for a, b in zip(carrier.p, frames.apply(carrier.R, o))]
    return [x for row in R for x in row] + p


def inertial_symbols(spec):
    """Per segment of the model's articulation, the ten parameters that are its body's inertial
    parameters (m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz), or None where they
    are not ten distinct parameters; [] for a model without an articulation."""
    record = next((r for r in spec.physics if isinstance(r, Articulation)), None)
    if record is None:
        return []
    parameters = set(spec.parameters)
    out = []
    for segment in record.segments:
        values = tuple(segment.inertia)
        ok = len(set(values)) == 10 and all(v in parameters for v in values)
        out.append(values if ok else None)
    return out


def inertial_parameters(spec):
    """The names of the model's inertial parameters, ten per body, in segment order."""
    return tuple(s.name for values in inertial_symbols(spec) if values for s in values)


def _subtree_ends(parent):
    """One past the last node of each node's subtree; NotATree unless `parent` lists the nodes
    in preorder (every parent before its children, each subtree contiguous)."""
    n = len(parent)
    end = list(range(1, n + 1))
    for k in range(n - 1, -1, -1):
        p = parent[k]
        if p >= k:
            raise NotATree("its joints are not listed parents first")
        if p >= 0:
            end[p] = max(end[p], end[k])
    for k in range(n):
        if any(parent[i] < k for i in range(k + 1, end[k])):
            raise NotATree("its subtrees are not contiguous")
    return tuple(end)


def explicit_time(tree, eq):
    """True if the node terms or Q depend on t (an articulation's: its Q and gravity, when its
    joints are numbers)."""
    if tree.joints is not None:
        return any(eq.t in x.free_symbols for x in list(tree.Q) + list(tree.gravity))
    return any(eq.t in x.free_symbols for x in tree.node_records())


def preorder(parent_coordinate):
    """(coordinate, parent, end) of the nodes in preorder from {coordinate: parent coordinate or
    −1}: roots and children by index, each subtree contiguous (`end`: one past its last node)."""
    n = len(parent_coordinate)
    children = {j: [] for j in range(-1, n)}
    for j in range(n):
        children[parent_coordinate[j]].append(j)
    coordinate, parent, end = [], [], [0] * n
    stack = [(root, -1) for root in reversed(children[-1])]
    while stack:
        j, p = stack.pop()
        coordinate.append(j)
        parent.append(p)
        k = len(coordinate) - 1
        stack.extend((c, k) for c in reversed(children[j]))
    return tuple(coordinate), tuple(parent), _subtree_ends(tuple(parent))


# -- hand-written bodies ----------------------------------------------------------------------------
@dataclass(eq=False)
class Body:
    """A body of a hand-written model (internal symbols): mass, centre p (3), orientation R
    (3×3, None for a particle), inertia about the centre in body axes (None for a particle),
    angular velocity in fixed axes, and the coordinates it depends on."""
    mass: object
    p: list
    R: list = None
    inertia: list = None
    omega: list = None
    coordinates: frozenset = frozenset()
    name: str = None


def _from_bodies(eq):
    """The tree of a model of `rigid_body_3d`s (and 3-D particles), proven from the expressions:
    each coordinate q_j moves the bodies below it rigidly with one twist s_j(q) (the same for all
    of them), fixed in the body above (∂s_j/∂q_k = s_k × s_j for k above j, 0 otherwise). The
    identities are tested at random points with exact rational arithmetic (sin and cos of each
    angle at a rational point of the unit circle), in floating point where a function other than
    sin and cos of a coordinate remains (`Identities`). Potentials m_b·g·p_b,i of the bodies with
    one g become gravity; everything else of V, R and Q is Q."""
    spec, q, t = eq.spec, eq.q, eq.t
    convert = eq.collected.convert
    bodies, others = [], []
    for record in spec.physics:
        if isinstance(record, Body3D):
            if record.orientation is None or record.omega_fixed is None:
                raise NotATree("a 3-D body has no orientation recorded")
            name = record.name if record.name is not None else \
                f"body{sum(b.R is not None for b in bodies)}"
            bodies.append(Body(convert(record.mass), [convert(x) for x in record.position],
                               [[convert(x) for x in row] for row in record.orientation.tolist()],
                               [[convert(x) for x in row] for row in record.inertia.tolist()],
                               [convert(x) for x in record.omega_fixed], name=name))
        elif isinstance(record, Particle) and len(record.position) == 3:
            bodies.append(Body(convert(record.mass), [convert(x) for x in record.position]))
        elif isinstance(record, APPLIED):
            others.append(record)
        else:
            raise NotATree(f"it has a {type(record).__name__} beside its 3-D bodies")
    moving, index = set(q) | set(eq.qd) | {t}, {qj: j for j, qj in enumerate(q)}
    for body in bodies:
        free = set().union(*(x.free_symbols for x in body.p + [y for row in body.R or []
                                                               for y in row]))
        if t in free or body.mass.free_symbols & moving or any(
                x.free_symbols & moving for row in body.inertia or [] for x in row):
            raise NotATree("a body moves with t, or its mass or inertia varies")
        body.coordinates = frozenset(index[s] for s in free if s in index)
    rigid = [b for b in bodies if b.R is not None]
    bodies = [b for b in bodies if b.coordinates]
    n = len(q)
    moved = [frozenset(b for b, body in enumerate(bodies) if j in body.coordinates)
             for j in range(n)]
    for j in range(n):
        if not any(bodies[b].R is not None for b in moved[j]):
            raise NotATree(f"coordinate {spec.coordinate_names[j]!r} moves no 3-D rigid body")
    twists = [_twist(eq, bodies, moved[j], j) for j in range(n)]
    check = Identities(eq)
    parent_coordinate = _chains(moved, twists, q, spec.coordinate_names, check)
    coordinate, parent, end = preorder(parent_coordinate)
    ancestors = {j: set() for j in range(n)}
    for j in range(n):
        k = parent_coordinate[j]
        while k >= 0:
            ancestors[j].add(k)
            k = parent_coordinate[k]
    for j in range(n):
        for b in moved[j]:
            if not check.same(_column(eq, bodies[b], j, twists[j]), twists[j]):
                raise NotATree(f"the bodies moved by {spec.coordinate_names[j]!r} do not move "
                               "as one rigid body with it")
        for k in range(n):
            expected = frames.cross6(twists[k], twists[j]) if k in ancestors[j] else [0] * 6
            if k not in ancestors[j] and not any(q[k] in x.free_symbols for x in twists[j]):
                continue
            derivative = [frames.diff(x, q[k]) for x in twists[j]]
            if not check.same(derivative, expected):
                raise NotATree(f"the axis of {spec.coordinate_names[j]!r} is not fixed in the "
                               f"body above it ({spec.coordinate_names[k]!r} turns it otherwise)")
    node_of = {j: k for k, j in enumerate(coordinate)}
    leaf = []
    for body in bodies:
        own = max(body.coordinates, key=node_of.get)
        if any(j != own and j not in ancestors[own] for j in body.coordinates):
            raise NotATree("a body depends on coordinates of two branches")
        leaf.append(own)
    gravity, rest = _gravity(eq, bodies, others, convert)
    Q = generalized_forces(rest, convert, q, eq.qd, t)
    zero = se.Integer(0)
    records, notes = [], []
    names = spec.coordinate_names
    for k, j in enumerate(coordinate):
        carried = [b for b, own in enumerate(leaf) if own == j]
        Y = [zero] * 10
        for b in carried:
            Y = [a + c for a, c in zip(Y, frames.centre_inertia(bodies[b]))]
        base = [zero] * 3 + [-g for g in gravity] if parent[k] < 0 else [zero] * 6
        records.append(list(twists[j]) + Y + base + [Q[j]])
        above = f", below {names[coordinate[parent[k]]]}" if parent[k] >= 0 else ", a root"
        notes.append(f"node {k}: coordinate {names[j]}{above}; carries "
                     f"{len(carried) or 'no'} bod{'y' if len(carried) == 1 else 'ies'}")
    identity = [se.Integer(int(i == j)) for i in range(3) for j in range(3)] + [zero] * 3
    poses = [identity] * len(coordinate)
    carrier = {id(body): node_of[own] for body, own in zip(bodies, leaf)}
    links = tuple((body.name, carrier.get(id(body), -1)) for body in rigid)
    link_poses = [[x for row in body.R for x in row] + body.p for body in rigid]
    return SpatialTree(coordinate, parent, end, lambda: (records, poses), Q, notes, links=links,
                       link_terms=lambda: link_poses)


def _column(eq, body, j, reference=None):
    """Body b's twist column for q̇_j at the fixed origin: [ω_j; ∂p/∂q_j − ω_j × p] with
    ω_j = ∂ω/∂q̇_j (fixed axes); for a particle, whose rotation is not known, ω_j is the
    `reference` twist's (the entries of ω not compared: None)."""
    qj, qdj = eq.q[j], eq.qd[j]
    dp = [frames.diff(x, qj) for x in body.p]
    if body.R is None:
        w = reference[:3]
        return [None] * 3 + [a - c for a, c in zip(dp, frames.cross(w, body.p))]
    w = [frames.diff(x, qdj) for x in body.omega]
    return w + [a - c for a, c in zip(dp, frames.cross(w, body.p))]


def _twist(eq, bodies, moved, j):
    """s_j from the rigid body that depends on the fewest coordinates among those q_j moves."""
    rigid = [b for b in moved if bodies[b].R is not None]
    chosen = min(rigid, key=lambda b: (len(bodies[b].coordinates), b))
    return _column(eq, bodies[chosen], j)


def _chains(moved, twists, q, names, check):
    """{coordinate: parent coordinate or −1} from the sets of bodies each coordinate moves
    (nested or disjoint); coordinates that move the same bodies form a chain, a coordinate whose
    twist depends on another (∂s_j/∂q_k ≠ 0 at the `check`'s points) after it."""
    n = len(moved)
    zero = [0] * 6
    depends = {j: {k for k in range(n) if k != j and moved[k] == moved[j]
                   and any(q[k] in x.free_symbols for x in twists[j])
                   and not check.same([frames.diff(x, q[k]) for x in twists[j]], zero)}
               for j in range(n)}
    order, placed_set = [], set()
    for size in sorted({len(m) for m in moved}, reverse=True):
        group = [j for j in range(n) if len(moved[j]) == size]
        while group:
            ready = [j for j in group if depends[j] <= placed_set]
            if not ready:
                raise NotATree("the axes of coordinates that move the same bodies depend on "
                               "each other")
            order.append(ready[0])
            placed_set.add(ready[0])
            group.remove(ready[0])
    parent = {}
    for position, j in enumerate(order):
        parent[j] = -1
        for i in order[:position]:
            common = moved[i] & moved[j]
            if not common:
                continue
            if common != moved[j]:
                raise NotATree(f"coordinates {names[i]!r} and {names[j]!r} move overlapping but "
                               "different sets of bodies")
            parent[j] = i
    return parent


def _gravity(eq, bodies, others, convert):
    """(g, the records left for Q): potentials c·p_b,i of one body each whose loads are m_b·g
    for one g (every massive body loaded), else g = 0 and every record stays."""
    zero = se.Integer(0)
    moving = set(eq.q) | set(eq.qd) | set(eq.u) | {eq.t}
    loads, used = [[zero] * 3 for _ in bodies], []
    for record in others:
        if not isinstance(record, PotentialEnergy):
            continue
        V = convert(record.expr)
        for b, body in enumerate(bodies):
            found = False
            for i, x in enumerate(body.p):
                if x == 0:
                    continue
                c = V / x
                if not (c.free_symbols & moving):
                    loads[b][i] -= c
                    used.append(record)
                    found = True
                    break
            if found:
                break
    if not used:
        return [zero] * 3, others
    g = None
    for load, body in zip(loads, bodies):
        if body.mass == 0:
            continue
        ratio = [se.expand(x / body.mass) for x in load]
        if g is None:
            g = ratio
        elif any(se.expand(a - b) != 0 for a, b in zip(g, ratio)):
            return [zero] * 3, others
    return g, [r for r in others if not any(r is u for u in used)]


class Identities:
    """Tests of identities between expressions of the equations `eq` at random points: exact
    where only sin and cos of coordinates and rational numbers remain after a rational
    substitution (each angle at a rational point of the unit circle, every other symbol
    rational), else (floating-point constants, other functions) in double precision to 1e-9
    relative (two points each)."""

    def __init__(self, eq, points=2, seed=20261128):
        import random
        rng = random.Random(seed)
        symbols = list(eq.q) + list(eq.qd) + list(eq.p) + list(eq.u) + [eq.t]
        self.exact, self.floats = [], []
        for _ in range(points):
            exact, floats = {}, {}
            for s in symbols:
                value = se.Rational(rng.randint(-97, 97), rng.randint(50, 97)) or se.Rational(1, 3)
                exact[s], floats[s] = value, float(value)
            for qj in eq.q:
                k = se.Rational(rng.randint(1, 89), 97)       # angle 2·atan(k): a circle point
                s, c = 2 * k / (1 + k * k), (1 - k * k) / (1 + k * k)
                exact[se.sin(qj)], exact[se.cos(qj)] = s, c
                floats[qj] = 2 * math.atan(float(k))
            self.exact.append(exact)
            self.floats.append(floats)

    def _exact(self, expr, point):
        """The exact value of `expr` at the point, or None."""
        value = expr.xreplace(self.exact[point])
        return value if value.is_Number and not isinstance(value, se.RealDouble) else None

    def _float(self, expr, point):
        """The value of `expr` in double precision at the point (each angle consistent with its
        sine and cosine)."""
        return float(expr.subs(self.floats[point]).n())

    def same(self, a, b):
        """True if the lists of expressions a and b agree at every point (an entry None in a is
        not tested)."""
        for point in range(len(self.exact)):
            for x, y in zip(a, b):
                if x is None:
                    continue
                x, y = se.sympify(x), se.sympify(y)
                vx, vy = self._exact(x, point), self._exact(y, point)
                if vx is not None and vy is not None:
                    if vx != vy:
                        return False
                    continue
                fx, fy = self._float(x, point), self._float(y, point)
                if abs(fx - fy) > 1e-9 * (1 + abs(fx) + abs(fy)):
                    return False
        return True
