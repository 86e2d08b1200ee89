"""Every example against its equations of motion derived by hand, M(q,t)·q̈ = F(q,q̇,t,u).

Each `hand_*` function states T, V, R and Q of the example and returns M and F worked out on paper
from d/dt(∂T/∂q̇) − ∂T/∂q + ∂V/∂q + ∂R/∂q̇ = Q, written in the model's own symbols (coordinates
q(t), velocities dq/dt, parameter symbols, input functions u(t)). They are compared symbolically
with `Model.mass_matrix()` / `Model.forcing()`, and numerically with the built model.
"""
import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

from conftest import example_model, random_point, state_function, FORMULATIONS


@pytest.fixture(scope="module", params=FORMULATIONS)
def formulation(request):
    """Every test here runs on both formulations (the recursive one for kinematic trees)."""
    return request.param

t = sp.Symbol("t")


def functions(names):
    """SymPy functions of t named `names` (coordinates or inputs), and their time derivatives."""
    fs = [sp.Function(n)(t) for n in names.split()]
    return fs, [f.diff(t) for f in fs]


def hand_double_pendulum():
    """pA = L1(sin θ1, −cos θ1), pB = pA + L2(sin θ2, −cos θ2), V = g(m1 yA + m2 yB), Q = F·∂xB/∂θ:
    M = [[(m1+m2)L1², m2 L1 L2 c12], [m2 L1 L2 c12, m2 L2²]], c12 = cos(θ1−θ2), s12 = sin(θ1−θ2),
    F1 = −m2 L1 L2 s12 θ̇2² − (m1+m2) g L1 sin θ1 + F L1 cos θ1,
    F2 =  m2 L1 L2 s12 θ̇1² − m2 g L2 sin θ2 + F L2 cos θ2."""
    (th1, th2), (w1, w2) = functions("theta1 theta2")
    m1, m2, L1, L2, g = sp.symbols("m1 m2 L1 L2 g")
    F = sp.Function("F")(t)
    c12, s12 = sp.cos(th1 - th2), sp.sin(th1 - th2)
    M = sp.Matrix([[(m1 + m2) * L1**2, m2 * L1 * L2 * c12], [m2 * L1 * L2 * c12, m2 * L2**2]])
    f = sp.Matrix([
        -m2 * L1 * L2 * s12 * w2**2 - (m1 + m2) * g * L1 * sp.sin(th1) + F * L1 * sp.cos(th1),
        m2 * L1 * L2 * s12 * w1**2 - m2 * g * L2 * sp.sin(th2) + F * L2 * sp.cos(th2)])
    return M, f


def hand_two_mass_absolute():
    """T = ½m1ẋ1² + ½m2ẋ2², V = ½k1x1² + ½k2(x2−x1)², R = ½c1ẋ1² + ½c2(ẋ2−ẋ1)², Q = (0, f):
    M = diag(m1, m2), F = (−k1x1 + k2(x2−x1) − c1ẋ1 + c2(ẋ2−ẋ1), −k2(x2−x1) − c2(ẋ2−ẋ1) + f)."""
    (x1, x2), (v1, v2) = functions("x1 x2")
    m1, m2, k1, k2, c1, c2 = sp.symbols("m1 m2 k1 k2 c1 c2")
    f = sp.Function("f")(t)
    M = sp.diag(m1, m2)
    F = sp.Matrix([-k1 * x1 + k2 * (x2 - x1) - c1 * v1 + c2 * (v2 - v1),
                   -k2 * (x2 - x1) - c2 * (v2 - v1) + f])
    return M, F


def hand_two_mass_relative():
    """x2 = x1 + s: T = ½m1ẋ1² + ½m2(ẋ1+ṡ)², V = ½k1x1² + ½k2s², R = ½c1ẋ1² + ½c2ṡ²,
    Q = f·∂(x1+s)/∂(x1, s) = (f, f): M = [[m1+m2, m2], [m2, m2]], F = (−k1x1 − c1ẋ1 + f, −k2s − c2ṡ + f)."""
    (x1, s), (v1, sd) = functions("x1 s")
    m1, m2, k1, k2, c1, c2 = sp.symbols("m1 m2 k1 k2 c1 c2")
    f = sp.Function("f")(t)
    M = sp.Matrix([[m1 + m2, m2], [m2, m2]])
    F = sp.Matrix([-k1 * x1 - c1 * v1 + f, -k2 * s - c2 * sd + f])
    return M, F


def hand_driven_pendulum():
    """bob = r(cos Ωt, sin Ωt) + L(sin θ, −cos θ): T = ½m(r²Ω² + L²θ̇² + 2rΩLθ̇ sin(θ−Ωt)),
    d/dt ∂T/∂θ̇ − ∂T/∂θ = mL²θ̈ − mrΩ²L cos(θ−Ωt), ∂V/∂θ = mgL sin θ:
    M = mL², F = m r Ω² L cos(θ − Ωt) − m g L sin θ."""
    (th,), _ = functions("theta")
    m, L, r, Om, g = sp.symbols("m L r Omega g")
    M = sp.Matrix([[m * L**2]])
    F = sp.Matrix([m * r * Om**2 * L * sp.cos(th - Om * t) - m * g * L * sp.sin(th)])
    return M, F


def hand_rolling_chain():
    """T = ½m1ẋ1² + ½m2ẋ2² + ½m3ẋ3² + ½(½m3R²)(ẋ3/R)², springs and dampers between neighbours,
    Q = (f, 0, 0): M = diag(m1, m2, 3m3/2),
    F_i = −∂V/∂x_i − ∂R/∂ẋ_i + Q_i with V = ½k1x1² + ½k2(x2−x1)² + ½k3(x3−x2)² (R alike with c, ẋ)."""
    (x1, x2, x3), (v1, v2, v3) = functions("x1 x2 x3")
    m1, m2, m3, R = sp.symbols("m1 m2 m3 R")
    k1, k2, k3, c1, c2, c3 = sp.symbols("k1 k2 k3 c1 c2 c3")
    f = sp.Function("f")(t)
    M = sp.diag(m1, m2, sp.Rational(3, 2) * m3)
    F = sp.Matrix([
        -k1 * x1 + k2 * (x2 - x1) - c1 * v1 + c2 * (v2 - v1) + f,
        -k2 * (x2 - x1) + k3 * (x3 - x2) - c2 * (v2 - v1) + c3 * (v3 - v2),
        -k3 * (x3 - x2) - c3 * (v3 - v2)])
    return M, F


def hand_cart_pendulum():
    """bob = (x + L sin θ, −L cos θ): T = ½(M+m)ẋ² + mLẋθ̇ cos θ + ½mL²θ̇², V = −mgL cos θ + ½ktθ²,
    Q = P·e·∂bob/∂(x, θ) + Fc·(1, 0) = (P sin θ + Fc, 0) (e ⟂ ∂bob/∂θ):
    M = [[M+m, mL cos θ], [mL cos θ, mL²]], F = (mLθ̇² sin θ + P sin θ + Fc, −mgL sin θ − ktθ)."""
    (x, th), (xd, thd) = functions("x theta")
    Mc, m, L, kt, g = sp.symbols("M m L kt g")
    P, Fc = sp.Function("P")(t), sp.Function("Fc")(t)
    M = sp.Matrix([[Mc + m, m * L * sp.cos(th)], [m * L * sp.cos(th), m * L**2]])
    F = sp.Matrix([m * L * thd**2 * sp.sin(th) + P * sp.sin(th) + Fc,
                   -m * g * L * sp.sin(th) - kt * th])
    return M, F


def hand_nlink(n):
    """Chain of n point masses, absolute angles: with μ_ij = Σ_{k ≥ max(i,j)} m_k,
    M_ij = μ_ij l_i l_j cos(q_i − q_j),
    F_i = −Σ_j μ_ij l_i l_j sin(q_i − q_j) q̇_j² − g l_i sin q_i Σ_{k ≥ i} m_k."""
    q, qd = functions(" ".join(f"q{i}" for i in range(n)))
    m = sp.symbols(f"m0:{n}")
    l = sp.symbols(f"l0:{n}")
    g = sp.Symbol("g")

    def mu(i, j):
        return sum(m[max(i, j):])
    M = sp.Matrix(n, n, lambda i, j: mu(i, j) * l[i] * l[j] * sp.cos(q[i] - q[j]))
    F = sp.Matrix([
        -sum(mu(i, j) * l[i] * l[j] * sp.sin(q[i] - q[j]) * qd[j]**2 for j in range(n))
        - g * l[i] * sp.sin(q[i]) * sum(m[i:]) for i in range(n)])
    return M, F


CASES = {
    "double_pendulum": (("double_pendulum", "model"), hand_double_pendulum),
    "two_mass_absolute": (("two_mass_chain", "absolute"), hand_two_mass_absolute),
    "two_mass_relative": (("two_mass_chain", "relative"), hand_two_mass_relative),
    "driven_pendulum": (("driven_pendulum", "model"), hand_driven_pendulum),
    "rolling_chain": (("rolling_chain", "model"), hand_rolling_chain),
    "cart_pendulum": (("cart_pendulum", "model"), hand_cart_pendulum),
    "nlink3": (("nlink_pendulum", "model"), lambda: hand_nlink(3)),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    """(Model, hand-derived M, hand-derived F) for one example."""
    (stem, attr), hand = CASES[request.param]
    return (example_model(stem, attr), *hand())


def symbolically_zero(expr):
    """True if `expr` simplifies to 0 (trig expansion first, `sp.simplify` as the fallback)."""
    expr = sp.expand(sp.expand_trig(expr))
    return expr == 0 or sp.simplify(expr) == 0


def assert_same_matrix(derived, hand):
    assert derived.shape == hand.shape
    for (i, j), d, h in zip(np.ndindex(*hand.shape), derived, hand):
        assert symbolically_zero(d - h), f"entry ({i}, {j}): derived {d}, by hand {h}"


def test_mass_matrix_matches_hand_derivation(case):
    model, M, _ = case
    assert_same_matrix(model.mass_matrix(), M)


def test_forcing_matches_hand_derivation(case):
    model, _, F = case
    assert_same_matrix(model.forcing(), F)


def test_built_model_matches_hand_derivation(case, build):
    """The built model's M and F equal the hand formulas at 5 random states (rtol 1e-12)."""
    model, M, F = case
    mod = build(model)
    q, qd = functions(" ".join(mod.coordinates))
    params = [sp.Symbol(name) for name in mod.parameters]
    inputs = [sp.Function(name)(t) for name in mod.inputs]
    hand_M = state_function(M, t, q, qd, params, inputs)
    hand_F = state_function(F, t, q, qd, params, inputs)
    rng = np.random.default_rng(7)
    for _ in range(5):
        qv, qdv, tv, p, u = random_point(mod, rng)
        assert_allclose(mod.mass_matrix(qv, tv, p, u), hand_M(qv, qdv, tv, p, u),
                        rtol=1e-12, atol=1e-12)
        assert_allclose(mod.forcing(qv, qdv, tv, p, u), hand_F(qv, qdv, tv, p, u).ravel(),
                        rtol=1e-12, atol=1e-11)


def test_coordinates_in_declared_order(case, build):
    """The hand derivations assume these coordinate orders; the built models must report them."""
    model, M, _ = case
    expected = {"double_pendulum": ("theta1", "theta2"), "two_mass_absolute": ("x1", "x2"),
                "two_mass_relative": ("x1", "s"), "driven_pendulum": ("theta",),
                "rolling_chain": ("x1", "x2", "x3"), "cart_pendulum": ("x", "theta"),
                "nlink3": ("q0", "q1", "q2")}[model.name]
    mod = build(model)
    assert mod.coordinates == expected
    assert mod.n_coordinates == M.shape[0]


def explicit_time(expr, coordinates):
    """True if `expr` depends on t other than through the coordinates and their velocities."""
    q, qd = functions(coordinates)
    frozen = {**{v: sp.Dummy() for v in qd}, **{c: sp.Dummy() for c in q}}
    return t in sp.sympify(expr).xreplace(frozen).free_symbols


def test_prescribed_motion_equations_contain_time():
    """The crank angle Ωt is prescribed, so F depends explicitly on t and M (here mL²) does not;
    a scleronomic model has no explicit t at all."""
    driven = example_model("driven_pendulum")
    assert explicit_time(driven.forcing(), "theta")
    assert not explicit_time(driven.mass_matrix(), "theta")
    pendulum = example_model("nlink_pendulum")
    assert not explicit_time(pendulum.forcing(), "q0 q1 q2")


def test_prescribed_motion_built_model_depends_on_time(build):
    """Numerically too: F(θ, θ̇, t) of the driven pendulum changes with t at a fixed state."""
    mod = build(example_model("driven_pendulum"))
    values = [mod.forcing([0.3], [0.1], t)[0] for t in (0.0, 0.25, 0.5)]
    assert np.ptp(values) > 0.1
