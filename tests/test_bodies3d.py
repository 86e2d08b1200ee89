"""Three-dimensional rigid bodies (issue 15): rotation.x/y/z, rigid_body_3d, torque_3d.

Compared against: MuJoCo (hinge chains in the same Euler sequence for M and the bias forces, ball
joints with quaternions for trajectories), SymPy's KanesMethod (M and forcing), closed forms (steady
precession of the heavy top, intermediate-axis instability), conservation laws, the planar
`rigid_body`, finite differences of the analytic Jacobian, and the two backends against each other.
"""
import functools
import warnings

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

import lagrgen
from lagrgen import Model, rotation
from lagrgen.bodies3d import Kinematics, rotational_kinetic_energy
from lagrgen.errors import MassMatrixError, ModelError

from conftest import state_function

RNG = np.random.default_rng(20261123)


# -- the models ------------------------------------------------------------------------------------
def top_model():
    """Heavy symmetric top on a fixed tip: z-x-z Euler angles (precession, nutation, spin)."""
    model = Model("top3d")
    psi, theta, phi = model.coordinates("psi theta phi")
    m, I1, I3, l, g = model.parameters(m=1.0, I1=0.3, I3=0.5, l=0.4, g=9.81)
    R = rotation.z(psi) * rotation.x(theta) * rotation.z(phi)
    com = R * sp.Matrix([0, 0, l])
    model.rigid_body_3d(m, [I1, I1, I3], com, R)
    model.potential_energy(m * g * com[2])
    return model


def free_body_model():
    """Torque-free asymmetric body about its fixed centre of mass: x-y-z Tait–Bryan angles."""
    model = Model("free3d")
    a, b, c = model.coordinates("a b c")
    I1, I2, I3 = model.parameters(I1=0.2, I2=0.35, I3=0.5)
    R = rotation.x(a) * rotation.y(b) * rotation.z(c)
    model.rigid_body_3d(1.0, (I1, I2, I3), [0, 0, 0], R)
    return model


def spin_model():
    """The same body with the spin angle first, R = z(c)·x(a)·y(b): c is cyclic (T does not depend
    on it), so a steady spin about body z at a = b = 0 has constant-coefficient linearization."""
    model = Model("spin3d")
    c, a, b = model.coordinates("c a b")
    I1, I2, I3 = model.parameters(I1=0.2, I2=0.35, I3=0.5)
    model.rigid_body_3d(1.0, (I1, I2, I3), [0, 0, 0], rotation.z(c) * rotation.x(a) * rotation.y(b))
    return model


DP = dict(m1=1.0, m2=0.8, l1=1.0, l2=0.8, e1=0.05, g=9.81,
          J1=(0.09, 0.08, 0.012), J2=(0.05, 0.045, 0.009))


def double_pendulum_model():
    """Two bodies on ball joints; each joint is z-y-x angles relative to the parent body."""
    model = Model("dpend3d")
    a1, b1, c1, a2, b2, c2 = model.coordinates("a1 b1 c1 a2 b2 c2")
    m1, m2, l1, l2, e1, g = model.parameters(**{k: DP[k] for k in "m1 m2 l1 l2 e1 g".split()})
    R1 = rotation.sequence("zyx", (a1, b1, c1))
    R2 = R1 * rotation.z(a2) * rotation.y(b2) * rotation.x(c2)
    com1 = R1 * sp.Matrix([e1, 0, -l1 / 2])
    joint2 = R1 * sp.Matrix([0, 0, -l1])
    com2 = joint2 + R2 * sp.Matrix([0, 0, -l2 / 2])
    model.rigid_body_3d(m1, DP["J1"], com1, R1)
    model.rigid_body_3d(m2, sp.diag(*DP["J2"]), com2, R2)
    model.potential_energy(g * (m1 * com1[2] + m2 * com2[2]))
    model.line([0, 0, 0], joint2, joint2 + R2 * sp.Matrix([0, 0, -l2]))
    model.geometry = dict(R1=R1, R2=R2, com1=com1, com2=com2)
    return model


TOP, FREE, SPIN, DPEND = top_model(), free_body_model(), spin_model(), double_pendulum_model()


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(model, backend) -> built model, each built once in this module."""
    out = tmp_path_factory.mktemp("gen3d")
    return functools.lru_cache(maxsize=None)(
        lambda model, backend: lagrgen.build(model, backend=backend, out_dir=out))


def numeric(model, expr):
    """f(q) for a SymPy expression of the model's coordinates (parameters at their defaults)."""
    values = {s: d for s, d in zip(model.parameter_symbols, model.parameter_defaults)}
    f = state_function(sp.sympify(expr).xreplace(values), model.t, model.q, model.qd, (), ())
    return lambda q, qd=None: f(q, np.zeros(len(q)) if qd is None else qd, 0.0, [], [])


def random_state(n, scale=1.0):
    return RNG.uniform(-1.2, 1.2, n) * scale, RNG.uniform(-2.0, 2.0, n)


# -- rotations -------------------------------------------------------------------------------------
def test_rotation_convention_and_closed_form_angular_velocity():
    a = sp.Symbol("a")
    assert rotation.z(a) * sp.Matrix([1, 0, 0]) == sp.Matrix([sp.cos(a), sp.sin(a), 0])
    assert rotation.x(a) * sp.Matrix([0, 1, 0]) == sp.Matrix([0, sp.cos(a), sp.sin(a)])
    assert rotation.y(a) * sp.Matrix([0, 0, 1]) == sp.Matrix([sp.sin(a), 0, sp.cos(a)])
    t = sp.Symbol("t")
    q = [sp.Function(n)(t) for n in "pqr"]
    R = rotation.sequence("zyx", q)
    assert R.factors == (("z", q[0]), ("y", q[1]), ("x", q[2]))
    closed, general = Kinematics(R, q, t), Kinematics(sp.Matrix(R), q, t)
    assert closed.W.equals(general.W) and closed.W_fixed.equals(general.W_fixed)
    vals = dict(zip(q, RNG.uniform(-1, 1, 3)))
    rates = dict(zip([c.diff(t) for c in q], RNG.uniform(-1, 1, 3)))
    Rd = R.diff(t).xreplace(rates).xreplace(vals)
    S = np.array((sp.Matrix(R).T.xreplace(vals) * Rd).evalf(), dtype=float)   # ω̃ = RᵀṘ
    w = np.array(closed.omega.xreplace(rates).xreplace(vals).evalf(), dtype=float).ravel()
    assert_allclose(w, [S[2, 1], S[0, 2], S[1, 0]], atol=1e-14)
    assert_allclose(S, -S.T, atol=1e-14)
    changed = rotation.z(q[0])
    changed[:, :] = rotation.z(2 * q[0])                # edited in place: its factors are stale
    assert Kinematics(changed, q, t).W[2, 0] == 2


def test_rheonomic_orientation_rotor_spun_at_constant_rate():
    """A disc spun at Ω·t about its axis, the axis tilted by θ: T = ½I1θ̇² + ½I3Ω² (θ̇ ⟂ spin)."""
    model = Model("rotor3d")
    theta, = model.coordinates("theta")
    I1, I3, W = model.parameters(I1=0.2, I3=0.4, W=7.0)
    R = rotation.x(theta) * rotation.z(W * model.t)
    model.rigid_body_3d(1.0, [I1, I1, I3], [0, 0, 0], R)
    assert sp.simplify(model.mass_matrix()[0, 0] - I1) == 0
    assert sp.simplify(model.forcing()[0]) == 0
    # a precessing frame instead: the gyroscopic moment I3·Ω·ψ̇ appears
    model2 = Model("rotor3d_b")
    psi, = model2.coordinates("psi")
    I1, I3, W = model2.parameters(I1=0.2, I3=0.4, W=7.0)
    model2.rigid_body_3d(1.0, [I1, I1, I3], [0, 0, 0], rotation.z(psi) * rotation.x(W * model2.t))
    M = sp.simplify(model2.mass_matrix()[0, 0])
    assert sp.simplify(M - (I1 + (I3 - I1) * sp.cos(W * model2.t) ** 2)) == 0


# -- against SymPy's KanesMethod -------------------------------------------------------------------
def kane(model, build_bodies):
    """(M, forcing) from KanesMethod with u = q̇, in the model's own symbols."""
    from sympy.physics.mechanics import KanesMethod, Point, ReferenceFrame, dynamicsymbols
    q = list(model.q)
    u = dynamicsymbols(f"u0:{len(q)}")
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    bodies, loads = build_bodies(N, O, q)
    km = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)])
    km.kanes_equations(bodies, loads)
    back = dict(zip(u, model.qd))
    ud = {ui.diff(): 0 for ui in u}
    return km.mass_matrix.xreplace(back), km.forcing.xreplace(ud).xreplace(back)


def kane_top(N, O, q):
    from sympy.physics.mechanics import RigidBody, inertia
    m, I1, I3, l, g = TOP.parameter_symbols
    A = N.orientnew("A", "Body", q, "ZXZ")
    P = O.locatenew("P", l * A.z)
    P.v2pt_theory(O, N, A)
    body = RigidBody("top", P, A, m, (inertia(A, I1, I1, I3), P))
    return [body], [(P, -m * g * N.z)]


def kane_free(N, O, q):
    from sympy.physics.mechanics import RigidBody, inertia
    I1, I2, I3 = FREE.parameter_symbols
    A = N.orientnew("A", "Body", q, "XYZ")
    O.set_vel(N, 0)
    return [RigidBody("b", O, A, 1, (inertia(A, I1, I2, I3), O))], []


def kane_dpend(N, O, q):
    from sympy.physics.mechanics import RigidBody, inertia
    m1, m2, l1, l2, e1, g = DPEND.parameter_symbols
    A = N.orientnew("A", "Body", q[:3], "ZYX")
    B = A.orientnew("B", "Body", q[3:], "ZYX")
    P1 = O.locatenew("P1", e1 * A.x - l1 / 2 * A.z)
    J = O.locatenew("J", -l1 * A.z)
    P2 = J.locatenew("P2", -l2 / 2 * B.z)
    P1.v2pt_theory(O, N, A)
    J.v2pt_theory(O, N, A)
    P2.v2pt_theory(J, N, B)
    bodies = [RigidBody("b1", P1, A, m1, (inertia(A, *DP["J1"]), P1)),
              RigidBody("b2", P2, B, m2, (inertia(B, *DP["J2"]), P2))]
    # the orientation convention: N.dcm(A) maps A components to N components, like R1
    assert sp.simplify(N.dcm(A) - sp.Matrix(DPEND.geometry["R1"])) == sp.zeros(3, 3)
    return bodies, [(P1, -m1 * g * N.z), (P2, -m2 * g * N.z)]


@pytest.mark.parametrize("model, bodies", [(TOP, kane_top), (FREE, kane_free),
                                           (DPEND, kane_dpend)], ids=["top", "free", "dpend"])
def test_against_kanes_method(model, bodies, built):
    Mk, Fk = kane(model, bodies)
    mod = built(model, "c")
    args = (model.t, model.q, model.qd, model.parameter_symbols, ())
    fM, fF = state_function(Mk, *args), state_function(Fk, *args)
    for _ in range(5):
        q, qd = random_state(mod.n_coordinates)
        p = np.asarray(mod.defaults) * RNG.uniform(0.7, 1.3, len(mod.defaults))
        M = mod.mass_matrix(q, 0.0, p)
        assert_allclose(M, fM(q, qd, 0.0, p, []), rtol=1e-10, atol=1e-10 * np.abs(M).max())
        F = mod.forcing(q, qd, 0.0, p)
        assert_allclose(F, fF(q, qd, 0.0, p, []).ravel(), rtol=1e-10,
                        atol=1e-10 * np.abs(F).max())


# -- against MuJoCo ---------------------------------------------------------------------------------
def _mjcf(joints, gravity):
    """The double pendulum (or, with one body, the free body) as MJCF: `joints` per body is
    'ball' or a sequence of hinge axes."""
    def joint_xml(name, kind):
        if kind == "ball":
            return f'<joint name="{name}" type="ball"/>'
        axis = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}
        return "".join(f'<joint name="{name}{a}" type="hinge" axis="{axis[a]}"/>' for a in kind)
    d = DP
    return f"""
<mujoco>
  <option gravity="0 0 {-gravity}" timestep="5e-4" integrator="RK4"/>
  <worldbody>
    <body name="b1">
      {joint_xml("j1", joints[0])}
      <inertial pos="{d['e1']} 0 {-d['l1'] / 2}" mass="{d['m1']}" diaginertia="{' '.join(map(str, d['J1']))}"/>
      <body name="b2" pos="0 0 {-d['l1']}">
        {joint_xml("j2", joints[1])}
        <inertial pos="0 0 {-d['l2'] / 2}" mass="{d['m2']}" diaginertia="{' '.join(map(str, d['J2']))}"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""


FREE_XML = """
<mujoco>
  <option gravity="0 0 0" timestep="5e-4" integrator="RK4"/>
  <worldbody>
    <body name="b">
      {joints}
      <inertial pos="0 0 0" mass="1" diaginertia="0.2 0.35 0.5"/>
    </body>
  </worldbody>
</mujoco>"""


def test_mass_matrix_and_bias_against_mujoco_hinge_chains(built):
    mujoco = pytest.importorskip("mujoco")
    cases = [(DPEND, _mjcf(("zyx", "zyx"), DP["g"])),
             (FREE, FREE_XML.format(joints="".join(
                 f'<joint name="h{a}" type="hinge" axis="{v}"/>'
                 for a, v in zip("xyz", ("1 0 0", "0 1 0", "0 0 1")))))]
    for model, xml in cases:
        mj = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(mj)
        mod = built(model, "c")
        n = mod.n_coordinates
        assert mj.nv == n
        for _ in range(4):
            q, qd = random_state(n)
            data.qpos[:], data.qvel[:] = q, qd
            mujoco.mj_forward(mj, data)
            Mmj = np.zeros((n, n))
            try:                                    # MuJoCo ≥ 3.3: (model, data, dst)
                mujoco.mj_fullM(mj, data, Mmj)
            except TypeError:                       # older: (model, dst, data.qM)
                mujoco.mj_fullM(mj, Mmj, data.qM)
            assert_allclose(mod.mass_matrix(q), Mmj, rtol=1e-9, atol=1e-12)
            # M·q̈ = F and MuJoCo's M·q̈ + bias = 0 without other forces
            assert_allclose(mod.forcing(q, qd), -data.qfrc_bias, rtol=1e-9, atol=1e-10)


def _quat(R):
    import mujoco
    out = np.zeros(4)
    mujoco.mju_mat2Quat(out, np.asarray(R, dtype=float).ravel())
    return out


def _relative(axes):
    """(R(angles), ω_body(angles, rates)) numerically for the sequence `axes`."""
    t = sp.Symbol("t")
    q = [sp.Function(f"_a{i}")(t) for i in range(3)]
    kin = Kinematics(rotation.sequence(axes, q), q, t)
    A, B = sp.symbols("_A0:3"), sp.symbols("_B0:3")
    rules = {**dict(zip([c.diff(t) for c in q], B)), **dict(zip(q, A))}
    R = sp.lambdify([A], kin.R.xreplace(rules))
    w = sp.lambdify([A, B], kin.omega.xreplace(rules))
    return (lambda a: np.array(R(a), dtype=float),
            lambda a, b: np.array(w(a, b), dtype=float).ravel())


def _mujoco_run(xml, qpos, qvel, times, bodies):
    import mujoco
    mj = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(mj)
    data.qpos[:], data.qvel[:] = qpos, qvel
    out = []
    for T in times:
        while data.time < T - 1e-9:
            mujoco.mj_step(mj, data)
        mujoco.mj_kinematics(mj, data)
        out.append([(data.xmat[mj.body(b).id].reshape(3, 3).copy(),
                     data.xipos[mj.body(b).id].copy()) for b in bodies])
    return out


def test_double_pendulum_trajectory_against_mujoco_ball_joints(built):
    pytest.importorskip("mujoco")
    mod = built(DPEND, "c")
    q0 = np.array([0.3, 0.4, -0.5, -0.6, 0.2, 0.5])
    qd0 = np.array([1.0, -0.5, 0.8, 0.6, 1.2, -1.0])
    Rrel, wrel = _relative("zyx")
    qpos = np.concatenate([_quat(Rrel(q0[:3])), _quat(Rrel(q0[3:]))])
    qvel = np.concatenate([wrel(q0[:3], qd0[:3]), wrel(q0[3:], qd0[3:])])
    times = [0.25, 0.5, 1.0]
    ref = _mujoco_run(_mjcf(("ball", "ball"), DP["g"]), qpos, qvel, times, ["b1", "b2"])
    sol = solve_ivp(mod.rhs, (0, 1.0), np.concatenate([q0, qd0]), method="DOP853",
                    rtol=1e-11, atol=1e-11, dense_output=True)
    g = DPEND.geometry
    f = {k: numeric(DPEND, v) for k, v in g.items()}
    for T, bodies in zip(times, ref):
        q = sol.sol(T)[:6]
        for (Rm, xm), (Rk, xk) in zip(bodies, [("R1", "com1"), ("R2", "com2")]):
            assert_allclose(f[Rk](q), Rm, atol=2e-7)
            assert_allclose(f[xk](q).ravel(), xm, atol=2e-7)
    # the comparison can fail: a 1 % heavier second body is visibly different after 1 s
    p = mod.defaults.copy()
    p[1] *= 1.01
    other = solve_ivp(mod.rhs, (0, 1.0), np.concatenate([q0, qd0]), args=(p,), method="DOP853",
                      rtol=1e-11, atol=1e-11)
    assert np.abs(f["com2"](other.y[:6, -1]).ravel() - ref[-1][1][1]).max() > 1e-4


def test_free_body_trajectory_against_mujoco_ball_joint(built):
    pytest.importorskip("mujoco")
    mod = built(FREE, "c")
    q0, qd0 = np.array([0.2, -0.3, 0.4]), np.array([0.5, 1.5, 3.0])
    R, w = _relative("xyz")
    ref = _mujoco_run(FREE_XML.format(joints='<joint name="j" type="ball"/>'), _quat(R(q0)),
                      w(q0, qd0), [0.5, 1.0], ["b"])
    sol = solve_ivp(mod.rhs, (0, 1.0), np.concatenate([q0, qd0]), method="DOP853",
                    rtol=1e-11, atol=1e-11, dense_output=True)
    for T, [(Rm, _)] in zip([0.5, 1.0], ref):
        assert_allclose(R(sol.sol(T)[:3]), Rm, atol=1e-7)


# -- the heavy symmetric top ------------------------------------------------------------------------
def top_constants():
    m, I1, I3, l, g = TOP.parameter_defaults
    return m, I1 + m * l * l, I3, l, g


@pytest.mark.parametrize("root", [-1, 1], ids=["slow", "fast"])
def test_top_steady_precession_rate(built, root):
    """I1'·Ω²·cosθ − I3·ω3·Ω + m·g·l = 0 (I1' about the tip, ω3 = φ̇ + ψ̇·cosθ): θ stays put."""
    mod = built(TOP, "c")
    m, I1p, I3, l, g = top_constants()
    theta0, w3 = 0.6, 40.0
    c = np.cos(theta0)
    Omega = (I3 * w3 + root * np.sqrt((I3 * w3) ** 2 - 4 * I1p * c * m * g * l)) / (2 * I1p * c)

    def run(rate):
        y0 = [0.0, theta0, 0.0, rate, 0.0, w3 - rate * c]
        return solve_ivp(mod.rhs, (0, 1.0), y0, method="DOP853", rtol=1e-12, atol=1e-12)
    sol = run(Omega)
    assert np.abs(sol.y[1] - theta0).max() < 1e-8
    assert_allclose(sol.y[3], Omega, rtol=1e-8)
    assert np.abs(run(1.05 * Omega).y[1] - theta0).max() > 1e-4     # any other rate nutates


def test_top_conserved_momenta_and_energy(built):
    mod = built(TOP, "c")
    m, I1p, I3, l, g = top_constants()
    y0 = [0.1, 0.7, 0.0, 1.0, 0.5, 25.0]
    sol = solve_ivp(mod.rhs, (0, 2.0), y0, method="DOP853", rtol=1e-12, atol=1e-12)
    q, qd = sol.y[:3].T, sol.y[3:].T
    p = np.array([mod.mass_matrix(a) @ b for a, b in zip(q, qd)])      # ∂T/∂q̇ = M·q̇
    E = 0.5 * np.einsum("ij,ij->i", p, qd) + m * g * l * np.cos(q[:, 1])
    for values in (p[:, 0], p[:, 2], E):
        assert np.ptp(values) < 1e-8 * np.abs(values).max()
    assert np.ptp(q[:, 1]) > 1e-2            # it nutates: θ moves, p_θ is not conserved
    assert np.ptp(p[:, 1]) > 1e-2


# -- the torque-free asymmetric body ---------------------------------------------------------------
def test_free_body_energy_and_angular_momentum(built):
    mod = built(FREE, "c")
    kin = Kinematics(rotation.x(FREE.q[0]) * rotation.y(FREE.q[1]) * rotation.z(FREE.q[2]),
                     FREE.q, FREE.t)
    I = np.diag(FREE.parameter_defaults)
    R, w = numeric(FREE, kin.R), numeric(FREE, kin.omega)
    sol = solve_ivp(mod.rhs, (0, 3.0), [0.1, 0.2, 0.0, 0.3, -0.2, 4.0], method="DOP853",
                    rtol=1e-12, atol=1e-12)
    H, E = [], []
    for y in sol.y.T:
        wb = w(y[:3], y[3:]).ravel()
        H.append(R(y[:3]) @ I @ wb)
        E.append(0.5 * wb @ I @ wb)
    H, E = np.array(H), np.array(E)
    T = numeric(FREE, rotational_kinetic_energy(FREE))
    assert_allclose([T(y[:3], y[3:]) for y in sol.y.T[:5]], E[:5], rtol=1e-13)
    assert np.ptp(E) < 1e-9 * E[0]
    assert np.ptp(np.linalg.norm(H, axis=1)) < 1e-9 * np.linalg.norm(H[0])
    assert np.abs(H - H[0]).max() < 1e-9 * np.linalg.norm(H[0])   # every fixed-frame component
    assert np.ptp(sol.y[5]) > 1e-3           # the spin rate itself varies: a real test


@pytest.mark.parametrize("moments, unstable", [((0.2, 0.35, 0.5), False),   # spin axis largest
                                               ((0.35, 0.5, 0.2), False),   # smallest
                                               ((0.2, 0.5, 0.35), True)],   # intermediate
                         ids=["largest", "smallest", "intermediate"])
def test_free_body_spin_stability(built, moments, unstable):
    """Linearized about a steady spin Ω about body z (lagrgen.linearize, both backends): the
    eigenvalues are 0, 0, ±iΩ (the frame) and ±λ with λ² = −Ω²·(I3−I1)(I3−I2)/(I1·I2) (Euler)."""
    I1, I2, I3 = moments
    W = 3.0
    lam2 = -W * W * (I3 - I1) * (I3 - I2) / (I1 * I2)
    for backend in ("python", "c"):
        lin = lagrgen.linearize(built(SPIN, backend), [0.0, 0.0, 0.0], [W, 0.0, 0.0],
                                p=list(moments))
        A = np.block([[np.zeros((3, 3)), np.eye(3)],
                      [-np.linalg.solve(lin.M, lin.K), -np.linalg.solve(lin.M, lin.C)]])
        lam = np.linalg.eigvals(A)
        if unstable:
            assert_allclose(lam.real.max(), np.sqrt(lam2), rtol=1e-9)
        else:
            assert np.abs(lam.real).max() < 1e-9
            assert np.abs(np.abs(lam.imag) - np.sqrt(-lam2)).min() < 1e-9
        assert np.abs(np.abs(lam) - W).min() < 1e-9


# -- planar, springs, torques -----------------------------------------------------------------------
def test_planar_body_declared_in_3d_matches_rigid_body():
    models = []
    for kind in ("3d", "2d"):
        model = Model(f"planar_{kind}")
        x, y, th = model.coordinates("x y th")
        m, Iz, k, g = model.parameters(m=2.0, Iz=0.3, k=5.0, g=9.81)
        F, = model.inputs("F")
        if kind == "3d":
            model.rigid_body_3d(m, [0.7, 0.9, Iz], [x, y, 0], rotation.z(th))
            model.torque_3d([0, 0, F], rotation.z(th))
        else:
            model.rigid_body(m, Iz, [x, y], th)
            model.torque(F, th)
        model.spring(k, sp.sqrt((x - 1) ** 2 + y ** 2))
        model.potential_energy(m * g * y)
        models.append(model)
    a, b = models
    assert sp.simplify(a.mass_matrix() - b.mass_matrix()) == sp.zeros(3, 3)
    assert sp.simplify(a.forcing() - b.forcing()) == sp.zeros(3, 1)


def test_torque_3d_and_3d_spring(built):
    """torque_3d: Q = W_fixedᵀ·moment (virtual power); a spring between 3-D points: Q = −∂V/∂q."""
    base = free_body_model()
    model = Model("loaded3d")
    a, b, c = model.coordinates("a b c")
    I1, I2, I3, k = model.parameters(I1=0.2, I2=0.35, I3=0.5, k=3.0)
    Mx, = model.inputs("Mx")
    R = rotation.x(a) * rotation.y(b) * rotation.z(c)
    model.rigid_body_3d(1.0, (I1, I2, I3), [0, 0, 0], R)
    tip = R * sp.Matrix([0.3, 0.1, 0.2])
    anchor = sp.Matrix([1.0, 0.5, -0.2])
    V = k * ((tip - anchor).dot(tip - anchor)) / 2
    model.spring(k, sp.sqrt((tip - anchor).dot(tip - anchor)), ends=(anchor, tip))
    moment = sp.Matrix([Mx, 0.4 * b, -0.3])
    model.torque_3d(moment, R)
    mod, ref = built(model, "c"), built(base, "c")
    kin = Kinematics(R, model.q, model.t)
    Wf, Vq = numeric(model, kin.W_fixed), numeric(model, V)
    for _ in range(3):
        q, qd = random_state(3)
        u = np.array([0.7])
        p = mod.defaults
        moment_n = np.array([u[0], 0.4 * q[1], -0.3])
        grad = np.array([(Vq(q + h) - Vq(q - h)) / 2e-6 for h in np.eye(3) * 1e-6]).ravel()
        Q = Wf(q).T @ moment_n - grad
        assert_allclose(mod.forcing(q, qd, 0.0, p, u) - ref.forcing(q, qd), Q,
                        rtol=1e-7, atol=1e-8)


# -- Jacobians, backends, gimbal lock ------------------------------------------------------------------
@pytest.mark.parametrize("model", [TOP, DPEND], ids=["top", "dpend"])
def test_jacobian_against_central_differences_and_backends_agree(model, built):
    c, py = built(model, "c"), built(model, "python")
    n = c.n_coordinates
    for _ in range(3):
        q, qd = random_state(n)
        y = np.concatenate([q, qd])
        J = c.jacobian(0.0, y)
        h = 1e-6
        fd = np.column_stack([(c.rhs(0.0, y + h * e) - c.rhs(0.0, y - h * e)) / (2 * h)
                              for e in np.eye(2 * n)])
        assert_allclose(J, fd, rtol=1e-6, atol=1e-6 * np.abs(J).max())
        for a, b in [(c.rhs(0.0, y), py.rhs(0.0, y)), (J, py.jacobian(0.0, y)),
                     (c.mass_matrix(q), py.mass_matrix(q)), (c.forcing(q, qd), py.forcing(q, qd))]:
            assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())


@pytest.mark.parametrize("backend", ["python", "c"])
def test_gimbal_lock_gives_mass_matrix_error(built, backend):
    mod = built(TOP, backend)
    mod.rhs(0.0, [0.0, 0.3, 0.0, 0.0, 0.0, 1.0])          # fine away from θ = 0
    with pytest.raises(MassMatrixError, match=r"top3d.*not positive definite.*q=\[0\.1 +0\. +0\.2\]"):
        mod.rhs(0.0, [0.1, 0.0, 0.2, 0.0, 0.0, 1.0])       # z-x-z at θ = 0: ψ and φ coincide


# -- bad input -----------------------------------------------------------------------------------------
def _bad(call):
    model = Model("bad3d")
    a, b = model.coordinates("a b")
    m, = model.parameters(m=1.0)
    R = rotation.z(a) * rotation.x(b)
    call(model, a, b, m, R)


@pytest.mark.parametrize("call, message", [
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 2], [0, 0, 0], R), "3 principal moments"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, sp.ones(2, 2), [0, 0, 0], R), "3×3"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, "heavy", [0, 0, 0], R), "3×3"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, sp.Matrix([[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]),
                                           [0, 0, 0], R), "symmetric"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, -1, 1], [0, 0, 0], R), "semi-definite"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 5], [0, 0, 0], R), "triangle inequality"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, a, 1], [0, 0, 0], R), "constant"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 1], [0, 0], R), "3 components"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 1], [0, 0, 0], sp.eye(2)), "3×3"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 1], [0, 0, 0], [[1, 0, 0]] * 3), "3×3"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 1], [0, 0, 0], 2 * R), "not a rotation"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 1], [0, 0, 0], sp.diag(1, 1, -1)),
     "reflection"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 1], [0, 0, 0], rotation.z(a.diff())),
     "velocities"),
    (lambda M, a, b, m, R: M.rigid_body_3d(m, [1, 1, 1], [0, 0, 0], rotation.z(sp.Symbol("w"))),
     "symbol w"),
    (lambda M, a, b, m, R: M.torque_3d([1, 0], R), "3 components"),
    (lambda M, a, b, m, R: M.torque_3d([1, 0, 0], sp.Matrix(R) + sp.ones(3, 3)), "not a rotation"),
    (lambda M, a, b, m, R: rotation.sequence("zq", (a, b)), "letters"),
])
def test_bad_input_raises_model_error(call, message):
    with pytest.raises(ModelError, match=message):
        _bad(call)


# -- the example and its 3-D animation ---------------------------------------------------------------
def test_spinning_top_example_animates_in_3d(tmp_path):
    from PIL import Image

    from conftest import example_model
    from lagrgen.outputs.animation3d import is_3d, tracks_3d
    from lagrgen.outputs.plotting import animate
    model = example_model("spinning_top")
    assert is_3d(model) and not is_3d(example_model("double_pendulum"))
    mod = lagrgen.build(model, backend="python")
    sol = lagrgen.simulate(mod, (0.0, 0.5), [0.0, 0.5, 0.0, 0.8, 0.0, 40.0], method="DOP853",
                           rtol=1e-8, atol=1e-10, dense_output=True)
    tracks = tracks_3d(model, mod.defaults, sol.t[-1:], sol.y[:3, -1:])
    (kind, (com, R)), = [tr for tr in tracks if tr[0] == "body3d"]
    assert_allclose(R[0] @ R[0].T, np.eye(3), atol=1e-12)            # drawn frame is a rotation
    assert_allclose(com[0], R[0] @ [0, 0, 0.05], atol=1e-12)          # centre of mass on its axis
    path = animate(model, sol, tmp_path / "top.gif", fps=10)
    with Image.open(path) as im:
        assert im.n_frames == 5
        frames = []
        for k in (0, im.n_frames - 1):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB"), dtype=float))
    assert np.abs(frames[0] - frames[1]).mean() > 0.1                  # the top moved


def test_pendulum3d_example_conserves_energy(built):
    from conftest import example_model
    model = example_model("pendulum3d")
    mod = built(model, "c")
    V = numeric(model, sum(model.spec().potential))
    sol = solve_ivp(mod.rhs, (0, 2.0), [0.3, 0.8, -0.5, 0, 0.9, 0.6, 2, 0, 0, 0, 0, 0],
                    method="DOP853", rtol=1e-11, atol=1e-11)
    E = [0.5 * y[6:] @ mod.mass_matrix(y[:6]) @ y[6:] + V(y[:6]) for y in sol.y.T]
    assert np.ptp(E) < 1e-8 * np.abs(E).max()
    assert np.ptp(sol.y[4]) > 0.1


# -- near-singular M: Euler angles at gimbal lock (issue 45 item 6) ---------------------------------
def brick_model():
    """A free brick in roll–pitch–yaw angles, R = Rz(yaw)·Ry(pitch)·Rx(roll), body x its major
    axis: M is singular at pitch = ±π/2 (roll and yaw turn about one axis there)."""
    model = Model("brick_rpy")
    roll, pitch, yaw = model.coordinates("roll pitch yaw")
    model.rigid_body_3d(1.0, (3.0, 2.0, 1.0), [0, 0, 0],
                        rotation.z(yaw) * rotation.y(pitch) * rotation.x(roll))
    return model


BRICK = brick_model()


@pytest.mark.parametrize("backend, formulation", [("c", "dense"), ("c", "recursive"),
                                                  ("python", "dense"), ("python", "recursive")])
def test_a_run_through_a_near_singular_mass_matrix_warns(tmp_path_factory, backend, formulation):
    """Spun about its major axis, tilted 1e-6 rad from pitch = π/2 (M's least relative pivot
    ~3e-13), the brick warns on every engine, backend and formulation; the same spin at pitch 0.3
    does not (and keeps its steady rotation: roll = Ω·t, pitch and yaw fixed)."""
    out = tmp_path_factory.mktemp(f"brick_{backend}_{formulation}")
    mod = lagrgen.build(BRICK, backend=backend, out_dir=out, formulation=formulation)
    assert mod.formulation == formulation
    engines = ("native", "scipy") if backend == "c" else ("scipy",)
    W = 2.0
    for engine in engines:
        with pytest.warns(lagrgen.NearSingularMassMatrixWarning,
                          match=r"nearly singular: the least pivot of M reached [0-9.]+e-1[23] "
                                r".*gimbal lock"):
            lagrgen.simulate(mod, (0, 1), {"pitch": np.pi / 2 - 1e-6, "roll_dot": W},
                             rtol=1e-9, atol=1e-12, engine=engine)
        with warnings.catch_warnings():
            warnings.simplefilter("error", lagrgen.NearSingularMassMatrixWarning)
            sol = lagrgen.simulate(mod, (0, 1), {"pitch": 0.3, "roll_dot": W}, rtol=1e-9,
                                   atol=1e-12, engine=engine)
        assert_allclose(sol.y[:3, -1], [W, 0.3, 0.0], atol=1e-8)
        assert mod.pivot_record() == 1.0              # each run read and reset its record
    near = np.array([0.0, np.pi / 2 - 1e-6, 0.0, W, 0.0, 0.0])
    if backend == "c":                                # the C batch of simulate_many, per run
        y0 = np.array([[0.0, 0.3, 0.0, W, 0.0, 0.0], near, [0.0, -0.5, 0.0, W, 0.0, 0.0]])
        with pytest.warns(lagrgen.NearSingularMassMatrixWarning, match=r"^run 1 of model"):
            ens = lagrgen.simulate_many(mod, (0, 1), y0, t_eval=np.linspace(0, 1, 3),
                                        rtol=1e-9, atol=1e-12, workers=1)
        assert ens.success.all()
    mod.rhs(0.0, near)
    assert 1e-14 < mod.pivot_record() < 1e-11 and mod.pivot_record() == 1.0
