"""A free base in NumPy: the Python backend of a model whose tree's root is free (the chart and
the transformations of `lagrgen/codegen/templates/free_base.c.in`, the same arithmetic; see
`lagrgen.free_base` for the mathematics).

The chart at ζ maps c = (e_x, e_y, e_z, r) to ζ(c) = r·ζ̂ ⊗ h(e), h(e) = q_x(e_x)⊗q_y(e_y)⊗q_z(e_z);
at c = (0, |ζ|) its derivatives are quaternion products of ζ with those of h at 0:

    Dh[u] = (½u, 0),   D²h[u, v] = (¼·κ(u, v), −¼·u·v),
    D³h[u, v, w] = (−⅛·(u·(v·w) + v·(u·w) + w·(u·v)) + ¼·u∘v∘w, −⅛·Σ_σ u_σx·v_σy·w_σz),

κ(u, v) = (u_y·v_z + u_z·v_y, −(u_x·v_z + u_z·v_x), u_x·v_y + u_y·v_x), ∘ the entrywise product and
σ the permutations of (x, y, z); quaternions are (x, y, z, w), as the coordinates.
"""
import numpy as np

from ..errors import LagrgenError, MassMatrixError
from .tree3d import SpatialPythonModel, SpatialRecursion

#: The model's index of the quaternion's first component, and the chart's block (e, r) there.
BLOCK = slice(3, 7)
#: The free base's quaternion coordinates (`from_urdf(..., base="free")`).
QUATERNION = ("base_qx", "base_qy", "base_qz", "base_qw")


def check_quaternion(coordinates, states):
    """ValueError where a free base's quaternion is zero in a state (a column of `states`, 2n ×
    runs, or one state): a y0 dict leaves the entries it does not name 0, and the error was a
    MassMatrixError about masses and inertias."""
    if tuple(coordinates[3:7]) != QUATERNION:
        return
    zeta = np.reshape(np.asarray(states, dtype=float), (2 * len(coordinates), -1))[BLOCK]
    if np.any(np.all(zeta == 0.0, axis=0)):
        raise ValueError("the free base's orientation quaternion (base_qx, base_qy, base_qz, "
                         "base_qw) is zero in the initial state: a y0 dict leaves the entries it "
                         "does not name 0; give base_qw=1 for the upright pose, or build the "
                         "state with lagrgen.base_state(mod, position=..., rpy=...)")


def qmul(a, b):
    """a ⊗ b of quaternions (x, y, z, w)."""
    out = np.empty(4)
    out[:3] = a[3] * b[:3] + b[3] * a[:3] + np.cross(a[:3], b[:3])
    out[3] = a[3] * b[3] - a[:3] @ b[:3]
    return out


def dh(u):
    return np.concatenate([0.5 * np.asarray(u[:3]), [0.0]])


def d2h(u, v):
    kappa = np.array([u[1] * v[2] + u[2] * v[1], -(u[0] * v[2] + u[2] * v[0]),
                      u[0] * v[1] + u[1] * v[0]])
    return np.concatenate([0.25 * kappa, [-0.25 * (u[:3] @ v[:3])]])


def d3h(u, v, w):
    u, v, w = u[:3], v[:3], w[:3]
    vector = -0.125 * (u * (v @ w) + v * (u @ w) + w * (u @ v)) + 0.25 * u * v * w
    perm = (u[0] * (v[1] * w[2] + v[2] * w[1]) + u[1] * (v[0] * w[2] + v[2] * w[0])
            + u[2] * (v[0] * w[1] + v[1] * w[0]))
    return np.concatenate([vector, [-0.125 * perm]])


class Chart:
    """The chart of a free base at the quaternion ζ: D = ∂ζ/∂c (4×4), its inverse and the second
    and third derivatives D²Φ, D³Φ of c ↦ ζ(c) at c = (0, |ζ|)."""

    def __init__(self, z):
        self.z = np.asarray(z, dtype=float)
        self.r = np.sqrt(self.z @ self.z)
        self.unit = self.z / self.r
        self.D = np.column_stack([self.d1(e) for e in np.eye(4)])
        self.Dinv = np.linalg.inv(self.D)

    def d1(self, x):
        """DΦ·x = ζ ⊗ Dh[x_e] + x_r·ζ̂."""
        return qmul(self.z, dh(x)) + x[3] * self.unit

    def d2(self, x, y):
        """D²Φ[x, y] = ζ ⊗ D²h[x_e, y_e] + x_r·ζ̂ ⊗ Dh[y_e] + y_r·ζ̂ ⊗ Dh[x_e]."""
        return qmul(self.z, d2h(x, y)) + x[3] * qmul(self.unit, dh(y)) + \
            y[3] * qmul(self.unit, dh(x))

    def d3(self, x, y, w):
        """D³Φ[x, y, w] (∂²/∂r² = 0)."""
        return (qmul(self.z, d3h(x, y, w)) + x[3] * qmul(self.unit, d2h(y, w))
                + y[3] * qmul(self.unit, d2h(x, w)) + w[3] * qmul(self.unit, d2h(x, y)))

    def matrix(self, f):
        """The 4×4 matrix of the linear map f (columns: f of the unit vectors)."""
        return np.column_stack([f(e) for e in np.eye(4)])


class FreeBasePythonModel(SpatialPythonModel):
    """A `PythonModel` of the recursive formulation over a tree whose root is a free base: the
    recursion in the base's chart (n − 1 coordinates), its results taken to q."""

    def __init__(self, info, source):
        super().__init__(info, source)
        n = self.n_coordinates
        self._tree = SpatialRecursion(self._kernels["TREE"], n - 1)
        self._radial = self._kernels["TREE"]["free"]["radial"]
        self._chart_rows = np.r_[0:6, 7:n]    # the model's indices of the chart's coordinates

    def _residual_hessian(self, t, q, qd, a, mu, p, u):
        """Not on this backend: the chart's second derivatives are not carried to q here."""
        raise LagrgenError(
            f"the Python backend of model {self.name!r} (a free base) has no residual Hessian; "
            "build it with the C backend (lagrgen.build(model)), whose Hessian is symbolic")

    # -- the chart -------------------------------------------------------------------------------
    def _frame(self, q, qd):
        """(chart, ċ with r: n, the recursion's rates ċ: n − 1)."""
        chart = Chart(np.asarray(q, dtype=float)[BLOCK])
        cd = np.array(qd, dtype=float)
        cd[BLOCK] = chart.Dinv @ cd[BLOCK]
        return chart, cd, cd[self._chart_rows]

    def _accelerations(self, chart, cd, a):
        """(c̈ with r: n, the recursion's c̈: n − 1) at the model's q̈ = a:
        c̈ = D⁻¹·(a − D²Φ[ċ, ċ]) in the block."""
        a = np.asarray(a, dtype=float)[:self.n_coordinates]
        cdd = a.copy()
        cdd[BLOCK] = chart.Dinv @ (a[BLOCK] - chart.d2(cd[BLOCK], cd[BLOCK]))
        return cdd, cdd[self._chart_rows]

    def _extended(self, matrix_rows):
        """The recursion's n − 1 rows as the chart's n (r's row zero)."""
        out = np.zeros((self.n_coordinates,) + matrix_rows.shape[1:])
        out[self._chart_rows] = matrix_rows
        return out

    def _mass_extended(self, nodes):
        """M̃_c: the recursion's M with r's row and column (J on the diagonal)."""
        n = self.n_coordinates
        M = np.zeros((n, n))
        M[np.ix_(self._chart_rows, self._chart_rows)] = self._tree.mass_matrix(nodes)
        M[6, 6] = self._radial
        return M

    def _full(self, block):
        """The n×n identity with the 4×4 `block` at the quaternion."""
        out = np.eye(self.n_coordinates)
        out[BLOCK, BLOCK] = block
        return out

    # -- the model's functions -------------------------------------------------------------------
    def _outputs(self, t, q, qd, p, u):
        """tree_outputs' (½·J·ṙ² of ζ's length among its energies), with the bodies' T and V
        from the records at the chart's rates."""
        out = super(SpatialPythonModel, self)._outputs(t, q, qd, p, u)
        T, V = self._record_energies(self._nodes(t, q, qd, p, u), self._frame(q, qd)[2])
        out[-3:] += [T, V, T + V]
        return out

    def _mf(self, t, q, qd, p, u):
        nodes = self._nodes(t, q, qd, p, u)
        chart, cd, ce = self._frame(q, qd)
        tau = self._inverse(nodes, ce, np.zeros(len(ce)))
        F = self._extended(self._tree.generalized_forces(nodes) - tau)
        M = self._mass_extended(nodes)
        bias = np.zeros(self.n_coordinates)
        bias[BLOCK] = chart.Dinv @ chart.d2(cd[BLOCK], cd[BLOCK])
        Dinv = self._full(chart.Dinv)
        return Dinv.T @ M @ Dinv, Dinv.T @ (F + M @ bias)

    def _factored(self, t, q, qd, p, u):
        """(node records, the recursion's factor, q̈, chart, ċ, c̈ with r)."""
        nodes = self._nodes(t, q, qd, p, u)
        chart, cd, ce = self._frame(q, qd)
        L = self._tree.factor(self._tree.mass_matrix(nodes))
        if L is None:
            raise MassMatrixError.at(self.name, t, q)
        Q = self._tree.generalized_forces(nodes)
        cdd = np.zeros(self.n_coordinates)
        cdd[self._chart_rows] = self._tree.solve(
            L, Q - self._inverse(nodes, ce, np.zeros(len(ce))))
        qdd = cdd.copy()
        qdd[BLOCK] = chart.D @ cdd[BLOCK] + chart.d2(cd[BLOCK], cd[BLOCK])
        return nodes, L, qdd, chart, cd, cdd

    def _solve(self, factored, X):
        """M_q⁻¹·X = D·M̃_c⁻¹·Dᵀ·X (rows of X in coordinate order), with `_factored`'s result."""
        _, L, _, chart, _, _ = factored
        X = np.array(X, dtype=float)
        X[BLOCK] = chart.D.T @ X[BLOCK]
        X[self._chart_rows] = self._tree.solve(L, X[self._chart_rows])
        X[6] /= self._radial
        X[BLOCK] = chart.D @ X[BLOCK]
        return X

    def _b(self, t, q, qd, a, p, u, nodes=None):
        """B = ∂Q/∂y − ∂τ_q/∂y at q̈ = a (see the module docstring of lagrgen.free_base): with
        δc = D⁻¹·δq, δċ = D⁻¹·(δq̇ − D²Φ[ċ, δc]),
        −∂τ_q[δy] = D⁻ᵀ·(x·D²Φ[δc, ·] + B_c·[δc; δċ] + M̃_c·D⁻¹·(D²Φ[δc, c̈] + D³Φ[δc, ċ, ċ]
        + 2·D²Φ[ċ, δċ])), x = D⁻ᵀ·τ̃_c."""
        n = self.n_coordinates
        if nodes is None:
            nodes = self._nodes(t, q, qd, p, u)
        chart, cd, ce = self._frame(q, qd)
        cdd, ca = self._accelerations(chart, cd, a)
        rows = self._chart_rows
        Bc = np.zeros((n, 2 * n))
        Bc[np.ix_(rows, np.r_[rows, n + rows])] = self._tree.b(nodes, ce, ca, [], [])
        tau = self._extended(self._inverse(nodes, ce, ca))
        tau[6] = self._radial * cdd[6]
        M = self._mass_extended(nodes)
        x = chart.Dinv.T @ tau[BLOCK]
        cb, ab = cd[BLOCK], cdd[BLOCK]
        Dinv = self._full(chart.Dinv)
        K1 = chart.matrix(lambda e: chart.d2(cb, e))
        Tc = np.zeros((n, 2 * n))
        Tc[:, :n] = Dinv
        Tcd = np.zeros((n, 2 * n))
        Tcd[:, n:] = Dinv
        Tcd[BLOCK, 3:7] = -chart.Dinv @ K1 @ chart.Dinv
        inner = np.zeros((n, 2 * n))
        inner[BLOCK] = (chart.matrix(lambda e: chart.d2(e, ab) + chart.d3(e, cb, cb))
                        @ Tc[BLOCK] + 2 * K1 @ Tcd[BLOCK])
        hessian = np.zeros((n, n))
        hessian[BLOCK, BLOCK] = np.array([[x @ chart.d2(e, f) for e in np.eye(4)]
                                          for f in np.eye(4)])
        inside = hessian @ Tc + Bc @ np.vstack([Tc, Tcd]) + M @ (Dinv @ inner)
        B = Dinv.T @ inside
        _, dQ, dQd = self._kernel("tree_slopes", t, q, qd, list(a), p, u)
        if len(dQ):
            np.add.at(B, (self._tree.dq[:, 0], self._tree.dq[:, 1]), dQ)
        if len(dQd):
            np.add.at(B, (self._tree.dqd[:, 0], n + self._tree.dqd[:, 1]), dQd)
        return B

    def _parameter_b(self, t, q, qd, a, p, u, nodes=None):
        """P = ∂Q/∂p − D⁻ᵀ·∂τ̃_c/∂p at q̈ = a (tangent sweeps of the recursion)."""
        n, k = self.n_coordinates, len(self.parameters)
        if nodes is None:
            nodes = self._nodes(t, q, qd, p, u)
        chart, cd, ce = self._frame(q, qd)
        cdd, ca = self._accelerations(chart, cd, a)
        dv, dQ = self._kernel("tree_parameters", t, q, qd, list(a), p, u)
        dnodes = self._tree.parameter_records(dv, k, nodes.shape[1])
        Pc = np.zeros((n, k))
        for j in range(k):
            if np.any(dnodes[j]):
                Pc[self._chart_rows, j] = -self._tree.tangent(nodes, dnodes[j], ce, ca)
        P = self._full(chart.Dinv).T @ Pc
        if len(dQ):
            np.add.at(P, (self._tree.dQp[:, 0], self._tree.dQp[:, 1]), dQ)
        return P
