"""Ensemble stores that keep what is not theirs and say what is damaged (issues 28.1, 32.3,
32.6): a store path is a local directory, never a URL chain; `~` means home on both sides; every
chunk is recorded when written and checked when read back."""
import os

import numpy as np
import pytest
import sympy as sp

import lagrgen
from lagrgen import Model, StoreError, StoreWarning

pytest.importorskip("zarr")
pytest.importorskip("xarray")

T = np.linspace(0.0, 1.0, 11)


def oscillator():
    model = Model("stored_oscillator")
    x, = model.coordinates("x")
    k, = model.parameters(k=4.0)
    model.particle(1, sp.Matrix([x, 0]))
    model.spring(k, x)
    return model


@pytest.fixture(scope="module")
def mod(compile_once):
    return compile_once(oscillator())


def six_runs(mod, store):
    """Six runs in three chunks of two (one thread: chunks of ceil(6 / 4) = 2 runs)."""
    return lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=np.arange(1.0, 7.0)[:, None],
                                 t_eval=T, workers=1, store=store)


# -- 28.1 and 32.6: the store is the directory named, `~` expanded ---------------------------------
def test_a_store_name_with_double_colons_leaves_other_directories_alone(mod, tmp_path,
                                                                        monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results" / "run" / "sub").mkdir(parents=True)
    (tmp_path / "results" / "run" / "notes.txt").write_text("mine")
    (tmp_path / "results" / "run" / "sub" / "data.csv").write_text("1,2")
    with pytest.raises(FileNotFoundError, match="no ensemble store at 'results/run::2.zarr'"):
        lagrgen.open_ensemble("results/run::2.zarr")             # reading one first: nothing
    with pytest.raises(lagrgen.StoreError, match="not a store of lagrgen.simulate_many"):
        lagrgen.open_ensemble("results/run")
    ds = six_runs(mod, "results/run::2.zarr")
    assert (tmp_path / "results" / "run" / "notes.txt").read_text() == "mine"
    assert (tmp_path / "results" / "run" / "sub" / "data.csv").read_text() == "1,2"
    assert (tmp_path / "results" / "run::2.zarr" / "y").is_dir()
    assert ds.success.values.all()
    again = lagrgen.open_ensemble("results/run::2.zarr")
    np.testing.assert_array_equal(again.y.values, ds.y.values)
    ds = six_runs(mod, "results/run::2.zarr")        # replacing it touches nothing else
    assert sorted(os.listdir(tmp_path / "results")) == ["run", "run::2.zarr"]


def test_a_tilde_means_home_when_writing_and_when_reading(mod, tmp_path, monkeypatch):
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(tmp_path)
    six_runs(mod, "~/x.zarr")
    assert (home / "x.zarr" / "y").is_dir() and not (tmp_path / "~").exists()
    assert lagrgen.open_ensemble("~/x.zarr").sizes["run"] == 6


# -- 32.3: a damaged store -----------------------------------------------------------------------
@pytest.fixture
def store(mod, tmp_path):
    path = tmp_path / "runs.zarr"
    whole = six_runs(mod, path)
    return path, whole.y.values.copy()


def test_a_deleted_chunk_reads_as_damaged_runs_never_as_successful_ones(store):
    path, y = store
    os.remove(path / "y" / "1.0.0")
    with pytest.warns(StoreWarning, match="runs 2–3: the chunk file y/1.0.0 is missing"):
        ds = lagrgen.open_ensemble(path)
    assert ds.success.values.tolist() == [True, True, False, False, True, True]
    assert ds.status.values.tolist() == [0, 0, -3, -3, 0, 0]
    assert np.isnan(ds.y.values[2:4]).all()
    np.testing.assert_array_equal(ds.y.values[[0, 1, 4, 5]], y[[0, 1, 4, 5]])
    assert ds.attrs["damaged"] == {"2": "the chunk file y/1.0.0 is missing"}


def test_a_deleted_array_marks_every_run(store):
    import shutil
    path, _ = store
    shutil.rmtree(path / "y")
    with pytest.warns(StoreWarning, match="runs 0–1: the chunk file y/0.0.0 is missing"):
        ds = lagrgen.open_ensemble(path)
    assert not ds.success.values.any() and (ds.status.values == -3).all()


def test_changed_or_corrupt_chunks_fail_their_checksum(store):
    import zarr
    path, y = store
    array = zarr.open_group(str(path), mode="r+")["y"]
    array[4, 0, 3] = 42.0                                  # a valid chunk with other numbers
    (path / "status" / "0").write_bytes(b"\x00junk, not a chunk")
    with pytest.warns(StoreWarning) as caught:
        ds = lagrgen.open_ensemble(path)
    message = str(caught[0].message)
    assert "runs 0–1: status/0 cannot be decoded" in message or \
        "runs 0–1: status/0 does not match its checksum" in message
    assert "runs 4–5: y/2.0.0 does not match its checksum" in message
    assert ds.success.values.tolist() == [False, False, True, True, False, False]
    np.testing.assert_array_equal(ds.y.values[2:4], y[2:4])
    quick = lagrgen.open_ensemble(path, verify=False)     # files present: not checked
    assert quick.success.values[4]


def test_damaged_metadata_is_a_clear_error(store):
    path, _ = store
    (path / ".zmetadata").write_bytes(b"\xff\xfe binary junk")
    with pytest.raises(StoreError, match="cannot be read as an ensemble store"):
        lagrgen.open_ensemble(path)


# -- 28.3: a model rebuilt under the same name on one Dask client --------------------------------
def spring(law):
    """The model "rebuilt": one name, its force law changed between builds."""
    model = Model("rebuilt_on_dask")
    x, = model.coordinates("x")
    k, = model.parameters(k=4.0)
    model.particle(1, sp.Matrix([x, 0]))
    model.potential_energy(k * x ** 2 / 2 if law == "linear" else k * x ** 4 / 4)
    return model


@pytest.fixture(scope="module")
def threads_client():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=":0", silence_logs=40) as cluster, \
            distributed.Client(cluster) as c:
        yield c


def test_a_client_restarted_between_ensembles_gets_the_model_again(dask_client, tmp_path):
    """client.restart() (workers restarted, their data dropped) between two calls: the second
    ships the module again (it raised a raw TypeError from a cancelled future)."""
    mod = lagrgen.build(spring("linear"), out_dir=tmp_path)
    P = np.linspace(1.0, 3.0, 4)[:, None]
    first = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=P, t_eval=T, client=dask_client)
    dask_client.restart()
    again = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=P, t_eval=T, client=dask_client)
    np.testing.assert_array_equal(again.y, first.y)


@pytest.mark.parametrize("cluster", ["processes", "threads"])
def test_a_model_rebuilt_under_the_same_name_runs_its_own_equations(cluster, dask_client,
                                                                    threads_client, tmp_path):
    """Edit a model and re-run with one long-lived client: each build's numbers, never the
    previous module's (process workers) and no crash (workers in this process)."""
    client = dask_client if cluster == "processes" else threads_client
    P = np.linspace(1.0, 3.0, 8)[:, None]
    for law in ("linear", "quartic", "linear"):
        mod = lagrgen.build(spring(law), out_dir=tmp_path)
        local = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=P, t_eval=T, workers=1)
        remote = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=P, t_eval=T,
                                       client=client)
        np.testing.assert_array_equal(remote.y, local.y)
    quartic = lagrgen.build(spring("quartic"), out_dir=tmp_path)
    assert not np.allclose(lagrgen.simulate_many(quartic, (0, 1), [1.0, 0.0], params=P,
                                                 t_eval=T, client=client).y, local.y)


# -- 37.12: sensitivities of an ensemble, here and on Dask workers ---------------------------------
SENSITIVITIES = ["k", "y0:x"]
K = np.array([[2.0], [4.0], [9.0]])


def test_an_ensemble_returns_each_runs_sensitivities(mod):
    """(runs, k, 2n, len(t)): per run those of `simulate(..., sensitivities=...)` (its states
    too), and x = cos(√k·t) gives ∂x/∂k = −t·sin(√k·t)/(2√k) and ∂x/∂x0 = cos(√k·t)."""
    for engine in ("native", "scipy"):
        ens = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=K, t_eval=T, workers=1,
                                    sensitivities=SENSITIVITIES, rtol=1e-10, atol=1e-12,
                                    engine=engine)
        assert ens.success.all() and ens.engines == [engine] * 3
        assert ens.sensitivities.shape == (3, 2, 2, len(T))
        assert ens.sensitivity_names == ("k", "y0:x")
        for run, (k,) in enumerate(K):
            alone = lagrgen.simulate(mod, (0, 1), [1.0, 0.0], params=[k], t_eval=T,
                                     sensitivities=SENSITIVITIES, rtol=1e-10, atol=1e-12,
                                     engine=engine)
            np.testing.assert_array_equal(ens.sensitivities[run], alone.sensitivities)
            np.testing.assert_array_equal(ens.y[run], alone.y)
            w = np.sqrt(k)
            np.testing.assert_allclose(ens.sensitivities[run, 0, 0],
                                       -T * np.sin(w * T) / (2 * w), atol=1e-8)
            np.testing.assert_allclose(ens.sensitivities[run, 1, 0], np.cos(w * T), atol=1e-8)
    plain = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=K, t_eval=T, workers=1)
    assert plain.sensitivities is None and plain.sensitivity_names == ()


def test_ensemble_sensitivities_are_labelled_and_stored(mod, tmp_path):
    ens = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=K, t_eval=T, workers=1,
                                sensitivities=SENSITIVITIES)
    ds = ens.to_xarray()
    assert ds.sensitivities.dims == ("run", "sensitivity", "state", "time")
    assert ds.sensitivity.values.tolist() == SENSITIVITIES
    np.testing.assert_array_equal(ds.sensitivities.values, ens.sensitivities)
    stored = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=K, t_eval=T, workers=1,
                                   sensitivities=SENSITIVITIES, store=tmp_path / "s.zarr")
    np.testing.assert_array_equal(stored.sensitivities.values, ens.sensitivities)
    assert lagrgen.open_ensemble(tmp_path / "s.zarr").sensitivity.values.tolist() == \
        SENSITIVITIES
    import shutil
    shutil.rmtree(tmp_path / "s.zarr" / "sensitivities")
    with pytest.warns(StoreWarning, match="the chunk file sensitivities/0.0.0.0 is missing"):
        assert not lagrgen.open_ensemble(tmp_path / "s.zarr").success.values.any()


def test_ensemble_sensitivities_that_cannot_be_had_are_refused_before_any_run(mod):
    with pytest.raises(lagrgen.UnknownNameError, match="unknown parameter name 'm'"):
        lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], t_eval=T, sensitivities=["m"])
    model = Model("sensitive_ball")
    y, = model.coordinates("y")
    model.particle(1, sp.Matrix([0, y]))
    model.potential_energy(9.81 * y)
    model.impact("floor", y)
    ball = lagrgen.build(model, backend="python")
    with pytest.raises(ValueError, match="sensitivities are computed for smooth models"):
        lagrgen.simulate_many(ball, (0, 1), [1.0, 0.0], t_eval=T, sensitivities=["y0:y"])


@pytest.mark.parametrize("cluster", ["processes", "threads"])
def test_dask_workers_get_the_units_the_runs_call(cluster, dask_client, threads_client, mod,
                                                  tmp_path):
    """The directional derivatives (a unit compiled on first use) go to the workers with the
    module: every run failed there, looking for a cache entry in the worker's directory."""
    client = dask_client if cluster == "processes" else threads_client
    local = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=K, t_eval=T, workers=1,
                                  sensitivities=SENSITIVITIES)
    remote = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=K, t_eval=T, client=client,
                                   sensitivities=SENSITIVITIES)
    assert remote.success.all(), remote.message
    np.testing.assert_array_equal(remote.sensitivities, local.sensitivities)
    np.testing.assert_array_equal(remote.y, local.y)
    stored = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=K, t_eval=T, client=client,
                                   sensitivities=SENSITIVITIES, store=tmp_path / "d.zarr")
    np.testing.assert_array_equal(stored.sensitivities.values, local.sensitivities)
