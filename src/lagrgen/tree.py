"""Kinematic trees: the recursive (articulated-body) formulation of a model whose bodies form a
chain or a tree.

The kinetic energy of a model made of constant masses at positions r_b(q) (its particles, and
each planar rigid body as a mass at its centre and its inertia at its 1-component 'position', the
angle) is T = Σ ½·m_b·|ṙ_b|². The model is a *kinematic tree* when its coordinates can be ordered
as the nodes of a rooted forest such that

  * every particle b depends on exactly the coordinates of the path from a root to its leaf ℓ_b
    (∂r_b/∂q_j ≠ 0 exactly for j on that path), and
  * for every coordinate j, all particles strictly below j (of one dimension d) share one column
    ∂r_b/∂q_j = Σ_j, which depends on q_j alone (p_b − p_parent depends on the own coordinate
    only: absolute angles, relative translations, a cart carrying a pendulum, ...).

Then the velocity of the subtree's attachment point follows the recursion V_k = V_parent + Σ_k·q̇_k,
a particle at node k moves with ṙ_b = V_parent + s_b·q̇_k (s_b = ∂r_b/∂q_k), and Lagrange's
equations τ_j = Σ_b m_b·(∂r_b/∂q_j)ᵀ·r̈_b = Q_j (Q: every other term, −∂V/∂q − ∂R/∂q̇ + forces)
are solved for q̈ in O(n) by the articulated-body recursion (Featherstone's ABA in this velocity
space), their Jacobian formed in O(n²) from the derivatives of each node's terms by its own q_j,
q̇_j (see `lagrgen/codegen/templates/tree.c.in` and `lagrgen.runtime.tree`).

A tree may hang from a support that moves with t (every body of the tree with the same
∂r_b/∂t = β(t)): its root's acceleration is then β̇(t) instead of 0. A potential m·g·r_b,i of one
particle becomes a constant load on it instead of a term of Q.

Every property the recursion relies on is checked on the expressions themselves (a column equal
to Σ_j is an identity of the expanded difference, the sets of particles each coordinate moves are
nested or disjoint, Σ_j and s_b depend on their own coordinate only, β on t only); anything not
proven — a 3-D body's rotation, a mass that varies, a driven joint inside the tree, constraints,
impacts, kinetic energy given as an expression, a column that differs — leaves the model to the
dense formulation, with the reason (`analyse`).

The velocity vector V of a node stacks one block per particle dimension present (e.g. the plane's
x, y and the planar bodies' angles: D = 3); particles of dimension d read their block.
"""
from dataclasses import dataclass, field

import symengine as se

from . import tree3d
from .calculus import diff
from .caching import once_per
from .contributions import APPLIED, generalized_forces
from .errors import ModelError, NotATree
from .records import Body3D, PotentialEnergy

#: The formulations a build can use: Cholesky of the dense M(q) (`lagrgen.kernels`), or the
#: articulated-body recursion over a kinematic tree.
FORMULATIONS = ("dense", "recursive")

#: The recursive formulation is chosen automatically from this many coordinates on: measured by
#: `benchmarks/vs_pinocchio.py` on the n-link chain (2 cores, load 4–5), the recursive rhs is the
#: faster from n ≈ 10, its Jacobian from n ≈ 13, its build from n ≈ 8.
RECURSIVE_FROM = 13


@dataclass(eq=False)
class Tree:
    """A model's kinematic tree and the symbolic terms of its nodes (internal symbols).

    Nodes are numbered in preorder (a parent before its children, every subtree contiguous):
    `coordinate[k]` is node k's coordinate, `parent[k]` its parent node (−1 for a root),
    `end[k]` one past the last node of its subtree. `dims` are the particle dimensions present,
    one block of the D-vector each (`offsets`). Per node (lists of D or of 1 entries, see
    `NODE_FIELDS`): S the column the node passes to its subtree, kappa = (∂S/∂q_k)·q̇_k², mass
    the node's own particles' mass per channel, u = Σ m_b·s_b, d = Σ m_b·s_b·s_b,
    e = Σ (m_b·κ_b − f_b), h = Σ s_b·(m_b·κ_b − f_b) (κ_b = (∂s_b/∂q_k)·q̇_k², f_b the constant
    load of a potential m·g·y on the particle, see `_loads`), Q the generalized force of
    everything else (coordinate order), and base the acceleration of the support a root's subtree
    hangs from (a prescribed motion β(t): every body of the subtree has ∂r_b/∂t = β(t); zero
    elsewhere).
    """
    coordinate: tuple
    parent: tuple
    end: tuple
    dims: tuple
    S: list
    kappa: list
    mass: list
    u: list
    d: list
    e: list
    h: list
    Q: list
    base: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    kind = "planar"

    @property
    def fields(self):
        """(name, width) of a node's record (NODE_FIELDS with "D" resolved)."""
        return tuple((name, self.D if w == "D" else w) for name, w in NODE_FIELDS)

    @property
    def width(self):
        return record_width(NODE_FIELDS, self.D)

    def node_records(self):
        return node_records(self)

    @property
    def n(self):
        return len(self.coordinate)

    @property
    def D(self):
        return sum(self.dims)

    @property
    def offsets(self):
        """{dimension: first channel of its block}."""
        out, k = {}, 0
        for d in self.dims:
            out[d] = k
            k += d
        return out

    @property
    def depth(self):
        """The number of nodes on the longest root-to-leaf path."""
        level = []
        for k, p in enumerate(self.parent):
            level.append(1 if p < 0 else level[p] + 1)
        return max(level)


#: Layout of one node's record in the `tree_nodes` kernel: (name, width in units of D or 1).
NODE_FIELDS = (("S", "D"), ("kappa", "D"), ("mass", "D"), ("u", "D"), ("d", 1), ("e", "D"),
               ("h", 1), ("Q", 1), ("base", "D"))
#: Layout of one node's record in the `tree_slopes` kernel: the node terms' derivatives by the own
#: coordinate q_k and rate q̇_k at a given q̈ (`a`): dS = ∂S/∂q_k, alpha = ∂(S·a_k + kappa)/∂q_k,
#: alpha_qd = ∂kappa/∂q̇_k, du = ∂u/∂q_k, c = ∂(d·a_k + h)/∂q_k, c_qd = ∂h/∂q̇_k,
#: g = ∂(u·a_k + e)/∂q_k, g_qd = ∂e/∂q̇_k.
SLOPE_FIELDS = (("dS", "D"), ("alpha", "D"), ("alpha_qd", "D"), ("du", "D"), ("c", 1),
                ("c_qd", 1), ("g", "D"), ("g_qd", "D"))


def record_width(fields, D):
    """The number of doubles in one node's record of `fields`."""
    return sum(D if w == "D" else w for _, w in fields)


def field_offsets(fields, D):
    """{name: offset of the field in a node's record}."""
    out, k = {}, 0
    for name, w in fields:
        out[name] = k
        k += D if w == "D" else w
    return out


@once_per
def analysed(eq):
    """(`Tree`, None) for the `Equations` `eq` of a kinematic tree, else (None, the reason)."""
    try:
        return _tree(eq), None
    except NotATree as exc:
        return None, str(exc)


def analyse(eq):
    """The `Tree` of `eq`; ModelError saying why when the model is not a kinematic tree."""
    tree, reason = analysed(eq)
    if tree is None:
        raise ModelError(f"model {eq.spec.name!r} cannot use formulation='recursive': {reason} "
                         "(use formulation='dense', or None to choose automatically)")
    return tree


def choose(eq, formulation):
    """The formulation a build of `eq` uses: `formulation` when given ("dense", or "recursive",
    checked), else "recursive" for a three-dimensional tree (its dense equations take minutes to
    derive from a few joints on, and run slower) and for a planar one of at least
    RECURSIVE_FROM coordinates."""
    if formulation not in (None,) + FORMULATIONS:
        raise ModelError(f"unknown formulation {formulation!r}: use 'dense', 'recursive' or None")
    if formulation == "recursive":
        analyse(eq)
        return "recursive"
    if formulation == "dense":
        return "dense"
    if tree3d.is_spatial(eq.spec):
        return "recursive" if analysed(eq)[0] is not None else "dense"
    if eq.n < RECURSIVE_FROM:
        return "dense"
    return "recursive" if analysed(eq)[0] is not None else "dense"


# -- detection -----------------------------------------------------------------------------------
def _tree(eq):
    spec = eq.spec
    if tree3d.is_spatial(spec):
        return tree3d.spatial_tree(eq)
    if spec.external is not None:
        raise NotATree("its M and F come from outside (from_sympy)")
    if eq.m:
        raise NotATree("it has constraints")
    if spec.nonsmooth:
        raise NotATree("it has impacts or friction")
    if any(isinstance(r, Body3D) for r in spec.physics):
        raise NotATree("it has 3-D rigid bodies (their rotations are not handled recursively)")
    collected = eq.collected
    if collected.sums.general_T:
        raise NotATree("part of its kinetic energy is given as an expression or has a mass "
                       "that varies")
    q, qd, t = eq.q, eq.qd, eq.t
    n = len(q)
    names = spec.coordinate_names
    index = {qj: j for j, qj in enumerate(q)}
    particles = []     # (mass, position, {coordinate: column})
    for mass, position in collected.particles:
        gradients = [_gradient(rc, index) for rc in position]
        columns = {}
        for j in sorted(set().union(*gradients)):
            column = [g.get(j, se.Integer(0)) for g in gradients]
            if any(c != 0 for c in column):
                columns[j] = column
        if columns:
            particles.append((mass, list(position), columns))
    for j in range(n):
        if not any(j in cols for _, _, cols in particles):
            raise NotATree(f"coordinate {names[j]!r} moves no body")
    dims = tuple(sorted({len(pos) for _, pos, _ in particles}))
    # The tree comes from the sets of bodies each coordinate moves (all bodies, else those of one
    # dimension: planar bodies' angles are moved by their own coordinate only); every body is then
    # placed on it and checked.
    first = None
    for d in (None,) + tuple(reversed(dims)) if len(dims) > 1 else (None,):
        chosen = [b for b, (_, pos, _) in enumerate(particles) if d is None or len(pos) == d]
        try:
            return _placed(eq, particles, chosen, dims)
        except NotATree as exc:
            first = first or exc
    raise first


def _placed(eq, particles, chosen, dims):
    """The `Tree` whose shape comes from the bodies `chosen`, with every body placed on it: its
    leaf the deepest coordinate it depends on, all of which must lie on the leaf's path; the
    columns shared (`_shared_columns`); NotATree otherwise."""
    q, names, n = eq.q, eq.spec.coordinate_names, eq.n
    moved = [frozenset(b for b in chosen if j in particles[b][2]) for j in range(n)]
    parent_coordinate = _forest(moved, names)
    coordinate, parent, end = tree3d.preorder(parent_coordinate)
    node_of = {j: k for k, j in enumerate(coordinate)}
    leaf = []
    for _, _, cols in particles:
        own = max(cols, key=node_of.get)
        k = node_of[own]
        if any(not (node_of[j] <= k < end[node_of[j]]) for j in cols):
            raise NotATree(f"a body depends on coordinates that are not on one path of the tree "
                           f"(through {names[own]!r})")
        leaf.append(own)
    S = _shared_columns(particles, leaf, dims, q, names, parent_coordinate, eq.t)
    for b, (_, _, cols) in enumerate(particles):
        own = leaf[b]
        if any(s.free_symbols & ((set(q) | {eq.t}) - {q[own]}) for s in cols[own]):
            raise NotATree(f"a body's own column depends on other coordinates than "
                           f"{names[own]!r} (or on t)")
    base = _base_motion(eq, particles, leaf, parent_coordinate, dims)
    loads, Q = _loads(eq, particles, leaf, coordinate)
    return _node_terms(eq, particles, leaf, dims, S, coordinate, parent, end, loads, Q, base)


def _base_motion(eq, particles, leaf, parent_coordinate, dims):
    """{root coordinate: {dimension: β̇(t)}}: a prescribed motion of the support each tree hangs
    from. Every body of a root's subtree must have the same ∂r_b/∂t = β(t) (a function of t
    alone, per dimension: zero included); then r̈_b holds β̇ and the root's acceleration is β̇
    instead of 0. NotATree otherwise (a driven joint inside the tree)."""
    t, names = eq.t, eq.spec.coordinate_names
    beta = {}
    for b, (_, position, _) in enumerate(particles):
        root = leaf[b]
        while parent_coordinate[root] >= 0:
            root = parent_coordinate[root]
        rate = [diff(rc, t) if t in rc.free_symbols else se.Integer(0) for rc in position]
        if any(r.free_symbols & (set(eq.q) | {t}) - {t} for r in rate):
            raise NotATree("a body's position depends on t together with the coordinates (a "
                           "driven joint or a moving frame)")
        known = beta.setdefault(root, {}).get(len(position))
        if known is None:
            beta[root][len(position)] = rate
        elif any(se.expand(x - y) != 0 for x, y in zip(known, rate)):
            raise NotATree(f"the bodies of the tree of {names[root]!r} move with t differently "
                           "(a driven joint inside the tree)")
    return {root: {d: [diff(r, t) for r in rates] for d, rates in by_dim.items()}
            for root, by_dim in beta.items()}


def _gradient(expr, index):
    """{j: ∂expr/∂q_j} for the coordinates q_j (`index`: symbol -> j) in expr; a sum is
    differentiated by q_j in its terms holding q_j only (a chain's positions are long sums)."""
    terms = expr.args if isinstance(expr, se.Add) else (expr,)
    by_coordinate = {}
    for term in terms:
        for v in term.free_symbols:
            if v in index:
                by_coordinate.setdefault(index[v], []).append(term)
    q = {j: v for v, j in index.items()}
    return {j: diff(se.Add(*parts), q[j]) for j, parts in by_coordinate.items()}


def _forest(moved, names):
    """{coordinate: parent coordinate or −1} from the sets of bodies each coordinate moves, which
    must be nested or disjoint (a laminar family); equal sets form a chain in index order, a
    coordinate that moves none of them is a root."""
    order = sorted(range(len(moved)), key=lambda j: (-len(moved[j]), j))   # supersets first
    parent = {}
    placed = []
    for j in order:
        parent[j] = -1
        for i in placed:
            common = moved[i] & moved[j]
            if not common:
                continue
            if common != moved[j]:
                raise NotATree(f"coordinates {names[i]!r} and {names[j]!r} move overlapping but "
                               "different sets of bodies")
            parent[j] = i          # the last (deepest) coordinate whose bodies contain j's
        placed.append(j)
    return parent


def _shared_columns(particles, leaf, dims, q, names, parent_coordinate, t):
    """Σ_j per dimension: the column every particle strictly below coordinate j has for q_j (zero
    where it does not depend on q_j, and where no particle is below), checked equal (expanded
    difference 0) and a function of q_j alone."""
    n = len(q)
    S = [{d: None for d in dims} for _ in range(n)]
    for b, (_, position, cols) in enumerate(particles):
        d = len(position)
        j = parent_coordinate[leaf[b]]
        while j >= 0:
            column = cols.get(j, [se.Integer(0)] * d)
            known = S[j][d]
            if known is None:
                if any(c.free_symbols & ((set(q) | {t}) - {q[j]}) for c in column):
                    raise NotATree(f"the column of {names[j]!r} in a body below it depends on "
                                   "other coordinates or t (relative angles or a rotating "
                                   "frame)")
                S[j][d] = column
            elif any(se.expand(a - c) != 0 for a, c in zip(known, column)):
                raise NotATree(f"bodies below {names[j]!r} move differently with it "
                               "(relative angles or a rotating frame)")
            j = parent_coordinate[j]
    return [{d: (col if col is not None else [se.Integer(0)] * d) for d, col in Sj.items()}
            for Sj in S]


# -- the nodes' terms ----------------------------------------------------------------------------
def _loads(eq, particles, leaf, coordinate):
    """({particle: load vector}, Q): the potential energies that are c·r_b,i + c₀ for one particle b
    (c, c₀ free of q, q̇, t, u: gravity on a mass) as constant loads −c·e_i on their particles,
    proven by the expanded difference; and Q_j = (applied forces)_j − ∂V/∂q_j − ∂R/∂q̇_j of all the
    other records of V, R and Q."""
    spec, q = eq.spec, eq.q
    convert = eq.collected.convert
    depth = {j: k for k, j in enumerate(coordinate)}
    by_leaf = {}
    for b, j in enumerate(leaf):
        by_leaf.setdefault(j, []).append(b)
    moving = set(eq.qd) | set(eq.u) | {eq.t}
    loads, rest = {}, []
    for record in spec.physics:
        if isinstance(record, PotentialEnergy):
            found = _particle_potential(convert(record.expr), particles, by_leaf, depth, q, moving)
            if found is not None:
                b, i, c = found
                load = loads.setdefault(b, [se.Integer(0)] * len(particles[b][1]))
                load[i] -= c
                continue
        if isinstance(record, APPLIED):
            rest.append(record)
    Q = generalized_forces(rest, convert, q, eq.qd, eq.t)
    return loads, Q


def _particle_potential(V, particles, by_leaf, depth, q, moving):
    """(particle b, component i, c) with V = c·r_b,i + c₀ (c, c₀ free of q and of `moving`), or
    None. Candidates are the particles of V's deepest coordinate; c = (∂V/∂q_ℓ)/(∂r_b,i/∂q_ℓ)."""
    free = V.free_symbols
    if free & moving:
        return None
    used = [j for j, qj in enumerate(q) if qj in free]
    if not used:
        return None
    own = max(used, key=depth.get)
    for b in by_leaf.get(own, ()):
        _, position, cols = particles[b]
        if any(j not in cols for j in used):
            continue
        dV = diff(V, q[own])
        for i, s in enumerate(cols[own]):
            if s == 0:
                continue
            c = dV / s
            if c.free_symbols & (set(q) | moving):
                continue
            if not (se.expand(V - c * position[i]).free_symbols & set(q)):
                return b, i, c
    return None


def _node_terms(eq, particles, leaf, dims, S_by_coordinate, coordinate, parent, end, loads, Q,
                base):
    q, qd = eq.q, eq.qd
    n = len(q)
    D = sum(dims)
    offsets, k0 = {}, 0
    for d in dims:
        offsets[d] = k0
        k0 += d
    zero = se.Integer(0)
    own = {j: [] for j in range(n)}
    for b, (mass, position, cols) in enumerate(particles):
        load = loads.get(b, [zero] * len(position))
        own[leaf[b]].append((mass, len(position), cols[leaf[b]], load))
    tree = Tree(coordinate, parent, end, dims, [], [], [], [], [], [], [], [])
    names = eq.spec.coordinate_names
    for k, j in enumerate(coordinate):
        qj, qdj = q[j], qd[j]
        S = [zero] * D
        for d, col in S_by_coordinate[j].items():
            S[offsets[d]:offsets[d] + d] = col
        kappa = [se.expand(diff(s, qj) * qdj ** 2) for s in S]
        mass, u, e = [zero] * D, [zero] * D, [zero] * D
        dd = h = zero
        for m, dim, s, load in own[j]:
            o = offsets[dim]
            bias = [m * diff(c, qj) * qdj ** 2 - f for c, f in zip(s, load)]   # m·κ_b − f_b
            for i in range(dim):
                mass[o + i] += m
                u[o + i] += m * s[i]
                e[o + i] += bias[i]
            dd += m * sum(c * c for c in s)
            h += sum(c * x for c, x in zip(s, bias))
        tree.S.append(S)
        tree.kappa.append(kappa)
        tree.mass.append(mass)
        tree.u.append([se.expand(x) for x in u])
        tree.d.append(se.expand(dd))
        tree.e.append([se.expand(x) for x in e])
        tree.h.append(se.expand(h))
        motion = [zero] * D
        for d, acc in base.get(j, {}).items() if parent[k] < 0 else ():
            motion[offsets[d]:offsets[d] + d] = acc
        tree.base.append(motion)
        above = f", below {names[coordinate[parent[k]]]}" if parent[k] >= 0 else ", a root"
        carried = ", ".join(_body_name(eq, m, dim) for m, dim, _, _ in own[j]) or "no body"
        tree.notes.append(f"node {k}: coordinate {names[j]}{above}; carries {carried}")
    tree.Q = Q
    return tree


def _body_name(eq, mass, dim):
    """How a comment of the generated code names a body: its kind and mass in the user's names."""
    kind = {1: "a 1-D mass or inertia", 2: "a planar mass", 3: "a mass"}[dim]
    return f"{kind} of {str(eq.to_user(mass)).replace('*/', '* /')}"


# -- kernel expressions --------------------------------------------------------------------------
def node_records(tree):
    """The `tree_nodes` kernel's output: each node's NODE_FIELDS record, in node order."""
    out = []
    for k, j in enumerate(tree.coordinate):
        values = {"S": tree.S[k], "kappa": tree.kappa[k], "mass": tree.mass[k], "u": tree.u[k],
                  "d": [tree.d[k]], "e": tree.e[k], "h": [tree.h[k]], "Q": [tree.Q[j]],
                  "base": tree.base[k]}
        for name, _ in NODE_FIELDS:
            out.extend(values[name])
    return out


def slope_records(tree, eq):
    """The `tree_slopes` kernel's output: each node's SLOPE_FIELDS record at a = q̈ (symbols)."""
    out = []
    for k, j in enumerate(tree.coordinate):
        qj, qdj, aj = eq.q[j], eq.qd[j], eq.a[j]
        S, kappa, u, e = tree.S[k], tree.kappa[k], tree.u[k], tree.e[k]
        dS = [diff(s, qj) for s in S]
        values = {
            "dS": dS,
            "alpha": [se.expand(ds * aj + diff(x, qj)) for ds, x in zip(dS, kappa)],
            "alpha_qd": [diff(x, qdj) for x in kappa],
            "du": [diff(x, qj) for x in u],
            "c": [se.expand(diff(tree.d[k], qj) * aj + diff(tree.h[k], qj))],
            "c_qd": [diff(tree.h[k], qdj)],
            "g": [se.expand(diff(x, qj) * aj + diff(y, qj)) for x, y in zip(u, e)],
            "g_qd": [diff(y, qdj) for y in e],
        }
        for name, _ in SLOPE_FIELDS:
            out.extend(values[name])
    return out


def gradients(tree, eq):
    """(([(i, j)], [∂Q_i/∂q_j]), ([(i, j)], [∂Q_i/∂q̇_j]), ∂Q/∂u as n×n_inputs lists): the
    derivatives of the generalized forces, the first two sparse (nonzero entries only)."""
    def sparse(variables):
        index, values = [], []
        for i, Qi in enumerate(tree.Q):
            free = Qi.free_symbols
            for j, v in enumerate(variables):
                if v in free:
                    d = diff(Qi, v)
                    if d != 0:
                        index.append((i, j))
                        values.append(d)
        return index, values
    dQ_du = [[diff(Qi, uk) if uk in Qi.free_symbols else se.Integer(0) for uk in eq.u]
             for Qi in tree.Q]
    return sparse(eq.q), sparse(eq.qd), dQ_du


def parameter_gradients(tree, eq):
    """(([(node, offset, parameter)], [∂record/∂p]), ([(coordinate, parameter)], [∂Q/∂p])): the
    nonzero derivatives of the node records (offset within a record) and of Q by the parameters,
    the first sorted by parameter."""
    if not eq.p:
        return ([], []), ([], [])
    width = tree.width
    records = tree.node_records()
    entries = []
    for pos, expr in enumerate(records):
        free = expr.free_symbols
        for j, pj in enumerate(eq.p):
            if pj in free:
                d = diff(expr, pj)
                if d != 0:
                    entries.append(((j, pos // width, pos % width), d))
    entries.sort(key=lambda item: item[0])
    forces = []
    for i, Qi in enumerate(tree.Q):
        free = Qi.free_symbols
        for j, pj in enumerate(eq.p):
            if pj in free:
                d = diff(Qi, pj)
                if d != 0:
                    forces.append(((i, j), d))
    return (([(k, o, j) for (j, k, o), _ in entries], [d for _, d in entries]),
            ([ij for ij, _ in forces], [d for _, d in forces]))


def explicit_time(tree, eq):
    """True if the equations depend on t explicitly (for a tree: through Q and the supports'
    motion)."""
    if tree.kind == "spatial":
        return tree3d.explicit_time(tree, eq)
    return any(eq.t in e.free_symbols for e in list(tree.Q) + [x for b in tree.base for x in b])
