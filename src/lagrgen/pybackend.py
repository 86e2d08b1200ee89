"""The pure-Python backend: the same kernels as the C path, printed as Python and run with NumPy.

Scalars go through `math` on Python floats (faster than NumPy for single values); q̈ comes from
NumPy's solve. This is the honest baseline the compiled path is measured against.
"""
import math

import numpy as np

from .arguments import as_vector, defaults_array, input_vector, parameter_vector
from .errors import MassMatrixError

#: A Cholesky pivot below this fraction of its diagonal entry of M counts as zero (LG_PIVOT_TOL in C).
PIVOT_TOL = 1e-14
from .kernels import all_kernels
from .printer import PythonPrinter, kernel_statements, print_statements

_NAMESPACE = {name: getattr(math, name) for name in (
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh",
    "acosh", "atanh", "exp", "log", "sqrt")}
_NAMESPACE["_sign"] = lambda x: (x > 0) - (x < 0)


def python_source(kernels):
    """Python source of one function per kernel, `name(t, q, qd, a, p, u)` -> its outputs."""
    printer = PythonPrinter()
    chunks = []
    for kernel in kernels:
        lines = [f"def {kernel.name}(t, q, qd, a, p, u):"]
        lines += [f"    {name} = [0.0] * {len(exprs)}" for name, exprs in kernel.outputs.items()]
        body = print_statements(printer, kernel_statements(kernel))
        if body:
            lines.append(body)
        lines.append(f"    return {', '.join(kernel.outputs)},")
        chunks.append("\n".join(lines))
    return "\n\n\n".join(chunks) + "\n"


class PythonModel:
    """A built model evaluated in Python (API.md §3); `lagrgen.build(model, backend="python")`."""

    backend = "python"

    def __init__(self, equations, metadata):
        meta = metadata
        self.name = meta["name"]
        self.coordinates = tuple(meta["coordinates"])
        self.parameters = tuple(meta["parameters"])
        self.inputs = tuple(meta["inputs"])
        self.defaults = defaults_array(meta["defaults"])
        self.content_hash = meta["content_hash"]
        self.n_coordinates = n = equations.n
        self.source = python_source(all_kernels(equations))
        namespace = dict(_NAMESPACE)
        exec(compile(self.source, f"<lagrgen python backend: {self.name}>", "exec"), namespace)
        self._kernels = namespace

    def __repr__(self):
        return f"<lagrgen model {self.name!r} (python backend), coordinates {self.coordinates}>"

    def _args(self, p, u):
        return (parameter_vector(p, self.parameters, self.defaults).tolist(),
                input_vector(u, self.inputs).tolist())

    def _factor(self, M, t, q):
        """Cholesky factor of the n×n matrix M, or MassMatrixError naming the state (also when a
        pivot is below PIVOT_TOL times its diagonal entry: numerically singular, as in C)."""
        try:
            L = np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            raise MassMatrixError.at(self.name, t, q) from None
        if np.any(np.diagonal(L) ** 2 <= PIVOT_TOL * np.diagonal(M)):
            raise MassMatrixError.at(self.name, t, q)
        return L

    def _mf(self, t, q, qd, p, u):
        """M (n×n array) and F (n array) at a point; q, qd, p, u as lists."""
        n = self.n_coordinates
        M, F = self._kernels["mf"](t, q, qd, None, p, u)
        return np.array(M).reshape(n, n), np.array(F)

    def _b(self, t, q, qd, a, p, u):
        """B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇], an (n, 2n) array."""
        n = self.n_coordinates
        return np.array(self._kernels["jacobian_b"](t, q, qd, a, p, u)[0]).reshape(n, 2 * n)

    def mass_matrix(self, q, t=0.0, p=None, u=None):
        """M(q, t), an (n, n) float64 array."""
        n = self.n_coordinates
        q = as_vector(q, n, "q").tolist()
        p, u = self._args(p, u)
        return self._mf(float(t), q, [0.0] * n, p, u)[0]

    def forcing(self, q, qd, t=0.0, p=None, u=None):
        """F(q, q̇, t, u), an (n,) float64 array with M·q̈ = F."""
        n = self.n_coordinates
        q, qd = as_vector(q, n, "q").tolist(), as_vector(qd, n, "qd").tolist()
        p, u = self._args(p, u)
        return self._mf(float(t), q, qd, p, u)[1]

    def _factored_point(self, t, y, p, u):
        """(q, qd, p, u as lists, M, F) at the state y, after checking M is positive definite."""
        n = self.n_coordinates
        y = as_vector(y, 2 * n, "y")
        q, qd = y[:n].tolist(), y[n:].tolist()
        p, u = self._args(p, u)
        M, F = self._mf(t, q, qd, p, u)
        self._factor(M, t, q)
        return q, qd, p, u, M, F

    def rhs(self, t, y, p=None, u=None):
        """ẏ = [q̇, M⁻¹F] for y = [q, q̇], a (2n,) float64 array."""
        n = self.n_coordinates
        q, qd, p, u, M, F = self._factored_point(t, y, p, u)
        out = np.empty(2 * n)
        out[:n] = qd
        out[n:] = np.linalg.solve(M, F)
        return out

    def jacobian(self, t, y, p=None, u=None):
        """∂ẏ/∂y = [[0, I], [M⁻¹(∂F/∂q − ∂(M·q̈)/∂q), M⁻¹·∂F/∂q̇]], a (2n, 2n) float64 array."""
        n = self.n_coordinates
        q, qd, p, u, M, F = self._factored_point(t, y, p, u)
        a = np.linalg.solve(M, F).tolist()
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:] = np.linalg.solve(M, self._b(t, q, qd, a, p, u))
        return J

    def linear_terms(self, q, qd, t=0.0, p=None, u=None):
        """(M, ∂F/∂q, ∂F/∂q̇, ∂F/∂u) at a point, as float64 arrays (B at a = 0 gives the middle two)."""
        n, k = self.n_coordinates, len(self.inputs)
        q, qd = as_vector(q, n, "q").tolist(), as_vector(qd, n, "qd").tolist()
        p, u = self._args(p, u)
        M, _ = self._mf(float(t), q, qd, p, u)
        B = self._b(float(t), q, qd, [0.0] * n, p, u)
        dF_du = np.array(self._kernels["dF_du"](float(t), q, qd, None, p, u)[0]).reshape(n, k)
        return M, B[:, :n].copy(), B[:, n:].copy(), dF_du
