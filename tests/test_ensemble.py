"""Ensembles (issue 10): per-run arguments, failures kept in their rows, threads and a Dask
LocalCluster giving the same numbers as one run at a time."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import lagrgen

from conftest import example_model

DOUBLE = example_model("double_pendulum")
T = np.linspace(0.0, 2.0, 21)


@pytest.fixture(scope="module")
def mod(compile_once):
    return compile_once(DOUBLE)


def test_runs_match_single_simulations_with_per_run_arguments(mod):
    P = np.tile(mod.defaults, (6, 1))
    P[:, 0] = np.linspace(0.5, 2.0, 6)
    Y0 = np.zeros((6, 4))
    Y0[:, 0] = np.linspace(0.1, 0.6, 6)
    inputs = [{"F": 0.1 * k} for k in range(6)]
    ens = lagrgen.simulate_many(mod, (0.0, 2.0), Y0, params=P, inputs=inputs, t_eval=T,
                                method="DOP853", rtol=1e-9, atol=1e-11, workers=2)
    assert ens.y.shape == (6, 4, len(T)) and ens.runs == 6 and ens.success.all()
    assert_allclose(ens.t, T)
    for k in range(6):
        ref = lagrgen.simulate(mod, (0.0, 2.0), Y0[k], method="DOP853", params=P[k],
                               inputs=inputs[k], rtol=1e-9, atol=1e-11, t_eval=T)
        assert_allclose(ens.y[k], ref.y, rtol=0, atol=0)
        assert ens.nfev[k] == ref.nfev
    assert ens.q.shape == ens.qd.shape == (6, 2, len(T))


def test_a_failed_run_stays_in_its_row(mod):
    params = [{"m1": 1.0}, {"m1": -3.0}, {"m1": 2.0}]
    ens = lagrgen.simulate_many(mod, (0.0, 1.0), {"theta1": 0.3}, params=params, t_eval=T[:11])
    assert list(ens.success) == [True, False, True]
    assert ens.status[1] == -1 and "not positive definite" in ens.message[1]
    assert np.isnan(ens.y[1]).all() and np.isfinite(ens.y[[0, 2]]).all()


def test_bad_ensemble_arguments(mod):
    with pytest.raises(ValueError, match="t_eval"):
        lagrgen.simulate_many(mod, (0, 1), [0.1, 0, 0, 0])
    with pytest.raises(ValueError, match="gives 2 runs but another argument gives 3"):
        lagrgen.simulate_many(mod, (0, 1), np.zeros((3, 4)), params=[{}, {}], t_eval=[0, 1])


def test_a_dask_local_cluster_gives_the_local_result(mod, python_double=None):
    distributed = pytest.importorskip("distributed")
    P = np.tile(mod.defaults, (8, 1))
    P[:, 4] = np.linspace(5.0, 12.0, 8)
    local = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                  method="RK45", workers=1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None,
                                  silence_logs=40) as cluster, distributed.Client(cluster) as client:
        remote = lagrgen.simulate_many(mod, (0.0, 2.0), [0.4, 0, 0, 0], params=P, t_eval=T,
                                       method="RK45", client=client)
        py = lagrgen.build(DOUBLE, backend="python")
        remote_py = lagrgen.simulate_many(py, (0.0, 2.0), [0.4, 0, 0, 0], params=P[:2], t_eval=T,
                                          method="RK45", client=client)
    assert_allclose(remote.y, local.y, rtol=0, atol=0)
    assert list(remote.nfev) == list(local.nfev) and remote.success.all()
    assert_allclose(remote_py.y, local.y[:2], rtol=1e-10, atol=1e-12)
