"""`lagrgen.from_sympy` of constrained SymPy models against SymPy's own constrained equations.

SymPy's accelerations (and, for LagrangesMethod, multipliers) come from its augmented
mass_matrix_full·[q̇; q̈; λ] = forcing_full (KanesMethod: [q̇; u̇], u = q̇), solved numerically at
states that satisfy the constraints; lagrgen's from `rhs` and `constraint_forces` there.

Sign convention (documented in `lagrgen.sympy_interop`): lagrgen's M·q̈ = F + Aᵀλ. The λ solved
from SymPy's mass_matrix_full/forcing_full is the same λ; SymPy's `eom` expression and
`solve_multipliers` carry the opposite sign (λ_lagrgen = −λ_solve_multipliers).
"""
import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from numpy.testing import assert_allclose

import lagrgen

t = me.dynamicsymbols._t


def numeric(expr, values):
    return np.array(me.msubs(sp.Matrix(expr), values).evalf(), dtype=float)


def sympy_solution(mass_full, forcing_full, values):
    return np.linalg.solve(numeric(mass_full, values), numeric(forcing_full, values).ravel())


@pytest.fixture(scope="module", params=["python", "c"])
def backend(request):
    return request.param


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("gen_sympy_constraints")


def cartesian_pendulum():
    """A particle at (x, y) on a rod of length L: LagrangesMethod with hol_coneqs x² + y² − L²,
    and a horizontal force P·cos(t)... as a forcelist entry (time-dependent load)."""
    x, y = me.dynamicsymbols("x y")
    m, g, L, P = sp.symbols("m g L P", positive=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    B = O.locatenew("B", x * N.x + y * N.y)
    B.set_vel(N, x.diff() * N.x + y.diff() * N.y)
    bob = me.Particle("bob", B, m)
    bob.potential_energy = m * g * y
    lm = me.LagrangesMethod(me.Lagrangian(N, bob), [x, y], hol_coneqs=[x ** 2 + y ** 2 - L ** 2],
                            forcelist=[(B, P * sp.cos(t) * N.x)], frame=N)
    lm.form_lagranges_equations()
    return lm, {m: 1.3, g: 9.81, L: 0.8, P: 0.4}


def knife_edge():
    """A sleigh: a rigid body at (x, y) heading θ, its knife edge at the c.o.m. − a along the
    heading; nonhol_coneqs: no sideways velocity of the edge; a torque and a pull as loads."""
    x, y, th = me.dynamicsymbols("x y theta")
    m, I, a, f, tau = sp.symbols("m I a f tau", positive=True)
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [th, N.z])
    G = me.Point("G")
    G.set_vel(N, x.diff() * N.x + y.diff() * N.y)
    body = me.RigidBody("body", G, A, m, (me.inertia(A, 0, 0, I), G))
    edge_velocity = G.vel(N) + A.ang_vel_in(N).cross(-a * A.x)   # the edge at G − a·A.x
    sideways = edge_velocity.dot(A.y)
    lm = me.LagrangesMethod(me.Lagrangian(N, body), [x, y, th], nonhol_coneqs=[sideways],
                            forcelist=[(G, f * A.x), (A, tau * N.z)], frame=N)
    lm.form_lagranges_equations()
    return lm, {m: 2.0, I: 0.3, a: 0.25, f: 0.7, tau: 0.2}


def check_lagrange(lm, values, mod, y, t0=0.4):
    n = len(lm.q)
    y = lagrgen.consistent_state(mod, y, t=t0)
    state = dict(zip(lm.q, y[:n]))
    state.update(zip([q.diff() for q in lm.q], y[n:]))
    state[t] = t0
    ours = mod.rhs(t0, y)
    theirs = sympy_solution(lm.mass_matrix_full, lm.forcing_full, {**values, **state})
    assert_allclose(ours, theirs[:2 * n], rtol=1e-9, atol=1e-12)
    lam = mod.constraint_forces(t0, y)
    assert_allclose(lam, theirs[2 * n:], rtol=1e-9, atol=1e-12)
    multipliers = lm.solve_multipliers({**values, **state,
                                        **dict(zip([q.diff(t, 2) for q in lm.q], ours[n:]))})
    assert_allclose(lam, [-float(multipliers[v]) for v in lm.lam_vec], rtol=1e-8)
    return y


def test_cartesian_pendulum_hol_coneqs(backend, out_dir):
    lm, values = cartesian_pendulum()
    model = lagrgen.from_sympy(lm, "sym_cartesian_pendulum", defaults=values)
    mod = lagrgen.build(model, backend=backend, out_dir=out_dir)
    assert mod.n_constraints == 1 and mod.coordinates == ("x", "y")
    for th, w in ((0.7, 1.1), (-2.0, -0.4), (3.0, 2.5)):
        y0 = [0.8 * np.sin(th), -0.8 * np.cos(th), 0.8 * w * np.cos(th), 0.8 * w * np.sin(th)]
        y = check_lagrange(lm, values, mod, y0)
        assert_allclose(mod.constraint_residuals(0.4, y), 0, atol=1e-12)
    # the rod pulls the bob up at rest at the bottom: λ·∂Φ/∂y = λ·2y > 0 with y < 0, λ = −mg/(2L)
    lam = mod.constraint_forces(0.0, [0.0, -0.8, 0.0, 0.0])
    assert_allclose(lam, [-1.3 * 9.81 / (2 * 0.8)], rtol=1e-12)


def test_simulation_keeps_the_rod_length(out_dir):
    lm, values = cartesian_pendulum()
    model = lagrgen.from_sympy(lm, "sym_cartesian_pendulum", defaults=values)
    mod = lagrgen.build(model, out_dir=out_dir)
    sol = lagrgen.simulate(mod, (0, 3), [0.8 * np.sin(1.0), -0.8 * np.cos(1.0), 0, 0],
                           method="DOP853", rtol=1e-10, atol=1e-12)
    assert_allclose(np.hypot(sol.q[0], sol.q[1]), 0.8, atol=1e-7)


def test_knife_edge_nonhol_coneqs(backend, out_dir):
    lm, values = knife_edge()
    model = lagrgen.from_sympy(lm, "sym_knife_edge", defaults=values)
    mod = lagrgen.build(model, backend=backend, out_dir=out_dir)
    assert mod.n_constraints == 1
    rng = np.random.default_rng(3)
    for _ in range(3):
        y = check_lagrange(lm, values, mod, rng.uniform(-1, 1, 6))
        assert_allclose(mod.constraint_residuals(0.4, y), 0, atol=1e-12)


def kane_pendulum_with_dependent_coordinate():
    """A particle at (x, y) on a rod: x independent, y dependent (x² + y² = L²); u = q̇; the
    velocity constraint x·u1 + y·u2 = 0 is the configuration constraint's derivative."""
    x, y = me.dynamicsymbols("x y")
    u1, u2 = me.dynamicsymbols("u1 u2")
    m, g, L = sp.symbols("m g L", positive=True)
    N = me.ReferenceFrame("N")
    P = me.Point("P")
    P.set_vel(N, u1 * N.x + u2 * N.y)
    km = me.KanesMethod(N, q_ind=[x], u_ind=[u1], kd_eqs=[u1 - x.diff(), u2 - y.diff()],
                        q_dependent=[y], configuration_constraints=[x ** 2 + y ** 2 - L ** 2],
                        u_dependent=[u2], velocity_constraints=[x * u1 + y * u2])
    km.kanes_equations([me.Particle("p", P, m)], [(P, -m * g * N.y)])
    return km, {m: 0.9, g: 9.81, L: 1.2}


def kane_sleigh():
    """The knife edge of `knife_edge` with KanesMethod: u = q̇, the sideways speed dependent."""
    x, y, th = me.dynamicsymbols("x y theta")
    u1, u2, u3 = me.dynamicsymbols("u1 u2 u3")
    m, I, a, f, tau = sp.symbols("m I a f tau", positive=True)
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [th, N.z])
    A.set_ang_vel(N, u3 * N.z)
    G = me.Point("G")
    G.set_vel(N, u1 * N.x + u2 * N.y)
    body = me.RigidBody("body", G, A, m, (me.inertia(A, 0, 0, I), G))
    sideways = (G.vel(N) + A.ang_vel_in(N).cross(-a * A.x)).dot(A.y)
    km = me.KanesMethod(N, q_ind=[x, y, th], u_ind=[u1, u3], u_dependent=[u2],
                        kd_eqs=[u1 - x.diff(), u2 - y.diff(), u3 - th.diff()],
                        velocity_constraints=[sideways])
    km.kanes_equations([body], [(G, f * A.x), (A, tau * N.z)])
    return km, {m: 2.0, I: 0.3, a: 0.25, f: 0.7, tau: 0.2}


def check_kane(km, values, mod, y):
    n = len(km.q)
    y = lagrgen.consistent_state(mod, y)
    rates = {q.diff(): v for q, v in zip(km.q, y[n:])}
    speeds = {km.kindiffdict()[q.diff()]: v for q, v in zip(km.q, y[n:])}
    state = {**dict(zip(km.q, y[:n])), **rates, **speeds}
    theirs = sympy_solution(km.mass_matrix_full, km.forcing_full, {**values, **state})
    udot = dict(zip(km.u, theirs[n:]))
    qdd = [udot[km.kindiffdict()[q.diff()]] for q in km.q]
    assert_allclose(mod.rhs(0.0, y), np.concatenate([y[n:], qdd]), rtol=1e-9, atol=1e-12)
    return y


def test_kane_dependent_coordinate(backend, out_dir):
    km, values = kane_pendulum_with_dependent_coordinate()
    model = lagrgen.from_sympy(km, "sym_kane_rod", defaults=values)
    assert len(model.spec().constraints) == 1 and not model.spec().velocity_constraints
    mod = lagrgen.build(model, backend=backend, out_dir=out_dir)
    assert mod.coordinates == ("x", "y") and mod.n_constraints == 1
    for th, w in ((0.5, 0.3), (-1.2, 2.0)):
        check_kane(km, values, mod, [1.2 * np.sin(th), -1.2 * np.cos(th),
                                     1.2 * w * np.cos(th), 1.2 * w * np.sin(th)])
    # the rod's tension: λ·(2x, 2y) is the force on the bob, at rest at the bottom m·g up
    lam = mod.constraint_forces(0.0, [0.0, -1.2, 0.0, 0.0])
    assert_allclose(lam * 2 * -1.2, 0.9 * 9.81, rtol=1e-12)


def test_kane_dependent_speed(backend, out_dir):
    km, values = kane_sleigh()
    model = lagrgen.from_sympy(km, "sym_kane_sleigh", defaults=values)
    assert not model.spec().constraints and len(model.spec().velocity_constraints) == 1
    mod = lagrgen.build(model, backend=backend, out_dir=out_dir)
    rng = np.random.default_rng(5)
    for _ in range(3):
        check_kane(km, values, mod, rng.uniform(-1, 1, 6))
    # the same sleigh from LagrangesMethod: the same rhs
    lm, _ = knife_edge()
    other = lagrgen.build(lagrgen.from_sympy(lm, "sym_knife_edge", defaults=values),
                          backend=backend, out_dir=out_dir)
    y = lagrgen.consistent_state(mod, rng.uniform(-1, 1, 6))
    assert_allclose(mod.rhs(0.0, y), other.rhs(0.0, y), rtol=1e-10, atol=1e-12)
    assert_allclose(mod.constraint_forces(0.0, y), other.constraint_forces(0.0, y), rtol=1e-10)


def test_kane_auxiliary_speeds_are_refused():
    x = me.dynamicsymbols("x")
    u, ua = me.dynamicsymbols("u ua")
    m = sp.Symbol("m")
    N = me.ReferenceFrame("N")
    P = me.Point("P")
    P.set_vel(N, u * N.x + ua * N.y)
    km = me.KanesMethod(N, q_ind=[x], u_ind=[u], kd_eqs=[u - x.diff()], u_auxiliary=[ua])
    km.kanes_equations([me.Particle("p", P, m)], [(P, -x * N.x)])
    with pytest.raises(lagrgen.ModelError, match="auxiliary"):
        lagrgen.from_sympy(km, "bad")


def kane_four_bar(rocker_mass=True):
    """A four-bar linkage: cranks of lengths l1 (at O) and l3 (at D = (d, 0)) joined by a coupler
    l2; point masses at the joints A and B and at the middle C of the second crank (without it
    q3 has no inertia of its own: a ModelError, see below); q1 independent, q2, q3 dependent through the loop
    closure, their speeds through its time derivative."""
    q1, q2, q3 = me.dynamicsymbols("q1:4")
    u1, u2, u3 = me.dynamicsymbols("u1:4")
    l1, l2, l3, d, mA, mB, g = sp.symbols("l1 l2 l3 d m_A m_B g", positive=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    A = O.locatenew("A", l1 * (sp.cos(q1) * N.x + sp.sin(q1) * N.y))
    B = A.locatenew("B", l2 * (sp.cos(q2) * N.x + sp.sin(q2) * N.y))
    loop = (B.pos_from(O) - (d * N.x + l3 * (sp.cos(q3) * N.x + sp.sin(q3) * N.y)))
    config = [loop.dot(N.x), loop.dot(N.y)]
    to_u = {q.diff(): u for q, u in zip((q1, q2, q3), (u1, u2, u3))}
    velocity = [sp.diff(c, t).xreplace(to_u) for c in config]
    C = O.locatenew("C", d * N.x + l3 / 2 * (sp.cos(q3) * N.x + sp.sin(q3) * N.y))
    O.set_vel(N, 0)
    C.set_vel(N, C.pos_from(O).dt(N).xreplace(to_u))
    A.set_vel(N, A.pos_from(O).dt(N).xreplace(to_u))
    B.set_vel(N, B.pos_from(O).dt(N).xreplace(to_u))
    km = me.KanesMethod(N, q_ind=[q1], u_ind=[u1], q_dependent=[q2, q3],
                        u_dependent=[u2, u3], configuration_constraints=config,
                        velocity_constraints=velocity,
                        kd_eqs=[u - q.diff() for q, u in zip((q1, q2, q3), (u1, u2, u3))])
    mC = sp.Symbol("m_C", positive=True)
    bodies = [me.Particle("pA", A, mA), me.Particle("pB", B, mB)]
    loads = [(A, -mA * g * N.y), (B, -mB * g * N.y)]
    if rocker_mass:
        bodies.append(me.Particle("pC", C, mC))
        loads.append((C, -mC * g * N.y))
    km.kanes_equations(bodies, loads)
    return km, {l1: 1.0, l2: 2.0, l3: 1.5, d: 2.0, mA: 0.7, mB: 1.1, mC: 0.4, g: 9.81}


def test_kane_four_bar(backend, out_dir):
    km, values = kane_four_bar()
    model = lagrgen.from_sympy(km, "sym_four_bar", defaults=values)
    assert len(model.spec().constraints) == 2 and not model.spec().velocity_constraints
    mod = lagrgen.build(model, backend=backend, out_dir=out_dir)
    for guess in ([1.0, 0.2, 1.3, 0.8, 0.0, 0.0], [1.6, 0.0, 1.8, -1.5, 0.3, 0.1]):
        y = check_kane(km, values, mod, guess)
        assert_allclose(mod.constraint_residuals(0.0, y), 0, atol=1e-10)
    sol = lagrgen.simulate(mod, (0, 1), lagrgen.consistent_state(mod, [1.0, 0.2, 1.3, 0, 0, 0]),
                           method="DOP853", rtol=1e-9, atol=1e-11)
    assert sol.success and np.abs(sol.constraint_residuals).max() < 1e-7


def test_a_massless_dependent_coordinate_is_explained():
    km, values = kane_four_bar(rocker_mass=False)
    with pytest.raises(lagrgen.ModelError, match="q3.*no inertia of its own"):
        lagrgen.from_sympy(km, "bad", defaults={k: v for k, v in values.items()
                                                 if k.name != "m_C"})


def test_a_system_with_a_dependent_coordinate(backend, out_dir):
    """A `System` (KanesMethod underneath) of a bob at (x, y), y dependent through the rod."""
    x, y = me.dynamicsymbols("x y")
    ux, uy = me.dynamicsymbols("u_x u_y")
    m, g, L = sp.symbols("m g L", positive=True)
    ground = me.RigidBody("ground")
    N = ground.frame
    system = me.System.from_newtonian(ground)
    system.add_coordinates(x, y, independent=[True, False])
    system.add_speeds(ux, uy, independent=[True, False])
    system.add_kdes(ux - x.diff(), uy - y.diff())
    P = system.fixed_point.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, ux * N.x + uy * N.y)
    system.add_bodies(me.Particle("bob", P, m))
    system.add_holonomic_constraints(x ** 2 + y ** 2 - L ** 2)
    system.velocity_constraints = [x * ux + y * uy]
    system.apply_uniform_gravity(-g * N.y)
    values = {m: 0.9, g: 9.81, L: 1.2}
    model = lagrgen.from_sympy(system, "sym_system_rod", defaults=values)
    assert len(model.spec().constraints) == 1 and not model.spec().velocity_constraints
    mod = lagrgen.build(model, backend=backend, out_dir=out_dir)
    check_kane(system.eom_method, values, mod, [0.5, -1.0, 0.4, 0.1])
    rod = lagrgen.build(lagrgen.from_sympy(kane_pendulum_with_dependent_coordinate()[0],
                                           "sym_kane_rod", defaults=values),
                        backend=backend, out_dir=out_dir)
    y0 = lagrgen.consistent_state(mod, [0.5, -1.0, 0.4, 0.1])
    assert_allclose(mod.constraint_forces(0.0, y0), rod.constraint_forces(0.0, y0), rtol=1e-12)
