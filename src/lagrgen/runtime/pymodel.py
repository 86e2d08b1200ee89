"""The pure-Python backend: the same kernels as the C path, printed as Python and run with NumPy.

Scalars go through `math` on Python floats (faster than NumPy for single values); q̈ comes from
NumPy's solve. This is the honest baseline the compiled path is measured against. Its methods come
from the same registry as the compiled ones (`lagrgen.functions`): each has one implementation
below, `_<name>(t, q, qd, p, u)` (`_<name>(t, q, qd, a, p, u)` for the implicit form), and is
called with the arguments of its call style.
"""
import math
import threading

import numpy as np

from ..errors import ConstraintError, LagrgenError, MassMatrixError, NonFiniteError
from ..functions import FUNCTIONS
from . import dual
from .arguments import (as_vector, defaults_array, initial_state_array, input_vector,
                        link_index, link_not_finite, link_point, parameter_vector)
from .describe import describe
from .info import INFO_ATTRIBUTES

#: A Cholesky pivot below this fraction of its diagonal entry of M counts as zero (LG_PIVOT_TOL in C).
PIVOT_TOL = 1e-14
_FUNCTIONS = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
              "asinh", "acosh", "atanh", "exp", "log", "sqrt")
_NUMPY_NAMES = {"asin": "arcsin", "acos": "arccos", "atan": "arctan", "atan2": "arctan2",
                "asinh": "arcsinh", "acosh": "arccosh", "atanh": "arctanh"}
#: Fast evaluation on Python floats.
_NAMESPACE = {name: getattr(math, name) for name in _FUNCTIONS}
_NAMESPACE["_sign"] = lambda x: float(x > 0) - float(x < 0)
_NAMESPACE["_nan"] = math.nan
#: IEEE evaluation on NumPy scalars (sqrt(−1) = nan, 1/0 = inf), as the C code computes, for the
#: points where Python's float arithmetic raises instead.
_IEEE_NAMESPACE = {name: getattr(np, _NUMPY_NAMES.get(name, name)) for name in _FUNCTIONS}
_IEEE_NAMESPACE["_sign"] = np.sign
_IEEE_NAMESPACE["abs"] = np.abs
_IEEE_NAMESPACE["_nan"] = np.nan
#: A relative pivot of M below this is noted for `pivot_record` (LG_PIVOT_NOTE in C).
PIVOT_NOTE = 1e-3
#: Per thread, {id(model): the least relative pivot of M below PIVOT_NOTE its factorizations
#: reached} (the C module's thread-local lg_least_pivot).
_PIVOTS = threading.local()


def watch_pivots(model, pivots, diagonal):
    """Note min(pivots/diagonal) of one factorization of M of `model` on this thread when it
    is below PIVOT_NOTE."""
    with np.errstate(all="ignore"):
        least = float(np.min(np.asarray(pivots) / np.asarray(diagonal), initial=1.0))
    if not least < PIVOT_NOTE:
        return
    record = getattr(_PIVOTS, "least", None)
    if record is None:
        record = _PIVOTS.least = {}
    if least < record.get(id(model), 1.0):
        record[id(model)] = least


class PythonModel:
    """A built model evaluated in Python (`BuiltModel`); `lagrgen.build(model, backend="python")`.

    Parameters
    ----------
    info : lagrgen.runtime.info.ModelInfo
        What the model says about itself (names, defaults, sizes, flags).
    source : str
        Python source of the kernels (`lagrgen.codegen.python_module.python_source`).
    """

    backend = "python"

    def __init__(self, info, source):
        self.info = info
        for name in INFO_ATTRIBUTES:
            setattr(self, name, getattr(info, name))
        self.defaults = defaults_array(info.defaults)
        self.initial_state = initial_state_array(info)
        self.build_info = {}
        self.source = source
        code = compile(source, f"<lagrgen python backend: {self.name}>", "exec")
        self._kernels, self._ieee_kernels = dict(_NAMESPACE), dict(_IEEE_NAMESPACE)
        self._dual_kernels = dict(dual.NAMESPACE)
        exec(code, self._kernels)
        exec(code, self._ieee_kernels)
        exec(code, self._dual_kernels)
        for spec in FUNCTIONS:
            setattr(self, spec.name, _CALLERS[spec.call](self, getattr(self, f"_{spec.name}")))

    def __repr__(self):
        return describe(self)

    def _arguments(self, p, u):
        """p and u as lists of floats: arrays already in order (what `simulate` passes) take the
        short path of one finiteness check; anything else goes through `runtime.arguments`."""
        p_list = _finite_list(p, len(self.parameters))
        if p_list is None:
            p_list = parameter_vector(p, self.parameters, self.defaults).tolist()
        u_list = _finite_list(u, len(self.inputs))
        if u_list is None:
            u_list = input_vector(u, self.inputs).tolist()
        return p_list, u_list

    def _factor(self, M, t, q):
        """Cholesky factor of the n×n matrix M, or MassMatrixError naming the state: also when M
        is not finite, or a pivot is below PIVOT_TOL times its diagonal entry (numerically
        singular, e.g. a 3-D body at gimbal lock), as in C."""
        if not np.isfinite(M).all():
            if np.isfinite(q).all() and np.isfinite(t):
                raise NonFiniteError.in_mass_matrix(self.name, t, q)
            raise MassMatrixError.at(self.name, t, q)
        try:
            L = np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            raise MassMatrixError.at(self.name, t, q) from None
        if np.any(np.diagonal(L) ** 2 <= PIVOT_TOL * np.diagonal(M)):
            raise MassMatrixError.at(self.name, t, q)
        watch_pivots(self, np.diagonal(L) ** 2, np.diagonal(M))
        return L

    def pivot_record(self):
        """The least pivot of M relative to its diagonal entry that this model's factorizations
        of M on this thread reached since the previous call (1.0 when none fell below
        PIVOT_NOTE = 1e-3); resets it."""
        record = getattr(_PIVOTS, "least", None)
        return 1.0 if record is None else record.pop(id(self), 1.0)

    def _kernel(self, name, t, q, qd, a, p, u):
        """The outputs of kernel `name` as float64 arrays, in IEEE arithmetic like the C code."""
        try:
            outputs = self._kernels[name](t, q, qd, a, p, u)
        except (ValueError, ZeroDivisionError, OverflowError):
            scalars = [None if v is None else [np.float64(x) for x in v] for v in (q, qd, a, p, u)]
            with np.errstate(all="ignore"):
                outputs = self._ieee_kernels[name](np.float64(t), *scalars)
        return [np.array(out, dtype=np.float64) for out in outputs]

    def _mf(self, t, q, qd, p, u):
        """M (n×n) and F (n) at a point."""
        n = self.n_coordinates
        M, F = self._kernel("mf", t, q, qd, None, p, u)
        return M.reshape(n, n), F

    def _b(self, t, q, qd, a, p, u):
        """B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇], an (n, 2n) array."""
        n = self.n_coordinates
        return self._kernel("jacobian_b", t, q, qd, a, p, u)[0].reshape(n, 2 * n)

    def _parameter_b(self, t, q, qd, a, p, u):
        """P = ∂F/∂p − ∂(M·a)/∂p at a given a, an (n, n_params) array."""
        n = self.n_coordinates
        return self._kernel("parameter_b", t, q, qd, a, p, u)[0].reshape(n, len(self.parameters))

    def _solved(self, t, q, qd, p, u):
        """(M, q̈ = M⁻¹F) after checking M is positive definite."""
        M, F = self._mf(t, q, qd, p, u)
        self._factor(M, t, q)
        return M, np.linalg.solve(M, F)

    def _constrained(self, t, q, qd, p, u, M, a):
        """(q̈, λ, A, W, S) of M·q̈ = F + Aᵀλ, A·q̈ = γ from the free q̈ = a = M⁻¹F: λ solves
        S·λ = γ − A·a with S = A·M⁻¹·Aᵀ, W = M⁻¹·Aᵀ, and q̈ = a + W·λ (as the C code)."""
        n, m = self.n_coordinates, self.n_constraints
        A, gamma = self._kernel("constraints", t, q, qd, None, p, u)
        A = A.reshape(m, n)
        W = np.linalg.solve(M, A.T)
        S = A @ W
        try:
            L = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            L = None
        if L is None or not np.all(np.diag(L) ** 2 > 1e-12 * np.diag(S)):
            raise ConstraintError.at(self.name, t, list(q) + list(qd), n)
        lam = np.linalg.solve(S, gamma - A @ a)
        return a + W @ lam, lam, A, W, S

    # -- one implementation per entry of lagrgen.functions.FUNCTIONS --------------------------
    def _mass_matrix(self, t, q, qd, p, u):
        return self._mf(t, q, [0.0] * self.n_coordinates, p, u)[0]

    def _forcing(self, t, q, qd, p, u):
        return self._mf(t, q, qd, p, u)[1]

    def _rhs(self, t, q, qd, p, u):
        M, a = self._solved(t, q, qd, p, u)
        if self.n_constraints:
            a = self._constrained(t, q, qd, p, u, M, a)[0]
        return np.concatenate([np.array(qd, dtype=np.float64), a])

    def _jacobian(self, t, q, qd, p, u):
        n = self.n_coordinates
        M, a = self._solved(t, q, qd, p, u)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        if not self.n_constraints:
            J[n:] = np.linalg.solve(M, self._b(t, q, qd, a.tolist(), p, u))
            return J
        # [M −Aᵀ; A 0]·[δa; δλ] = [B + H·δq; G]: δλ = S⁻¹(G − A·M⁻¹R1), δa = M⁻¹R1 + W·δλ
        a, lam, A, W, S = self._constrained(t, q, qd, p, u, M, a)
        al = a.tolist() + lam.tolist()
        R1 = self._b(t, q, qd, al, p, u)
        H, G = self._kernel("constraint_jacobian", t, q, qd, al, p, u)
        R1[:, :n] += H.reshape(n, n)
        X = np.linalg.solve(M, R1)
        dlam = np.linalg.solve(S, G.reshape(-1, 2 * n) - A @ X)
        J[n:] = X + W @ dlam
        return J

    def _parameter_jacobian(self, t, q, qd, p, u):
        n, k = self.n_coordinates, len(self.parameters)
        M, a = self._solved(t, q, qd, p, u)
        out = np.zeros((2 * n, k))
        if not k:
            return out
        if not self.n_constraints:
            out[n:] = np.linalg.solve(M, self._parameter_b(t, q, qd, a.tolist(), p, u))
            return out
        # [M −Aᵀ; A 0]·[δa; δλ] = [P + Hp; Gp]: δλ = S⁻¹(Gp − A·M⁻¹R1), δa = M⁻¹R1 + W·δλ
        a, lam, A, W, S = self._constrained(t, q, qd, p, u, M, a)
        al = a.tolist() + lam.tolist()
        R1 = self._parameter_b(t, q, qd, al, p, u)
        Hp, Gp = self._kernel("constraint_parameter_jacobian", t, q, qd, al, p, u)
        X = np.linalg.solve(M, R1 + Hp.reshape(n, k))
        out[n:] = X + W @ np.linalg.solve(S, Gp.reshape(-1, k) - A @ X)
        return out

    def _directional_derivatives(self, t, q, qd, p, u, dy, dp):
        n, m = self.n_coordinates, self.n_constraints
        M, F, A, gamma, c = self._kernel("motion_tape", t, q, qd, None, p, u)
        M = M.reshape(n, n)
        self._factor(M, t, q)
        a = np.linalg.solve(M, F)
        al = a
        if m:
            a, lam, A, W, S = self._constrained(t, q, qd, p, u, M, a)
            al = np.concatenate([a, lam])
        tangent, c, al = self._kernels["motion_tangent"], c.tolist(), al.tolist()
        out = np.empty((len(dy), 2 * n))
        for s, (d, dps) in enumerate(zip(dy, dp)):
            dR, dG = (np.array(v, dtype=np.float64)
                      for v in tangent(c, al, d[:n].tolist(), d[n:].tolist(), dps.tolist()))
            X = np.linalg.solve(M, dR)
            if m:
                X += W @ np.linalg.solve(S, dG - A @ X)
            out[s, :n], out[s, n:] = d[n:], X
        return np.concatenate([np.array(qd, dtype=np.float64), a]), out

    def _events(self, t, q, qd, p, u):
        if not self.event_definitions:
            return np.zeros(0)
        return self._kernel("events", t, q, qd, None, p, u)[0]

    def _hybrid_terms(self, t, q, qd, p, u):
        n, m = self.n_coordinates, self.n_constraints
        M, F = self._mf(t, q, qd, p, u)
        A, gamma = (self._kernel("constraints", t, q, qd, None, p, u) if m
                    else (np.zeros(0), np.zeros(0)))
        terms = (self._kernel("nonsmooth", t, q, qd, None, p, u)[0]
                 if self.dimensions.get("n_hybrid", 0) else np.zeros(0))
        return M, F, A.reshape(m, n), gamma, terms

    def _constraint_forces(self, t, q, qd, p, u):
        if not self.n_constraints:
            return np.zeros(0)
        M, a = self._solved(t, q, qd, p, u)
        return self._constrained(t, q, qd, p, u, M, a)[1]

    def _constraint_residuals(self, t, q, qd, p, u):
        if not self.n_constraints:
            return np.zeros(0)
        return self._kernel("constraint_residuals", t, q, qd, None, p, u)[0]

    def _constraint_residual_jacobian(self, t, q, qd, p, u):
        n_res = self.dimensions["n_residuals"]
        if not self.n_constraints:
            return np.zeros((0, 2 * self.n_coordinates))
        return self._kernel("constraint_residual_jacobian", t, q, qd, None, p, u)[0].reshape(
            n_res, 2 * self.n_coordinates)

    def _constraint_terms(self, t, q, qd, p, u):
        n, m = self.n_coordinates, self.n_constraints
        if not m:
            return np.zeros((0, n)), np.zeros(0), np.zeros((n, n))
        M, a = self._solved(t, q, qd, p, u)
        a, lam, A, _, _ = self._constrained(t, q, qd, p, u, M, a)
        H = self._kernel("constraint_jacobian", t, q, qd, a.tolist() + lam.tolist(), p, u)[0]
        return A, lam, H.reshape(n, n)

    def _linear_terms(self, t, q, qd, p, u):
        n, k = self.n_coordinates, len(self.inputs)
        M, _ = self._mf(t, q, qd, p, u)
        B = self._b(t, q, qd, [0.0] * n, p, u)
        dF_du = self._kernel("dF_du", t, q, qd, None, p, u)[0].reshape(n, k)
        return M, B[:, :n].copy(), B[:, n:].copy(), dF_du

    def _residual_terms(self, t, q, qd, a, p, u):
        n, m, k = self.n_coordinates, self.n_constraints, len(self.inputs)
        M, F = self._mf(t, q, qd, p, u)
        acc = np.array(a[:n])
        r = np.zeros(n + m)
        r[:n] = M @ acc - F
        dr_dy = np.zeros((n + m, 2 * n))
        dr_dy[:n] = -self._b(t, q, qd, a, p, u)
        dr_da = np.zeros((n + m, n + m))
        dr_da[:n, :n] = M
        dr_du = np.zeros((n + m, k))
        dr_du[:n] = -self._kernel("dF_du", t, q, qd, None, p, u)[0].reshape(n, k)
        if m:
            A, gamma = self._kernel("constraints", t, q, qd, None, p, u)
            A = A.reshape(m, n)
            H, G = self._kernel("constraint_jacobian", t, q, qd, a, p, u)
            r[:n] -= A.T @ np.array(a[n:])
            r[n:] = A @ acc - gamma
            dr_dy[:n, :n] -= H.reshape(n, n)
            dr_dy[n:] = -G.reshape(m, 2 * n)
            dr_da[:n, n:] = -A.T
            dr_da[n:, :n] = A
        return r, dr_dy, dr_da, dr_du

    def _residual_hessian(self, t, q, qd, a, mu, p, u):
        """∇²_z(Σ mu_i·r_i): the gradient of Σ mu_i·r_i from the first-derivative kernels (as
        `_residual_terms` assembles them) evaluated on duals seeded with z = [q, q̇, a, u]."""
        n, m, k = self.n_coordinates, self.n_constraints, len(self.inputs)
        if "jacobian_b" not in self._dual_kernels:
            raise LagrgenError(
                f"the Python backend of model {self.name!r} ({self.formulation} formulation) "
                "has no residual Hessian: its first derivatives come from a recursion, not from "
                "kernels it could differentiate; build it with the C backend "
                "(lagrgen.build(model)), whose Hessian is symbolic")
        z = dual.seeded(list(q) + list(qd) + list(a) + list(u))
        dq, dqd, da, du = z[:n], z[n:2 * n], z[2 * n:3 * n + m], z[3 * n + m:]
        kernels = self._dual_kernels
        M, F = kernels["mf"](t, dq, dqd, None, p, du)
        B, = kernels["jacobian_b"](t, dq, dqd, da, p, du)
        Fu, = kernels["dF_du"](t, dq, dqd, None, p, du)
        w, nu = mu[:n], mu[n:]
        g = [0.0] * len(z)
        for i in range(n):
            if not w[i]:
                continue
            for j in range(2 * n):
                g[j] -= w[i] * B[i * 2 * n + j]
            for j in range(n):
                g[2 * n + j] += w[i] * M[i * n + j]
            for c in range(k):
                g[3 * n + m + c] -= w[i] * Fu[i * k + c]
        if m:
            A, _ = kernels["constraints"](t, dq, dqd, None, p, du)
            H, G = kernels["constraint_jacobian"](t, dq, dqd, da, p, du)
            for i in range(n):
                for j in range(n):
                    g[j] -= w[i] * H[i * n + j]
                for c in range(m):
                    g[2 * n + n + c] -= w[i] * A[c * n + i]
            for c in range(m):
                for j in range(2 * n):
                    g[j] -= nu[c] * G[c * 2 * n + j]
                for j in range(n):
                    g[2 * n + j] += nu[c] * A[c * n + j]
        return np.array([dual.gradient(x, len(z)) for x in g])

    def _residual_parameter_jacobian(self, t, q, qd, a, p, u):
        n, m, k = self.n_coordinates, self.n_constraints, len(self.parameters)
        out = np.zeros((n + m, k))
        if not k:
            return out
        out[:n] = -self._parameter_b(t, q, qd, a, p, u)
        if m:
            Hp, Gp = self._kernel("constraint_parameter_jacobian", t, q, qd, a, p, u)
            out[:n] -= Hp.reshape(n, k)
            out[n:] = -Gp.reshape(m, k)
        return out

    def _regressor(self, t, q, qd, a, p, u):
        """Y = ∂(M·q̈ − F)/∂π: minus P's columns of the inertial parameters at q̈ = a."""
        n = self.n_coordinates
        index = [self.parameters.index(name) for name in self.inertial_parameters]
        if not index:
            return np.zeros((n, 0))
        return -self._parameter_b(t, q, qd, list(a[:n]), p, u)[:, index]

    def _link_frames(self, link, q, point, p):
        """(x = p + R·point, R, the link's index, the nodes' twists) of a link (an index of
        `link_names`)."""
        poses, twists = self._kernel("link_frames", 0.0, q, [0.0] * len(q), None, p,
                                     [0.0] * len(self.inputs))
        pose = poses.reshape(-1, 12)[link]
        R = pose[:9].reshape(3, 3)
        return pose[9:] + R @ point, R, twists.reshape(-1, 6)

    def _link_pose(self, link, q, point, p):
        x, R, _ = self._link_frames(link, q, point, p)
        return x, R

    def _link_jacobian(self, link, q, point, p):
        """The columns [v_i + ω_i × x; ω_i] of the twists [ω_i; v_i] of the nodes at and above
        the link's, summed per coordinate."""
        x, _, twists = self._link_frames(link, q, point, p)
        tables = self._kernels["LINKS"]
        J = np.zeros((6, self.n_coordinates))
        i = tables["node"][link]
        while i >= 0:
            w, v = twists[i, :3], twists[i, 3:]
            J[:3, tables["coordinate"][i]] += v + np.cross(w, x)
            J[3:, tables["coordinate"][i]] += w
            i = tables["parent"][i]
        return J

    def _outputs(self, t, q, qd, p, u):
        return self._kernel("outputs", t, q, qd, None, p, u)[0]

    def _power_terms(self, t, q, qd, p, u):
        return self._kernel("outputs", t, q, qd, None, p, u)[1]


def _finite_list(values, size):
    """`values` as a list when it is a 1-D float64 array of `size` finite numbers, else None."""
    if type(values) is not np.ndarray or values.dtype != np.float64 or values.shape != (size,):
        return None
    out = values.tolist()
    return out if all(map(math.isfinite, out)) else None


def _state_caller(model, impl):
    n = model.n_coordinates

    def call(t, y, p=None, u=None):
        y = as_vector(y, 2 * n, "y")
        return impl(float(t), y[:n].tolist(), y[n:].tolist(), *model._arguments(p, u))
    call.__doc__ = impl.__doc__
    return call


def _coordinate_caller(model, impl):
    n = model.n_coordinates

    def call(q, t=0.0, p=None, u=None):
        return impl(float(t), as_vector(q, n, "q").tolist(), [0.0] * n, *model._arguments(p, u))
    return call


def _state_arguments_caller(model, impl):
    n = model.n_coordinates

    def call(q, qd, t=0.0, p=None, u=None):
        return impl(float(t), as_vector(q, n, "q").tolist(), as_vector(qd, n, "qd").tolist(),
                    *model._arguments(p, u))
    return call


def _directions_caller(model, impl):
    n, n_params = model.n_coordinates, len(model.parameters)

    def call(t, y, dy, dp=None, p=None, u=None):
        y = as_vector(y, 2 * n, "y")
        directions = np.asarray(dy, dtype=np.float64)
        if directions.ndim not in (1, 2) or directions.shape[-1] != 2 * n:
            raise ValueError(f"dy must have shape ({2 * n},) or (k, {2 * n}), got "
                             f"{directions.shape}")
        single, directions = directions.ndim == 1, directions.reshape(-1, 2 * n)
        k = len(directions)
        if dp is None:
            dp = np.zeros((k, n_params))
        dp = np.asarray(dp, dtype=np.float64)
        if dp.shape not in ((k, n_params), (n_params,) if single else None):
            raise ValueError(f"dp must have shape ({n_params},) or ({k}, {n_params}) to match "
                             f"dy, got {dp.shape}")
        dp = dp.reshape(k, n_params)
        if not (np.isfinite(directions).all() and np.isfinite(dp).all()):
            raise ValueError("dy and dp must be finite")
        ydot, out = impl(float(t), y[:n].tolist(), y[n:].tolist(), *model._arguments(p, u),
                         directions, dp)
        return ydot, (out[0] if single else out)
    return call


def _implicit_caller(model, impl):
    n, m = model.n_coordinates, model.n_constraints

    def call(q, qd, a, t=0.0, p=None, u=None):
        return impl(float(t), as_vector(q, n, "q").tolist(), as_vector(qd, n, "qd").tolist(),
                    as_vector(a, n + m, "a (the accelerations, then the constraint "
                              "multipliers)").tolist(), *model._arguments(p, u))
    return call


def _link_caller(model, impl):
    n = model.n_coordinates

    def call(link, q, point=(0, 0, 0), p=None):
        index = link_index(model.name, model.link_names, link)
        point = link_point(point)
        p_list = model._arguments(p, None)[0]
        out = impl(index, as_vector(q, n, "q").tolist(), point, p_list)
        if not all(np.isfinite(x).all() for x in (out if isinstance(out, tuple) else (out,))):
            raise ValueError(link_not_finite(model.name, impl.__name__.removeprefix("_"), link))
        return out
    call.__doc__ = impl.__doc__
    return call


def _weighted_caller(model, impl):
    n, m = model.n_coordinates, model.n_constraints

    def call(q, qd, a, mu, t=0.0, p=None, u=None):
        return impl(float(t), as_vector(q, n, "q").tolist(), as_vector(qd, n, "qd").tolist(),
                    as_vector(a, n + m, "a (the accelerations, then the constraint "
                              "multipliers)").tolist(),
                    as_vector(mu, n + m, "mu (a weight per row of the residual)").tolist(),
                    *model._arguments(p, u))
    return call


_CALLERS = {"state": _state_caller, "q": _coordinate_caller, "q_qd": _state_arguments_caller,
            "directions": _directions_caller, "implicit": _implicit_caller,
            "weighted": _weighted_caller, "link": _link_caller}
