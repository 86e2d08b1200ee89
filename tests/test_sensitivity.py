"""Issue 21: the parameter Jacobian ∂ẏ/∂p on both backends (constrained models included), forward
sensitivities against central differences and a closed form, and least-squares identification."""
import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model, UnknownNameError

from conftest import EXAMPLES, example_model

EXAMPLE_CHAIN = EXAMPLES / "two_mass_chain.py"


def damped_oscillator():
    model = Model("damped_osc")
    x, = model.coordinates("x", units="m")
    m, c, k = model.parameters(m=1.0, c=0.4, k=4.0)
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    model.damper(c, x)
    return model


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("sensitivity")
    models = {"osc": damped_oscillator(), "pendulum": example_model("double_pendulum"),
              "crank": example_model("slider_crank"),
              "chain": example_model("two_mass_chain", "absolute")}
    built = {(name, backend): lagrgen.build(model, out_dir=out, backend=backend)
             for name, model in models.items() for backend in ("python", "c")}
    for name in ("pendulum", "chain"):          # the same trees in the recursive formulation
        for backend in ("python", "c"):
            built[f"{name}-recursive", backend] = lagrgen.build(
                models[name], out_dir=out, backend=backend, formulation="recursive")
    return built


def central_parameter_jacobian(mod, t, y, p, u, h=1e-6):
    out = np.zeros((len(y), len(p)))
    for j in range(len(p)):
        step = h * max(1.0, abs(p[j]))
        e = np.zeros(len(p))
        e[j] = step
        out[:, j] = (mod.rhs(t, y, p + e, u) - mod.rhs(t, y, p - e, u)) / (2 * step)
    return out


@pytest.mark.parametrize("name", ["pendulum", "crank", "chain", "chain-recursive"])
@pytest.mark.parametrize("backend", ["python", "c"])
def test_parameter_jacobian_matches_central_differences(built, name, backend):
    mod = built[name, backend]
    rng = np.random.default_rng(7)
    n = mod.n_coordinates
    for _ in range(3):
        p = np.asarray(mod.defaults) * rng.uniform(0.8, 1.2, len(mod.defaults))
        u = rng.uniform(-1, 1, len(mod.inputs))
        y = np.concatenate([rng.uniform(-0.5, 0.5, n), rng.uniform(-1, 1, n)])
        if mod.n_constraints:
            y = lagrgen.consistent_state(mod, y, 0.3, p)
        J = mod.parameter_jacobian(0.3, y, p, u)
        assert J.shape == (2 * n, len(mod.parameters))
        assert np.all(J[:n] == 0.0)
        reference = central_parameter_jacobian(mod, 0.3, y, p, u)
        assert_allclose(J, reference, rtol=1e-6, atol=1e-6 * np.abs(reference).max())


def both_backends_at(built, name):
    """The C and Python builds of `name` and a (consistent) state to compare them at."""
    c, py = built[name, "c"], built[name, "python"]
    y = np.concatenate([np.full(c.n_coordinates, 0.3), np.full(c.n_coordinates, -0.2)])
    return c, py, lagrgen.consistent_state(c, y) if c.n_constraints else y


@pytest.mark.parametrize("name", ["pendulum", "crank", "pendulum-recursive"])
def test_parameter_jacobian_in_c_equals_python(built, name):
    c, py, y = both_backends_at(built, name)
    assert_allclose(c.parameter_jacobian(0.1, y), py.parameter_jacobian(0.1, y), rtol=1e-12,
                    atol=1e-12)


@pytest.mark.parametrize("name", ["pendulum", "crank", "chain", "pendulum-recursive",
                                  "chain-recursive"])
@pytest.mark.parametrize("backend", ["python", "c"])
def test_directional_derivatives_are_the_jacobian_products(built, name, backend):
    """ẏ and J·dy + ∂ẏ/∂p·dp along k directions (forward mode on the kernels) against the
    Jacobian and parameter Jacobian formed whole; one direction keeps its 1-D shape."""
    mod = built[name, backend]
    rng = np.random.default_rng(11)
    n, n_params = mod.n_coordinates, len(mod.parameters)
    p = np.asarray(mod.defaults) * rng.uniform(0.8, 1.2, n_params)
    u = rng.uniform(-1, 1, len(mod.inputs))
    y = np.concatenate([rng.uniform(-0.5, 0.5, n), rng.uniform(-1, 1, n)])
    if mod.n_constraints:
        y = lagrgen.consistent_state(mod, y, 0.3, p)
    dy, dp = rng.standard_normal((3, 2 * n)), rng.standard_normal((3, n_params))
    ydot, products = mod.directional_derivatives(0.3, y, dy, dp, p, u)
    expected = (dy @ mod.jacobian(0.3, y, p, u).T + dp @ mod.parameter_jacobian(0.3, y, p, u).T)
    assert_allclose(ydot, mod.rhs(0.3, y, p, u), rtol=1e-13, atol=1e-13)
    assert products.shape == (3, 2 * n)
    assert_allclose(products, expected, rtol=1e-10, atol=1e-11 * np.abs(expected).max())
    one = mod.directional_derivatives(0.3, y, dy[1], p=p, u=u)[1]
    assert one.shape == (2 * n,)
    assert_allclose(one, dy[1] @ mod.jacobian(0.3, y, p, u).T, rtol=1e-10,
                    atol=1e-11 * np.abs(expected).max())
    with pytest.raises(ValueError, match="dy must have shape"):
        mod.directional_derivatives(0.3, y, np.ones(2 * n + 1))
    with pytest.raises(ValueError, match="dp must have shape"):
        mod.directional_derivatives(0.3, y, dy, np.ones((2, n_params + 1)))


@pytest.mark.parametrize("name", ["pendulum", "crank", "pendulum-recursive"])
def test_directional_derivatives_in_c_equal_python(built, name):
    c, py, y = both_backends_at(built, name)
    dy = np.linspace(-1, 1, 4 * c.n_coordinates).reshape(2, -1)
    dp = np.linspace(1, 2, 2 * len(c.parameters)).reshape(2, -1)
    for a, b in zip(c.directional_derivatives(0.1, y, dy, dp),
                    py.directional_derivatives(0.1, y, dy, dp)):
        assert_allclose(a, b, rtol=1e-12, atol=1e-12)


def closed_form_x(t, k, c, m=1.0):
    """x(t) of m·ẍ + c·ẋ + k·x = 0 from x = 1, ẋ = 0 (underdamped)."""
    wn = np.sqrt(k / m)
    zeta = c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta ** 2)
    return np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))


@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "BDF"])
@pytest.mark.parametrize("backend", ["python", "c"])
def test_sensitivities_match_the_closed_form_and_central_differences(built, method, backend):
    mod = built["osc", backend]
    t = np.linspace(0, 5, 11)
    sol = lagrgen.simulate(mod, (0, 5), [1.0, 0.0], method=method, t_eval=t, rtol=1e-10,
                           atol=1e-12, sensitivities=["k", "c", "y0:x"])
    assert sol.sensitivities.shape == (3, 2, 11) and sol.y.shape == (2, 11)
    assert_allclose(sol.y[0], closed_form_x(t, 4.0, 0.4), atol=1e-7)
    h = 1e-6
    dx_dk = (closed_form_x(t, 4.0 + h, 0.4) - closed_form_x(t, 4.0 - h, 0.4)) / (2 * h)
    dx_dc = (closed_form_x(t, 4.0, 0.4 + h) - closed_form_x(t, 4.0, 0.4 - h)) / (2 * h)
    tol = 2e-5 if method == "BDF" else 1e-6
    assert_allclose(sol.sensitivities[0, 0], dx_dk, atol=tol)
    assert_allclose(sol.sensitivities[1, 0], dx_dc, atol=tol)
    assert_allclose(sol.sensitivities[2, 0], closed_form_x(t, 4.0, 0.4), atol=tol)  # ∂x/∂x0


@pytest.mark.parametrize("engine", ["native", "scipy"])
def test_dense_output_with_sensitivities_gives_the_states(built, engine):
    """sol.sol(t) of a run with sensitivities returned the augmented state (states, then the
    sensitivities: 8 rows for 2 states); it gives the states as sol.y holds them, and
    sol.sol.sensitivities(t) the rest."""
    mod = built["osc", "c"]
    sol = lagrgen.simulate(mod, (0, 5), [1.0, 0.0], t_eval=[0.0, 2.5, 5.0], rtol=1e-10,
                           atol=1e-12, sensitivities=["k", "c"], dense_output=True,
                           engine=engine)
    assert sol.sol(2.5).shape == (2,) and sol.sol([1.0, 2.5]).shape == (2, 2)
    assert_allclose(sol.sol(2.5), sol.y[:, 1], atol=1e-9)
    assert sol.sol.sensitivities(2.5).shape == (2, 2)
    assert_allclose(sol.sol.sensitivities([2.5, 5.0]), sol.sensitivities[:, :, 1:], atol=1e-9)


def test_sensitivities_of_a_constrained_model_match_central_differences(built):
    mod = built["crank", "c"]
    y0 = lagrgen.consistent_state(mod, np.r_[np.full(mod.n_coordinates, 0.2),
                                             np.zeros(mod.n_coordinates)])
    t = np.linspace(0, 1, 6)
    name = mod.parameters[0]
    sol = lagrgen.simulate(mod, (0, 1), y0, method="DOP853", t_eval=t, rtol=1e-10, atol=1e-12,
                           sensitivities=[name])
    h = 1e-5 * max(1.0, abs(mod.defaults[0]))
    runs = [lagrgen.simulate(mod, (0, 1), y0, method="DOP853", t_eval=t, rtol=1e-12,
                             atol=1e-14, params={name: mod.defaults[0] + s}).y for s in (h, -h)]
    reference = (runs[0] - runs[1]) / (2 * h)
    assert_allclose(sol.sensitivities[0], reference, atol=1e-5 * max(1, np.abs(reference).max()))


def test_sensitivity_names_are_checked(built):
    mod = built["osc", "c"]
    with pytest.raises(UnknownNameError, match="unknown parameter name 'kk'"):
        lagrgen.simulate(mod, (0, 1), [1.0, 0.0], sensitivities=["kk"])
    with pytest.raises(UnknownNameError, match="unknown state name 'q'"):
        lagrgen.simulate(mod, (0, 1), [1.0, 0.0], sensitivities=["y0:q"])
    with pytest.raises(ValueError, match="at least one"):
        lagrgen.simulate(mod, (0, 1), [1.0, 0.0], sensitivities=[])


@pytest.mark.parametrize("method", ["DOP853", "Radau", "BDF"])
def test_native_sensitivities_equal_the_scipy_engines(built, method):
    mod = built["pendulum", "c"]
    t = np.linspace(0, 2, 9)
    runs = [lagrgen.simulate(mod, (0, 2), [0.4, -0.2, 0.0, 0.3], method=method, t_eval=t,
                             rtol=1e-9, atol=1e-11, sensitivities=["m1", "L2", "y0:theta1"],
                             engine=engine, inputs={"F": 0.2}) for engine in ("native", "scipy")]
    assert [r.engine for r in runs] == ["native", "scipy"]
    scale = np.abs(runs[1].sensitivities).max()
    assert_allclose(runs[0].sensitivities, runs[1].sensitivities, atol=1e-6 * scale)
    assert_allclose(runs[0].y, runs[1].y, atol=1e-8)


@pytest.mark.parametrize("backend", ["python", "c"])
def test_recursive_sensitivities_equal_the_dense_ones(built, backend):
    """The same pendulum in both formulations: ẏ, J·dy + ∂ẏ/∂p·dp to round-off, and the
    sensitivities integrated with them (native engine for C) to the integration's tolerance."""
    dense, recursive = built["pendulum", backend], built["pendulum-recursive", backend]
    assert (dense.formulation, recursive.formulation) == ("dense", "recursive")
    y = np.array([0.4, -0.2, 0.1, 0.3])
    dy = np.linspace(-1, 1, 36).reshape(9, 4)
    dp = np.linspace(1, 2, 9 * len(dense.parameters)).reshape(9, -1)
    for a, b in zip(recursive.directional_derivatives(0.1, y, dy, dp, u=[0.2]),
                    dense.directional_derivatives(0.1, y, dy, dp, u=[0.2])):
        assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
    t = np.linspace(0, 2, 9)
    runs = [lagrgen.simulate(mod, (0, 2), y, method="DOP853", t_eval=t, rtol=1e-10, atol=1e-12,
                             sensitivities=["m1", "L2", "y0:theta1"], inputs={"F": 0.2})
            for mod in (recursive, dense)]
    assert_allclose(runs[0].sensitivities, runs[1].sensitivities,
                    atol=1e-7 * np.abs(runs[1].sensitivities).max())


# -- identification ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def chain_data(built):
    mod = built["chain", "c"]
    t = np.linspace(0, 10, 201)
    y0 = [0.1, -0.05, 0.0, 0.0]
    truth = lagrgen.simulate(mod, (0, 10), y0, method="DOP853", t_eval=t, rtol=1e-10,
                             atol=1e-12)
    rng = np.random.default_rng(3)
    return mod, t, y0, truth.y[:2] + 1e-3 * rng.standard_normal((2, t.size))


def test_fit_recovers_stiffness_and_damping_within_their_standard_errors(chain_data):
    mod, t, y0, data = chain_data
    names = ["k1", "k2", "c1", "c2"]
    true = {n: mod.defaults[list(mod.parameters).index(n)] for n in names}
    fit = lagrgen.fit(mod, t, data, names, y0, initial={n: 1.3 * v for n, v in true.items()},
                      method="DOP853", rtol=1e-9, atol=1e-11)
    assert fit.success and fit.cov.shape == (4, 4) and fit.residuals.shape == data.shape
    for n in names:
        assert abs(fit.params[n] - true[n]) < 4 * fit.stderr[n], n
        assert 0 < fit.stderr[n] < 0.05 * true[n]
    assert np.sqrt(2 * fit.cost / data.size) == pytest.approx(1e-3, rel=0.2)


def test_fit_an_initial_state_and_a_velocity_record(chain_data):
    mod, t, y0, data = chain_data
    velocity = lagrgen.simulate(mod, (0, 10), y0, method="DOP853", t_eval=t, rtol=1e-10,
                                atol=1e-12).y[2]
    fit = lagrgen.fit(mod, t, velocity, ["k1", "y0:x1"], y0, measured=["x1_dot"],
                      initial={"k1": 35.0, "y0:x1": 0.08}, bounds={"k1": (1.0, 100.0)},
                      method="DOP853", rtol=1e-10, atol=1e-12)
    assert fit.params["k1"] == pytest.approx(40.0, rel=1e-5)
    assert fit.params["y0:x1"] == pytest.approx(0.1, rel=1e-5)


def test_fit_explains_bad_input(chain_data):
    mod, t, y0, data = chain_data
    with pytest.raises(UnknownNameError, match="unknown parameter name 'k9'"):
        lagrgen.fit(mod, t, data, ["k9"], y0)
    with pytest.raises(UnknownNameError, match="unknown measured name 'x3'"):
        lagrgen.fit(mod, t, data, ["k1"], y0, measured=["x1", "x3"])
    with pytest.raises(ValueError, match=r"data must have shape \(len\(measured\), len\(t\)\)"):
        lagrgen.fit(mod, t, data[:, :-1], ["k1"], y0)
    with pytest.raises(ValueError, match="increasing sample times"):
        lagrgen.fit(mod, t[::-1], data, ["k1"], y0)


def test_fit_modes_recovers_two_stiffnesses_from_measured_frequencies(built):
    mod = built["chain", "c"]
    true = lagrgen.modes(mod, [0.0, 0.0])
    update = lagrgen.fit_modes(mod, [0.0, 0.0], true.frequencies_hz, ["k1", "k2"],
                               initial={"k1": 25.0, "k2": 40.0})
    assert update.success
    assert update.params["k1"] == pytest.approx(40.0, rel=1e-6)
    assert update.params["k2"] == pytest.approx(25.0, rel=1e-6)
    assert_allclose(update.frequencies_hz, true.frequencies_hz, rtol=1e-8)
    swapped = lagrgen.fit_modes(mod, [0.0, 0.0], true.frequencies_hz[::-1], ["k1", "k2"],
                                shapes=true.shapes[:, ::-1], initial={"k1": 35.0, "k2": 30.0})
    assert swapped.pairing == (1, 0)
    assert swapped.params["k1"] == pytest.approx(40.0, rel=1e-6)


def test_fit_command_prints_estimates_and_plots(chain_data, tmp_path, capsys):
    import csv
    from lagrgen.cli import main
    mod, t, y0, data = chain_data
    record = tmp_path / "run.csv"
    with open(record, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(["t [s]", "x1 [m]", "x2 [m]"])
        writer.writerows(zip(t, *data))
    status = main(["fit", str(EXAMPLE_CHAIN), "--model", "two_mass_absolute", "--data",
                   str(record), "--params", "k1,k2,y0:x1,y0:x2", "--initial", "k1=30,k2=30",
                   "--plot", str(tmp_path / "fit.png"), "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert status == 0 and "fit of k1, k2, y0:x1, y0:x2 to x1, x2 (402 samples" in out
    estimates = dict(line.split("=") for line in out.splitlines()[1:])
    k1, k1_err = (float(v) for v in estimates["  k1    "].split("±"))
    assert abs(k1 - 40.0) < 4 * k1_err and (tmp_path / "fit.png").stat().st_size > 10_000
    assert main(["fit", str(EXAMPLE_CHAIN), "--model", "two_mass_absolute", "--data",
                 str(record), "--params", "k9", "--out", str(tmp_path)]) == 1
    assert "unknown parameter name 'k9'" in capsys.readouterr().err
