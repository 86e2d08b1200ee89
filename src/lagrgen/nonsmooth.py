"""Impacts, resting contact and Coulomb friction with sticking: their derivation.

`Model.impact` and `Model.friction` record an `Impact` or a `Friction` (`lagrgen.records`);
`terms(eq)` derives what the hybrid drivers (`lagrgen.hybrid` with SciPy, `native/lg_hybrid.c` in
C) need at a state, as one row-major vector `terms` of the model function `hybrid_terms`:

    per impact i (4 + n):   g, ġ, γ, e, W (n)        W = ∂g/∂q, W·q̈ = γ keeps g̈ = 0,
                                                      γ = −(∂ġ/∂q·q̇ + ∂ġ/∂t), e the restitution
    per friction j (5 + n): v, γ, μ, μ_s, N, w (n)   w = ∂v/∂q̇, w·q̈ = γ keeps v̇ = 0,
                                                      γ = −(∂v/∂q·q̇ + ∂v/∂t), N the normal-force
                                                      expression (0 when N is a multiplier)
    per planar friction k (7 + 2n): v1, v2, γ1, γ2, μ, μ_s, N, w1 (n), w2 (n)
                                                      the same for its two slip velocities

Impacts come first, then frictions, then planar frictions, each in declaration order. The mode equations, impact law and
switching rules themselves are in `lagrgen.hybrid` (and its C port).
"""
import symengine as se

from .errors import ModelError
from .functions import HYBRID_FIELDS, HYBRID_GRADIENTS
from .records import Friction, Impact

IMPACT_FIELDS = HYBRID_FIELDS["impact"]
FRICTION_FIELDS = HYBRID_FIELDS["friction"]


def kind(element):
    """"impact", "friction" or "planar_friction"."""
    if isinstance(element, Impact):
        return "impact"
    return "planar_friction" if element.planar else "friction"


def record_size(element, n):
    """How many entries of `terms` one element takes."""
    return HYBRID_FIELDS[kind(element)] + HYBRID_GRADIENTS[kind(element)] * n


def n_terms(elements, n):
    """The length of the `terms` vector for `elements` and n coordinates."""
    return sum(record_size(e, n) for e in elements)


def describe(spec):
    """The drivers' description of the elements of `spec` (stored in the built model's metadata),
    in the order of `terms` (impacts, then frictions): a list of {"name", "kind": "impact"|"friction", "normal": None | ["constraint", k] |
    ["impact", i]}."""
    impacts = [e.name for e in spec.nonsmooth if isinstance(e, Impact)]
    out = []
    for e in ordered(spec.nonsmooth):
        if isinstance(e, Impact):
            out.append({"name": e.name, "kind": "impact", "normal": None})
            continue
        normal = None
        if isinstance(e.normal_force, str):
            if e.normal_force in spec.constraint_names:
                normal = ["constraint", spec.constraint_names.index(e.normal_force)]
            elif e.normal_force in impacts:
                normal = ["impact", impacts.index(e.normal_force)]
            else:
                known = ", ".join(list(spec.constraint_names) + impacts) or "none"
                raise ModelError(
                    f"friction {e.name!r}: normal_force {e.normal_force!r} names no constraint or "
                    f"impact of model {spec.name!r} (those are: {known}); give an expression or "
                    "one of those names")
        out.append({"name": e.name, "kind": kind(e), "normal": normal})
    return out


def ordered(elements):
    """Impacts first, then frictions, then planar frictions, each in declaration order (the
    layout of `terms`)."""
    return [e for k in ("impact", "friction", "planar_friction") for e in elements
            if kind(e) == k]


def terms(eq):
    """The `terms` vector (SymEngine expressions in the internal symbols) of the equations `eq`."""
    from .lagrange import _Converter, diff, rate
    spec = eq.spec
    convert = _Converter(spec)
    q, qd, t = eq.q, eq.qd, eq.t
    out = []
    for e in ordered(spec.nonsmooth):
        if isinstance(e, Impact):
            g = convert(e.gap)
            W = [diff(g, qj) for qj in q]
            gd = rate(g, q, qd, t)
            gamma = -rate_at_fixed_qd(gd, q, qd, t)
            out += [g, gd, gamma, convert(e.restitution)] + W
        else:
            vs = [convert(x) for x in (e.slip_velocity if e.planar else [e.slip_velocity])]
            ws = [[diff(v, v_j) for v_j in qd] for v in vs]
            gammas = [-rate_at_fixed_qd(v, q, qd, t) for v in vs]
            normal = 0 if isinstance(e.normal_force, str) else convert(e.normal_force)
            out += vs + gammas + [convert(e.mu), convert(e.mu_static), normal] + \
                [x for w in ws for x in w]
    return [se.sympify(x) for x in out]


def rate_at_fixed_qd(expr, q, qd, t):
    """∂expr/∂q·q̇ + ∂expr/∂t: the rate of `expr` with q̇ held (the part of its rate not from q̈)."""
    from .lagrange import diff
    free = expr.free_symbols
    total = diff(expr, t) if t in free else 0
    for qj, vj in zip(q, qd):
        if qj in free:
            total = total + diff(expr, qj) * vj
    return total
