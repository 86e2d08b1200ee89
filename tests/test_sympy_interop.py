"""`lagrgen.from_sympy` against SymPy's own equations: a cart-pole `System` made of joints, an n-link
`LagrangesMethod`, a 3-D body on a `SphericalJoint` and a `KanesMethod` whose speeds are listed in
another order. SymPy's rhs is its mass_matrix_full⁻¹·forcing_full, evaluated numerically."""
import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import ModelError

t = me.dynamicsymbols._t


def cart_pole(extra_load=None):
    """A cart on a rail (PrismaticJoint) carrying a pole (PinJoint), gravity, a force F on the cart."""
    m_c, m_p, l, g, I_p = sp.symbols("m_c m_p l g I_p", positive=True)
    F = me.dynamicsymbols("F")
    rail = me.RigidBody("rail")
    cart = me.RigidBody("cart", mass=m_c)
    pole = me.RigidBody("pole", mass=m_p)
    pole.inertia = (me.inertia(pole.frame, 0, 0, I_p), pole.masscenter)
    slider = me.PrismaticJoint("slider", rail, cart, joint_axis=rail.x)
    pin = me.PinJoint("pin", cart, pole, joint_axis=cart.z, child_point=l * pole.y)
    system = me.System.from_newtonian(rail)
    system.add_joints(slider, pin)
    system.apply_uniform_gravity(-g * rail.y)
    system.add_loads(me.Force(cart, F * rail.x))
    if extra_load is not None:
        system.add_loads(extra_load(rail, cart, pole, slider, pin))
    return system


CART_POLE_DEFAULTS = {"m_c": 1.0, "m_p": 0.3, "l": 0.5, "g": 9.81, "I_p": 0.01}


def nlink_lagrange(n):
    """A planar n-link pendulum of point masses as a LagrangesMethod, with a torque input at the
    first joint."""
    q = me.dynamicsymbols(f"th1:{n + 1}")
    tau = me.dynamicsymbols("tau")
    m = sp.symbols(f"m1:{n + 1}")
    L = sp.symbols(f"L1:{n + 1}")
    g = sp.Symbol("g")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P, particles, frames = O, [], []
    for i in range(n):
        A = N.orientnew(f"A{i}", "Axis", [q[i], N.z])
        frames.append(A)
        P = P.locatenew(f"P{i}", -L[i] * A.y)
        P.set_vel(N, P.pos_from(O).dt(N))
        particles.append(me.Particle(f"pa{i}", P, m[i]))
    V = sum(m[i] * g * particles[i].point.pos_from(O).dot(N.y) for i in range(n))
    lm = me.LagrangesMethod(me.Lagrangian(N, *particles) - V, q,
                            forcelist=[(frames[0], tau * N.z)], frame=N)
    lm.form_lagranges_equations()
    defaults = {**{s: 1.0 + 0.1 * i for i, s in enumerate(m)},
                **{s: 0.5 + 0.1 * i for i, s in enumerate(L)}, g: 9.81}
    return lm, defaults


def spherical_top():
    """A rigid body hanging from a fixed point on a SphericalJoint (3 body-fixed angles), gravity,
    a torque input about the body's own z axis."""
    m, l, g, Ixx, Iyy, Izz = sp.symbols("m l g Ixx Iyy Izz")
    T = me.dynamicsymbols("T")
    ground = me.RigidBody("ground")
    body = me.RigidBody("body", mass=m)
    body.inertia = (me.inertia(body.frame, Ixx, Iyy, Izz), body.masscenter)
    joint = me.SphericalJoint("ball", ground, body, child_point=l * body.z)
    system = me.System.from_newtonian(ground)
    system.add_joints(joint)
    system.apply_uniform_gravity(-g * ground.z)
    system.add_loads(me.Torque(body, T * body.z))
    defaults = {"m": 2.0, "l": 0.4, "g": 9.81, "Ixx": 0.3, "Iyy": 0.2, "Izz": 0.1}
    return system, defaults


def sympy_rhs(obj, model):
    """f(y, p, u) = ẏ from `obj`'s own mass_matrix_full and forcing_full (SymPy's rhs), with y, p,
    u in the orders of the lagrgen `model`; speeds u_i = q̇_i (Kane) or q̇_i (Lagrange)."""
    method = obj.eom_method if isinstance(obj, me.System) else obj
    q = list(method.q)
    speeds = list(method.u) if isinstance(method, me.KanesMethod) else [qi.diff(t) for qi in q]
    kindiff = method.kindiffdict() if isinstance(method, me.KanesMethod) else {}
    rates = [kindiff.get(qi.diff(t), qi.diff(t)) for qi in q]   # q̇_i as a speed
    MM, FF = method.mass_matrix_full, method.forcing_full
    free = set().union(*(e.free_symbols for e in list(MM) + list(FF))) - {t}
    params = {s.name: s for s in free}
    funcs = set().union(*(e.atoms(sp.core.function.AppliedUndef) for e in list(MM) + list(FF)))
    inputs = {f.func.__name__: f for f in funcs if f not in q and f not in speeds}
    Q, U = sp.symbols(f"_q0:{len(q)}"), sp.symbols(f"_u0:{len(q)}")
    rules = {**dict(zip(speeds, U)), **dict(zip(q, Q))}
    P = [params[name] for name in model.parameter_names]
    I = [inputs.get(name, sp.Symbol(f"_unused_{name}")) for name in model.input_names]
    f = sp.lambdify([Q, U, P, I], [MM.xreplace(rules), FF.xreplace(rules)], "numpy")
    n = len(q)
    index = [speeds.index(r) for r in rates]   # speed slot holding q̇_i

    def rhs(y, p, u):
        us = np.empty(n)
        us[index] = y[n:]
        M, F = f(list(y[:n]), list(us), list(p), list(u))
        x = np.linalg.solve(np.asarray(M, float), np.asarray(F, float).ravel())  # [q̇; u̇]
        return np.concatenate([x[:n], x[n:][index]])
    return rhs


def compare(obj, model, mod, seed=1, points=5, rtol=1e-12):
    ref = sympy_rhs(obj, model)
    rng = np.random.default_rng(seed)
    n = mod.n_coordinates
    worst = 0.0
    for _ in range(points):
        y = np.concatenate([rng.uniform(-1.2, 1.2, n), rng.uniform(-2, 2, n)])
        p = np.asarray(mod.defaults) * rng.uniform(0.7, 1.3, len(mod.parameters))
        u = rng.uniform(-1, 1, len(mod.inputs))
        got, want = mod.rhs(0.3, y, p, u), ref(y, p, u)
        assert_allclose(got, want, rtol=rtol, atol=rtol * np.max(np.abs(want)))
        worst = max(worst, np.max(np.abs(got - want)) / np.max(np.abs(want)))
    return worst


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("gen_sympy")


@pytest.mark.parametrize("backend", ["c", "python"])
def test_cart_pole_from_joints(backend, out_dir):
    system = cart_pole()
    model = lagrgen.from_sympy(system, "cart_pole_joints", defaults=CART_POLE_DEFAULTS)
    assert model.coordinate_names == ("q_slider", "q_pin")
    assert model.parameter_names == tuple(CART_POLE_DEFAULTS)
    assert model.input_names == ("F",)
    mod = lagrgen.build(model, backend=backend, out_dir=out_dir)
    compare(system, model, mod)
    # the Jacobian is the derivative of that rhs
    y = np.array([0.2, 0.7, -0.4, 1.1])
    J = mod.jacobian(0.0, y, None, [0.3])
    h = 1e-6
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        fd = (mod.rhs(0.0, y + e, None, [0.3]) - mod.rhs(0.0, y - e, None, [0.3])) / (2 * h)
        assert_allclose(J[:, j], fd, rtol=1e-6, atol=1e-7)


def test_nlink_lagrange_both_backends(out_dir):
    lm, defaults = nlink_lagrange(4)
    model = lagrgen.from_sympy(lm, "nlink4_sympy", defaults=defaults)
    assert model.coordinate_names == ("th1", "th2", "th3", "th4")
    assert model.parameter_names[:4] == ("m1", "m2", "m3", "m4")
    for backend in ("c", "python"):
        compare(lm, model, lagrgen.build(model, backend=backend, out_dir=out_dir))


def test_spherical_joint_3d_body(out_dir):
    system, defaults = spherical_top()
    model = lagrgen.from_sympy(system, "spherical_top", defaults=defaults)
    assert model.coordinate_names == tuple(str(c.func) for c in system.q)
    mod = lagrgen.build(model, out_dir=out_dir)
    compare(system, model, mod, points=8)


def test_kanes_method_with_speeds_in_another_order(out_dir):
    """u1 = q̇2, u2 = q̇1: the rows and columns of Kane's M are put in coordinate order."""
    x, th = me.dynamicsymbols("x th")
    u1, u2 = me.dynamicsymbols("u1 u2")
    m, M_, l, g, k = sp.symbols("m M l g k")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [th, N.z])
    A.set_ang_vel(N, u1 * N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", x * N.x)
    C.set_vel(N, u2 * N.x)
    P = C.locatenew("P", -l * A.y)
    P.v2pt_theory(C, N, A)
    bodies = [me.Particle("cart", C, M_), me.Particle("bob", P, m)]
    loads = [(C, -k * x * N.x), (P, -m * g * N.y)]
    km = me.KanesMethod(N, q_ind=[x, th], u_ind=[u1, u2], kd_eqs=[u1 - th.diff(), u2 - x.diff()])
    km.kanes_equations(bodies, loads)
    model = lagrgen.from_sympy(km, "kane_swapped", defaults={"m": 0.5, "M": 2.0, "l": 0.8,
                                                              "g": 9.81, "k": 30.0})
    assert model.coordinate_names == ("x", "th")
    mod = lagrgen.build(model, out_dir=out_dir)
    compare(km, model, mod)


def test_system_formed_with_lagranges_method():
    """A System whose bodies move with q̇ works with LagrangesMethod too; one whose velocities are
    in the joints' speeds gets M = 0 from SymPy, which is refused."""
    th = me.dynamicsymbols("th")
    m, l, g = sp.symbols("m l g")
    ground = me.RigidBody("ground")
    N, O = ground.frame, ground.masscenter
    P = O.locatenew("P", l * (sp.sin(th) * N.x - sp.cos(th) * N.y))
    P.set_vel(N, P.pos_from(O).dt(N))
    system = me.System.from_newtonian(ground)
    system.add_coordinates(th)
    system.add_bodies(me.Particle("bob", P, m))
    system.apply_uniform_gravity(-g * N.y)
    system.form_eoms(eom_method=me.LagrangesMethod)
    py = lagrgen.build(lagrgen.from_sympy(system, "pend_system", {"m": 1.0, "l": 2.0, "g": 9.81}),
                       backend="python")
    assert_allclose(py.rhs(0.0, [0.3, 0.7]), [0.7, -9.81 / 2.0 * np.sin(0.3)], rtol=1e-15)
    joints = cart_pole()
    joints.form_eoms(eom_method=me.LagrangesMethod)
    with pytest.raises(ModelError, match="zero diagonal entry"):
        lagrgen.from_sympy(joints, "bad", CART_POLE_DEFAULTS)


def test_a_changed_sympy_model_is_never_served_stale(out_dir):
    """Same name, same out_dir: a torsion spring added to the SymPy model changes the build."""
    first = cart_pole()
    mod1 = lagrgen.build(lagrgen.from_sympy(first, "cart_pole_stale", CART_POLE_DEFAULTS),
                         out_dir=out_dir)
    y = np.array([0.1, 0.5, 0.0, 0.0])
    a1 = mod1.rhs(0.0, y)
    kappa = 3.0

    def spring(rail, cart, pole, slider, pin):
        return me.Torque(pole, -kappa * pin.coordinates[0] * cart.z)
    second = cart_pole(spring)
    model2 = lagrgen.from_sympy(second, "cart_pole_stale", CART_POLE_DEFAULTS)
    mod2 = lagrgen.build(model2, out_dir=out_dir)
    assert mod2.build_info["cache_hit"] is False
    a2 = mod2.rhs(0.0, y)
    assert not np.allclose(a1, a2)
    compare(second, model2, mod2)
    # and a later process loading by name gets the new one
    assert_allclose(lagrgen.load("cart_pole_stale", out_dir=out_dir).rhs(0.0, y), a2, rtol=0)
    # building the first again is a cache hit on its own entry, with its own numbers
    mod3 = lagrgen.build(lagrgen.from_sympy(cart_pole(), "cart_pole_stale", CART_POLE_DEFAULTS),
                         out_dir=out_dir)
    assert mod3.build_info["cache_hit"] is True
    assert_allclose(mod3.rhs(0.0, y), a1, rtol=0)


def test_lagrgen_physics_adds_to_a_sympy_model(out_dir):
    """A torsion spring declared on the lagrgen side equals the same spring as a SymPy load."""
    kappa = 3.0
    model = lagrgen.from_sympy(cart_pole(), "cart_pole_plus", CART_POLE_DEFAULTS)
    k, = model.parameters(kappa=kappa)
    model.spring(k, model.q[1])
    reference = cart_pole(lambda rail, cart, pole, slider, pin:
                          me.Torque(pole, -kappa * pin.coordinates[0] * cart.z))
    mod = lagrgen.build(model, out_dir=out_dir)
    ref = sympy_rhs(reference, lagrgen.from_sympy(reference, "ref", CART_POLE_DEFAULTS))
    y = np.array([0.3, -0.6, 0.4, 1.2])
    assert_allclose(mod.rhs(0.0, y, None, [0.2]), ref(y, mod.defaults[:5], [0.2]), rtol=1e-13)


def test_simulate_vibration_and_cli(out_dir, tmp_path, capsys):
    system = cart_pole()
    model = lagrgen.from_sympy(system, "cart_pole_run", CART_POLE_DEFAULTS)
    mod = lagrgen.build(model, out_dir=out_dir)
    sol = lagrgen.simulate(mod, (0, 1), {"q_pin": 0.3}, method="Radau", inputs={"F": 0.5},
                           rtol=1e-9, atol=1e-11)
    assert sol.success and sol.coordinates == ("q_slider", "q_pin")
    # energy balance with F = 0: T + V conserved
    free = lagrgen.simulate(mod, (0, 2), [0.0, 0.8, 0.3, 0.0], method="DOP853", rtol=1e-11,
                            atol=1e-12)
    m_c, m_p, l, g, I_p = mod.defaults

    def energy(y):
        x, th, xd, thd = y
        vx, vy = xd + l * thd * np.cos(th), l * thd * np.sin(th)
        return 0.5 * m_c * xd ** 2 + 0.5 * m_p * (vx ** 2 + vy ** 2) + 0.5 * I_p * thd ** 2 \
            - m_p * g * l * np.cos(th)
    e = [energy(free.y[:, k]) for k in range(free.y.shape[1])]
    assert np.ptp(e) < 1e-8
    # small oscillations with a free cart: ω² = g·l·m_p·(m_c + m_p) / (J·(m_c + m_p) − (l·m_p)²)
    res = lagrgen.modes(mod, [0.0, 0.0])
    J = I_p + l ** 2 * m_p
    omega = np.sqrt(g * l * m_p * (m_c + m_p) / (J * (m_c + m_p) - (l * m_p) ** 2))
    assert_allclose(res.omega, [0.0, omega], atol=1e-7, rtol=1e-12)
    # a model file that builds its model with from_sympy works with the command line
    src = tmp_path / "cp_file.py"
    src.write_text(
        "import sys\nsys.path.insert(0, %r)\nimport lagrgen\nfrom test_sympy_interop import "
        "cart_pole, CART_POLE_DEFAULTS\nmodel = lagrgen.from_sympy(cart_pole(), 'cart_pole_cli', "
        "CART_POLE_DEFAULTS)\n" % str(__import__("pathlib").Path(__file__).parent))
    from lagrgen.cli import main
    assert main(["modes", str(src), "--out", str(out_dir), "--quiet"]) == 0
    assert main(["modes", str(src), "--out", str(out_dir)]) == 0
    out = capsys.readouterr().out
    assert f"{omega:.6g}" in out
    assert main(["show", str(src), "--latex"]) == 0
    assert r"\ddot{q}_{pin}" in capsys.readouterr().out


def test_parameters_defaults_and_inputs():
    system = cart_pole()
    model = lagrgen.from_sympy(system, "cp_order", defaults={sp.Symbol("g", positive=True): 9.8,
                                                             "l": 0.5}, inputs=["F", "G"])
    # defaults first in their order, then the rest by name; none given: must be given at run time
    assert model.parameter_names == ("g", "l", "I_p", "m_c", "m_p")
    assert model.parameter_defaults == (9.8, 0.5, None, None, None)
    assert model.input_names == ("F", "G")
    py = lagrgen.build(model, backend="python")
    with pytest.raises(ValueError):
        py.rhs(0.0, np.zeros(4))
    assert np.all(np.isfinite(py.rhs(0.0, np.zeros(4), [9.8, 0.5, 0.01, 1, 0.3], [1, 0])))


def test_errors():
    with pytest.raises(ModelError, match="not a parameter"):
        lagrgen.from_sympy(cart_pole(), "bad", defaults={"mass": 1.0})
    with pytest.raises(ModelError, match="not among the inputs"):
        lagrgen.from_sympy(cart_pole(), "bad", inputs=[])
    with pytest.raises(TypeError, match="LagrangesMethod, KanesMethod"):
        lagrgen.from_sympy(sp.Matrix([1]), "bad")
    with pytest.raises(ModelError, match="model name"):
        lagrgen.from_sympy(cart_pole(), "not valid")
    # u ≠ q̇
    q = me.dynamicsymbols("q")
    u = me.dynamicsymbols("u")
    N = me.ReferenceFrame("N")
    P = me.Point("P")
    P.set_vel(N, u * N.x)
    km = me.KanesMethod(N, q_ind=[q], u_ind=[u], kd_eqs=[2 * u - q.diff()])
    km.kanes_equations([me.Particle("p", P, sp.Symbol("m"))], [(P, -q * N.x)])
    half = lagrgen.build(lagrgen.from_sympy(km, "half_rate", defaults={"m": 2.0}),
                         backend="python")     # u = q̇/2: m·u̇ = −q is q̈ = −2q/m
    assert_allclose(half.rhs(0.0, [0.3, 0.8]), [0.8, -0.3], rtol=1e-14)
    assert half.output_names[0] == "u" and half.outputs(0.0, [0.3, 0.8])[0] == 0.4
    # a System's constraints (LagrangesMethod and KanesMethod ones: test_sympy_constraints.py)
    system = cart_pole()
    system.add_holonomic_constraints(system.q[1])     # q[1] not declared dependent
    with pytest.raises(ModelError, match="could not form the System's equations"):
        lagrgen.from_sympy(system, "bad")
    # names that are not identifiers
    a = sp.Symbol("k[0]")
    x = me.dynamicsymbols("x")
    lm = me.LagrangesMethod(x.diff() ** 2 / 2 - a * x ** 2 / 2, [x])
    with pytest.raises(ModelError, match="not a Python identifier"):
        lagrgen.from_sympy(lm, "bad")


def test_external_mass_matrix_must_be_symmetric():
    """Entries equal in value but not in form pass (compared at random points); others do not."""
    model = lagrgen.Model("asymmetric")
    x, y = model.coordinates("x y")
    a, = model.parameters(a=1.0)
    model._add_equations(sp.Matrix([[1, a * sp.cos(x)], [a, 2]]), sp.Matrix([0, 0]))
    with pytest.raises(ModelError, match="not symmetric"):
        model.equations()
    same = lagrgen.Model("symmetric_in_value")
    x, y = same.coordinates("x y")
    same._add_equations(sp.Matrix([[1, sp.sin(x) ** 2 + sp.cos(x) ** 2 - sp.Rational(1, 2)],
                                   [sp.Rational(1, 2), 2]]), sp.Matrix([0, -y]))
    py = lagrgen.build(same, backend="python")
    assert_allclose(py.mass_matrix([0.4, 0.0]), [[1, 0.5], [0.5, 2]], rtol=1e-15)
    assert_allclose(py.rhs(0.0, [0.0, 1.0, 0.0, 0.0]), [0, 0, 2 / 7, -4 / 7], rtol=1e-14)
