# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
# cython: embedsignature=True, binding=False
"""The compiled half of every built model: argument conversion, output arrays, errors, timing.

Compiled once when lagrgen is installed. A generated model module holds only its equations (the
plain-C model functions, listed in an `lg_model_t` table behind a capsule) and calls `bind_module`
when imported, which makes the module itself a built model (`lagrgen.runtime.protocol.BuiltModel`):
one callable per entry of `lagrgen.functions.FUNCTIONS`.

Thread safety: nothing a call depends on is stored in a shared object. Converted arguments are
locals of the call, which keeps them alive for as long as C (or a nogil loop) reads them.
"""
import time
import weakref

import numpy as np
cimport numpy as cnp
from cpython.pycapsule cimport PyCapsule_GetPointer, PyCapsule_IsValid
from libc.math cimport isfinite
from libc.string cimport memcpy, memset

from lagrgen.runtime.abi cimport (LG_ABI_VERSION, LG_CAPSULE_NAME, lg_directions_fn,
                                  lg_function, lg_model_t)
from lagrgen.errors import BuildError, ConstraintError, MassMatrixError, NonFiniteError
from lagrgen.functions import BY_NAME, FUNCTIONS, MODEL_UNIT, NO_MEMORY
from lagrgen.runtime.describe import BuiltModule
from lagrgen.runtime.info import INFO_ATTRIBUTES, ModelInfo
from lagrgen.runtime import units
from lagrgen.runtime.arguments import (defaults_array, initial_state_array, input_vector,
                                       link_index, link_not_finite, link_point,
                                       parameter_vector, require_finite)

cnp.import_array()

ABI_VERSION = LG_ABI_VERSION


cdef inline bint is_ready(object obj, Py_ssize_t size):
    """obj is a 1-D C-contiguous, aligned, native-order float64 array of length size."""
    cdef cnp.ndarray arr
    if type(obj) is not cnp.ndarray:
        return False
    arr = <cnp.ndarray>obj
    return (cnp.PyArray_TYPE(arr) == cnp.NPY_DOUBLE and cnp.PyArray_NDIM(arr) == 1
            and cnp.PyArray_ISCARRAY_RO(arr) and cnp.PyArray_ISNOTSWAPPED(arr)
            and cnp.PyArray_DIM(arr, 0) == size)


cdef inline cnp.ndarray as_f64(object obj, Py_ssize_t size, str what):
    """obj as a 1-D float64 array of length size (no copy when it already is a ready one)."""
    cdef cnp.ndarray arr
    if is_ready(obj, size):
        return <cnp.ndarray>obj
    try:
        arr = np.ascontiguousarray(obj, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be an array of {size} numbers ({exc})") from None
    if cnp.PyArray_NDIM(arr) != 1 or cnp.PyArray_DIM(arr, 0) != size:
        raise ValueError(f"{what} must be a 1-D array of length {size}, got shape {np.shape(obj)}")
    return arr


cdef bint finite_numbers(const double *x, Py_ssize_t count) noexcept nogil:
    """True if the count numbers at x are all finite: x − x is 0 for a finite x and NaN for an
    infinite or NaN one; summed in four lanes, with no branch per number (a 6×18 Jacobian is
    checked in a third of the time of an isfinite per entry)."""
    cdef double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0
    cdef Py_ssize_t i = 0
    while i + 4 <= count:
        s0 += x[i] - x[i]
        s1 += x[i + 1] - x[i + 1]
        s2 += x[i + 2] - x[i + 2]
        s3 += x[i + 3] - x[i + 3]
        i += 4
    while i < count:
        s0 += x[i] - x[i]
        i += 1
    return (s0 + s1) + (s2 + s3) == 0.0


cdef inline bint all_finite(cnp.ndarray arr):
    return finite_numbers(<const double *>cnp.PyArray_DATA(arr), cnp.PyArray_DIM(arr, 0))


cdef inline const double *data(cnp.ndarray arr):
    return <const double *>cnp.PyArray_DATA(arr)


cdef inline void copy_into(double *destination, cnp.ndarray source, Py_ssize_t count):
    memcpy(destination, cnp.PyArray_DATA(source), count * sizeof(double))


cdef class CompiledModel:
    """A model's compiled equations: sizes, names, and the C function table of its module."""

    cdef const lg_model_t *model
    cdef readonly object info
    cdef readonly int n_coordinates, n_params, n_inputs, n_constraints
    cdef readonly str name
    cdef readonly tuple parameters, inputs
    cdef readonly object defaults
    cdef readonly dict dimensions
    cdef cnp.ndarray _zeros
    cdef bint _defaults_complete
    cdef dict _addresses, _units
    cdef object _module

    def __cinit__(self, capsule):
        if not PyCapsule_IsValid(capsule, LG_CAPSULE_NAME):
            raise TypeError("expected the capsule of a lagrgen model module")
        self.model = <const lg_model_t *>PyCapsule_GetPointer(capsule, LG_CAPSULE_NAME)
        if self.model.abi_version != LG_ABI_VERSION:
            raise BuildError(
                f"this model was compiled for lagrgen runtime ABI {self.model.abi_version}, "
                f"but the installed lagrgen uses {LG_ABI_VERSION}: rebuild it")
        info = ModelInfo.from_json(self.model.metadata.decode("utf-8"))
        self.info = info
        self.name = info.name
        self.n_coordinates = self.model.n
        self.n_params = self.model.n_params
        self.n_inputs = self.model.n_inputs
        self.n_constraints = info.n_constraints
        self.parameters = info.parameters
        self.inputs = info.inputs
        self.dimensions = info.dimensions
        self.defaults = defaults_array(info.defaults)
        self._defaults_complete = bool(np.isfinite(self.defaults).all())
        self._zeros = np.zeros(max(self.n_inputs, 1))
        self._zeros.setflags(write=False)
        self._addresses = table(self.model)
        self._units = {}
        self._module = None
        missing = [f.name for f in FUNCTIONS if f.unit == MODEL_UNIT and f.name not in self._addresses]
        if missing:
            raise BuildError(f"compiled model {self.name!r} lacks {', '.join(missing)}: it was "
                             "built by another lagrgen version; rebuild it")

    cdef cnp.ndarray params(self, object p):
        """The parameter vector of one call (the defaults for None), finite, in parameter order."""
        if p is None and self._defaults_complete:
            return self.defaults
        if is_ready(p, self.n_params) and all_finite(<cnp.ndarray>p):
            return <cnp.ndarray>p
        return parameter_vector(p, self.parameters, self.defaults)

    cdef cnp.ndarray input_values(self, object u):
        """The input vector of one call (zeros for None), finite, in input order."""
        if u is None:
            return self._zeros
        if is_ready(u, self.n_inputs) and all_finite(<cnp.ndarray>u):
            return <cnp.ndarray>u if self.n_inputs else self._zeros
        if isinstance(u, dict):
            values = input_vector(u, self.inputs)
        else:
            values = require_finite(as_f64(u, self.n_inputs, "u (the input vector)"),
                                    self.inputs, "input")
        return values if self.n_inputs else self._zeros

    def address(self, str name):
        """The address of the registered function `name`, compiling its unit on first use."""
        if name not in self._addresses:
            if name not in BY_NAME:
                raise ValueError(f"model {self.name!r} has no function {name!r}: it has "
                                 f"{', '.join(f.name for f in FUNCTIONS)}")
            self.attach(BY_NAME[name].unit)
        return self._addresses[name]

    def attach(self, str label):
        """Add the functions of the unit `label` (compiled on first use, `runtime.units`)."""
        with units.LOCK:
            if label in self._units:
                return
            module = self._module() if self._module is not None else None
            path = getattr(module, "__file__", None)
            if path is None:
                raise BuildError(f"the module of compiled model {self.name!r} has no file: its "
                                 f"{label} functions cannot be compiled")
            unit = units.unit_module(path, self.info, label)
            capsule = getattr(unit, "_lagrgen_unit", None)
            if capsule is None or not PyCapsule_IsValid(capsule, LG_CAPSULE_NAME):
                raise BuildError(f"{unit.__name__} is not a unit of a lagrgen model")
            found = <const lg_model_t *>PyCapsule_GetPointer(capsule, LG_CAPSULE_NAME)
            other = ModelInfo.from_json(found.metadata.decode("utf-8"))
            if found.abi_version != LG_ABI_VERSION or other.content_hash != self.info.content_hash:
                raise BuildError(f"the {label} unit {unit.__file__} does not belong to compiled "
                                 f"model {self.name!r} (another build or lagrgen version): "
                                 "rebuild the model")
            self._addresses.update(table(found))
            self._units[label] = unit

    cdef lg_function pointer(self, str name) except NULL:
        """The C function `name` of the one signature lg_function."""
        if name in DIRECTION_FUNCTIONS:
            raise ValueError(f"{name} of model {self.name!r} does not have the signature (t, y, "
                             "p, u, out)")
        return <lg_function><size_t>self.address(name)

    def pivot_record(self):
        """The least Cholesky (or articulated-body) pivot of M relative to its diagonal entry
        that the factorizations of M on this thread reached since the previous call (1.0 when
        none fell below 1e-3, or for a model compiled without the record); resets the record."""
        cdef double value = 1.0
        cdef lg_function fn
        address = self._addresses.get("pivot_record")
        if address is None:
            return 1.0
        fn = <lg_function><size_t>address
        fn(0.0, NULL, NULL, NULL, &value)
        return value

    def function_address(self, str name):
        """The address of the C function `name` (for native solvers that call it without Python;
        a function of call style "directions" has the signature lg_directions_fn), compiling its
        unit on first use."""
        return self.address(name)

    cdef failed(self, int status, double t, const double *y, const double *p, const double *u):
        """Raise the error of a call that returned `status` at (t, y): no memory for its work
        arrays (NO_MEMORY), else M not positive definite, or (when M is) dependent constraints."""
        cdef int n = self.n_coordinates
        if status == NO_MEMORY:
            raise MemoryError(f"compiled model {self.name!r} could not allocate the work arrays "
                              f"of a function at t = {t!r} (the heap has no room)")
        state = np.array([y[i] for i in range(2 * n)])
        if np.all(np.isfinite(state)) and np.isfinite(t):
            M = np.empty(n * n)
            if self.pointer("mass_matrix")(t, y, p, u, <double *>cnp.PyArray_DATA(M)):
                raise MassMatrixError.at(self.name, t, state[:n])
            if not np.all(np.isfinite(M)):
                raise NonFiniteError.in_mass_matrix(self.name, t, state[:n])
            if not self.n_constraints:
                raise MassMatrixError.at(self.name, t, state[:n])
            try:
                np.linalg.cholesky(M.reshape(n, n))
            except np.linalg.LinAlgError:
                pass
            else:
                raise ConstraintError.at(self.name, t, state, n)
        raise MassMatrixError.at(self.name, t, state[:n])

    def time_in_c(self, str which, double t, y, p=None, u=None, long repeat=10000):
        """Seconds per call of the C function `which` (e.g. "rhs", "jacobian"), looped inside C."""
        cdef lg_function fn = self.pointer(which)
        cdef int n = self.n_coordinates
        cdef cnp.ndarray ya = np.zeros(3 * n + self.n_constraints)   # room for [q, q̇, q̈, λ]
        ya[:2 * n] = as_f64(y, 2 * n, "y")
        cdef cnp.ndarray pa = self.params(p)
        cdef cnp.ndarray ua = self.input_values(u)
        cdef cnp.ndarray out = np.empty(max(f.size(self.dimensions) for f in FUNCTIONS
                                            if f.name not in DIRECTION_FUNCTIONS) + 1)
        cdef double *o = <double *>cnp.PyArray_DATA(out)
        cdef const double *yp = data(ya)
        cdef const double *pp = data(pa)
        cdef const double *up = data(ua)
        cdef long i
        cdef int status = 0
        start = time.perf_counter()
        with nogil:
            for i in range(repeat):
                status = fn(t, yp, pp, up, o)
                if status:
                    break
        elapsed = time.perf_counter() - start
        if status:
            self.failed(status, t, yp, pp, up)
        return elapsed / repeat


cdef dict table(const lg_model_t *model):
    """{name: address} of a module's function table."""
    cdef int i
    return {model.functions[i].name.decode("ascii"): <size_t>model.functions[i].fn
            for i in range(model.n_functions)}


cdef class BoundFunction:
    """One model function of a compiled model, called with the arguments of its call style."""

    cdef CompiledModel model
    cdef lg_function fn
    cdef readonly str name, formula
    cdef tuple shapes
    cdef Py_ssize_t size
    cdef int nd
    cdef cnp.npy_intp dims[2]

    def __init__(self, CompiledModel model, spec):
        self.model = model
        self.name = spec.name
        self.formula = spec.formula
        self.fn = model.pointer(spec.name) if spec.unit == MODEL_UNIT else NULL
        self.shapes = tuple(spec.shapes(model.dimensions))
        self.size = spec.size(model.dimensions)
        self.nd = len(self.shapes[0])
        self.dims[0] = self.shapes[0][0]
        self.dims[1] = self.shapes[0][1] if self.nd == 2 else 1

    def __repr__(self):
        return f"<{self.name} of compiled model {self.model.name!r}: {self.formula}>"

    cdef object evaluate(self, double t, const double *y, object p, object u):
        if self.fn == NULL:
            self.fn = self.model.pointer(self.name)
        cdef cnp.ndarray pa = self.model.params(p)
        cdef cnp.ndarray ua = self.model.input_values(u)
        cdef cnp.ndarray out
        cdef cnp.npy_intp size = self.size
        if len(self.shapes) == 1:
            out = <cnp.ndarray>cnp.PyArray_EMPTY(self.nd, self.dims, cnp.NPY_DOUBLE, 0)
        else:
            out = <cnp.ndarray>cnp.PyArray_EMPTY(1, &size, cnp.NPY_DOUBLE, 0)
        cdef int status = self.fn(t, y, data(pa), data(ua), <double *>cnp.PyArray_DATA(out))
        if status:
            self.model.failed(status, t, y, data(pa), data(ua))
        if len(self.shapes) == 1:
            return out
        parts, start = [], 0
        for shape in self.shapes:
            count = int(np.prod(shape))
            parts.append(out[start:start + count].reshape(shape))
            start += count
        return tuple(parts)

    cdef cnp.ndarray state_from(self, q, qd):
        """[q, q̇] (q̇ zero for None) in a new array."""
        cdef cnp.npy_intp n = self.model.n_coordinates
        cdef cnp.npy_intp size = 2 * n
        cdef cnp.ndarray y = <cnp.ndarray>cnp.PyArray_EMPTY(1, &size, cnp.NPY_DOUBLE, 0)
        cdef double *yp = <double *>cnp.PyArray_DATA(y)
        copy_into(yp, as_f64(q, n, "q"), n)
        if qd is None:
            memset(yp + n, 0, n * sizeof(double))
        else:
            copy_into(yp + n, as_f64(qd, n, "qd"), n)
        return y


cdef class StateFunction(BoundFunction):
    """f(t, y, p=None, u=None) with y = [q, q̇]; a new float64 array on every call."""

    def __call__(self, double t, y, p=None, u=None):
        cdef cnp.ndarray ya = as_f64(y, 2 * self.model.n_coordinates, "y")
        return self.evaluate(t, data(ya), p, u)


cdef class CoordinateFunction(BoundFunction):
    """f(q, t=0.0, p=None, u=None); a new float64 array on every call."""

    def __call__(self, q, double t=0.0, p=None, u=None):
        cdef cnp.ndarray ya = self.state_from(q, None)
        return self.evaluate(t, data(ya), p, u)


cdef class StateArgumentsFunction(BoundFunction):
    """f(q, qd, t=0.0, p=None, u=None); new float64 arrays on every call."""

    def __call__(self, q, qd, double t=0.0, p=None, u=None):
        cdef cnp.ndarray ya = self.state_from(q, qd)
        return self.evaluate(t, data(ya), p, u)


cdef class ImplicitFunction(BoundFunction):
    """f(q, qd, a, t=0.0, p=None, u=None) with a = [q̈, λ]; new float64 arrays on every call."""

    def __call__(self, q, qd, a, double t=0.0, p=None, u=None):
        cdef cnp.npy_intp n = self.model.n_coordinates
        cdef cnp.npy_intp size = 3 * n + self.model.n_constraints
        cdef cnp.ndarray y = <cnp.ndarray>cnp.PyArray_EMPTY(1, &size, cnp.NPY_DOUBLE, 0)
        cdef double *yp = <double *>cnp.PyArray_DATA(y)
        copy_into(yp, as_f64(q, n, "q"), n)
        copy_into(yp + n, as_f64(qd, n, "qd"), n)
        copy_into(yp + 2 * n,
                  as_f64(a, size - 2 * n, "a (the accelerations, then the constraint multipliers)"),
                  size - 2 * n)
        return self.evaluate(t, data(y), p, u)


cdef class WeightedFunction(BoundFunction):
    """f(q, qd, a, mu, t=0.0, p=None, u=None) with a = [q̈, λ] and mu the weights of the implicit
    form's rows; new float64 arrays on every call."""

    def __call__(self, q, qd, a, mu, double t=0.0, p=None, u=None):
        cdef cnp.npy_intp n = self.model.n_coordinates
        cdef cnp.npy_intp ni = n + self.model.n_constraints
        cdef cnp.npy_intp size = 2 * n + 2 * ni
        cdef cnp.ndarray y = <cnp.ndarray>cnp.PyArray_EMPTY(1, &size, cnp.NPY_DOUBLE, 0)
        cdef double *yp = <double *>cnp.PyArray_DATA(y)
        copy_into(yp, as_f64(q, n, "q"), n)
        copy_into(yp + n, as_f64(qd, n, "qd"), n)
        copy_into(yp + 2 * n,
                  as_f64(a, ni, "a (the accelerations, then the constraint multipliers)"), ni)
        copy_into(yp + 2 * n + ni, as_f64(mu, ni, "mu (a weight per row of the residual)"), ni)
        return self.evaluate(t, data(y), p, u)


cdef class DirectionsFunction:
    """f(t, y, dy, dp=None, p=None, u=None) -> (ẏ, the derivatives of ẏ along the directions):
    dy is one direction (2n,) or k of them (k, 2n), dp the matching parameter directions (n_params,)
    or (k, n_params) (None: zeros); the derivatives have dy's shape."""

    cdef CompiledModel model
    cdef lg_directions_fn fn
    cdef readonly str name, formula

    def __init__(self, CompiledModel model, spec):
        self.model = model
        self.name = spec.name
        self.formula = spec.formula
        self.fn = NULL

    def __repr__(self):
        return f"<{self.name} of compiled model {self.model.name!r}: {self.formula}>"

    def __call__(self, double t, y, dy, dp=None, p=None, u=None):
        if self.fn == NULL:
            self.fn = <lg_directions_fn><size_t>self.model.address(self.name)
        cdef int dim = 2 * self.model.n_coordinates, n_params = self.model.n_params
        cdef cnp.ndarray ya = as_f64(y, dim, "y")
        cdef cnp.ndarray pa = self.model.params(p)
        cdef cnp.ndarray ua = self.model.input_values(u)
        directions = np.asarray(dy, dtype=np.float64)
        single = directions.ndim == 1
        if directions.ndim not in (1, 2) or directions.shape[directions.ndim - 1] != dim:
            raise ValueError(f"dy must have shape ({dim},) or (k, {dim}), got {directions.shape}")
        cdef cnp.ndarray dya = np.ascontiguousarray(directions.reshape(-1, dim))
        cdef int k = dya.shape[0]
        cdef cnp.ndarray dpa
        if dp is None or not n_params:
            dpa = np.zeros((k, max(n_params, 1)))
        else:
            dpa = np.ascontiguousarray(dp, dtype=np.float64)
            if np.shape(dpa) != (tuple([n_params]) if single else tuple([k, n_params])):
                raise ValueError(f"dp must have shape ({n_params},) or ({k}, {n_params}) to match "
                                 f"dy, got {np.shape(dp)}")
        if not (np.isfinite(dya).all() and np.isfinite(dpa).all()):
            raise ValueError("dy and dp must be finite")
        cdef cnp.ndarray out = np.empty((k + 1) * dim)
        cdef int status = self.fn(t, data(ya), data(pa), data(ua), k, data(dya), data(dpa),
                                  <double *>cnp.PyArray_DATA(out))
        if status:
            self.model.failed(status, t, data(ya), data(pa), data(ua))
        derivatives = out[dim:].reshape(k, dim)
        return out[:dim], (derivatives[0] if single else derivatives)


#: The default point of a link function: the link frame's origin.
ORIGIN = (0, 0, 0)


cdef int three_numbers(object point, double *out) except -1:
    """1 with `point` written to out when it is a tuple of 3 finite floats or ints (a link's
    point as people write it) or a 1-D float64 array of 3 finite numbers, read without
    converting it, else 0 (link_point converts and checks it)."""
    cdef int i
    cdef object v
    cdef cnp.ndarray arr
    if type(point) is cnp.ndarray:
        arr = <cnp.ndarray>point
        if arr.ndim != 1 or arr.shape[0] != 3 or cnp.PyArray_TYPE(arr) != cnp.NPY_DOUBLE \
                or not cnp.PyArray_ISNOTSWAPPED(arr):
            return 0
        for i in range(3):
            out[i] = (<double *>cnp.PyArray_GETPTR1(arr, i))[0]
            if not isfinite(out[i]):
                return 0
        return 1
    if type(point) is not tuple or len(<tuple>point) != 3:
        return 0
    for i in range(3):
        v = (<tuple>point)[i]
        if type(v) is int:
            if not -1e300 < v < 1e300:
                return 0
        elif type(v) is not float:
            return 0
        out[i] = v
        if not isfinite(out[i]):
            return 0
    return 1
#: A link function's state [q, point, index] stays on the stack up to this many coordinates.
cdef enum:
    LINK_STACK = 256


cdef class LinkFunction(BoundFunction):
    """f(link, q, point=(0, 0, 0), p=None) of a link of the model's tree (`link_names`); in C
    the state is [q, point, the link's index]. New float64 arrays on every call."""

    cdef dict index
    cdef tuple links

    def __init__(self, CompiledModel model, spec):
        BoundFunction.__init__(self, model, spec)
        self.links = tuple(model.info.link_names)
        self.index = {name: k for k, name in enumerate(self.links)}

    def __call__(self, link, q, point=ORIGIN, p=None):
        found = self.index.get(link) if type(link) is str else None
        if found is None:
            link_index(self.name_of_model(), self.links, link)
        if self.fn == NULL:
            self.fn = self.model.pointer(self.name)
        cdef Py_ssize_t n = self.model.n_coordinates
        cdef double stack[LINK_STACK + 4]
        cdef cnp.ndarray heap = None
        cdef double *y = stack
        if n > LINK_STACK:
            heap = np.empty(n + 4)
            y = <double *>cnp.PyArray_DATA(heap)
        memcpy(y, cnp.PyArray_DATA(as_f64(q, n, "q")), n * sizeof(double))
        if point is ORIGIN:
            y[n] = y[n + 1] = y[n + 2] = 0.0
        elif not three_numbers(point, y + n):
            memcpy(y + n, cnp.PyArray_DATA(link_point(point)), 3 * sizeof(double))
        y[n + 3] = <int>found
        cdef cnp.ndarray pa = self.model.params(p)
        cdef cnp.ndarray out
        cdef double buffer[12]
        cdef int status
        if len(self.shapes) == 1:
            out = <cnp.ndarray>cnp.PyArray_EMPTY(self.nd, self.dims, cnp.NPY_DOUBLE, 0)
            status = self.fn(0.0, y, data(pa), data(self.model._zeros),
                             <double *>cnp.PyArray_DATA(out))
            if status:
                self.link_failed(status)
            if not finite_numbers(<double *>cnp.PyArray_DATA(out), 6 * n):
                self.not_finite(link)
            return out
        status = self.fn(0.0, y, data(pa), data(self.model._zeros), buffer)
        if status:
            self.link_failed(status)
        if not finite_numbers(buffer, 12):
            self.not_finite(link)
        cdef cnp.npy_intp three = 3
        cdef cnp.npy_intp square[2]
        square[0] = square[1] = 3
        cdef cnp.ndarray position = <cnp.ndarray>cnp.PyArray_EMPTY(1, &three, cnp.NPY_DOUBLE, 0)
        cdef cnp.ndarray rotation = <cnp.ndarray>cnp.PyArray_EMPTY(2, square, cnp.NPY_DOUBLE, 0)
        memcpy(cnp.PyArray_DATA(position), buffer, 3 * sizeof(double))
        memcpy(cnp.PyArray_DATA(rotation), buffer + 3, 9 * sizeof(double))
        return position, rotation

    cdef str name_of_model(self):
        return self.model.name

    cdef not_finite(self, link):
        raise ValueError(link_not_finite(self.model.name, self.name, link))

    cdef link_failed(self, int status):
        if status == NO_MEMORY:
            raise MemoryError(f"compiled model {self.model.name!r} could not allocate the work "
                              f"arrays of {self.name}")
        raise BuildError(f"{self.name} of compiled model {self.model.name!r} failed (status "
                         f"{status}): its links unit does not match the model; rebuild it")


CALLABLES = {"state": StateFunction, "q": CoordinateFunction, "q_qd": StateArgumentsFunction,
             "implicit": ImplicitFunction, "weighted": WeightedFunction,
             "directions": DirectionsFunction, "link": LinkFunction}
#: The functions not of the one signature lg_function.
DIRECTION_FUNCTIONS = frozenset(f.name for f in FUNCTIONS if f.call == "directions")


def bind_module(module, capsule):
    """Make `module` (a freshly imported model module) a built model: called by its PyInit."""
    cdef CompiledModel model = CompiledModel(capsule)
    model._module = weakref.ref(module)
    module.info = model.info
    for attr in INFO_ATTRIBUTES:
        setattr(module, attr, getattr(model.info, attr))
    module.defaults = model.defaults
    module.initial_state = initial_state_array(model.info)
    module.time_in_c = model.time_in_c
    module.function_address = model.function_address
    module.pivot_record = model.pivot_record
    module.backend = "c"
    module.build_info = {}
    for spec in FUNCTIONS:
        setattr(module, spec.name, CALLABLES[spec.call](model, spec))
    module.compiled_model = model
    module.__class__ = BuiltModule   # its repr names the coordinates, parameters and inputs
    return None
