"""The recursions of an articulation traced for one robot: straight-line C in which its numbers
are folded (`lagrgen.trace`).

The articulated-body algorithm runs in each joint's own frame (Featherstone, RBDA ch. 7): body
k's frame is its parent's moved by the joint's placement (rotation P, origin o: numbers) and by
its motion J(θ) (a rotation about the unit axis a, or a translation along it), so that its motion
subspace S is [a; 0] or [0; a] (one unit vector for an axis along x, y or z), its inertia a
constant and each transform a product of constant and sparse factors. Spatial vectors are
[ω; v] and [n; f] at the frame's origin; an articulated inertia is symmetric, [[A, B], [Bᵀ, C]].

    pass 1 (root to leaves)  v_k = X_k·v_λ + S·q̇,  c_k = (X_k·v_λ) × S·q̇,  I^A_k = I_k,
                             p^A_k = v_k ×* I_k·v_k
    pass 2 (leaves to root)  U = I^A·S, D = Sᵀ·U, u = Q − Sᵀ·p^A;  I^a = I^A − U·Uᵀ/D,
                             p^a = p^A + I^a·c + U·u/D;  I^A_λ += X_kᵀ·I^a·X_k,  p^A_λ += X_kᵀ·p^a
    pass 3 (root to leaves)  a' = X_k·a_λ + c_k (a root's a_λ: [0; −g]),  q̈ = (u − Uᵀ·a')/D,
                             a_k = a' + S·q̈

Everything a robot's file fixes is a number at trace time, so every product with a zero entry of
a placement, an axis or an inertia is dropped and every product with ±1 is a sign.
"""
import math
from dataclasses import dataclass

from .trace import Printer, Tape

#: A robot of at most this many joints may get its recursions traced into straight-line code; a
#: larger one runs the generic loops of tree3d.c.in (the straight-line code grows like the robot,
#: and its compile time with it: ~0.5 s of gcc per 1000 flops).
LEAN_MAX_JOINTS = 64
#: The flops of straight-line code a build accepts (q̈ first, then the node records): gcc takes
#: about 0.7 s per 1000 at -O2 (Talos' q̈, 8 800 flops: 5.8 s; cut into parts it takes longer,
#: 20 s). Talos' q̈ and records (13 700) fit, and tiago's q̈ (13 400) without its records: in
#: the loops tiago's q̈ costs 1.95× the instructions of the trace, Talos' M 0.84× crba's.
LEAN_MAX_FLOPS = 14000
#: A traced q̈ of more flops per joint than this runs slower than the loops (measured: the 3-D
#: chains of random placements, 690 flops per joint traced, are faster in the loops).
LEAN_MAX_FLOPS_PER_JOINT = 450
#: The same for the traced node records (placements of arbitrary rotations: 230 per joint, barely
#: fewer than the loop's, at seconds of compile time).
LEAN_MAX_NODE_FLOPS_PER_JOINT = 200


@dataclass
class Traced:
    """A traced C function `int name(parameters)`: its comment and body, the names of the
    functions it calls and their prototypes (`declarations`, given by the code that defines
    them: `codegen.tree_code`), its flops, and whether it traced the loads (Q, g) itself."""
    name: str
    parameters: str
    comment: str
    body: str
    flops: int
    loads: bool = False
    calls: tuple = ()
    declarations: tuple = ()

    def declaration(self, linkage="static"):
        """Its prototype, `linkage` static or LG_PART_FN (a unit of its own, `c_model`)."""
        return f"LG_FN {linkage} int {self.name}({self.parameters});"

    def definition(self, linkage="static"):
        """Its C text, after the declarations of the functions it calls."""
        return ("".join(f"{line}\n" for line in self.declarations) + f"/* {self.comment} */\n"
                + self.declaration(linkage)[:-1] + f"\n{{\n{self.body}}}\n")


class Spatial:
    """Spatial algebra on a `Tape` (vectors and matrices as lists of its values)."""

    def __init__(self, tape):
        self.t = tape

    def rot(self, E, x):
        """E·x (E: 3 rows)."""
        return [self.t.dot(row, x) for row in E]

    def rot_t(self, E, x):
        """Eᵀ·x."""
        t = self.t
        return [t.dot((E[0][i], E[1][i], E[2][i]), x) for i in range(3)]

    def cross(self, a, b):
        t = self.t
        return [t.sub(t.mul(a[1], b[2]), t.mul(a[2], b[1])),
                t.sub(t.mul(a[2], b[0]), t.mul(a[0], b[2])),
                t.sub(t.mul(a[0], b[1]), t.mul(a[1], b[0]))]

    def vadd(self, a, b):
        return [self.t.add(x, y) for x, y in zip(a, b)]

    def vsub(self, a, b):
        return [self.t.sub(x, y) for x, y in zip(a, b)]

    def scale(self, c, a):
        return [self.t.mul(c, x) for x in a]

    def crm(self, v, m):
        """v × m of motions."""
        w, vo = v[:3], v[3:]
        return self.cross(w, m[:3]) + self.vadd(self.cross(w, m[3:]), self.cross(vo, m[:3]))

    def crf(self, v, f):
        """v ×* f (a motion on a force)."""
        w, vo = v[:3], v[3:]
        return self.vadd(self.cross(w, f[:3]), self.cross(vo, f[3:])) + self.cross(w, f[3:])

    # -- transforms: a stage (E, r) takes parent coordinates to child ones, the child's origin at
    # r (parent axes) and its axes E·(parent axes) --------------------------------------------
    def motion(self, stage, m):
        """[E·ω; E·(v − r × ω)]."""
        E, r = stage
        w, v = m[:3], m[3:]
        if r is not None:
            v = self.vsub(v, self.cross(r, w))
        return self.rot(E, w) + self.rot(E, v) if E is not None else list(w) + list(v)

    def force_back(self, stage, f):
        """The child's force in parent coordinates: f_p = Eᵀ·f, n_p = Eᵀ·n + r × f_p."""
        E, r = stage
        n, fo = f[:3], f[3:]
        if E is not None:
            n, fo = self.rot_t(E, n), self.rot_t(E, fo)
        if r is not None:
            n = self.vadd(n, self.cross(r, fo))
        return list(n) + list(fo)

    def sym_rot_back(self, E, A):
        """Eᵀ·A·E of a symmetric 3×3 A (full lists, shared entries)."""
        t = self.t
        AE = [[t.dot(A[i], (E[0][j], E[1][j], E[2][j])) for j in range(3)] for i in range(3)]
        out = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                out[i][j] = out[j][i] = t.dot((E[0][i], E[1][i], E[2][i]),
                                              (AE[0][j], AE[1][j], AE[2][j]))
        return out

    def full_rot_back(self, E, B):
        """Eᵀ·B·E of a 3×3 B."""
        t = self.t
        BE = [[t.dot(B[i], (E[0][j], E[1][j], E[2][j])) for j in range(3)] for i in range(3)]
        return [[t.dot((E[0][i], E[1][i], E[2][i]), (BE[0][j], BE[1][j], BE[2][j]))
                 for j in range(3)] for i in range(3)]

    def inertia_back(self, stage, I):
        """Xᵀ·I·X of an articulated inertia I = (A, B, C) through the stage X = (E, r)."""
        E, r = stage
        A, B, C = I
        if E is not None:
            A, B, C = self.sym_rot_back(E, A), self.full_rot_back(E, B), self.sym_rot_back(E, C)
        if r is None:
            return A, B, C
        t = self.t
        R = _skew(t, r)
        RC = [[t.dot(R[i], (C[0][j], C[1][j], C[2][j])) for j in range(3)] for i in range(3)]
        B2 = [[t.add(B[i][j], RC[i][j]) for j in range(3)] for i in range(3)]
        RBt = [[t.dot(R[i], B[j]) for j in range(3)] for i in range(3)]       # R·Bᵀ
        A2 = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(i, 3):
                RCR = t.dot(RC[i], (R[0][j], R[1][j], R[2][j]))
                A2[i][j] = A2[j][i] = t.sub(t.add(A[i][j], t.add(RBt[i][j], RBt[j][i])), RCR)
        return A2, B2, C

    def inertia_apply(self, I, m):
        """I·m = [A·ω + B·v; Bᵀ·ω + C·v]."""
        A, B, C = I
        w, v = m[:3], m[3:]
        t = self.t
        n = [t.add(t.dot(A[i], w), t.dot(B[i], v)) for i in range(3)]
        f = [t.add(t.dot((B[0][i], B[1][i], B[2][i]), w), t.dot(C[i], v)) for i in range(3)]
        return n + f


def _skew(t, r):
    """[r]× on the tape."""
    return [[0.0, t.neg(r[2]), r[1]], [r[2], 0.0, t.neg(r[0])], [t.neg(r[1]), r[0], 0.0]]


def rigid_inertia(t, body):
    """(A, B, C) of a rigid body of parameters (m, h, I_O: xx, xy, yy, xz, yz, zz) about the
    frame's origin: A = I_O, B = [h]×, C = m·1."""
    m, h = body[0], body[1:4]
    xx, xy, yy, xz, yz, zz = body[4:]
    A = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
    return A, _skew(t, h), [[m, 0.0, 0.0], [0.0, m, 0.0], [0.0, 0.0, m]]


def joint_rotation(t, axis, s, c):
    """J(θ) = 1 + sin θ·[a]× + (1 − cos θ)·[a]×² from s = sin θ, c = cos θ: exactly c and ±s
    for an axis along x, y or z."""
    nonzero = [i for i, a in enumerate(axis) if a != 0.0]
    if len(nonzero) == 1 and abs(axis[nonzero[0]]) == 1.0:
        i = nonzero[0]
        j, k = (i + 1) % 3, (i + 2) % 3
        sign = axis[i]
        J = [[0.0] * 3 for _ in range(3)]
        J[i][i] = 1.0
        J[j][j] = J[k][k] = c
        J[k][j], J[j][k] = t.mul(sign, s), t.mul(-sign, s)
        return J
    a = axis
    K = [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]]
    K2 = [[sum(K[i][m] * K[m][j] for m in range(3)) for j in range(3)] for i in range(3)]
    c1 = t.sub(1.0, c)
    return [[t.add(t.add(float(i == j), t.mul(K[i][j], s)), t.mul(K2[i][j], c1))
             for j in range(3)] for i in range(3)]


class Robot:
    """The joints of an articulation (`lagrgen.tree3d.Joints`) and its tree, on a tape: each
    node's stages from its parent's frame to its own, its S and its body's inertia."""

    def __init__(self, tape, joints, parent, coordinate, inputs=None):
        self.t, self.sp = tape, Spatial(tape)
        self.parent, self.coordinate = parent, coordinate
        self.n = len(parent)
        inputs = inputs or {}
        q = inputs.get("q", lambda i: tape.leaf(f"q[{i}]"))
        p = inputs.get("p", lambda j: tape.leaf(f"p[{j}]"))
        self.stages, self.S, self.inertia = [], [], []
        for k in range(self.n):
            P = joints.placement[k]
            axis = [float(a) for a in joints.axis[k]]
            mult, offset = joints.motion[k]
            theta = tape.add(tape.mul(float(mult), q(coordinate[k])), float(offset))
            rotation = [[float(P[3 * j + i]) for j in range(3)] for i in range(3)]   # Pᵀ
            origin = [float(x) for x in P[9:]]
            placement = (None if rotation == [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
                         else rotation, None if origin == [0.0, 0.0, 0.0] else origin)
            if joints.prismatic[k]:
                motion = (None, [tape.mul(a, theta) for a in axis])
                S = [0.0] * 3 + [a * float(mult) for a in axis]
            else:
                J = joint_rotation(tape, axis, tape.sin(theta), tape.cos(theta))
                motion = ([[J[j][i] for j in range(3)] for i in range(3)], None)    # Jᵀ
                S = [a * float(mult) for a in axis] + [0.0] * 3
            self.stages.append([s for s in (placement, motion) if s != (None, None)])
            self.S.append(S)
            body = [p(j) if j >= 0 else float(x)
                    for x, j in zip(joints.inertia[k], joints.inertia_parameter[k])]
            self.inertia.append(rigid_inertia(tape, body))

    def motion_in(self, k, m):
        """X_k·m: a motion of the parent's frame in node k's."""
        for stage in self.stages[k]:
            m = self.sp.motion(stage, m)
        return m

    def force_out(self, k, f):
        """X_kᵀ·f: a force of node k's frame in its parent's."""
        for stage in reversed(self.stages[k]):
            f = self.sp.force_back(stage, f)
        return f

    def inertia_out(self, k, I):
        """X_kᵀ·I·X_k."""
        for stage in reversed(self.stages[k]):
            I = self.sp.inertia_back(stage, I)
        return I


def _sym_minus_outer(t, M, U, Dinv, S):
    """I^a = M − U·Uᵀ/D of a symmetric 6×6 M = (A, B, C) and U = M·S (6), D = Sᵀ·U. I^a·S = 0:
    for S along one coordinate axis e, its row and column e are exact zeros (not formed)."""
    A, B, C = M
    W = [t.mul(x, Dinv) for x in U]
    axes = [i for i, x in enumerate(S) if x != 0.0]
    null = axes[0] if len(axes) == 1 else -1

    def entry(x, i, j):
        return 0.0 if null in (i, j) else t.sub(x, t.mul(W[i], U[j]))
    A2 = [[None] * 3 for _ in range(3)]
    C2 = [[None] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            A2[i][j] = A2[j][i] = entry(A[i][j], i, j)
            C2[i][j] = C2[j][i] = entry(C[i][j], 3 + i, 3 + j)
    B2 = [[entry(B[i][j], i, 3 + j) for j in range(3)] for i in range(3)]
    return A2, B2, C2


def _sym_add(t, M, N):
    return tuple([[t.add(x, y) for x, y in zip(rm, rn)] for rm, rn in zip(bm, bn)]
                 for bm, bn in zip(M, N))


def articulated_body(tape, robot, qd, Q, g):
    """(q̈ per coordinate, [D_k]) of the articulated-body algorithm on the tape."""
    t, sp, n = tape, robot.sp, robot.n
    v, c, IA, pA = [None] * n, [None] * n, [None] * n, [None] * n
    for k in range(n):
        S, ck = robot.S[k], robot.coordinate[k]
        vJ = sp.scale(qd(ck), S)
        parent = robot.parent[k]
        if parent < 0:
            v[k], c[k] = vJ, [0.0] * 6
        else:
            vp = robot.motion_in(k, v[parent])
            v[k], c[k] = sp.vadd(vp, vJ), sp.crm(vp, vJ)
        IA[k] = robot.inertia[k]
        pA[k] = sp.crf(v[k], sp.inertia_apply(IA[k], v[k]))
    U, Dinv, u, D = [None] * n, [None] * n, [None] * n, [None] * n
    for k in range(n - 1, -1, -1):
        S = robot.S[k]
        U[k] = sp.inertia_apply(IA[k], S)
        D[k] = t.dot(S, U[k])
        Dinv[k] = t.inv(D[k])
        u[k] = t.sub(Q(robot.coordinate[k]), t.dot(S, pA[k]))
        parent = robot.parent[k]
        if parent < 0:
            continue
        Ia = _sym_minus_outer(t, IA[k], U[k], Dinv[k], S)
        pa = sp.vadd(sp.vadd(pA[k], sp.inertia_apply(Ia, c[k])),
                     sp.scale(t.mul(u[k], Dinv[k]), U[k]))
        IA[parent] = _sym_add(t, IA[parent], robot.inertia_out(k, Ia))
        pA[parent] = sp.vadd(pA[parent], robot.force_out(k, pa))
    a, qdd = [None] * n, {}
    base = [0.0] * 3 + [t.neg(x) for x in g]
    for k in range(n):
        parent = robot.parent[k]
        ap = robot.motion_in(k, a[parent] if parent >= 0 else base)
        ap = sp.vadd(ap, c[k])
        x = t.mul(t.sub(u[k], t.dot(U[k], ap)), Dinv[k])
        qdd[robot.coordinate[k]] = x
        a[k] = sp.vadd(ap, sp.scale(x, robot.S[k]))
    return qdd, D


def _loads(tape, loads):
    """(Q, g) as functions of the index: the expressions `loads` = (Q, g) traced (a robot's
    inputs, dampers, gravity), or the arrays Q and g of the kernel tree_loads when one of them is
    not traceable (`traced` False)."""
    from .trace import NotTraceable, from_symengine
    if loads is not None:
        try:
            memo = {}
            Q = [from_symengine(tape, x, memo) for x in loads[0]]
            g = [from_symengine(tape, x, memo) for x in loads[1]]
            return Q.__getitem__, g, True
        except NotTraceable:
            pass
    return (lambda i: tape.leaf(f"Q[{i}]")), [tape.leaf(f"g[{i}]") for i in range(3)], False


#: A pivot of M below this fraction of its diagonal entry is noted (linalg.c.in's LG_PIVOT_NOTE).
PIVOT_NOTE = 1e-3


def diagonal_bounds(joints, parent):
    """An upper bound of M_kk over every q for each node k, from the numbers of its subtree:
    Σ m_b of a prismatic joint; Σ_b trace(I_b about its centre of mass) + m_b·ρ_b² of a revolute
    one, ρ_b the centre's distance from the joint's origin bounded by the placements' lengths on
    the way (times the joint's multiplier squared); inf where a body's inertia is a parameter or a
    prismatic joint on the way moves it without bound."""
    n = len(parent)
    children = [[] for _ in range(n)]
    for k, up in enumerate(parent):
        if up >= 0:
            children[up].append(k)
    bounds = []
    for k in range(n):
        total, stack = 0.0, [(k, 0.0, False)]
        while stack:
            b, reach, unbounded = stack.pop()
            if any(j >= 0 for j in joints.inertia_parameter[b]):
                total = math.inf
                break
            m, h, I = float(joints.inertia[b][0]), joints.inertia[b][1:4], joints.inertia[b][4:]
            centre = math.sqrt(sum(float(x) ** 2 for x in h)) / m if m > 0 else 0.0
            own = float(I[0]) + float(I[2]) + float(I[5]) - 2 * m * centre ** 2
            if joints.prismatic[k]:
                total += m
            elif unbounded and m > 0:
                total = math.inf
                break
            else:
                total += max(own, 0.0) + m * (reach + centre) ** 2
            for c in children[b]:
                length = math.sqrt(sum(float(x) ** 2 for x in joints.placement[c][9:]))
                stack.append((c, reach + length, unbounded or bool(joints.prismatic[c])))
        bounds.append(total * float(joints.motion[k][0]) ** 2)
    return bounds


def trace_qdd(joints, parent, coordinate, notes, loads=None, name="lg_lean_qdd"):
    """The C function `int name(t, q, qd, p, u, Q, g, qdd)`: q̈ by the articulated-body algorithm
    traced for the robot (1 when M is not positive definite; a pivot D_k not above PIVOT_NOTE of
    the bound of M_kk, `diagonal_bounds`, has M's pivots checked and noted by lg_lean_pivots as
    the generic recursion's are), with the
    generalized forces and the gravity `loads` = (Q, g) (SymEngine) traced too where they can
    be (`Traced.loads` False: it reads them from the arrays Q and g, lg_tree_loads')."""
    tape = Tape()
    robot = Robot(tape, joints, parent, coordinate)
    Q, g, traced = _loads(tape, loads)
    qdd, D = articulated_body(tape, robot, lambda i: tape.leaf(f"qd[{i}]"), Q, g)
    outputs = [qdd[i] for i in range(len(qdd))]
    printer = Printer(tape)
    floors = [PIVOT_NOTE * b if math.isfinite(b) else 0.0
              for b in diagonal_bounds(joints, parent)]
    pivots = " && ".join(f"{printer.ref(d)} > {floor!r}" for d, floor in zip(D, floors)
                         if not isinstance(d, float))
    legend = "\n".join(f" *   {note}" for note in notes)
    stores = [f"    if (!({pivots or '1'}) && lg_lean_pivots(t, q, p))\n        return 1;"]
    stores += [f"    qdd[{i}] = {printer.ref(x)};" for i, x in enumerate(outputs)]
    return _function(
        tape, outputs + D, stores, name, "double t, const double *q, const double *qd, "
        "const double *p, const double *u, const double *Q, const double *g, double *qdd",
        "q̈ of the robot by the articulated-body algorithm in joint frames (lagrgen.lean3d), "
        "traced with its\n * numbers folded: {flops} flops ({per_joint} per joint). "
        f"Nodes:\n{legend}\n", len(parent), traced, calls=("lg_lean_pivots",))


def _function(tape, values, stores, name, parameters, comment, joints, loads, calls=()):
    """The `Traced` C function `int name(parameters)` computing the tape's `values` (the nodes
    they need as `const double` temporaries), then the `stores`; `comment` (with {flops} and
    {per_joint}) heads it, and `calls` names the functions it calls."""
    nodes = tape.needed(values)
    flops = tape.flops(nodes)
    names = [part.replace("*", " ").split()[-1] for part in parameters.split(",")]
    head = comment.format(flops=flops, per_joint=f"{flops / max(joints, 1):.0f}")
    body = ("    " + ", ".join(f"(void){x}" for x in names[:-1]) + ";\n"
            + "\n".join(Printer(tape).statements(nodes) + stores) + "\n    return 0;\n")
    return Traced(name, parameters, head, body, flops, loads, calls)


def world_records(tape, joints, parent, coordinate, Q, g, inputs=None):
    """Each node's record (lagrgen.tree3d.FIELDS: s, Y, base, Q) in the fixed frame, on the tape:
    the frames composed down the tree, R_k = R_λ·P_k·J(θ), o_k = o_λ + R_λ·(o + P·a·θ for a
    prismatic joint); s = multiplier·[d; o_k × d] (revolute) or multiplier·[0; d], d = R_λ·P_k·a;
    Y the body's inertia at the fixed origin (lagrgen.frames.world_inertia)."""
    t = tape
    inputs = inputs or {}
    q = inputs.get("q", lambda i: t.leaf(f"q[{i}]"))
    p = inputs.get("p", lambda j: t.leaf(f"p[{j}]"))
    identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    frames, records = [], []
    for k in range(len(parent)):
        Rp, op = frames[parent[k]] if parent[k] >= 0 else (identity, [0.0] * 3)
        P = joints.placement[k]
        axis = [float(a) for a in joints.axis[k]]
        mult, offset = (float(x) for x in joints.motion[k])
        theta = t.add(t.mul(mult, q(coordinate[k])), offset)
        PM = [[float(P[3 * i + j]) for j in range(3)] for i in range(3)]
        RP = [[t.dot(Rp[i], (PM[0][j], PM[1][j], PM[2][j])) for j in range(3)] for i in range(3)]
        d = [t.dot(row, axis) for row in RP]
        o = [t.add(op[i], t.dot(Rp[i], [float(x) for x in P[9:]])) for i in range(3)]
        if joints.prismatic[k]:
            R = RP
            o = [t.add(o[i], t.mul(d[i], theta)) for i in range(3)]
            s = [0.0] * 3 + d
        else:
            J = joint_rotation(t, axis, t.sin(theta), t.cos(theta))
            R = [[t.dot(RP[i], (J[0][j], J[1][j], J[2][j])) for j in range(3)] for i in range(3)]
            s = d + Spatial(t).cross(o, d)
        frames.append((R, o))
        body = [p(j) if j >= 0 else float(x)
                for x, j in zip(joints.inertia[k], joints.inertia_parameter[k])]
        base = [0.0] * 3 + [t.neg(x) for x in g] if parent[k] < 0 else [0.0] * 6
        records.append([t.mul(mult, x) for x in s] + _world_inertia(t, R, o, body) + base
                       + [Q(coordinate[k])])
    return records


def _world_inertia(t, R, o, body):
    """(m, h_w, Ī: xx, xy, yy, xz, yz, zz) of `body` (m, h, I_O about its frame) at the fixed
    origin: h_w = m·o + R·h, Ī = R·I_O·Rᵀ + m·((o·o)·1 − o·oᵀ) + 2·(o·h')·1 − o·h'ᵀ − h'·oᵀ."""
    m, h = body[0], body[1:4]
    xx, xy, yy, xz, yz, zz = body[4:]
    I = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
    hr = [t.dot(R[i], h) for i in range(3)]
    RI = [[t.dot(R[i], (I[0][j], I[1][j], I[2][j])) for j in range(3)] for i in range(3)]
    oo, oh = t.dot(o, o), t.mul(2.0, t.dot(o, hr))
    diagonal = t.add(t.mul(m, oo), oh)
    out = [m] + [t.add(t.mul(m, o[i]), hr[i]) for i in range(3)]
    for i, j in ((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)):
        x = t.sub(t.dot(RI[i], R[j]), t.add(t.mul(t.mul(m, o[i]), o[j]),
                                            t.add(t.mul(o[i], hr[j]), t.mul(hr[i], o[j]))))
        out.append(t.add(x, diagonal) if i == j else x)
    return out


def trace_nodes(joints, parent, coordinate, notes, loads, name="lg_tree_nodes"):
    """The kernel tree_nodes' function `int name(t, q, qd, a, p, u, nodes)` traced for the robot
    (its loads traced too), or None when a load is not traceable."""
    from .trace import NotTraceable, from_symengine
    tape = Tape()
    try:
        memo = {}
        Q = [from_symengine(tape, x, memo) for x in loads[0]]
        g = [from_symengine(tape, x, memo) for x in loads[1]]
    except NotTraceable:
        return None
    records = world_records(tape, joints, parent, coordinate, Q.__getitem__, g)
    printer = Printer(tape)
    width = len(records[0])
    stores = []
    for k, record in enumerate(records):
        stores.append(f"    /* {notes[k]} */")
        stores += [f"    nodes[{k * width + i}] = {printer.ref(x)};" for i, x in enumerate(record)]
    return _function(
        tape, [x for record in records for x in record], stores, name,
        "double t, const double *q, const double *qd, const double *a, const double *p, "
        "const double *u, double *nodes",
        "Each node's record (lagrgen.tree3d.FIELDS) in the fixed frame, traced for the robot "
        "with its numbers\n * folded (lagrgen.lean3d.world_records): {flops} flops "
        "({per_joint} per joint).", len(parent), True)
