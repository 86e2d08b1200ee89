"""Runs that end, options that are numbers (issue 28): every numeric option checked once with
one message on both engines and in ensembles; a native solve whose step size collapses stops,
and what a native solve saves is bounded; the guards hold with sensitivities and in `fit`."""
import re
import time

import numpy as np
import pytest
import sympy as sp

import lagrgen
from lagrgen import Model

G = 9.81


def oscillator():
    model = Model("guarded_oscillator")
    x, = model.coordinates("x")
    k, c = model.parameters(k=4.0, c=0.1)
    model.particle(1, sp.Matrix([x, 0]))
    model.spring(k, x)
    model.damper(c, x)
    return model


def bouncing():
    model = Model("option_ball")
    y, = model.coordinates("y")
    model.particle(1, sp.Matrix([0, y]))
    model.potential_energy(G * y)
    model.impact("floor", y, restitution=0.5)
    return model


@pytest.fixture(scope="module")
def osc(compile_once):
    return compile_once(oscillator())


@pytest.fixture(scope="module")
def ball(compile_once):
    return compile_once(bouncing())


RUNNERS = {
    "native": lambda mod, **kw: lagrgen.simulate(mod, (0, 1), [1.0, 0.0], engine="native", **kw),
    "scipy": lambda mod, **kw: lagrgen.simulate(mod, (0, 1), [1.0, 0.0], engine="scipy", **kw),
    "ensemble": lambda mod, **kw: lagrgen.simulate_many(
        mod, (0, 1), [[1.0, 0.0], [0.5, 0.0]], **{"t_eval": [0.0, 1.0], **kw}),
}

BAD_OPTIONS = [
    (dict(t_eval=[0.0, np.nan, 1.0]), "t_eval must hold finite times: entry 1 is nan"),
    (dict(rtol=np.inf), "rtol must be positive and less than 1"),
    (dict(rtol=1e10), "rtol must be positive and less than 1"),
    (dict(rtol=np.nan), "rtol must be positive and less than 1"),
    (dict(rtol=0.0), "rtol must be positive and less than 1"),
    (dict(atol=np.nan), "atol must be a finite number ≥ 0"),
    (dict(atol=-1e-9), "atol must be a finite number ≥ 0"),
    (dict(atol=[1e-9, np.inf]), "atol must be a finite number ≥ 0.*entry 1 is inf"),
    (dict(first_step=np.nan), "first_step must be a positive number"),
    (dict(first_step=2.0), "first_step must be a positive number no larger than the time span"),
    (dict(max_step=np.nan), "max_step must be a positive number"),
    (dict(max_step=0.0), "max_step must be a positive number"),
    (dict(max_steps=2 ** 70), "max_steps must be a positive integer up to 2147483647"),
    (dict(max_steps=np.nan), "max_steps must be a positive integer"),
    (dict(max_steps=2.5), "max_steps must be a positive integer"),
    (dict(max_wall_time=np.nan), "max_wall_time must be a positive number of seconds"),
    (dict(max_wall_time=np.inf), "max_wall_time must be a positive number of seconds"),
    (dict(gap_tol=1e-9), "gap_tol applies to a model with impacts or frictions"),
]


@pytest.mark.parametrize("runner", sorted(RUNNERS))
@pytest.mark.parametrize("options, message", BAD_OPTIONS,
                         ids=[f"{next(iter(o))}={next(iter(o.values()))}" for o, _ in BAD_OPTIONS])
def test_every_numeric_option_is_checked_once_with_one_message(osc, runner, options, message):
    with pytest.raises(ValueError, match=message):
        RUNNERS[runner](osc, **options)


BAD_SWITCHING = [
    (dict(gap_tol=np.inf), "gap_tol must be a finite number ≥ 0"),
    (dict(gap_tol=np.nan), "gap_tol must be a finite number ≥ 0"),
    (dict(gap_tol=-1e-9), "gap_tol must be a finite number ≥ 0"),
    (dict(rest_velocity=np.nan), "rest_velocity must be a finite number ≥ 0"),
    (dict(rest_velocity=-1.0), "rest_velocity must be a finite number ≥ 0"),
    (dict(max_transitions=2 ** 70), "max_transitions must be a positive integer"),
    (dict(max_transitions=np.nan), "max_transitions must be a positive integer"),
    (dict(max_transitions=0), "max_transitions must be a positive integer"),
]


@pytest.mark.parametrize("runner", sorted(RUNNERS))
@pytest.mark.parametrize("options, message", BAD_SWITCHING,
                         ids=[f"{next(iter(o))}={next(iter(o.values()))}"
                              for o, _ in BAD_SWITCHING])
def test_switching_options_are_checked_once_with_one_message(ball, runner, options, message):
    with pytest.raises(ValueError, match=message):
        RUNNERS[runner](ball, **options)


def test_nan_in_t_eval_no_longer_truncates_a_native_run(osc, ball):
    """Before: the native engine stopped at the NaN with success=True; now refused everywhere
    (also the hybrid solve), while good options still run."""
    for mod in (osc, ball):
        with pytest.raises(ValueError, match="entry 2 is nan"):
            lagrgen.simulate(mod, (0, 1), [1.0, 0.0], t_eval=[0.0, 0.5, np.nan, 1.0])
    sol = lagrgen.simulate(osc, (0, 1), [1.0, 0.0], t_eval=[0.0, 0.5, 1.0], rtol=0.5,
                           max_steps=np.int64(10 ** 6), max_step=np.inf)
    assert sol.success and sol.t.tolist() == [0.0, 0.5, 1.0]


# -- 28.8: a stalled native solve -----------------------------------------------------------
@pytest.mark.parametrize("method", ["RK45", "RK23"])
def test_a_collapsing_step_size_stops_the_native_solve(osc, method):
    """k = 1e300: the explicit step is limited to ~1e-150 and t never grows; the solve stops
    after 1000 such steps instead of storing steps until the machine runs out of memory."""
    start = time.monotonic()
    sol = lagrgen.simulate(osc, (0, 1), [1.0, 0.0], method=method, params={"k": 1e300})
    assert time.monotonic() - start < 5
    assert not sol.success and sol.status == -1
    assert "step size collapsed: 1000 steps in a row" in sol.message
    assert len(sol.t) == 1001 and sol.t[-1] < 1e-100


def test_a_stiff_but_legitimate_start_is_not_cut(osc):
    """Steps far below the span's resolution at the start (a fast transient) that then grow:
    not a stall. c = 1e9 gives an initial step near 1e-13 on a span of 10."""
    sol = lagrgen.simulate(osc, (0, 10), [1.0, 0.0], method="Radau", params={"c": 1e9},
                           first_step=1e-14)
    assert sol.success and sol.t[-1] == 10


def test_what_a_native_solve_saves_is_bounded(osc):
    """Without t_eval and max_steps the native engine stops (keeping what it has) once the saved
    steps exceed its budget (1 GiB by default; a small one here), saying how to go on."""
    from lagrgen.native.engine import report_guard, solve_native
    sol = solve_native(osc, (0, 1e4), [1.0, 0.0], "RK45", save_budget=3000)
    report_guard(sol, (0, 1e4), None, None)
    assert sol.stopped == "saved" and not sol.success
    assert 3000 <= sol.t.size + sol.y.size <= 3000 + 3 * 3
    assert "t_eval" in sol.message and "max_steps" in sol.message
    assert_whole = solve_native(osc, (0, 1e4), [1.0, 0.0], "RK45", save_budget=3000,
                                t_eval=np.linspace(0, 1e4, 5))
    assert assert_whole.success and assert_whole.stopped is None
    assert solve_native(osc, (0, 1e4), [1.0, 0.0], "RK45", save_budget=3000,
                        max_steps=10 ** 7).success


@pytest.mark.parametrize("engine", ["native", "scipy"])
def test_max_steps_and_max_wall_time_work_with_sensitivities(osc, engine):
    sol = lagrgen.simulate(osc, (0, 100), [1.0, 0.0], sensitivities=["k"], max_steps=20,
                           engine=engine)
    assert not sol.success and "max_steps=20" in sol.guard
    assert sol.sensitivities.shape == (1, 2, sol.t.size) and 0 < sol.t[-1] < 100
    full = lagrgen.simulate(osc, (0, 1), [1.0, 0.0], sensitivities=["k"], max_steps=10 ** 6,
                            max_wall_time=60, engine=engine)
    assert full.success and full.guard is None


def test_fit_takes_the_guards(osc):
    t = np.linspace(0, 2, 21)
    truth = lagrgen.simulate(osc, (0, 2), [1.0, 0.0], params={"k": 6.0}, t_eval=t,
                             rtol=1e-10, atol=1e-12)
    fitted = lagrgen.fit(osc, t, truth.y[:1], ["k"], [1.0, 0.0], initial={"k": 4.0},
                         rtol=1e-10, atol=1e-12, max_steps=10 ** 6, max_wall_time=60)
    assert fitted.success and fitted.params["k"] == pytest.approx(6.0, rel=1e-6)
    with pytest.raises(lagrgen.LagrgenError, match="max_steps=3"):
        lagrgen.fit(osc, t, truth.y[:1], ["k"], [1.0, 0.0], max_steps=3)


# -- the same rules in the command line and in an FMU's solver settings ---------------------------
@pytest.mark.parametrize("option, message", [
    (["--rtol", "1e10"], "--rtol must be positive and less than 1"),
    (["--rtol", "nan"], "--rtol must be positive and less than 1"),
    (["--atol", "-1"], "--atol must be a finite number ≥ 0"),
    (["--max-step", "nan"], "--max-step: max_step must be a positive number"),
    (["--max-time", "inf"], "--max-time must be a positive number of seconds"),
    (["--max-time", "-1"], "--max-time must be a positive number of seconds"),
    (["--max-steps", "0"], "--max-steps must be a positive integer"),
])
def test_the_command_line_checks_the_same_rules(option, message, capsys):
    from conftest import EXAMPLES
    from lagrgen.cli import main
    code = main(["simulate", str(EXAMPLES / "double_pendulum.py"), "--t-end", "1", *option])
    assert code == 1 and message in capsys.readouterr().err


def test_the_fmu_solver_settings_follow_the_same_rules(tmp_path, fmi2_callbacks):
    fmpy = pytest.importorskip("fmpy")
    from fmpy.fmi2 import FMU2Slave
    with pytest.raises(ValueError, match="rtol must be positive and less than 1"):
        lagrgen.export_fmu(oscillator(), tmp_path, kind="cs", rtol=1e10)
    path = lagrgen.export_fmu(oscillator(), tmp_path, kind="cs", rtol=1e-6)
    md = fmpy.read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(path), tmp_path / "unzipped"),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="rules")
    fmu.instantiate(callbacks=fmi2_callbacks)
    try:
        for bad in (1e10, 1.0, np.inf, np.nan, 0.0):
            with pytest.raises(Exception):
                fmu.setReal([vr["solver.rtol"]], [bad])
        fmu.setReal([vr["solver.rtol"]], [0.5])
        assert fmu.getReal([vr["solver.rtol"]]) == [0.5]
        with pytest.raises(Exception):
            fmu.setReal([vr["solver.atol"]], [np.nan])
        assert any(b"solver.rtol must be positive and less than 1" in m for m in fmi2_callbacks.messages
                   if isinstance(m, bytes))
    finally:
        fmu.freeInstance()


@pytest.mark.parametrize("keyword, said", [
    ("u", "'u': give it as inputs="), ("p", "'p': give it as params="),
    ("vectorized", "one state at a time"), ("max_stpe", "did you mean 'max_step'"),
    ("foo", "passed on to the solver are first_step")])
def test_a_keyword_no_solver_takes_is_a_type_error(keyword, said, tmp_path_factory):
    """simulate(mod, ..., u={...}) passed u on to SciPy, which only warned, and ran with the
    inputs at 0; p= failed inside with 'multiple values'; every keyword that is neither
    simulate's nor a solver's is now a TypeError saying what was meant, in simulate_many too."""
    model = lagrgen.Model("keyword_push")
    x, = model.coordinates("x")
    F, = model.inputs("F")
    model.particle(1.0, sp.Matrix([x]))
    model.force(sp.Matrix([F]), sp.Matrix([x]))
    mod = lagrgen.build(model, out_dir=str(tmp_path_factory.mktemp("keyword")), quiet=True)
    with pytest.raises(TypeError, match=re.escape(said)):
        lagrgen.simulate(mod, (0.0, 1.0), [0.0, 0.0], **{keyword: 1.0})
    with pytest.raises(TypeError, match=r"simulate_many\(\).*" + re.escape(said)):
        lagrgen.simulate_many(mod, (0.0, 1.0), [0.0, 0.0], t_eval=[0.0, 1.0], **{keyword: 1.0})
    pushed = lagrgen.simulate(mod, (0.0, 1.0), [0.0, 0.0], inputs={"F": 1.0}, max_step=0.1,
                              rtol=1e-10, atol=1e-12)
    assert abs(pushed.y[0, -1] - 0.5) < 1e-9


def test_a_value_given_twice_or_an_input_that_is_no_number_is_named(tmp_path_factory):
    """params={k_symbol: 9, "k": 4} named one parameter twice and one value won silently; an
    array for a constant input of a compiled ensemble failed with NumPy's 'only 0-dimensional
    arrays' and a function returning an array with 'setting an array element': each is now a
    ValueError naming the parameter or input."""
    model = lagrgen.Model("named_twice")
    x, = model.coordinates("x")
    k, = model.parameters(k=4.0)
    F, = model.inputs("F")
    model.particle(1.0, sp.Matrix([x]))
    model.potential_energy(k * x ** 2 / 2)
    model.force(sp.Matrix([F]), sp.Matrix([x]))
    mod = lagrgen.build(model, out_dir=str(tmp_path_factory.mktemp("twice")), quiet=True)
    with pytest.raises(ValueError, match="parameter 'k' is given twice"):
        lagrgen.simulate(mod, (0.0, 1.0), [1.0, 0.0], params={k: 9.0, "k": 4.0})
    with pytest.raises(ValueError, match="input 'F' is given twice"):
        lagrgen.simulate(mod, (0.0, 1.0), [1.0, 0.0], inputs={F: 1.0, "F": lambda t: 2.0})
    with pytest.raises(ValueError, match=r"input 'F' must be a number.*array"):
        lagrgen.simulate_many(mod, (0.0, 1.0), [1.0, 0.0], t_eval=[0.0, 1.0],
                              inputs={"F": np.array([1.0, 0.0])})
    with pytest.raises(ValueError, match="input 'F': its function returned array"):
        lagrgen.simulate(mod, (0.0, 1.0), [1.0, 0.0], inputs={"F": lambda t: np.array([1.0, 2.0])})
    sol = lagrgen.simulate(mod, (0.0, 1.0), [1.0, 0.0], params={k: 9.0}, rtol=1e-10, atol=1e-12)
    assert abs(sol.y[0, -1] - np.cos(3.0)) < 1e-8
