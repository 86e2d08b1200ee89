"""The recursive formulation's code: the generic recursions of `templates/tree.c.in` (a planar
tree, `lagrgen.tree`) or `templates/tree3d.c.in` (a three-dimensional one, `lagrgen.tree3d`)
filled with one model's kinematic tree (its node tables, record layout and sparsity of ∂Q/∂y),
and the same tables for the Python backend (`lagrgen.runtime.tree`, `lagrgen.runtime.tree3d`)."""
from string import Template

from .. import tree as trees
from ..kernels import tree_gradients, tree_parameter_gradients

#: The template of each kind of tree.
TEMPLATES = {"planar": "tree.c.in", "spatial": "tree3d.c.in"}


def template_name(equations):
    """The C template of the equations' tree."""
    return TEMPLATES[trees.analyse(equations).kind]


def layout(equations):
    """The tables of the equations' tree: {"kind", "node_width", "node_fields", "coordinate",
    "parent", "end", "dq", "dqd", "dnode", "dnode_start", "dQp", "inertial_column"}, and for a
    planar tree "D", "slope_width", "slope_fields" (plain Python values). The entries of ∂Q/∂y
    (dq, dqd) are pairs of nodes for a planar tree, of coordinates for a spatial one (whose
    coordinates may have several nodes)."""
    tree = trees.analyse(equations)
    (dq, _), (dqd, _), _ = tree_gradients(equations)
    (dnode, _), (dQp, _) = tree_parameter_gradients(equations)
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
    for values in trees.tree3d.inertial_symbols(equations.spec) or [None] * len(tree.coordinate):
        columns.append(start if values else -1)
        start += 10 if values else 0
    out["inertial_column"] = columns
    if tree.kind == "planar":
        out.update(D=tree.D, slope_width=trees.record_width(trees.SLOPE_FIELDS, tree.D),
                   slope_fields=trees.field_offsets(trees.SLOPE_FIELDS, tree.D))
    return out


def _nodes(pairs, tree):
    """(row, column) pairs of coordinates as pairs of nodes."""
    node = {j: k for k, j in enumerate(tree.coordinate)}
    return [[node[i], node[j]] for i, j in pairs]


def _ints(values):
    return ", ".join(str(int(v)) for v in values) if values else "0"


def tree_c(equations, template, kernels=("tree_nodes", "tree_slopes", "tree_parameters")):
    """`template` (the text of the tree's template, `template_name`) for the equations' tree, in
    a unit that has the `kernels` (names: the parts calling tree_slopes or tree_parameters are
    compiled when they are among them)."""
    tables = layout(equations)
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
    return Template(template).substitute(
        has_slopes=int("tree_slopes" in kernels),
        has_parameters=int("tree_parameters" in kernels),
        has_poses=int("tree_poses" in kernels),
        inertial_columns=_ints(tables["inertial_column"]),
        tree_d=tables.get("D", 0), node_width=tables["node_width"],
        slope_width=tables.get("slope_width", 0),
        nnz_q=len(tables["dq"]), nnz_qd=len(tables["dqd"]), field_offsets="\n".join(offsets),
        coordinates=_ints(tables["coordinate"]), parents=_ints(tables["parent"]),
        node_rows=_ints(range(n)), n_nodes=n, first_nodes=_ints(first),
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
    return {"node": [node for _, node, _ in tree.links], "parent": list(tree.parent),
            "coordinate": list(tree.coordinate)}
