"""`base_state`: the state vector y = [q, q̇] of a robot with a floating base, from the base's pose
and velocity as people give them and the joints by name.

A "free" base (`from_urdf(..., base="free")`, `lagrgen.free_base`) holds its orientation as a unit
quaternion ζ = (q_x, q_y, q_z, q_w) (w ≥ 0 here) and its rate ζ̇ = ½·(ω, 0) ⊗ ζ (ω in fixed axes);
a "floating" one as URDF's roll, pitch and yaw, R = Rz(yaw)·Ry(pitch)·Rx(roll), whose rates follow
from ω = ẏaw·e_z + Rz(yaw)·(ṗitch·e_y + Ry(pitch)·ṙoll·e_x) (none at pitch = ±π/2).
"""
import math
import numbers

import numpy as np

from .errors import ModelError
from .numbers import finite_number
from .runtime.free_base import qmul as quaternion_product
from .urdf import FLOATING_ORDER, FREE_BASE, rpy_matrix


def base_state(mod, position=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0),
               angular_velocity=(0.0, 0.0, 0.0), q=None, qd=None):
    """The state vector of a model with a floating base ("free" or "floating", `from_urdf`).

    Parameters
    ----------
    mod : a built model (or a `lagrgen.Model`) whose first coordinates are a floating base's
    position : 3 numbers
        The base frame's origin in the fixed frame, m.
    rpy : 3 numbers
        Its orientation as URDF's roll, pitch, yaw (R = Rz(yaw)·Ry(pitch)·Rx(roll)), rad.
    velocity : 3 numbers
        The velocity of its origin, fixed axes, m/s.
    angular_velocity : 3 numbers
        Its angular velocity, fixed axes, rad/s.
    q, qd : dict, optional
        The joints' positions and rates by coordinate name; 0 where absent.

    Returns
    -------
    numpy.ndarray of 2n: y = [q, q̇] in the model's coordinate order.
    """
    names = getattr(mod, "coordinates", None)
    names = tuple(names if isinstance(names, (tuple, list)) else
                  getattr(mod, "coordinate_names", ()))
    kind = "free" if names[:7] == FREE_BASE else \
        "floating" if names[:6] == FLOATING_ORDER else None
    if kind is None:
        raise ModelError("base_state needs a model with a floating base: its first coordinates "
                         f"are {', '.join(names[:7])}, not {', '.join(FREE_BASE)} (from_urdf(..., "
                         f"base='free')) or {', '.join(FLOATING_ORDER)} (base='floating')")
    position, rpy, velocity, omega = (_vector(v, what) for v, what in (
        (position, "position"), (rpy, "rpy"), (velocity, "velocity"),
        (angular_velocity, "angular_velocity")))
    n = len(names)
    y = np.zeros(2 * n)
    width = 7 if kind == "free" else 6
    for k, (values, what) in enumerate(((q, "q"), (qd, "qd"))):
        for name, value in _joints(values, what, names, width).items():
            y[k * n + names.index(name)] = value
    y[:3], y[n:n + 3] = position, velocity
    if kind == "free":
        z = quaternion_of(np.array(rpy_matrix(rpy)))
        y[3:7] = z
        y[n + 3:n + 7] = 0.5 * quaternion_product(np.concatenate([omega, [0.0]]), z)
    else:
        y[3:6] = rpy
        y[n + 3:n + 6] = rpy_rates(rpy, omega)
    return y


def _vector(value, what):
    if isinstance(value, (str, bytes)) or np.ndim(value) != 1 or len(value) != 3:
        raise ModelError(f"base_state: {what} must be 3 numbers, got {value!r}")
    return np.array([finite_number(v, f"base_state {what}", ModelError) for v in value])


def _joints(values, what, names, width):
    """{coordinate name: float} of a q or qd dict, checked against the joints' names."""
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise ModelError(f"base_state: {what} must be a dict of joint names and values, got "
                         f"{type(values).__name__}")
    joints = names[width:]
    out = {}
    for key, value in values.items():
        name = key if isinstance(key, str) else getattr(getattr(key, "func", None), "__name__",
                                                        None)
        if name not in joints:
            raise ModelError(f"base_state {what}: {key!r} is not a joint of the model (its "
                             f"joints are {', '.join(joints) or 'none'}; the base is given by "
                             "position, rpy, velocity and angular_velocity)")
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ModelError(f"base_state {what}[{name!r}] must be a number, got {value!r}")
        out[name] = finite_number(value, f"base_state {what}[{name!r}]", ModelError)
    return out


def quaternion_of(R):
    """The unit quaternion (x, y, z, w), w ≥ 0, of the rotation matrix R (Shepperd's method:
    from its largest diagonal combination)."""
    trace = np.trace(R)
    candidates = [trace, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(candidates))
    if k == 0:
        w = math.sqrt(1.0 + trace) / 2
        z = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1], 4 * w * w]) / (4 * w)
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        v = np.zeros(4)
        v[i] = math.sqrt(max(1.0 + 2 * R[i, i] - trace, 0.0)) / 2
        v[j] = (R[j, i] + R[i, j]) / (4 * v[i])
        v[m] = (R[m, i] + R[i, m]) / (4 * v[i])
        v[3] = (R[m, j] - R[j, m]) / (4 * v[i])
        z = v
    z = z / np.linalg.norm(z)
    return -z if z[3] < 0 else z


def rpy_rates(rpy, omega):
    """(ṙoll, ṗitch, ẏaw) of the angular velocity ω (fixed axes) at `rpy`: zero at rest, also at
    pitch = ±π/2, where otherwise no rates give every ω (ModelError)."""
    roll, pitch, yaw = rpy
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    # ω = E·[ṙoll, ṗitch, ẏaw] with columns Rz·Ry·e_x, Rz·e_y, e_z
    E = np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
    if not np.any(omega):
        return np.zeros(3)                  # at rest: zero rates, gimbal lock or not
    if abs(cp) < 1e-12:
        raise ModelError(f"base_state: at pitch {float(pitch)!r} (±π/2) roll–pitch–yaw rates "
                         "cannot give every angular velocity (gimbal lock): use a model with "
                         "from_urdf(..., base='free')")
    return np.linalg.solve(E, omega)
