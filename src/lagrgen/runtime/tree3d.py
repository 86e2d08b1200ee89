"""The recursive formulation of a three-dimensional tree in NumPy: the Python backend of a model
built with formulation="recursive" whose tree is spatial (the recursions of
`lagrgen/codegen/templates/tree3d.c.in`, the same arithmetic on the same kernel outputs; see
`lagrgen.tree3d` for the mathematics).
"""
import numpy as np

from ..errors import MassMatrixError
from .pymodel import PIVOT_TOL, watch_pivots
from .tree import FactoredModel


def crm(v, m):
    """v × m of motions (…, 6)."""
    w, vo = v[..., :3], v[..., 3:]
    return np.concatenate([np.cross(w, m[..., :3]),
                           np.cross(w, m[..., 3:]) + np.cross(vo, m[..., :3])], axis=-1)


def crf(v, f):
    """v ×* f of a motion on a force (…, 6)."""
    w, vo = v[..., :3], v[..., 3:]
    return np.concatenate([np.cross(w, f[..., :3]) + np.cross(vo, f[..., 3:]),
                           np.cross(w, f[..., 3:])], axis=-1)


def inertia_matrix(Y):
    """The 6×6 matrix of the inertia (m, h, Ī) (10 numbers)."""
    m, h, I = Y[0], Y[1:4], Y[4:]
    H = np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])
    Ibar = np.array([[I[0], I[1], I[3]], [I[1], I[2], I[4]], [I[3], I[4], I[5]]])
    return np.block([[Ibar, H], [H.T, m * np.eye(3)]])


def inertia_apply(Y, m):
    """Y·m for the inertia Y (10 numbers) and the motion m."""
    return inertia_matrix(Y) @ m


def cross_matrix(m):
    """The 6×6 matrix of x ↦ m × x (motions)."""
    w, v = skew(m[:3]), skew(m[3:])
    return np.block([[w, np.zeros((3, 3))], [v, w]])


def skew(x):
    """The 3×3 matrix of y ↦ x × y."""
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def force_cross_matrix(f):
    """The 6×6 matrix of x ↦ x ×* f (a motion x on the force f)."""
    n, l = skew(f[:3]), skew(f[3:])
    return np.block([[-n, -l], [-l, np.zeros((3, 3))]])


def variation(s, B):
    """[s]×*·B − B·[s]×: the change of the operator B when its body turns with s."""
    C = cross_matrix(s)
    return -C.T @ B - B @ C


def force_derivative(Y, v):
    """The 6×6 operator dY·ψ = v ×* (Y·ψ) − Y·(v × ψ) + ψ ×* (Y·v) (tree3d.c.in's
    lg_sv_force_derivative, as a full matrix)."""
    I6 = inertia_matrix(Y)
    mom = I6 @ v
    out = np.empty((6, 6))
    for c in range(6):
        e = np.zeros(6)
        e[c] = 1.0
        out[:, c] = crf(v, I6 @ e) - I6 @ crm(v, e) + crf(e, mom)
    return out


def joint_frame(placement, axis, prismatic, parent, theta):
    """(R, o, d) of a joint's frame from its parent's (R, o) (tree3d.c.in's lg_joint_frame):
    R = Rp·P·J(θ) (Rodrigues; 1 for a prismatic joint), o = op + Rp·(o_P + P·a·θ for a
    prismatic joint), d = Rp·P·a."""
    Rp, op = parent
    RP = Rp @ placement[:9].reshape(3, 3)
    d = RP @ axis
    o = op + Rp @ placement[9:]
    if prismatic:
        return RP, o + d * theta, d
    x = np.cross(RP, axis)
    return RP + np.sin(theta) * x + (1.0 - np.cos(theta)) * np.cross(x, axis), o, d


def world_inertia(R, o, body):
    """(m, h_w, Ī) at the fixed origin of a body of parameters (m, h, I_O) about its frame
    (R, o) (lagrgen.frames.world_inertia)."""
    m, h = body[0], R @ body[1:4]
    xx, xy, yy, xz, yz, zz = body[4:]
    W = R @ np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) @ R.T
    Ibar = W + (m * (o @ o) + 2.0 * (o @ h)) * np.eye(3) - m * np.outer(o, o) \
        - np.outer(o, h) - np.outer(h, o)
    return np.r_[m, m * o + h, Ibar[0, 0], Ibar[0, 1], Ibar[1, 1], Ibar[0, 2], Ibar[1, 2],
                 Ibar[2, 2]]


class SpatialRecursion:
    """The tables of one model's spatial tree (`TREE` of its Python source) and the recursions.
    Nodes are joints; a coordinate has one node or several (joints that follow it)."""

    def __init__(self, tables, n_coordinates):
        self.coordinate = np.array(tables["coordinate"], dtype=np.intp)
        self.parent = list(tables["parent"])
        self.end = list(tables["end"])
        self.n = len(self.parent)
        self.nc = n_coordinates
        self.fields = tables["node_fields"]
        self.dq = np.array(tables["dq"], dtype=np.intp).reshape(-1, 2)
        self.dqd = np.array(tables["dqd"], dtype=np.intp).reshape(-1, 2)
        self.dnode = np.array(tables["dnode"], dtype=np.intp).reshape(-1, 2)
        self.dnode_start = list(tables["dnode_start"])
        self.dQp = np.array(tables["dQp"], dtype=np.intp).reshape(-1, 2)
        self.qh = [tuple(rc) for rc in tables.get("qh", [])]
        self.first = np.unique(self.coordinate, return_index=True)[1]
        self.energies = bool(tables.get("energies", False))
        self.joints = tables.get("joints")
        self.width = tables["node_width"]
        self.path = []
        for k in range(self.n):
            up, i = [k], self.parent[k]
            while i >= 0:
                up.append(i)
                i = self.parent[i]
            self.path.append(up)

    def joint_records(self, q, p, Q, g):
        """The node records (nodes × width) from the joints' numbers (`lagrgen.tree3d.Joints`),
        the generalized forces Q and the gravity g (tree3d.c.in's lg_tree_joint_nodes)."""
        J, o = self.joints, self.fields
        nodes = np.zeros((self.n, self.width))
        frames = []
        for k in range(self.n):
            parent = frames[self.parent[k]] if self.parent[k] >= 0 else (np.eye(3), np.zeros(3))
            mult, offset = J["motion"][k]
            prismatic = J["prismatic"][k]
            R, origin, d = joint_frame(np.asarray(J["placement"][k]), np.asarray(J["axis"][k]),
                                       prismatic, parent, mult * q[self.coordinate[k]] + offset)
            frames.append((R, origin))
            s = np.r_[np.zeros(3), d] if prismatic else np.r_[d, np.cross(origin, d)]
            body = np.array([p[j] if j >= 0 else x for x, j in
                             zip(J["inertia"][k], J["inertia_parameter"][k])], dtype=float)
            nodes[k, o["s"]:o["s"] + 6] = mult * s
            nodes[k, o["Y"]:o["Y"] + 10] = world_inertia(R, origin, body)
            if self.parent[k] < 0:
                nodes[k, o["base"] + 3:o["base"] + 6] = -np.asarray(g)
            nodes[k, o["Q"]] = Q[self.coordinate[k]]
        return nodes

    def split(self, nodes):
        """(s, Y, base, Q in node order) of the node records (nodes × width)."""
        o = self.fields
        return (nodes[:, o["s"]:o["s"] + 6], nodes[:, o["Y"]:o["Y"] + 10],
                nodes[:, o["base"]:o["base"] + 6], nodes[:, o["Q"]])

    def generalized_forces(self, nodes):
        """Q in coordinate order (each coordinate's from its first node)."""
        Q = np.empty(self.nc)
        Q[self.coordinate[self.first]] = self.split(nodes)[3][self.first]
        return Q

    def motion(self, nodes, qd, a):
        """(v, acc) of every node at q̇ and q̈ = a (coordinate order)."""
        s, _, base, _ = self.split(nodes)
        v, acc = np.zeros((self.n, 6)), np.zeros((self.n, 6))
        for k in range(self.n):
            parent, ck = self.parent[k], self.coordinate[k]
            vp = v[parent] if parent >= 0 else np.zeros(6)
            ap = acc[parent] if parent >= 0 else base[k]
            v[k] = vp + s[k] * qd[ck]
            acc[k] = ap + s[k] * a[ck] + crm(vp, s[k]) * qd[ck]
        return v, acc

    def forces(self, nodes, v, acc):
        """The subtrees' inertia forces fc (nodes × 6) and τ (coordinate order)."""
        s, Y, _, _ = self.split(nodes)
        f = np.array([inertia_apply(Y[k], acc[k]) + crf(v[k], inertia_apply(Y[k], v[k]))
                      for k in range(self.n)])
        tau = np.zeros(self.nc)
        for k in range(self.n - 1, -1, -1):
            tau[self.coordinate[k]] += s[k] @ f[k]
            if self.parent[k] >= 0:
                f[self.parent[k]] += f[k]
        return f, tau

    def mass_matrix(self, nodes):
        """M (coordinate order) by the composite-rigid-body algorithm, the nodes' entries summed
        per coordinate."""
        s, Y, _, _ = self.split(nodes)
        Yc = np.array(Y)
        H = np.zeros((self.n, self.n))
        for k in range(self.n - 1, -1, -1):
            F = inertia_apply(Yc[k], s[k])
            for i in self.path[k]:
                H[i, k] = H[k, i] = s[i] @ F
            if self.parent[k] >= 0:
                Yc[self.parent[k]] += Yc[k]
        G = np.zeros((self.n, self.nc))
        G[np.arange(self.n), self.coordinate] = 1.0
        return G.T @ H @ G

    def factor(self, M):
        """The Cholesky factor of M (None when it is not positive definite, as the C code's
        pivot test)."""
        if not np.isfinite(M).all():
            return None
        try:
            L = np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            return None
        if np.any(np.diagonal(L) ** 2 <= PIVOT_TOL * np.diagonal(M)):
            return None
        return L

    def solve(self, L, X):
        """M⁻¹·X for X in coordinate order (rows), with the factor L."""
        X = np.asarray(X, dtype=np.float64)
        return np.linalg.solve(L.T, np.linalg.solve(L, X))

    def b(self, nodes, qd, a, dQ, dQd):
        """B = [∂Q/∂q − ∂τ/∂q | ∂Q/∂q̇ − ∂τ/∂q̇] (coordinate order) at q̈ = a (tree3d.c.in's
        lg_tree_b), the nodes' entries summed per coordinate."""
        n, nc = self.n, self.nc
        s, Y, base, _ = self.split(nodes)
        v, acc = self.motion(nodes, qd, a)
        f, _ = self.forces(nodes, v, acc)
        psi, alpha = np.zeros((n, 6)), np.zeros((n, 6))
        Yc, dY = np.array(Y), np.zeros((n, 6, 6))
        for k in range(n):
            parent = self.parent[k]
            vp = v[parent] if parent >= 0 else np.zeros(6)
            ap = acc[parent] if parent >= 0 else base[k]
            psi[k] = crm(vp, s[k])
            alpha[k] = crm(ap, s[k]) + crm(vp, psi[k])
            dY[k] = force_derivative(Y[k], v[k])
        B = np.zeros((nc, 2 * nc))
        Fa, G = np.zeros((n, 6)), np.zeros((n, 6))
        c = self.coordinate
        for k in range(n - 1, -1, -1):
            Fa[k] = inertia_apply(Yc[k], s[k])
            G[k] = dY[k].T @ s[k]
            dFq = inertia_apply(Yc[k], alpha[k]) + dY[k] @ psi[k] + crf(s[k], f[k])
            dFv = inertia_apply(Yc[k], 2 * psi[k]) + dY[k] @ s[k]
            for i in self.path[k]:
                B[c[i], c[k]] -= s[i] @ dFq
                B[c[i], nc + c[k]] -= s[i] @ dFv
            below = np.arange(k + 1, self.end[k])
            np.add.at(B, (c[below], c[k]), -(Fa[below] @ alpha[k] + G[below] @ psi[k]))
            np.add.at(B, (c[below], nc + c[k]), -(Fa[below] @ (2 * psi[k]) + G[below] @ s[k]))
            parent = self.parent[k]
            if parent >= 0:
                Yc[parent] += Yc[k]
                dY[parent] += dY[k]
        if len(dQ):
            np.add.at(B, (self.dq[:, 0], self.dq[:, 1]), dQ)
        if len(dQd):
            np.add.at(B, (self.dqd[:, 0], nc + self.dqd[:, 1]), dQd)
        return B

    def hessian(self, nodes, qd, a, mu, size):
        """Σ_c mu_c·∇²τ_c (coordinate order) in z = [q, q̇, q̈, …] (size × size, symmetric) at
        q̈ = a: the second-order derivatives of the inverse dynamics contracted with mu
        (tree3d.c.in's lg_tree_hessian, the same formulas, for the nodes k ≤ j ≤ i of a path)."""
        n, nc = self.n, self.nc
        s, Y, base, _ = self.split(nodes)
        c = self.coordinate
        v, acc = self.motion(nodes, qd, a)
        psi, psidd = np.zeros((n, 6)), np.zeros((n, 6))
        Yc = np.array([inertia_matrix(Y[k]) for k in range(n)])
        BC, fc = np.zeros((n, 6, 6)), np.zeros((n, 6))
        for k in range(n):
            parent = self.parent[k]
            vp = v[parent] if parent >= 0 else np.zeros(6)
            ap = acc[parent] if parent >= 0 else base[k]
            psi[k] = crm(vp, s[k])
            psidd[k] = crm(ap, s[k]) + crm(vp, psi[k])
            h = Yc[k] @ v[k]
            fc[k] = Yc[k] @ acc[k] + crf(v[k], h)
            BC[k] = variation(v[k], Yc[k]) + force_cross_matrix(h)
        H = np.zeros((size, size))
        Hqq, Hvv = H[:nc, :nc], H[nc:2 * nc, nc:2 * nc]
        Hqv, Haq = H[:nc, nc:2 * nc], H[2 * nc:3 * nc, :nc]
        for i in range(n - 1, -1, -1):
            Si, ip = s[i], c[i]
            r1 = variation(Si, Yc[i])
            r0 = force_cross_matrix(Yc[i] @ Si)
            Bic = r1 + r0
            r2 = r0 - r1
            r3 = (variation(psi[i], Yc[i]) + force_cross_matrix(Yc[i] @ psi[i])
                  + variation(Si, BC[i]))
            r4 = force_cross_matrix(BC[i].T @ Si)
            r5 = force_cross_matrix(BC[i] @ psi[i] + crf(Si, fc[i]) + Yc[i] @ psidd[i])
            r6 = r0 - cross_matrix(Si).T @ Yc[i]
            r7 = force_cross_matrix(BC[i] @ Si + 2.0 * Yc[i] @ psi[i])
            mi = mu[ip]
            for j in self.path[i]:
                Sj, jq, mj = s[j], c[j], mu[c[j]]
                u1, u2 = r3.T @ Sj, r1.T @ Sj
                u3 = r3 @ psi[j] + r1 @ psidd[j] + r5 @ Sj
                u4, u5 = r6 @ Sj, r2 @ psi[j]
                u6 = Bic @ psi[j] + r7 @ Sj
                u7 = r3 @ Sj + 2.0 * r1 @ psi[j]
                u8, u9, u10 = r4 @ Sj, r0 @ Sj, Bic @ Sj
                u11, u12, u13 = Bic.T @ Sj, Bic.T @ psi[j], r1 @ Sj
                for k in self.path[j]:
                    Sk, kr, mk = s[k], c[k], mu[c[k]]
                    p1 = u11 @ psi[k]
                    p2 = u9 @ psidd[k] + (u8 - u12) @ psi[k]
                    Hqq[jq, kr] += mi * p2
                    Hqv[kr, jq] -= mi * p1
                    if j != i:
                        t = u1 @ psi[k] + u2 @ psidd[k]
                        p3, p4 = u11 @ Sk, Sk @ u13
                        Hqq[kr, ip] += mj * t
                        Hqq[ip, kr] += mj * t
                        Hqv[kr, ip] += mj * p1
                        Hqv[ip, kr] += mj * (u1 @ Sk + 2.0 * u2 @ psi[k])
                        Hvv[kr, ip] += mj * p3
                        Hvv[ip, kr] += mj * p3
                        Haq[jq, ip] += mk * p4
                        if k != j:
                            Haq[kr, ip] += mj * p4
                    if k != j:
                        p3, p5, t = -(u11 @ Sk), Sk @ u9, Sk @ u3
                        Hqq[kr, jq] += mi * p2
                        Hqq[ip, jq] += mk * t
                        Hvv[jq, kr] += mi * p3
                        Hvv[kr, jq] += mi * p3
                        Hqv[jq, kr] += mi * (Sk @ (u5 + u8) + 2.0 * u9 @ psi[k])
                        Hqv[jq, ip] += mk * (Sk @ u6)
                        Haq[ip, jq] += mk * p5
                        Haq[kr, jq] += mi * p5
                        if j != i:
                            p6 = Sk @ u10
                            Hqq[jq, ip] += mk * t
                            Hvv[ip, jq] += mk * p6
                            Hvv[jq, ip] += mk * p6
                            Hqv[ip, jq] += mk * (Sk @ u7)
                        else:
                            Hvv[jq, ip] += mk * (Sk @ u4)
                    else:
                        Hvv[jq, kr] -= mi * (u2 @ Sk)
            parent = self.parent[i]
            if parent >= 0:
                Yc[parent] += Yc[i]
                BC[parent] += BC[i]
                fc[parent] += fc[i]
        H[nc:2 * nc, :nc] = Hqv.T
        H[:nc, 2 * nc:3 * nc] = Haq.T
        return H

    def tangent(self, nodes, dnodes, qd, a):
        """δτ (coordinate order) of the inverse dynamics at q̈ = a when the node records change
        by `dnodes` (tree3d.c.in's lg_tree_tangent)."""
        n = self.n
        s, Y, base, _ = self.split(nodes)
        ds, dYn, dbase, _ = self.split(dnodes)
        v, acc = self.motion(nodes, qd, a)
        dv, dacc = np.zeros((n, 6)), np.zeros((n, 6))
        f, df = np.zeros((n, 6)), np.zeros((n, 6))
        for k in range(n):
            parent, ck = self.parent[k], self.coordinate[k]
            vp = v[parent] if parent >= 0 else np.zeros(6)
            dvp = dv[parent] if parent >= 0 else np.zeros(6)
            dap = dacc[parent] if parent >= 0 else dbase[k]
            dv[k] = dvp + ds[k] * qd[ck]
            dacc[k] = dap + ds[k] * a[ck] + (crm(dvp, s[k]) + crm(vp, ds[k])) * qd[ck]
            mom = inertia_apply(Y[k], v[k])
            f[k] = inertia_apply(Y[k], acc[k]) + crf(v[k], mom)
            df[k] = (inertia_apply(dYn[k], acc[k]) + inertia_apply(Y[k], dacc[k])
                     + crf(dv[k], mom)
                     + crf(v[k], inertia_apply(dYn[k], v[k]) + inertia_apply(Y[k], dv[k])))
        dtau = np.zeros(self.nc)
        for k in range(n - 1, -1, -1):
            dtau[self.coordinate[k]] += ds[k] @ f[k] + s[k] @ df[k]
            parent = self.parent[k]
            if parent >= 0:
                f[parent] += f[k]
                df[parent] += df[k]
        return dtau

    def parameter_records(self, dv, n_params, width):
        """The node records' derivatives by each parameter, (n_params, nodes, width)."""
        dnodes = np.zeros((n_params, self.n, width))
        params = np.repeat(np.arange(n_params), np.diff(self.dnode_start))
        if len(dv):
            dnodes[params, self.dnode[:, 0], self.dnode[:, 1]] = dv
        return dnodes


class SpatialPythonModel(FactoredModel):
    """A `PythonModel` of the recursive formulation over a three-dimensional tree."""

    def __init__(self, info, source):
        super().__init__(info, source)
        self._tree = SpatialRecursion(self._kernels["TREE"], self.n_coordinates)

    def _nodes(self, t, q, qd, p, u):
        if self._tree.joints is not None:
            Q, g = self._kernel("tree_loads", t, q, qd, None, p, u)
            return self._tree.joint_records(np.asarray(q, dtype=float),
                                            np.asarray(p, dtype=float), Q, g)
        return self._kernel("tree_nodes", t, q, qd, None, p, u)[0].reshape(self._tree.n, -1)

    def _outputs(self, t, q, qd, p, u):
        """tree_outputs', with an articulation's bodies' energies added from their records
        (T = ½·Σ v_k·Y_k·v_k, V = −g·Σ h_k; tree3d.c.in's lg_outputs)."""
        out = super()._outputs(t, q, qd, p, u)
        if self._tree.energies:
            T, V = self._record_energies(self._nodes(t, q, qd, p, u), qd)
            out[-3:] += [T, V, T + V]
        return out

    def _record_energies(self, nodes, rates):
        """(T, V) of the nodes' bodies from their records at the recursion's `rates`:
        T = ½·Σ v_k·Y_k·v_k, V = −g·Σ h_k."""
        _, Y, base, _ = self._tree.split(nodes)
        v = self._tree.motion(nodes, np.asarray(rates, dtype=float), np.zeros(len(rates)))[0]
        T = 0.5 * sum(v[k] @ inertia_apply(Y[k], v[k]) for k in range(self._tree.n))
        return T, float(base[0, 3:] @ Y[:, 1:4].sum(axis=0))

    def _inverse(self, nodes, qd, a):
        v, acc = self._tree.motion(nodes, np.asarray(qd, dtype=float), np.asarray(a, dtype=float))
        return self._tree.forces(nodes, v, acc)[1]

    def _mf(self, t, q, qd, p, u):
        nodes = self._nodes(t, q, qd, p, u)
        tau = self._inverse(nodes, qd, np.zeros(self.n_coordinates))
        return self._tree.mass_matrix(nodes), self._tree.generalized_forces(nodes) - tau

    def _factored(self, t, q, qd, p, u):
        """(node records, the node-order factor of M, q̈); MassMatrixError when M is not
        positive definite."""
        nodes = self._nodes(t, q, qd, p, u)
        M = self._tree.mass_matrix(nodes)
        L = self._tree.factor(M)
        if L is None:
            raise MassMatrixError.at(self.name, t, q)
        watch_pivots(self, np.diagonal(L) ** 2, np.diagonal(M))
        Q = self._tree.generalized_forces(nodes)
        qdd = self._tree.solve(L, Q - self._inverse(nodes, qd, np.zeros(self.n_coordinates)))
        return nodes, L, qdd

    def _b(self, t, q, qd, a, p, u, nodes=None):
        if nodes is None:
            nodes = self._nodes(t, q, qd, p, u)
        _, dQ, dQd = self._kernel("tree_slopes", t, q, qd, list(a), p, u)
        return self._tree.b(nodes, np.asarray(qd, dtype=float), np.asarray(a, dtype=float),
                            dQ, dQd)

    def _solve(self, factored, X):
        """M⁻¹·X (rows in coordinate order) with the factor of `_factored`'s result."""
        return self._tree.solve(factored[1], X)

    def _jacobian(self, t, q, qd, p, u):
        n = self.n_coordinates
        factored = self._factored(t, q, qd, p, u)
        nodes, _, qdd = factored[:3]
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:] = self._solve(factored, self._b(t, q, qd, qdd, p, u, nodes))
        return J

    def _residual_hessian(self, t, q, qd, a, mu, p, u):
        """∇²_z(Σ mu_i·r_i) = the recursion's second derivatives of τ minus those of the
        generalized forces Q (the kernel tree_q_hessian)."""
        n = self.n_coordinates
        size = self.dimensions["n_point"]
        nodes = self._nodes(t, q, qd, p, u)
        H = self._tree.hessian(nodes, np.asarray(qd, dtype=float), np.asarray(a[:n], dtype=float),
                               np.asarray(mu[:n], dtype=float), size)
        HQ, = self._kernels["tree_q_hessian"](t, q, qd, a, p, u, mu)
        for (r, c), value in zip(self._tree.qh, HQ):
            H[r, c] -= value
            if r != c:
                H[c, r] -= value
        return H

    def _parameter_b(self, t, q, qd, a, p, u, nodes=None):
        """P = ∂Q/∂p − ∂τ/∂p (n × n_params) at q̈ = a, by tangent sweeps."""
        n, k = self.n_coordinates, len(self.parameters)
        if nodes is None:
            nodes = self._nodes(t, q, qd, p, u)
        dv, dQ = self._kernel("tree_parameters", t, q, qd, list(a), p, u)
        P = np.zeros((n, k))
        if len(dQ):
            P[self._tree.dQp[:, 0], self._tree.dQp[:, 1]] = dQ
        dnodes = self._tree.parameter_records(dv, k, nodes.shape[1])
        a = np.asarray(a, dtype=float)
        for j in range(k):
            if np.any(dnodes[j]):
                P[:, j] -= self._tree.tangent(nodes, dnodes[j], np.asarray(qd, dtype=float), a)
        return P

    def _parameter_jacobian(self, t, q, qd, p, u):
        n, k = self.n_coordinates, len(self.parameters)
        out = np.zeros((2 * n, k))
        if not k:
            return out
        factored = self._factored(t, q, qd, p, u)
        nodes, _, qdd = factored[:3]
        out[n:] = self._solve(factored, self._parameter_b(t, q, qd, qdd, p, u, nodes))
        return out

    def _directional_derivatives(self, t, q, qd, p, u, dy, dp):
        n = self.n_coordinates
        factored = self._factored(t, q, qd, p, u)
        nodes, _, qdd = factored[:3]
        R = self._b(t, q, qd, qdd, p, u, nodes) @ np.asarray(dy, dtype=float).T
        if len(self.parameters) and np.any(dp):
            R += self._parameter_b(t, q, qd, qdd, p, u, nodes) @ np.asarray(dp, dtype=float).T
        out = np.empty((len(dy), 2 * n))
        out[:, :n] = np.asarray(dy)[:, n:]
        out[:, n:] = self._solve(factored, R).T
        return np.concatenate([np.array(qd, dtype=np.float64), qdd]), out
