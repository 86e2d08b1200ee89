"""Kernels: the symbolic quantities the generated code computes, declared once, with common
subexpressions eliminated.

Every kernel is a function of (t, q, q̇, a, p, u) with a = q̈ where it matters; its outputs are
row-major arrays. The model functions of `lagrgen.functions` (mass matrix, rhs, Jacobian, ...) are
assembled from these by the backends:

    mf           M(q, t) and F(q, q̇, t, u) together (one CSE over both)
    jacobian_b   B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇] for a given a (= q̈); ∂ẏ/∂y's bottom half is M⁻¹·B.
                 At a = 0 it is [∂F/∂q | ∂F/∂q̇], the linearization's −K and −C.
    dF_du        ∂F/∂u, the linearization's input matrix
    outputs      the model's outputs: the user's, then T, V, T + V, input power, R
    constraints  A (m×n) and γ (m) of A·q̈ = γ                       } only for a model with
    constraint_residuals  Φ, then A·q̇ + b                            } constraints (m > 0);
    constraint_residual_jacobian  ∂[Φ; A·q̇ + b]/∂[q, q̇]              }
    constraint_jacobian   ∂(Aᵀλ)/∂q and [∂γ/∂q − ∂(A·a)/∂q | ∂γ/∂q̇]  } a = [q̈, λ] there
    parameter_b  P = ∂F/∂p − ∂(M·a)/∂p for a given a (= q̈); ∂ẏ/∂p's bottom half is M⁻¹·P
    constraint_parameter_jacobian  ∂(Aᵀλ)/∂p and ∂γ/∂p − ∂(A·a)/∂p (m > 0; a = [q̈, λ])
    motion_tape  M, F (and A, γ) by the programs of mf (and constraints), with the tape c of
                 their forward-mode coefficients (lagrgen.tangents)
    motion_tangent  along one direction (δq, δq̇, δp), from the tape: δR = δF − δM·a + δAᵀ·λ and
                 δG = δγ − δA·a with a = [q̈, λ] held fixed; [M −Aᵀ; A 0]·[δq̈; δλ] = [δR; δG]

The recursive formulation of a kinematic tree (`lagrgen.tree`) computes what mf, jacobian_b,
parameter_b and the motion kernels give from the terms of each node, which generic recursions over
the tree combine (`model_kernels`, `TREE_REPLACES`):

    tree_nodes   each node's record (lagrgen.tree.NODE_FIELDS), in node order
    tree_slopes  their derivatives by the node's own q_j, q̇_j at a given a (SLOPE_FIELDS), and
                 the nonzero entries of ∂Q/∂q and ∂Q/∂q̇
    dF_du        ∂Q/∂u (the particles' terms do not depend on u)
    tree_parameters  the nonzero derivatives of the node records and of Q by the parameters
"""
from dataclasses import dataclass, field

import symengine as se

from . import hessians, nonsmooth, tree
from .caching import once_per
from .functions import Output
from .tangents import linearize

#: The arguments of every kernel, in order (C: `double t, const double *q, ...`).
KERNEL_ARGUMENTS = ("t", "q", "qd", "a", "p", "u")


@dataclass(frozen=True)
class KernelSpec:
    """A kernel's declaration: name, formula, outputs (with shapes) and how to form them."""
    name: str
    formula: str
    outputs: tuple       # of functions.Output
    expressions: object  # Equations -> {output name: [expression, row-major]}
    when: object = None  # Equations -> bool: whether the model has this kernel (None: always)
    notes: object = None  # Equations -> {(output name, index): comment} for the generated code
    build: object = None  # Equations -> Kernel, for a kernel not CSE'd from `expressions`
    arguments: tuple = KERNEL_ARGUMENTS   # its arguments: `t` a double, the others arrays
    lanes: tuple = ()    # arrays holding one entry per direction: in C the kernel runs several
                         # directions at once, entry i of lane b at [i·LG_LANES + b]
    python: bool = True  # formed for the Python backend too (False: only a compiled unit's C
                         # calls it, and the Python backend computes its function otherwise)


@dataclass
class Kernel:
    """A kernel after CSE: temporaries in dependency order, then the reduced outputs."""
    spec: KernelSpec
    temporaries: list    # [(symbol, expression)]
    outputs: dict        # name -> [expression], row-major
    notes: dict = field(default_factory=dict)   # (output name, index) -> a comment before it

    @property
    def name(self):
        return self.spec.name


def has_links(eq):
    """True if the equations are those of a three-dimensional tree with links
    (`lagrgen.links`)."""
    found = tree.analysed(eq)[0] if tree.tree3d.is_spatial(eq.spec) else None
    return found is not None and bool(found.links)


def link_frames(spatial):
    """The link_frames kernel's outputs of a `SpatialTree`: the links' poses, the nodes' twists."""
    return {"poses": [x for pose in spatial.link_poses for x in pose],
            "twists": [x for twist in spatial.link_tree.twists for x in twist]}


#: A link's point in its own frame, the argument `point` of its kernels (`link_chains`).
LINK_POINT = tuple(se.Symbol(f"point[{r}]") for r in range(3))
#: A tree's links have kernels of their own (`link_chains`) while the nodes above its links number
#: at most this many in all (Σ over the links of their depth: a chain of n joints has about n²/2,
#: so a long chain's links keep to the walk over the tree's twists, `link_frames`). Their CSE
#: grows with that sum: solo12 (138) adds about 0.5 s to its links unit, a chain of 27 joints (378)
#: would add 2.6 s.
LINK_CHAIN_MAX_DEPTHS = 200
LINK_POSE = KernelSpec("link_pose", "a link's pose: the world position x = o + R·point of a point "
                       "fixed in it, then its rotation R (row-major)",
                       (Output("out", ("12",)),), None, arguments=("q", "p", "point"))
LINK_JACOBIAN = KernelSpec("link_jacobian", "a link's frame Jacobian at a point fixed in it: "
                           "[ẋ; ω] = J·q̇, the column of node i's coordinate [v_i + ω_i × x; ω_i] "
                           "from its twist [ω_i; v_i] for each node i at or above the link",
                           (Output("out", ("6", "n")),), None, arguments=("q", "p", "point"))


def link_chain(spatial, k, n):
    """({"out": pose}, {"out": J}) of link k of a `SpatialTree` with n model coordinates: its
    x = o + R·point and R, and its frame Jacobian (6×n, row-major) summed over the nodes at and
    above it, each node's twist [ω; v] giving [v + ω × x; ω] in its coordinate's column."""
    pose, walked = spatial.link_poses[k], spatial.link_tree
    R, o = pose[:9], pose[9:]
    x = [o[r] + sum(R[3 * r + c] * LINK_POINT[c] for c in range(3)) for r in range(3)]
    J = [[se.Integer(0)] * n for _ in range(6)]
    i = spatial.links[k][1]
    while i >= 0:
        w, v, c = walked.twists[i][:3], walked.twists[i][3:], walked.coordinate[i]
        cross = [w[1] * x[2] - w[2] * x[1], w[2] * x[0] - w[0] * x[2], w[0] * x[1] - w[1] * x[0]]
        for r in range(3):
            J[r][c] += v[r] + cross[r]
            J[3 + r][c] += w[r]
        i = walked.parent[i]
    return {"out": x + list(R)}, {"out": flatten(J)}


def link_depths(spatial):
    """Σ over a tree's links of the nodes at and above each (`LINK_CHAIN_MAX_DEPTHS`)."""
    parent, total = spatial.link_tree.parent, 0
    for _, i in spatial.links:
        while i >= 0:
            total, i = total + 1, parent[i]
    return total


@once_per
def link_chains(eq):
    """[(pose kernel, Jacobian kernel)] of each link of the equations' tree (`link_chain`, one
    CSE over both, each printing only the temporaries it needs: only the link's own chain is
    computed), or [] for a tree whose links are too many or too deep (`LINK_CHAIN_MAX_DEPTHS`),
    and for a model without links."""
    if not has_links(eq):
        return []
    spatial = tree.analyse(eq)
    if link_depths(spatial) > LINK_CHAIN_MAX_DEPTHS:
        return []
    chains = []
    for k in range(len(spatial.links)):
        pose, jacobian = link_chain(spatial, k, eq.n)
        both = cse_kernel(LINK_JACOBIAN, {"pose": pose["out"], "J": jacobian["out"]})
        chains.append((Kernel(LINK_POSE, both.temporaries, {"out": both.outputs["pose"]}),
                       Kernel(LINK_JACOBIAN, both.temporaries, {"out": both.outputs["J"]})))
    return chains


def flatten(matrix):
    """Row-major list of the entries of a list of lists."""
    return [e for row in matrix for e in row]


def _parameter_b(eq):
    return {"P": [eq.dF_dp[i][j] - eq.dMa_dp[i][j] for i in range(eq.n)
                  for j in range(len(eq.p))]}


def _split_outputs(outputs):
    return {"out": list(outputs[:-2]), "power": list(outputs[-2:])}


def _jacobian_b(eq):
    B = []
    for i in range(eq.n):
        B.extend(eq.dF_dq[i][j] - eq.dMa_dq[i][j] for j in range(eq.n))
        B.extend(eq.dF_dqd[i])
    return {"B": B}


#: The seeds of the directional derivatives: each input's direction (an array argument).
def _seeds(eq):
    return {**{q: se.Symbol(f"dq[{i}]") for i, q in enumerate(eq.q)},
            **{v: se.Symbol(f"dqd[{i}]") for i, v in enumerate(eq.qd)},
            **{p: se.Symbol(f"dp[{j}]") for j, p in enumerate(eq.p)}}


@once_per
def motion_program(eq):
    """(temporaries, {name: [expression]}) of M and F (and A, γ for a constrained model): the very
    programs of the kernels mf (and constraints, its temporaries renumbered after mf's), so that
    the values equal those of the rhs to the last bit."""
    mf = kernel(eq, "mf")
    temporaries, outputs = list(mf.temporaries), dict(mf.outputs)
    if eq.m:
        con = kernel(eq, "constraints")
        start = 1 + max((int(str(x)[1:]) for x, _ in temporaries), default=-1)
        rename = {x: se.Symbol(f"x{start + i}") for i, (x, _) in enumerate(con.temporaries)}
        temporaries += [(rename[x], e.xreplace(rename)) for x, e in con.temporaries]
        outputs.update({key: [e.xreplace(rename) for e in exprs]
                        for key, exprs in con.outputs.items()})
    return temporaries, outputs


@once_per
def motion_linearized(eq):
    """The forward-mode program (`lagrgen.tangents.Linearized`) of `motion_program`."""
    return linearize(*motion_program(eq), _seeds(eq))


#: The arguments of a kernel of weighted sums: the kernel arguments and the weights mu.
WEIGHTED_ARGUMENTS = KERNEL_ARGUMENTS + ("mu",)


def _residual_hessian(eq):
    return {"H": hessians.full_matrix(hessians.residual_hessian(eq), hessians.point_size(eq))}


def _motion_tape(eq):
    lin, values = motion_linearized(eq), motion_program(eq)[1]
    outputs = {key: values.get(key, []) for key in ("M", "F", "A", "gamma")}
    outputs["c"] = list(lin.tape)
    return Kernel(KERNELS_BY_NAME["motion_tape"], lin.tape_temporaries, outputs)


def _motion_tangent(eq):
    lin = motion_linearized(eq)
    n, m = eq.n, eq.m
    d = lin.tangents
    a = [se.Symbol(f"a[{i}]") for i in range(n + m)]
    dR = []
    for i in range(n):
        r = d["F"][i] - sum((a[j] * d["M"][i * n + j] for j in range(n)), se.Integer(0))
        r += sum((a[n + k] * d["A"][k * n + i] for k in range(m)), se.Integer(0))
        dR.append(r)
    dG = [d["gamma"][k] - sum((a[j] * d["A"][k * n + j] for j in range(n)), se.Integer(0))
          for k in range(m)]
    return Kernel(KERNELS_BY_NAME["motion_tangent"], list(lin.temporaries),
                  {"dR": dR, "dG": dG})


KERNELS = (
    KernelSpec("mf", "M (n×n) and F (n), sharing their common subexpressions",
               (Output("M", ("n", "n")), Output("F", ("n",))),
               lambda eq: {"M": flatten(eq.M), "F": list(eq.F)}),
    KernelSpec("jacobian_b", "B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇], n×2n, for a given a = q̈",
               (Output("B", ("n", "2n")),), _jacobian_b),
    KernelSpec("dF_du", "∂F/∂u, n×n_inputs", (Output("dF_du", ("n", "n_inputs")),),
               lambda eq: {"dF_du": flatten(eq.dF_du)}),
    KernelSpec("outputs", "the user's outputs, then T, V, T + V; and Σ Q_j·q̇_j, R",
               (Output("out", ("n_outputs",)), Output("power", ("n_power",))),
               lambda eq: _split_outputs(eq.outputs)),
    KernelSpec("constraints", "A (m×n) and γ (m) of the constraints A·q̈ = γ (Baumgarte-stabilized)",
               (Output("A", ("n_constraints", "n")), Output("gamma", ("n_constraints",))),
               lambda eq: {"A": flatten(eq.A), "gamma": list(eq.gamma)}, lambda eq: eq.m > 0),
    KernelSpec("constraint_residuals", "Φ (n_holonomic), then A·q̇ + b (m)",
               (Output("residuals", ("n_residuals",)),),
               lambda eq: {"residuals": list(eq.residuals)}, lambda eq: eq.m > 0),
    KernelSpec("constraint_residual_jacobian", "∂[Φ; c]/∂[q, q̇] (n_residuals×2n)",
               (Output("dr_dy", ("n_residuals", "2n")),),
               lambda eq: {"dr_dy": flatten(eq.residual_jacobian)}, lambda eq: eq.m > 0),
    KernelSpec("constraint_jacobian",
               "H = ∂(Aᵀλ)/∂q (n×n) and G = [∂γ/∂q − ∂(A·a)/∂q | ∂γ/∂q̇] (m×2n), a = [q̈, λ]",
               (Output("H", ("n", "n")), Output("G", ("n_constraints", "2n"))),
               lambda eq: {"H": flatten(eq.dAl_dq), "G": flatten(eq.G)}, lambda eq: eq.m > 0),
    KernelSpec("parameter_b", "P = ∂F/∂p − ∂(M·a)/∂p, n×n_params, for a given a = q̈",
               (Output("P", ("n", "n_params")),), _parameter_b),
    KernelSpec("constraint_parameter_jacobian",
               "Hp = ∂(Aᵀλ)/∂p (n×n_params) and Gp = ∂γ/∂p − ∂(A·a)/∂p (m×n_params), a = [q̈, λ]",
               (Output("Hp", ("n", "n_params")), Output("Gp", ("n_constraints", "n_params"))),
               lambda eq: {"Hp": flatten(eq.dAl_dp), "Gp": flatten(eq.G_p)}, lambda eq: eq.m > 0),
    KernelSpec("body_poses", "each body's pose (R, p) in the fixed frame (a spatial tree only)",
               (Output("poses", ("n", "12")),), lambda eq: {"poses": []},
               when=lambda eq: False),
    KernelSpec("link_frames", "each link's frame (R row-major, then its origin p) in the fixed "
               "frame, and each node's twist s = [ω; v] per unit rate (a spatial tree's links)",
               (Output("poses", ("n_links", "12")), Output("twists", ("n_nodes", "6"))),
               lambda eq: link_frames(tree.analyse(eq)), when=lambda eq: has_links(eq)),
    KernelSpec("events", "the event functions g_k(t, q, q̇, u), whose roots the solvers locate",
               (Output("g", ("n_events",)),), lambda eq: {"g": list(eq.events)},
               when=lambda eq: bool(eq.events)),
    KernelSpec("nonsmooth", "the impacts' and frictions' terms (layout in lagrgen.nonsmooth)",
               (Output("terms", ("n_hybrid",)),), lambda eq: {"terms": nonsmooth.terms(eq)},
               when=lambda eq: bool(eq.spec.nonsmooth)),
    KernelSpec("residual_hessian", "H = ∇²_z(Σ mu_i·r_i) of the implicit form's residual "
               "r = [M·q̈ − F − Aᵀλ; A·q̈ − γ], z = [q, q̇, q̈, λ, u] (symmetric, full)",
               (Output("H", ("n_point", "n_point")),), _residual_hessian,
               arguments=WEIGHTED_ARGUMENTS, python=False),
    KernelSpec("motion_tape", "M, F (and A, γ) as mf (and constraints) compute them, and the tape c "
               "of their forward-mode coefficients (lagrgen.tangents)",
               (Output("M", ("n", "n")), Output("F", ("n",)),
                Output("A", ("n_constraints", "n")), Output("gamma", ("n_constraints",)),
                Output("c", ("n_tape",))), None, build=_motion_tape),
    KernelSpec("motion_tangent", "along one direction (dq, dqd, dp), from the tape c: "
               "dR = δF − δM·a + δAᵀ·λ and dG = δγ − δA·a, a = [q̈, λ] held fixed",
               (Output("dR", ("n",)), Output("dG", ("n_constraints",))), None,
               build=_motion_tangent, arguments=("c", "a", "dq", "dqd", "dp"),
               lanes=("dq", "dqd", "dp", "dR", "dG")),
)
KERNELS_BY_NAME = {k.name: k for k in KERNELS}


def _signed(expr, memo):
    """`expr` with every sum inside it written as ±S where S is the one of S, −S whose term with the
    smallest hash has a positive coefficient (the same value), so that CSE sees X and −X as one.
    Iterative (an explicit stack, children before parents): an expression nested deeper than
    Python's recursion limit (the energies of a long chain) is walked like any other."""
    stack = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if node in memo:
            continue
        if not node.args or isinstance(node, se.Number):
            memo[node] = node
            continue
        if not ready:
            stack.append((node, True))
            stack.extend((a, False) for a in node.args if a not in memo)
            continue
        args = [memo[a] for a in node.args]
        memo[node] = _signed_sum(args) if isinstance(node, se.Add) else _rebuilt(node, args)
    return memo[expr]


def _signed_sum(args):
    """The sum of the (already signed) terms `args`, as ±S with S's leading term positive."""
    lead = min(args, key=lambda a: hash(_strip_number(a)))
    lead_negative = isinstance(lead, se.Number) and lead.is_negative or (
        isinstance(lead, se.Mul) and isinstance(lead.args[0], se.Number)
        and lead.args[0].is_negative)
    return -se.Add(*(-a for a in args)) if lead_negative else se.Add(*args)


def _rebuilt(expr, args):
    """`expr` with its arguments replaced by `args` (itself when none changed)."""
    if all(a is b for a, b in zip(args, expr.args)):
        return expr
    try:
        return expr.func(*args)
    except (AttributeError, TypeError):   # relations, Piecewise: left as they are
        return expr


def _strip_number(term):
    if isinstance(term, se.Number):
        return se.Integer(1)
    if isinstance(term, se.Mul) and isinstance(term.args[0], se.Number):
        return se.Mul(*term.args[1:])
    return term


def cse_kernel(spec, outputs, notes=None):
    """The kernel `spec` computing `outputs` ({name: [expr]}) after one CSE over all of them (sums
    first brought to one sign, see `_signed`); `notes` label output entries for the reader."""
    memo = {}
    outputs = {key: [_signed(e, memo) for e in exprs] for key, exprs in outputs.items()}
    everything = [e for exprs in outputs.values() for e in exprs]
    replacements, reduced = se.cse(everything) if everything else ([], [])
    result, pos = {}, 0
    for key, exprs in outputs.items():
        result[key] = list(reduced[pos:pos + len(exprs)])
        pos += len(exprs)
    return Kernel(spec, list(replacements), result, dict(notes or {}))


def _tree_nodes(eq):
    return {"nodes": tree.analyse(eq).node_records()}


def _tree_slopes(eq):
    """The planar tree's slopes (a spatial tree needs none: see lagrgen.tree3d) and ∂Q/∂y."""
    t = tree.analyse(eq)
    (_, dq), (_, dqd), _ = tree_gradients(eq)
    slopes = tree.slope_records(t, eq) if t.kind == "planar" else []
    return {"slopes": slopes, "dQ": dq, "dQd": dqd}


def _node_notes(output, slopes=False):
    def notes(eq):
        t = tree.analyse(eq)
        if slopes and t.kind != "planar":
            return {}
        width = tree.record_width(tree.SLOPE_FIELDS, t.D) if slopes else t.width
        return {(output, k * width): note for k, note in enumerate(t.notes)}
    return notes


@once_per
def tree_q_hessian(eq):
    """The nonzero lower entries [(row, col, expr)] of ∇²_z(Σ mu_i·Q_i) of a spatial tree's
    generalized forces Q (`lagrgen.hessians.q_hessian`), once per Equations."""
    return hessians.q_hessian(tree.analyse(eq).Q, eq)


def _is_spatial_tree(eq):
    """True for a three-dimensional tree whose residual's second derivatives come from its
    recursion (not one with a free base: its recursion runs in the base's chart)."""
    t = tree.analyse(eq)
    return t.kind == "spatial" and not getattr(t, "free", None)


@once_per
def tree_gradients(eq):
    """`lagrgen.tree.gradients` of the equations' tree, once per Equations."""
    return tree.gradients(tree.analyse(eq), eq)


def joint_tables(eq):
    """The `lagrgen.tree3d.Joints` of the equations' tree, or None: an articulation whose joints
    are numbers has its node records computed from them (in C by tree3d.c.in's lg_tree_nodes, in
    Python by `lagrgen.runtime.tree3d`), with the kernel tree_loads for Q and g; any other tree
    by the kernel tree_nodes."""
    return getattr(tree.analyse(eq), "joints", None)


def _tree_loads(eq):
    t = tree.analyse(eq)
    return {"Q": list(t.Q), "g": list(t.gravity)}


TREE_KERNELS = (
    KernelSpec("tree_nodes", "each node's terms of the recursion over the kinematic tree "
               "(lagrgen.tree.NODE_FIELDS), in node order",
               (Output("nodes", ("n", "node_width")),), _tree_nodes,
               notes=_node_notes("nodes"), when=lambda eq: joint_tables(eq) is None),
    KernelSpec("tree_loads", "the generalized forces Q (coordinate order) and the gravity g of "
               "an articulation whose node records follow from its joints' numbers",
               (Output("Q", ("n",)), Output("g", ("3",))), _tree_loads,
               when=lambda eq: joint_tables(eq) is not None),
    KernelSpec("tree_slopes", "the node terms' derivatives by their own q_k, q̇_k at a given "
               "a = q̈ (lagrgen.tree.SLOPE_FIELDS), and the nonzero entries of ∂Q/∂q, ∂Q/∂q̇",
               (Output("slopes", ("n", "slope_width")), Output("dQ", ("nnz_q",)),
                Output("dQd", ("nnz_qd",))), _tree_slopes,
               notes=_node_notes("slopes", slopes=True)),
    KernelSpec("dF_du", "∂F/∂u = ∂Q/∂u, n×n_inputs", (Output("dF_du", ("n", "n_inputs")),),
               lambda eq: {"dF_du": flatten(tree_gradients(eq)[2])}),
    KernelSpec("tree_poses", "each node's frame (R row-major, then its origin p) in the fixed frame "
               "(a spatial tree: the frame its body's inertial parameters are about)",
               (Output("poses", ("n", "12")),),
               lambda eq: {"poses": [x for pose in tree.analyse(eq).poses for x in pose]},
               when=lambda eq: tree.analyse(eq).kind == "spatial"
               and bool(tree.tree3d.inertial_parameters(eq.spec))),
    KernelSpec("tree_outputs", "the user's outputs, then T, V, T + V; and Σ Q_j·q̇_j, R, without "
               "the energies of an articulation's bodies (lg_outputs adds those from the node "
               "records)", (Output("out", ("n_outputs",)), Output("power", ("n_power",))),
               lambda eq: _split_outputs(eq.outputs_of(
                   eq.collected.energies_beside_articulations))),
    KernelSpec("tree_parameters", "the nonzero derivatives of the node records and of Q by the "
               "parameters (lagrgen.tree.parameter_gradients)",
               (Output("dnode", ("nnz_p",)), Output("dQp", ("nnz_qp",))),
               lambda eq: {"dnode": tree_parameter_gradients(eq)[0][1],
                           "dQp": tree_parameter_gradients(eq)[1][1]}),
    KernelSpec("tree_q_hessian", "the nonzero lower entries of ∇²_z(Σ mu_i·Q_i) of the generalized "
               "forces Q (a spatial tree: its inertia forces' part comes from the recursion)",
               (Output("HQ", ("nnz_qh",)),),
               lambda eq: {"HQ": [e for _, _, e in tree_q_hessian(eq)]},
               when=_is_spatial_tree, arguments=WEIGHTED_ARGUMENTS),
    KernelSpec("tree_residual_hessian", "H = ∇²_z(Σ mu_i·r_i) as the dense kernel residual_hessian "
               "(a planar tree or a free base: no recursion of second derivatives)",
               (Output("H", ("n_point", "n_point")),), _residual_hessian,
               when=lambda eq: not _is_spatial_tree(eq), arguments=WEIGHTED_ARGUMENTS,
               python=False),
)
#: The dense kernels the recursive formulation keeps (none of them needs M or F).
_KEPT = ("events", "nonsmooth", "link_frames")
#: The kernels of each formulation, in the order they are generated.
FORMULATION_KERNELS = {"dense": KERNELS,
                       "recursive": TREE_KERNELS + tuple(k for k in KERNELS if k.name in _KEPT)}
#: What the recursive formulation computes a dense kernel from: `lagrgen/codegen/templates/
#: tree.c.in` (and `lagrgen.runtime.tree`) define lg_mf, lg_jacobian_b, lg_parameter_b and the
#: directional derivatives by recursions over these kernels' node terms; a dense kernel not listed
#: is kept as it is (the constraints' are absent: a tree has none).
TREE_REPLACES = {"mf": ("tree_nodes",),
                 "jacobian_b": ("tree_nodes", "tree_slopes"),
                 "parameter_b": ("tree_nodes", "tree_parameters"),
                 "motion_tape": ("tree_nodes", "tree_slopes", "tree_parameters"),
                 "motion_tangent": (),
                 "body_poses": ("tree_poses",),
                 "residual_hessian": ("tree_nodes", "tree_q_hessian", "tree_residual_hessian"),
                 "outputs": ("tree_nodes", "tree_outputs")}


@once_per
def tree_parameter_gradients(eq):
    """`lagrgen.tree.parameter_gradients` of the equations' tree, once per Equations."""
    return tree.parameter_gradients(tree.analyse(eq), eq)


@once_per
def _kernels_of(eq):
    return {}


def kernel(eq, name, formulation="dense"):
    """The kernel `name` of the `formulation`'s kernels for the equations `eq` (computed once per
    Equations)."""
    spec = next(k for k in FORMULATION_KERNELS[formulation] if k.name == name)
    done = _kernels_of(eq)
    if spec not in done:
        done[spec] = spec.build(eq) if spec.build else \
            cse_kernel(spec, spec.expressions(eq), spec.notes(eq) if spec.notes else None)
    return done[spec]


def kernel_names(names, formulation="dense"):
    """The kernels of `formulation` that compute what the dense kernels `names` give (the node
    records: tree_nodes, or tree_loads for an articulation's joints, whichever the model has)."""
    if formulation == "dense":
        return set(names)
    out = {r for k in names for r in TREE_REPLACES.get(k, (k,))}
    return out | {"tree_loads"} if "tree_nodes" in out else out


def model_kernels(eq, formulation="dense", names=None, python=False):
    """The kernels a build of `eq` in `formulation` ("dense" or "recursive") generates, in order:
    those the model has, and only those computing the dense kernels `names` when given (the
    others are not formed); with `python`, only those the Python backend forms."""
    wanted = None if names is None else kernel_names(names, formulation)
    return [kernel(eq, k.name, formulation) for k in FORMULATION_KERNELS[formulation]
            if (wanted is None or k.name in wanted) and (k.python or not python)
            and (k.when is None or k.when(eq))]


def all_kernels(eq, names=None):
    """The dense formulation's kernels (`model_kernels`)."""
    return model_kernels(eq, "dense", names)
