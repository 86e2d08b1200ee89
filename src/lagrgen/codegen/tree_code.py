"""The recursive formulation's code: the generic recursions of `templates/tree.c.in` (a planar
tree, `lagrgen.tree`) or `templates/tree3d.c.in` (a three-dimensional one, `lagrgen.tree3d`)
filled with one model's kinematic tree (its node tables, record layout and sparsity of ∂Q/∂y),
and the same tables for the Python backend (`lagrgen.runtime.tree`, `lagrgen.runtime.tree3d`)."""
import re
from dataclasses import replace
from pathlib import Path
from string import Template

from .. import tree as trees
from ..kernels import tree_gradients, tree_parameter_gradients, tree_q_hessian
from ..lean3d import (LEAN_MAX_FLOPS, LEAN_MAX_FLOPS_PER_JOINT, LEAN_MAX_JOINTS,
                      LEAN_MAX_NODE_FLOPS_PER_JOINT, trace_nodes, trace_qdd)

#: The template of each kind of tree.
TEMPLATES = {"planar": "tree.c.in", "spatial": "tree3d.c.in"}
#: The transformation of a free base's recursion (in its chart) to the model's coordinates.
FREE_BASE_TEMPLATE = Path(__file__).resolve().parent / "templates" / "free_base.c.in"


def template_name(equations):
    """The C template of the equations' tree."""
    return TEMPLATES[trees.analyse(equations).kind]


def layout(equations, parameters=True):
    """The tables of the equations' tree: {"kind", "node_width", "node_fields", "coordinate",
    "parent", "end", "dq", "dqd", "dnode", "dnode_start", "dQp", "inertial_column"}, and for a
    planar tree "D", "slope_width", "slope_fields" (plain Python values). The entries of ∂Q/∂y
    (dq, dqd) are pairs of nodes for a planar tree, of coordinates for a spatial one (whose
    coordinates may have several nodes). Without `parameters` the tables of the derivatives by
    the parameters are left empty (a unit without the kernel tree_parameters)."""
    tree = trees.analyse(equations)
    (dq, _), (dqd, _), _ = tree_gradients(equations)
    (dnode, _), (dQp, _) = tree_parameter_gradients(equations) if parameters else (([], []),
                                                                                   ([], []))
    n_params = len(equations.p)
    start = [0] * (n_params + 1)
    for _, _, j in dnode:
        start[j + 1] += 1
    for j in range(n_params):
        start[j + 1] += start[j]
    pairs = _nodes if tree.kind == "planar" else (lambda ij, _: [list(p) for p in ij])
    out = {"kind": tree.kind, "node_width": tree.width,
           "node_fields": trees.field_offsets(tree.fields, None),
           "coordinate": list(tree.coordinate), "parent": list(tree.parent),
           "end": list(tree.end), "dq": pairs(dq, tree), "dqd": pairs(dqd, tree),
           "dnode": [[k, o] for k, o, _ in dnode], "dnode_start": start,
           "dQp": [list(ij) for ij in dQp]}
    columns, start = [], 0
    bodies = trees.tree3d.inertial_symbols(equations.spec) or [None] * len(tree.coordinate)
    if tree.kind == "spatial" and tree.free:          # segment 0's body is on the sixth node
        bodies = [None] * 5 + list(bodies)
        out["free"] = {"radial": tree.free.radial}
    for values in bodies:
        columns.append(start if values else -1)
        start += 10 if values else 0
    out["inertial_column"] = columns
    if tree.kind == "spatial" and not getattr(tree, "free", None):
        out["qh"] = [[r, c] for r, c, _ in tree_q_hessian(equations)]
    out["energies"] = bool(getattr(tree, "articulated", False) or getattr(tree, "free", None))
    joints = getattr(tree, "joints", None)
    if joints is not None:
        out["joints"] = joints.table()
    if tree.kind == "planar":
        out.update(D=tree.D, slope_width=trees.record_width(trees.SLOPE_FIELDS, tree.D),
                   slope_fields=trees.field_offsets(trees.SLOPE_FIELDS, tree.D))
    return out


def structure(equations):
    """What the sparsity of a spatial tree's residual derivatives follows from (`ModelInfo.
    tree_structure`): the nodes' coordinate and parent, the nonzero entries of ∂Q/∂q, ∂Q/∂q̇,
    ∂Q/∂u (coordinate, variable) and of ∇²(Σ mu_i·Q_i) (`qh`, point indices); {} for a planar
    tree and a free base (their residual's second derivatives are symbolic)."""
    tree = trees.analyse(equations)
    if tree.kind != "spatial" or getattr(tree, "free", None):
        return {}
    tables = layout(equations)
    du = [[i, k] for i, row in enumerate(tree_gradients(equations)[2])
          for k, e in enumerate(row) if e != 0]
    return {key: tables[key] for key in ("coordinate", "parent", "dq", "dqd", "qh")} | {"du": du}


def _nodes(pairs, tree):
    """(row, column) pairs of coordinates as pairs of nodes."""
    node = {j: k for k, j in enumerate(tree.coordinate)}
    return [[node[i], node[j]] for i, j in pairs]


def _runs(parent):
    """Per node, the first node of the run of consecutive nodes ending at it, each the parent of
    the next."""
    run = []
    for k, p in enumerate(parent):
        run.append(run[k - 1] if k > 0 and p == k - 1 else k)
    return run


def _ints(values):
    return ", ".join(str(int(v)) for v in values) if values else "0"


def _rows(rows, notes, number=repr):
    """C initializer rows `{a, b, ...},` one per node, each after its note as a comment."""
    return "\n".join(f"    /* {note} */\n    {{{', '.join(number(x) for x in row)}}},"
                      for row, note in zip(rows, notes)) or "    {0}"


def template_prototypes(template, names):
    """The prototypes of the functions `names` as the C `template` defines them (the line
    `LG_FN ... name(...)` before its body), for code in another unit that calls them."""
    found = []
    for name in names:
        match = re.search(rf"^(LG_FN [^\n(]*\b{re.escape(name)}\([^)]*\))\n\{{", template, re.M)
        if match is None:
            raise ValueError(f"the template defines no function {name}")
        found.append(match.group(1) + ";")
    return tuple(found)


def _lean(equations, tables, traced, apart, template):
    """The template's traced functions (`lagrgen.lean3d`) where the tree has them: q̈ when its
    flops per joint and in all are within LEAN_MAX_FLOPS_PER_JOINT and LEAN_MAX_FLOPS, then the
    node records when the flops left allow them. Each is appended to the list `traced`; one
    named in `apart` is only declared in the template (its definition is a unit of its own,
    `c_model.model_source`), the others are defined there."""
    none = dict(has_lean_qdd=0, lean_qdd="", lean_loads=0, has_lean_nodes=0, lean_nodes="")
    tree = trees.analyse(equations)
    joints, coordinate = getattr(tree, "joints", None), tables["coordinate"]
    if joints is None or len(coordinate) > LEAN_MAX_JOINTS or \
            len(set(coordinate)) != len(coordinate):
        return none

    def placed(function):
        function = replace(function,
                           declarations=template_prototypes(template, function.calls))
        traced.append(function)
        return function.declaration(APART) if function.name in apart else function.definition()

    loads, budget, out = (tree.Q, tree.gravity), LEAN_MAX_FLOPS, dict(none)
    qdd = trace_qdd(joints, tables["parent"], coordinate, tree.notes, loads)
    if qdd.flops <= min(budget, LEAN_MAX_FLOPS_PER_JOINT * len(coordinate)):
        budget -= qdd.flops
        out.update(has_lean_qdd=1, lean_qdd=placed(qdd), lean_loads=int(qdd.loads))
    nodes = trace_nodes(joints, tables["parent"], coordinate, tree.notes, loads)
    if nodes is not None and nodes.flops <= min(budget, LEAN_MAX_NODE_FLOPS_PER_JOINT
                                                 * len(coordinate)):
        out.update(has_lean_nodes=1, lean_nodes=placed(nodes))
    return out


#: The linkage of a traced function compiled as a unit of its own (c_model.TU_SETUP).
APART = "LG_PART_FN"


def _joint_tables(tables, notes):
    """The template's joint tables (`lagrgen.tree3d.Joints`), or placeholders when the tree has
    none."""
    joints = tables.get("joints")
    if joints is None:
        return dict(has_joints=0, has_joint_parameters=0, joint_placement="{0}",
                    joint_axis="{0}", joint_motion="{0}", joint_inertia="{0}",
                    joint_inertia_parameter="{0}")
    real = lambda x: repr(float(x))            # noqa: E731
    axis = [list(a) + [k] for a, k in zip(joints["axis"], joints["prismatic"])]
    return dict(has_joints=1,
                has_joint_parameters=int(any(j >= 0 for row in joints["inertia_parameter"]
                                             for j in row)),
                joint_placement=_rows(joints["placement"], notes, real),
                joint_axis=_rows(axis, notes, real),
                joint_motion=_rows(joints["motion"], notes, real),
                joint_inertia=_rows(joints["inertia"], notes, real),
                joint_inertia_parameter=_rows(joints["inertia_parameter"], notes, str))


def tree_c(equations, template, kernels=("tree_nodes", "tree_slopes", "tree_parameters"),
           traced=None, apart=()):
    """`template` (the text of the tree's template, `template_name`) for the equations' tree, in
    a unit that has the `kernels` (names: the parts calling tree_slopes or tree_parameters are
    compiled when they are among them); a free base's, in its chart within
    `templates/free_base.c.in`. The functions traced for the robot (`lagrgen.lean3d.Traced`)
    are appended to the list `traced`; those named in `apart` are only declared in the text."""
    tables = layout(equations, "tree_parameters" in kernels)
    traced = [] if traced is None else traced
    if "free" in tables:
        return free_base_c(equations, tables, template, kernels, traced, apart)
    return _tree_c(equations, tables, template, kernels, traced, apart)


def free_base_c(equations, tables, template, kernels, traced, apart):
    """The recursion of a free base's tree in its chart (its own n − 1 coordinates, no slopes or
    parameter derivatives of Q: those are the model's) within the transformation to the model's
    coordinates (`templates/free_base.c.in`)."""
    chart = dict(tables, dq=[], dqd=[], dQp=[])
    return Template(FREE_BASE_TEMPLATE.read_text()).substitute(
        n=len(equations.q), n_e=len(equations.q) - 1, radial=repr(float(tables["free"]["radial"])),
        nnz_q=len(tables["dq"]), nnz_qd=len(tables["dqd"]), nnz_qp=len(tables["dQp"]),
        dq_index=_ints([i for ij in tables["dq"] for i in ij]),
        dqd_index=_ints([i for ij in tables["dqd"] for i in ij]),
        dqp_index=_ints([i for ij in tables["dQp"] for i in ij]),
        has_parameters=int("tree_parameters" in kernels),
        tree=_tree_c(equations, chart, template, kernels, traced, apart))


def _tree_c(equations, tables, template, kernels, traced, apart):
    n = len(tables["coordinate"])
    first, seen = [], set()
    for c in tables["coordinate"]:
        first.append(int(c not in seen))
        seen.add(c)
    names = {"d": "DD"}
    offsets = [f"#define TREE_{names.get(name, name.upper())} {offset}"
               for name, offset in tables["node_fields"].items()]
    offsets += [f"#define TREE_{name.upper()} {offset}"
                for name, offset in tables.get("slope_fields", {}).items()]
    qh = tables.get("qh", [])
    return Template(template).substitute(
        has_slopes=int("tree_slopes" in kernels),
        has_hessian=int("tree_q_hessian" in kernels and "qh" in tables), nnz_qh=len(qh),
        qh_index=_ints([i for rc in qh for i in rc]),
        has_parameters=int("tree_parameters" in kernels),
        has_poses=int("tree_poses" in kernels),
        has_outputs=int("tree_outputs" in kernels),
        **_lean(equations, tables, traced, apart, template),
        **_joint_tables(tables, trees.analyse(equations).notes),
        has_energies=int(tables.get("energies", False)),
        inertial_columns=_ints(tables["inertial_column"]),
        tree_d=tables.get("D", 0), node_width=tables["node_width"],
        slope_width=tables.get("slope_width", 0),
        nnz_q=len(tables["dq"]), nnz_qd=len(tables["dqd"]), field_offsets="\n".join(offsets),
        coordinates=_ints(tables["coordinate"]), parents=_ints(tables["parent"]),
        node_rows=_ints(range(n)), n_nodes=n, first_nodes=_ints(first),
        runs=_ints(_runs(tables["parent"])),
        in_order=int(list(tables["coordinate"]) == list(range(n))),
        ends=_ints(tables["end"]), dq_index=_ints([i for ij in tables["dq"] for i in ij]),
        dqd_index=_ints([i for ij in tables["dqd"] for i in ij]),
        columns=_ints(tables["coordinate"] + [len(equations.q) + j
                                              for j in tables["coordinate"]]),
        nnz_p=len(tables["dnode"]), nnz_qp=len(tables["dQp"]),
        dnode_index=_ints([i for ko in tables["dnode"] for i in ko]),
        dnode_start=_ints(tables["dnode_start"]),
        dqp_index=_ints([i for ij in tables["dQp"] for i in ij]))


def link_layout(equations):
    """The tables of a three-dimensional tree's links: {"node": the node carrying each link (−1:
    fixed), "parent": each node's parent (−1: a root), "coordinate": each node's coordinate}."""
    tree = trees.analyse(equations)
    walked = tree.link_tree
    return {"node": [node for _, node in tree.links], "parent": list(walked.parent),
            "coordinate": list(walked.coordinate)}
