# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# cython: embedsignature=True, binding=False
"""The compiled half of every built model: argument checking, output arrays, errors, timing.

Compiled once when lagrgen is installed. A generated model module holds only its equations (C
functions behind an `lg_model_t` capsule) and calls `bind_module` when imported, which makes the
module itself the built model of API.md §3.
"""
import json
import time

import numpy as np
cimport cython
cimport numpy as cnp
from cpython.pycapsule cimport PyCapsule_GetPointer, PyCapsule_IsValid

from .arguments import defaults_array, input_vector, parameter_vector
from .errors import BuildError, MassMatrixError
from . import __version__

cnp.import_array()

cdef extern from "lagrgen_model.h":
    int LG_ABI_VERSION
    const char *LG_CAPSULE_NAME
    ctypedef struct lg_model_t:
        int abi_version
        int n
        int n_params
        int n_inputs
        const char *metadata
        void (*mass_matrix)(double, const double *, const double *, double *) noexcept nogil
        void (*forcing)(double, const double *, const double *, const double *, const double *,
                        double *) noexcept nogil
        int (*rhs)(double, const double *, const double *, const double *, double *) noexcept nogil
        int (*jacobian)(double, const double *, const double *, const double *,
                        double *) noexcept nogil
        void (*linear_terms)(double, const double *, const double *, const double *,
                             const double *, double *, double *, double *, double *) noexcept nogil

ABI_VERSION = LG_ABI_VERSION


cdef inline cnp.ndarray new_array(int nd, cnp.npy_intp *dims):
    return <cnp.ndarray>cnp.PyArray_EMPTY(nd, dims, cnp.NPY_DOUBLE, 0)


cdef inline cnp.ndarray as_f64(object obj, Py_ssize_t size, str what):
    """obj as a C-contiguous 1-D float64 array of length size (no copy when it already is one)."""
    cdef cnp.ndarray arr
    if type(obj) is cnp.ndarray:
        arr = <cnp.ndarray>obj
        if (cnp.PyArray_TYPE(arr) == cnp.NPY_DOUBLE and cnp.PyArray_NDIM(arr) == 1
                and cnp.PyArray_IS_C_CONTIGUOUS(arr) and cnp.PyArray_DIM(arr, 0) == size):
            return arr
    try:
        arr = np.ascontiguousarray(obj, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be an array of {size} numbers ({exc})") from None
    if cnp.PyArray_NDIM(arr) != 1 or cnp.PyArray_DIM(arr, 0) != size:
        raise ValueError(f"{what} must be a 1-D array of length {size}, got shape {np.shape(obj)}")
    return arr


cdef inline const double *data(cnp.ndarray arr):
    return <const double *>cnp.PyArray_DATA(arr)


@cython.final
cdef class CompiledModel:
    """A model's compiled equations, with the interface of API.md §3."""

    cdef const lg_model_t *model
    cdef readonly int n_coordinates
    cdef int n_params, n_inputs
    cdef readonly str name, content_hash, lagrgen_version
    cdef readonly tuple coordinates, parameters, inputs
    cdef readonly object defaults
    cdef cnp.ndarray _defaults, _zeros
    cdef bint _defaults_complete
    cdef readonly str backend
    cdef object _keep_p, _keep_u

    def __cinit__(self, capsule):
        if not PyCapsule_IsValid(capsule, LG_CAPSULE_NAME):
            raise TypeError("expected the capsule of a lagrgen model module")
        self.model = <const lg_model_t *>PyCapsule_GetPointer(capsule, LG_CAPSULE_NAME)
        if self.model.abi_version != LG_ABI_VERSION:
            raise BuildError(
                f"this model was compiled for lagrgen runtime ABI {self.model.abi_version}, "
                f"but the installed lagrgen uses {LG_ABI_VERSION}: rebuild it")
        meta = json.loads(self.model.metadata.decode("utf-8"))
        self.n_coordinates = self.model.n
        self.n_params = self.model.n_params
        self.n_inputs = self.model.n_inputs
        self.name = meta["name"]
        self.content_hash = meta["content_hash"]
        self.lagrgen_version = meta["lagrgen_version"]
        self.coordinates = tuple(meta["coordinates"])
        self.parameters = tuple(meta["parameters"])
        self.inputs = tuple(meta["inputs"])
        self._defaults = defaults_array(meta["defaults"])
        self._defaults_complete = not np.isnan(self._defaults).any()
        self.defaults = defaults_array(meta["defaults"])
        self._zeros = np.zeros(max(self.n_inputs, 1))
        self.backend = "c"

    def __repr__(self):
        return f"<lagrgen model {self.name!r} (compiled), coordinates {self.coordinates}>"

    cdef inline const double *_p(self, object p) except NULL:
        """The parameter vector: defaults for None; converted arrays are kept alive on self."""
        if p is None and self._defaults_complete:
            return data(self._defaults)
        if type(p) is cnp.ndarray:
            self._keep_p = as_f64(p, self.n_params, "p (the parameter vector)")
        else:
            self._keep_p = parameter_vector(p, self.parameters, self._defaults)
        if self.n_params == 0:
            return data(self._zeros)
        return data(self._keep_p)

    cdef inline const double *_u(self, object u) except NULL:
        if u is None:
            return data(self._zeros)
        if type(u) is cnp.ndarray or not isinstance(u, dict):
            self._keep_u = as_f64(u, self.n_inputs, "u (the input vector)")
        else:
            self._keep_u = input_vector(u, self.inputs)
        if self.n_inputs == 0:
            return data(self._zeros)
        return data(self._keep_u)

    cdef _not_positive_definite(self, double t, const double *q):
        raise MassMatrixError.at(self.name, t, [q[i] for i in range(self.n_coordinates)])

    def mass_matrix(self, q, double t=0.0, p=None, u=None):
        """M(q, t), an (n, n) float64 array."""
        cdef cnp.ndarray qa = as_f64(q, self.n_coordinates, "q")
        cdef const double *pp = self._p(p)
        cdef cnp.npy_intp dims[2]
        dims[0] = dims[1] = self.n_coordinates
        cdef cnp.ndarray out = new_array(2, dims)
        self.model.mass_matrix(t, data(qa), pp, <double *>cnp.PyArray_DATA(out))
        return out

    def forcing(self, q, qd, double t=0.0, p=None, u=None):
        """F(q, q̇, t, u), an (n,) float64 array with M·q̈ = F."""
        cdef cnp.ndarray qa = as_f64(q, self.n_coordinates, "q")
        cdef cnp.ndarray qda = as_f64(qd, self.n_coordinates, "qd")
        cdef const double *pp = self._p(p)
        cdef const double *up = self._u(u)
        cdef cnp.npy_intp dims[1]
        dims[0] = self.n_coordinates
        cdef cnp.ndarray out = new_array(1, dims)
        self.model.forcing(t, data(qa), data(qda), pp, up, <double *>cnp.PyArray_DATA(out))
        return out

    def rhs(self, double t, y, p=None, u=None):
        """ẏ = [q̇, M⁻¹F] for y = [q, q̇], a new (2n,) float64 array on every call."""
        cdef cnp.ndarray ya = as_f64(y, 2 * self.n_coordinates, "y")
        cdef const double *pp = self._p(p)
        cdef const double *up = self._u(u)
        cdef cnp.npy_intp dims[1]
        dims[0] = 2 * self.n_coordinates
        cdef cnp.ndarray out = new_array(1, dims)
        if self.model.rhs(t, data(ya), pp, up, <double *>cnp.PyArray_DATA(out)):
            self._not_positive_definite(t, data(ya))
        return out

    def jacobian(self, double t, y, p=None, u=None):
        """∂ẏ/∂y, a new (2n, 2n) float64 array (analytic)."""
        cdef cnp.ndarray ya = as_f64(y, 2 * self.n_coordinates, "y")
        cdef const double *pp = self._p(p)
        cdef const double *up = self._u(u)
        cdef cnp.npy_intp dims[2]
        dims[0] = dims[1] = 2 * self.n_coordinates
        cdef cnp.ndarray out = new_array(2, dims)
        if self.model.jacobian(t, data(ya), pp, up, <double *>cnp.PyArray_DATA(out)):
            self._not_positive_definite(t, data(ya))
        return out

    def linear_terms(self, q, qd, double t=0.0, p=None, u=None):
        """(M, ∂F/∂q, ∂F/∂q̇, ∂F/∂u) at one point, as float64 arrays."""
        cdef int n = self.n_coordinates
        cdef cnp.ndarray qa = as_f64(q, n, "q")
        cdef cnp.ndarray qda = as_f64(qd, n, "qd")
        cdef const double *pp = self._p(p)
        cdef const double *up = self._u(u)
        M, dq, dqd = np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
        du = np.empty((n, self.n_inputs))
        cdef double[:, ::1] Mv = M, dqv = dq, dqdv = dqd
        cdef double[:, ::1] duv = du if self.n_inputs else np.empty((n, 1))
        self.model.linear_terms(t, data(qa), data(qda), pp, up, &Mv[0, 0], &dqv[0, 0],
                                &dqdv[0, 0], &duv[0, 0])
        return M, dq, dqd, du

    def time_in_c(self, str which, double t, y, p=None, u=None, long repeat=10000):
        """Seconds per call of the C function `which` ("rhs" or "jacobian"), looped inside C."""
        cdef int n = self.n_coordinates
        cdef cnp.ndarray ya = as_f64(y, 2 * n, "y")
        cdef const double *pp = self._p(p)
        cdef const double *up = self._u(u)
        cdef cnp.ndarray out = np.empty(4 * n * n)
        cdef double *o = <double *>cnp.PyArray_DATA(out)
        cdef const double *yp = data(ya)
        cdef long i
        cdef int status = 0
        if which not in ("rhs", "jacobian"):
            raise ValueError("which must be 'rhs' or 'jacobian'")
        cdef bint is_rhs = which == "rhs"
        start = time.perf_counter()
        with nogil:
            if is_rhs:
                for i in range(repeat):
                    status |= self.model.rhs(t, yp, pp, up, o)
            else:
                for i in range(repeat):
                    status |= self.model.jacobian(t, yp, pp, up, o)
        elapsed = time.perf_counter() - start
        if status:
            self._not_positive_definite(t, yp)
        return elapsed / repeat


    def function_address(self, str name):
        """The address (an int) of the model's C function `name` ("rhs" or "jacobian"),
        for lagrgen's native engine; valid while this model is alive."""
        if name == "rhs":
            return <size_t>self.model.rhs
        if name == "jacobian":
            return <size_t>self.model.jacobian
        raise ValueError(f"no C function {name!r}: use 'rhs' or 'jacobian'")


def bind_module(module, capsule):
    """Make `module` (a freshly imported model module) a built model: called by its PyInit."""
    model = CompiledModel(capsule)
    for attr in ("name", "coordinates", "parameters", "inputs", "defaults", "n_coordinates",
                 "content_hash", "lagrgen_version", "backend", "mass_matrix", "forcing", "rhs",
                 "jacobian", "linear_terms", "time_in_c"):
        setattr(module, attr, getattr(model, attr))
    module.compiled_model = model
    return None
