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
from dataclasses import dataclass, field

import symengine as se

from . import frames
from .contributions import APPLIED, generalized_forces
from .errors import NotATree
from .records import Articulation

#: Layout of one node's record in the tree_nodes kernel: (name, width).
FIELDS = (("s", 6), ("Y", 10), ("base", 6), ("Q", 1))


@dataclass(eq=False)
class SpatialTree:
    """A model's three-dimensional kinematic tree and its nodes' terms (internal symbols).

    Nodes are in preorder (a parent before its children, every subtree contiguous):
    `coordinate[k]` is node k's coordinate, `parent[k]` its parent node (−1: a root), `end[k]`
    one past the last node of its subtree; `records[k]` the node's FIELDS (SymEngine), `Q` the
    generalized forces in coordinate order.
    """
    coordinate: tuple
    parent: tuple
    end: tuple
    records: list
    Q: list
    notes: list = field(default_factory=list)
    kind = "spatial"
    fields = FIELDS

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


def is_spatial(spec):
    """True if the model's bodies are three-dimensional (an articulation or 3-D rigid bodies):
    the recursion over its tree, if any, is this module's."""
    from .records import Body3D
    return any(isinstance(r, (Articulation, Body3D)) for r in spec.physics)


def spatial_tree(eq):
    """The `SpatialTree` of the `Equations` eq; NotATree saying why it has none."""
    spec = eq.spec
    if eq.m:
        raise NotATree("it has constraints")
    articulations = [r for r in spec.physics if isinstance(r, Articulation)]
    if not articulations:
        raise NotATree("its 3-D rigid bodies are not an articulation (from_urdf): the "
                       "recursion over hand-written 3-D bodies is not available")
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
    """The tree of an Articulation: its segments in order, one coordinate each."""
    q, names = eq.q, eq.spec.coordinate_names
    convert = eq.collected.convert
    coordinate = []
    for segment in record.segments:
        motion = convert(segment.motion)
        if motion not in q:
            raise NotATree(f"joint {segment.name!r} follows another joint (mimic): one "
                           "coordinate moves two branches")
        coordinate.append(q.index(motion))
    if sorted(coordinate) != list(range(len(q))):
        raise NotATree("its coordinates are not one joint each")
    parent = tuple(s.parent for s in record.segments)
    end = _subtree_ends(parent)
    world = frames.frames(record, convert, q, eq.qd, eq.t)
    gravity = [convert(g) for g in record.gravity]
    Q = generalized_forces(others, convert, q, eq.qd, eq.t)
    zero = se.Integer(0)
    records, notes = [], []
    for k, (segment, frame) in enumerate(zip(record.segments, world)):
        base = [zero] * 3 + [-g for g in gravity] if parent[k] < 0 else [zero] * 6
        records.append(list(frame.twist) + frames.world_inertia(frame) + base
                       + [Q[coordinate[k]]])
        above = (f", below {names[coordinate[parent[k]]]}" if parent[k] >= 0
                 else ", a root")
        notes.append(f"node {k}: {segment.kind} joint {names[coordinate[k]]}{above}; carries "
                     f"{('link ' + segment.link) if segment.link else 'no body'}")
    return SpatialTree(tuple(coordinate), parent, end, records, Q, notes)


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
    """True if the node terms or Q depend on t."""
    return any(eq.t in x.free_symbols for x in tree.node_records())
