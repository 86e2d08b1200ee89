"""The model description: coordinates, parameters, inputs and the physics, recorded as the typed
records of `lagrgen.records` (SymPy expressions, checked by `lagrgen.checks`).

`Description` only records what the user says; `Description.spec()` freezes it into a `ModelSpec`,
from which `lagrgen.lagrange` derives the equations of motion. `lagrgen.Model` is this class plus
the derived equations.
"""
import math

import sympy as sp

from .caching import once_per
from .checks import (as_vector, check_affine_in_velocities, check_coefficient,
                     check_distinct_gap, check_expression, check_restitution,
                     check_static_coefficient, check_unit, split_names, split_units)
from .errors import ModelError, UnknownNameError
from .names import check_model_name, check_name
from .numbers import finite_number, is_zero
from .records import (AUTOMATIC_OUTPUTS, BAUMGARTE_DEFAULTS, ENERGY_OUTPUTS, Body3D, Constraint,
                      Damper, Dissipation, Event, ExternalEquations, Force, GeneralizedForce,
                      Friction, Impact, KineticEnergy, ModelSpec, Output, Particle, PlanarBody,
                      PotentialEnergy, Spring, Torque, VelocityConstraint, frozen)

#: Drawing shapes of rigid bodies (see `Description.rigid_body`).
SHAPES = ("disk", "bar", "box")
#: The largest count an event's `terminal` may take (a C int in the compiled code).
MAX_EVENT_COUNT = 2**31 - 1


class Description:
    """What the user declares about a mechanical system, recorded as typed records (the base of
    `lagrgen.Model`, which adds the derived equations).

    Lagrange's equations d/dt(∂T/∂q̇) − ∂T/∂q + ∂V/∂q + ∂R/∂q̇ = Q are derived from what is added here.
    """

    def __init__(self, name):
        self._name = check_model_name(name)
        self.t = sp.Symbol("t")
        self._names = {"t": "time"}
        self._coordinates = []
        self._parameters = []
        self._defaults = []
        self._inputs = []
        self._physics = []         # records of lagrgen.records: what enters T, V, R and Q
        self._external = None      # ExternalEquations (lagrgen.from_sympy), added as given
        self._drawables = []       # (kind, points): what an animation can draw
        self._outputs = []         # Output records: named quantities evaluated along a solution
        self._units = {}           # name -> unit label (coordinates, parameters, inputs, outputs)
        self._constraints = []     # Constraint records: Φ(q, t) = 0
        self._velocity_constraints = []  # VelocityConstraint records: A(q, t)·q̇ + b(q, t) = 0
        self._events = []          # Event records: roots of g located by the solvers
        self._nonsmooth = []       # Impact / Friction records, in declaration order
        self._initial = None       # {coordinate name: (q0, q̇0)}: the declared initial state
        self._limits = {}          # coordinate name -> (lower, upper, velocity, effort)
        self._stops = {}           # coordinate name -> restitution of its enforced range
        self._stabilization = BAUMGARTE_DEFAULTS
        self._kinematics = {}      # orientation → bodies3d.Kinematics, computed once each

    @property
    def name(self):
        """The model's name (read-only: it names the compiled module and its files)."""
        return self._name

    # -- declarations -------------------------------------------------------------------------
    def _declare(self, name, what):
        if name in self._names:
            raise ModelError(
                f"{what} name {name!r} is already used for the {self._names[name]} of model "
                f"{self.name!r}: names must be unique within a model")
        velocity_of = name[:-4] if name.endswith("_dot") else None
        if self._names.get(velocity_of) == "coordinate" or (
                what == "coordinate" and f"{name}_dot" in self._names):
            coordinate = velocity_of if self._names.get(velocity_of) == "coordinate" else name
            other = name if velocity_of == coordinate else f"{name}_dot"
            raise ModelError(
                f"{what} name {name!r} clashes with the velocity name {coordinate + '_dot'!r} of "
                f"coordinate {coordinate!r} (model {self.name!r}): states are named "
                f"<coordinate> and <coordinate>_dot in y0, results, fits and FMUs, so "
                f"{other!r} would name two things; rename the {self._names.get(other, what)}")
        self._names[name] = what

    def coordinates(self, names, units=None):
        """Declare generalized coordinates; return them as SymPy functions of t, in order.

        `units` (optional): one unit label per name, e.g. ``coordinates("x theta", units="m rad")``.
        """
        names = split_names(names, "coordinate")
        labels = split_units(units, names, "coordinate")
        new = []
        for name in names:
            self._declare(name, "coordinate")
            new.append(sp.Function(name)(self.t))
        self._coordinates.extend(new)
        self._units.update(labels)
        self._changed()
        return tuple(new)

    def parameters(self, *names, **defaults):
        """Declare constant parameters (keyword = default value); return them as SymPy symbols.

        A default may be a pair ``(value, "unit")``, e.g. ``parameters(m=(1.0, "kg"))``. Names
        without defaults (given at run time) may be positional: ``parameters("m k")`` or
        ``parameters("m", "k")``.
        """
        positional = [n for group in names
                      for n in (split_names(group, "parameter") if isinstance(group, str) else [group])]
        entries = [(n, None) for n in positional] + list(defaults.items())
        if not entries:
            raise ModelError("no parameter names given")
        new = []
        for name, default in entries:
            check_name(name, "parameter")
            if isinstance(default, tuple):
                if len(default) != 2:
                    raise ModelError(f"parameter {name!r}: give a default, or (default, 'unit'), "
                                     f"got {default!r}")
                default, unit = default
                self._units[name] = check_unit(unit, f"parameter {name!r}")
            if default is not None:
                try:
                    default = float(default)
                except (TypeError, ValueError):
                    raise ModelError(
                        f"default of parameter {name!r} must be a number, got {default!r}") from None
                if not math.isfinite(default):
                    raise ModelError(f"default of parameter {name!r} must be finite, got {default}")
            self._declare(name, "parameter")
            symbol = sp.Symbol(name)
            self._parameters.append(symbol)
            self._defaults.append(default)
            new.append(symbol)
        self._changed()
        return tuple(new)

    def inputs(self, names, units=None):
        """Declare time-varying inputs (values given at run time); return SymPy functions of t.

        `units` (optional): one unit label per name, e.g. ``inputs("F", units="N")``.
        """
        names = split_names(names, "input")
        labels = split_units(units, names, "input")
        new = []
        for name in names:
            self._declare(name, "input")
            new.append(sp.Function(name)(self.t))
        self._inputs.extend(new)
        self._units.update(labels)
        self._changed()
        return tuple(new)

    def output(self, name, expr, units=None):
        """Declare a named scalar output y = expr(q, q̇, t, p, u), evaluated along a solution.

        Parameters
        ----------
        name : str
            A new name (not one of the automatic outputs ``kinetic_energy``, ... ).
        expr : SymPy expression of the coordinates, velocities, t, parameters and inputs.
        units : str, optional
            A unit label (never changes a number).

        Returns
        -------
        The expression, sympified.
        """
        check_name(name, "output")
        if name in AUTOMATIC_OUTPUTS:
            raise ModelError(f"output name {name!r} is provided automatically; choose another name")
        expr = self._check(expr, f"output {name!r}")
        if isinstance(expr, sp.MatrixBase):
            if len(expr) != 1:
                raise ModelError(f"output {name!r} must be one scalar, got a {expr.shape} matrix; "
                                 "declare one output per component")
            expr = expr[0]
        self._declare(name, "output")
        if units is not None:
            self._units[name] = check_unit(units, f"output {name!r}")
        self._outputs.append(Output(name, expr))
        self._changed()
        return expr

    # -- what has been declared ---------------------------------------------------------------
    @property
    def q(self):
        """The generalized coordinates q_i(t), in declaration order."""
        return tuple(self._coordinates)

    @property
    def qd(self):
        """The generalized speeds dq_i/dt, in declaration order."""
        cached = self.__dict__.get("_speeds")
        if cached is None or len(cached) != len(self._coordinates):
            cached = tuple(sp.Derivative(c, self.t) for c in self._coordinates)
            self.__dict__["_speeds"] = cached
        return cached

    @property
    def parameter_symbols(self):
        return tuple(self._parameters)

    @property
    def input_functions(self):
        return tuple(self._inputs)

    @property
    def coordinate_names(self):
        return tuple(c.func.__name__ for c in self._coordinates)

    @property
    def parameter_names(self):
        return tuple(s.name for s in self._parameters)

    @property
    def input_names(self):
        return tuple(u.func.__name__ for u in self._inputs)

    @property
    def output_names(self):
        """The user's outputs, then "kinetic_energy", "potential_energy", "total_energy"."""
        return tuple(o.name for o in self._outputs) + ENERGY_OUTPUTS

    @property
    def units(self):
        """{name: unit label} of the coordinates, parameters, inputs and outputs that have one."""
        return dict(self._units)

    @property
    def parameter_defaults(self):
        """Defaults in parameter order; None where a value must be given at run time."""
        return tuple(self._defaults)

    # -- checking expressions -----------------------------------------------------------------
    def _check(self, expr, where, velocities=True, inputs=True, vector=False):
        """`expr` sympified and checked against this model's declarations (`checks.check_expression`)."""
        return check_expression(self, expr, where, velocities, inputs, vector)

    def _coordinate(self, coordinate):
        if isinstance(coordinate, str):
            for c in self._coordinates:
                if c.func.__name__ == coordinate:
                    return c
        elif coordinate in set(self._coordinates):     # hashed: SymPy's == is slow
            return coordinate
        raise ModelError(
            f"{coordinate!r} is not a generalized coordinate of model {self.name!r} "
            f"(its coordinates are {', '.join(self.coordinate_names) or 'none'})")

    def _changed(self):
        _frozen_spec.forget(self)

    def _add(self, record):
        """Record one physics term (a record of `lagrgen.records`)."""
        self._physics.append(record)
        self._changed()

    # -- physics ------------------------------------------------------------------------------
    def particle(self, mass, position):
        """T += ½·mass·ṙ·ṙ with ṙ the total time derivative of `position` (1 to 3 components)."""
        mass = self._check(mass, "particle mass", velocities=False, inputs=False)
        position = self._check(as_vector(position, "particle position"), "particle position",
                               velocities=False, inputs=False, vector=True)
        self._drawables.append(("point", (position, mass)))
        self._add(Particle(mass, frozen(position)))

    def rigid_body(self, mass, inertia, position, angle, shape=None):
        """Planar rigid body: T += ½·mass·ṙ·ṙ + ½·inertia·(d angle/dt)², position of its centre of mass.

        `shape` (drawing only) is ``("disk", r)``, ``("bar", length)`` or ``("box", width,
        height)``, drawn about the centre of mass and rotating with `angle`; the size entries may be
        numbers or parameter expressions.
        """
        shape = self._shape(shape)
        mass = self._check(mass, "rigid body mass", velocities=False, inputs=False)
        inertia = self._check(inertia, "rigid body inertia", velocities=False, inputs=False)
        position = self._check(as_vector(position, "rigid body position"), "rigid body position",
                               velocities=False, inputs=False, vector=True)
        angle = self._check(angle, "rigid body angle", velocities=False, inputs=False)
        self._drawables.append(("body", (position, angle, shape, mass)))
        self._add(PlanarBody(mass, inertia, frozen(position), angle))

    def _shape(self, shape):
        if shape is None:
            return None
        if isinstance(shape, str):
            shape = (shape,)
        shape = tuple(shape)
        sizes = {"disk": 1, "bar": 1, "box": 2}
        if not shape or shape[0] not in sizes:
            raise ModelError(f"unknown body shape {shape[:1]!r}: use ('disk', r), ('bar', length) "
                             "or ('box', width, height)")
        if len(shape) != 1 + sizes[shape[0]]:
            raise ModelError(f"shape {shape[0]!r} needs {sizes[shape[0]]} size(s), got {shape[1:]!r}")
        return (shape[0],) + tuple(self._check(v, f"{shape[0]} size", velocities=False,
                                               inputs=False) for v in shape[1:])

    def rigid_body_3d(self, mass, inertia, position, orientation, name=None):
        """Rigid body in space: T += ½·mass·ṙ·ṙ + ½·ωᵀ·I·ω, with ω the body-frame angular velocity
        (ω̃ = Rᵀ·Ṙ) of the orientation R.

        Parameters
        ----------
        mass : expression, the body's mass.
        inertia : 3×3 matrix (symmetric, positive semi-definite), or 3 principal moments (list or
            tuple), about the centre of mass in body axes; constant (parameters and numbers only).
        position : 3 components, the centre of mass in the fixed frame (coordinates, t).
        orientation : 3×3 rotation matrix R(q, t) mapping body-frame components to fixed-frame
            ones, best built from `lagrgen.rotation` (``rotation.z(psi) * rotation.x(theta)``).
        name : str, optional, the body's name as a link (`link_position`; default body<k>, k
            counting the 3-D bodies in declaration order).
        """
        from .bodies3d import body_inertia
        if name is not None:
            check_name(name, "rigid_body_3d name")
            if name in self.link_names:
                raise ModelError(f"rigid_body_3d: model {self.name!r} already has a link "
                                 f"{name!r}")
        mass = self._check(mass, "rigid body mass", velocities=False, inputs=False)
        inertia = body_inertia(self, inertia)
        position = self._check(as_vector(position, "rigid body position"), "rigid body position",
                               velocities=False, inputs=False, vector=True)
        if len(position) != 3:
            raise ModelError(f"rigid_body_3d position must have 3 components (x, y, z), got "
                             f"{len(position)}")
        kin = self._orientation(orientation, "rigid_body_3d orientation")
        self._drawables.append(("body3d", (position, kin.R)))
        self._add(Body3D(mass, frozen(position), frozen(inertia), frozen(kin.omega), frozen(kin.R),
                          frozen(kin.omega_fixed), name))

    @property
    def link_names(self):
        """The model's links: a URDF robot's links, then its `rigid_body_3d` bodies (named, or
        body<k>), in order."""
        from .links import link_names
        return link_names(self._physics)

    def link_position(self, link, point=(0, 0, 0)):
        """The position in the fixed frame of a point fixed in a link.

        Parameters
        ----------
        link : str, one of `link_names` (a URDF link, or a rigid_body_3d's name)
        point : 3 numbers or parameter expressions, the point in the link's frame (a URDF
            link's frame; a rigid_body_3d's frame is at its centre of mass, along its body axes)

        Returns
        -------
        sympy.Matrix (3×1): p_link + R_link·point in the model's symbols
        """
        from .links import pose
        R, p = pose(self._physics, link, self.name)
        return p + R * self._link_point(point)

    def link_rotation(self, link):
        """The orientation of a link's frame in the fixed frame: the 3×3 SymPy Matrix R with
        x_fixed = R·x_link."""
        from .links import pose
        return pose(self._physics, link, self.name)[0]

    def _link_point(self, point):
        """`point` as a 3×1 Matrix of constants (numbers and parameters)."""
        where = "link point"
        point = self._check(as_vector(point, where), where, velocities=False, inputs=False,
                            vector=True)
        if len(point) != 3:
            raise ModelError(f"a {where} has 3 components (x, y, z in the link's frame), got "
                             f"{len(point)}")
        if any(point.has(c) for c in self._coordinates):
            raise ModelError(f"a {where} is fixed in its link: it must not depend on the "
                             "coordinates")
        return point

    def torque_3d(self, moment, orientation):
        """A moment acting on the body of orientation R: Q_j += moment · ∂ω_fixed/∂q̇_j.

        Parameters
        ----------
        moment : 3 components in the fixed frame (may depend on q, q̇, t, inputs).
        orientation : the body's 3×3 rotation matrix, as given to `rigid_body_3d`.
        """
        moment = self._check(as_vector(moment, "torque_3d moment"), "torque_3d moment",
                             vector=True)
        if len(moment) != 3:
            raise ModelError(f"torque_3d moment must have 3 components, got {len(moment)}")
        kin = self._orientation(orientation, "torque_3d orientation")
        for j, coordinate in enumerate(self._coordinates):
            arm = kin.W_fixed[:, j]
            if not all(is_zero(e) for e in arm):
                self._add(GeneralizedForce(coordinate, moment.dot(arm)))

    def _orientation(self, orientation, where):
        """The checked `bodies3d.Kinematics` of a 3×3 orientation matrix (computed once each)."""
        from .bodies3d import Kinematics, check_rotation
        if not isinstance(orientation, sp.MatrixBase) or orientation.shape != (3, 3):
            shape = getattr(orientation, "shape", None)
            raise ModelError(f"{where} must be a 3×3 SymPy Matrix (e.g. from lagrgen.rotation), "
                             f"got {type(orientation).__name__}" + (f" of shape {shape}" if shape
                                                                    else ""))
        self._check(orientation, where, velocities=False, inputs=False, vector=True)
        key = (sp.ImmutableMatrix(orientation), getattr(orientation, "factors", None))
        if key not in self._kinematics:
            check_rotation(orientation, [*self._coordinates, self.t, *self._parameters], where)
            self._kinematics[key] = Kinematics(orientation, self._coordinates, self.t)
        return self._kinematics[key]

    def kinetic_energy(self, expr):
        """T += expr (may contain coordinates, velocities, t and parameters)."""
        self._add(KineticEnergy(self._check(expr, "kinetic energy", inputs=False)))

    def potential_energy(self, expr):
        """V += expr (coordinates, t, parameters, inputs)."""
        self._add(PotentialEnergy(self._check(expr, "potential energy", velocities=False)))

    def spring(self, k, length, rest=0, ends=None):
        """V += ½·k·(length − rest)²; `ends=(a, b)` optionally names the two points it joins."""
        k = self._check(k, "spring stiffness", velocities=False)
        length = self._check(length, "spring length", velocities=False, inputs=False)
        rest = self._check(rest, "spring rest length", velocities=False)
        self._add_ends("spring", ends)
        self._add(Spring(k, length, rest))

    def damper(self, c, length, ends=None):
        """Rayleigh R += ½·c·(d length/dt)²; `ends=(a, b)` optionally names the two points it joins."""
        c = self._check(c, "damping coefficient", velocities=False)
        length = self._check(length, "damper length", velocities=False, inputs=False)
        self._add_ends("damper", ends)
        self._add(Damper(c, length))

    def dissipation(self, expr):
        """R += expr, a Rayleigh dissipation function of the velocities."""
        self._add(Dissipation(self._check(expr, "dissipation function")))

    def force(self, vector, at):
        """Q_j += vector · ∂at/∂q_j (virtual work of a force applied at the point `at`)."""
        vector = self._check(as_vector(vector, "force"), "force", vector=True)
        at = self._check(as_vector(at, "force point"), "force point", velocities=False, inputs=False, vector=True)
        if len(vector) != len(at):
            raise ModelError(
                f"force has {len(vector)} components but its point of application has {len(at)}")
        self._add(Force(frozen(vector), frozen(at)))

    def torque(self, moment, angle):
        """Q_j += moment · ∂angle/∂q_j."""
        moment = self._check(moment, "torque")
        angle = self._check(angle, "torque angle", velocities=False, inputs=False)
        self._add(Torque(moment, angle))

    def generalized_force(self, coordinate, expr):
        """Q_j += expr for the coordinate j given (its function or its name)."""
        coordinate = self._coordinate(coordinate)
        expr = self._check(expr, "generalized force")
        self._add(GeneralizedForce(coordinate, expr))

    # -- constraints --------------------------------------------------------------------------
    def constraint(self, expr, name=None):
        """Add a holonomic constraint Φ(q, t) = 0 (coordinates, t and parameters only; an
        equation lhs = rhs means lhs − rhs = 0).

        Its multiplier λ_i enters the equations as M·q̈ = F + Φ_qᵀ·λ (see `lagrgen.lagrange`);
        `name` (an identifier) names λ_i in results (`sol.multipliers[name]`), CSV columns and
        `show`; unnamed constraints are lambda1, lambda2, ... in the order of `constraint_names`.
        """
        where = f"constraint {len(self._constraints) + 1}"
        expr = self._check(self._equation(expr), where, velocities=False, inputs=False)
        if not any(expr.has(c) for c in self._coordinates):
            raise ModelError(f"{where} ({expr} = 0) does not involve any coordinate: it is not a "
                             "constraint on the motion")
        self._name_constraint(name)
        self._constraints.append(Constraint(expr, name))
        self._changed()

    def _name_constraint(self, name):
        if name is None:
            return
        check_name(name, "constraint name")
        if name.startswith("lambda") and name[6:].isdigit():
            raise ModelError(f"constraint name {name!r} is reserved for unnamed constraints; "
                             "choose another name")
        self._declare(name, "constraint")

    def initial_state(self, q=None, qd=None):
        """Declare the model's initial state y0 = [q0, q̇0], which `simulate`, `simulate_many`,
        `sweep`, the command line and FMU start values use when no initial state is given.

        Parameters
        ----------
        q, qd : dict of coordinate names (or the coordinates model.coordinates returned) ->
            number, or a sequence of one number per coordinate; coordinates not given start
            at 0 (qd: at rest). Each call replaces the whole initial state.
        """
        names = self.coordinate_names
        if not names:
            raise ModelError("initial_state: declare the coordinates first")
        start = {c: [0.0, 0.0] for c in names}
        for k, (what, given) in enumerate((("q", q), ("qd", qd))):
            for name, value in self._state_values(what, given, names).items():
                start[name][k] = value
        self._initial = {c: tuple(v) for c, v in start.items()}
        self._changed()

    def _state_values(self, what, given, names):
        """{coordinate name: float} of one part of `initial_state` (see there)."""
        if given is None:
            return {}
        if isinstance(given, dict):
            items = {}
            for key, value in given.items():
                name = key if isinstance(key, str) else getattr(getattr(key, "func", None),
                                                                "__name__", None)
                if name not in names:
                    raise ModelError(f"initial_state {what}: {key!r} is not a coordinate of "
                                     f"model {self.name!r} (its coordinates are "
                                     f"{', '.join(names)})")
                items[name] = value
        else:
            values = list(given) if not isinstance(given, str) else None
            if values is None or len(values) != len(names):
                raise ModelError(f"initial_state {what}: give a dict of coordinate names or "
                                 f"{len(names)} numbers (one per coordinate {', '.join(names)}), "
                                 f"got {given!r}")
            items = dict(zip(names, values))
        return {name: finite_number(value, f"initial_state {what}[{name!r}]", ModelError)
                for name, value in items.items()}

    @property
    def initial_values(self):
        """The declared initial state [q0, q̇0] as 2n floats in coordinate order (coordinates
        declared after it start at 0), or () when none was declared."""
        if self._initial is None:
            return ()
        names = self.coordinate_names
        pairs = [self._initial.get(c, (0.0, 0.0)) for c in names]
        return tuple(q for q, _ in pairs) + tuple(qd for _, qd in pairs)

    def limit(self, coordinate, lower=None, upper=None, velocity=None, effort=None,
              enforce=False, restitution=0.0):
        """Declare a coordinate's limits: its range lower ≤ q ≤ upper, its largest speed
        abs(q̇) ≤ velocity and the largest effort abs(tau_<coordinate>) ≤ effort of the input that
        drives it (a URDF joint's <limit>); None leaves one out. Each call replaces that
        coordinate's limits; `model.limits` lists them and a built model keeps them
        (`mod.limits`), which `Collocation.bound_limits()` turns into bounds.

        Parameters
        ----------
        coordinate : str or the function `model.coordinates` returned
        lower, upper : float or None, lower ≤ upper
        velocity, effort : float ≥ 0 or None
        enforce : bool
            True: the range acts in simulations as two unilateral contacts, stops named
            <coordinate>_lower (gap q − lower) and <coordinate>_upper (gap upper − q), struck
            with the `restitution` (0: inelastic; a stop reached at rest holds the coordinate
            there until the force on it pulls away), as `impact`s in `simulate` and
            `simulate_many` on both engines. Other tools (linearization, collocation, FMUs,
            sensitivities) see the model without its stops.
        restitution : float in [0, 1], the stops' coefficient of restitution
        """
        name = self._limited_coordinate(coordinate)
        values = [_limit_value(v, what, name) for what, v in
                  (("lower", lower), ("upper", upper), ("velocity", velocity), ("effort", effort))]
        low, high, speed, force = values
        if low is not None and high is not None and low > high:
            raise ModelError(f"limit({name!r}, lower={low}, upper={high}): the lower limit exceeds "
                             "the upper")
        for what, v in (("velocity", speed), ("effort", force)):
            if v is not None and v < 0:
                raise ModelError(f"limit({name!r}, {what}={v}): a {what} limit bounds abs({what}) "
                                 "and must not be negative")
        self._limits[name] = tuple(values)
        self._stops.pop(name, None)
        if enforce:
            e = finite_number(restitution, f"limit({name!r}) restitution", ModelError)
            if not 0.0 <= e <= 1.0:
                raise ModelError(f"limit({name!r}, restitution={e}): a restitution is between 0 "
                                 "and 1")
            if low is not None or high is not None:
                self._stops[name] = e
        self._changed()

    @property
    def stops(self):
        """{coordinate name: restitution} of the limits enforced in simulations (`limit`)."""
        return {c: self._stops[c] for c in self.coordinate_names if c in self._stops}

    def _limited_coordinate(self, coordinate):
        """The name of `coordinate` (a name or the function `coordinates` returned)."""
        names = self.coordinate_names
        name = coordinate if isinstance(coordinate, str) else getattr(
            getattr(coordinate, "func", None), "__name__", None)
        if name in names and (isinstance(coordinate, str) or coordinate in self._coordinates):
            return name
        raise UnknownNameError(f"limit: {coordinate!r} is not a coordinate of model "
                               f"{self.name!r} (its coordinates are {', '.join(names) or 'none'})")

    @property
    def limits(self):
        """{coordinate name: (lower, upper, velocity, effort)} of the coordinates with declared
        limits (`limit`), in coordinate order; None where a limit is absent."""
        return {c: self._limits[c] for c in self.coordinate_names if c in self._limits}

    def event(self, name, expr, terminal=False, direction=0):
        """Declare an event: a root of `expr` (a function of q, q̇, t, parameters, inputs) that
        the solvers locate, as solve_ivp's events; compiled with the model.

        Parameters
        ----------
        name : str, a Python identifier unique among the model's events
        expr : the event function g; an event happens where g crosses zero
        terminal : bool or int, stop the integration at the first (or this many) occurrences
        direction : 0 (any crossing), +1 (g rising) or -1 (g falling)
        """
        check_name(name, "event")
        if any(e.name == name for e in self._events):
            raise ModelError(f"event {name!r} is already declared on model {self.name!r}")
        if direction not in (-1, 0, 1):
            raise ModelError(f"event {name!r}: direction must be -1, 0 or +1, got {direction!r}")
        if isinstance(terminal, bool):
            terminal = int(terminal)
        if not isinstance(terminal, int) or not 0 <= terminal <= MAX_EVENT_COUNT:
            raise ModelError(f"event {name!r}: terminal must be True, False or a count from 0 to "
                             f"{MAX_EVENT_COUNT}, got {terminal!r}")
        expr = self._check(expr, f"event {name}")
        self._events.append(Event(name, expr, terminal, int(direction)))
        self._changed()

    def impact(self, name, gap, restitution=1.0):
        """A unilateral contact gap(q, t) ≥ 0 (the guide's "Impacts, contact and dry friction"): on
        closing contact q̇ jumps by Newton's law along ∇gap with restitution `restitution` (a
        number in [0, 1] or an expression of parameters); accumulating impacts become a resting
        contact, released when its multiplier (the contact force, M·q̈ = F + ∇gapᵀ·λ) would turn
        negative. See `lagrgen.hybrid`."""
        check_name(name, "impact name")
        where = f"impact {name}"
        gap = self._check(gap, where, velocities=False, inputs=False)
        e = check_restitution(self._check(restitution, where + " restitution", velocities=False,
                                          inputs=False), name)
        if any(e.has(c) for c in self._coordinates):
            raise ModelError(f"{where}: restitution must not depend on the coordinates")
        if not any(gap.has(c) for c in self._coordinates):
            raise ModelError(f"{where}: the gap {gap} involves no coordinate")
        check_distinct_gap(name, gap, [r for r in self._nonsmooth if isinstance(r, Impact)],
                           self._coordinates, self.t)
        self._declare(name, "impact")
        self._nonsmooth.append(Impact(name, gap, e))
        self._changed()

    def friction(self, name, slip_velocity, normal_force, mu, mu_static=None):
        """Coulomb friction with sticking on the slip velocity v = w(q, t)·q̇ + b(q, t) (the guide's
        "Impacts, contact and dry friction"): a force −mu·abs(N)·sign(v) along ∂v/∂q̇ while
        slipping; v = 0 held while the force that takes is at most mu_static·abs(N) (mu_static
        defaults to mu). `normal_force` is an expression
        or the name of a constraint or impact whose multiplier is N: write that constraint or gap
        as a signed distance (a gradient of unit length, e.g. x·sin α + y·cos α for a slope), so
        that its multiplier is a force; likewise v should be the sliding speed itself.

        A slip velocity of two components (v1, v2), the velocities along two orthogonal unit
        directions of a plane, is isotropic friction in that plane: while slipping a force
        −mu·abs(N)·v/‖v‖ (each component along its ∂v_i/∂q̇; below 1e-7 m/s the direction blends
        with the one it began to slip in, `lagrgen.hybrid.PLANAR_BLEND`); v = 0 held while the
        force that takes is at most mu_static·abs(N) in norm (a friction disk). Its normal force
        named as an impact, it acts only while that contact is held (its mode is "open"
        otherwise).
        `ground_contact` declares one with its impact."""
        self._friction(name, slip_velocity, normal_force, mu, mu_static)

    def _friction(self, name, slip_velocity, normal_force, mu, mu_static, affine=False):
        """`friction`; `affine`: the slip velocity is known to be w(q, t)·q̇ + b(q, t) (a point's
        velocity: `ground_contact`), and is not differentiated to check it."""
        check_name(name, "friction name")
        where = f"friction {name}"

        def checked(c):
            c = self._check(c, where, inputs=False)
            return c if affine else check_affine_in_velocities(c, self.qd, where)
        if isinstance(slip_velocity, (list, tuple, sp.MatrixBase)) and len(slip_velocity) == 2:
            v = frozen([checked(c) for c in slip_velocity])
        else:
            v = checked(slip_velocity)
        if isinstance(normal_force, str):
            check_name(normal_force, "normal_force name")
            normal = normal_force
        else:
            normal = self._check(normal_force, where + " normal_force")
        mu = check_coefficient(self._check(mu, where + " mu", velocities=False, inputs=False),
                               where, "mu")
        mu_s = mu if mu_static is None else check_static_coefficient(mu, check_coefficient(
            self._check(mu_static, where + " mu_static", velocities=False, inputs=False), where,
            "mu_static"), where)
        self._declare(name, "friction")
        self._nonsmooth.append(Friction(name, v, normal, mu, mu_s))
        self._changed()

    def ground_contact(self, name, link, point=(0, 0, 0), mu=1.0, restitution=0.0, height=0.0,
                       normal=(0, 0, 1)):
        """A point fixed in a link against the plane normal·x = height: the impact
        `name` on the gap normal·x − height (x = `link_position(link, point)`, the normal made a
        unit vector) with the `restitution`, and, when mu is not 0, isotropic Coulomb friction in
        the plane, the friction `<name>_friction` on the point's velocity along two unit tangents
        t1, t2 (t1 the fixed x axis projected onto the plane, or y when the normal is along x;
        t2 = normal × t1), its normal force the contact's (`friction` with two components).

        Parameters
        ----------
        name : str, the contact's name (its impact; the friction is <name>_friction)
        link : str, one of `link_names`
        point : 3 numbers or parameter expressions in the link's frame
        mu : friction coefficient (a number ≥ 0 or an expression of parameters); static and
            kinetic alike
        restitution : number in [0, 1] or an expression of parameters
        height : the plane's offset along the normal (a number or parameter expression)
        normal : 3 numbers, the plane's normal (pointing out of the ground)
        """
        where = f"ground contact {name}"
        x = self.link_position(link, point)
        n, t1, t2 = plane_axes(normal, name)
        mu = check_coefficient(self._check(mu, where + " mu", velocities=False, inputs=False),
                               where, "mu")
        frictional = not (mu.is_number and float(mu) == 0.0)
        for taken in (name, f"{name}_friction") if frictional else (name,):
            check_name(taken, "ground contact name")
            if taken in self._names:
                raise ModelError(f"{where}: the name {taken!r} is already used for the "
                                 f"{self._names[taken]} of model {self.name!r}")
        height = self._check(height, where + " height", velocities=False, inputs=False)
        self.impact(name, along(n, x) - height, restitution)
        plane = ("ground", (tuple(float(v) for v in n), height))
        if plane not in self._drawables:
            self._drawables.append(plane)
        self._drawables.append(("point", (x, sp.Integer(0))))
        if frictional:
            from .links import velocity
            xd = velocity(x, self.t)
            self._friction(f"{name}_friction", [along(t1, xd), along(t2, xd)], name, mu, None,
                           affine=True)

    @property
    def nonsmooth(self):
        """The impacts and frictions (`Impact`, `Friction` records), in declaration order."""
        return tuple(self._nonsmooth)

    def velocity_constraint(self, expr, name=None):
        """Add a constraint linear in the velocities, A(q, t)·q̇ + b(q, t) = 0 (nonholonomic,
        e.g. a knife edge −sin θ·ẋ + cos θ·ẏ = 0); its multiplier enters M·q̈ = F + Aᵀ·λ.
        `name` as for `constraint`."""
        where = f"velocity constraint {len(self._velocity_constraints) + 1}"
        expr = self._check(self._equation(expr), where, velocities=True, inputs=False)
        qd = self.qd
        coefficients = [sp.diff(expr, v) for v in qd]
        for v, c in zip(qd, coefficients):
            if any(c.has(w) for w in qd):
                raise ModelError(
                    f"{where} ({expr} = 0) is not linear in the velocities: its coefficient of "
                    f"{v} is {c}, which depends on velocities; write it as A(q, t)·q̇ + b(q, t)")
        if all(is_zero(c) for c in coefficients):
            raise ModelError(
                f"{where} ({expr} = 0) involves no velocity: a constraint on positions alone is "
                "holonomic, add it with model.constraint(expr)")
        self._name_constraint(name)
        self._velocity_constraints.append(VelocityConstraint(expr, name))
        self._changed()

    def constraint_stabilization(self, alpha=BAUMGARTE_DEFAULTS[0], beta=BAUMGARTE_DEFAULTS[1]):
        """Set Baumgarte's drift control (1/s): the constraints are imposed at the acceleration
        level as Φ̈ + 2α·Φ̇ + β²·Φ = 0 (holonomic) and ċ + 2α·c = 0 (velocity constraints c = 0).
        α = β = 0 switches it off."""
        values = []
        for name, value in (("alpha", alpha), ("beta", beta)):
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ModelError(f"Baumgarte {name} must be a number, got {value!r}") from None
            if not (math.isfinite(value) and value >= 0):
                raise ModelError(f"Baumgarte {name} must be finite and ≥ 0, got {value}")
            values.append(value)
        self._stabilization = tuple(values)
        self._changed()

    @staticmethod
    def _equation(expr):
        """An equation lhs = rhs as lhs − rhs (a constraint means expr = 0)."""
        return expr.lhs - expr.rhs if isinstance(expr, sp.Equality) else expr

    @property
    def constraints(self):
        """The holonomic constraints Φ_i (each meaning Φ_i = 0), in declaration order."""
        return tuple(c.expr for c in self._constraints)

    @property
    def velocity_constraints(self):
        """The velocity constraints (each meaning A(q,t)·q̇ + b = 0), in declaration order."""
        return tuple(c.expr for c in self._velocity_constraints)

    @property
    def constraint_names(self):
        """The names of the multipliers λ: the holonomic constraints, then the velocity ones
        (the order of A's rows); lambda<k> (k from 1 in that order) where none was given."""
        records = self._constraints + self._velocity_constraints
        return tuple(c.name or f"lambda{k + 1}" for k, c in enumerate(records))

    def line(self, *points):
        """Draw a polyline through `points` in animations (an extension: rods, outlines)."""
        pts = tuple(self._check(as_vector(p, "line point"), "line point", velocities=False,
                                inputs=False, vector=True) for p in points)
        if len(pts) < 2:
            raise ModelError("a line needs at least two points")
        self._drawables.append(("line", pts))

    def _add_ends(self, kind, ends):
        if ends is None:
            return
        if len(ends) != 2:
            raise ModelError(f"{kind} ends must be a pair of points, got {len(ends)}")
        a, b = (self._check(as_vector(p, f"{kind} end"), f"{kind} end", velocities=False,
                            inputs=False, vector=True) for p in ends)
        self._drawables.append((kind, (a, b)))

    def _add_equations(self, M, F):
        """Add externally derived equations M·q̈ = F (SymPy, in this model's own symbols) to what
        Lagrange's equations of the declared physics give. Private: `lagrgen.from_sympy` uses it."""
        n = len(self._coordinates)
        M, F = sp.Matrix(M), sp.Matrix(F)
        if M.shape != (n, n) or F.shape not in ((n, 1), (1, n)):
            raise ModelError(f"external equations of model {self.name!r} must be M ({n}×{n}) and "
                             f"F ({n}), got shapes {M.shape} and {F.shape}")
        M = self._check(M, "mass matrix", velocities=False, inputs=False, vector=True)
        F = self._check(F.reshape(n, 1), "forcing", vector=True)
        if self._external is not None:
            M, F = M + self._external.M, F + self._external.F
        self._external = ExternalEquations(frozen(M), frozen(F))
        self._changed()

    @property
    def drawables(self):
        """What an animation can draw: (kind, points) pairs, in declaration order."""
        return tuple(self._drawables)

    def spec(self):
        """A frozen snapshot of the description (`ModelSpec`): what `lagrgen.build` works from."""
        return _frozen_spec(self)


@once_per
def _frozen_spec(description):
    """The `ModelSpec` of `description` as it stands (forgotten whenever it changes)."""
    d = description
    physics = tuple(d._physics) + ((d._external,) if d._external is not None else ())
    return ModelSpec(
        name=d.name, t=d.t, coordinates=d.q, parameters=d.parameter_symbols,
        defaults=d.parameter_defaults, inputs=d.input_functions, physics=physics,
        outputs=tuple(d._outputs), units=tuple(sorted(d._units.items())),
        constraints=d.constraints, velocity_constraints=d.velocity_constraints,
        constraint_names=d.constraint_names, stabilization=d._stabilization,
        events=tuple(d._events), nonsmooth=tuple(d._nonsmooth),
        initial_state=d.initial_values,
        limits=tuple((name, *values) for name, values in d.limits.items()),
        stops=tuple(d.stops.items()))


def along(axis, x):
    """axisᵀ·x over axis's nonzero components (a matrix product multiplies the long
    expressions of a link's point by the zeros too)."""
    return sp.Add(*(a * e for a, e in zip(axis, x) if a != 0))


def plane_axes(normal, name):
    """(n, t1, t2): the unit `normal` of a ground contact's plane and two unit tangents, t1 the
    fixed x axis projected on the plane (y when the normal is along x), t2 = n × t1 (SymPy
    3×1 matrices of floats, integers where exact)."""
    try:
        values = [float(v) for v in normal]
    except (TypeError, ValueError):
        raise ModelError(f"ground contact {name}: normal must be 3 numbers, got {normal!r}") \
            from None
    norm = math.sqrt(sum(v * v for v in values))
    if len(values) != 3 or not math.isfinite(norm) or norm == 0.0:
        raise ModelError(f"ground contact {name}: normal must be 3 finite numbers, not all 0, "
                         f"got {normal!r}")
    n = [v / norm for v in values]
    axis = [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0]
    along = sum(a * b for a, b in zip(axis, n))
    t1 = [a - along * b for a, b in zip(axis, n)]
    size = math.sqrt(sum(v * v for v in t1))
    t1 = [v / size for v in t1]
    t2 = [n[1] * t1[2] - n[2] * t1[1], n[2] * t1[0] - n[0] * t1[2], n[0] * t1[1] - n[1] * t1[0]]

    def exact(v):
        return sp.Matrix([sp.Integer(int(x)) if float(x).is_integer() else sp.Float(x)
                          for x in v])
    return exact(n), exact(t1), exact(t2)


def _limit_value(value, what, name):
    """A limit as a float, or None when absent; a ModelError for anything but a finite number."""
    return None if value is None else finite_number(value, f"limit({name!r}, {what}=...)",
                                                    ModelError)
