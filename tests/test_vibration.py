"""Vibration analysis against closed-form results, on both backends.

- two equal masses and springs, fixed–free: ω² = (k/m)(3 ∓ √5)/2, shapes x2/x1 = (1 ± √5)/2;
- double pendulum with equal masses and lengths: ω² = (g/L)(2 ∓ √2) about the equilibrium found;
- mass-normalized shapes: Φᵀ·M·Φ = I and K·Φ = M·Φ·diag(ω²);
- damping: a single spring–mass–damper has ζ = c/(2√(km)) (also overdamped); Rayleigh damping
  C = αM + βK gives ζ_i = α/(2ω_i) + βω_i/2, each matched to its own mode;
- frequency response: H(ω) = 1/(k − mω² + icω), |H| largest at ω_n√(1 − 2ζ²);
- linearize: K, C, B equal finite differences of F, B by hand; a small-amplitude nonlinear
  simulation follows the linear one, exp(A·t)·y0;
- rigid-body modes, an unstable equilibrium, a circulatory (non-symmetric) K, a gyroscopic C;
- the compiled and the Python backend give the same numbers; clear errors for bad arguments.
"""
import warnings

import numpy as np
import pytest
import scipy.linalg
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from conftest import example_model
from lagrgen.vibration import EquilibriumError, Linearization, state_matrix


def chain_model():
    """wall –k– m –k– m, with ground dampers α·m on each mass and β·k beside each spring."""
    model = lagrgen.Model("vib_chain")
    x1, x2 = model.coordinates("x1 x2")
    m, k, alpha, beta = model.parameters(m=2.0, k=50.0, alpha=0.0, beta=0.0)
    f, = model.inputs("f")
    model.particle(m, x1)
    model.particle(m, x2)
    model.spring(k, x1)
    model.spring(k, x2 - x1)
    model.damper(alpha * m, x1)
    model.damper(alpha * m, x2)
    model.damper(beta * k, x1)
    model.damper(beta * k, x2 - x1)
    model.force(f, at=x2)
    return model


def oscillator_model():
    """m·ẍ + c·ẋ + k·x = F."""
    model = lagrgen.Model("vib_oscillator")
    x, = model.coordinates("x")
    m, k, c = model.parameters(m=1.5, k=600.0, c=3.0)
    F, = model.inputs("F")
    model.particle(m, x)
    model.spring(k, x)
    model.damper(c, x)
    model.force(F, at=x)
    return model


def free_pair_model():
    """Two masses joined by a spring, free in space: one rigid-body mode."""
    model = lagrgen.Model("vib_free_pair")
    x1, x2 = model.coordinates("x1 x2")
    m, k = model.parameters(m=1.0, k=8.0)
    f, = model.inputs("f")
    model.particle(m, x1)
    model.particle(m, x2)
    model.spring(k, x2 - x1)
    model.force(f, at=x1)
    return model


def duffing_model():
    """m·ẍ + k·x + β·x³ = f: a hardening spring, ω² = (k + 3β·x²)/m about x."""
    model = lagrgen.Model("vib_duffing")
    x, = model.coordinates("x")
    m, k, beta, f = model.parameters(m=1.0, k=1.0, beta=1.0, f=0.0)
    model.particle(m, x)
    model.potential_energy(k * x**2 / 2 + beta * x**4 / 4 - f * x)
    return model


def rotating_frame_model():
    """A mass on isotropic springs seen in a frame turning at Ω: gyroscopic coupling, no damping."""
    model = lagrgen.Model("vib_rotating")
    x, y = model.coordinates("x y")
    m, k, Omega = model.parameters(m=1.0, k=25.0, Omega=1.5)
    t = model.t
    vx, vy = x.diff(t) - Omega * y, y.diff(t) + Omega * x
    model.kinetic_energy(m * (vx**2 + vy**2) / 2)
    model.potential_energy(k * (x**2 + y**2) / 2)
    return model


def pulled_cart_pendulum():
    """A cart s on a spring carrying a pendulum whose bob (x, y) is held by a rod,
    (x − s)² + y² = L², and pulled sideways by a constant force P: its equilibrium leans."""
    model = lagrgen.Model("pulled_cart_pendulum")
    s, x, y = model.coordinates("s x y")
    M, m, k, L, g, P = model.parameters(M=1.0, m=0.5, k=4.0, L=1.0, g=9.81, P=2.0)
    model.particle(M, sp.Matrix([s]))
    model.particle(m, sp.Matrix([x, y]))
    model.potential_energy(k * s**2 / 2 + m * g * y - P * x)
    model.constraint((x - s)**2 + y**2 - L**2, name="rod")
    return model


CHAIN = chain_model()
OSCILLATOR = oscillator_model()
DOUBLE = example_model("double_pendulum")
FREE_PAIR = free_pair_model()
PULLED = pulled_cart_pendulum()
DUFFING = duffing_model()
EQUAL_PENDULUM = {"m1": 1.3, "m2": 1.3, "L1": 0.7, "L2": 0.7, "g": 9.81}


@pytest.fixture(scope="module")
def built(build, backend):
    """Model -> built model of the backend of this run (every model really compiled for "c")."""
    build.backend = backend
    return build


def test_chain_frequencies_and_shapes(built):
    mod = built(CHAIN)
    m, k = 2.0, 50.0
    res = lagrgen.modes(mod, [0.0, 0.0])
    assert_allclose(res.omega**2, (k / m) * (3 - np.array([np.sqrt(5), -np.sqrt(5)])) / 2,
                    rtol=1e-12)
    assert_allclose(res.frequencies_hz, res.omega / (2 * np.pi))
    ratios = res.shapes[1] / res.shapes[0]
    assert_allclose(ratios, [(1 + np.sqrt(5)) / 2, (1 - np.sqrt(5)) / 2], rtol=1e-10)
    assert_allclose(res.damping_ratios, 0.0, atol=0)


def test_shapes_are_mass_normalized(built):
    mod = built(DOUBLE)
    lin = lagrgen.linearize(mod, [0.0, 0.0], p={"m1": 2.0, "L2": 0.6})
    res = lagrgen.modes(lin)
    Phi = res.shapes
    assert_allclose(Phi.T @ lin.M @ Phi, np.eye(2), atol=1e-12)
    assert_allclose(lin.K @ Phi, lin.M @ Phi @ np.diag(res.omega**2), atol=1e-10)
    assert np.all(np.diff(res.omega) > 0)


def test_double_pendulum_small_oscillations(built):
    mod = built(DOUBLE)
    q0 = lagrgen.equilibrium(mod, [0.3, -0.2], p=EQUAL_PENDULUM)
    assert_allclose(q0, [0.0, 0.0], atol=1e-10)
    res = lagrgen.modes(mod, q0, p=EQUAL_PENDULUM)
    g, L = 9.81, 0.7
    assert_allclose(res.omega**2, (g / L) * np.array([2 - np.sqrt(2), 2 + np.sqrt(2)]),
                    rtol=1e-12)
    assert_allclose(res.shapes[1] / res.shapes[0], [np.sqrt(2), -np.sqrt(2)], rtol=1e-10)


def test_inverted_pendulum_is_unstable(built):
    mod = built(DOUBLE)
    q0 = lagrgen.equilibrium(mod, [3.0, 3.3])
    assert_allclose(q0, [np.pi, np.pi], atol=1e-9)
    with pytest.warns(lagrgen.UnstableModeWarning, match=r"2 of 2 modes have ω² < 0.*NaN"):
        res = lagrgen.modes(mod, q0)
    assert np.all(np.isnan(res.omega)) and not res.stable
    with warnings.catch_warnings():
        warnings.simplefilter("error", lagrgen.UnstableModeWarning)
        assert lagrgen.modes(mod, [0.0, 0.0]).stable
    assert np.all(np.real(res.omega_squared) < 0)
    assert np.real(res.eigenvalues).max() > 2.0    # s = ±√(−ω²): one real root grows
    from lagrgen.outputs.plotting import mode_label
    assert mode_label(res, 0) == f"mode 1: unstable (ω² = {np.real(res.omega_squared[0]):.4g} " \
        "rad²/s²)"
    growing = lagrgen.vibration.Modes(omega=np.array([2.0]), shapes=np.ones((1, 1)),
                                      damping_ratios=np.array([-1.0]), omega_damped=np.zeros(1),
                                      eigenvalues=np.array([2.0 + 0j]), kind="state")
    assert mode_label(growing, 0).endswith("ζ = -1, unstable")   # a real root s > 0
    from lagrgen.cli.modes import modes_table
    model = lagrgen.Model("real_state_mode")
    model.coordinates("x")
    assert "mode shapes (largest entry 1, one column" in modes_table(model, [0.0], growing)


def test_linearize_is_the_derivative_of_the_residual(built):
    mod = built(DOUBLE)
    q0, qd0, u0 = np.array([0.4, -0.3]), np.array([0.7, -1.1]), np.array([0.5])
    lin = lagrgen.linearize(mod, q0, qd0, t=0.0, u=u0)
    h = 1e-6

    def column(f, x, j):
        e = np.zeros(len(x))
        e[j] = h
        return (f(x + e) - f(x - e)) / (2 * h)
    qdd0 = np.linalg.solve(mod.mass_matrix(q0), mod.forcing(q0, qd0, 0.0, None, u0))

    def residual(q):          # M(q)·q̈0 − F(q, q̇0): K is its derivative, q̈0 held fixed
        return mod.mass_matrix(q) @ qdd0 - mod.forcing(q, qd0, 0.0, None, u0)
    dq = -np.column_stack([column(residual, q0, j) for j in range(2)])
    dqd = np.column_stack([column(lambda v: mod.forcing(q0, v, 0.0, None, u0), qd0, j)
                           for j in range(2)])
    assert_allclose(lin.K, -dq, rtol=1e-6, atol=1e-8)
    assert_allclose(lin.C, -dqd, rtol=1e-6, atol=1e-8)
    assert_allclose(lin.B[:, 0], np.cos(q0), rtol=1e-13)
    assert_allclose(lin.M, mod.mass_matrix(q0), rtol=1e-13)
    assert lin.B.shape == (2, 1) and lin.coordinates == ("theta1", "theta2")


def test_damping_ratio_of_one_oscillator(built):
    mod = built(OSCILLATOR)
    for c in (3.0, 80.0):
        m, k = 1.5, 600.0
        res = lagrgen.modes(mod, [0.0], p={"c": c})
        zeta = c / (2 * np.sqrt(k * m))
        assert_allclose(res.omega, [np.sqrt(k / m)], rtol=1e-12)
        assert_allclose(res.damping_ratios, [zeta], rtol=1e-9)
        if zeta < 1:
            assert_allclose(res.omega_damped, [np.sqrt(k / m) * np.sqrt(1 - zeta**2)], rtol=1e-9)
    assert zeta > 1


def test_rayleigh_damping_is_matched_mode_by_mode(built):
    mod = built(CHAIN)
    alpha, beta = 0.8, 0.01
    res = lagrgen.modes(mod, [0.0, 0.0], p={"alpha": alpha, "beta": beta})
    w = res.omega
    assert_allclose(res.damping_ratios, alpha / (2 * w) + beta * w / 2, rtol=1e-9)
    assert res.damping_ratios[0] != pytest.approx(res.damping_ratios[1], rel=1e-3)


def test_frequency_response_of_one_oscillator(built):
    mod = built(OSCILLATOR)
    m, k, c = 1.5, 600.0, 6.0
    wn = np.sqrt(k / m)
    zeta = c / (2 * np.sqrt(k * m))
    freqs = np.linspace(0.0, 2 * wn / (2 * np.pi), 4001)
    H = lagrgen.frequency_response(mod, [0.0], freqs, input="F", p={"c": c})
    assert H.shape == (len(freqs), 1) and np.iscomplexobj(H)
    w = 2 * np.pi * freqs
    assert_allclose(H[:, 0], 1 / (k - m * w**2 + 1j * c * w), rtol=1e-12)
    peak = w[np.argmax(np.abs(H[:, 0]))]
    assert peak == pytest.approx(wn * np.sqrt(1 - 2 * zeta**2), abs=w[1] - w[0])
    assert abs(peak - wn) > 2 * (w[1] - w[0])


def test_frequency_response_of_the_chain(built):
    mod = built(CHAIN)
    p = {"alpha": 0.3, "beta": 0.002}
    lin = lagrgen.linearize(mod, [0.0, 0.0], p=p)
    freqs = [0.0, 0.5, 1.3]
    H = lagrgen.frequency_response(mod, [0.0, 0.0], freqs, input="f", p=p)
    for f, row in zip(freqs, H):
        w = 2 * np.pi * f
        assert_allclose((lin.K - w**2 * lin.M + 1j * w * lin.C) @ row, lin.B[:, 0], atol=1e-12)
    assert_allclose(H[0].real, [1 / 50.0, 2 / 50.0], rtol=1e-12)
    assert_allclose(lagrgen.frequency_response(lin, None, freqs, input="f"), H)


def test_small_oscillation_follows_the_linear_model(built):
    """The nonlinear motion differs from exp(A·t)·y0 by O(amplitude²), relative to the amplitude."""
    mod = built(DOUBLE)
    times = np.linspace(0.0, 4.0, 81)
    lin = lagrgen.linearize(mod, [0.0, 0.0], p=EQUAL_PENDULUM)
    A = state_matrix(lin.M, lin.C, lin.K)
    relative = []
    for scale in (1e-2, 1e-3):
        y0 = scale * np.array([1.0, -1.5, 0.0, 2.0])
        sol = lagrgen.simulate(mod, (0.0, 4.0), y0, method="DOP853", params=EQUAL_PENDULUM,
                               t_eval=times, rtol=1e-12, atol=1e-15)
        linear = np.column_stack([scipy.linalg.expm(A * t) @ y0 for t in times])
        amplitude = np.abs(linear[:2]).max()
        assert np.abs(linear[:2] - y0[:2, None]).max() > amplitude
        relative.append(np.abs(sol.y[:2] - linear[:2]).max() / amplitude)
    assert relative[1] < 1e-4
    assert 50 < relative[0] / relative[1] < 200


def test_backends_agree(compile_once):
    for model, q0, p in [(CHAIN, [0.01, -0.02], {"alpha": 0.4, "beta": 0.003}),
                         (DOUBLE, [0.2, -0.4], {"m2": 1.7})]:
        c_mod, py_mod = compile_once(model), lagrgen.build(model, backend="python")
        u = np.full(len(py_mod.inputs), 0.3)
        lin_c = lagrgen.linearize(c_mod, q0, qd0=[0.5, -0.25], p=p, u=u)
        lin_py = lagrgen.linearize(py_mod, q0, qd0=[0.5, -0.25], p=p, u=u)
        for name in "MCKB":
            assert_allclose(getattr(lin_c, name), getattr(lin_py, name), rtol=1e-12, atol=1e-14)
        with pytest.warns(lagrgen.NotAnEquilibriumWarning):        # any point, to compare
            res_c, res_py = lagrgen.modes(c_mod, q0, p=p), lagrgen.modes(py_mod, q0, p=p)
        assert_allclose(res_c.omega, res_py.omega, rtol=1e-12)
        assert_allclose(res_c.shapes, res_py.shapes, rtol=1e-10, atol=1e-12)
        assert_allclose(res_c.damping_ratios, res_py.damping_ratios, rtol=1e-10, atol=1e-14)
        name = py_mod.inputs[0]
        assert_allclose(lagrgen.frequency_response(c_mod, q0, [0.3, 1.1], input=name, p=p),
                        lagrgen.frequency_response(py_mod, q0, [0.3, 1.1], input=name, p=p),
                        rtol=1e-12)
        assert_allclose(lagrgen.equilibrium(c_mod, [0.1, 0.1], p=p),
                        lagrgen.equilibrium(py_mod, [0.1, 0.1], p=p), atol=1e-12)


def test_rigid_body_mode():
    mod = lagrgen.build(free_pair_model(), backend="python")
    q0 = lagrgen.equilibrium(mod, [0.3, 0.3])
    assert_allclose(q0, [0.3, 0.3])
    res = lagrgen.modes(mod, q0)
    assert_allclose(res.omega, [0.0, 4.0], atol=1e-12)
    assert_allclose(res.shapes.T @ res.shapes, np.eye(2), atol=1e-12)
    assert_allclose(np.abs(res.shapes[:, 0]), [np.sqrt(0.5)] * 2, rtol=1e-12)
    assert_allclose(res.damping_ratios, 0.0)
    H = lagrgen.frequency_response(mod, q0, [0.0, 1.0], input="f")
    assert np.all(np.isinf(H[0])) and np.all(np.isfinite(H[1]))


def test_repeated_frequency_shapes_follow_the_damping():
    """Three equal masses on a ring of equal springs: ω² = 0, 3, 3 (a repeated pair, any basis of
    shapes ⊥ [1, 1, 1]). A damper on a−b alone damps the shape [1, −1, 0] only (s = −0.1 ±
    i√(3 − 0.01)), so the damped mode must be reported with that shape, not an arbitrary one."""
    model = lagrgen.Model("vib_ring")
    a, b, c = model.coordinates("a b c")
    model.particle(1, sp.Matrix([a, b, c]))
    for x, y in ((a, b), (b, c), (c, a)):
        model.spring(1, x - y)
    model.damper(sp.Rational(1, 10), a - b)
    res = lagrgen.modes(lagrgen.build(model, backend="python"), [0.0, 0.0, 0.0])
    assert_allclose(res.omega, [0.0, np.sqrt(3), np.sqrt(3)], atol=1e-12)
    damped = int(np.argmax(res.damping_ratios))
    assert res.damping_ratios[damped] == pytest.approx(0.1 / np.sqrt(3), rel=1e-10)
    assert_allclose(np.abs(res.shapes[:, damped]), [np.sqrt(0.5), np.sqrt(0.5), 0], atol=1e-10)
    assert_allclose(np.delete(res.damping_ratios, damped), 0.0, atol=1e-12)
    assert_allclose(res.shapes.T @ res.shapes, np.eye(3), atol=1e-12)


def test_equilibrium_keeps_a_rigid_body_direction():
    mod = lagrgen.build(example_model("cart_pendulum"), backend="python")
    q0 = lagrgen.equilibrium(mod, [1.5, 0.4])
    assert_allclose(q0, [1.5, 0.0], atol=1e-9)


def test_circulatory_force_gives_non_symmetric_stiffness():
    mod = lagrgen.build(example_model("cart_pendulum"), backend="python")
    u = [4.0, 0.0]
    lin = lagrgen.linearize(mod, [0.0, 0.0], u=u)
    assert abs(lin.K[0, 1] - lin.K[1, 0]) > 1.0
    res = lagrgen.modes(lin)
    expected = np.sort(np.linalg.eigvals(np.linalg.solve(lin.M, lin.K)).real)
    assert_allclose(res.omega**2, expected, atol=1e-10)
    for i in range(2):
        phi = res.shapes[:, i]
        assert_allclose(lin.K @ phi, res.omega[i]**2 * lin.M @ phi, atol=1e-10)
        assert phi @ lin.M @ phi == pytest.approx(1.0)


def test_gyroscopic_coupling_is_not_damping():
    mod = lagrgen.build(rotating_frame_model(), backend="python")
    res = lagrgen.modes(mod, [0.0, 0.0])
    w0, Omega = 5.0, 1.5
    # skew C: the modes are the state matrix's, backward and forward whirl at ω0 ∓ Ω, undamped
    assert res.kind == "state" and res.stable
    assert_allclose(res.omega, [w0 - Omega, w0 + Omega], rtol=1e-10)
    assert_allclose(res.damping_ratios, 0.0, atol=1e-12)
    assert_allclose(res.omega_damped, [w0 - Omega, w0 + Omega], rtol=1e-10)
    lin = lagrgen.linearize(mod, [0.0, 0.0])
    assert_allclose(lin.K, (w0**2 - Omega**2) * np.eye(2), rtol=1e-12)   # centrifugal softening
    assert_allclose(lin.C, [[0, -2 * Omega], [2 * Omega, 0]], atol=1e-12)


def test_clear_errors():
    py = lagrgen.build(DOUBLE, backend="python")
    with pytest.raises(lagrgen.UnknownNameError, match="inputs of model 'double_pendulum' are F"):
        lagrgen.frequency_response(py, [0.0, 0.0], [1.0], input="G")
    with pytest.raises(ValueError, match="length 2"):
        lagrgen.linearize(py, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="length 2"):
        lagrgen.modes(py, [0.0])
    with pytest.raises(ValueError, match="length 2"):
        lagrgen.equilibrium(py, [0.0])
    driven = lagrgen.build(example_model("driven_pendulum"), backend="python")
    with pytest.raises(lagrgen.LagrgenError, match="has no inputs"):
        lagrgen.frequency_response(driven, [0.0], [1.0])
    cart = lagrgen.build(example_model("cart_pendulum"), backend="python")
    with pytest.raises(EquilibriumError, match="no equilibrium"):
        lagrgen.equilibrium(cart, [0.0, 3.0])
    with pytest.raises(lagrgen.MassMatrixError, match="not positive definite"):
        lagrgen.linearize(py, [0.0, 0.0], p={"m1": -3.0})
    assert isinstance(lagrgen.linearize(py, [0, 0]), Linearization)


def test_a_point_that_is_not_finite_is_refused():
    """NaN in q0 gave a NaN state matrix, inf in qd0 a linearization as if it were finite."""
    mod = lagrgen.build(oscillator_model(), backend="python")
    with pytest.raises(ValueError, match=r"q0: x is nan"):
        lagrgen.linearize(mod, [np.nan])
    with pytest.raises(ValueError, match=r"qd0: x_dot is inf"):
        lagrgen.linearize(mod, [0.0], [np.inf])
    with pytest.raises(ValueError, match=r"q_guess: x is nan"):
        lagrgen.equilibrium(mod, [np.nan])


def test_modes_default_to_the_equilibrium_near_zero():
    py = lagrgen.build(DOUBLE, backend="python")
    u = [2.0]
    q0 = lagrgen.equilibrium(py, [0.0, 0.0], u=u)
    F = py.forcing(q0, [0.0, 0.0], 0.0, None, u)
    assert_allclose(F, 0.0, atol=1e-9)
    assert np.all(q0 > 0.05)
    assert_allclose(lagrgen.modes(py, u=u).omega, lagrgen.modes(py, q0, u=u).omega, rtol=1e-10)


def test_display_symbols_round_trip():
    """The printed equations, read back, are M·q̈ − F (checks display.py against the model)."""
    from lagrgen.outputs.display import display_symbols, equation_lines, equations
    eqs = equations(DOUBLE)
    rules, _ = display_symbols(DOUBLE)
    lines = equation_lines(eqs)
    assert len(lines) == 2
    names = {f"{c}{s}": sp.Symbol(f"{c}{s}") for c in ("theta1", "theta2") for s in ("", "'", "''")}
    for i, line in enumerate(lines):
        lhs, rhs = line.split(" = ")
        text = lhs + "-(" + rhs + ")"
        for c in ("theta1", "theta2"):
            text = text.replace(f"{c}''", f"{c}__dd").replace(f"{c}'", f"{c}__d")
        read = sp.sympify(text, locals={"F": sp.Symbol("F")})
        read = read.subs({sp.Symbol(f"{c}__dd"): names[f"{c}''"] for c in ("theta1", "theta2")})
        read = read.subs({sp.Symbol(f"{c}__d"): names[f"{c}'"] for c in ("theta1", "theta2")})
        M, F = DOUBLE.mass_matrix().xreplace(rules), DOUBLE.forcing().xreplace(rules)
        expected = sum(M[i, j] * names[f"theta{j + 1}''"] for j in range(2)) - F[i]
        assert sp.simplify(read - expected) == 0


def test_modes_away_from_an_equilibrium_warn(built):
    """Modes at a point that is not an equilibrium describe no motion (issue 37, item 10): the
    pendulum at θ = 1 (θ̈ ≠ 0), or passing its lowest point (θ̇ ≠ 0), warns; its equilibria,
    stable or not, and a steady motion (two masses drifting together) do not."""
    mod = built(DOUBLE)
    with pytest.warns(lagrgen.NotAnEquilibriumWarning, match=r"accelerations are not zero "
                      r"\(theta1_ddot = .*Find an equilibrium with lagrgen.equilibrium"):
        lagrgen.modes(mod, [1.0, 0.0])
    with pytest.warns(lagrgen.NotAnEquilibriumWarning, match=r"the accelerations change along "
                      r"its rates \(theta1_dot = 2, theta2_dot = -1\)"):
        lagrgen.modes(mod, [0.0, 0.0], qd0=[2.0, -1.0])
    with pytest.warns(lagrgen.NotAnEquilibriumWarning, match="accelerations"):
        lagrgen.modes(lagrgen.linearize(mod, [1.0, 0.0]))        # from a Linearization too
    with warnings.catch_warnings():
        warnings.simplefilter("error", lagrgen.NotAnEquilibriumWarning)
        assert lagrgen.modes(mod, [0.0, 0.0]).stable
        with pytest.warns(lagrgen.UnstableModeWarning):
            lagrgen.modes(mod, [np.pi, np.pi])                  # an equilibrium, unstable
        free = built(FREE_PAIR)
        lagrgen.modes(free, [0.0, 0.0], qd0=[0.5, 0.5])         # drifting: a steady motion


def test_the_off_equilibrium_warning_does_not_depend_on_the_units(built):
    """Issue 45 item 13: a micro-scale Duffing oscillator at 1 µm (ω = 2 there, 1 at its
    equilibrium) is warned about alike with lengths in micrometres and in metres (the old
    absolute threshold let it pass in metres); its equilibria, at the origin or pushed off it,
    are not warned about at any scale."""
    mod = built(DUFFING)
    for unit in (1.0, 1e-6):                        # 1 µm in micrometres, then in metres
        p = {"beta": 1 / unit**2}                   # 3·β·x² = 3 at x = 1 µm
        with pytest.warns(lagrgen.NotAnEquilibriumWarning,
                          match=r"accelerations are not zero \(x_ddot = -2(e-06)?\)"):
            res = lagrgen.modes(mod, [unit], p=p)
        assert_allclose(res.omega, [2.0], rtol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error", lagrgen.NotAnEquilibriumWarning)
        for unit in (1e-12, 1e-9, 1e-6, 1.0, 1e3, 1e6):
            p = {"beta": 1 / unit**2}
            assert_allclose(lagrgen.modes(mod, [0.0], p=p).omega, [1.0], rtol=1e-12)
            pushed = {**p, "f": 2 * unit}           # k·x + β·x³ = f at x = 1 unit: ω = 2
            assert_allclose(lagrgen.modes(mod, [unit], p=pushed).omega, [2.0], rtol=1e-12)
        for unit in (1e-6, 1.0):                   # an equilibrium found, not given
            p = {"beta": 1 / unit**2, "f": 2 * unit}
            q = lagrgen.equilibrium(mod, [0.5 * unit], p=p)
            assert_allclose(q, [unit], rtol=1e-9)
            lagrgen.modes(mod, q, p=p)


def test_modes_take_the_dependent_coordinates(built):
    """A constrained model's modes: at its (leaning) equilibrium the frequencies do not depend on
    which coordinates are dependent; away from it they do, and the warning says so."""
    mod = built(PULLED)
    q0 = lagrgen.equilibrium(mod, [0.0, 0.3, -0.9])
    assert abs(q0[1] - q0[0]) > 0.1                              # leaning: x, y and s all free
    with warnings.catch_warnings():
        warnings.simplefilter("error", lagrgen.NotAnEquilibriumWarning)
        reference = lagrgen.modes(mod, q0).frequencies_hz
        for dependent in (["s"], ["x"], ["y"]):
            res = lagrgen.modes(mod, q0, dependent=dependent)
            assert res.linearization.coordinates == tuple(c for c in "sxy" if c not in dependent)
            assert_allclose(res.frequencies_hz, reference, rtol=1e-9)
    off = np.array([0.3, 0.3 + np.sin(0.8), -np.cos(0.8)])
    answers = []
    for dependent in (["s"], ["x"]):
        with pytest.warns(lagrgen.NotAnEquilibriumWarning, match="which coordinates are dependent"):
            answers.append(lagrgen.modes(mod, off, dependent=dependent).frequencies_hz)
    assert np.abs(answers[0] - answers[1]).max() > 1e-3
    lin = lagrgen.linearize(mod, q0)
    with pytest.raises(lagrgen.LagrgenError, match="pass dependent= to lagrgen.linearize"):
        lagrgen.modes(lin, dependent=["x"])
