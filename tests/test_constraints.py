"""Constrained systems (API.md §9): holonomic and velocity constraints with Lagrange multipliers.

Closed forms and independent derivations: the pendulum in x, y against its angle form and the rod
tension m·(g·cos θ + L·θ̇²); the Cartesian double pendulum against the angle form; the four-bar
linkage against SymPy's LagrangesMethod (hol_coneqs) and against its one-coordinate form; the
Chaplygin sleigh against SymPy (nonhol_coneqs) and its conserved energy; analytic Jacobians against
central differences; the two backends against each other; every bad input of a constraint.
"""
import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import LagrangesMethod, ReferenceFrame, dynamicsymbols

import lagrgen
from conftest import EXAMPLES as EXAMPLES_DIR, example_model
from lagrgen import ConstraintError, Model, ModelError

EXAMPLES = ("cartesian_pendulum", "cartesian_double_pendulum", "four_bar", "slider_crank",
            "chaplygin_sleigh")

#: Guesses projected by consistent_state before use (q, q̇).
GUESSES = {
    "cartesian_pendulum": [0.5, -0.8, 0.4, 0.3],
    "cartesian_double_pendulum": [0.8, -0.6, 1.5, -0.9, 0.1, 0.2, -0.3, 0.4],
    "four_bar": [1.0, 0.4, 1.6, 2.0, 0.0, 0.0],
    "slider_crank": [0.5, 0.1, 0.24, 10.0, 0.0, 0.0],
    "chaplygin_sleigh": [0.1, -0.2, 0.3, 1.0, 0.5, 0.7],
}


def angle_pendulum():
    model = Model("angle_pendulum")
    th, = model.coordinates("theta")
    m, L, g = model.parameters(m=1.0, L=1.0, g=9.81)
    bob = sp.Matrix([L * sp.sin(th), -L * sp.cos(th)])
    model.particle(m, bob)
    model.potential_energy(m * g * bob[1])
    return model


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(stem, backend) -> built model, each built once in this module."""
    out_dir = tmp_path_factory.mktemp("gen_constraints")
    models = {stem: example_model(stem) for stem in EXAMPLES + ("double_pendulum",)}
    models["angle_pendulum"] = angle_pendulum()
    cache = {}

    def get(stem, backend="c"):
        if (stem, backend) not in cache:
            cache[stem, backend] = lagrgen.build(models[stem], backend=backend, out_dir=out_dir)
        return cache[stem, backend]
    return get


@pytest.fixture(scope="module")
def states(built):
    """stem -> a consistent state (from the C model; the projection is checked below)."""
    return {stem: lagrgen.consistent_state(built(stem), GUESSES[stem]) for stem in EXAMPLES}


def finite_difference_jacobian(mod, t, y, u=None, h=1e-6):
    cols = []
    for e in np.eye(len(y)):
        step = h * max(1.0, abs(float(e @ y)))
        cols.append((mod.rhs(t, y + step * e, None, u) - mod.rhs(t, y - step * e, None, u))
                    / (2 * step))
    return np.array(cols).T


def inputs_of(mod, value=0.3):
    return np.full(len(mod.inputs), value)


# -- sizes and the projection -----------------------------------------------------------------
@pytest.mark.parametrize("backend", ["python", "c"])
def test_sizes(built, backend):
    counts = {"cartesian_pendulum": (1, 1), "cartesian_double_pendulum": (2, 2),
              "four_bar": (2, 2), "slider_crank": (2, 2), "chaplygin_sleigh": (1, 0)}
    for stem, (m, n_h) in counts.items():
        mod = built(stem, backend)
        assert mod.n_constraints == m
        y = np.zeros(2 * mod.n_coordinates)
        assert mod.constraint_forces(0.0, np.array(GUESSES[stem])).shape == (m,)
        assert mod.constraint_residuals(0.0, y).shape == (n_h + m,)
    assert built("four_bar", backend).constraint_names == ("B_x", "B_y")
    assert built("chaplygin_sleigh", backend).constraint_names == ("blade",)
    plain = built("double_pendulum", backend)
    assert plain.n_constraints == 0 and plain.constraint_names == ()
    assert plain.constraint_forces(0.0, np.zeros(4)).shape == (0,)
    assert plain.constraint_residuals(0.0, np.zeros(4)).shape == (0,)


@pytest.mark.parametrize("stem", EXAMPLES)
def test_consistent_state_projects(built, states, stem):
    mod = built(stem)
    y = states[stem]
    assert np.abs(mod.constraint_residuals(0.0, y)).max() < 1e-12
    guess, n = np.array(GUESSES[stem]), mod.n_coordinates
    assert np.abs(y[:n] - guess[:n]).max() < 0.25  # a nearby configuration, not any one
    again = lagrgen.consistent_state(mod, y)       # a consistent state stays where it is
    assert np.abs(again - y).max() < 1e-12


def test_consistent_state_is_least_change_for_velocities(built):
    """q̇ is projected orthogonally: the change is along Aᵀ (here along the rod)."""
    mod = built("cartesian_pendulum")
    y = lagrgen.consistent_state(mod, [0.6, -0.8, 1.0, 1.0])
    assert np.allclose(y[:2], [0.6, -0.8], atol=1e-14)
    change = y[2:] - [1.0, 1.0]
    assert abs(change[0] * 0.8 + change[1] * 0.6) < 1e-14   # no tangential change
    assert abs(y[2] * 0.6 - y[3] * 0.8) < 1e-14               # no radial speed left
    assert y[2] * 0.8 + y[3] * 0.6 == pytest.approx(1.4)      # tangential speed kept


# -- pendulum in x, y ------------------------------------------------------------------------------
def test_cartesian_pendulum_matches_angle_form(built):
    mod, ref = built("cartesian_pendulum"), built("angle_pendulum")
    th0, w0 = 0.9, -0.5
    t_eval = np.linspace(0.0, 5.0, 51)
    y0 = [np.sin(th0), -np.cos(th0), np.cos(th0) * w0, np.sin(th0) * w0]
    sol = lagrgen.simulate(mod, (0.0, 5.0), y0, method="DOP853", rtol=1e-12, atol=1e-12,
                           t_eval=t_eval)
    sref = lagrgen.simulate(ref, (0.0, 5.0), [th0, w0], method="DOP853", rtol=1e-12,
                            atol=1e-12, t_eval=t_eval)
    th, w = sref.y
    assert np.abs(sol.y[0] - np.sin(th)).max() < 1e-8
    assert np.abs(sol.y[1] + np.cos(th)).max() < 1e-8
    assert np.abs(sol.y[2] - np.cos(th) * w).max() < 1e-8
    # the rod tension from λ (Φ_qᵀλ = 2λ·(x, y), so the tension is −2·L·λ) against the closed form
    tension = -2.0 * sol.constraint_forces[0]
    assert np.abs(tension - (9.81 * np.cos(th) + w**2)).max() < 1e-7
    assert sol.constraint_forces.shape == (1, len(t_eval))
    assert sol.constraint_names == ("rod",)
    assert np.array_equal(sol.multipliers["rod"], sol.constraint_forces[0])
    assert np.abs(sol.constraint_residuals).max() < 1e-9


@pytest.mark.parametrize("backend", ["python", "c"])
def test_lambda_sign_against_closed_form(built, backend):
    """M·q̈ = F + Aᵀλ: at θ, θ̇ the rod pulls the bob inwards with m·(g·cos θ + L·θ̇²)."""
    mod = built("cartesian_pendulum", backend)
    for th, w in [(0.3, 0.7), (-1.2, 2.0), (2.5, 0.1)]:
        y = [np.sin(th), -np.cos(th), np.cos(th) * w, np.sin(th) * w]
        p = [2.0, 1.0, 9.81]
        lam, = mod.constraint_forces(0.0, y, p)
        assert -2.0 * lam == pytest.approx(2.0 * (9.81 * np.cos(th) + w**2), rel=1e-12)
        # and the equation itself: M·q̈ − F = Aᵀλ
        qdd = mod.rhs(0.0, y, p)[2:]
        M, F = mod.mass_matrix(y[:2], 0.0, p), mod.forcing(y[:2], y[2:], 0.0, p)
        assert np.allclose(M @ qdd - F, 2 * lam * np.array(y[:2]), atol=1e-12)


def test_energy_conserved_on_the_pendulum(built):
    mod = built("cartesian_pendulum")
    y0 = lagrgen.consistent_state(mod, [0.8, -0.6, 1.0, 1.3])
    sol = lagrgen.simulate(mod, (0.0, 10.0), y0, method="DOP853", rtol=1e-11, atol=1e-12)
    energy = 0.5 * (sol.y[2]**2 + sol.y[3]**2) + 9.81 * sol.y[1]
    assert np.abs(energy - energy[0]).max() < 1e-8


def test_small_oscillation_frequency_is_sqrt_g_over_l(built):
    for backend in ("python", "c"):
        mod = built("cartesian_pendulum", backend)
        p = {"L": 0.7, "g": 9.81, "m": 3.0}
        q0 = lagrgen.equilibrium(mod, [0.1, -0.6], p=p)
        assert np.allclose(q0, [0.0, -0.7], atol=1e-10)
        res = lagrgen.modes(mod, q0, p=p)
        assert res.omega == pytest.approx([np.sqrt(9.81 / 0.7)], rel=1e-10)
        assert res.shapes.shape == (2, 1)
        assert abs(res.shapes[1, 0]) < 1e-12       # the mode moves the bob sideways
        assert res.shapes[:, 0] @ (3.0 * res.shapes[:, 0]) == pytest.approx(1.0)
        lin = lagrgen.linearize(mod, q0, p=p)
        assert lin.basis.shape == (4, 2) and lin.M.shape == (1, 1)    # δy = basis·[δx, δẋ]
        assert lin.states == ("x", "x_dot") and lin.coordinates == ("x",)
        assert lin.constraint_forces[0] == pytest.approx(-3.0 * 9.81 / (2 * 0.7))


def test_double_pendulum_modes_match_angle_form(built):
    mod, ref = built("cartesian_double_pendulum"), built("double_pendulum")
    q0 = lagrgen.equilibrium(mod, [0.05, -0.9, -0.05, -2.1])
    assert np.allclose(q0, [0, -1, 0, -2], atol=1e-10)
    assert lagrgen.modes(mod, q0).omega == pytest.approx(lagrgen.modes(ref, [0, 0]).omega,
                                                          rel=1e-10)


# -- Cartesian double pendulum ----------------------------------------------------------------------
def angle_to_cartesian(th1, th2, w1, w2):
    x1, y1 = np.sin(th1), -np.cos(th1)
    x2, y2 = x1 + np.sin(th2), y1 - np.cos(th2)
    vx1, vy1 = np.cos(th1) * w1, np.sin(th1) * w1
    return np.array([x1, y1, x2, y2, vx1, vy1, vx1 + np.cos(th2) * w2, vy1 + np.sin(th2) * w2])


def test_cartesian_double_pendulum_matches_angle_form(built):
    mod, ref = built("cartesian_double_pendulum"), built("double_pendulum")
    a0 = np.array([0.7, -0.4, 0.3, 0.9])
    t_eval = np.linspace(0.0, 4.0, 41)
    sol = lagrgen.simulate(mod, (0.0, 4.0), angle_to_cartesian(*a0), method="DOP853",
                           rtol=1e-12, atol=1e-12, t_eval=t_eval)
    sref = lagrgen.simulate(ref, (0.0, 4.0), a0, method="DOP853", rtol=1e-12, atol=1e-12,
                            t_eval=t_eval)
    expected = angle_to_cartesian(*sref.y)
    assert np.abs(sol.y[:4] - expected[:4]).max() < 1e-8
    assert np.abs(sol.y[4:] - expected[4:]).max() < 1e-7


def test_double_pendulum_position_residual_stays_small(built):
    """The drift target at a shorter horizon (benchmarks/constraint_drift.py runs 100 s)."""
    mod = built("cartesian_double_pendulum")
    y0 = angle_to_cartesian(1.2, -0.5, 0.0, 1.0)
    sol = lagrgen.simulate(mod, (0.0, 20.0), y0, method="DOP853", rtol=1e-10, atol=1e-10)
    assert sol.success
    assert np.abs(sol.constraint_residuals[:2]).max() < 1e-8


# -- the four-bar linkage ------------------------------------------------------------------------------
FOUR_BAR = dict(a=0.1, b=0.3, c=0.25, d=0.3, m2=0.5, m3=1.0, m4=0.8, g=9.81)


def four_bar_sympy():
    """The four-bar linkage through SymPy's LagrangesMethod with hol_coneqs (an independent
    derivation): returns a function (q, q̇, Tq) -> (q̈, λ) from mass_matrix_full·x = forcing_full."""
    t = dynamicsymbols._t
    q = dynamicsymbols("th2 th3 th4")
    qd = [s.diff(t) for s in q]
    a, b, c, d, m2, m3, m4, g, Tq = sp.symbols("a b c d m2 m3 m4 g Tq")

    def e(th):
        return sp.Matrix([sp.cos(th), sp.sin(th)])
    A = a * e(q[0])
    bodies = [(m2, a, sp.zeros(2, 1), q[0]), (m3, b, A, q[1]),
              (m4, c, sp.Matrix([d, 0]), q[2])]
    T, V = 0, 0
    for m, length, start, angle in bodies:
        centre = start + length / 2 * e(angle)
        v = centre.diff(t)
        T += m * (v.T * v)[0] / 2 + m * length**2 / 12 * angle.diff(t)**2 / 2
        V += m * g * centre[1]
    N = ReferenceFrame("N")
    crank = N.orientnew("crank", "Axis", [q[0], N.z])
    crank.set_ang_vel(N, qd[0] * N.z)
    hol = [a * sp.cos(q[0]) + b * sp.cos(q[1]) - c * sp.cos(q[2]) - d,
           a * sp.sin(q[0]) + b * sp.sin(q[1]) - c * sp.sin(q[2])]
    lm = LagrangesMethod(T - V, q, hol_coneqs=hol, forcelist=[(crank, Tq * N.z)], frame=N)
    lm.form_lagranges_equations()
    values = {sp.Symbol(k): v for k, v in FOUR_BAR.items()}
    MM = lm.mass_matrix_full.subs(values)
    FF = lm.forcing_full.subs(values)
    args = list(q) + qd + [Tq]
    mm, ff = sp.lambdify([args], MM), sp.lambdify([args], FF)
    lam_vec = list(lm.lam_vec)
    eom = sp.lambdify([args + [s.diff(t) for s in qd] + lam_vec], lm.eom.subs(values))

    def solve(y, torque):
        x = np.linalg.solve(np.array(mm(list(y) + [torque]), dtype=float),
                            np.array(ff(list(y) + [torque]), dtype=float).ravel())
        return x[3:6], x[6:], eom
    return solve


@pytest.mark.parametrize("backend", ["python", "c"])
def test_four_bar_against_sympy(built, states, backend):
    mod = built("four_bar", backend)
    solve = four_bar_sympy()
    y = states["four_bar"].copy()
    y[3:] = lagrgen.consistent_state(mod, np.r_[y[:3], 2.0, 0.0, 0.0])[3:]
    for torque in (0.0, 1.5):
        qdd_ref, lam_ref, eom = solve(y, torque)
        qdd = mod.rhs(0.0, y, None, [torque])[3:]
        lam = mod.constraint_forces(0.0, y, None, [torque])
        assert np.allclose(qdd, qdd_ref, rtol=1e-9, atol=1e-9)
        # sympy#30215: mass_matrix_full carries −Φ_qᵀ in its λ columns while `eom` carries +Φ_qᵀ,
        # so λ solved from mass_matrix_full equals ours (M·q̈ = F + Φ_qᵀλ) and the λ satisfying
        # LagrangesMethod.eom is its negative.
        assert np.allclose(lam, lam_ref, rtol=1e-9, atol=1e-9)
        point = list(y) + [torque] + list(qdd)
        assert np.abs(np.array(eom(point + list(-lam)), dtype=float)).max() < 1e-9
        assert np.abs(np.array(eom(point + list(lam)), dtype=float)).max() > 1e-3


def four_bar_closure(th2, guess):
    """(θ3, θ4) closing the loop at θ2, by Newton from `guess`."""
    a, b, c, d = (FOUR_BAR[k] for k in "abcd")
    x = np.array(guess, dtype=float)
    for _ in range(50):
        th3, th4 = x
        r = np.array([a * np.cos(th2) + b * np.cos(th3) - c * np.cos(th4) - d,
                      a * np.sin(th2) + b * np.sin(th3) - c * np.sin(th4)])
        J = np.array([[-b * np.sin(th3), c * np.sin(th4)], [b * np.cos(th3), -c * np.cos(th4)]])
        x = x - np.linalg.solve(J, r)
    return x


def test_four_bar_against_one_coordinate_form(built, states):
    """θ̈2 from the one-coordinate Lagrange equation M_e(θ2)·θ̈2 + ½·M_e'·θ̇2² + V_e' = Tq, with
    M_e = Jᵀ·M·J (J = dq/dθ2 along the loop) and V_e evaluated numerically, agrees with rhs."""
    mod = built("four_bar")
    y = states["four_bar"]
    m2, m3, m4, g = (FOUR_BAR[k] for k in ("m2", "m3", "m4", "g"))
    a, b, c, d = (FOUR_BAR[k] for k in "abcd")

    def config(th2):
        return np.r_[th2, four_bar_closure(th2, y[1:3])]

    def dq(th2, h=1e-6):
        return (config(th2 + h) - config(th2 - h)) / (2 * h)

    def M_e(th2):
        J = dq(th2)
        return J @ mod.mass_matrix(config(th2)) @ J

    def V_e(th2):
        th2, th3, th4 = config(th2)
        return g * (m2 * a / 2 * np.sin(th2) + m3 * (a * np.sin(th2) + b / 2 * np.sin(th3))
                    + m4 * c / 2 * np.sin(th4))

    th2, torque, h = y[0], 0.8, 1e-4
    for w in (0.0, 3.0):
        yy = np.r_[config(th2), dq(th2) * w]
        dM = (M_e(th2 + h) - M_e(th2 - h)) / (2 * h)
        dV = (V_e(th2 + h) - V_e(th2 - h)) / (2 * h)
        expected = (torque - dV - 0.5 * dM * w**2) / M_e(th2)
        assert mod.rhs(0.0, yy, None, [torque])[3] == pytest.approx(expected, rel=1e-6, abs=1e-6)


def test_four_bar_energy_and_work(built, states):
    """Without torque the energy is conserved; constraint forces do no work."""
    mod = built("four_bar")
    y0 = states["four_bar"]
    sol = lagrgen.simulate(mod, (0.0, 2.0), y0, method="Radau", rtol=1e-10, atol=1e-12)
    p = FOUR_BAR
    energies = []
    for y in sol.y.T:
        q, qd = y[:3], y[3:]
        T = 0.5 * qd @ mod.mass_matrix(q) @ qd
        V = p["g"] * (p["m2"] * p["a"] / 2 * np.sin(q[0])
                      + p["m3"] * (p["a"] * np.sin(q[0]) + p["b"] / 2 * np.sin(q[1]))
                      + p["m4"] * p["c"] / 2 * np.sin(q[2]))
        energies.append(T + V)
    assert np.ptp(energies) < 1e-7
    assert np.abs(sol.constraint_residuals).max() < 1e-8


# -- the Chaplygin sleigh ------------------------------------------------------------------------------
def sleigh_sympy():
    t = dynamicsymbols._t
    q = dynamicsymbols("x y theta")
    qd = [s.diff(t) for s in q]
    m, I, a = 1.0, 0.2, 0.5
    T = m * (qd[0]**2 + qd[1]**2) / 2 + I * qd[2]**2 / 2
    nonhol = [-sp.sin(q[2]) * qd[0] + sp.cos(q[2]) * qd[1] - a * qd[2]]
    lm = LagrangesMethod(T, q, nonhol_coneqs=nonhol)
    lm.form_lagranges_equations()
    args = list(q) + qd
    mm, ff = sp.lambdify([args], lm.mass_matrix_full), sp.lambdify([args], lm.forcing_full)

    def solve(y):
        x = np.linalg.solve(np.array(mm(list(y)), dtype=float),
                            np.array(ff(list(y)), dtype=float).ravel())
        return x[3:6], x[6:]
    return solve


@pytest.mark.parametrize("backend", ["python", "c"])
def test_sleigh_against_sympy(built, states, backend):
    mod = built("chaplygin_sleigh", backend)
    solve = sleigh_sympy()
    y = states["chaplygin_sleigh"]
    qdd_ref, lam_ref = solve(y)
    assert np.allclose(mod.rhs(0.0, y)[3:], qdd_ref, rtol=1e-10, atol=1e-12)
    assert np.allclose(mod.constraint_forces(0.0, y), lam_ref, rtol=1e-10, atol=1e-12)
    assert mod.constraint_residuals(0.0, y).shape == (1,)


def test_sleigh_conserves_energy(built, states):
    mod = built("chaplygin_sleigh")
    y0 = states["chaplygin_sleigh"]
    sol = lagrgen.simulate(mod, (0.0, 20.0), y0, method="DOP853", rtol=1e-11, atol=1e-12)
    energy = 0.5 * (sol.y[3]**2 + sol.y[4]**2) + 0.5 * 0.2 * sol.y[5]**2
    assert np.abs(energy - energy[0]).max() < 1e-8
    assert np.abs(sol.constraint_residuals).max() < 1e-9
    # the known behaviour: the sleigh ends up moving straight along its heading (θ̇ → 0)
    assert abs(sol.y[5, -1]) < 1e-2 * abs(y0[5]) + 1e-3


# -- Jacobians, backends ---------------------------------------------------------------------------------
@pytest.mark.parametrize("backend", ["python", "c"])
@pytest.mark.parametrize("stem", EXAMPLES)
def test_jacobian_against_finite_differences(built, states, stem, backend):
    mod = built(stem, backend)
    rng = np.random.default_rng(7)
    y = states[stem] + 0.01 * rng.standard_normal(len(states[stem]))   # off the manifold too
    u = inputs_of(mod)
    J = mod.jacobian(0.3, y, None, u)
    Jfd = finite_difference_jacobian(mod, 0.3, y, u)
    assert np.abs(J - Jfd).max() <= 1e-7 * max(1.0, np.abs(J).max())


@pytest.mark.parametrize("stem", EXAMPLES)
def test_backends_agree(built, states, stem):
    c, py = built(stem, "c"), built(stem, "python")
    rng = np.random.default_rng(3)
    for _ in range(3):
        y = states[stem] + 0.05 * rng.standard_normal(len(states[stem]))
        u = inputs_of(c, rng.standard_normal())
        for name in ("rhs", "jacobian", "constraint_forces", "constraint_residuals"):
            a, b = getattr(c, name)(0.2, y, None, u), getattr(py, name)(0.2, y, None, u)
            assert np.abs(a - b).max() <= 1e-12 * max(1.0, np.abs(a).max()), name
        n = c.n_coordinates
        for a, b in zip(c.constraint_terms(y[:n], y[n:], 0.2, None, u),
                        py.constraint_terms(y[:n], y[n:], 0.2, None, u)):
            assert np.abs(a - b).max() <= 1e-12 * max(1.0, np.abs(a).max())


def test_unconstrained_model_code_has_no_constraint_kernels(built):
    from lagrgen.kernels import all_kernels
    plain = example_model("double_pendulum")
    names = [k.name for k in all_kernels(plain.equations())]
    assert names == ["mf", "jacobian_b", "dF_du", "outputs", "parameter_b", "residual_hessian",
                     "motion_tape", "motion_tangent"]
    four_bar = [k.name for k in all_kernels(example_model("four_bar").equations())]
    assert {"constraints", "constraint_residuals", "constraint_jacobian"} <= set(four_bar)


def test_slider_crank_runs_with_a_gas_force(built, states):
    """A force on the piston turns the flywheel; λ2 (pin force across the axis) is finite."""
    mod = built("slider_crank")
    y0 = states["slider_crank"]
    sol = lagrgen.simulate(mod, (0.0, 0.5), y0, method="Radau", rtol=1e-9, atol=1e-11,
                           inputs={"P": lambda t: 100.0 * (np.sin(y0[0]) > 0), "Tl": 0.0})
    assert sol.success
    assert np.abs(sol.constraint_residuals).max() < 1e-8
    assert np.all(np.isfinite(sol.constraint_forces))
    r, l = 0.05, 0.2
    # the constraints hold: piston at r·cos θ + l·cos φ
    assert np.allclose(sol.y[2], r * np.cos(sol.y[0]) + l * np.cos(sol.y[1]), atol=1e-8)


# -- bad input ------------------------------------------------------------------------------------------
def small_model(name="bad"):
    model = Model(name)
    x, y = model.coordinates("x y")
    k, = model.parameters(k=1.0)
    F, = model.inputs("F")
    model.particle(1.0, sp.Matrix([x, y]))
    return model, x, y, k, F


def test_constraint_errors():
    model, x, y, k, F = small_model()
    t = model.t
    with pytest.raises(ModelError, match="not linear in the velocities"):
        model.velocity_constraint(x.diff(t)**2 + y.diff(t))
    with pytest.raises(ModelError, match="not linear in the velocities"):
        model.velocity_constraint(x.diff(t) * y.diff(t))
    with pytest.raises(ModelError, match="must not depend on input F"):
        model.constraint(x - F)
    with pytest.raises(ModelError, match="must not depend on input F"):
        model.velocity_constraint(x.diff(t) - F)
    with pytest.raises(ModelError, match="must not depend on velocities"):
        model.constraint(x.diff(t) - y)
    with pytest.raises(ModelError, match="does not involve any coordinate"):
        model.constraint(k - 1)
    with pytest.raises(ModelError, match="involves no velocity"):
        model.velocity_constraint(x - y)
    with pytest.raises(ModelError, match="must be a scalar expression"):
        model.constraint(sp.Matrix([x, y]))
    with pytest.raises(ModelError, match="neither a coordinate"):
        model.constraint(x - sp.Symbol("zz"))
    with pytest.raises(ModelError, match="Baumgarte beta"):
        model.constraint_stabilization(alpha=1.0, beta=-1.0)
    with pytest.raises(ModelError, match="Baumgarte alpha"):
        model.constraint_stabilization(alpha=float("nan"))
    with pytest.raises(ModelError, match="not an expression"):
        model.constraint(x < y)
    assert model.constraints == () and model.velocity_constraints == ()
    model.constraint(sp.Eq(x, y))         # an equation means lhs − rhs = 0
    assert model.constraints == (x - y,)


@pytest.mark.parametrize("backend", ["python", "c"])
def test_redundant_constraints_raise(backend, tmp_path):
    model, x, y, _, _ = small_model(f"redundant_{backend}")
    model.constraint(x - y)
    model.constraint(2 * x - 2 * y)        # the same constraint again: A is rank 1
    mod = lagrgen.build(model, backend=backend, out_dir=tmp_path)
    with pytest.raises(ConstraintError, match=r"redundant at the initial state.*x=0\.5, y=0\.5"):
        lagrgen.simulate(mod, (0.0, 1.0), [0.5, 0.5, 0.0, 0.0])
    with pytest.raises(ConstraintError, match="redundant"):
        lagrgen.consistent_state(mod, [0.5, 0.5, 0.0, 0.0])
    with pytest.raises(ConstraintError, match=r"not independent at t=0\.0, q=\[0\.5 0\.5\]"):
        mod.rhs(0.0, [0.5, 0.5, 0.0, 0.0])
    with pytest.raises(ConstraintError):
        mod.jacobian(0.0, [0.5, 0.5, 0.0, 0.0])
    with pytest.raises(ConstraintError):
        mod.constraint_forces(0.0, [0.5, 0.5, 0.0, 0.0])


def test_singular_configuration_and_bad_guess(built):
    mod = built("cartesian_pendulum")
    with pytest.raises(ConstraintError, match="redundant"):   # Φ_q = 0 at the pivot
        lagrgen.consistent_state(mod, [0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ConstraintError, match="not independent"):
        mod.rhs(0.0, [0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        lagrgen.consistent_state(mod, [np.nan, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="length 4"):
        lagrgen.consistent_state(mod, [1.0, 0.0])


def test_constraint_must_restrict_motion(tmp_path):
    model, x, y, k, _ = small_model("rheonomic_only")
    model.constraint(x - k * model.t)     # a driven coordinate is fine
    mod = lagrgen.build(model, backend="python")
    y0 = lagrgen.consistent_state(mod, [0.3, 0.0, 0.0, 0.0], t=0.5)
    assert np.allclose(y0, [0.5, 0.0, 1.0, 0.0])
    assert np.allclose(mod.rhs(0.5, y0)[2:], [0.0, 0.0])


def test_stabilization_is_part_of_the_equations():
    model, x, y, _, _ = small_model("baumgarte")
    model.constraint(x**2 + y**2 - 1)
    off = [1.1, 0.0, 0.0, 0.0]            # Φ = 0.21 off the manifold
    default = lagrgen.build(model, backend="python")
    model.constraint_stabilization(alpha=0.0, beta=0.0)
    plain = lagrgen.build(model, backend="python")
    assert plain.rhs(0.0, off)[2] == pytest.approx(0.0, abs=1e-14)
    # Φ̈ = −β²Φ with Φ_q = (2x, 0), β = 10: 2x·ẍ = −100·0.21
    assert default.rhs(0.0, off)[2] == pytest.approx(-100 * 0.21 / 2.2)


def test_constraint_names():
    model, x, y, k, _ = small_model("named")
    model.velocity_constraint(x.diff(model.t) - y.diff(model.t), name="slot")
    model.constraint(x**2 + y**2 - 1)
    assert model.constraint_names == ("lambda1", "slot")    # holonomic rows first
    with pytest.raises(ModelError, match="already used for the coordinate"):
        model.constraint(x - y, name="x")
    with pytest.raises(ModelError, match="already used for the constraint"):
        model.constraint(x - y, name="slot")
    with pytest.raises(ModelError, match="reserved"):
        model.constraint(x - y, name="lambda2")
    with pytest.raises(ModelError, match="invalid constraint name"):
        model.constraint(x - y, name="not valid")
    assert len(model.constraints) == 1
    mod = lagrgen.build(model, backend="python")
    assert mod.constraint_names == ("lambda1", "slot") and mod.n_constraints == 2


def test_rheonomic_constraint_jacobian_and_drift():
    """A pendulum whose pivot is driven sideways, Φ = (x − A·sin ωt)² + y² − L²: ∂Φ/∂t enters
    γ and its Jacobian; the motion stays on the moving circle."""
    model = Model("driven_pivot")
    x, y = model.coordinates("x y")
    A, w, g = model.parameters(A=0.2, w=3.0, g=9.81)
    model.particle(1.0, sp.Matrix([x, y]))
    model.potential_energy(g * y)
    model.constraint((x - A * sp.sin(w * model.t))**2 + y**2 - 1)
    mod = lagrgen.build(model, backend="python")
    y0 = lagrgen.consistent_state(mod, [0.3, -0.9, 0.0, 0.0], t=0.4)
    assert np.abs(mod.constraint_residuals(0.4, y0)).max() < 1e-12
    J = mod.jacobian(0.4, y0 + 0.01)
    assert np.abs(J - finite_difference_jacobian(mod, 0.4, y0 + 0.01)).max() < 1e-7 * np.abs(J).max()
    sol = lagrgen.simulate(mod, (0.4, 5.0), y0, method="DOP853", rtol=1e-10, atol=1e-12)
    pivot = 0.2 * np.sin(3.0 * sol.t)
    assert np.abs(np.hypot(sol.y[0] - pivot, sol.y[1]) - 1).max() < 1e-9


def test_frequency_response_in_full_coordinates():
    """δx/δF of a pendulum in x, y = L·δθ/δF of the angle form (force F along x at the bob)."""
    cart, angle = Model("fr_cartesian"), Model("fr_angle")
    x, y = cart.coordinates("x y")
    th, = angle.coordinates("theta")
    for model in (cart, angle):
        m, L, g, c = model.parameters(m=2.0, L=0.5, g=9.81, c=0.3)
        F, = model.inputs("F")
        bob = sp.Matrix([x, y]) if model is cart else sp.Matrix([L * sp.sin(th), -L * sp.cos(th)])
        model.particle(m, bob)
        model.potential_energy(m * g * bob[1])
        model.force(sp.Matrix([F, 0]), at=bob)
        model.damper(c, bob[0])
    cart.constraint(x**2 + y**2 - cart.parameter_symbols[1]**2)
    mc, ma = (lagrgen.build(mdl, backend="python") for mdl in (cart, angle))
    freqs = np.linspace(0.1, 2.0, 7)
    Hc = lagrgen.frequency_response(mc, [0.0, -0.5], freqs, input="F")
    Ha = lagrgen.frequency_response(ma, [0.0], freqs, input="F")
    assert Hc.shape == (7, 2)
    assert np.allclose(Hc[:, 0], 0.5 * Ha[:, 0], rtol=1e-10)
    assert np.allclose(Hc[:, 1], 0.0, atol=1e-14)
    zc, za = lagrgen.modes(mc, [0.0, -0.5]), lagrgen.modes(ma, [0.0])
    assert zc.omega == pytest.approx(za.omega, rel=1e-12)
    assert zc.damping_ratios == pytest.approx(za.damping_ratios, rel=1e-10)


def test_cli_show_and_csv(tmp_path, capsys):
    from lagrgen.cli import main
    path = str(EXAMPLES_DIR / "four_bar.py")
    assert main(["show", path]) == 0
    shown = capsys.readouterr().out
    assert "a*cos(th2) + b*cos(th3) - c*cos(th4) - d = 0    (holonomic, multiplier B_x)" in shown
    assert "F + A^T lambda" in shown
    csv_path = tmp_path / "fb.csv"
    assert main(["simulate", path, "--y0", "1.0,0.4,1.6,2,0,0", "--t-end", "0.2", "--samples",
                 "3", "--backend", "python", "--csv", str(csv_path), "--quiet"]) == 0
    rows = [line.split(",") for line in csv_path.read_text().splitlines()]
    assert rows[0][:9] == ["t", "th2", "th3", "th4", "th2_dot", "th3_dot", "th4_dot", "B_x", "B_y"]
    assert rows[0][9:12] == ["kinetic_energy", "potential_energy", "total_energy"]
    first = np.array(rows[1], dtype=float)
    mod = lagrgen.build(example_model("four_bar"), backend="python")
    assert np.abs(mod.constraint_residuals(0.0, first[1:7])).max() < 1e-12   # projected y0
    assert np.allclose(first[7:9], mod.constraint_forces(0.0, first[1:7]), rtol=1e-12)


def test_a_start_off_the_constraints_warns(built, states):
    """The Cartesian pendulum started at |r| = 1.27 (L = 1), or with a rate across the rod, ran
    with success True and no word while the stabilization dragged it onto the circle; simulate
    now warns ConstraintWarning naming the constraint and consistent_state; a consistent start
    and one off by round-off do not warn."""
    import warnings
    mod = built("cartesian_pendulum")
    with pytest.warns(lagrgen.ConstraintWarning, match=r"largest residual 0\.62.*consistent_state"):
        lagrgen.simulate(mod, (0.0, 0.1), [0.9, -0.9, 0.0, 0.0])
    with pytest.warns(lagrgen.ConstraintWarning, match="of the rate of"):
        lagrgen.simulate(mod, (0.0, 0.1), [0.6, -0.8, 1.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error", lagrgen.ConstraintWarning)
        lagrgen.simulate(mod, (0.0, 0.1), states["cartesian_pendulum"])
        lagrgen.simulate(mod, (0.0, 0.1), [0.6, -0.8 + 1e-12, 0.0, 0.0])
