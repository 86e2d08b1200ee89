"""The recursive formulation in NumPy: the Python backend of a model built with
formulation="recursive" (the recursions of `lagrgen/codegen/templates/tree.c.in`, the same
arithmetic on the same kernel outputs, see `lagrgen.tree` for the mathematics).

`RecursivePythonModel` is a `PythonModel` whose M, F, q̈, Jacobian and parameter Jacobian come
from the kinematic tree: the node records of the `tree_nodes` kernel and their slopes
(`tree_slopes`), combined by the articulated-body recursion (q̈ in O(n)), the composite-body sums
(M) and the derivative recursion (B), and M⁻¹ applied by the recursion's factor.
"""
import numpy as np

from ..errors import MassMatrixError
from .pymodel import PIVOT_TOL, PythonModel, watch_pivots


class Recursion:
    """The tables of one model's tree (`TREE` of its Python source) and the recursions on them."""

    def __init__(self, tables):
        self.D = tables["D"]
        self.coordinate = np.array(tables["coordinate"], dtype=np.intp)
        self.parent = list(tables["parent"])
        self.end = list(tables["end"])
        self.n = len(self.parent)
        self.node_fields = tables["node_fields"]
        self.slope_fields = tables["slope_fields"]
        self.dq = np.array(tables["dq"], dtype=np.intp).reshape(-1, 2)
        self.dqd = np.array(tables["dqd"], dtype=np.intp).reshape(-1, 2)
        self.dnode = np.array(tables["dnode"], dtype=np.intp).reshape(-1, 2)
        self.dnode_start = list(tables["dnode_start"])
        self.dQp = np.array(tables["dQp"], dtype=np.intp).reshape(-1, 2)
        self.ancestors = []
        for k in range(self.n):
            up, i = [], self.parent[k]
            while i >= 0:
                up.append(i)
                i = self.parent[i]
            self.ancestors.append(np.array(up, dtype=np.intp))

    def fields(self, records, layout, names):
        """Views of the named fields of the node records (n × width): D-wide or scalar."""
        D = self.D
        return [records[:, layout[name]:layout[name] + D] if _WIDTHS[name] == "D"
                else records[:, layout[name]] for name in names]

    def factor(self, nodes):
        """(U, 1/D, ν, Mc) of the articulated-body recursion, leaves to root; None when M is not
        positive definite (a pivot D_k ≤ PIVOT_TOL·M_kk, or NaN)."""
        n, D = self.n, self.D
        S, kap, m, uu, d, e, h, Q, _ = self.fields(nodes, self.node_fields, _NODE_NAMES)
        I = np.zeros((n, D, D))
        pb = np.zeros((n, D))
        Mc = np.zeros((n, D))
        U = np.empty((n, D))
        Dinv = np.empty(n)
        nu = np.empty(n)
        for k in range(n - 1, -1, -1):
            IS = I[k] @ S[k]
            Ikap = I[k] @ kap[k]
            U[k] = uu[k] + IS
            Mkk = d[k] + np.dot(S[k] * Mc[k], S[k])
            Dk = d[k] + np.dot(S[k], IS)
            if not Dk > PIVOT_TOL * Mkk:
                return None
            Dinv[k] = 1.0 / Dk
            nu[k] = Q[k] - h[k] - np.dot(S[k], Ikap + pb[k])
            parent = self.parent[k]
            if parent >= 0:
                I[parent] += I[k] - np.outer(U[k], U[k]) * Dinv[k] + np.diag(m[k])
                pb[parent] += e[k] + Ikap + pb[k] + U[k] * nu[k] * Dinv[k]
                Mc[parent] += m[k] + Mc[k]
        return U, Dinv, nu, Mc

    def accelerate(self, nodes, factor):
        """(q̈ in coordinate order, the subtree accelerations A), root to leaves."""
        U, Dinv, nu, _ = factor
        S, kap, base = self.fields(nodes, self.node_fields, ("S", "kappa", "base"))
        A = np.zeros((self.n, self.D))
        qdd = np.empty(self.n)
        for k in range(self.n):
            parent = self.parent[k]
            Ap = A[parent] if parent >= 0 else base[k]
            a = (nu[k] - np.dot(U[k], Ap)) * Dinv[k]
            qdd[self.coordinate[k]] = a
            A[k] = Ap + S[k] * a + kap[k]
        return qdd, A

    def accelerations(self, nodes, a):
        """A_k = A_parent + S_k·a_k + kappa_k for a given a (coordinate order)."""
        S, kap, base = self.fields(nodes, self.node_fields, ("S", "kappa", "base"))
        A = np.zeros((self.n, self.D))
        for k in range(self.n):
            parent = self.parent[k]
            A[k] = (A[parent] if parent >= 0 else base[k]) + S[k] * a[self.coordinate[k]] + kap[k]
        return A

    def forces(self, nodes, a, A):
        """(G, τ in coordinate order, Mc): the children's forces, the generalized inertia forces
        and the strict subtrees' composite masses, leaves to root."""
        S, m, uu, d, e, h, base = self.fields(nodes, self.node_fields,
                                              ("S", "mass", "u", "d", "e", "h", "base"))
        n, D = self.n, self.D
        G = np.zeros((n, D))
        Mc = np.zeros((n, D))
        tau = np.empty(n)
        for k in range(n - 1, -1, -1):
            parent = self.parent[k]
            Ap = A[parent] if parent >= 0 else base[k]
            ak = a[self.coordinate[k]]
            tau[self.coordinate[k]] = np.dot(uu[k], Ap) + d[k] * ak + h[k] + np.dot(S[k], G[k])
            if parent >= 0:
                G[parent] += m[k] * Ap + uu[k] * ak + e[k] + G[k]
                Mc[parent] += m[k] + Mc[k]
        return G, tau, Mc

    def mass_matrix(self, nodes, Mc):
        """M from the composite-body sums (see lg_mf in tree.c.in)."""
        S, uu, d = self.fields(nodes, self.node_fields, ("S", "u", "d"))
        n = self.n
        M = np.zeros((n, n))
        W = uu + Mc * S
        for k in range(n):
            ck = self.coordinate[k]
            M[ck, ck] = d[k] + np.dot(S[k] * Mc[k], S[k])
            up = self.ancestors[k]
            if up.size:
                rows = self.coordinate[up]
                M[rows, ck] = M[ck, rows] = S[up] @ W[k]
        return M

    def b(self, nodes, slopes, dQ, dQd, a, A):
        """B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇] (n×2n, coordinate order) at a (see lg_tree_b in
        tree.c.in, which forms it in node order)."""
        n = self.n
        S, uu, base = self.fields(nodes, self.node_fields, ("S", "u", "base"))
        dS, al, ald, du, c, cd, g, gd = self.fields(slopes, self.slope_fields, _SLOPE_NAMES)
        G, _, Mc = self.forces(nodes, a, A)
        W = uu + Mc * S
        B = np.zeros((n, 2 * n))             # node order
        if len(dQ):
            B[self.dq[:, 0], self.dq[:, 1]] = dQ
        if len(dQd):
            B[self.dqd[:, 0], n + self.dqd[:, 1]] = dQd
        for j in range(n):
            parent = self.parent[j]
            Ap = A[parent] if parent >= 0 else base[j]
            Mal, Mald = Mc[j] * al[j], Mc[j] * ald[j]
            B[j, j] -= np.dot(du[j], Ap) + c[j] + np.dot(dS[j], G[j]) + np.dot(S[j], Mal)
            B[j, n + j] -= cd[j] + np.dot(S[j], Mald)
            up = self.ancestors[j]
            if up.size:
                B[up, j] -= S[up] @ (g[j] + Mal)
                B[up, n + j] -= S[up] @ (gd[j] + Mald)
            below = slice(j + 1, self.end[j])
            B[below, j] -= W[below] @ al[j]
            B[below, n + j] -= W[below] @ ald[j]
        out = np.empty_like(B)
        columns = np.concatenate([self.coordinate, n + self.coordinate])
        out[np.ix_(self.coordinate, columns)] = B
        return out

    def parameter_records(self, dv, n_params, width):
        """The node records' derivatives by each parameter, (n_params, n, width), from the
        nonzero ones `dv` of the tree_parameters kernel."""
        dnodes = np.zeros((n_params, self.n, width))
        params = np.repeat(np.arange(n_params), np.diff(self.dnode_start))
        if len(dv):
            dnodes[params, self.dnode[:, 0], self.dnode[:, 1]] = dv
        return dnodes

    def parameter_b(self, nodes, dv, dQ, a, A, n_params):
        """P = ∂Q/∂p − ∂τ/∂p (n×n_params) at a, by tangent sweeps of the recursion, all
        parameters at once (see lg_parameter_b in tree.c.in)."""
        G, _, _ = self.forces(nodes, a, A)
        P = np.zeros((self.n, n_params))
        if len(dQ):
            P[self.dQp[:, 0], self.dQp[:, 1]] = dQ
        dnodes = self.parameter_records(dv, n_params, nodes.shape[1])
        return P - self.tangent(nodes, a, A, G, dnodes=dnodes)

    def tangent(self, nodes, a, A, G, dnodes=None, slopes=None, dy=None):
        """δτ (n × columns, coordinate order) by one tangent sweep of the recursion per column at
        a given a (see lg_tree_tangent in tree.c.in): the node records changing by `dnodes`
        (columns × n × width) and/or each node's own coordinate and rate by `dy` (columns × 2n,
        coordinate order) through its `slopes`."""
        n, D = self.n, self.D
        columns = len(dnodes) if dnodes is not None else len(dy)
        S, m, uu, base = self.fields(nodes, self.node_fields, ("S", "mass", "u", "base"))
        a_node = np.asarray(a, dtype=np.float64)[self.coordinate]
        own = np.zeros((n, columns, D))          # each node's own change of its A_k
        dbase = np.zeros((n, columns, D))
        if dnodes is not None:
            def field(name):      # (n, columns, D) or (n, columns)
                o = self.node_fields[name]
                if _WIDTHS[name] == "D":
                    return dnodes[:, :, o:o + D].transpose(1, 0, 2)
                return dnodes[:, :, o].T
            dS, dkap, dm, du, dd, de, dh, dbase = (field(name) for name in (
                "S", "kappa", "mass", "u", "d", "e", "h", "base"))
            own += dS * a_node[:, None, None] + dkap
        if dy is not None:
            dq, dqd = dy[:, self.coordinate].T, dy[:, n + self.coordinate].T   # (n, columns)
            sS, al, ald, su, c, cd, g, gd = self.fields(slopes, self.slope_fields, _SLOPE_NAMES)
            own += al[:, None, :] * dq[:, :, None] + ald[:, None, :] * dqd[:, :, None]
        dA = np.zeros((n, columns, D))
        for k in range(n):
            parent = self.parent[k]
            dA[k] = (dA[parent] if parent >= 0 else dbase[k]) + own[k]
        dG = np.zeros((n, columns, D))
        dtau = np.zeros((n, columns))
        for k in range(n - 1, -1, -1):
            parent, ck = self.parent[k], self.coordinate[k]
            Ap = A[parent] if parent >= 0 else base[k]
            dAp = dA[parent] if parent >= 0 else dbase[k]
            x = dAp @ uu[k] + dG[k] @ S[k]
            f = m[k] * dAp + dG[k]
            if dnodes is not None:
                x += du[k] @ Ap + dd[k] * a_node[k] + dh[k] + dS[k] @ G[k]
                f += dm[k] * Ap + du[k] * a_node[k] + de[k]
            if dy is not None:
                x += (su[k] @ Ap + c[k] + sS[k] @ G[k]) * dq[k] + cd[k] * dqd[k]
                f += g[k] * dq[k][:, None] + gd[k] * dqd[k][:, None]
            dtau[ck] = x
            if parent >= 0:
                dG[parent] += f
        return dtau

    def solve(self, nodes, factor, X):
        """M⁻¹·X for the n×k array X (rows: coordinates), with the recursion's factor."""
        U, Dinv, _, _ = factor
        S, = self.fields(nodes, self.node_fields, ("S",))
        n, D = self.n, self.D
        R = np.array(X, dtype=np.float64)[self.coordinate]
        P = np.zeros((n, D, R.shape[1]))
        for k in range(n - 1, -1, -1):
            R[k] -= S[k] @ P[k]
            parent = self.parent[k]
            if parent >= 0:
                P[parent] += P[k] + np.outer(U[k] * Dinv[k], R[k])
        zero = np.zeros((D, R.shape[1]))
        for k in range(n):
            parent = self.parent[k]
            Ap = P[parent] if parent >= 0 else zero
            R[k] = (R[k] - U[k] @ Ap) * Dinv[k]
            P[k] = Ap + np.outer(S[k], R[k])
        out = np.empty_like(R)
        out[self.coordinate] = R
        return out


_NODE_NAMES = ("S", "kappa", "mass", "u", "d", "e", "h", "Q", "base")
_SLOPE_NAMES = ("dS", "alpha", "alpha_qd", "du", "c", "c_qd", "g", "g_qd")
#: Width of each field: "D" or 1 (lagrgen.tree.NODE_FIELDS and SLOPE_FIELDS; the runtime does
#: not import the derivation).
_WIDTHS = {"S": "D", "kappa": "D", "mass": "D", "u": "D", "d": 1, "e": "D", "h": 1, "Q": 1,
           "base": "D",
           "dS": "D", "alpha": "D", "alpha_qd": "D", "du": "D", "c": 1, "c_qd": 1, "g": "D",
           "g_qd": "D"}


class FactoredModel(PythonModel):
    """A `PythonModel` whose q̈ comes from its recursion's `_factored(t, q, qd, p, u)`, a tuple
    whose third entry is q̈ (the planar and the spatial recursions)."""

    def _solved(self, t, q, qd, p, u):
        M, _ = self._mf(t, q, qd, p, u)
        return M, self._factored(t, q, qd, p, u)[2]

    def _rhs(self, t, q, qd, p, u):
        return np.concatenate([np.array(qd, dtype=np.float64), self._factored(t, q, qd, p, u)[2]])

    def _outputs(self, t, q, qd, p, u):
        return self._kernel("tree_outputs", t, q, qd, None, p, u)[0]

    def _power_terms(self, t, q, qd, p, u):
        return self._kernel("tree_outputs", t, q, qd, None, p, u)[1]


class RecursivePythonModel(FactoredModel):
    """A `PythonModel` of the recursive formulation (`build(..., formulation="recursive")`)."""

    def __init__(self, info, source):
        super().__init__(info, source)
        self._tree = Recursion(self._kernels["TREE"])

    def _nodes(self, t, q, qd, p, u):
        n = self.n_coordinates
        return self._kernel("tree_nodes", t, q, qd, None, p, u)[0].reshape(n, -1)

    def _factored(self, t, q, qd, p, u):
        """(node records, factor, q̈, A); MassMatrixError when M is not positive definite."""
        nodes = self._nodes(t, q, qd, p, u)
        factor = self._tree.factor(nodes)
        if factor is None:
            raise MassMatrixError.at(self.name, t, q)
        S, d = self._tree.fields(nodes, self._tree.node_fields, ("S", "d"))
        watch_pivots(self, 1.0 / factor[1], d + np.sum(S * factor[3] * S, axis=1))   # D_k, M_kk
        qdd, A = self._tree.accelerate(nodes, factor)
        return nodes, factor, qdd, A

    def _mf(self, t, q, qd, p, u):
        nodes = self._nodes(t, q, qd, p, u)
        zeros = np.zeros(self.n_coordinates)
        _, tau, Mc = self._tree.forces(nodes, zeros, self._tree.accelerations(nodes, zeros))
        F = self._tree.fields(nodes, self._tree.node_fields, ("Q",))[0][
            np.argsort(self._tree.coordinate)] - tau
        return self._tree.mass_matrix(nodes, Mc), F

    def _b(self, t, q, qd, a, p, u, nodes=None, A=None):
        n = self.n_coordinates
        if nodes is None:
            nodes = self._nodes(t, q, qd, p, u)
            A = self._tree.accelerations(nodes, a)
        slopes, dQ, dQd = self._kernel("tree_slopes", t, q, qd, list(a), p, u)
        return self._tree.b(nodes, slopes.reshape(n, -1), dQ, dQd, np.asarray(a, dtype=float), A)

    def _jacobian(self, t, q, qd, p, u):
        n = self.n_coordinates
        nodes, factor, qdd, A = self._factored(t, q, qd, p, u)
        B = self._b(t, q, qd, qdd.tolist(), p, u, nodes, A)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:] = self._tree.solve(nodes, factor, B)
        return J

    def _parameter_jacobian(self, t, q, qd, p, u):
        n, k = self.n_coordinates, len(self.parameters)
        out = np.zeros((2 * n, k))
        if not k:
            return out
        nodes, factor, qdd, A = self._factored(t, q, qd, p, u)
        P = self._parameter_b(t, q, qd, qdd, p, u, nodes, A)
        out[n:] = self._tree.solve(nodes, factor, P)
        return out

    def _parameter_b(self, t, q, qd, a, p, u, nodes=None, A=None):
        """P = ∂F/∂p − ∂(M·a)/∂p at a given a (the residual's), by the recursion's tangent sweeps
        (the node records and accelerations at a: `nodes`, `A`, formed here when not given)."""
        a = np.asarray(a[:self.n_coordinates], dtype=np.float64)
        if nodes is None:
            nodes = self._nodes(t, q, qd, p, u)
            A = self._tree.accelerations(nodes, a)
        dv, dQ = self._kernel("tree_parameters", t, q, qd, a.tolist(), p, u)
        return self._tree.parameter_b(nodes, dv, dQ, a, A, len(self.parameters))

    def _directional_derivatives(self, t, q, qd, p, u, dy, dp):
        """ẏ and, per direction, J·dy + ∂ẏ/∂p·dp: δR = δQ − δτ by tangent sweeps of the recursion
        (all directions at once), then δq̈ = M⁻¹·δR by the recursion's solve (see
        lg_tree_directions in tree.c.in)."""
        n, k = self.n_coordinates, len(dy)
        tree = self._tree
        nodes, factor, qdd, A = self._factored(t, q, qd, p, u)
        G, _, _ = tree.forces(nodes, qdd, A)
        slopes, dQ, dQd = self._kernel("tree_slopes", t, q, qd, qdd.tolist(), p, u)
        dnodes, R = None, np.zeros((n, k))
        if len(self.parameters) and np.any(dp):
            dv, dQp = self._kernel("tree_parameters", t, q, qd, qdd.tolist(), p, u)
            per_parameter = tree.parameter_records(dv, len(self.parameters), nodes.shape[1])
            dnodes = np.tensordot(dp, per_parameter, axes=1)
            if len(dQp):
                np.add.at(R, tree.dQp[:, 0], dQp[:, None] * dp[:, tree.dQp[:, 1]].T)
        c = tree.coordinate
        if len(dQ):
            np.add.at(R, c[tree.dq[:, 0]], dQ[:, None] * dy[:, c[tree.dq[:, 1]]].T)
        if len(dQd):
            np.add.at(R, c[tree.dqd[:, 0]], dQd[:, None] * dy[:, n + c[tree.dqd[:, 1]]].T)
        R -= tree.tangent(nodes, qdd, A, G, dnodes, slopes.reshape(n, -1), dy)
        out = np.empty((k, 2 * n))
        out[:, :n] = dy[:, n:]
        out[:, n:] = tree.solve(nodes, factor, R).T
        return np.concatenate([np.array(qd, dtype=np.float64), qdd]), out
