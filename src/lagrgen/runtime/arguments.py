"""The one boundary where user values become float64 vectors: names or SymPy Symbols/functions as
keys, dicts, lists, arrays, None. Everything below it takes raw arrays.

Non-finite parameter and input values are refused here (ValueError), the same on both backends.
"""
import numpy as np

from ..errors import UnknownNameError
from ..names import key_name  # noqa: F401  (re-exported: the runtime reads keys with it)


def key_names(names):
    """A name, a Symbol, an applied function x(t) or a sequence of them as a list of names
    (`key_name` of each)."""
    single = isinstance(names, str) or getattr(names, "is_Symbol", False) \
        or getattr(names, "is_Function", False)
    return [key_name(name) for name in ([names] if single else names)]


def unknown_name(what, key, names):
    """The one "unknown name" error: `key` is not among the model's `names` of kind `what`."""
    known = ", ".join(names) if names else "none"
    return UnknownNameError(f"unknown {what} name {key!r}: the model's {what}s are {known}")


def defaults_array(defaults):
    """Parameter defaults as a read-only float64 array, NaN where a value must be given."""
    out = np.array([np.nan if d is None else d for d in defaults], dtype=np.float64)
    out.setflags(write=False)
    return out


def initial_state_array(info):
    """A built model's initial state [q0, q̇0] as a read-only float64 array: the declared one,
    or zeros."""
    out = np.array(info.initial_state or [0.0] * (2 * len(info.coordinates)), dtype=np.float64)
    out.setflags(write=False)
    return out


def as_vector(obj, size, what):
    """`obj` as a C-contiguous, aligned, native-order 1-D float64 array of length `size`."""
    try:
        arr = np.ascontiguousarray(obj, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be an array of {size} numbers ({exc})") from None
    if arr.ndim != 1 or arr.shape[0] != size:
        raise ValueError(f"{what} must be a 1-D array of length {size}, got shape {arr.shape}")
    return arr


def link_index(model, links, link):
    """The index of `link` among the model's `links` (names); UnknownNameError listing them."""
    try:
        return links.index(link)
    except ValueError:
        pass
    if not links:
        raise UnknownNameError(f"model {model!r} has no links: link_pose and link_jacobian "
                               "need a three-dimensional tree (a robot from a URDF file, or "
                               "rigid_body_3d bodies that form a tree)")
    raise UnknownNameError(f"{link!r} is not a link of model {model!r}; its links are "
                           f"{', '.join(links)}")


def link_not_finite(model, function, link):
    """The message of a link function whose result is not finite."""
    return (f"{function} of model {model!r} at link {link!r} is not finite: q must be finite "
            "numbers (and a free base's quaternion q[3:7] nonzero)")


def link_point(point):
    """A point in a link's frame as 3 finite float64 numbers."""
    point = as_vector(point, 3, "point (3 coordinates in the link's frame)")
    if not np.isfinite(point).all():
        raise ValueError(f"point must be 3 finite numbers, got {point}")
    return point


def require_finite(values, names, what):
    """Raise ValueError naming the first entry of `values` that is NaN or infinite."""
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        i = int(bad[0])
        label = names[i] if i < len(names) else str(i)
        raise ValueError(f"{what} {label!r} is {values[i]}: parameters and inputs must be finite "
                         "numbers")
    return values


def named_vector(values, names, base, what):
    """`base` (copied) with entries replaced from the dict `values` (name or symbol -> number)."""
    out = np.array(base, dtype=np.float64)
    index = {name: i for i, name in enumerate(names)}
    seen = set()
    for key, value in values.items():
        name = key_name(key)
        if name not in index:
            raise unknown_name(what, name, names)
        if name in seen:
            raise ValueError(f"{what} {name!r} is given twice (by its name and by its Symbol or "
                             "function): give it once")
        seen.add(name)
        try:
            out[index[name]] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{what} {name!r} must be a number, got {value!r}") from None
    return out


def parameter_vector(p, names, defaults):
    """p as a float64 array in parameter order: None -> defaults; a dict overrides defaults."""
    if p is None or isinstance(p, dict):
        given = set() if p is None else {key_name(key) for key in p}
        p = defaults if p is None else named_vector(p, names, defaults, "parameter")
        missing = [name for name, value in zip(names, p) if np.isnan(value) and name not in given]
        if missing:
            raise ValueError(
                f"parameter(s) {', '.join(missing)} have no default value: give them at run time, "
                f"e.g. params={{{missing[0]!r}: 1.0}} or a full p array in the order "
                f"{', '.join(names)}")
    else:
        p = as_vector(p, len(names), "p (the parameter vector)")
    return require_finite(p, names, "parameter")


def input_vector(u, names):
    """u as a float64 array in input order: None -> zeros; a dict sets the named inputs."""
    if u is None:
        return np.zeros(len(names))
    if isinstance(u, dict):
        u = named_vector(u, names, np.zeros(len(names)), "input")
    else:
        u = as_vector(u, len(names), "u (the input vector)")
    return require_finite(u, names, "input")


def state_vector(y0, coordinates, what="y0"):
    """y = [q, q̇] as a float64 array from 2n numbers or a dict of `<coordinate>` and
    `<coordinate>_dot` names (missing entries are 0)."""
    n = len(coordinates)
    if isinstance(y0, dict):
        names = list(coordinates) + [f"{c}_dot" for c in coordinates]
        return named_vector(y0, names, np.zeros(2 * n), "state")
    return as_vector(y0, 2 * n, f"{what} (= [q0, qd0] for coordinates {', '.join(coordinates)})")


def parameters_from(mod, params):
    """The parameter vector of the built model `mod` for `params`: None, a dict (names or
    Symbols -> value) or an array."""
    return parameter_vector(params, tuple(mod.parameters), np.asarray(mod.defaults, dtype=float))


def input_function(mod, inputs):
    """A function t -> the input vector u(t), in input order.

    `inputs` maps input names (or the functions `model.inputs` returned) to constants or callables
    of t; unnamed inputs are zero. A full array gives constant inputs in input order. Constant
    inputs give one read-only vector, the same for every t.
    """
    names = tuple(mod.inputs)
    if inputs is None or not isinstance(inputs, dict):
        u0 = np.zeros(len(names)) if inputs is None else require_finite(
            as_vector(inputs, len(names), "inputs (the input vector)"), names, "input")
        return constant(u0)
    by_name = {}
    for key, value in inputs.items():
        name = key_name(key)
        if name not in names:
            raise unknown_name("input", name, names)
        if name in by_name:
            raise ValueError(f"input {name!r} is given twice (by its name and by its function): "
                             "give it once")
        by_name[name] = value
    constants = {k: v for k, v in by_name.items() if not callable(v)}
    u0 = require_finite(named_vector(constants, names, np.zeros(len(names)), "input"), names,
                        "input")
    varying = [(names.index(k), f) for k, f in by_name.items() if callable(f)]
    if not varying:
        return constant(u0)

    def u_at(t):
        u = u0.copy()
        for i, f in varying:
            value = f(t)
            try:
                u[i] = value
            except (TypeError, ValueError):
                raise ValueError(f"input {names[i]!r}: its function returned {value!r} at "
                                 f"t = {t!r}; it must return one number") from None
        return u
    return u_at


def constant(u0):
    """t -> u0 for every t (u0 made read-only: every call shares it)."""
    u0.setflags(write=False)

    def u_at(t):
        return u0
    return u_at


def python_callable_inputs(inputs):
    """The names of the inputs given as Python callables (not constants or lagrgen.Signals)."""
    from ..signals import Signal
    if not isinstance(inputs, dict):
        return []
    return [key_name(k) for k, v in inputs.items() if callable(v) and not isinstance(v, Signal)]


def input_specs(mod, inputs):
    """The native engine's per-input descriptions for `inputs` (None, an array, or a dict of
    constants and Signals; unnamed inputs are 0)."""
    from ..signals import Signal, constant_spec
    names = tuple(mod.inputs)
    if inputs is None:
        return [constant_spec(0.0) for _ in names]
    if not isinstance(inputs, dict):
        u = require_finite(as_vector(inputs, len(names), "inputs (the input vector)"), names,
                           "input")
        return [constant_spec(x) for x in u]
    inputs = {key_name(k): v for k, v in inputs.items()}
    unknown = [k for k in inputs if k not in names]
    if unknown:
        raise unknown_name("input", unknown[0], names)
    specs = []
    for name in names:
        v = inputs.get(name, 0.0)
        if isinstance(v, Signal):
            specs.append(v.native_spec())
        else:
            try:
                x = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"input {name!r} must be a number, a lagrgen.Signal or a "
                                 f"function of t, got {v!r}") from None
            if not np.isfinite(x):
                raise ValueError(f"input {name!r} is {x}: parameters and inputs must be finite "
                                 "numbers")
            specs.append(constant_spec(x))
    return specs
