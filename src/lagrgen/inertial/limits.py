"""The joints' limits identification and exciting trajectories use: the model's (a URDF's
position, velocity and effort limits) merged field by field with the ones given."""
import numpy as np

from ..runtime.arguments import unknown_name


def _limit_arrays(mod, limits):
    """(lower, upper, velocity, acceleration), each (n,), inf where a joint has no such limit:
    from `limits` ({coordinate: (lower, upper, velocity, acceleration)}), each None there taken
    from the model's `limits` ({coordinate: (lower, upper, velocity, effort)}, the effort
    not used)."""
    merged = {c: tuple(entry[:3]) + (None,) for c, entry in mod.limits.items()}
    for coordinate, entry in (limits or {}).items():
        if coordinate not in mod.coordinates:
            raise unknown_name("coordinate", coordinate, tuple(mod.coordinates))
        own = merged.get(coordinate, (None,) * 4)
        merged[coordinate] = tuple(o if value is None else value
                                   for o, value in zip(own, _limit_entry(coordinate, entry)))
    out = np.tile(np.array([[-np.inf], [np.inf], [np.inf], [np.inf]]), (1, mod.n_coordinates))
    for coordinate, entry in merged.items():
        j = mod.coordinates.index(coordinate)
        for row, value in enumerate(entry):
            if value is not None:
                out[row, j] = float(value)
    lower, upper, velocity, acceleration = out
    bad = np.flatnonzero((lower >= upper) | (velocity <= 0) | (acceleration <= 0))
    if bad.size:
        raise ValueError(f"the limits of {mod.coordinates[bad[0]]!r} must have lower < upper "
                         "and positive velocity and acceleration limits")
    return lower, upper, velocity, acceleration


def _limit_entry(coordinate, entry):
    """One joint's (lower, upper, velocity, acceleration), None where absent."""
    entry = tuple(entry) if entry is not None else (None,) * 4
    if len(entry) != 4 or any(v is not None and not np.isfinite(float(v)) for v in entry):
        raise ValueError(f"limits[{coordinate!r}] must be (lower, upper, velocity, acceleration), "
                         f"finite numbers or None, got {entry!r}")
    return entry
