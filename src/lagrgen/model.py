"""The model description: coordinates, parameters, inputs and the physics, as SymPy expressions.

A `Model` only records what the user says; `lagrgen.lagrange` turns it into equations of motion.
"""
import hashlib
import keyword
import math

import sympy as sp
from sympy.core.function import AppliedUndef

from . import __version__
from .errors import ModelError

#: SymPy functions that have a C99 equivalent and that the symbolic core can differentiate.
SUPPORTED_FUNCTIONS = (
    sp.sin, sp.cos, sp.tan, sp.asin, sp.acos, sp.atan, sp.atan2,
    sp.sinh, sp.cosh, sp.tanh, sp.asinh, sp.acosh, sp.atanh,
    sp.exp, sp.log, sp.Abs, sp.sign,
)


def check_name(name, what="name"):
    """Return `name` if it is a valid, non-keyword Python identifier, else raise ModelError."""
    if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
        raise ModelError(
            f"invalid {what} {name!r}: names must be valid Python identifiers "
            "(letters, digits and underscores, not starting with a digit, not a Python keyword)")
    return name


def check_model_name(name):
    """Return `name` if it can name a compiled module: an ASCII identifier other than 'lagrgen'."""
    check_name(name, "model name")
    if not name.isascii():
        raise ModelError(f"invalid model name {name!r}: it becomes the name of a compiled Python "
                         "module, so use ASCII letters, digits and underscores only")
    if name == "lagrgen":
        raise ModelError("a model cannot be called 'lagrgen': its module would hide the package")
    return name


def split_names(names, what):
    """Return a list of names from a space/comma-separated string or an iterable of strings."""
    if isinstance(names, str):
        names = names.replace(",", " ").split()
    else:
        names = list(names)
    if not names:
        raise ModelError(f"no {what} names given")
    return [check_name(n, what) for n in names]


def as_vector(value, what):
    """Return `value` (scalar, list, tuple or Matrix) as a SymPy column Matrix of 1 to 3 entries."""
    if isinstance(value, sp.MatrixBase):
        vec = sp.Matrix(value).reshape(len(value), 1)
    elif isinstance(value, (list, tuple)):
        vec = sp.Matrix([sp.sympify(v) for v in value])
    else:
        vec = sp.Matrix([sp.sympify(value)])
    if not 1 <= len(vec) <= 3:
        raise ModelError(f"{what} must have 1 to 3 components, got {len(vec)}")
    return vec


class Model:
    """A mechanical system described by its energies, dissipation and generalized forces.

    Lagrange's equations d/dt(∂T/∂q̇) − ∂T/∂q + ∂V/∂q + ∂R/∂q̇ = Q are derived from what is added here.
    """

    def __init__(self, name):
        self.name = check_model_name(name)
        self.t = sp.Symbol("t")
        self._names = {"t": "time"}
        self._coordinates = []
        self._parameters = []
        self._defaults = []
        self._inputs = []
        self.particles = []        # (mass, position) pairs: T += ½·mass·|ṙ|²
        self.kinetic_terms = []    # T += expr
        self.potential_terms = []  # V += expr
        self.dissipation_terms = []  # R += expr
        self.virtual_work = []     # (vector, position): Q_j += vector · ∂position/∂q_j
        self.drawables = []        # (kind, points): what an animation can draw
        self._bodies_3d = []       # (inertia 3×3, ω body frame): T += ½·ωᵀ·I·ω (lagrgen.bodies3d)
        self._kinematics = {}      # orientation → bodies3d.Kinematics, computed once each
        self._version = 0

    # -- declarations -------------------------------------------------------------------------
    def _declare(self, name, what):
        if name in self._names:
            raise ModelError(
                f"{what} name {name!r} is already used for the {self._names[name]} of model "
                f"{self.name!r}: names must be unique within a model")
        self._names[name] = what

    def coordinates(self, names):
        """Declare generalized coordinates; return them as SymPy functions of t, in order."""
        new = []
        for name in split_names(names, "coordinate"):
            self._declare(name, "coordinate")
            new.append(sp.Function(name)(self.t))
        self._coordinates.extend(new)
        self._version += 1
        return tuple(new)

    def parameters(self, *names, **defaults):
        """Declare constant parameters (keyword = default value); return them as SymPy symbols."""
        entries = [(n, None) for n in names] + list(defaults.items())
        if not entries:
            raise ModelError("no parameter names given")
        new = []
        for name, default in entries:
            check_name(name, "parameter")
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
        self._version += 1
        return tuple(new)

    def inputs(self, names):
        """Declare time-varying inputs (values given at run time); return SymPy functions of t."""
        new = []
        for name in split_names(names, "input"):
            self._declare(name, "input")
            new.append(sp.Function(name)(self.t))
        self._inputs.extend(new)
        self._version += 1
        return tuple(new)

    # -- what has been declared ---------------------------------------------------------------
    @property
    def q(self):
        """The generalized coordinates q_i(t), in declaration order."""
        return tuple(self._coordinates)

    @property
    def qd(self):
        """The generalized speeds dq_i/dt, in declaration order."""
        return tuple(c.diff(self.t) for c in self._coordinates)

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
    def parameter_defaults(self):
        """Defaults in parameter order; None where a value must be given at run time."""
        return tuple(self._defaults)

    # -- checking expressions -----------------------------------------------------------------
    def _check(self, expr, where, velocities=True, inputs=True):
        """Return `expr` sympified, after checking every symbol and function in it is known."""
        try:
            expr = sp.sympify(expr)
        except (sp.SympifyError, TypeError) as exc:
            raise ModelError(f"{where}: cannot read {expr!r} as a SymPy expression ({exc})") from None
        if isinstance(expr, sp.MatrixBase):
            for e in expr:
                self._check(e, where, velocities, inputs)
            return expr
        allowed = set(self._parameters) | {self.t}
        for s in expr.free_symbols - allowed:
            raise ModelError(
                f"{where}: symbol {s} is neither a coordinate, a parameter, an input nor t; "
                f"declare it with model.parameters({s}=...) or model.inputs('{s}')")
        for d in expr.atoms(sp.Derivative):
            if d.expr not in self._coordinates or d.variables != (self.t,):
                raise ModelError(
                    f"{where}: {d} is not allowed; only first time derivatives of coordinates "
                    "(velocities) may appear")
            if not velocities:
                raise ModelError(f"{where}: must not depend on velocities, but contains {d}")
        for f in expr.atoms(AppliedUndef):
            if f in self._coordinates:
                continue
            if f in self._inputs:
                if not inputs:
                    raise ModelError(
                        f"{where}: must not depend on input {f.func.__name__} (its time derivative "
                        "is not known); use t for a prescribed motion")
                continue
            raise ModelError(
                f"{where}: {f} is neither a coordinate nor an input of model {self.name!r}; "
                "coordinates and inputs must be functions of model.t declared on this model")
        for f in expr.atoms(sp.Function):
            if not isinstance(f, AppliedUndef) and not isinstance(f, SUPPORTED_FUNCTIONS):
                names = ", ".join(fn.__name__ for fn in SUPPORTED_FUNCTIONS)
                raise ModelError(f"{where}: function {f.func.__name__} is not supported (use {names})")
        if expr.has(sp.zoo, sp.oo, sp.nan, -sp.oo):
            raise ModelError(f"{where}: expression {expr} contains an infinity or NaN")
        return expr

    def _coordinate(self, coordinate):
        if isinstance(coordinate, str):
            for c in self._coordinates:
                if c.func.__name__ == coordinate:
                    return c
        elif coordinate in self._coordinates:
            return coordinate
        raise ModelError(
            f"{coordinate!r} is not a generalized coordinate of model {self.name!r} "
            f"(its coordinates are {', '.join(self.coordinate_names) or 'none'})")

    def _changed(self):
        self._version += 1

    # -- physics ------------------------------------------------------------------------------
    def particle(self, mass, position):
        """T += ½·mass·ṙ·ṙ with ṙ the total time derivative of `position` (1 to 3 components)."""
        mass = self._check(mass, "particle mass", velocities=False, inputs=False)
        position = self._check(as_vector(position, "particle position"), "particle position",
                               velocities=False, inputs=False)
        self.particles.append((mass, position))
        self.drawables.append(("point", (position,)))
        self._changed()

    def rigid_body(self, mass, inertia, position, angle):
        """Planar rigid body: T += ½·mass·ṙ·ṙ + ½·inertia·(d angle/dt)², position of its centre of mass."""
        mass = self._check(mass, "rigid body mass", velocities=False, inputs=False)
        inertia = self._check(inertia, "rigid body inertia", velocities=False, inputs=False)
        position = self._check(as_vector(position, "rigid body position"), "rigid body position",
                               velocities=False, inputs=False)
        angle = self._check(angle, "rigid body angle", velocities=False, inputs=False)
        self.particles.append((mass, position))
        self.particles.append((inertia, sp.Matrix([angle])))
        self.drawables.append(("body", (position, angle)))
        self._changed()

    def rigid_body_3d(self, mass, inertia, position, orientation):
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
        """
        from .bodies3d import body_inertia
        mass = self._check(mass, "rigid body mass", velocities=False, inputs=False)
        inertia = body_inertia(self, inertia)
        position = self._check(as_vector(position, "rigid body position"), "rigid body position",
                               velocities=False, inputs=False)
        if len(position) != 3:
            raise ModelError(f"rigid_body_3d position must have 3 components (x, y, z), got "
                             f"{len(position)}")
        kin = self._orientation(orientation, "rigid_body_3d orientation")
        self.particles.append((mass, position))
        self._bodies_3d.append((inertia, kin.omega))
        self.drawables.append(("body3d", (position, kin.R)))
        self._changed()

    def torque_3d(self, moment, orientation):
        """A moment acting on the body of orientation R: Q_j += moment · ∂ω_fixed/∂q̇_j.

        Parameters
        ----------
        moment : 3 components in the fixed frame (may depend on q, q̇, t, inputs).
        orientation : the body's 3×3 rotation matrix, as given to `rigid_body_3d`.
        """
        moment = self._check(as_vector(moment, "torque_3d moment"), "torque_3d moment")
        if len(moment) != 3:
            raise ModelError(f"torque_3d moment must have 3 components, got {len(moment)}")
        kin = self._orientation(orientation, "torque_3d orientation")
        for j, coordinate in enumerate(self._coordinates):
            arm = kin.W_fixed[:, j]
            if any(e != 0 for e in arm):
                self.virtual_work.append((sp.Matrix([moment.dot(arm)]), sp.Matrix([coordinate])))
        self._changed()

    def _orientation(self, orientation, where):
        """The checked `bodies3d.Kinematics` of a 3×3 orientation matrix (computed once each)."""
        from .bodies3d import Kinematics, check_rotation
        if not isinstance(orientation, sp.MatrixBase) or orientation.shape != (3, 3):
            shape = getattr(orientation, "shape", None)
            raise ModelError(f"{where} must be a 3×3 SymPy Matrix (e.g. from lagrgen.rotation), "
                             f"got {type(orientation).__name__}" + (f" of shape {shape}" if shape
                                                                    else ""))
        self._check(orientation, where, velocities=False, inputs=False)
        key = (sp.ImmutableMatrix(orientation), getattr(orientation, "factors", None))
        if key not in self._kinematics:
            check_rotation(orientation, [*self._coordinates, self.t, *self._parameters], where)
            self._kinematics[key] = Kinematics(orientation, self._coordinates, self.t)
        return self._kinematics[key]

    def kinetic_energy(self, expr):
        """T += expr (may contain coordinates, velocities, t and parameters)."""
        self.kinetic_terms.append(self._check(expr, "kinetic energy", inputs=False))
        self._changed()

    def potential_energy(self, expr):
        """V += expr (coordinates, t, parameters, inputs)."""
        self.potential_terms.append(self._check(expr, "potential energy", velocities=False))
        self._changed()

    def spring(self, k, length, rest=0, ends=None):
        """V += ½·k·(length − rest)²; `ends=(a, b)` optionally names the two points it joins."""
        k = self._check(k, "spring stiffness", velocities=False)
        length = self._check(length, "spring length", velocities=False, inputs=False)
        rest = self._check(rest, "spring rest length", velocities=False)
        self.potential_terms.append(k * (length - rest) ** 2 / 2)
        self._add_ends("spring", ends)
        self._changed()

    def damper(self, c, length, ends=None):
        """Rayleigh R += ½·c·(d length/dt)²; `ends=(a, b)` optionally names the two points it joins."""
        c = self._check(c, "damping coefficient", velocities=False)
        length = self._check(length, "damper length", velocities=False, inputs=False)
        self.dissipation_terms.append(c * length.diff(self.t) ** 2 / 2)
        self._add_ends("damper", ends)
        self._changed()

    def dissipation(self, expr):
        """R += expr, a Rayleigh dissipation function of the velocities."""
        self.dissipation_terms.append(self._check(expr, "dissipation function"))
        self._changed()

    def force(self, vector, at):
        """Q_j += vector · ∂at/∂q_j (virtual work of a force applied at the point `at`)."""
        vector = self._check(as_vector(vector, "force"), "force")
        at = self._check(as_vector(at, "force point"), "force point", velocities=False, inputs=False)
        if len(vector) != len(at):
            raise ModelError(
                f"force has {len(vector)} components but its point of application has {len(at)}")
        self.virtual_work.append((vector, at))
        self._changed()

    def torque(self, moment, angle):
        """Q_j += moment · ∂angle/∂q_j."""
        moment = self._check(moment, "torque")
        angle = self._check(angle, "torque angle", velocities=False, inputs=False)
        self.virtual_work.append((sp.Matrix([moment]), sp.Matrix([angle])))
        self._changed()

    def generalized_force(self, coordinate, expr):
        """Q_j += expr for the coordinate j given (its function or its name)."""
        coordinate = self._coordinate(coordinate)
        expr = self._check(expr, "generalized force")
        self.virtual_work.append((sp.Matrix([expr]), sp.Matrix([coordinate])))
        self._changed()

    def line(self, *points):
        """Draw a polyline through `points` in animations (an extension: rods, outlines)."""
        pts = tuple(self._check(as_vector(p, "line point"), "line point", velocities=False,
                                inputs=False) for p in points)
        if len(pts) < 2:
            raise ModelError("a line needs at least two points")
        self.drawables.append(("line", pts))

    def _add_ends(self, kind, ends):
        if ends is None:
            return
        if len(ends) != 2:
            raise ModelError(f"{kind} ends must be a pair of points, got {len(ends)}")
        a, b = (self._check(as_vector(p, f"{kind} end"), f"{kind} end", velocities=False,
                            inputs=False) for p in ends)
        self.drawables.append((kind, (a, b)))

    # -- the equations ------------------------------------------------------------------------
    def equations(self):
        """Return the derived `lagrgen.lagrange.Equations` (cached until the model changes)."""
        from .lagrange import derive
        cached = getattr(self, "_equations", None)
        if cached is None or cached[0] != self._version:
            self._equations = (self._version, derive(self))
        return self._equations[1]

    def mass_matrix(self):
        """M = ∂²T/∂q̇∂q̇ᵀ as a SymPy Matrix in the model's own symbols."""
        return self.equations().user_matrix("M")

    def forcing(self):
        """F(q, q̇, t, u), so that M·q̈ = F, as a SymPy column Matrix in the model's own symbols."""
        return self.equations().user_matrix("F")

    def content_hash(self):
        """A hex digest of everything that determines the generated code (and lagrgen's version).

        Computed once per state of the model (every change to it makes a new one)."""
        cached = getattr(self, "_content_hash", None)
        if cached is None or cached[0] != self._version:
            self._content_hash = (self._version, self._hash_contents())
        return self._content_hash[1]

    def _hash_contents(self):
        h = hashlib.sha256()
        parts = [
            __version__, self.name, self.coordinate_names, self.parameter_names,
            self.parameter_defaults, self.input_names,
            [(sp.srepr(m), sp.srepr(r)) for m, r in self.particles],
            [sp.srepr(e) for e in self.kinetic_terms],
            [sp.srepr(e) for e in self.potential_terms],
            [sp.srepr(e) for e in self.dissipation_terms],
            [(sp.srepr(v), sp.srepr(r)) for v, r in self.virtual_work],
            [(sp.srepr(i), sp.srepr(w)) for i, w in self._bodies_3d],
        ]
        for part in parts:
            h.update(repr(part).encode())
            h.update(b"\0")
        return h.hexdigest()

    def metadata(self):
        """What a built model reports about itself: names, defaults (None: none), hash, version."""
        return {
            "name": self.name, "coordinates": list(self.coordinate_names),
            "parameters": list(self.parameter_names), "inputs": list(self.input_names),
            "defaults": list(self.parameter_defaults), "content_hash": self.content_hash(),
            "lagrgen_version": __version__,
        }

    def __repr__(self):
        return (f"Model({self.name!r}: coordinates {self.coordinate_names}, "
                f"parameters {self.parameter_names}, inputs {self.input_names})")
