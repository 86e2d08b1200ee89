"""Physically consistent inertial estimates (identify_inertial(..., consistent=True)) of robots
read from URDF files: the seven-joint arm of examples/robots/arm7.urdf and a UR5-like arm
(tests/data/ur5_like.urdf, the joint placements and inertial values of example-robot-data's
UR5). Torques are the regressor times the file's values, so the file's values are consistent
and fit: the consistent estimate keeps them (every pseudo-inertia positive definite, the links
the records do not see at the file's values, no price); torques of the wrong sign fit no set of
bodies, and that is said (a FitWarning), never returned silently."""
import warnings

import numpy as np
import pytest

import lagrgen
from lagrgen import FitWarning
from lagrgen.inertial import base_parameters, exciting_trajectory, identify_inertial, links_of
from lagrgen.inertial import pseudo_inertia

from conftest import ROOT

ROBOTS = {"arm7": ROOT / "examples" / "robots" / "arm7.urdf",
          "ur5_like": ROOT / "tests" / "data" / "ur5_like.urdf"}


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def robot(request, tmp_path_factory):
    """The robot with its inertial parameters, base parameters and 10 s of 1 kHz records of an
    exciting trajectory within its limits: t, q, q̇, q̈ and the torques at the file's values."""
    name = request.param
    model = lagrgen.from_urdf(ROBOTS[name], parameters="inertial", joint_dynamics=False,
                              name=f"consistent_{name}")
    mod = lagrgen.build(model, out_dir=tmp_path_factory.mktemp(name))
    base = base_parameters(mod)
    limits = {joint: (None, None, None, 10.0) for joint in mod.coordinates}
    trajectory = exciting_trajectory(mod, 10.0, limits=limits, base=base, max_iterations=10)
    t = np.arange(10000) * 1e-3
    q, qd, qdd = trajectory.q(t), trajectory.qd(t), trajectory.qdd(t)
    truth = dict(zip(mod.parameters, mod.defaults))
    pi = np.array([truth[p] for p in mod.inertial_parameters])
    tau = np.array([mod.regressor(q[:, i], qd[:, i], qdd[:, i]) @ pi for i in range(t.size)]).T
    return mod, base, truth, (t, q, qd, qdd, tau)


def smallest_eigenvalues(pi, names):
    return np.array([np.linalg.eigvalsh(pseudo_inertia({f: pi[names[i]] for f, i in
                                                         fields.items()}))[0]
                     for _, fields in links_of(names)])


def consistent_without_warning(mod, base, *records):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)
        return identify_inertial(mod, *records, consistent=True, base=base)


@pytest.mark.parametrize("noise", [0.0, 1e-6])
def test_the_files_values_fit_and_are_kept(robot, noise):
    """Exact velocities and accelerations: the consistent estimate is the file's values, every
    one of them (those the records see and those they do not, as a link's mass on a fixed
    axis), at no price, without a warning."""
    mod, base, truth, (t, q, qd, qdd, tau) = robot
    tau = tau + noise * np.random.default_rng(3).standard_normal(tau.shape)
    est = consistent_without_warning(mod, base, t, q, tau, qd, qdd)
    assert est.success and "within the noise" in est.message
    assert 0 <= est.price < 1e-6
    names = base.parameters
    assert np.all(smallest_eigenvalues(est.inertial, names) > 0)
    estimate = np.array([est.inertial[p] for p in names])
    file = np.array([truth[p] for p in names])
    assert np.allclose(estimate, file, rtol=1e-6, atol=1e-6 * np.abs(file).max())
    assert len(base.unidentifiable) > 0            # a mass on a fixed axis among them
    for p in base.unidentifiable:                 # untouched, whatever the noise
        assert est.inertial[p] == pytest.approx(truth[p], rel=1e-6, abs=1e-12)


def test_noisy_positions_give_a_consistent_estimate_at_a_negligible_price(robot):
    """Positions with 1e-4 rad and torques with 0.2 N·m of noise, filtered: each link consistent,
    the parameters the torques do not depend on at the file's values, a price of a fraction of a
    percent and no warning."""
    mod, base, truth, (t, q, _, _, tau) = robot
    rng = np.random.default_rng(5)
    est = consistent_without_warning(mod, base, t, q + 1e-4 * rng.standard_normal(q.shape),
                                     tau + 0.2 * rng.standard_normal(tau.shape))
    assert est.success and 0 <= est.price < 0.01
    assert np.all(smallest_eigenvalues(est.inertial, base.parameters) > 0)
    assert np.allclose(base.values(est.inertial), [est.values[n] for n in base.names],
                       rtol=1e-9, atol=1e-9)
    for p in base.unidentifiable:                 # the UR5's shoulder mass stays 3.7 kg
        assert est.inertial[p] == pytest.approx(truth[p], rel=1e-6, abs=1e-12)


def test_torques_of_the_wrong_sign_are_said_to_fit_no_body(robot):
    """−τ: the nearest consistent estimate is far from the records, beyond anything noise
    explains: a FitWarning says so and the message stays on the result; the estimate is still
    physically consistent."""
    mod, base, _, (t, q, qd, qdd, tau) = robot
    tau = -tau + 1e-6 * np.random.default_rng(4).standard_normal(tau.shape)
    with pytest.warns(FitWarning, match="no physically consistent set of links"):
        est = identify_inertial(mod, t, q, tau, qd, qdd, consistent=True, base=base)
    assert est.price > 1e3 and "noise explains" in est.message
    assert np.all(smallest_eigenvalues(est.inertial, base.parameters) > 0)
    assert "physically consistent: residual +" in est.summary()
