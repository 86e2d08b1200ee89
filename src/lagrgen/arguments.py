"""Turning what users pass at run time (arrays, lists, dicts, None) into float64 vectors."""
import numpy as np

from .errors import UnknownNameError


def defaults_array(defaults):
    """Parameter defaults as a read-only float64 array, NaN where a value must be given."""
    out = np.array([np.nan if d is None else d for d in defaults], dtype=np.float64)
    out.setflags(write=False)
    return out


def as_vector(obj, size, what):
    """Return `obj` as a C-contiguous 1-D float64 array of length `size`, or raise ValueError."""
    try:
        arr = np.ascontiguousarray(obj, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be an array of {size} numbers ({exc})") from None
    if arr.ndim != 1 or arr.shape[0] != size:
        raise ValueError(f"{what} must be a 1-D array of length {size}, got shape {arr.shape}")
    return arr


def named_vector(values, names, base, what):
    """Return `base` (copied) with entries replaced from the dict `values` (name -> number)."""
    out = np.array(base, dtype=np.float64)
    index = {name: i for i, name in enumerate(names)}
    for key, value in values.items():
        if key not in index:
            known = ", ".join(names) if names else "none"
            raise UnknownNameError(f"unknown {what} name {key!r}: the model's {what}s are {known}")
        try:
            out[index[key]] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{what} {key!r} must be a number, got {value!r}") from None
    return out


def parameter_vector(p, names, defaults):
    """p as a float64 array in parameter order: None -> defaults; a dict overrides defaults."""
    if p is None:
        p = defaults
    elif isinstance(p, dict):
        p = named_vector(p, names, defaults, "parameter")
    else:
        p = as_vector(p, len(names), "p (the parameter vector)")
    missing = [name for name, value in zip(names, p) if np.isnan(value)]
    if missing:
        raise ValueError(
            f"parameter(s) {', '.join(missing)} have no default value: give them at run time, "
            f"e.g. params={{{missing[0]!r}: 1.0}} or a full p array in the order {', '.join(names)}")
    return p


def input_vector(u, names):
    """u as a float64 array in input order: None -> zeros; a dict sets the named inputs."""
    if u is None:
        return np.zeros(len(names))
    if isinstance(u, dict):
        return named_vector(u, names, np.zeros(len(names)), "input")
    return as_vector(u, len(names), "u (the input vector)")
