"""The description as typed records: one small frozen record per physics kind, and `ModelSpec`, the
frozen description `lagrgen.build` derives from.

A record holds what the user declared (SymPy, in the model's own symbols, already checked by
`lagrgen.checks`); each physics kind has one contribution function in the derivation
(`lagrgen.contributions.CONTRIBUTIONS`) that adds its part of T, V, R or Q. A new kind is one record
here, its declaring method on `Description`, and its contribution function.
"""
from dataclasses import dataclass
from typing import NamedTuple

import sympy as sp

from .functions import POWER_TERMS

#: The outputs every built model provides after the user's own (`Model.output`), in this order:
#: T, V, T + V, then the power Σ Q_j·q̇_j of the applied forces and the Rayleigh function R, so that
#: d(T + V)/dt = input_power − 2·R for a scleronomic model with R quadratic in q̇.
ENERGY_OUTPUTS = ("kinetic_energy", "potential_energy", "total_energy")
#: Names no user output may take: the energies and the power terms (evaluated beside the outputs).
AUTOMATIC_OUTPUTS = ENERGY_OUTPUTS + POWER_TERMS
#: Baumgarte's (α, β) in 1/s unless `Model.constraint_stabilization` sets others: the constraint
#: error then decays like e^(−10·t)·(1 + 10·t) (critically damped).
BAUMGARTE_DEFAULTS = (10.0, 10.0)


def frozen(vector):
    """A SymPy matrix as an immutable one."""
    return sp.ImmutableMatrix(vector)


# -- physics: what enters T, V, R and Q ------------------------------------------------------------
@dataclass(frozen=True)
class Particle:
    """T += ½·mass·ṙ·ṙ, ṙ the total time derivative of `position` (1 to 3 components)."""
    mass: sp.Expr
    position: sp.ImmutableMatrix


@dataclass(frozen=True)
class PlanarBody:
    """T += ½·mass·ṙ·ṙ + ½·inertia·(d angle/dt)², `position` of the centre of mass."""
    mass: sp.Expr
    inertia: sp.Expr
    position: sp.ImmutableMatrix
    angle: sp.Expr


@dataclass(frozen=True)
class Body3D:
    """T += ½·mass·ṙ·ṙ + ½·ωᵀ·I·ω, ω the body-frame angular velocity (contains q̇), I constant;
    `orientation` the rotation R(q, t) (body → fixed components) ω comes from, `omega_fixed`
    the angular velocity in fixed axes, R·ω."""
    mass: sp.Expr
    position: sp.ImmutableMatrix
    inertia: sp.ImmutableMatrix
    omega: sp.ImmutableMatrix
    orientation: sp.ImmutableMatrix = None
    omega_fixed: sp.ImmutableMatrix = None
    name: str = None                # the link it is (`Model.link_position`); None: body<k>


@dataclass(frozen=True)
class Segment:
    """One moving joint of an `Articulation` and the body it carries.

    The segment's frame sits at `offset`, rotated by `rotation` (3×3, numbers), in its parent's
    frame (parent −1: the fixed base, whose frame is the fixed frame), and then moves by `motion`
    about (revolute) or along (prismatic) the unit `axis` (segment frame, numbers): `motion` is
    the joint's coordinate q(t), or multiplier·q(t) + offset of the coordinate a mimic joint
    follows. `inertia` is its body's (m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)
    about the segment frame's origin in its axes (SymPy numbers or parameter expressions; all
    zero for a massless frame); `name` the joint's, `link` the body's (empty for none).

    A "free" segment (a floating base without singularity, `lagrgen.frames`) is a root whose
    `motion` is the 7×1 matrix of its coordinates (x, y, z, q_x, q_y, q_z, q_w): the position of
    its frame and a quaternion ζ of any nonzero length whose direction is its orientation;
    `radial` is the inertia of ζ's length, T += ½·radial·(d|ζ|/dt)², which moves nothing else."""
    name: str
    link: str
    parent: int
    kind: str
    axis: tuple
    rotation: sp.ImmutableMatrix
    offset: sp.ImmutableMatrix
    motion: sp.Expr
    inertia: tuple
    radial: float = 0.0


@dataclass(frozen=True)
class Articulation:
    """A tree of rigid bodies joined by revolute and prismatic joints (`lagrgen.from_urdf`):
    T of every segment's body, V = −Σ m·g·c of a uniform gravity `gravity` (3, fixed frame).
    Segments come parents first; `links` (`LinkFrame`s) says where each link's frame is."""
    segments: tuple
    gravity: sp.ImmutableMatrix
    links: tuple = ()


@dataclass(frozen=True)
class LinkFrame:
    """Where a link's frame is: fixed in the frame of segment `segment` (−1: the fixed frame) at
    `offset` (3×1), rotated by `rotation` (3×3), numbers; links that fixed joints merge into a
    body keep their own frames."""
    name: str
    segment: int
    rotation: sp.ImmutableMatrix
    offset: sp.ImmutableMatrix


@dataclass(frozen=True)
class KineticEnergy:
    """T += expr."""
    expr: sp.Expr


@dataclass(frozen=True)
class PotentialEnergy:
    """V += expr."""
    expr: sp.Expr


@dataclass(frozen=True)
class Spring:
    """V += ½·k·(length − rest)²."""
    k: sp.Expr
    length: sp.Expr
    rest: sp.Expr


@dataclass(frozen=True)
class Damper:
    """R += ½·c·(d length/dt)²."""
    c: sp.Expr
    length: sp.Expr


@dataclass(frozen=True)
class Dissipation:
    """R += expr, a Rayleigh dissipation function."""
    expr: sp.Expr


@dataclass(frozen=True)
class Force:
    """Q_j += vector · ∂at/∂q_j (virtual work of a force applied at the point `at`)."""
    vector: sp.ImmutableMatrix
    at: sp.ImmutableMatrix


@dataclass(frozen=True)
class Torque:
    """Q_j += moment · ∂angle/∂q_j."""
    moment: sp.Expr
    angle: sp.Expr


@dataclass(frozen=True)
class GeneralizedForce:
    """Q_j += expr for the coordinate j (a function q_j(t))."""
    coordinate: sp.Expr
    expr: sp.Expr


@dataclass(frozen=True)
class ExternalEquations:
    """M·q̈ = F derived elsewhere (`lagrgen.from_sympy`), added as given; its energies are unknown."""
    M: sp.ImmutableMatrix
    F: sp.ImmutableMatrix


# -- what is not physics: constraints, events, outputs ---------------------------------------------
@dataclass(frozen=True)
class Constraint:
    """Φ(q, t) = 0 (holonomic); `name` names its multiplier (None: lambda<k>)."""
    expr: sp.Expr
    name: str = None


@dataclass(frozen=True)
class VelocityConstraint:
    """A(q, t)·q̇ + b(q, t) = 0; `name` names its multiplier (None: lambda<k>)."""
    expr: sp.Expr
    name: str = None


@dataclass(frozen=True)
class Impact:
    """A unilateral contact gap(q, t) ≥ 0 with Newton's restitution coefficient (`Model.impact`)."""
    name: str
    gap: sp.Expr
    restitution: sp.Expr


@dataclass(frozen=True)
class Friction:
    """Coulomb friction with sticking on v(q, q̇, t) = w(q, t)·q̇ + b(q, t) (`Model.friction`);
    `normal_force` an expression, or the name (str) of a constraint or impact whose multiplier
    is the normal force. A `slip_velocity` of two components (a 2×1 matrix) is isotropic
    friction in a plane (`planar`)."""
    name: str
    slip_velocity: sp.Expr
    normal_force: object
    mu: sp.Expr
    mu_static: sp.Expr

    @property
    def planar(self):
        return isinstance(self.slip_velocity, sp.MatrixBase)


class Event(NamedTuple):
    """A root of g(t, q, q̇, u) located by the solvers, as solve_ivp's events."""
    name: str
    expr: sp.Expr
    terminal: int
    direction: int


class Output(NamedTuple):
    """A named scalar y = expr(q, q̇, t, p, u) evaluated along a solution."""
    name: str
    expr: sp.Expr


def _record_view(kinds, pairs):
    """A ModelSpec property: `pairs(record)` for each of its records of the given kinds."""
    def view(spec):
        return tuple(pair for record in spec.physics if isinstance(record, kinds)
                     for pair in pairs(record))
    return property(view)


@dataclass(frozen=True, eq=False)
class ModelSpec:
    """A frozen model description: names, symbols and physics records (SymPy, immutable).

    `lagrgen.build` derives from this alone; nothing below it sees the mutable `Model`.
    """

    name: str
    t: sp.Symbol
    coordinates: tuple      # q_i(t)
    parameters: tuple       # Symbols
    defaults: tuple         # floats, None where a value must be given at run time
    inputs: tuple           # u_k(t)
    physics: tuple = ()     # the records of T, V, R and Q, in declaration order
    outputs: tuple = ()     # Output(name, expr): the user's outputs
    units: tuple = ()       # sorted (name, unit label) pairs
    constraints: tuple = ()   # Φ_i(q, t) = 0
    velocity_constraints: tuple = ()  # A(q, t)·q̇ + b(q, t) = 0
    constraint_names: tuple = ()  # one per multiplier, holonomic first
    stabilization: tuple = (0.0, 0.0)  # Baumgarte (α, β), 1/s
    events: tuple = ()        # Event(name, g, terminal, direction)
    nonsmooth: tuple = ()     # Impact / Friction records, in declaration order
    initial_state: tuple = ()  # [q0, q̇0] as 2n floats, or () when none is declared
    limits: tuple = ()        # (coordinate name, lower, upper, velocity, effort), None if absent
    stops: tuple = ()         # (coordinate name, restitution): limits enforced in simulations

    @property
    def external(self):
        """(M, F) derived elsewhere (an `ExternalEquations` record), or None."""
        return next(((r.M, r.F) for r in self.physics if isinstance(r, ExternalEquations)), None)

    # the physics grouped as in earlier versions: (mass, position) pairs, plain terms, ...
    particles = _record_view((Particle, PlanarBody, Body3D), lambda r: (
        [(r.mass, r.position), (r.inertia, frozen(sp.Matrix([r.angle])))]
        if isinstance(r, PlanarBody) else [(r.mass, r.position)]))
    kinetic = _record_view(KineticEnergy, lambda r: [r.expr])
    potential = _record_view((PotentialEnergy, Spring), lambda r: [
        r.k * (r.length - r.rest) ** 2 / 2 if isinstance(r, Spring) else r.expr])
    dissipation = _record_view(Dissipation, lambda r: [r.expr])
    dampers = _record_view(Damper, lambda r: [(r.c, r.length)])
    virtual_work = _record_view((Force, Torque, GeneralizedForce), lambda r: [
        (r.vector, r.at) if isinstance(r, Force) else
        (frozen([r.moment]), frozen([r.angle])) if isinstance(r, Torque) else
        (frozen([r.expr]), frozen([r.coordinate]))])
    bodies_3d = _record_view(Body3D, lambda r: [(r.inertia, r.omega)])

    @property
    def output_names(self):
        return tuple(n for n, _ in self.outputs) + ENERGY_OUTPUTS

    @property
    def qd(self):
        return tuple(c.diff(self.t) for c in self.coordinates)

    @property
    def coordinate_names(self):
        return tuple(c.func.__name__ for c in self.coordinates)

    @property
    def parameter_names(self):
        return tuple(s.name for s in self.parameters)

    @property
    def input_names(self):
        return tuple(u.func.__name__ for u in self.inputs)
