"""The pure-Python backend: the same kernels as the C path, printed as Python and run with NumPy.

Scalars go through `math` on Python floats (faster than NumPy for single values); q̈ comes from
NumPy's solve. This is the honest baseline the compiled path is measured against. Its methods come
from the same registry as the compiled ones (`lagrgen.functions`): each has one implementation
below, `_<name>(t, q, qd, p, u)`, and is called with the arguments of its call style.
"""
import math

import numpy as np

from ..errors import MassMatrixError
from ..functions import FUNCTIONS
from .arguments import as_vector, defaults_array, input_vector, parameter_vector

_NAMESPACE = {name: getattr(math, name) for name in (
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh",
    "acosh", "atanh", "exp", "log", "sqrt")}
_NAMESPACE["_sign"] = lambda x: float(x > 0) - float(x < 0)
_NAMESPACE["_nan"] = math.nan


class PythonModel:
    """A built model evaluated in Python (API.md §3); `lagrgen.build(model, backend="python")`.

    Parameters
    ----------
    info : dict
        name, coordinates, parameters, inputs, defaults, content_hash (as in the C metadata).
    n : int
        The number of coordinates.
    source : str
        Python source of the kernels (`lagrgen.codegen.python_module.python_source`).
    """

    backend = "python"

    def __init__(self, info, n, source):
        self.name = info["name"]
        self.coordinates = tuple(info["coordinates"])
        self.parameters = tuple(info["parameters"])
        self.inputs = tuple(info["inputs"])
        self.defaults = defaults_array(info["defaults"])
        self.content_hash = info["content_hash"]
        self.n_coordinates = n
        self.dimensions = dict(info["dimensions"])
        self.output_names = tuple(info["output_names"])
        self.units = dict(info["units"])
        self.explicit_time = bool(info["explicit_time"])
        self.source = source
        namespace = dict(_NAMESPACE)
        exec(compile(source, f"<lagrgen python backend: {self.name}>", "exec"), namespace)
        self._kernels = namespace
        for spec in FUNCTIONS:
            setattr(self, spec.name, _CALLERS[spec.call](self, getattr(self, f"_{spec.name}")))

    def __repr__(self):
        return f"<lagrgen model {self.name!r} (python backend), coordinates {self.coordinates}>"

    def _arguments(self, p, u):
        return (parameter_vector(p, self.parameters, self.defaults).tolist(),
                input_vector(u, self.inputs).tolist())

    def _factor(self, M, t, q):
        """Cholesky factor of the n×n matrix M, or MassMatrixError naming the state."""
        try:
            return np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            raise MassMatrixError.at(self.name, t, q) from None

    def _kernel(self, name, t, q, qd, a, p, u):
        """The outputs of kernel `name` as float64 arrays."""
        return [np.array(out, dtype=np.float64) for out in
                self._kernels[name](t, q, qd, a, p, u)]

    def _mf(self, t, q, qd, p, u):
        """M (n×n) and F (n) at a point."""
        n = self.n_coordinates
        M, F = self._kernel("mf", t, q, qd, None, p, u)
        return M.reshape(n, n), F

    def _b(self, t, q, qd, a, p, u):
        """B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇], an (n, 2n) array."""
        n = self.n_coordinates
        return self._kernel("jacobian_b", t, q, qd, a, p, u)[0].reshape(n, 2 * n)

    def _solved(self, t, q, qd, p, u):
        """(M, q̈ = M⁻¹F) after checking M is positive definite."""
        M, F = self._mf(t, q, qd, p, u)
        self._factor(M, t, q)
        return M, np.linalg.solve(M, F)

    # -- one implementation per entry of lagrgen.functions.FUNCTIONS --------------------------
    def _mass_matrix(self, t, q, qd, p, u):
        return self._mf(t, q, [0.0] * self.n_coordinates, p, u)[0]

    def _forcing(self, t, q, qd, p, u):
        return self._mf(t, q, qd, p, u)[1]

    def _rhs(self, t, q, qd, p, u):
        _, a = self._solved(t, q, qd, p, u)
        return np.concatenate([np.array(qd, dtype=np.float64), a])

    def _jacobian(self, t, q, qd, p, u):
        n = self.n_coordinates
        M, a = self._solved(t, q, qd, p, u)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:] = np.linalg.solve(M, self._b(t, q, qd, a.tolist(), p, u))
        return J

    def _linear_terms(self, t, q, qd, p, u):
        n, k = self.n_coordinates, len(self.inputs)
        M, _ = self._mf(t, q, qd, p, u)
        B = self._b(t, q, qd, [0.0] * n, p, u)
        dF_du = self._kernel("dF_du", t, q, qd, None, p, u)[0].reshape(n, k)
        return M, B[:, :n].copy(), B[:, n:].copy(), dF_du

    def _outputs(self, t, q, qd, p, u):
        return self._kernel("outputs", t, q, qd, None, p, u)[0]


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


_CALLERS = {"state": _state_caller, "q": _coordinate_caller, "q_qd": _state_arguments_caller}
