"""Co-simulation and FMI 3.0 FMUs (API.md §16), checked with FMPy: every kind validates; FMPy's
runs agree with `lagrgen.simulate` (co-simulation: the native engine at the same method and
tolerances, closely; FMI 3.0 Model Exchange: FMPy's CVode); parameters, inputs and the solver
settings set through FMPy act as in `simulate`; FMU states round-trip; terminal events end a
co-simulation where `simulate` ends."""
import zipfile

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model, ModelError
from lagrgen.cli import main
from lagrgen.methods import NATIVE_CODES

from conftest import EXAMPLES, example_model

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402

STATES = ["theta1", "theta2", "theta1_dot", "theta2_dot"]
KINDS = [("cs", 2), ("me", 3), ("cs", 3)]


def swinging_pendulum():
    """A pendulum whose second rising passage through theta = 0 (its fourth passage) ends the
    run (a counted, directed terminal event) and whose crossings of theta = 0.2 are only
    located."""
    model = Model("counted_pendulum")
    theta, = model.coordinates("theta")
    m, L, g = model.parameters(m=1.0, L=1.0, g=9.81)
    model.particle(m, sp.Matrix([L * sp.sin(theta), -L * sp.cos(theta)]))
    model.potential_energy(-m * g * L * sp.cos(theta))
    model.event("rises_through_bottom", theta, terminal=2, direction=1)
    model.event("passes_02", theta - 0.2)
    return model


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    """The double pendulum, compiled, and its FMUs of every kind but FMI 2.0 ME (test_fmu.py)."""
    out = tmp_path_factory.mktemp("fmu_kinds")
    model = example_model("double_pendulum")
    mod = lagrgen.build(model, out_dir=out / "gen")
    fmus = {(kind, version): lagrgen.export_fmu(model, out / f"{kind}{version}", kind=kind,
                                                fmi_version=version, rtol=1e-9)
            for kind, version in KINDS}
    return model, mod, fmus


def by_name(path):
    md = fmpy.read_model_description(str(path))
    return md, {v.name: v for v in md.modelVariables}


@pytest.mark.parametrize("kind, version", KINDS)
def test_every_kind_validates_and_is_described(pendulum, kind, version):
    model, _, fmus = pendulum
    path = fmus[kind, version]
    assert validate_fmu(str(path)) == []
    md, variables = by_name(path)
    assert md.fmiVersion == f"{version}.0"
    assert (md.coSimulation is not None, md.modelExchange is not None) == (kind == "cs",
                                                                          kind == "me")
    interface = md.coSimulation or md.modelExchange
    assert interface.canGetAndSetFMUstate and interface.canSerializeFMUstate
    assert [o.variable.name for o in md.outputs] == ["theta1", "theta2"]
    for name, value in zip(model.parameter_names, model.parameter_defaults):
        assert (variables[name].causality, float(variables[name].start)) == ("parameter", value)
    assert variables["F"].causality == "input"
    names = zipfile.ZipFile(path).namelist()
    folder = "linux64" if version == 2 else "x86_64-linux"
    assert f"binaries/{folder}/double_pendulum.so" in names
    assert f"documentation/licenses/fmi{version}-headers.txt" in names
    assert {f"sources/fmi{version}Functions.h", "sources/double_pendulum_fmu.c",
            "sources/double_pendulum_fmu_core.c", "sources/double_pendulum_model.c"} <= set(names)
    if kind == "cs":
        assert {"sources/lg_ode.c", "sources/lg_ode.h", "sources/lg_ode_tables.h",
                "documentation/licenses/scipy-lg_ode.txt"} <= set(names)
        assert variables["solver.method"].type == "Enumeration"
        assert variables["solver.method"].declaredType.items[2].name == "DOP853"
        assert int(variables["solver.method"].start) == 2          # DOP853, the default
        assert float(variables["solver.rtol"].start) == 1e-9
        assert float(variables["solver.atol"].start) == pytest.approx(1e-12)
    else:
        assert [d.variable.name for d in md.derivatives] == [f"der({s})" for s in STATES]
        assert "solver.rtol" not in variables and "lg_ode.c" not in str(names)
    for name in ("kinetic_energy", "potential_energy", "total_energy"):
        assert (variables[name].causality, variables[name].initial) == ("local", "calculated")
    if version == 3:
        assert variables["time"].causality == "independent"


def constant_input(value, T):
    return np.array([(0.0, value), (T, value)], dtype=[("time", float), ("F", float)])


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("method, rtol, atol, tol", [("DOP853", 1e-10, 1e-12, 1e-8),
                                                      ("Radau", 1e-8, 1e-10, 1e-7)])
def test_cosimulation_agrees_with_simulate(pendulum, version, method, rtol, atol, tol):
    """The solver settings are set through FMPy; each communication step is a native solve."""
    model, mod, fmus = pendulum
    T = 4.0
    start = {"theta1": 0.6, "theta2_dot": -0.3}
    params = {"L1": 0.9, "m2": 1.3}
    solver = {"solver.method": NATIVE_CODES[method],
              "solver.rtol": rtol, "solver.atol": atol}
    res = fmpy.simulate_fmu(str(fmus["cs", version]), start_values={**start, **params, **solver},
                            input=constant_input(0.5, T), stop_time=T, output_interval=0.05,
                            output=STATES + list(mod.output_names))
    sol = lagrgen.simulate(mod, (0.0, T), start, params=params, inputs={"F": 0.5},
                           method=method, rtol=rtol, atol=atol, t_eval=res["time"])
    assert sol.engine == "native" and len(res) == 81
    fmu_y = np.array([res[k] for k in STATES])
    assert np.ptp(fmu_y) > 0.5
    assert_allclose(fmu_y, sol.y, atol=tol, rtol=0)
    # the model's outputs (here the energies) are variables too, computed from the state
    p = np.array([{**dict(zip(model.parameter_names, model.parameter_defaults)), **params}[k]
                  for k in model.parameter_names])
    want = np.array([mod.outputs(t, y, p, [0.5]) for t, y in zip(sol.t, sol.y.T)]).T
    assert_allclose(np.array([res[k] for k in mod.output_names]), want, atol=20 * tol, rtol=0)
    # the importer's tolerance replaces solver.rtol's start value: a loose one moves the result
    loose = fmpy.simulate_fmu(str(fmus["cs", version]),
                              start_values={**start, **params,
                                            "solver.method": solver["solver.method"]},
                              input=constant_input(0.5, T), stop_time=T, output_interval=0.05,
                              output=STATES, relative_tolerance=1e-3)
    assert 1e-8 < np.abs(np.array([loose[k] for k in STATES]) - fmu_y).max() < 0.1


@pytest.mark.parametrize("version", [2, 3])
def test_a_stepped_input_acts_as_in_simulate(pendulum, version):
    """FMPy applies the input at each communication point (a step at t = 1 lands on one); the
    FMU holds it over the step, as `simulate` with a "previous" Signal."""
    model, mod, fmus = pendulum
    T = 3.0
    signal = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 2.0), (T, 2.0)],
                      dtype=[("time", float), ("F", float)])
    res = fmpy.simulate_fmu(str(fmus["cs", version]), start_values={"theta1": 0.3,
                                                                     "solver.rtol": 1e-10,
                                                                     "solver.atol": 1e-12},
                            input=signal, stop_time=T, output_interval=0.1, output=STATES)
    force = lagrgen.Signal([0.0, 1.0, T], [0.0, 2.0, 2.0], kind="previous")
    sol = lagrgen.simulate(mod, (0.0, T), {"theta1": 0.3}, inputs={"F": force},
                           method="DOP853", rtol=1e-10, atol=1e-12, t_eval=res["time"])
    unforced = lagrgen.simulate(mod, (0.0, T), {"theta1": 0.3}, method="DOP853", rtol=1e-10,
                                atol=1e-12, t_eval=res["time"])
    fmu_y = np.array([res[k] for k in STATES])
    assert_allclose(fmu_y, sol.y, atol=1e-7, rtol=0)
    assert np.abs(fmu_y - unforced.y).max() > 0.05


def test_fmi3_model_exchange_agrees_with_simulate(pendulum):
    model, mod, fmus = pendulum
    T = 4.0
    start = {"theta1": 0.6, "theta2_dot": -0.3}
    params = {"L1": 0.9, "m2": 1.3}
    res = fmpy.simulate_fmu(str(fmus["me", 3]), start_values={**start, **params},
                            input=constant_input(0.5, T), stop_time=T, output_interval=0.05,
                            relative_tolerance=1e-10, output=STATES)
    sol = lagrgen.simulate(mod, (0.0, T), start, params=params, inputs={"F": 0.5},
                           method="DOP853", rtol=1e-12, atol=1e-12, t_eval=res["time"])
    assert len(res) == 81
    assert_allclose(np.array([res[k] for k in STATES]), sol.y, atol=2e-6, rtol=0)


def test_fmi3_directional_derivatives_equal_the_jacobian(pendulum, tmp_path):
    from fmpy.fmi3 import FMU3Model
    model, mod, fmus = pendulum
    md, variables = by_name(fmus["me", 3])
    fmu = FMU3Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmus["me", 3]), tmp_path),
                    modelIdentifier="double_pendulum", instanceName="dd3")
    fmu.instantiate()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    vr = {name: v.valueReference for name, v in variables.items()}
    p = np.array([1.2, 0.8, 0.9, 1.1, 9.81])
    y = np.array([0.4, -0.7, 1.3, 0.2])
    fmu.setFloat64([vr[k] for k in model.parameter_names], list(p))
    fmu.setFloat64([vr["F"]], [0.6])
    fmu.enterContinuousTimeMode()
    fmu.setTime(0.3)
    fmu.setContinuousStates((fmpy.fmi3.fmi3Float64 * 4)(*y), 4)
    dx = (fmpy.fmi3.fmi3Float64 * 4)()
    fmu.getContinuousStateDerivatives(dx, 4)
    assert_allclose(list(dx), mod.rhs(0.3, y, p, [0.6]), rtol=1e-14, atol=1e-14)
    assert fmu.getFloat64([vr["time"]]) == [0.3]
    derivatives = [vr[f"der({s})"] for s in STATES]
    J = mod.jacobian(0.3, y, p, [0.6])
    dv = [0.3, -1.0, 2.0, 0.5]
    got = fmu.getDirectionalDerivative(derivatives, [vr[s] for s in STATES], dv)
    assert_allclose(got, J @ dv, rtol=1e-13, atol=1e-13)
    fmu.terminate()
    fmu.freeInstance()


def cs_instance(path, tmp_path, version, callbacks=None):
    """An initialized co-simulation instance (FMPy's FMU2Slave / FMU3Slave) and its value
    references by name."""
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave
    md, variables = by_name(path)
    unzipped = fmpy.extract(str(path), tmp_path / f"unzipped{version}")
    vr = {name: v.valueReference for name, v in variables.items()}
    if version == 2:
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.
                        modelIdentifier, instanceName="state")
        fmu.instantiate(callbacks=callbacks)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        set_real, get_real = fmu.setReal, fmu.getReal
    else:
        fmu = FMU3Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.
                        modelIdentifier, instanceName="state")
        fmu.instantiate()
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        set_real, get_real = fmu.setFloat64, fmu.getFloat64
    return fmu, vr, set_real, get_real


@pytest.mark.parametrize("version", [2, 3])
def test_fmu_state_round_trip(pendulum, tmp_path, version):
    """Do a step, save the state, do steps, restore, redo: the same result, bit for bit; a
    serialized state restores the same; settings (input, tolerance) are part of the state."""
    model, mod, fmus = pendulum
    fmu, vr, set_real, get_real = cs_instance(fmus["cs", version], tmp_path, version)
    states = [vr[s] for s in STATES]
    set_real([vr["theta1"], vr["theta2_dot"], vr["F"]], [0.6, -0.3, 0.5])
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.1)
    saved = fmu.getFMUState()
    blob = fmu.serializeFMUState(saved)

    def run_on(t0):
        out = []
        for k in range(5):
            fmu.doStep(currentCommunicationPoint=t0 + 0.1 * k, communicationStepSize=0.1)
            out.append(get_real(states))
        return np.array(out)

    first = run_on(0.1)
    set_real([vr["F"], vr["solver.rtol"]], [-3.0, 1e-3])    # changed, then restored
    fmu.setFMUState(saved)
    again = run_on(0.1)
    assert np.array_equal(first, again)
    assert np.ptp(first) > 0.05
    deserialize = fmu.deSerializeFMUstate if version == 2 else fmu.deserializeFMUState
    restored = deserialize(blob)
    fmu.setFMUState(restored)
    assert np.array_equal(run_on(0.1), first)
    # the states after 0.6 s agree with simulate
    sol = lagrgen.simulate(mod, (0.0, 0.6), {"theta1": 0.6, "theta2_dot": -0.3},
                           inputs={"F": 0.5}, method="DOP853", rtol=1e-9, atol=1e-12)
    assert_allclose(first[-1], sol.y[:, -1], atol=1e-7)
    with pytest.raises(Exception):
        deserialize(blob[:-1])
    with pytest.raises(Exception):          # tolerances are checked
        set_real([vr["solver.rtol"]], [-1.0])
    with pytest.raises(Exception):          # a communication point that is not the FMU's time
        fmu.doStep(currentCommunicationPoint=5.0, communicationStepSize=0.1)
    fmu.freeFMUState(saved)
    fmu.freeFMUState(restored)
    fmu.terminate()
    fmu.freeInstance()


def test_model_exchange_state_round_trip(tmp_path):
    from fmpy.fmi2 import FMU2Model
    model = swinging_pendulum()
    path = lagrgen.export_fmu(model, tmp_path)
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path))
    fmu = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(path), tmp_path / "u"),
                    modelIdentifier=model.name, instanceName="me_state")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.enterContinuousTimeMode()
    fmu.setTime(0.25)
    fmu.setContinuousStates((fmpy.fmi2.fmi2Real * 2)(0.3, -0.1), 2)
    saved = fmu.getFMUstate()
    fmu.setContinuousStates((fmpy.fmi2.fmi2Real * 2)(9.0, 9.0), 2)
    fmu.setTime(4.0)
    fmu.setFMUstate(saved)
    x = (fmpy.fmi2.fmi2Real * 2)()
    fmu.getContinuousStates(x, 2)
    assert list(x) == [0.3, -0.1]
    dx = (fmpy.fmi2.fmi2Real * 2)()
    fmu.getDerivatives(dx, 2)
    assert_allclose(list(dx), [-0.1, -9.81 * np.sin(0.3)], rtol=1e-15)
    fmu.freeFMUstate(saved)
    fmu.terminate()
    fmu.freeInstance()


@pytest.fixture(scope="module")
def counted(tmp_path_factory):
    """The counted pendulum and `simulate`'s run of it, which its fourth passage ends."""
    model = swinging_pendulum()
    mod = lagrgen.build(model, out_dir=tmp_path_factory.mktemp("counted"))
    sol = lagrgen.simulate(mod, (0.0, 10.0), {"theta": 0.5}, method="DOP853", rtol=1e-10,
                           atol=1e-12)
    assert sol.status == 1 and len(sol.t_events[0]) == 2 and len(sol.t_events[1]) == 3
    return model, sol


@pytest.mark.parametrize("kind, version", [("cs", 2), ("cs", 3), ("me", 2), ("me", 3)])
def test_a_counted_terminal_event_ends_the_run(counted, tmp_path, kind, version):
    """The second rising passage through theta = 0 ends the run where `simulate` ends: counted
    in its direction across communication steps by the co-simulation FMU's native engine, and,
    in Model Exchange, from the event indicators whose crossings FMPy's CVode locates; FMPy
    records the state there."""
    model, sol = counted
    path = lagrgen.export_fmu(model, tmp_path, kind=kind, fmi_version=version, rtol=1e-10,
                              atol=1e-12)
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path))
    assert md.numberOfEventIndicators == (2 if kind == "me" else 0)
    res = fmpy.simulate_fmu(str(path), start_values={"theta": 0.5}, stop_time=10.0,
                            output_interval=0.05, output=["theta", "theta_dot"],
                            relative_tolerance=1e-10 if kind == "me" else None,
                            early_return_allowed=True)
    t_end = sol.t_events[0][-1]
    rtol = 1e-9 if kind == "cs" else 1e-7
    assert res["time"][-1] == pytest.approx(t_end, rel=rtol)
    assert abs(res["theta"][-1]) < 1e-7
    assert_allclose(res["theta_dot"][-1], sol.y[1, -1], rtol=1e-6)
    assert len(res) < 100                    # it stopped: 10 s would be over 200 samples


def test_command_line_kinds_and_errors(tmp_path, capsys):
    source = EXAMPLES / "double_pendulum.py"
    assert main(["export-fmu", str(source), "--out", str(tmp_path), "--kind", "cs",
                 "--fmi-version", "3", "--method", "Radau", "--rtol", "1e-7"]) == 0
    assert "FMI 3.0 Co-Simulation FMU" in capsys.readouterr().out
    path = tmp_path / "double_pendulum.fmu"
    assert validate_fmu(str(path)) == []
    md, variables = by_name(path)
    assert md.fmiVersion == "3.0" and md.coSimulation is not None
    assert int(variables["solver.method"].start) == 3
    assert float(variables["solver.rtol"].start) == 1e-7
    assert float(variables["solver.atol"].start) == pytest.approx(1e-10)
    rebuilt_from_its_sources(path, tmp_path / "rebuild")
    with pytest.raises(SystemExit):
        main(["export-fmu", str(source), "--out", str(tmp_path), "--kind", "hybrid"])
    model = example_model("double_pendulum")
    with pytest.raises(ValueError, match="kind must be 'me'"):
        lagrgen.export_fmu(model, tmp_path, kind="CS")
    with pytest.raises(ValueError, match="fmi_version must be 2 or 3"):
        lagrgen.export_fmu(model, tmp_path, fmi_version=1)
    with pytest.raises(ValueError, match="LSODA.*no native implementation"):
        lagrgen.export_fmu(model, tmp_path, kind="cs", method="LSODA")
    with pytest.raises(ValueError, match="rtol must be positive"):
        lagrgen.export_fmu(model, tmp_path, kind="cs", rtol=0.0)


def rebuilt_from_its_sources(path, work):
    """Compile the FMU's sources/ as its buildDescription.xml lists them (C99, -Wall: no
    warning), load the library and call it."""
    import ctypes
    import subprocess
    import xml.etree.ElementTree as ET
    from lagrgen.codegen.fmu import compiler_command      # the toolchain the export uses
    with zipfile.ZipFile(path) as fmu:
        fmu.extractall(work)
    sources = work / "sources"
    listed = [f.get("name") for f in
              ET.parse(sources / "buildDescription.xml").getroot().iter("SourceFile")]
    assert listed == ["double_pendulum_fmu.c", "lg_ode.c"]
    library = work / "rebuilt.so"
    result = subprocess.run([*compiler_command(), "-std=c99", "-Wall", "-shared", "-fPIC", "-O1",
                             "-I", str(sources), *(str(sources / f) for f in listed), "-o",
                             str(library), "-lm"], capture_output=True, text=True)
    assert result.returncode == 0 and "warning" not in result.stderr, result.stderr
    dll = ctypes.CDLL(str(library))
    dll.fmi3GetVersion.restype = ctypes.c_char_p
    assert dll.fmi3GetVersion() == b"3.0"


def test_a_constrained_model_cosimulates_as_simulate(tmp_path):
    """The slider-crank (two holonomic constraints, two inputs): the FMU integrates the same
    constrained, stabilized rhs with the native engine."""
    from conftest import load_example
    model = load_example("slider_crank").model
    path = lagrgen.export_fmu(model, tmp_path, kind="cs", rtol=1e-10, atol=1e-12)
    assert validate_fmu(str(path)) == []
    mod = lagrgen.build(model, out_dir=tmp_path / "gen")
    y0 = lagrgen.consistent_state(mod, [0.3, 0.0, 0.25, 20.0, 0.0, 0.0])
    names = ["th", "phi", "x", "th_dot", "phi_dot", "x_dot"]
    T = 1.0
    force = np.array([(0.0, 5.0, 0.1), (T, 5.0, 0.1)],
                     dtype=[("time", float), ("P", float), ("Tl", float)])
    res = fmpy.simulate_fmu(str(path), start_values=dict(zip(names, y0)), input=force,
                            stop_time=T, output_interval=0.01, output=names)
    sol = lagrgen.simulate(mod, (0.0, T), y0, inputs={"P": 5.0, "Tl": 0.1}, method="DOP853",
                           rtol=1e-10, atol=1e-12, t_eval=res["time"])
    fmu_y = np.array([res[k] for k in names])
    assert np.ptp(fmu_y[0]) > 10.0           # the crank turns over several times
    assert_allclose(fmu_y, sol.y, atol=1e-8, rtol=0)
    assert np.abs(mod.constraint_residuals(T, fmu_y[:, -1])).max() < 1e-8


def test_user_outputs_are_variables_and_names_may_not_clash(tmp_path):
    from fmpy.fmi2 import FMU2Model
    model = Model("tip_pendulum")
    theta, = model.coordinates("theta", units="rad")
    m, L, g = model.parameters(m=(1.0, "kg"), L=(0.7, "m"), g=9.81)
    tip = sp.Matrix([L * sp.sin(theta), -L * sp.cos(theta)])
    model.particle(m, tip)
    model.potential_energy(m * g * tip[1])
    model.output("tip_x", tip[0], units="m")
    path = lagrgen.export_fmu(model, tmp_path)
    assert validate_fmu(str(path)) == []
    md, variables = by_name(path)
    assert "[m]" in variables["tip_x"].description
    fmu = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(path), tmp_path / "u"),
                    modelIdentifier=model.name, instanceName="outputs")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([variables["theta"].valueReference, variables["theta_dot"].valueReference,
                 variables["L"].valueReference], [0.4, 1.5, 0.9])
    fmu.exitInitializationMode()
    got = fmu.getReal([variables[k].valueReference for k in ("tip_x", "kinetic_energy")])
    assert_allclose(got, [0.9 * np.sin(0.4), 0.5 * 0.81 * 1.5 ** 2], rtol=1e-15)
    fmu.terminate()
    fmu.freeInstance()
    clash = Model("clash_out")
    x, = clash.coordinates("x")
    clash.particle(1, x)
    with pytest.raises(ModelError, match="'x_dot' clashes with the velocity name"):
        clash.output("x_dot", 2 * x)
    timed = Model("clash_time")
    x, = timed.coordinates("x")
    timed.particle(1, x)
    timed.output("time", x)
    assert validate_fmu(str(lagrgen.export_fmu(timed, tmp_path))) == []     # FMI 2.0: no time
    with pytest.raises(ModelError, match="'time' would be used twice.*FMU's own"):
        lagrgen.export_fmu(timed, tmp_path, fmi_version=3)


@pytest.mark.parametrize("version", [2, 3])
def test_a_failing_step_is_an_error_that_says_why(pendulum, version):
    """Negative masses make M negative definite: the step fails with the engine's reason."""
    _, _, fmus = pendulum
    messages = []
    with pytest.raises(Exception, match=f"fmi{version}DoStep"):
        fmpy.simulate_fmu(str(fmus["cs", version]), start_values={"m1": -1.0, "m2": -1.0},
                          stop_time=1.0, logger=lambda *args: messages.append(args[-1]))
    assert any(b"mass matrix is not positive definite at t = 0" in m for m in messages)


@pytest.mark.parametrize("version", [2, 3])
def test_solver_settings_out_of_range_are_refused_in_both_fmi_versions(pendulum, tmp_path,
                                                                       version, fmi2_callbacks):
    """The setters of solver.rtol, solver.atol and solver.method apply the rules of
    lagrgen.options (issue 28, item 6): a bad value is an FMI error and the setting is kept."""
    model, mod, fmus = pendulum
    fmu, vr, set_real, get_real = cs_instance(fmus["cs", version], tmp_path, version,
                                              fmi2_callbacks if version == 2 else None)
    set_int = fmu.setInteger if version == 2 else fmu.setInt64
    get_int = fmu.getInteger if version == 2 else fmu.getInt64
    try:
        for name, bad in [("solver.rtol", v) for v in (1e10, 1.0, np.inf, np.nan, 0.0, -1e-6)] + \
                         [("solver.atol", v) for v in (np.nan, np.inf, -1.0)]:
            kept = get_real([vr[name]])
            with pytest.raises(Exception):
                set_real([vr[name]], [bad])
            assert get_real([vr[name]]) == kept, (name, bad)
        kept = get_int([vr["solver.method"]])
        for bad in (-1, 99, 2 ** 31 - 1):
            with pytest.raises(Exception):
                set_int([vr["solver.method"]], [bad])
            assert get_int([vr["solver.method"]]) == kept
        set_real([vr["solver.rtol"], vr["solver.atol"]], [1e-7, 1e-10])
        set_int([vr["solver.method"]], [1])
        assert get_real([vr["solver.rtol"], vr["solver.atol"]]) == [1e-7, 1e-10]
        assert get_int([vr["solver.method"]]) == [1]
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.05)
    finally:
        fmu.freeInstance()
