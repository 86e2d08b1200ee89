"""Ensembles (issues 10, 22): per-run arguments, failures kept in their rows, the C batch giving
exactly the numbers of one run at a time, on threads, on a Dask LocalCluster and into a Zarr store;
multipliers, outputs, labelled results (xarray) and Ctrl-C."""
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose, assert_array_equal

import lagrgen

from conftest import example_model, interrupted_script

DOUBLE = example_model("double_pendulum")
ROD = example_model("cartesian_pendulum")
T = np.linspace(0.0, 2.0, 21)


def spring_with_units():
    """m·ẍ + c·ẋ + k·x = F, with units and one output (the spring force)."""
    model = lagrgen.Model("ens_spring")
    x, = model.coordinates("x", units="m")
    m, k, c = model.parameters(m=(1.0, "kg"), k=(4.0, "N/m"), c=(0.1, "N*s/m"))
    F, = model.inputs("F", units="N")
    t = sp.Symbol("t")
    model.kinetic_energy(m * sp.diff(x, t) ** 2 / 2)
    model.potential_energy(k * x ** 2 / 2)
    model.dissipation(c * sp.diff(x, t) ** 2 / 2)
    model.generalized_force(x, F)
    model.output("spring_force", -k * x, units="N")
    return model


SPRING = spring_with_units()


@pytest.fixture(scope="module")
def mod(compile_once):
    return compile_once(DOUBLE)


@pytest.fixture(scope="module")
def rod(compile_once):
    return compile_once(ROD)


@pytest.fixture(scope="module")
def spring(compile_once):
    return compile_once(SPRING)


@pytest.fixture(scope="module")
def client(dask_client):
    return dask_client


def masses(mod, runs):
    P = np.tile(mod.defaults, (runs, 1))
    P[:, 0] = np.linspace(0.5, 2.0, runs)
    return P


def test_runs_match_single_simulations_with_per_run_arguments(mod):
    P = np.tile(mod.defaults, (6, 1))
    P[:, 0] = np.linspace(0.5, 2.0, 6)
    Y0 = np.zeros((6, 4))
    Y0[:, 0] = np.linspace(0.1, 0.6, 6)
    inputs = [{"F": 0.1 * k} for k in range(6)]
    ens = lagrgen.simulate_many(mod, (0.0, 2.0), Y0, params=P, inputs=inputs, t_eval=T,
                                method="DOP853", rtol=1e-9, atol=1e-11, workers=2)
    assert ens.y.shape == (6, 4, len(T)) and ens.runs == 6 and ens.success.all()
    assert set(ens.engines) == {"native"}
    assert_allclose(ens.t, T)
    for k in range(6):
        ref = lagrgen.simulate(mod, (0.0, 2.0), Y0[k], method="DOP853", params=P[k],
                               inputs=inputs[k], rtol=1e-9, atol=1e-11, t_eval=T)
        assert_array_equal(ens.y[k], ref.y)
        assert ens.nfev[k] == ref.nfev and ens.message[k] == ref.message
    assert ens.q.shape == ens.qd.shape == (6, 2, len(T))


def test_shared_signal_input_and_per_run_input_array(mod):
    F = lagrgen.Signal([0.0, 1.0, 2.0], [0.0, 1.0, -1.0], kind="cubic")
    ens = lagrgen.simulate_many(mod, (0.0, 2.0), [0.2, 0, 0, 0], params=masses(mod, 3),
                                inputs=[{"F": F}] * 3, t_eval=T, workers=2)
    arr = lagrgen.simulate_many(mod, (0.0, 2.0), [0.2, 0, 0, 0], params=masses(mod, 3),
                                inputs=np.array([[0.0], [0.5], [1.0]]), t_eval=T, workers=1)
    for k in range(3):
        ref = lagrgen.simulate(mod, (0.0, 2.0), [0.2, 0, 0, 0], params=masses(mod, 3)[k],
                               inputs={"F": F}, t_eval=T)
        assert_array_equal(ens.y[k], ref.y)
        ref = lagrgen.simulate(mod, (0.0, 2.0), [0.2, 0, 0, 0], params=masses(mod, 3)[k],
                               inputs={"F": 0.5 * k}, t_eval=T)
        assert_array_equal(arr.y[k], ref.y)
    assert set(ens.engines) == {"native"}


def test_callable_inputs_and_lsoda_take_the_per_run_path(mod):
    ens = lagrgen.simulate_many(mod, (0.0, 1.0), [0.2, 0, 0, 0], params=masses(mod, 2),
                                inputs={"F": lambda t: 0.5 * t}, t_eval=T[:11], workers=2)
    lsoda = lagrgen.simulate_many(mod, (0.0, 1.0), [0.2, 0, 0, 0], params=masses(mod, 2),
                                  t_eval=T[:11], method="LSODA")
    assert set(ens.engines) == set(lsoda.engines) == {"scipy"}
    ref = lagrgen.simulate(mod, (0.0, 1.0), [0.2, 0, 0, 0], params=masses(mod, 2)[1],
                           inputs={"F": lambda t: 0.5 * t}, t_eval=T[:11])
    assert_array_equal(ens.y[1], ref.y)
    assert lsoda.success.all()


def test_a_failed_run_stays_in_its_row(mod):
    params = [{"m1": 1.0}, {"m1": -3.0}, {"m1": 2.0}]
    ens = lagrgen.simulate_many(mod, (0.0, 1.0), {"theta1": 0.3}, params=params, t_eval=T[:11])
    assert list(ens.success) == [True, False, True]
    assert ens.status[1] == -1 and "not positive definite" in ens.message[1]
    assert np.isnan(ens.y[1]).all() and np.isfinite(ens.y[[0, 2]]).all()


def test_multipliers_match_single_runs(rod):
    L = np.array([1.0, 1.5, 2.0])
    P = np.tile(rod.defaults, (3, 1))
    P[:, rod.parameters.index("L")] = L
    Y0 = np.zeros((3, 4))
    Y0[:, 0], Y0[:, 1] = L * np.sin(0.4), -L * np.cos(0.4)
    ens = lagrgen.simulate_many(rod, (0.0, 2.0), Y0, params=P, t_eval=T, method="DOP853",
                                rtol=1e-9, atol=1e-11, workers=2)
    assert ens.multipliers.shape == (3, rod.n_constraints, len(T))
    assert ens.constraint_names == tuple(rod.constraint_names)
    for k in range(3):
        ref = lagrgen.simulate(rod, (0.0, 2.0), Y0[k], params=P[k], t_eval=T, method="DOP853",
                               rtol=1e-9, atol=1e-11)
        assert_array_equal(ens.y[k], ref.y)
        assert_array_equal(ens.multipliers[k], ref.constraint_forces)
    # the rod's pull T = m (g cos θ + L θ̇²) = m (v² − g y) / L acts along −(x, y)/L, and the
    # constraint force is 2 λ (x, y) (the gradient of x² + y² − L²): λ = −m (v² − g y) / (2 L²)
    m, g = P[:, rod.parameters.index("m")], P[:, rod.parameters.index("g")]
    x, y, vx, vy = (ens.y[:, i] for i in range(4))
    tension = -m[:, None] * (vx ** 2 + vy ** 2 - g[:, None] * y) / (2 * L[:, None] ** 2)
    assert_allclose(ens.multipliers[:, 0], tension, rtol=1e-6)
    ds = ens.to_xarray()
    assert list(ds.constraint.values) == list(rod.constraint_names)
    assert ds.multipliers.dims == ("run", "constraint", "time")


def test_outputs_match_evaluate_outputs(spring):
    P = np.tile(spring.defaults, (4, 1))
    P[:, 1] = [1.0, 2.0, 4.0, 8.0]
    ens = lagrgen.simulate_many(spring, (0.0, 2.0), [0.1, 0.0], params=P,
                                inputs=[{"F": 0.5}] * 4, t_eval=T, outputs=True, workers=2)
    assert ens.output_names == tuple(spring.output_names)
    assert ens.outputs.shape == (4, len(spring.output_names), len(T))
    for k in range(4):
        ref = lagrgen.simulate(spring, (0.0, 2.0), [0.1, 0.0], params=P[k], inputs={"F": 0.5},
                               t_eval=T)
        table = lagrgen.evaluate_outputs(spring, ref)
        assert_array_equal(ens.outputs[k], np.asarray(table)[:len(spring.output_names)])
        assert_allclose(ens.outputs[k, 0], -P[k, 1] * ens.y[k, 0], rtol=1e-14)
    none = lagrgen.simulate_many(spring, (0.0, 2.0), [0.1, 0.0], params=P, t_eval=T)
    assert none.outputs is None and none.multipliers is None


def test_to_xarray_labels_and_units(spring):
    xr = pytest.importorskip("xarray")
    P = np.tile(spring.defaults, (3, 1))
    P[:, 0] = [1.0, 2.0, 3.0]
    ens = lagrgen.simulate_many(spring, (0.0, 2.0), [0.1, 0.0], params=P, t_eval=T,
                                outputs=True)
    ds = ens.to_xarray()
    assert isinstance(ds, xr.Dataset)
    assert ds.y.dims == ("run", "state", "time") and ds.y.shape == (3, 2, len(T))
    assert list(ds.state.values) == ["x", "x_dot"]
    assert_array_equal(ds.time.values, T)
    assert ds.time.attrs["units"] == "s"
    assert_array_equal(ds.y.values, ens.y)
    assert_array_equal(ds.m.values, [1.0, 2.0, 3.0]) and ds.m.dims == ("run",)
    assert ds.m.attrs["units"] == "kg" and ds.k.attrs["units"] == "N/m"
    assert ds.y.attrs["state_units"] == ["m", "m/s"]
    assert ds.success.dtype == bool and ds.success.all() and ds.status.dims == ("run",)
    assert list(ds.output.values) == list(spring.output_names)
    assert ds.outputs.attrs["output_units"][0] == "N"
    assert_array_equal(ds.outputs.sel(output="spring_force").values, ens.outputs[:, 0])


def test_a_zarr_store_holds_the_same_dataset(mod, tmp_path):
    pytest.importorskip("zarr")
    P = masses(mod, 37)
    local = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                  workers=2, outputs=True)
    path = tmp_path / "runs.zarr"
    stored = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                   workers=2, outputs=True, store=path)
    assert type(stored.y.data).__module__.startswith("dask")        # read lazily
    assert stored.y.chunks[0][0] < 37                               # written chunk by chunk
    ds = local.to_xarray()
    for name in ("y", "outputs", "success", "status", "nfev", "m1", "g"):
        assert_array_equal(stored[name].values, ds[name].values)
        assert stored[name].dims == ds[name].dims
    assert list(stored.state.values) == list(ds.state.values)
    assert stored.attrs["complete"] is True and stored.attrs["method"] == "RK45"
    assert stored.attrs["messages"] == {}
    assert {k: v for k, v in stored.attrs.items() if k not in ("complete", "messages")} == \
        ds.attrs
    again = lagrgen.open_ensemble(str(path))
    assert_array_equal(again.y.values, local.y)
    assert again.y.attrs == ds.y.attrs
    replaced = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P[:5], t_eval=T,
                                     store=path)     # a new ensemble replaces an ensemble store
    assert replaced.sizes["run"] == 5 and "outputs" not in replaced
    assert_array_equal(replaced.y.values, local.y[:5])


def test_a_dask_local_cluster_gives_the_local_result_bit_for_bit(mod, client, tmp_path):
    pytest.importorskip("zarr")
    P = masses(mod, 24)
    P[:, 4] = np.linspace(5.0, 12.0, 24)
    local = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                  method="RK45", workers=1)
    remote = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                   method="RK45", client=client)
    assert_array_equal(remote.y, local.y)
    assert list(remote.nfev) == list(local.nfev) and remote.success.all()
    assert remote.message == local.message
    P[5, 0] = -1.0          # M not positive definite: a failed run, its message kept
    local = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                  method="RK45", workers=2)
    stored = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                   method="RK45", client=client, store=tmp_path / "d.zarr")
    assert_array_equal(stored.y.values, local.y)
    assert list(stored.nfev.values) == list(local.nfev)
    assert list(stored.success.values) == list(local.success) and not local.success[5]
    assert stored.attrs["messages"] == {"5": local.message[5]}
    assert "not positive definite" in local.message[5]
    py = lagrgen.build(DOUBLE, backend="python")
    remote_py = lagrgen.simulate_many(py, (0.0, 2.0), [0.4, 0, 0, 0], params=P[:2], t_eval=T,
                                      method="RK45", client=client)
    assert_allclose(remote_py.y, local.y[:2], rtol=1e-10, atol=1e-12)


@pytest.mark.filterwarnings("ignore:Consolidated metadata")
def test_bad_ensemble_arguments(mod, tmp_path):
    with pytest.raises(ValueError, match="t_eval"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0])
    with pytest.raises(ValueError, match="gives 2 runs but another argument gives 3"):
        lagrgen.simulate_many(mod, (0, 1), np.zeros((3, 4)), params=[{}, {}], t_eval=[0, 1])
    with pytest.raises(ValueError, match="gives 2 runs but another argument gives 3"):
        lagrgen.simulate_many(mod, (0, 1), np.zeros((3, 4)), params=masses(mod, 2),
                              t_eval=[0, 1])
    with pytest.raises(ValueError, match="not within `t_span`"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 2])
    with pytest.raises(ValueError, match="unknown method 'RK99'"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1], method="RK99")
    with pytest.raises(TypeError, match="params"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1], args=(1.0,))
    with pytest.raises(ValueError, match="max_steps must be a positive integer"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1], max_steps=-1)
    with pytest.raises(ValueError, match="workers must be a positive integer"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1], workers=0)
    with pytest.raises(ValueError, match="either workers"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1], workers=2,
                              client=object())
    with pytest.raises(TypeError, match="dask.distributed.Client"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1], client=object())
    P = masses(mod, 2)
    P[1, 2] = np.nan
    with pytest.raises(ValueError, match="run 1 has a NaN"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], params=P, t_eval=[0, 1])
    with pytest.raises(ValueError, match="columns, expected 5"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], params=np.ones((2, 3)),
                              t_eval=[0, 1])
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "notes.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="not an ensemble store"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1],
                              store=tmp_path / "taken")
    assert (tmp_path / "taken" / "notes.txt").read_text() == "mine"
    with pytest.raises(TypeError, match="local path"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0], t_eval=[0, 1], store="s3://b/x")
    with pytest.raises(FileNotFoundError, match="no ensemble store"):
        lagrgen.open_ensemble(tmp_path / "missing.zarr")
    xr = pytest.importorskip("xarray")
    pytest.importorskip("zarr")
    xr.Dataset({"a": ("x", [1.0])}).to_zarr(tmp_path / "other.zarr")
    with pytest.raises(ValueError, match="not an ensemble store") as info:
        lagrgen.open_ensemble(tmp_path / "other.zarr")
    assert isinstance(info.value, lagrgen.StoreError)          # as open_ensemble's Raises says


def test_progress_bar_on_request(mod, capsys):
    lagrgen.simulate_many(mod, (0.0, 1.0), [0.2, 0, 0, 0], params=masses(mod, 5),
                          t_eval=T[:11], progress=True)
    err = capsys.readouterr().err
    assert "5/5" in err and "run" in err
    lagrgen.simulate_many(mod, (0.0, 1.0), [0.2, 0, 0, 0], params=masses(mod, 5),
                          t_eval=T[:11], progress=False)
    assert capsys.readouterr().err == ""


CTRL_C = """
P = np.tile(mod.defaults, (int(sys.argv[1]), 1))
t_end = float(sys.argv[2])
store = None if sys.argv[3] == "-" else sys.argv[3]
lagrgen.simulate_many, lagrgen.open_ensemble      # imported before the clock starts
if store:
    import xarray, zarr
print("start", flush=True)
try:
    lagrgen.simulate_many(mod, (0.0, t_end), [0.5, 0, 0, 0], params=P,
                          t_eval=np.linspace(0, t_end, 11), rtol=1e-10, atol=1e-10, workers=2,
                          progress=False, store=store)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("stopped", time.monotonic() - hit[0], flush=True)
if store:
    print("complete", lagrgen.open_ensemble(store).attrs["complete"], flush=True)
ens = lagrgen.simulate_many(mod, (0.0, 1.0), [0.5, 0, 0, 0], t_eval=[0.0, 1.0], workers=2)
print("usable", bool(ens.success.all()), flush=True)
"""


@pytest.mark.parametrize("runs, t_end, store", [(400000, 10.0, False), (6, 1e5, True)],
                         ids=["many short runs", "a few long runs into a store"])
def test_ctrl_c_stops_every_running_batch_quickly(mod, runs, t_end, store, tmp_path):
    if store:
        pytest.importorskip("zarr")
    script = interrupted_script(mod, CTRL_C)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    path = str(tmp_path / "cut.zarr") if store else "-"
    proc = subprocess.Popen([sys.executable, "-c", script, str(runs), str(t_end), path],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "start"
        waited = time.monotonic()
        while store and not os.path.exists(os.path.join(path, "y")) and \
                time.monotonic() - waited < 30:
            time.sleep(0.05)            # the store is created: the runs are under way
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    lines = out.split("\n")
    assert lines[0].startswith("stopped"), (out, err)
    assert float(lines[0].split()[1]) < 0.5
    if store:
        assert lines.pop(1) == "complete False"
    assert lines[1] == "usable True"


INTERRUPTED_OFTEN = """
import faulthandler, importlib, random, signal, sys
import numpy as np
sys.path.insert(0, {directory!r})
import lagrgen
mod = importlib.import_module({name!r})
def on_alarm(signum, frame):
    raise KeyboardInterrupt
signal.signal(signal.SIGALRM, on_alarm)
P = np.tile(mod.defaults, (200000, 1))
lagrgen.simulate_many(mod, (0.0, 1e-3), [0.5, 0, 0, 0], params=P[:4], t_eval=[0.0, 1e-3],
                      workers=2, progress=False)      # imported before the interrupts start
rng = random.Random(5)
faulthandler.dump_traceback_later(60, exit=True)
for k in range(30):
    signal.setitimer(signal.ITIMER_REAL, rng.uniform(0.02, 0.2))
    try:
        lagrgen.simulate_many(mod, (0.0, 1e-3), [0.5, 0, 0, 0], params=P, t_eval=[0.0, 1e-3],
                              workers=2, progress=False)
        signal.setitimer(signal.ITIMER_REAL, 0)
    except KeyboardInterrupt:
        pass
faulthandler.cancel_dump_traceback_later()
print("interrupted 30 times", flush=True)
"""


def test_ctrl_c_at_any_moment_never_deadlocks_the_pool(mod):
    """30 interrupts at random moments of an ensemble of 400 short chunks: each one returns.
    (A `concurrent.futures` pool deadlocked here: `wait` takes every pending future's lock in a
    Python loop, `submit` its idle Semaphore's, and an interrupt inside left a lock held.)"""
    script = INTERRUPTED_OFTEN.format(directory=os.path.dirname(mod.__file__),
                                      name=mod.__name__)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, timeout=180)
    assert proc.stdout.strip() == "interrupted 30 times", proc.stderr[-3000:]


def test_step_guard_per_run_in_the_batch(mod):
    ens = lagrgen.simulate_many(mod, (0.0, 10.0), [0.5, 0, 0, 0], params=masses(mod, 3),
                                t_eval=[0.0, 10.0], max_steps=5, workers=2)
    ref = lagrgen.simulate(mod, (0.0, 10.0), [0.5, 0, 0, 0], params=masses(mod, 3)[2],
                           t_eval=[0.0, 10.0], max_steps=5)
    assert not ens.success.any() and list(ens.status) == [-1] * 3
    assert ens.message[2] == ref.message and "max_steps" in ref.message
    assert_array_equal(ens.y[2, :, :ref.y.shape[1]], ref.y)


def test_inputs_as_one_vector_or_one_row_per_run(mod):
    shared = lagrgen.simulate_many(mod, (0.0, 1.0), [0.2, 0, 0, 0], inputs=np.array([0.3]),
                                   t_eval=T[:11])
    rows = lagrgen.simulate_many(mod, (0.0, 1.0), [0.2, 0, 0, 0],
                                 inputs=np.array([[0.0], [0.3]]), t_eval=T[:11])
    assert shared.runs == 1 and rows.runs == 2
    ref = lagrgen.simulate(mod, (0.0, 1.0), [0.2, 0, 0, 0], inputs={"F": 0.3}, t_eval=T[:11])
    assert_array_equal(shared.y[0], ref.y)
    assert_array_equal(rows.y[1], ref.y)
    with pytest.raises(ValueError, match="inputs gives 2 runs but another argument gives 3"):
        lagrgen.simulate_many(mod, (0.0, 1.0), np.zeros((3, 4)), inputs=[{}, {}], t_eval=T[:11])


def test_transitions_of_a_nonsmooth_model_per_run(compile_once):
    ball = compile_once(example_model("bouncing_ball"))
    e = np.array([0.9, 0.5])
    P = np.tile(ball.defaults, (2, 1))
    P[:, ball.parameters.index("e")] = e
    t = np.linspace(0.0, 2.0, 11)
    ens = lagrgen.simulate_many(ball, (0.0, 2.0), {"y": 1.0}, params=P, t_eval=t)
    assert len(ens.transitions) == 2
    for k in range(2):
        ref = lagrgen.simulate(ball, (0.0, 2.0), {"y": 1.0}, params=P[k], t_eval=t)
        assert ens.transitions[k] == list(ref.transitions)
        assert_array_equal(ens.y[k], ref.y)
    assert ens.transitions[0][0][1:] == ("floor", "impact")
    assert len(ens.transitions[0]) != len(ens.transitions[1])
