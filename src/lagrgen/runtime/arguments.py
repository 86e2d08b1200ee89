"""The one boundary where user values become float64 vectors: names or SymPy Symbols/functions as
keys, dicts, lists, arrays, None. Everything below it takes raw arrays.

Non-finite parameter and input values are refused here (ValueError), the same on both backends.
"""
import numpy as np

from ..errors import UnknownNameError
from ..names import key_name  # noqa: F401  (re-exported: the runtime reads keys with it)


def unknown_name(what, key, names):
    """The one "unknown name" error: `key` is not among the model's `names` of kind `what`."""
    known = ", ".join(names) if names else "none"
    return UnknownNameError(f"unknown {what} name {key!r}: the model's {what}s are {known}")


def defaults_array(defaults):
    """Parameter defaults as a read-only float64 array, NaN where a value must be given."""
    out = np.array([np.nan if d is None else d for d in defaults], dtype=np.float64)
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
    for key, value in values.items():
        name = key_name(key)
        if name not in index:
            raise unknown_name(what, name, names)
        try:
            out[index[name]] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{what} {name!r} must be a number, got {value!r}") from None
    return out


def parameter_vector(p, names, defaults):
    """p as a float64 array in parameter order: None -> defaults; a dict overrides defaults."""
    if p is None or isinstance(p, dict):
        p = defaults if p is None else named_vector(p, names, defaults, "parameter")
        missing = [name for name, value in zip(names, p) if np.isnan(value)]
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
