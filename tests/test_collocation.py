"""Direct collocation (lagrgen.Collocation): known optima, the NLP's derivatives against finite
differences, identification against the truth and against lagrgen.fit, constrained models, free
durations, and the errors bad input gets."""
import subprocess
import sys
import warnings

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen.errors import LagrgenError, UnknownNameError
from conftest import damped_oscillator, double_integrator, example_model, nlp_derivatives

pytest.importorskip("cyipopt", reason="IPOPT (pip install 'lagrgen[optimize]') is not installed")


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("collocation")


@pytest.fixture(scope="module")
def integrator(out_dir):
    """A unit mass pushed by a force F: ẍ = F."""
    model = double_integrator("colloc_integrator")
    return model, lagrgen.build(model, out_dir=out_dir)


@pytest.fixture(scope="module")
def oscillator(out_dir):
    """A damped oscillator m·ẍ + c·ẋ + k·x = F."""
    model = damped_oscillator("colloc_oscillator")
    return model, lagrgen.build(model, out_dir=out_dir)


@pytest.fixture(scope="module")
def cart(out_dir):
    model = example_model("cart_pendulum")
    return model, lagrgen.build(model, out_dir=out_dir)


@pytest.fixture(scope="module")
def pendulums(out_dir):
    """The same pendulum as one angle and in Cartesian coordinates with the rod a constraint,
    each driven by a horizontal force on the bob."""
    angle = lagrgen.Model("colloc_pendulum")
    th, = angle.coordinates("theta")
    m, L, g = angle.parameters(m=1.0, L=1.0, g=9.81)
    F, = angle.inputs("F")
    bob = sp.Matrix([L * sp.sin(th), -L * sp.cos(th)])
    angle.particle(m, bob)
    angle.potential_energy(m * g * bob[1])
    angle.force(sp.Matrix([F, 0]), at=bob)
    cartesian = lagrgen.Model("colloc_cartesian")
    x, y = cartesian.coordinates("x y")
    m, L, g = cartesian.parameters(m=1.0, L=1.0, g=9.81)
    F, = cartesian.inputs("F")
    cartesian.particle(m, sp.Matrix([x, y]))
    cartesian.potential_energy(m * g * y)
    cartesian.force(sp.Matrix([F, 0]), at=sp.Matrix([x, y]))
    cartesian.constraint(x ** 2 + y ** 2 - L ** 2, name="rod")
    return ((angle, lagrgen.build(angle, out_dir=out_dir)),
            (cartesian, lagrgen.build(cartesian, out_dir=out_dir)))


#: Tests that solve on coarse grids on purpose (mesh_tol=None): the warning that the
#: dynamics error is above 1e-6 is expected there (test_collocation_accuracy tests it).
COARSE = pytest.mark.filterwarnings(
    "ignore::lagrgen.collocation.refine.DiscretizationWarning")


def effort_problem(mod, F, nodes, scheme):
    """Move the unit mass from rest at 0 to rest at 1 in 1 s with the least ∫F² dt."""
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=1.0, scheme=scheme)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0])
    return prob.minimize(integral=F ** 2)


# -- the model function of the implicit form ---------------------------------------------------
@pytest.mark.parametrize("backend", ["c", "python"])
def test_residual_terms_are_the_implicit_form_and_its_exact_derivatives(backend, out_dir):
    model = example_model("cartesian_pendulum")
    mod = lagrgen.build(model, out_dir=out_dir, backend=backend)
    n, m = mod.n_coordinates, mod.n_constraints
    rng = np.random.default_rng(4)
    q, qd, a = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-1, 1, n + m)
    p = np.array(mod.defaults) * rng.uniform(0.5, 1.5, len(mod.defaults))
    r, dr_dy, dr_da, dr_du = mod.residual_terms(q, qd, a, 0.3, p)
    y = np.r_[q, qd]
    acc, lam = mod.rhs(0.3, y, p)[n:], mod.constraint_forces(0.3, y, p)
    assert_allclose(mod.residual_terms(q, qd, np.r_[acc, lam], 0.3, p)[0], 0, atol=1e-12)

    def numeric(f, x, eps=1e-6):
        return np.array([(f(x + eps * e) - f(x - eps * e)) / (2 * eps) for e in np.eye(x.size)]).T
    assert_allclose(numeric(lambda z: mod.residual_terms(z[:n], z[n:], a, 0.3, p)[0], y), dr_dy,
                    atol=1e-7)
    assert_allclose(numeric(lambda z: mod.residual_terms(q, qd, z, 0.3, p)[0], a), dr_da,
                    atol=1e-7)
    assert_allclose(numeric(lambda z: mod.residual_terms(q, qd, a, 0.3, z)[0], p),
                    mod.residual_parameter_jacobian(q, qd, a, 0.3, p), atol=1e-7)
    assert dr_du.shape == (n + m, 0)


# -- known optima --------------------------------------------------------------------------------
@COARSE
def test_minimum_effort_double_integrator_is_the_closed_form(integrator):
    """F = 6 − 12t, x = 3t² − 2t³, ∫F² = 12: Hermite–Simpson is exact on cubics (one Newton
    step with the exact Hessian), the trapezoidal rule converges at second order."""
    model, mod = integrator
    F, = model.input_functions
    res = effort_problem(mod, F, 11, "hermite-simpson").solve(progress=False)
    assert res.success and res.iterations <= 2
    assert res.objective == pytest.approx(12.0, rel=1e-10)
    assert_allclose(res.u[0], 6 - 12 * res.t, atol=1e-8)
    assert_allclose(res.y[0], 3 * res.t ** 2 - 2 * res.t ** 3, atol=1e-10)
    assert res.check() < 1e-8
    errors = [effort_problem(mod, F, N, "trapezoidal").solve(progress=False,
                                                              mesh_tol=None).objective - 12
              for N in (11, 21)]
    assert 3.5 < errors[0] / errors[1] < 4.5


@COARSE
def test_exact_hessian_and_quasi_newton_reach_the_same_optimum(integrator):
    model, mod = integrator
    F, = model.input_functions
    prob = effort_problem(mod, F, 15, "trapezoidal")
    prob.path(F, -5.5, 5.5)                      # active near both ends
    start = {"x": 0.0, "F": 0.0}                   # not the optimum (the default start nearly is)
    exact = prob.solve(guess=start, progress=False, mesh_tol=None)
    quasi = prob.solve(guess=start, hessian="quasi-newton", progress=False, mesh_tol=None)
    assert exact.success and quasi.success
    assert exact.objective == pytest.approx(quasi.objective, rel=1e-7)
    assert exact.iterations < quasi.iterations
    assert np.max(np.abs(exact.u)) == pytest.approx(5.5, abs=1e-6)


def test_minimum_time_with_a_bounded_force_is_bang_bang(integrator):
    """From rest at 0 to rest at 1 with |F| ≤ 1: full push then full brake, T = 2."""
    model, mod = integrator
    prob = lagrgen.Collocation(mod, nodes=41, duration=(0.5, 5.0), scheme="trapezoidal")
    prob.bound("F", -1, 1)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0])
    res = prob.minimize(time=True).solve(progress=False)
    assert res.success
    assert res.duration == pytest.approx(2.0, rel=2e-3)
    assert res.objective == pytest.approx(res.duration)
    early, late = res.t < 0.8, res.t > 1.2
    assert_allclose(res.u[0, early], 1.0, atol=1e-4)
    assert_allclose(res.u[0, late], -1.0, atol=1e-4)


def test_warm_start_from_an_earlier_result_on_another_grid(integrator):
    model, mod = integrator
    F, = model.input_functions
    coarse = effort_problem(mod, F, 11, "trapezoidal").solve(progress=False)
    fine = effort_problem(mod, F, 31, "hermite-simpson")
    res = fine.solve(guess=coarse, progress=False)
    assert res.success and res.iterations <= 3
    assert res.objective == pytest.approx(12.0, rel=1e-9)


# -- derivatives against finite differences --------------------------------------------------------
@pytest.mark.parametrize("scheme", ["trapezoidal", "hermite-simpson", "backward-euler"])
@pytest.mark.parametrize("duration", [1.0, (0.5, 2.0)], ids=["fixed", "free"])
def test_jacobian_and_lagrangian_hessian_match_finite_differences(cart, scheme, duration):
    """Every ingredient at once: dynamics, unknown parameters, two path constraints (one with an
    acceleration), an integrand with parameters, periodicity, bounded states, data (fixed
    duration) or minimum time (free: with the states' hulls between the points); and the
    sparsity structures cover every nonzero."""
    model, mod = cart
    x, th = model.q
    P, Fc = model.input_functions
    M, m, L, kt, g = model.parameter_symbols
    t = model.t
    prob = lagrgen.Collocation(mod, nodes=4, duration=duration, scheme=scheme,
                               unknown_params=["kt", "m"])
    prob.path(sp.sin(th) * x.diff(t) + P ** 2 + m * th.diff(t, 2), -1, 1)
    prob.path(L * sp.cos(x) * kt, hi=3)
    free = isinstance(duration, tuple)
    prob.minimize(integral=Fc ** 2 + m * kt * th ** 2 + sp.cos(th) * x.diff(t) ** 2, time=free)
    if not free:
        prob.track([0.1, 0.35, 0.9], [[0.1, 0.2, 0.3], [0.0, 0.1, 0.3]], ["theta", "x_dot"])
    prob.periodic(["x"])
    prob.bound("x", -2, 2).bound("theta_dot", hi=5)      # a free duration's states' hulls
    J, Jn, H, Hn, grad, gradn = nlp_derivatives(prob)
    scale = 1 + np.abs(Jn).max()
    assert np.abs(J - Jn).max() < 1e-7 * scale
    assert np.abs(Jn[J == 0]).max(initial=0) < 1e-7 * scale       # structure covers the nonzeros
    assert np.abs(grad - gradn).max() < 1e-7 * (1 + np.abs(gradn).max())
    hscale = 1 + np.abs(Hn).max()
    assert np.abs(H - Hn).max() < 1e-6 * hscale
    assert np.abs(Hn[H == 0]).max(initial=0) < 1e-6 * hscale


def test_constrained_model_derivatives_match_finite_differences(pendulums):
    (_, _), (cartesian, mod) = pendulums
    x, y = cartesian.q
    prob = lagrgen.Collocation(mod, nodes=3, duration=(0.5, 2), scheme="hermite-simpson",
                               unknown_params=["L"])
    prob.minimize(integral=x ** 2 * y.diff(cartesian.t) ** 2, time=True)
    J, Jn, H, Hn, grad, gradn = nlp_derivatives(prob, seed=1)
    assert np.abs(J - Jn).max() < 1e-6 * (1 + np.abs(Jn).max())
    assert np.abs(Jn[J == 0]).max(initial=0) < 1e-6
    assert np.abs(H - Hn).max() < 1e-5 * (1 + np.abs(Hn).max())
    assert np.abs(Hn[H == 0]).max(initial=0) < 1e-5


# -- constrained models --------------------------------------------------------------------------
@COARSE
def test_a_constrained_model_gives_the_optimum_of_its_unconstrained_twin(pendulums):
    """The minimum-effort swing to 60° in 2 s, described by one angle or by (x, y) with the rod
    as a constraint (multipliers as variables): the same optimum and motion."""
    (angle, amod), (cartesian, cmod) = pendulums
    target = np.pi / 3
    results = []
    for model, mod in ((angle, amod), (cartesian, cmod)):
        F, = model.input_functions
        prob = lagrgen.Collocation(mod, nodes=41, duration=2.0, scheme="hermite-simpson")
        if model is angle:
            prob.initial(q=[0.0], qd=[0.0]).final(q=[target], qd=[0.0])
        else:
            prob.initial(q=[0.0, -1.0], qd=[0.0, 0.0])
            prob.final(q={"x": np.sin(target)}, qd={"x": 0.0})
        results.append(prob.minimize(integral=F ** 2).solve(progress=False, mesh_tol=None))
    a, c = results
    assert a.success and c.success
    assert c.objective == pytest.approx(a.objective, rel=1e-3)
    assert_allclose(c.y[0], np.sin(a.y[0]), atol=2e-3)
    residual = c.y[0] ** 2 + c.y[1] ** 2 - 1
    assert np.abs(residual).max() < 1e-4
    tension = -2 * c.multipliers[0]           # the rod's pull is −2·L·λ
    assert np.all(tension > 0)
    assert c.check() < 1e-2


def test_the_first_node_of_a_constrained_model_is_consistent(pendulums):
    """Initial values of independent coordinates only: the rod's position and velocity levels
    hold at the first node (the acceleration level at every point); a full initial state off
    the constraint is refused."""
    (_, _), (cartesian, mod) = pendulums
    F, = cartesian.input_functions
    prob = lagrgen.Collocation(mod, nodes=21, duration=1.0)
    prob.initial(q={"x": 0.6}, qd={"x": 0.3}).final(q={"x": 0.0})
    res = prob.minimize(integral=F ** 2).solve(guess={"y": -0.8}, progress=False)
    assert res.success
    x0, y0, xd0, yd0 = res.y[:, 0]
    assert (x0, y0) == (pytest.approx(0.6), pytest.approx(-0.8))
    assert x0 * xd0 + y0 * yd0 == pytest.approx(0.0, abs=1e-9)
    assert np.abs(res.y[0] ** 2 + res.y[1] ** 2 - 1).max() < 1e-5
    bad = lagrgen.Collocation(mod, nodes=11, duration=1.0)
    bad.initial(q=[0.6, -0.6], qd=[0.0, 0.0]).minimize(integral=F ** 2)
    with pytest.raises(LagrgenError, match="position level of constraint 'rod'"):
        bad.solve(progress=False)


# -- identification ----------------------------------------------------------------------------
def test_identification_recovers_the_truth_within_its_standard_errors(oscillator):
    """k and c of a damped oscillator from a noisy record with a gap (samples at arbitrary times),
    the force known, the initial state unknown: estimates within 3 standard errors of the truth,
    and estimates and standard errors that agree with lagrgen.fit's on the same data (an
    independent method: least squares on simulations with their sensitivities)."""
    model, mod = oscillator
    truth = {"k": 4.0, "c": 0.3}
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(0, 6, 160))
    t = t[(t < 2.5) | (t > 3.6)]                       # a gap in the record
    force = lagrgen.Signal(np.linspace(0, 6, 61), np.sin(1.7 * np.linspace(0, 6, 61)))
    exact = lagrgen.simulate(mod, (0, 6), [0.5, 0.0], params=truth, inputs={"F": force},
                             t_eval=t, rtol=1e-11, atol=1e-12)
    sigma = 0.01
    data = exact.y[0] + sigma * rng.standard_normal(t.size)
    prob = lagrgen.Collocation(mod, nodes=121, duration=6.0, scheme="hermite-simpson",
                               unknown_params=["k", "c"], params={"k": 3.0, "c": 0.1})
    prob.input("F", force)
    prob.track(t, data, "x", weights=1 / sigma ** 2)
    res = prob.solve(progress=False)
    assert res.success
    for name, value in truth.items():
        assert abs(res.params[name] - value) < 3 * res.stderr[name]
        assert 0 < res.stderr[name] < 0.05 * value
    fitted = lagrgen.fit(mod, t, data[None, :], params=["k", "c", "y0:x", "y0:x_dot"],
                         y0=[0.4, 0.0], initial={"k": 3.0, "c": 0.1}, inputs={"F": force},
                         rtol=1e-10, atol=1e-12, measured=["x"])
    for name in truth:
        assert res.params[name] == pytest.approx(fitted.params[name], abs=0.1 * res.stderr[name])
        assert res.stderr[name] == pytest.approx(fitted.stderr[name], rel=0.05)


# -- results --------------------------------------------------------------------------------------
def test_result_views(integrator, tmp_path):
    model, mod = integrator
    F, = model.input_functions
    res = effort_problem(mod, F, 11, "hermite-simpson").solve(progress=False)
    assert res.y.shape == (2, 11) and res.u.shape == (1, 11) and res.t.shape == (11,)
    ds = res.to_xarray()
    assert_allclose(ds["y"].sel(state="x").values, res.y[0])
    assert ds.attrs["objective"] == pytest.approx(12.0)
    fig = res.plot(tmp_path / "effort.png")
    assert (tmp_path / "effort.png").stat().st_size > 1000 and len(fig.axes) == 3
    signals = res.input_signals()
    assert signals["F"](0.5) == pytest.approx(0.0, abs=1e-8)
    anim = res.animate(max_frames=12)
    assert len(anim) == 12 and anim.q.shape == (1, 12)


def test_an_instance_constraint_between_nodes_holds_on_the_interpolant(integrator):
    model, mod = integrator
    F, = model.input_functions
    prob = effort_problem(mod, F, 11, "hermite-simpson")
    prob.at(0.37, "x", 0.8).at(0.5, "x_dot", 1.0)          # between nodes, and on a node
    res = prob.solve(progress=False)
    assert res.success
    assert res.state_at(0.37)[0] == pytest.approx(0.8, abs=1e-9)
    assert res.y[1, np.flatnonzero(np.isclose(res.t, 0.5))[0]] == pytest.approx(1.0, abs=1e-9)
    assert res.objective > 12.0


def test_guess_from_a_simulation(oscillator):
    model, mod = oscillator
    sim = lagrgen.simulate(mod, (0, 2), [0.5, 0.0], t_eval=np.linspace(0, 2, 201), rtol=1e-10,
                           atol=1e-12)
    prob = lagrgen.Collocation(mod, nodes=21, duration=2.0, scheme="hermite-simpson")
    prob.initial(q=[0.5], qd=[0.0])
    F, = model.input_functions
    res = prob.minimize(integral=F ** 2).solve(guess=sim, progress=False)
    assert res.success and res.objective == pytest.approx(0.0, abs=1e-9)
    assert res.iterations <= 5
    assert_allclose(res.y[0], np.interp(res.t, sim.t, sim.y[0]), atol=1e-4)


def test_the_command_line_solves_a_problem_file(integrator, tmp_path, capsys):
    model, mod = integrator
    problem_file = tmp_path / "problem.py"
    problem_file.write_text(
        "import sympy as sp\nimport lagrgen\n"
        "model = lagrgen.Model('cli_integrator')\nx, = model.coordinates('x')\n"
        "F, = model.inputs('F')\nmodel.particle(1, sp.Matrix([x]))\n"
        "model.generalized_force(x, F)\n"
        f"mod = lagrgen.build(model, out_dir={str(tmp_path / 'gen')!r})\n"
        "problem = lagrgen.Collocation(mod, nodes=11, duration=1.0)\n"
        "problem.initial(q=[0], qd=[0]).final(q=[1], qd=[0]).minimize(integral=F**2)\n")
    from lagrgen.cli import main
    assert main(["optimize", str(problem_file), "--plot", str(tmp_path / "p.png")]) == 0
    out = capsys.readouterr().out
    assert "objective 12" in out and "deviation" in out
    assert (tmp_path / "p.png").exists()


def test_a_solve_imports_no_scipy_and_leaves_cyipopt_whole(integrator, out_dir):
    """IPOPT's wrapper is loaded without cyipopt's SciPy interface (a third of a second of a
    process); a later `import cyipopt` gets the same Problem class and exception."""
    script = f"""
import sys
import sympy as sp
import lagrgen
model = lagrgen.Model("colloc_integrator")
x, = model.coordinates("x")
m, = model.parameters(m=1.0)
F, = model.inputs("F")
model.particle(m, sp.Matrix([x]))
model.generalized_force(x, F)
mod = lagrgen.build(model, out_dir={str(out_dir)!r})
prob = lagrgen.Collocation(mod, nodes=11, duration=1.0)
prob.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(integral=F ** 2)
res = prob.solve(progress=False)
assert abs(res.objective - 12.0) < 1e-8, res.objective
assert not [name for name in sys.modules if name.split(".")[0] == "scipy"]
import cyipopt
from cyipopt.exceptions import CyIpoptEvaluationError
assert cyipopt.Problem is sys.modules["ipopt_wrapper"].Problem
assert cyipopt.CyIpoptEvaluationError is CyIpoptEvaluationError
assert sys.modules["ipopt_wrapper"].CyIpoptEvaluationError is CyIpoptEvaluationError
print("ok")
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


# -- bad input ------------------------------------------------------------------------------
def test_bad_input_gets_clear_errors(integrator, out_dir):
    model, mod = integrator
    F, = model.input_functions
    x, = model.q
    with pytest.raises(LagrgenError, match="C backend"):
        lagrgen.Collocation(lagrgen.build(model, backend="python"), 11, 1.0)
    with pytest.raises(TypeError, match="built model"):
        lagrgen.Collocation(model, 11, 1.0)
    with pytest.raises(LagrgenError, match="at least 2"):
        lagrgen.Collocation(mod, 1, 1.0)
    with pytest.raises(LagrgenError, match="positive"):
        lagrgen.Collocation(mod, 11, -1.0)
    for pair in ((0.0, 3.0), (-1.0, 3.0), (2.0, 1.0)):   # a motion of no time has no least time
        with pytest.raises(LagrgenError, match="0 < lo < hi"):
            lagrgen.Collocation(mod, 11, pair)
    with pytest.raises(LagrgenError, match="scheme"):
        lagrgen.Collocation(mod, 11, 1.0, scheme="rk4")
    with pytest.raises(UnknownNameError):
        lagrgen.Collocation(mod, 11, 1.0, unknown_params=["mass"])
    prob = lagrgen.Collocation(mod, 11, 1.0)
    with pytest.raises(UnknownNameError, match="x_dot"):
        prob.bound("y", 0, 1)
    with pytest.raises(LagrgenError, match="lower bound exceeds"):
        prob.bound("F", 1, -1)
    with pytest.raises(LagrgenError, match="needs a bound"):
        prob.path(F ** 2)
    with pytest.raises(LagrgenError, match="free duration"):
        prob.minimize(time=True)
    with pytest.raises(LagrgenError, match="neither"):
        prob.path(sp.Symbol("z") * x, -1, 1)
    with pytest.raises(LagrgenError, match="shape"):
        prob.track([0.1, 0.2], [1.0, 2.0, 3.0], "x")
    with pytest.raises(LagrgenError, match="lie in"):
        prob.track([0.5, 2.0], [1.0, 2.0], "x")
    with pytest.raises(LagrgenError, match="outside"):
        prob.at(3.0, "x", 1.0)
    with pytest.raises(LagrgenError, match="no objective"):
        prob.solve(progress=False)
    with pytest.raises(LagrgenError, match="hessian"):
        prob.minimize(integral=F ** 2).solve(hessian="bfgs", progress=False)
    free = lagrgen.Collocation(mod, 11, (0.5, 2.0))
    with pytest.raises(LagrgenError, match="depends on t"):
        free.minimize(integral=model.t * F ** 2)
    with pytest.raises(LagrgenError, match="fixed duration"):
        free.track([0.1], [1.0], "x")
    bounded = lagrgen.Collocation(mod, 11, 1.0)
    bounded.bound("x", 0, 0.5).final(q=[1.0]).minimize(integral=F ** 2)
    with pytest.raises(LagrgenError, match="outside its bounds"):
        bounded.solve(progress=False)
    with pytest.raises(LagrgenError, match="decision vector"):
        effort_problem(mod, F, 11, "trapezoidal").solve(guess=np.zeros(3), progress=False)


def test_the_constructor_defaults_are_the_contracts(integrator):
    """API §18 shows Collocation(mod, nodes=101, duration=2.0, scheme="hermite-simpson",
    unknown_params=None): those are the defaults."""
    _, mod = integrator
    prob = lagrgen.Collocation(mod)
    assert prob.nodes == 101 and prob.duration_bounds == (2.0, 2.0)
    assert prob.scheme == "hermite-simpson" and prob.unknown == () and not prob.free_duration


def test_a_failed_solve_reports_the_objective_of_its_answer(out_dir):
    """Where IPOPT stops on an error (a path constraint that is NaN at the start: status -13),
    res.objective is the objective at the motion it returns (IPOPT says 0), not 0."""
    model = lagrgen.Model("colloc_nan_path")
    th, = model.coordinates("theta")
    T, = model.inputs("T")
    model.kinetic_energy(th.diff(model.t) ** 2 / 2)
    model.potential_energy(-9.81 * sp.cos(th))
    model.torque(T, th)
    mod = lagrgen.build(model, out_dir=out_dir)
    prob = lagrgen.Collocation(mod, nodes=21, duration=3.0)
    prob.bound("T", -15, 15).initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0])
    prob.minimize(integral=model.input_functions[0] ** 2)
    prob.path(sp.sqrt(th - 1), lo=0, hi=10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = prob.solve(progress=False, mesh_tol=None)
    assert not res.success and res.status < 0
    effort = float(res._transcription.objective(res.x))
    assert res.objective == effort and effort > 1.0
    assert abs(effort - np.trapezoid(res.u[0] ** 2, res.t)) < 0.05 * effort


def test_given_inputs_and_per_sample_weights_are_checked(integrator):
    """A known input outside the bounds given to it is a contradiction (it was solved as if the
    bound were absent, with a constraint violation of 0); one name's weights may be per sample."""
    model, mod = integrator
    F, = model.input_functions
    given = lagrgen.Collocation(mod, 11, 1.0)
    given.bound("F", 1.0, 2.0).input("F", 0.0)
    given.initial(q=[0.0], qd=[0.0]).minimize(integral=model.q[0] ** 2)
    with pytest.raises(LagrgenError, match="given values of input 'F'.*outside its bounds"):
        given.solve(progress=False)
    prob = lagrgen.Collocation(mod, 11, 1.0)
    t = np.linspace(0.0, 1.0, 5)
    prob.track(t, t ** 2, "x", weights=np.arange(1.0, 6.0))
    assert_allclose(prob._tracks[0][3], [np.arange(1.0, 6.0)])
    with pytest.raises(LagrgenError, match="weights"):
        prob.track(t, t ** 2, "x", weights=np.ones(3))
    with pytest.raises(LagrgenError, match="infinite; give a missing sample as NaN"):
        prob.track(t, np.r_[0.0, np.inf, 0.0, 1.0, np.nan], "x")


@COARSE
def test_check_converges_at_the_order_of_hermite_simpson(pendulums):
    """Hermite–Simpson takes the input quadratic on each interval (node, midpoint, node): the
    re-simulation of check() with that input deviates by the scheme's own O(h⁴) error (a cubic
    spline through all points made it O(h²), 10–200× too large on these grids)."""
    (model, mod), _ = pendulums
    F, = model.input_functions
    deviations = []
    for nodes in (11, 21):
        prob = lagrgen.Collocation(mod, nodes=nodes, duration=2.0)
        prob.initial(q=[0.0], qd=[0.0]).final(q=[0.8], qd=[0.0]).minimize(integral=F ** 2)
        res = prob.solve(progress=False, mesh_tol=None)
        assert res.success
        deviations.append(float(res.check()))
        u = res.input_signals()["F"]
        assert_allclose(u(res.t_points), res._point_values("u", 0), atol=1e-12)
    assert deviations[1] < deviations[0] / 10 and deviations[1] < 2e-4


@COARSE
def test_an_answer_at_ipopts_acceptable_level_says_so(integrator):
    """IPOPT's "Solved To Acceptable Level" (status 1) is a success looser than tol: the result
    says so in its notes (of a least-time problem, that its duration may be above the least by
    more); a solve to tol does not."""
    model, mod = integrator
    F, = model.input_functions
    loose = {"acceptable_tol": 1e3, "acceptable_iter": 1, "acceptable_constr_viol_tol": 1e3,
             "acceptable_dual_inf_tol": 1e10, "acceptable_compl_inf_tol": 1e3}
    res = effort_problem(mod, F, 11, "trapezoidal").solve(
        progress=False, mesh_tol=None, hessian="quasi-newton", tol=1e-12, options=loose)
    assert res.status == 1 and res.success
    said = [note for note in res.notes if "acceptable level" in note]
    assert len(said) == 1 and "optimal to about 1e-6" in said[0]
    fastest = lagrgen.Collocation(mod, nodes=11, duration=(0.5, 5.0), scheme="trapezoidal")
    fastest.bound("F", -1, 1).initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0])
    res = fastest.minimize(time=True).solve(progress=False, mesh_tol=None, options=loose)
    said = [note for note in res.notes if "acceptable level" in note]
    assert res.status == 1 and len(said) == 1 and "above the least" in said[0]
    assert "optimal to about 1e-6" not in said[0]
    res = effort_problem(mod, F, 11, "trapezoidal").solve(progress=False, mesh_tol=None)
    assert res.status == 0 and not any("acceptable level" in note for note in res.notes)
