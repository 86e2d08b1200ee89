"""The inertial regressor: M(q)·q̈ − F(q, q̇) = Y(q, q̇, q̈)·π over the links' ten inertial
parameters π = (m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz) per link, from the model's
`regressor` or the inertial columns of its `residual_parameter_jacobian`."""
import numpy as np

from ..errors import LagrgenError

#: The ten inertial parameters of a link, in Pinocchio's order: m_<link>, mx_<link>, ...
FIELDS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def inertial_parameters_of(mod):
    """The model's inertial parameter names: `mod.inertial_parameters` when it names some (a
    model built from an articulation, such as a URDF's), else the parameters named
    `<field>_<link>` (FIELDS) of each link with a mass parameter `m_<link>`, by link in
    parameter order."""
    names = _declared_inertial(mod)
    if names:
        return names
    present = set(mod.parameters)
    links = [name[2:] for name in mod.parameters if name.startswith("m_") and len(name) > 2]
    names = tuple(f"{f}_{link}" for link in links for f in FIELDS if f"{f}_{link}" in present)
    if not names:
        raise LagrgenError(
            f"model {mod.name!r} has no inertial parameters: build it with "
            "lagrgen.from_urdf(path, parameters='inertial'), or name its parameters "
            "m_<link>, mx_<link>, my_<link>, mz_<link>, Ixx_<link>, ... in Pinocchio's order")
    return names


def links_of(names):
    """[(link, {field: index in names})] of inertial parameter names `<field>_<link>`."""
    links = {}
    for i, name in enumerate(names):
        head, _, link = name.partition("_")
        links.setdefault(link, {})[head] = i
    return list(links.items())


def _declared_inertial(mod):
    """The inertial parameters the built model declares (empty when it declares none)."""
    return tuple(getattr(mod, "inertial_parameters", None) or ())


def _regressor_function(mod):
    """A function (q, qd, qdd) -> Y (n, k): `mod.regressor` when the model declares its inertial
    parameters, else the columns of the inertial parameters of ∂r/∂p, r = M·q̈ − F (the
    equations being linear in π, these are Y itself)."""
    regressor = getattr(mod, "regressor", None)
    if regressor is not None and _declared_inertial(mod):
        return regressor
    if mod.n_constraints:
        raise LagrgenError(
            f"model {mod.name!r} has constraints: the regressor of M·q̈ − F = Y·π needs a chain "
            "or tree in independent coordinates (write the model without constraints)")
    names = inertial_parameters_of(mod)
    columns = [list(mod.parameters).index(name) for name in names]
    p = np.array(mod.defaults, dtype=float)
    p[columns] = np.where(np.isnan(p[columns]), 1.0, p[columns])   # Y does not depend on π
    n = mod.n_coordinates
    jacobian = mod.residual_parameter_jacobian

    def regressor_from_jacobian(q, qd, qdd):
        return jacobian(q, qd, qdd, 0.0, p)[:n, columns]
    return regressor_from_jacobian


def regressor_of(mod, q, qd, qdd):
    """Y(q, q̇, q̈), (n, k) with M·q̈ − F = Y·π, columns in `inertial_parameters_of(mod)` order."""
    return np.asarray(_regressor_function(mod)(q, qd, qdd), dtype=float)


def stacked_regressor(mod, q, qd, qdd):
    """Y at each of N samples, (N, n, k), from states q, qd, qdd of shape (N, n): one regressor
    call per sample."""
    return _stack(_regressor_function(mod), q, qd, qdd)


def _stack(one, q, qd, qdd):
    """`stacked_regressor` with the regressor function `one`."""
    q, qd, qdd = (np.ascontiguousarray(x, dtype=float) for x in (q, qd, qdd))
    first = np.asarray(one(q[0], qd[0], qdd[0]))
    out = np.empty((len(q),) + first.shape)
    out[0] = first
    for i in range(1, len(q)):
        out[i] = one(q[i], qd[i], qdd[i])
    return out
