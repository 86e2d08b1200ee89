"""`from_sympy`: a lagrgen Model from the equations of motion of `sympy.physics.mechanics`.

SymPy's `LagrangesMethod`, `KanesMethod` and `System` all end in M(q, t)·q̈ = F(q, q̇, t, u). A
Lagrangian's are that already; a `KanesMethod`'s M_u·u̇ = F_u is taken into the coordinates through
its kinematic differential equations solved for the speeds, u = W(q, t)·q̇ + w(q, t) (u = q̇, W = I
with SymPy's default joints): M = Wᵀ·M_u·W, F = Wᵀ·(F_u − M_u·(u̇ − W·q̈)), a speed that no
coordinate's rate needs getting the ignorable coordinate `int_<u>` (`speed_map`), and outputs
named like the speeds giving them back. Those M and F are handed to the Model as they are
(lagrgen compiles them, with their analytic Jacobian); the build's cache key hashes them, so a
changed SymPy model is never served stale.

Constraints become lagrgen's (M·q̈ = F + Aᵀλ, the guide's "Constraints"):

- `LagrangesMethod(L, q, hol_coneqs=Φ, nonhol_coneqs=c)`: each Φ_i(q, t) = 0 is
  `model.constraint(Φ_i)` and each c_i(q, q̇, t) = 0 `model.velocity_constraint(c_i)`; M and F are
  SymPy's without the multiplier columns. SymPy writes M·q̈ = F + lam_coeffsᵀ·λ with
  lam_coeffs = −∂(Φ̇, c)/∂q̇ = −A, so lagrgen's multipliers are the negatives of SymPy's
  `lam_vec`: λ_lagrgen = −λ_SymPy.
- `KanesMethod` with `q_dependent`, `configuration_constraints`, `u_dependent` and
  `velocity_constraints`: Kane's equations are formed again with every coordinate and speed
  independent (the same bodies and loads), which gives M·q̈ = F of the unconstrained system in all
  coordinates; each configuration constraint is a `model.constraint`, and each velocity
  constraint that is not a time derivative of the configuration constraints (independent of their
  Jacobian rows) a `model.velocity_constraint`. Kane's projected equations eliminate the
  multipliers; lagrgen's λ are the constraint forces along A (per unit of each constraint as
  written).
"""
import random

import numpy as np
import scipy.linalg
import sympy as sp
from sympy.core.function import AppliedUndef

from .errors import ModelError
from .model import Model
from .names import check_name, key_name
from .numbers import is_zero


def from_sympy(method_or_system, name, defaults=None, inputs=None):
    """Return a lagrgen `Model` whose equations M(q, t)·q̈ = F(q, q̇, t, u) are those of
    `method_or_system`.

    For a `KanesMethod` (or a `System`, whose equations are formed with `form_eoms()` if they have
    not been) the kinematic differential equations must be solvable for q̇: M·u̇ = F is taken into
    the coordinates through u = W(q, t)·q̇ + w(q, t), a speed that is no coordinate's rate gets
    the ignorable coordinate `int_<u>`, and the model has an output named like each speed (see
    the module docstring). A `System` that forms its equations with `LagrangesMethod` needs
    u = q̇.

    Parameters
    ----------
    method_or_system : sympy.physics.mechanics LagrangesMethod, KanesMethod or System
        Constraints (`hol_coneqs`, `nonhol_coneqs`; Kane's or a System's dependent coordinates
        and speeds) become the model's constraints (see the module docstring for the multipliers'
        sign); auxiliary speeds are refused.
    name : str
        The model's name (a Python identifier; it names the compiled module).
    defaults : dict, optional
        Parameter defaults keyed by Symbol or name. The parameters are the free symbols of M and F
        other than t: first those named in `defaults` (in its order), then the others by name;
        those without a default must be given at run time.
    inputs : list, optional
        The inputs (functions of time, or their names) in the order wanted; every function of time
        in M and F other than the coordinates must be among them. Default: those found, by name.

    Returns
    -------
    lagrgen.Model, with the coordinates `method_or_system.q` (in order), usable like any other Model
    (more physics may be added to it). Its equations come without energies: the outputs
    kinetic_energy, potential_energy and total_energy (and the input power and Rayleigh
    function of `evaluate_outputs`) are NaN; declare what you want to watch with
    `model.output(name, expr)`.
    """
    from sympy.physics.mechanics import dynamicsymbols
    t = dynamicsymbols._t
    q, M, F, holonomic, velocity, speeds = _equations(method_or_system, t)
    coordinates = list(q)
    for c in coordinates:
        if not (isinstance(c, AppliedUndef) and c.args == (t,)):
            raise ModelError(f"coordinate {c} is not a function of time t alone")
    for i, c in enumerate(coordinates):
        if is_zero(M[i, i]) and (holonomic or velocity):
            raise ModelError(
                f"coordinate {c} has no inertia of its own (a zero diagonal entry of the mass "
                "matrix formed with every coordinate independent): lagrgen imposes constraints "
                "through multipliers on M·q̈ = F + Aᵀλ and needs M positive definite. Give the "
                f"body that {c} moves a mass or inertia, or make {c} independent")
        if is_zero(M[i, i]):
            raise ModelError(
                f"SymPy's mass matrix has a zero diagonal entry for coordinate {c}: its equations "
                "do not determine that coordinate's acceleration (a System formed with "
                "LagrangesMethod whose bodies' velocities are written in the speeds u gets M = 0 "
                "from SymPy; form it with KanesMethod, the default)")
    velocities = {c.diff(t) for c in coordinates}
    found_inputs, symbols = set(), set()
    for e in list(M) + list(F) + list(holonomic) + list(velocity):
        symbols |= e.free_symbols
        for d in e.atoms(sp.Derivative):
            if d not in velocities:
                raise ModelError(f"the equations contain {d}: only the coordinates' first "
                                 "derivatives may appear in M and F")
        found_inputs |= {f for f in e.atoms(AppliedUndef) if f not in coordinates}
    parameters = _parameters(symbols - {t}, defaults)
    input_list = _inputs(found_inputs, inputs, t)
    for f in input_list:
        if not (isinstance(f, AppliedUndef) and f.args == (t,)):
            raise ModelError(f"{f} is a function of {f.args}, not of time t alone: lagrgen "
                             "inputs are functions of t")

    model = Model(name)
    new_q = model.coordinates([_name(c.func.__name__, "coordinate", c) for c in coordinates])
    rules = {t: model.t} if t != model.t else {}
    rules.update(zip(coordinates, new_q))
    for s, default in parameters:
        new_p, = model.parameters(s.name) if default is None else \
            model.parameters(**{s.name: default})
        rules[s] = new_p
    if input_list:
        new_u = model.inputs([_name(f.func.__name__, "input", f) for f in input_list])
        rules.update(zip(input_list, new_u))
    model._add_equations(M.xreplace(rules), F.xreplace(rules))
    for expr in holonomic:
        model.constraint(expr.xreplace(rules))
    for expr in velocity:
        model.velocity_constraint(expr.xreplace(rules))
    for speed, expr in speeds:
        model.output(_name(speed.func.__name__, "speed", speed), expr.xreplace(rules))
    return model


def _name(name, what, obj):
    try:
        return check_name(name, what)
    except ModelError:
        raise ModelError(f"the {what} {obj} is named {name!r}, which is not a Python identifier; "
                         "lagrgen's names become C and Python names: rename it in the SymPy model "
                         "(e.g. dynamicsymbols('q1') or symbols('m_1'))") from None


def _parameters(symbols, defaults):
    """[(Symbol, default or None)]: those named in `defaults` first (in its order), then by name."""
    by_name = {}
    for s in symbols:
        _name(s.name, "parameter", s)
        if s.name in by_name:
            raise ModelError(f"two different symbols are both named {s.name!r} (different "
                             "assumptions?): give them different names")
        by_name[s.name] = s
    given = {}
    for key, value in (defaults or {}).items():
        kname = key_name(key)
        if kname not in by_name:
            known = ", ".join(sorted(by_name)) or "none"
            raise ModelError(f"defaults: {kname!r} is not a parameter of the equations (their "
                             f"parameters are {known})")
        given[kname] = value
    order = list(given) + sorted(set(by_name) - set(given))
    return [(by_name[k], given.get(k)) for k in order]


def _inputs(found, inputs, t):
    """The inputs in order: `inputs` (functions or names) if given, else those found, by name."""
    by_name = {}
    for f in found:
        fname = f.func.__name__
        if fname in by_name:
            raise ModelError(f"two different functions are both named {fname!r}")
        by_name[fname] = f
    if inputs is None:
        return [by_name[k] for k in sorted(by_name)]
    if isinstance(inputs, str):
        inputs = inputs.replace(",", " ").split()
    names = [key_name(k) for k in inputs]
    missing = sorted(set(by_name) - set(names))
    if missing:
        raise ModelError(f"the equations depend on {', '.join(missing)}, which "
                         f"{'is' if len(missing) == 1 else 'are'} not among the inputs given")
    if len(set(names)) != len(names):
        raise ModelError(f"inputs: a name is given twice in {names}")
    return [by_name.get(k, sp.Function(k)(t)) for k in names]


def _equations(obj, t):
    """(q, M, F, holonomic, velocity, speeds) of `obj`: M·q̈ = F, the holonomic constraints
    Φ(q, t), the velocity constraints c(q, q̇, t), and [(speed, its expression in q, q̇)] of a
    KanesMethod, in SymPy's own symbols."""
    from sympy.physics.mechanics import KanesMethod, LagrangesMethod, System
    if isinstance(obj, System):
        if len(obj.u_aux):
            raise ModelError("this System has auxiliary speeds, which from_sympy does not "
                             "support: form the equations without them")
        if obj.eom_method is None:
            try:
                obj.form_eoms()
            except ValueError as exc:
                raise ModelError(f"SymPy could not form the System's equations: {exc}") from None
        system, obj = obj, obj.eom_method
        if isinstance(obj, LagrangesMethod):
            _no_system_constraints(system)
            # the bodies' velocities may be written in the System's speeds: u = q̇ puts them back
            q, M, F, holonomic, velocity = _lagrange(obj)
            rates = _rates_of_speeds(list(system.q), list(system.u), list(system.kdes), t)
            return q, M.xreplace(rates), F.xreplace(rates), holonomic, velocity, []
    if isinstance(obj, LagrangesMethod):
        return (*_lagrange(obj), [])
    if isinstance(obj, KanesMethod):
        return _kane(obj, t)
    raise TypeError(f"from_sympy() takes a sympy.physics.mechanics LagrangesMethod, KanesMethod "
                    f"or System, got {type(obj).__name__}")


def _rates_of_speeds(q, u, kdes, t):
    """{u_j: q̇_i} from kinematic equations that say u = q̇ (in any order); ModelError otherwise."""
    if not u:
        return {}
    solved = sp.solve(kdes, u, dict=True) if len(kdes) == len(u) else []
    rates = {qi.diff(t) for qi in q}
    if len(solved) != 1 or any(solved[0].get(uj) not in rates for uj in u) \
            or len(set(solved[0].values())) != len(u):
        raise ModelError(f"the kinematic differential equations {list(kdes)} are not u = q̇: "
                         "from_sympy needs every generalized speed to be a coordinate's rate (as "
                         "with SymPy's default joints)")
    return solved[0]


def _no_system_constraints(system):
    for what, attr in (("holonomic constraints", "holonomic_constraints"),
                       ("nonholonomic constraints", "nonholonomic_constraints"),
                       ("dependent coordinates", "q_dep"), ("dependent speeds", "u_dep"),
                       ("auxiliary speeds", "u_aux")):
        if len(getattr(system, attr)):
            raise ModelError(f"this System has {what} and forms its equations with "
                             "LagrangesMethod, which from_sympy does not support: form them with "
                             "KanesMethod (System.form_eoms(), the default)")


def _lagrange(lm):
    """(q, M, F, Φ, c) of a LagrangesMethod: M and F without the multiplier columns."""
    if getattr(lm, "eom", None) is None:
        lm.form_lagranges_equations()
    n = len(lm.q)
    holonomic = list(getattr(lm, "_hol_coneqs", ()))
    velocity = list(lm.coneqs[len(holonomic):]) if len(lm.coneqs) else []
    M = sp.Matrix(lm.mass_matrix)[:, :n]
    return list(lm.q), M, sp.Matrix(lm.forcing), holonomic, velocity


def _kane(km, t):
    """(q, M, F, Φ, c, speeds) of a KanesMethod with any kinematic differential equations that
    can be solved for q̇ (see the module docstring)."""
    if len(getattr(km, "_uaux", ())):
        raise ModelError("this KanesMethod has auxiliary speeds, which from_sympy does not "
                         "support: form the equations without u_auxiliary")
    if getattr(km, "_bodylist", None) is None or getattr(km, "_fr", None) is None:
        raise ModelError("the KanesMethod has no equations yet: call kanes_equations(bodies, "
                         "loads) first")
    constrained = bool(len(getattr(km, "_qdep", ())) or len(getattr(km, "_udep", ())))
    full = _all_speeds_independent(km) if constrained else km
    M_u, F_u = sp.Matrix(full.mass_matrix), sp.Matrix(full.forcing)
    u = list(km.u)
    for e in list(M_u) + list(F_u):
        left = {d for d in e.atoms(sp.Derivative) if d.expr in u}
        if left:
            raise ModelError(f"the equations contain the speed derivatives {left}")
    kinematics = speed_map(km, t)
    q = kinematics.coordinates
    W = kinematics.W
    to_speeds = dict(zip(u, kinematics.speeds))
    M = W.T * M_u * W
    F = W.T * (F_u.xreplace(to_speeds) - M_u * kinematics.convective)
    holonomic = [sp.sympify(e) for e in km._f_h]
    velocity = []
    if len(km._k_nh):
        rows = km._k_nh * sp.Matrix(u) + km._f_nh
        velocity = [sp.sympify(e).xreplace(to_speeds) for e in rows]
    return (q, M, F, holonomic, _nonholonomic(q, holonomic, velocity, t),
            list(zip(u, kinematics.speeds)))


def _all_speeds_independent(km):
    """Kane's equations of `km` formed again with every coordinate and speed independent."""
    from sympy.physics.mechanics import KanesMethod
    kd_eqs = [rate - value for rate, value in km.kindiffdict().items()]
    free = KanesMethod(km._inertial, q_ind=list(km.q), u_ind=list(km.u), kd_eqs=kd_eqs)
    free.kanes_equations(km._bodylist, km._forcelist or [])
    return free


class SpeedMap:
    """The speeds u in the coordinates' rates: u = W(q, t)·q̇ + w(q, t), for the coordinates
    `coordinates` (the KanesMethod's, then one ignorable `int_<u>` per speed that is no
    coordinate's rate), and `convective` = u̇ − W·q̈ = Σ_j ∂(W·q̇ + w)/∂q_j·q̇_j + ∂(W·q̇ + w)/∂t."""

    def __init__(self, coordinates, W, w, t):
        self.coordinates = coordinates
        self.W = W
        rates = sp.Matrix([qi.diff(t) for qi in coordinates])
        self.speeds = list(W * rates + w)
        Q = [sp.Dummy(f"Q{i}") for i in range(len(coordinates))]
        V = [sp.Dummy(f"V{i}") for i in range(len(coordinates))]
        to_dummies = {**dict(zip(rates, V))}
        plain = [e.xreplace(to_dummies).xreplace(dict(zip(coordinates, Q))) for e in self.speeds]
        back = {**dict(zip(Q, coordinates)), **dict(zip(V, rates))}
        self.convective = sp.Matrix([
            (sum((sp.diff(e, Qj) * Vj for Qj, Vj in zip(Q, V)), sp.Integer(0))
             + sp.diff(e, t)).xreplace(back) for e in plain])


def speed_map(km, t):
    """The SpeedMap of a KanesMethod, from its kinematic differential equations
    k_q̇·q̇ + k_u·u + f = 0 (n rows for n coordinates and p ≥ n speeds): the p − n speeds that
    no equation needs get ignorable coordinates int_<u> with int_u̇ = u, and the p×p system is
    solved for u."""
    from sympy.physics.mechanics import dynamicsymbols
    q, u = list(km.q), list(km.u)
    n, p = len(q), len(u)
    k_qd, k_u, f = _kinematic_matrices(km, t)
    if p < n:
        raise ModelError(
            f"the KanesMethod has {p} speeds for {n} coordinates: each coordinate's rate must "
            "follow from the speeds and each speed from the rates; add speeds, or make the "
            "coordinates whose rates are prescribed functions of time")
    extra = [u[j] for j in _speeds_without_coordinates(k_u, n, p)]
    names = {str(c.func) for c in q}
    ignorable = []
    for speed in extra:
        name = f"int_{speed.func.__name__}"
        if name in names:
            raise ModelError(f"the speed {speed} has no coordinate and the name {name!r} of the "
                             "ignorable coordinate lagrgen would give it is taken: rename it")
        ignorable.append(dynamicsymbols(name))
    rows_u = k_u.col_join(sp.Matrix(len(extra), p, lambda i, j: int(u[j] == extra[i])))
    rows_qd = sp.diag(k_qd, -sp.eye(len(extra))) if extra else k_qd
    rhs = -(rows_qd.row_join(f.col_join(sp.zeros(len(extra), 1))))
    try:
        solved = rows_u.LUsolve(rhs)
    except (ValueError, ZeroDivisionError, NotImplementedError) as exc:
        raise ModelError(f"the kinematic differential equations cannot be solved for the "
                         f"speeds ({exc}): each speed must follow from the coordinates' rates "
                         "(q̇ = N(q, t)·u + n(q, t) with N of full rank)") from None
    return SpeedMap(q + ignorable, solved[:, :p], solved[:, p], t)


def _kinematic_matrices(km, t):
    """(k_q̇, k_u, f) of the kinematic differential equations k_q̇·q̇ + k_u·u + f = 0 as the user
    wrote them (SymPy keeps them; otherwise from q̇ = kindiffdict: k_q̇ = I)."""
    implicit = [getattr(km, name, None) for name in
                ("_k_kqdot_implicit", "_k_ku_implicit", "_f_k_implicit")]
    if all(m is not None and len(m) for m in implicit):
        return tuple(sp.Matrix(m) for m in implicit)
    q, u = list(km.q), list(km.u)
    solved = km.kindiffdict()
    rates = sp.Matrix([solved[qi.diff(t)] for qi in q])
    k_u = -rates.jacobian(u)
    return sp.eye(len(q)), k_u, -rates.xreplace(dict.fromkeys(u, 0))


def _speeds_without_coordinates(k_u, n, p, seed=0):
    """Indices of the p − n speeds to give ignorable coordinates: those the kinematic equations
    can spare, i.e. outside n columns of k_u that are independent (pivoted QR at a random point;
    a speed in no equation is spared first)."""
    if p == n:
        return []
    numeric = _at_random_point(k_u, seed)
    _, r, order = scipy.linalg.qr(numeric, pivoting=True)
    diag = np.abs(np.diag(r))
    if diag.size < n or not diag[n - 1] > 1e-9 * max(diag[0], 1e-300):
        raise ModelError(
            "the kinematic differential equations do not determine the speeds: their "
            "coefficients of the speeds have rank below the number of coordinates (a "
            "coordinate whose rate no speed sets?)")
    return sorted(int(j) for j in order[n:])


def _at_random_point(matrix, seed=0):
    """`matrix` as floats at a random point of its symbols and functions of time."""
    rng = random.Random(seed)
    atoms = set()
    for e in matrix:
        atoms |= set(e.atoms(sp.Derivative)) | set(e.atoms(AppliedUndef)) | e.free_symbols
    point = {a: sp.Float(rng.uniform(0.3, 1.3)) for a in atoms}
    values = [[complex(sp.sympify(matrix[i, j]).xreplace(point).doit().evalf()).real
               for j in range(matrix.shape[1])] for i in range(matrix.shape[0])]
    return np.array(values, dtype=float).reshape(matrix.shape)


def _nonholonomic(q, holonomic, velocity, t, seed=0):
    """The velocity constraints whose rows ∂c/∂q̇ are independent of the holonomic constraints'
    ∂Φ/∂q and of each other (at a random point): those that are not Φ̇ = 0 restated."""
    if not velocity:
        return []
    rates = [qi.diff(t) for qi in q]
    rows = [[sp.diff(e, qi) for qi in q] for e in holonomic] + \
           [[sp.diff(e, r) for r in rates] for e in velocity]
    numeric = _at_random_point(sp.Matrix(rows), seed).tolist()
    chosen, basis = [], [numeric[i] for i in range(len(holonomic))]
    for k, e in enumerate(velocity):
        trial = basis + [numeric[len(holonomic) + k]]
        if np.linalg.matrix_rank(np.array(trial), tol=1e-9 * max(1.0, np.abs(trial).max())) \
                == len(trial):
            basis, chosen = trial, chosen + [e]
    return chosen
