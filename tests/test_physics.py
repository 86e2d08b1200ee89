"""Physics and calculus checks on the built models, independent of how the equations were derived.

- the analytic Jacobian ∂ẏ/∂y equals central finite differences of rhs, for every example;
- power balance dE/dt = ∇E(y)·ẏ = P_in(y) at random states, with E = T + V and the input power
  P_in (applied forces minus 2R) written by hand from the positions and velocities of the masses;
- a conservative model keeps its energy under a tight DOP853 integration;
- a damped model loses energy;
- the same physical system in two coordinate sets moves the same way.
"""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import lagrgen
from conftest import EXAMPLE_MODELS, example_id, example_model, random_point, FORMULATIONS


@pytest.fixture(scope="module", params=FORMULATIONS)
def formulation(request):
    """Every test here runs on both formulations (the recursive one for kinematic trees)."""
    return request.param


@pytest.fixture(scope="module", params=EXAMPLE_MODELS, ids=example_id)
def mod(request, build):
    return build(example_model(*request.param))


def finite_difference_jacobian(f, y, rel=1e-6):
    """Columns (f(y + h e_j) − f(y − h e_j)) / 2h with h = rel·max(1, |y_j|)."""
    J = np.empty((len(f(y)), len(y)))
    for j in range(len(y)):
        h = rel * max(1.0, abs(y[j]))
        e = np.zeros(len(y))
        e[j] = h
        J[:, j] = (f(y + e) - f(y - e)) / (2 * h)
    return J


def test_jacobian_matches_finite_differences(mod):
    rng = np.random.default_rng(21)
    for _ in range(3):
        q, qd, t, p, u = random_point(mod, rng)
        y = np.concatenate([q, qd])
        J = mod.jacobian(t, y, p, u)
        J_fd = finite_difference_jacobian(lambda z: mod.rhs(t, z, p, u), y)
        assert J.shape == (len(y), len(y))
        assert_allclose(J, J_fd, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(J).max()))


# -- energies and powers, by hand --------------------------------------------------------------

def chain_points(q, qd, lengths):
    """Positions and velocities of the ends of a chain of links at absolute angles q:
    p_k = Σ_{i≤k} l_i (sin q_i, −cos q_i), v_k = Σ_{i≤k} l_i q̇_i (cos q_i, sin q_i)."""
    lengths = np.asarray(lengths)
    x = np.cumsum(lengths * np.sin(q))
    y = -np.cumsum(lengths * np.cos(q))
    vx = np.cumsum(lengths * np.cos(q) * qd)
    vy = np.cumsum(lengths * np.sin(q) * qd)
    return x, y, vx, vy


def chain_energy(q, qd, masses, lengths, g):
    """E = Σ ½ m_k |v_k|² + m_k g y_k."""
    _, y, vx, vy = chain_points(q, qd, lengths)
    masses = np.asarray(masses)
    return float(np.sum(masses * (vx**2 + vy**2) / 2 + masses * g * y))


def double_pendulum_energy(q, qd, p, u):
    m1, m2, L1, L2, g = p
    return chain_energy(q, qd, [m1, m2], [L1, L2], g)


def double_pendulum_power(q, qd, p, u):
    """F · ẋ_B."""
    _, _, vx, _ = chain_points(q, qd, p[2:4])
    return u[0] * vx[1]


def nlink_energy(q, qd, p, u):
    n = len(q)
    return chain_energy(q, qd, p[:n], p[n:2 * n], p[2 * n])


def two_mass_state(q, qd, relative):
    """(x1, x2, ẋ1, ẋ2) from either coordinate set."""
    if relative:
        return q[0], q[0] + q[1], qd[0], qd[0] + qd[1]
    return q[0], q[1], qd[0], qd[1]


def two_mass_energy(relative):
    """E = ½m1ẋ1² + ½m2ẋ2² + ½k1x1² + ½k2(x2−x1)²."""
    def energy(q, qd, p, u):
        m1, m2, k1, k2, _, _ = p
        x1, x2, v1, v2 = two_mass_state(q, qd, relative)
        return (m1 * v1**2 + m2 * v2**2 + k1 * x1**2 + k2 * (x2 - x1)**2) / 2
    return energy


def two_mass_power(relative):
    """−c1ẋ1² − c2(ẋ2−ẋ1)² + f·ẋ2."""
    def power(q, qd, p, u):
        _, _, _, _, c1, c2 = p
        _, _, v1, v2 = two_mass_state(q, qd, relative)
        return -c1 * v1**2 - c2 * (v2 - v1)**2 + u[0] * v2
    return power


def rolling_chain_energy(q, qd, p, u):
    """E = ½m1ẋ1² + ½m2ẋ2² + ½m3ẋ3² + ½(½m3R²)(ẋ3/R)² + ½Σk_i(x_i − x_{i−1})² (x_0 = 0)."""
    m1, m2, m3, R, k1, k2, k3 = p[:7]
    stretch = np.diff(np.concatenate([[0.0], q]))
    kinetic = (m1 * qd[0]**2 + m2 * qd[1]**2 + m3 * qd[2]**2 + m3 * R**2 / 2 * (qd[2] / R)**2) / 2
    return kinetic + np.dot([k1, k2, k3], stretch**2) / 2


def rolling_chain_power(q, qd, p, u):
    """−Σc_i(ẋ_i − ẋ_{i−1})² + f·ẋ1."""
    rates = np.diff(np.concatenate([[0.0], qd]))
    return -np.dot(p[7:10], rates**2) + u[0] * qd[0]


def cart_pendulum_energy(q, qd, p, u):
    """E = ½Mẋ² + ½m|v_bob|² + m g y_bob + ½ktθ², bob = (x + L sin θ, −L cos θ)."""
    M, m, L, kt, g = p
    x, th = q
    xd, thd = qd
    vx, vy = xd + L * np.cos(th) * thd, L * np.sin(th) * thd
    return M * xd**2 / 2 + m * (vx**2 + vy**2) / 2 - m * g * L * np.cos(th) + kt * th**2 / 2


def cart_pendulum_power(q, qd, p, u):
    """P e·v_bob + Fc ẋ with e = (sin θ, −cos θ)."""
    L = p[2]
    x, th = q
    xd, thd = qd
    v_bob = np.array([xd + L * np.cos(th) * thd, L * np.sin(th) * thd])
    return u[0] * np.dot([np.sin(th), -np.cos(th)], v_bob) + u[1] * xd


def no_power(q, qd, p, u):
    return 0.0


POWER_CASES = {
    "double_pendulum": (("double_pendulum", "model"), double_pendulum_energy, double_pendulum_power),
    "two_mass_absolute": (("two_mass_chain", "absolute"), two_mass_energy(False),
                          two_mass_power(False)),
    "two_mass_relative": (("two_mass_chain", "relative"), two_mass_energy(True),
                          two_mass_power(True)),
    "rolling_chain": (("rolling_chain", "model"), rolling_chain_energy, rolling_chain_power),
    "cart_pendulum": (("cart_pendulum", "model"), cart_pendulum_energy, cart_pendulum_power),
    "nlink3": (("nlink_pendulum", "model"), nlink_energy, no_power),
}


@pytest.mark.parametrize("name", sorted(POWER_CASES))
def test_power_balance(name, build):
    """dE/dt along the motion, ∇_y E · rhs(y) (gradient by central differences), equals the power
    of the applied forces minus 2R, at random states with nonzero inputs."""
    entry, energy, power = POWER_CASES[name]
    mod = build(example_model(*entry))
    n = mod.n_coordinates
    rng = np.random.default_rng(31)
    for _ in range(3):
        q, qd, t, p, u = random_point(mod, rng)
        y = np.concatenate([q, qd])
        grad = finite_difference_jacobian(
            lambda z: np.array([energy(z[:n], z[n:], p, u)]), y, rel=1e-5)[0]
        dE_dt = grad @ mod.rhs(t, y, p, u)
        scale = max(1.0, np.abs(grad).max() * np.abs(y).max())
        assert dE_dt == pytest.approx(power(q, qd, p, u), rel=1e-6, abs=1e-6 * scale)


# -- integrating -------------------------------------------------------------------------------

@pytest.mark.parametrize("entry, energy, y0", [
    (("double_pendulum", "model"), double_pendulum_energy, [1.2, -0.6, 0.0, 1.5]),
    (("nlink_pendulum", "model"), nlink_energy, [0.5, 0.5, 0.5, 0.0, 0.0, 0.0]),
], ids=["double_pendulum", "nlink3"])
def test_conservative_model_conserves_energy(entry, energy, y0, build):
    """With no inputs acting, E = T + V stays constant along the DOP853 solution (drift < 1e-8)."""
    mod = build(example_model(*entry))
    n = mod.n_coordinates
    sol = lagrgen.simulate(mod, (0.0, 5.0), y0, method="DOP853", rtol=1e-12, atol=1e-12,
                           t_eval=np.linspace(0.0, 5.0, 51))
    assert sol.success
    p, u = mod.defaults, np.zeros(len(mod.inputs))
    E = np.array([energy(y[:n], y[n:], p, u) for y in sol.y.T])
    assert np.ptp(sol.y[0]) > 0.5
    assert np.max(np.abs(E - E[0])) / abs(E[0]) < 1e-8


def test_damped_model_loses_energy(build):
    """The rolling chain with f = 0: dE/dt = −2R ≤ 0, so E never grows and decays markedly."""
    mod = build(example_model("rolling_chain"))
    sol = lagrgen.simulate(mod, (0.0, 5.0), [0.1, -0.05, 0.2, 0.0, 0.3, 0.0], method="DOP853",
                           rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 5.0, 201))
    p, u = mod.defaults, np.zeros(1)
    E = np.array([rolling_chain_energy(y[:3], y[3:], p, u) for y in sol.y.T])
    assert np.all(np.diff(E) <= 1e-10 * E[0])
    assert E[-1] < 0.5 * E[0]


def test_two_coordinate_sets_give_the_same_motion(build):
    """two_mass_absolute (x1, x2) and two_mass_relative (x1, s = x2 − x1) describe one system:
    driven by the same f(t) from the same initial state, x2(t) = x1(t) + s(t) to 1e-7."""
    absolute = build(example_model("two_mass_chain", "absolute"))
    relative = build(example_model("two_mass_chain", "relative"))
    x0, v0 = np.array([0.1, -0.2]), np.array([0.0, 0.5])
    options = dict(method="DOP853", rtol=1e-11, atol=1e-12, t_eval=np.linspace(0.0, 6.0, 121),
                   params={"m2": 0.7, "c2": 0.1},
                   inputs={"f": lambda t: 2.0 * np.sin(3.0 * t) + 0.5})
    sol_a = lagrgen.simulate(absolute, (0.0, 6.0), np.concatenate([x0, v0]), **options)
    y0_r = np.concatenate([[x0[0], x0[1] - x0[0]], [v0[0], v0[1] - v0[0]]])
    sol_r = lagrgen.simulate(relative, (0.0, 6.0), y0_r, **options)
    x2_a, x2_r = sol_a.y[1], sol_r.y[0] + sol_r.y[1]
    assert np.ptp(x2_a) > 0.1
    assert_allclose(x2_r, x2_a, rtol=0, atol=1e-7)
    assert_allclose(sol_r.y[0], sol_a.y[0], rtol=0, atol=1e-7)
