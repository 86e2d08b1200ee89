"""FMI 2.0 Model Exchange export, checked with FMPy: the description validates, FMPy's CVode run
agrees with `lagrgen.simulate`, the directional derivatives equal the analytic Jacobian."""
import zipfile

import numpy as np
import pytest
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model, ModelError
from lagrgen.cli import main

from conftest import EXAMPLES, example_model

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402


def damped_chain(n=4):
    """n masses in a line, each joined to the one before (the first to a wall) by a spring and a
    damper; a force f on the last."""
    model = Model(f"damped_chain{n}")
    x = model.coordinates([f"x{i + 1}" for i in range(n)])
    m = model.parameters(**{f"m{i + 1}": 1.0 + 0.25 * i for i in range(n)})
    k, c = model.parameters(k=30.0, c=0.3)
    f, = model.inputs("f")
    previous = 0
    for i in range(n):
        model.particle(m[i], x[i])
        model.spring(k * (1 + 0.1 * i), x[i] - previous)
        model.damper(c, x[i] - previous)
        previous = x[i]
    model.force(f, at=x[-1])
    return model


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("fmu")
    pendulum = example_model("double_pendulum")
    chain = damped_chain()
    return {m.name: (m, lagrgen.export_fmu(m, out)) for m in (pendulum, chain)}


def test_description_validates_and_names(fmus):
    model, path = fmus["double_pendulum"]
    assert path.name == "double_pendulum.fmu"
    assert validate_fmu(str(path)) == []
    names = zipfile.ZipFile(path).namelist()
    assert "binaries/linux64/double_pendulum.so" in names
    assert {"sources/double_pendulum_fmu.c", "sources/double_pendulum_model.c",
            "sources/double_pendulum_model.h", "modelDescription.xml"} <= set(names)
    md = fmpy.read_model_description(str(path))
    assert md.fmiVersion == "2.0" and md.modelExchange.providesDirectionalDerivative
    assert md.coSimulation is None
    by_name = {v.name: v for v in md.modelVariables}
    states = [d.variable.derivative.name for d in md.derivatives]
    assert states == ["theta1", "theta2", "theta1_dot", "theta2_dot"]
    assert [o.variable.name for o in md.outputs] == ["theta1", "theta2"]
    for name, value in zip(model.parameter_names, model.parameter_defaults):
        v = by_name[name]
        assert (v.causality, v.variability, float(v.start)) == ("parameter", "tunable", value)
    assert by_name["F"].causality == "input" and by_name["F"].variability == "continuous"
    assert float(md.defaultExperiment.stopTime) == 10.0
    chain_problems = validate_fmu(str(fmus["damped_chain4"][1]))
    assert chain_problems == []


@pytest.mark.parametrize("name, start, params, force", [
    ("double_pendulum", {"theta1": 0.6, "theta2_dot": -0.3}, {"L1": 0.9, "m2": 1.3}, 0.5),
    ("damped_chain4", {"x1": 0.1, "x4": -0.2, "x2_dot": 0.5}, {"k": 45.0}, 1.5),
])
def test_fmpy_cvode_agrees_with_simulate(fmus, tmp_path, name, start, params, force):
    model, path = fmus[name]
    mod = lagrgen.build(model, out_dir=tmp_path)
    T = 5.0
    signal = np.array([(0.0, force), (T, force)],
                      dtype=[("time", float), (model.input_names[0], float)])
    outputs = [*model.coordinate_names, *(f"{c}_dot" for c in model.coordinate_names)]
    res = fmpy.simulate_fmu(str(path), start_values={**start, **params}, input=signal,
                            stop_time=T, relative_tolerance=1e-10, output_interval=0.05,
                            output=outputs)
    sol = lagrgen.simulate(mod, (0.0, T), start, params=params,
                           inputs={model.input_names[0]: force}, method="DOP853", rtol=1e-12,
                           atol=1e-12, t_eval=res["time"])
    fmu_y = np.array([res[k] for k in outputs])
    assert len(res) == 101 and np.ptp(fmu_y) > 0.1
    assert_allclose(fmu_y, sol.y, atol=2e-6, rtol=0)


def test_directional_derivatives_equal_the_jacobian(fmus, tmp_path):
    from fmpy.fmi2 import FMU2Model
    model, path = fmus["double_pendulum"]
    mod = lagrgen.build(model, out_dir=tmp_path)
    md = fmpy.read_model_description(str(path))
    fmu = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(path), tmp_path / "unzipped"),
                    modelIdentifier="double_pendulum", instanceName="dd")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    p = np.array([1.2, 0.8, 0.9, 1.1, 9.81])
    y = np.array([0.4, -0.7, 1.3, 0.2])
    u = np.array([0.6])
    fmu.setReal([vr[k] for k in model.parameter_names], list(p))
    fmu.setReal([vr["F"]], list(u))
    fmu.enterContinuousTimeMode()
    fmu.setTime(0.3)
    fmu.setContinuousStates((fmpy.fmi2.fmi2Real * 4)(*y), 4)
    derivatives = [vr[f"der({s})"] for s in ("theta1", "theta2", "theta1_dot", "theta2_dot")]
    states = [vr[s] for s in ("theta1", "theta2", "theta1_dot", "theta2_dot")]
    assert_allclose(fmu.getReal(derivatives), mod.rhs(0.3, y, p, u), rtol=1e-14, atol=1e-14)
    J = mod.jacobian(0.3, y, p, u)
    got = np.array([fmu.getDirectionalDerivative(derivatives, [s], [1.0]) for s in states]).T
    assert_allclose(got, J, rtol=1e-13, atol=1e-13)
    # a combination of knowns is the same combination of columns
    dv = [0.3, -1.0, 2.0, 0.5]
    assert_allclose(fmu.getDirectionalDerivative(derivatives, states, dv), J @ dv, rtol=1e-13,
                    atol=1e-13)
    # with respect to the input: [0; M⁻¹·∂F/∂u]
    lin = lagrgen.linearize(mod, y[:2], y[2:], t=0.3, p=p, u=u)
    want = np.concatenate([np.zeros(2), np.linalg.solve(lin.M, lin.B[:, 0])])
    assert_allclose(fmu.getDirectionalDerivative(derivatives, [vr["F"]], [1.0]), want,
                    rtol=1e-12, atol=1e-14)
    # the outputs are the coordinates: unit rows
    assert_allclose(fmu.getDirectionalDerivative([vr["theta1"], vr["theta2"]], states, dv),
                    dv[:2], rtol=0)
    fmu.terminate()
    fmu.freeInstance()


def test_export_fmu_command_and_errors(tmp_path, capsys):
    source = EXAMPLES / "double_pendulum.py"
    assert main(["export-fmu", str(source), "--out", str(tmp_path), "--params", "g=9.80665",
                 "--stop-time", "3"]) == 0
    assert "double_pendulum.fmu" in capsys.readouterr().out
    md = fmpy.read_model_description(str(tmp_path / "double_pendulum.fmu"))
    assert float(md.defaultExperiment.stopTime) == 3.0
    assert float({v.name: v for v in md.modelVariables}["g"].start) == 9.80665
    assert main(["export-fmu", str(source), "--out", str(tmp_path), "--params", "G=1"]) == 1
    assert "unknown parameter name 'G'" in capsys.readouterr().err
    # a parameter without default needs a start value
    model = Model("no_default")
    x, = model.coordinates("x")
    m, = model.parameters("m")
    model.particle(m, x)
    with pytest.raises(ModelError, match="no default"):
        lagrgen.export_fmu(model, tmp_path)
    assert validate_fmu(str(lagrgen.export_fmu(model, tmp_path, params={"m": 2.0}))) == []
    # <coordinate>_dot is taken by the velocity: refused when declared (test_declarations.py)
    clash = Model("clash")
    x, = clash.coordinates("x")
    with pytest.raises(ModelError, match="'x_dot' clashes with the velocity name"):
        clash.parameters(x_dot=1.0)


def test_a_sympy_model_exports_and_a_wrong_guid_is_refused(tmp_path):
    from fmpy.fmi2 import FMU2Model
    from test_sympy_interop import CART_POLE_DEFAULTS, cart_pole
    model = lagrgen.from_sympy(cart_pole(), "cart_pole_fmu", CART_POLE_DEFAULTS)
    path = lagrgen.export_fmu(model, tmp_path)
    assert validate_fmu(str(path)) == []
    mod = lagrgen.build(model, out_dir=tmp_path / "gen")
    res = fmpy.simulate_fmu(str(path), start_values={"q_pin": 0.3}, stop_time=2.0,
                            relative_tolerance=1e-10, output_interval=0.1,
                            output=["q_slider", "q_pin"])
    sol = lagrgen.simulate(mod, (0.0, 2.0), {"q_pin": 0.3}, method="DOP853", rtol=1e-12,
                           atol=1e-12, t_eval=res["time"])
    assert_allclose(np.array([res["q_slider"], res["q_pin"]]), sol.q, atol=2e-6, rtol=0)
    unzipped = fmpy.extract(str(path), tmp_path / "unzipped")
    fmu = FMU2Model(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=unzipped,
                    modelIdentifier="cart_pole_fmu", instanceName="wrong")
    with pytest.raises(Exception, match="instantiate|NULL|Failed"):
        fmu.instantiate()
