"""The sparsity of a three-dimensional tree's residual derivatives, from its structure alone.

For r = τ(q, q̇, q̈) − Q(q, q̇, u) of a tree in the recursive formulation, τ_i depends on q_j, q̇_j
and q̈_j only when the joints of coordinates i and j lie on one path from a root (one at or below
the other: the forces of other branches are summed, never multiplied), and so do its second
derivatives ∂²(Σ mu·τ)/∂z_a∂z_b; the generalized forces Q add the entries of their own first and
second derivatives (`ModelInfo.tree_structure`). Nothing symbolic is formed: a robot's collocation
problem is laid out from the tables its build recorded.
"""
import numpy as np


def related(structure, n):
    """(n, n) boolean: the coordinates whose joints lie on one path from a root."""
    coordinate, parent = structure["coordinate"], structure["parent"]
    out = np.zeros((n, n), dtype=bool)
    for k, c in enumerate(coordinate):
        i = k
        while i >= 0:
            out[c, coordinate[i]] = out[coordinate[i], c] = True
            i = parent[i]
    return out


def jacobian_structure(structure, n, n_inputs, n_params):
    """Which entries of ∂r/∂[q, q̇], ∂r/∂a, ∂r/∂u and ∂r/∂p may be nonzero, as boolean nested
    lists shaped like `residual_terms`' outputs (`lagrgen.hessians.residual_jacobian_structure`'s
    layout; ∂r/∂p all False: a problem with unknown parameters takes the symbolic path)."""
    path = related(structure, n)
    dq, dqd = path.copy(), path.copy()
    for i, j in structure["dq"]:
        dq[i, j] = True
    for i, j in structure["dqd"]:
        dqd[i, j] = True
    du = np.zeros((n, n_inputs), dtype=bool)
    for i, k in structure["du"]:
        du[i, k] = True
    return {"dr_dy": np.hstack([dq, dqd]).tolist(), "dr_da": path.tolist(),
            "dr_du": du.tolist(), "dr_dp": np.zeros((n, n_params), dtype=bool).tolist()}


def hessian_entries(structure, n, n_inputs):
    """The lower-triangle entries (row, col) of ∇²_z(Σ mu_i·r_i) that may be nonzero, z = [q, q̇,
    q̈, u], in row-major order: (q, q), (q̇, q), (q̇, q̇) and (q̈, q) of coordinates on one path, and
    those of the generalized forces' second derivatives."""
    size = 3 * n + n_inputs
    mask = np.zeros((size, size), dtype=bool)
    path = related(structure, n)
    mask[:n, :n] = path
    mask[n:2 * n, :n] = path
    mask[n:2 * n, n:2 * n] = path
    mask[2 * n:3 * n, :n] = path
    for r, c in structure["qh"]:
        mask[max(r, c), min(r, c)] = True
    rows, cols = np.nonzero(np.tril(mask))
    return np.column_stack([rows, cols]).astype(np.int64)
