"""Issues 32.1, 32.2 and 32.6: what an importer hands back to an FMU is checked. A serialized FMU
state carries a checksum of its values and every field is validated as the setters validate it;
damaging each aligned field of a serialized state in turn (and random bytes), with and without a
matching checksum, never crashes the importer (each FMU kind is fuzzed in a subprocess of its
own): it gets an FMI error. A co-simulation step of 1e300 fails after a bounded number of engine
steps, without memory that grows with the step; a NaN communication point says so."""
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import sympy as sp

import lagrgen
from lagrgen import Model

fmpy = pytest.importorskip("fmpy")

KINDS = [("me", 2), ("cs", 2), ("me", 3), ("cs", 3)]
FUZZ = Path(__file__).with_name("fmu_state_fuzz.py")


def fuzzed_model():
    """A pendulum with a parameter set, an input and two events (one terminal, counted, that
    its swing never reaches), so that every field of an FMU state is in use."""
    model = Model("fuzzed_pendulum")
    theta, = model.coordinates("theta")
    m, L, g = model.parameters(m=1.0, L=1.0, g=9.81)
    T, = model.inputs("T")
    model.particle(m, sp.Matrix([L * sp.sin(theta), -L * sp.cos(theta)]))
    model.potential_energy(-m * g * L * sp.cos(theta))
    model.torque(T, theta)
    model.event("far", theta - 3, terminal=2, direction=1)
    model.event("passes", theta - 0.2)
    return model


def limit_memory():
    import resource
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


def fuzz(path, kind, version, unzipped):
    run = subprocess.run([sys.executable, str(FUZZ), str(path), kind, str(version), unzipped],
                         capture_output=True, text=True, timeout=300, preexec_fn=limit_memory)
    return run


@pytest.fixture(scope="module")
def fuzzed(tmp_path_factory):
    out = tmp_path_factory.mktemp("fmu_state")
    model = fuzzed_model()
    jobs = []
    for kind, version in KINDS:
        path = lagrgen.export_fmu(model, out / f"{kind}{version}", kind=kind,
                                  fmi_version=version)
        jobs.append((path, kind, version, fmpy.extract(str(path), str(out / f"x{kind}{version}"))))
    with ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(lambda job: fuzz(*job), jobs))
    return dict(zip(KINDS, runs))


@pytest.mark.parametrize("kind, version", KINDS)
def test_a_damaged_serialized_state_is_refused_and_never_crashes(fuzzed, kind, version):
    run = fuzzed[kind, version]
    assert run.returncode == 0, run.stderr[-2000:]
    summary = json.loads(run.stdout.splitlines()[-1])
    assert summary["good_accepted"]
    assert summary["raw"] > 300 and summary["raw_refused"] == summary["raw"]   # the checksum
    assert summary["random_refused"] == summary["random"] == 200
    # with the checksum made to match, each field is checked as the setters check it
    assert summary["signed"] > 250 and summary["signed_refused"] > 100
    assert summary["nan_accepted"] == [] and summary["int_accepted"] == []
    assert all(0 < rtol < 1 for rtol in summary["rtol_accepted"])   # as the setter takes it
    assert summary["accepted_then_ok"] > 100


@pytest.mark.parametrize("version", [2, 3])
def test_steps_no_engine_can_take_are_fmi_errors_that_say_why(fuzzed, version):
    run = fuzzed["cs", version]
    assert run.returncode == 0, run.stderr[-2000:]
    summary = json.loads(run.stdout.splitlines()[-1])
    assert summary["steps"] == {"nan_point": True, "huge_step": True, "nan_step": True}
    log = run.stdout
    assert f"fmi{version}DoStep: the communication point must be finite, got nan" in log
    # stopped by the engine's step cap, or earlier by its stall test (steps that can never
    # reach t = 1e300: native/lg_ode.h, LG_STALL_STEPS)
    assert "to 1.0000000000000001e+300 took more than 1000000 steps" in log or \
        "the step size collapsed" in log and "it cannot reach t = 1e+300" in log
    assert "the communication step size must be finite and positive, got nan" in log
