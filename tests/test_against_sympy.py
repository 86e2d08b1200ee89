"""Every example against SymPy's own `sympy.physics.mechanics.LagrangesMethod`.

Each `mechanics_*` function rebuilds an example with reference frames, points, particles and rigid
bodies, L = T − V from `Lagrangian`, applied forces (inputs and damper forces) as a forcelist, and
returns LagrangesMethod's M and f (M·q̈ = f). Those are compared with the built model's mass matrix
and forcing at random states, parameters and inputs.
"""
import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose
from sympy.physics.mechanics import (LagrangesMethod, Lagrangian, Particle, Point, ReferenceFrame,
                                     RigidBody, dynamicsymbols, inertia)

from conftest import example_model, random_point, state_function, FORMULATIONS


@pytest.fixture(scope="module", params=FORMULATIONS)
def formulation(request):
    """Every test here runs on both formulations (the recursive one for kinematic trees)."""
    return request.param

t = dynamicsymbols._t


class System:
    """An inertial frame N with a fixed origin O, and helpers to add moving points to it."""

    def __init__(self):
        self.N = ReferenceFrame("N")
        self.O = Point("O")
        self.O.set_vel(self.N, 0)

    def point(self, name, base, offset):
        """A point at `base` + `offset`, its velocity the time derivative of its position in N."""
        P = base.locatenew(name, offset)
        P.set_vel(self.N, P.pos_from(self.O).dt(self.N))
        return P

    def height(self, P):
        return P.pos_from(self.O).dot(self.N.y)


def lagrange(system, bodies, V, q, forces=(), params=(), inputs=()):
    """(M, f, q, params, inputs) of LagrangesMethod for L = T(bodies) − V with applied `forces`."""
    lm = LagrangesMethod(Lagrangian(system.N, *bodies) - V, q, forcelist=list(forces),
                         frame=system.N)
    lm.form_lagranges_equations()
    return lm.mass_matrix, lm.forcing, q, dict(zip(map(str, params), params)), \
        {str(u.func): u for u in inputs}


def mechanics_double_pendulum():
    """Links as frames A, B turned by θ1, θ2 about z; bobs at −L·(link y axis); F·N.x at the tip."""
    th1, th2 = dynamicsymbols("theta1 theta2")
    F = dynamicsymbols("F")
    m1, m2, L1, L2, g = sp.symbols("m1 m2 L1 L2 g")
    s = System()
    A = s.N.orientnew("A", "Axis", [th1, s.N.z])
    B = s.N.orientnew("B", "Axis", [th2, s.N.z])
    PA = s.point("PA", s.O, -L1 * A.y)
    PB = s.point("PB", PA, -L2 * B.y)
    bodies = [Particle("a", PA, m1), Particle("b", PB, m2)]
    V = g * (m1 * s.height(PA) + m2 * s.height(PB))
    return lagrange(s, bodies, V, [th1, th2], [(PB, F * s.N.x)], (m1, m2, L1, L2, g), [F])


def two_mass(relative):
    """Masses at x1·N.x and x2·N.x; the dampers and f enter as forces on the two points."""
    x1, y = dynamicsymbols("x1 s" if relative else "x1 x2")
    x2 = x1 + y if relative else y
    f = dynamicsymbols("f")
    m1, m2, k1, k2, c1, c2 = sp.symbols("m1 m2 k1 k2 c1 c2")
    s = System()
    P1 = s.point("P1", s.O, x1 * s.N.x)
    P2 = s.point("P2", s.O, x2 * s.N.x)
    bodies = [Particle("p1", P1, m1), Particle("p2", P2, m2)]
    V = k1 * x1**2 / 2 + k2 * (x2 - x1)**2 / 2
    v1, v12 = x1.diff(t), (x2 - x1).diff(t)
    forces = [(P1, (-c1 * v1 + c2 * v12) * s.N.x), (P2, (-c2 * v12 + f) * s.N.x)]
    return lagrange(s, bodies, V, [x1, y], forces, (m1, m2, k1, k2, c1, c2), [f])


def mechanics_driven_pendulum():
    """Crank frame C turned by Ωt (explicit t), tip at r·C.x; pendulum frame A; bob at tip − L·A.y."""
    th = dynamicsymbols("theta")
    m, L, r, Om, g = sp.symbols("m L r Omega g")
    s = System()
    C = s.N.orientnew("C", "Axis", [Om * t, s.N.z])
    A = s.N.orientnew("A", "Axis", [th, s.N.z])
    tip = s.point("tip", s.O, r * C.x)
    bob = s.point("bob", tip, -L * A.y)
    return lagrange(s, [Particle("bob", bob, m)], m * g * s.height(bob), [th],
                    params=(m, L, r, Om, g))


def mechanics_rolling_chain():
    """The disk is a RigidBody (I_zz = ½m3R²) whose frame D turns by −x3/R about z (no slip)."""
    x1, x2, x3 = dynamicsymbols("x1 x2 x3")
    f = dynamicsymbols("f")
    m1, m2, m3, R = sp.symbols("m1 m2 m3 R")
    k1, k2, k3, c1, c2, c3 = sp.symbols("k1 k2 k3 c1 c2 c3")
    s = System()
    D = s.N.orientnew("D", "Axis", [-x3 / R, s.N.z])
    P1 = s.point("P1", s.O, x1 * s.N.x)
    P2 = s.point("P2", s.O, x2 * s.N.x)
    P3 = s.point("P3", s.O, x3 * s.N.x + R * s.N.y)
    Izz = m3 * R**2 / 2
    disk = RigidBody("disk", P3, D, m3, (inertia(D, Izz / 2, Izz / 2, Izz), P3))
    bodies = [Particle("p1", P1, m1), Particle("p2", P2, m2), disk]
    V = (k1 * x1**2 + k2 * (x2 - x1)**2 + k3 * (x3 - x2)**2) / 2
    d1, d2, d3 = (e.diff(t) for e in (x1, x2 - x1, x3 - x2))
    forces = [(P1, (-c1 * d1 + c2 * d2 + f) * s.N.x), (P2, (-c2 * d2 + c3 * d3) * s.N.x),
              (P3, -c3 * d3 * s.N.x)]
    return lagrange(s, bodies, V, [x1, x2, x3], forces, (m1, m2, m3, R, k1, k2, k3, c1, c2, c3), [f])


def mechanics_cart_pendulum():
    """Link frame A turned by θ; bob at hinge − L·A.y; P along −A.y (hinge to bob) at the bob."""
    x, th = dynamicsymbols("x theta")
    P, Fc = dynamicsymbols("P Fc")
    Mc, m, L, kt, g = sp.symbols("M m L kt g")
    s = System()
    A = s.N.orientnew("A", "Axis", [th, s.N.z])
    hinge = s.point("hinge", s.O, x * s.N.x)
    bob = s.point("bob", hinge, -L * A.y)
    bodies = [Particle("cart", hinge, Mc), Particle("bob", bob, m)]
    V = m * g * s.height(bob) + kt * th**2 / 2
    forces = [(bob, -P * A.y), (hinge, Fc * s.N.x)]
    return lagrange(s, bodies, V, [x, th], forces, (Mc, m, L, kt, g), [P, Fc])


def mechanics_nlink(n):
    """Frame A_i per link turned by q_i; mass i at the previous point − l_i·A_i.y."""
    q = dynamicsymbols(f"q0:{n}")
    m = sp.symbols(f"m0:{n}")
    l = sp.symbols(f"l0:{n}")
    g = sp.Symbol("g")
    s = System()
    base, bodies, V = s.O, [], 0
    for i in range(n):
        A = s.N.orientnew(f"A{i}", "Axis", [q[i], s.N.z])
        base = s.point(f"P{i}", base, -l[i] * A.y)
        bodies.append(Particle(f"p{i}", base, m[i]))
        V += m[i] * g * s.height(base)
    return lagrange(s, bodies, V, list(q), params=(*m, *l, g))


CASES = {
    "double_pendulum": (("double_pendulum", "model"), mechanics_double_pendulum),
    "two_mass_absolute": (("two_mass_chain", "absolute"), lambda: two_mass(relative=False)),
    "two_mass_relative": (("two_mass_chain", "relative"), lambda: two_mass(relative=True)),
    "driven_pendulum": (("driven_pendulum", "model"), mechanics_driven_pendulum),
    "rolling_chain": (("rolling_chain", "model"), mechanics_rolling_chain),
    "cart_pendulum": (("cart_pendulum", "model"), mechanics_cart_pendulum),
    "nlink3": (("nlink_pendulum", "model"), lambda: mechanics_nlink(3)),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request, build):
    """(built model, reference M(q,qd,t,p,u), reference f(q,qd,t,p,u)) for one example."""
    (stem, attr), mechanics = CASES[request.param]
    mod = build(example_model(stem, attr))
    M, f, q, params, inputs = mechanics()
    assert tuple(params) == mod.parameters and tuple(inputs) == mod.inputs
    qd = [c.diff(t) for c in q]
    args = (t, q, qd, list(params.values()), list(inputs.values()))
    return mod, state_function(M, *args), state_function(f, *args)


def test_mass_matrix_matches_lagranges_method(case):
    mod, M, _ = case
    rng = np.random.default_rng(11)
    for _ in range(5):
        q, qd, tv, p, u = random_point(mod, rng)
        assert_allclose(mod.mass_matrix(q, tv, p, u), M(q, qd, tv, p, u), rtol=1e-12, atol=1e-12)


def test_forcing_matches_lagranges_method(case):
    mod, _, f = case
    rng = np.random.default_rng(12)
    for _ in range(5):
        q, qd, tv, p, u = random_point(mod, rng)
        assert_allclose(mod.forcing(q, qd, tv, p, u), f(q, qd, tv, p, u).ravel(),
                        rtol=1e-11, atol=1e-11)


def test_accelerations_match_lagranges_method(case):
    """q̈ from rhs equals M⁻¹f of LagrangesMethod (rhs solves the same system as the reference)."""
    mod, M, f = case
    rng = np.random.default_rng(13)
    for _ in range(3):
        q, qd, tv, p, u = random_point(mod, rng)
        qdd = np.linalg.solve(M(q, qd, tv, p, u), f(q, qd, tv, p, u).ravel())
        ydot = mod.rhs(tv, np.concatenate([q, qd]), p, u)
        assert_allclose(ydot, np.concatenate([qd, qdd]), rtol=1e-10, atol=1e-10)
