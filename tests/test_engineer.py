"""Issue 13, the engineer's view: outputs and energies, discontinuous forces, the integration guard,
linearization at a frozen time and state-space form, units, and the CLI edges."""
import csv
import io
import subprocess
import sys
import warnings

import numpy as np
import pytest
import sympy as sp

import lagrgen
from lagrgen import Model
from lagrgen.errors import ModelError

from conftest import BACKENDS


def oscillator_model():
    """Two masses, springs and dampers, a force input F: every automatic output is exercised."""
    m = Model("eng_osc")
    x1, x2 = m.coordinates("x1 x2", units="m m")
    m1, m2, k1, k2, c1, c2 = m.parameters(m1=(1.0, "kg"), m2=(2.0, "kg"), k1=(10.0, "N/m"),
                                          k2=(5.0, "N/m"), c1=0.4, c2=0.2)
    F, = m.inputs("F", units="N")
    m.particle(m1, [x1])
    m.particle(m2, [x2])
    m.spring(k1, x1)
    m.spring(k2, x2 - x1)
    m.damper(c1, x1)
    m.damper(c2, x2 - x1)
    m.force([F], at=[x2])
    m.output("stretch", x2 - x1, units="m")
    m.output("spring_force", k2 * (x2 - x1), units="N")
    return m


def switching_model():
    """Every discontinuous function, of q, q̇ and t."""
    m = Model("eng_switch")
    x, = m.coordinates("x")
    t = m.t
    k, mu = m.parameters(k=3.0, mu=0.5)
    m.particle(1, [x])
    m.potential_energy(k * sp.Max(0, x - 0.5) ** 2 / 2)            # a one-sided stop at x = 0.5
    xd = x.diff(t)
    m.generalized_force(x, -mu * sp.sign(xd) + sp.Heaviside(t - 1) + sp.sign(t - 2) * sp.Abs(x)
                        + sp.Min(x, t, 0.3) + sp.Piecewise((sp.sin(t), x < 0.1), (x ** 2, x < 0.7),
                                                           (1.0, True)))
    m.output("gap", 0.5 - x, units="m")
    return m


def rheonomic_model():
    m = Model("eng_rheo")
    y, = m.coordinates("y")
    m.particle(1, [y])
    m.spring(4, y - sp.sin(m.t))
    m.potential_energy(sp.cos(m.t) * y ** 4)
    return m


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("eng")
    cache = {}

    def get(make, backend):
        key = (make.__name__, backend)
        if key not in cache:
            cache[key] = lagrgen.build(make(), out_dir=out, backend=backend)
        return cache[key]
    return get


# -- 1. outputs ---------------------------------------------------------------------------------
@pytest.mark.parametrize("backend", BACKENDS)
def test_output_names_and_energies_match_hand_formulas(built, backend):
    mod = built(oscillator_model, backend)
    assert mod.output_names == ("stretch", "spring_force", "kinetic_energy", "potential_energy",
                                "total_energy")
    x1, x2, v1, v2, F = 0.3, -0.2, 1.5, -0.7, 2.5
    m1, m2, k1, k2, c1, c2 = mod.defaults
    out = mod.outputs(0.0, np.array([x1, x2, v1, v2]), u=[F])
    T = m1 * v1 ** 2 / 2 + m2 * v2 ** 2 / 2
    V = k1 * x1 ** 2 / 2 + k2 * (x2 - x1) ** 2 / 2
    R = c1 * v1 ** 2 / 2 + c2 * (v2 - v1) ** 2 / 2
    expected = [x2 - x1, k2 * (x2 - x1), T, V, T + V]
    assert out.shape == (5,) and out.dtype == np.float64
    np.testing.assert_allclose(out, expected, rtol=1e-14, atol=1e-14)
    power = mod.power_terms(0.0, np.array([x1, x2, v1, v2]), u=[F])
    np.testing.assert_allclose(power, [F * v2, R], rtol=1e-14, atol=1e-14)


def test_outputs_are_the_same_on_both_backends(built):
    c, py = built(oscillator_model, "c"), built(oscillator_model, "python")
    rng = np.random.default_rng(3)
    for _ in range(5):
        y, u, t = rng.normal(size=4), rng.normal(size=1), rng.normal()
        np.testing.assert_allclose(c.outputs(t, y, u=u), py.outputs(t, y, u=u), rtol=1e-13,
                                   atol=1e-14)


@pytest.mark.parametrize("backend", BACKENDS)
def test_power_balance_closes_along_a_solution(built, backend):
    """E(t) − E(0) = ∫ (P_in − 2R) dt for a damped, forced system (trapezoid on a fine grid)."""
    mod = built(oscillator_model, backend)
    t = np.linspace(0.0, 4.0, 4001)
    sol = lagrgen.simulate(mod, (0.0, 4.0), [0.5, -0.2, 0.0, 1.0], method="DOP853",
                           inputs={"F": lambda s: np.sin(3 * s)}, t_eval=t, rtol=1e-11,
                           atol=1e-12)
    out = lagrgen.evaluate_outputs(mod, sol)
    assert out.shape == (len(mod.output_names) + 2, len(t))
    E, P, R = out["total_energy"], out["input_power"], out["rayleigh_dissipation"]
    rate = P - 2 * R
    integral = np.concatenate([[0.0], np.cumsum((rate[1:] + rate[:-1]) / 2 * np.diff(t))])
    assert np.max(np.abs(E - E[0] - integral)) < 1e-5 * np.max(np.abs(E))
    # with no input the energy falls monotonically (dissipation only)
    free = lagrgen.simulate(mod, (0.0, 4.0), [0.5, -0.2, 0.0, 1.0], t_eval=t[::100], rtol=1e-10,
                            atol=1e-12)
    energy = lagrgen.evaluate_outputs(mod, free)["total_energy"]
    assert np.all(np.diff(energy) < 0) and energy[-1] < 0.5 * energy[0]


def test_output_declaration_errors():
    m = Model("eng_bad")
    x, = m.coordinates("x")
    with pytest.raises(ModelError, match="provided automatically"):
        m.output("total_energy", x)
    m.output("tip", x)
    with pytest.raises(ModelError, match="already used"):
        m.output("tip", 2 * x)
    with pytest.raises(ModelError, match="scalar"):
        m.output("both", sp.Matrix([x, x]))
    with pytest.raises(ModelError, match="neither"):
        m.output("bad", sp.Symbol("zeta") * x)


# -- 2. discontinuous forces --------------------------------------------------------------------
SWITCH_POINTS = [  # (t, x, xdot): at and next to every switching surface
    (t, x, v) for t in (0.0, 1.0, 1.0 - 1e-12, 1.0 + 1e-12, np.float64(2.0), 2.0 + 1e-9, 0.3)
    for x in (0.1, 0.1 - 1e-13, 0.5, 0.5 + 1e-12, 0.7, 0.3, 0.3 + 1e-14, -0.4)
    for v in (0.0, 1e-15, -1e-15, -1.0)]


def test_discontinuous_functions_agree_on_both_backends(built):
    c, py = built(switching_model, "c"), built(switching_model, "python")
    for t, x, v in SWITCH_POINTS:
        y = np.array([x, v])
        for name in ("rhs", "jacobian", "outputs"):
            a, b = getattr(c, name)(t, y), getattr(py, name)(t, y)
            np.testing.assert_array_equal(a, b, err_msg=f"{name} at t={t}, x={x}, v={v}")


@pytest.mark.parametrize("backend", BACKENDS)
def test_discontinuous_values_follow_sympy(built, backend):
    """The rhs against SymPy's own evaluation, including Heaviside(0) = ½ and sign(0) = 0."""
    mod = built(switching_model, backend)
    m = switching_model()
    F = m.forcing()[0]
    x = m.q[0]
    for t, xv, v in [(1.0, 0.1, 0.0), (2.0, 0.5, 1e-15), (1.0 + 1e-12, 0.7, -1.0), (0.3, 0.8, 0)]:
        value = float(F.subs({x.diff(m.t): v}).subs({x: xv, m.t: t,
                                                     sp.Symbol("k"): 3.0, sp.Symbol("mu"): 0.5}))
        assert mod.rhs(np.float64(t), [xv, v])[1] == pytest.approx(value, rel=1e-13, abs=1e-15)


def test_python_backend_sign_of_time_does_not_crash(built):
    mod = built(switching_model, "python")
    for t in (np.float64(2.0), np.float32(1.5), 3):
        assert np.all(np.isfinite(mod.rhs(t, np.array([0.2, 0.1]))))


@pytest.mark.parametrize("backend", BACKENDS)
def test_guard_stops_a_long_integration_with_the_partial_result(built, backend):
    mod = built(switching_model, backend)
    sol = lagrgen.simulate(mod, (0.0, 50.0), [0.0, 1.0], max_steps=25,
                           t_eval=np.linspace(0, 50, 5001))
    assert not sol.success and sol.status == -1 and "max_steps=25" in sol.guard
    assert "max_steps=25" in sol.message and 0 < sol.t[-1] < 50 and sol.y.shape[1] == len(sol.t)
    assert sol.t_events is None or len(sol.t_events) == 0
    timed = lagrgen.simulate(mod, (0.0, 1e6), [0.0, 1.0], max_wall_time=0.2)
    assert "max_wall_time" in timed.guard and timed.t[-1] < 1e6
    full = lagrgen.simulate(mod, (0.0, 0.5), [0.0, 1.0], max_steps=10_000)
    assert full.success and full.guard is None and full.t[-1] == 0.5
    with pytest.raises(ValueError, match="max_steps"):
        lagrgen.simulate(mod, (0.0, 1.0), [0.0, 1.0], max_steps=0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_output_event_finds_the_contact(built, backend):
    mod = built(switching_model, backend)
    event = lagrgen.output_event(mod, "gap", terminal=True, direction=-1)
    sol = lagrgen.simulate(mod, (0.0, 10.0), [0.0, 1.0], events=[event], rtol=1e-10, atol=1e-12)
    assert sol.status == 1 and sol.y_events[0][0][0] == pytest.approx(0.5, abs=1e-9)
    with pytest.raises(lagrgen.UnknownNameError):
        lagrgen.output_event(mod, "nope")


def test_coulomb_friction_example_loses_four_mu_g_over_k_per_cycle():
    """Classic result: each half cycle the amplitude drops by 2·μ·m·g/k (events at v = 0)."""
    from conftest import load_example
    ex = load_example("coulomb_friction")
    mod = lagrgen.build(ex.model, backend="python")
    turns = ex.turning_points(mod, x0=1.0, t_end=20.0)
    x = np.array(turns)
    p = dict(zip(mod.parameters, mod.defaults))
    band = p["mu"] * p["m"] * p["g"] / p["k"]
    assert len(x) >= 10
    # each half cycle is harmonic about +band (x > 0) or −band: x_next = −x + 2·band·sign(x)
    np.testing.assert_allclose(x[1:], -x[:-1] + 2 * band * np.sign(x[:-1]), rtol=0, atol=1e-8)
    assert abs(x[-1]) <= band and abs(x[-2]) > band   # it sticks at the first stop inside


# -- 3. linearization at a frozen time ----------------------------------------------------------
@pytest.mark.parametrize("backend", BACKENDS)
def test_rheonomic_model_warns_and_freezes_time(built, backend):
    mod = built(rheonomic_model, backend)
    assert mod.explicit_time
    with pytest.warns(lagrgen.FrozenTimeWarning, match="frozen time t = 0.7"):
        q0 = lagrgen.equilibrium(mod, [0.0], t=0.7)
    assert q0[0] == pytest.approx(np.sin(0.7) - np.cos(0.7) * q0[0] ** 3 / 1, abs=1e-8)
    with pytest.warns(lagrgen.FrozenTimeWarning):
        lin = lagrgen.linearize(mod, q0, t=0.7)
    assert lin.K[0, 0] == pytest.approx(4 + 12 * np.cos(0.7) * q0[0] ** 2, rel=1e-12)
    with pytest.warns(lagrgen.FrozenTimeWarning, match="modal analysis"):
        res = lagrgen.modes(mod, t=0.7)
    assert res.omega[0] == pytest.approx(np.sqrt(lin.K[0, 0]), rel=1e-9)
    steady = built(oscillator_model, backend)
    assert not steady.explicit_time
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lagrgen.modes(steady)


@pytest.mark.parametrize("backend", BACKENDS)
def test_state_space(built, backend):
    mod = built(oscillator_model, backend)
    lin = lagrgen.linearize(mod, [0.0, 0.0])
    ss = lin.state_space()
    from scipy.signal import StateSpace
    assert isinstance(ss, StateSpace)
    M, K, C, B = lin.M, lin.K, lin.C, lin.B
    np.testing.assert_allclose(ss.A[2:, :2], -np.linalg.solve(M, K))
    np.testing.assert_allclose(ss.A[2:, 2:], -np.linalg.solve(M, C))
    np.testing.assert_allclose(ss.A[:2], np.hstack([np.zeros((2, 2)), np.eye(2)]))
    np.testing.assert_allclose(ss.B[:, 0], [0, 0, 0, 1 / 2.0])
    np.testing.assert_allclose(ss.C, np.eye(4))
    np.testing.assert_allclose(ss.D, np.zeros((4, 1)))
    assert lin.state_names == ("x1", "x2", "x1_dot", "x2_dot")
    # the static gain of δx2 to a unit force: K⁻¹·B
    gain = -ss.C @ np.linalg.solve(ss.A, ss.B)
    np.testing.assert_allclose(gain[:2, 0], np.linalg.solve(K, B[:, 0]), rtol=1e-12)


# -- 4. units -----------------------------------------------------------------------------------
@pytest.mark.parametrize("backend", BACKENDS)
def test_units_reach_built_models_and_never_change_numbers(built, backend):
    mod = built(oscillator_model, backend)
    assert mod.units == {"x1": "m", "x2": "m", "m1": "kg", "m2": "kg", "k1": "N/m", "k2": "N/m",
                         "F": "N", "stretch": "m", "spring_force": "N", "kinetic_energy": "J",
                         "potential_energy": "J", "total_energy": "J"}   # energies: read off
    np.testing.assert_array_equal(mod.defaults, [1.0, 2.0, 10.0, 5.0, 0.4, 0.2])


def test_unit_errors():
    m = Model("eng_units")
    with pytest.raises(ModelError, match="one unit per name"):
        m.coordinates("x y", units="m")
    with pytest.raises(ModelError, match="without spaces"):
        m.inputs("F", units=["N m"])
    with pytest.raises(ModelError, match="default"):
        m.parameters(k=(1.0, "N", 3))


#: Labels that are no unit (issue 37.4): one that runs code if evaluated, Python values that are
#: not expressions, labels that do not tokenize, and a number too large to compute.
HOSTILE_LABELS = ('__import__("pathlib").Path("PWNED").touch()', '"abc"', "[1,2]",
                  "(1).__class__", "]]>", "<![CDATA[x", "10^(10^10)", "m^", "((m)", "N/0")


def test_unit_labels_are_read_by_a_grammar_never_evaluated(tmp_path, monkeypatch):
    """A label is inert text: read by the unit grammar, and "no unit" when it cannot be read;
    the labels a model gives still label it, verbatim, in C metadata as in Python."""
    from lagrgen.dimensions import read_unit, unit_quantity
    import sympy.physics.units as u
    monkeypatch.chdir(tmp_path)
    for label in HOSTILE_LABELS:
        assert read_unit(label) is None and unit_quantity(label) is None, label
    assert not (tmp_path / "PWNED").exists()
    assert read_unit("kg*m^2/s^2") == u.kilogram * u.meter ** 2 / u.second ** 2
    assert read_unit("N*s/m") == u.newton * u.second / u.meter
    assert read_unit("s^-1") == read_unit("s**(-1)") == read_unit("1/s") == 1 / u.second
    assert read_unit("(m/s)^2") == u.meter ** 2 / u.second ** 2
    assert read_unit("1e-3*m") == u.meter / 1000
    model = Model("hostile_units")
    names = [f"x{i}" for i in range(len(HOSTILE_LABELS))]
    xs = model.coordinates(names, units=list(HOSTILE_LABELS))
    k, = model.parameters(k=(2.0, "N/m"))
    for x in xs:
        model.particle(1, [x])
        model.spring(k, x)
    for backend in ("python", "c"):
        mod = lagrgen.build(model, backend=backend, out_dir=tmp_path / "out", quiet=True)
        assert mod.units == {**dict(zip(names, HOSTILE_LABELS)), "k": "N/m"}
        assert mod.rhs(0.0, np.r_[np.ones(len(names)), np.zeros(len(names))])[-1] == -2.0
    assert not (tmp_path / "PWNED").exists()


def test_csv_headers_and_plot_panels_carry_units(built):
    from lagrgen.cli.simulate import write_csv
    from lagrgen.outputs.plotting import plot_time_history
    mod = built(oscillator_model, "python")
    model = oscillator_model()
    sol = lagrgen.simulate(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 0.5, 1])
    stream = io.StringIO()
    write_csv(stream, sol, model.coordinate_names, lagrgen.evaluate_outputs(mod, sol), model.units)
    header = next(csv.reader(io.StringIO(stream.getvalue())))
    assert header[:5] == ["t [s]", "x1 [m]", "x2 [m]", "x1_dot [m/s]", "x2_dot [m/s]"]
    assert "spring_force [N]" in header and "kinetic_energy" in header
    fig = plot_time_history(sol, model.coordinate_names, units=model.units)
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["[m]", "[m/s]"]


# -- 6. command line ----------------------------------------------------------------------------
def run(*args, cwd, check=True, stdin=None):
    proc = subprocess.run([sys.executable, "-m", "lagrgen", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=120)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


FORCED = """import sympy as sp
from lagrgen import Model
model = Model('eng_cli')
x, = model.coordinates('x', units='m')
m, k = model.parameters(m=(1.0, 'kg'), k=(4.0, 'N/m'))
F, G = model.inputs('F G', units='N N')
model.particle(m, [x])
model.spring(k, x)
model.generalized_force(x, F + G)
model.output('tip_x', 2*x, units='m')
"""


def test_split_items():
    from lagrgen.cli.arguments import assignments
    assert assignments(["F=Max(0,t-0.5);G=1", "H=2,K=Min(1,2)"], "--inputs") == {
        "F": "Max(0,t-0.5)", "G": "1", "H": "2", "K": "Min(1,2)"}


def test_cli_inputs_with_commas_csv_to_stdout_and_outputs(tmp_path):
    (tmp_path / "m.py").write_text(FORCED)
    proc = run("simulate", "m.py", "--backend", "python", "--t-end", 2, "--samples", 5,
               "--inputs", "F=Max(0,t-0.5)", "--inputs", "G=Heaviside(t-1)", "--csv", "-",
               "--plot", "h.png", "--plot-outputs", "energy,tip_x", cwd=tmp_path)
    rows = list(csv.reader(io.StringIO(proc.stdout)))
    assert rows[0][:3] == ["t [s]", "x [m]", "x_dot [m/s]"] and "tip_x [m]" in rows[0]
    assert not (tmp_path / "-").exists() and (tmp_path / "h_outputs.png").stat().st_size > 0
    last = dict(zip(rows[0], map(float, rows[-1])))
    assert last["tip_x [m]"] == pytest.approx(2 * last["x [m]"])
    bad = run("simulate", "m.py", "--backend", "python", "--t-end", 1, "--inputs",
              "F=frobnicate(t)", cwd=tmp_path, check=False)
    assert bad.returncode == 1 and "Traceback" not in bad.stderr and "frobnicate" in bad.stderr
    bad = run("simulate", "m.py", "--backend", "python", "--t-end", 1, "--plot-outputs", "nope",
              cwd=tmp_path, check=False)
    assert bad.returncode == 1 and "no output 'nope'" in bad.stderr


def test_cli_closed_pipe_ends_quietly(tmp_path):
    (tmp_path / "m.py").write_text(FORCED)
    cmd = (f"{sys.executable} -m lagrgen simulate m.py --backend python --t-end 5 "
           "--samples 200000 --y0 0.1 | head -n 2")
    proc = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.stdout.count("\n") == 2 and proc.stderr == "" and proc.returncode == 0


def test_cli_guard_and_frozen_time(tmp_path):
    (tmp_path / "m.py").write_text(FORCED)
    proc = run("simulate", "m.py", "--backend", "python", "--t-end", 20, "--y0", 1,
               "--max-steps", 40, "--csv", "out.csv", cwd=tmp_path, check=False)
    assert proc.returncode == 1 and "max_steps=40" in proc.stderr and "partial" in proc.stderr
    assert 2 < len((tmp_path / "out.csv").read_text().splitlines()) < 502
    (tmp_path / "r.py").write_text(
        "import sympy as sp\nfrom lagrgen import Model\nmodel = Model('eng_rheo_cli')\n"
        "y, = model.coordinates('y', units='m')\nmodel.particle(1, [y])\n"
        "model.spring(4, y - sp.sin(model.t))\n")
    proc = run("modes", "r.py", "--backend", "python", "--t", "0.5", cwd=tmp_path)
    assert "frozen time t = 0.5" in proc.stderr and "y = 0.479426 m" in proc.stdout


# -- energies of every example against the hand formulas of test_physics ---------------------------
def test_example_energies_and_power_match_hand_formulas(tmp_path):
    """total_energy and input_power − 2R of every example equal test_physics' hand-written E and
    power (which already checks dE/dt = power) at random states, both backends."""
    from test_physics import POWER_CASES
    from conftest import example_model, random_point
    rng = np.random.default_rng(7)
    for name, (entry, energy, power) in sorted(POWER_CASES.items()):
        model = example_model(*entry)
        for backend in BACKENDS:
            mod = lagrgen.build(model, backend=backend, out_dir=tmp_path)
            n = mod.n_coordinates
            q, qd, t, p, u = random_point(mod, rng)
            y = np.concatenate([q, qd])
            out = dict(zip(mod.output_names + ("input_power", "rayleigh_dissipation"),
                           [*mod.outputs(t, y, p, u), *mod.power_terms(t, y, p, u)]))
            assert out["total_energy"] == pytest.approx(energy(q, qd, p, u), rel=1e-12, abs=1e-12)
            assert out["input_power"] - 2 * out["rayleigh_dissipation"] == pytest.approx(
                power(q, qd, p, u), rel=1e-12, abs=1e-12), name
            assert n == len(q)


# -- 5. pictures ----------------------------------------------------------------------------------
def test_pictures_show_shapes_masses_dampers_and_distinct_positions():
    from conftest import example_model
    from lagrgen.outputs.plotting import Scene, drawable_tracks, marker_sizes, new_figure
    model = example_model("rolling_chain")
    p = np.array(lagrgen.build(model, backend="python").defaults)
    times = np.array([0.0, 0.5])
    q = np.array([[0.0, 0.1], [0.0, -0.1], [0.0, 0.3]])
    tracks = drawable_tracks(model, p, times, q)
    kinds = [k for k, _ in tracks]
    assert kinds.count("point") == 2 and kinds.count("body") == 1 and kinds.count("damper") == 3
    xs = sorted(data[0][0, 0] for k, data in tracks if k in ("point", "body"))
    assert np.min(np.diff(xs)) >= 0.9                     # the chain is spread out along the line
    sizes = [s for s in marker_sizes(tracks) if s is not None]
    assert sizes[0] < sizes[1] < sizes[2]                   # m1 < m2 < m3: bigger markers
    fig = new_figure(4, 4)
    ax = fig.add_subplot(1, 1, 1)
    scene = Scene(ax, tracks, 4.0)
    body = kinds.index("body")
    spokes = []
    for k in range(2):
        scene.update(k)
        outline, spoke = (np.array(a.get_data()).T for a in scene.artists[body])
        radius = np.hypot(*(outline - outline.mean(axis=0)).T)
        assert np.allclose(radius, p[3], rtol=0.05)          # a disk of radius R ...
        spokes.append(spoke[1] - spoke[0])
    turn = np.arctan2(spokes[1][1], spokes[1][0]) - np.arctan2(spokes[0][1], spokes[0][0])
    assert turn == pytest.approx(-0.3 / p[3], abs=1e-9)    # ... turning by −x3/R as it rolls
    damper = scene.artists[kinds.index("damper")]
    assert len(damper.get_xdata()) > 4                       # a dashpot, not a bare line


def test_frames_are_drawn_with_the_simulation_s_parameters_and_a_scene_at_rest_is_readable(
        tmp_path):
    """A pendulum run with L = 3: `frames_png` drew its bob at L = 1 (the model's default, not
    sol.params); at rest, the scene's axes spanned ±6e-10 m around the bob."""
    from lagrgen.outputs.plotting import drawable_tracks, frames_png, scene_limits, \
        solution_parameters
    model = Model("eng_pendulum")
    th, = model.coordinates("th")
    m, L, g = model.parameters(m=1.0, L=1.0, g=9.81)
    model.particle(m, sp.Matrix([L * sp.sin(th), -L * sp.cos(th)]))
    model.potential_energy(-m * g * L * sp.cos(th))
    mod = lagrgen.build(model, backend="python")
    sol = lagrgen.simulate(mod, (0, 1), [0.5, 0.0], params={"L": 3.0})
    p = solution_parameters(model, sol, None)
    assert p[list(model.parameter_names).index("L")] == 3.0
    (kind, (bob, *_)), = drawable_tracks(model, p, np.array([0.0]), np.array([[0.5]]))
    np.testing.assert_allclose(bob[0], [3 * np.sin(0.5), -3 * np.cos(0.5)])
    assert len(frames_png(model, sol, str(tmp_path / "f"), count=2)) == 2
    rest = lagrgen.simulate(mod, (0, 1), [0.0, 0.0], params={"L": 3.0})
    tracks = drawable_tracks(model, solution_parameters(model, rest, None), rest.t[:3],
                             rest.y[:1, :3])
    x0, x1, y0, y1 = scene_limits(tracks)
    assert x1 - x0 > 1.0 and y0 < -3.0 < y1


def test_frames_between_long_steps_follow_the_motion_not_straight_lines():
    """An explicit solver stepped a bouncing ball from t = 0.794 to 1.174 and the frame at t = 1
    drew it 0.18 m off its path (linear interpolation); q between saved points is now the cubic
    Hermite interpolant of q and q̇, exact for a fall, and at an impact (two points at one time)
    the frame at that time shows the state after it."""
    from lagrgen.outputs.plotting import hermite_states
    g = 9.81
    t = np.array([0.0, 0.3, 0.8, 0.8, 1.1])
    v = np.array([0.0, -g * 0.3, -g * 0.8, 0.5 * g * 0.8, 0.5 * g * 0.8 - g * 0.3])
    q = np.array([1.0, 1 - g * 0.3 ** 2 / 2, 1 - g * 0.8 ** 2 / 2, 1 - g * 0.8 ** 2 / 2,
                  1 - g * 0.8 ** 2 / 2 + 0.5 * g * 0.8 * 0.3 - g * 0.3 ** 2 / 2])
    times = np.array([0.1, 0.55, 0.8, 0.95])
    drawn = hermite_states(t, np.vstack([q, v]), times)
    fall = 1 - g * times[:2] ** 2 / 2
    np.testing.assert_allclose(drawn[0, :2], fall, atol=1e-12)
    np.testing.assert_allclose(drawn[1, 2], v[3])
    rise = q[3] + v[3] * 0.15 - g * 0.15 ** 2 / 2
    np.testing.assert_allclose(drawn[0, 3], rise, atol=1e-12)


def test_show_prints_units(tmp_path):
    (tmp_path / "m.py").write_text(FORCED)
    proc = run("show", "m.py", cwd=tmp_path)
    assert "# units: x [m], m [kg], k [N/m], F [N], G [N], tip_x [m]" in proc.stdout


def test_guard_keeps_the_model_events(tmp_path):
    m = switching_model()
    m.event("contact", 0.5 - m.q[0], terminal=True, direction=-1)
    mod = lagrgen.build(m, backend="python")
    sol = lagrgen.simulate(mod, (0.0, 10.0), [0.0, 1.0], max_steps=100_000, rtol=1e-10,
                           atol=1e-12)
    assert sol.guard is None and sol.status == 1 and len(sol.t_events) == 1
    assert sol.y_events[0][0][0] == pytest.approx(0.5, abs=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_energy_of_a_3d_body_and_nan_for_external_equations(backend, tmp_path):
    """T of a spinning 3-D body is ½·ωᵀIω; a from_sympy model's energies are NaN, never 0."""
    from lagrgen import rotation
    m = Model("eng_spin")
    phi, = m.coordinates("phi")
    m.rigid_body_3d(2.0, [1.0, 2.0, 3.0], [0, 0, 0], orientation=rotation.z(phi))
    mod = lagrgen.build(m, backend=backend, out_dir=tmp_path)
    out = dict(zip(mod.output_names, mod.outputs(0.0, [0.3, 1.5])))
    assert out["kinetic_energy"] == pytest.approx(3.0 * 1.5 ** 2 / 2, rel=1e-14)
    import sympy.physics.mechanics as me
    q = me.dynamicsymbols("q")
    mass, k = sp.symbols("mass k")
    lm = me.LagrangesMethod(mass * q.diff() ** 2 / 2 - k * q ** 2 / 2, [q])
    lm.form_lagranges_equations()
    ext = lagrgen.build(lagrgen.from_sympy(lm, "eng_ext", defaults={"mass": 2.0, "k": 3.0}),
                        backend=backend, out_dir=tmp_path)
    assert np.all(np.isnan(ext.outputs(0.0, [1.0, 2.0])))
