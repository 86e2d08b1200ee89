"""A floating base without singularity (issue 44, item 3): `from_urdf(..., base="free")` holds the
base's orientation as a quaternion (`lagrgen.free_base`), `lagrgen.base_state` writes the state
of any floating base. A free brick spun through pitch = π/2 against its closed form; the
recursion in the base's chart against the dense Lagrangian, finite differences, the floating
(roll–pitch–yaw) model away from its singularity and Pinocchio's free-flyer; both engines,
ensembles, linearization, collocation, the FMU and the C's hygiene."""
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

import lagrgen
from conftest import benchmark
from lagrgen.base_state import quaternion_of, quaternion_product
from lagrgen.urdf import FREE_BASE, rpy_matrix

ROOT = Path(__file__).resolve().parent.parent
BRICK = ROOT / "examples" / "robots" / "brick.urdf"
QUADRUPED = ROOT / "examples" / "robots" / "quadruped.urdf"
#: The brick's principal moments (body axes x, y, z: y is the major axis) and mass.
MOMENTS, MASS = np.array([0.2 / 3, 0.26 / 3, 0.1 / 3]), 2.0


def hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def rotation_of(z):
    """The rotation matrix of the direction of the quaternion z = (x, y, z, w)."""
    x, y, zz, w = np.asarray(z) / np.linalg.norm(z)
    return np.array([[1 - 2 * (y * y + zz * zz), 2 * (x * y - w * zz), 2 * (x * zz + w * y)],
                     [2 * (x * y + w * zz), 1 - 2 * (x * x + zz * zz), 2 * (y * zz - w * x)],
                     [2 * (x * zz - w * y), 2 * (y * zz + w * x), 1 - 2 * (x * x + y * y)]])


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("free_base")


@pytest.fixture(scope="module")
def brick(out):
    return lagrgen.build(lagrgen.from_urdf(BRICK, base="free"), out_dir=out, quiet=True)


@pytest.fixture(scope="module")
def brick_python():
    return lagrgen.build(lagrgen.from_urdf(BRICK, base="free", name="brick_py"), backend="python")


@pytest.fixture(scope="module")
def quadruped(out):
    """The quadruped with a free base and with a floating one (rigid-body dynamics only)."""
    free = lagrgen.from_urdf(QUADRUPED, base="free", joint_dynamics=False, name="quad_free",
                             limits=False)
    floating = lagrgen.from_urdf(QUADRUPED, base="floating", joint_dynamics=False,
                                 name="quad_floating", limits=False)
    return (lagrgen.build(free, out_dir=out, quiet=True),
            lagrgen.build(floating, out_dir=out, quiet=True))


# -- the model ----------------------------------------------------------------------------------
def test_a_free_base_has_a_quaternion_its_inputs_outputs_and_an_upright_start(brick, quadruped):
    free, _ = quadruped
    assert brick.coordinates == FREE_BASE and brick.formulation == "recursive"
    assert free.coordinates[:7] == FREE_BASE and free.coordinates[7:10] == (
        "FL_abad", "FL_hip_joint", "FL_knee")
    assert brick.inputs == ("force_base_x", "force_base_y", "force_base_z", "torque_base_x",
                            "torque_base_y", "torque_base_z")
    assert free.inputs[:3] == ("tau_FL_abad", "tau_FL_hip_joint", "tau_FL_knee")
    assert brick.output_names[:3] == ("base_roll", "base_pitch", "base_yaw")
    y0 = np.zeros(14)
    y0[6] = 1.0
    assert np.array_equal(brick.initial_state, y0)
    assert brick.units["base_qw"] in ("1", "") and brick.units["base_x"] == "m"
    sol = lagrgen.simulate(brick, (0.0, 0.5))      # from the declared state: falls upright
    assert sol.success and sol.y[2, -1] == pytest.approx(-9.81 / 8, rel=1e-9)
    assert np.allclose(sol.y[3:7, -1], [0, 0, 0, 1], atol=1e-12)


def test_a_free_base_refuses_mimic_joints_and_a_zero_quaternion(tmp_path, brick):
    text = QUADRUPED.read_text().replace(
        '<joint name="FR_abad" type="revolute">',
        '<joint name="FR_abad" type="revolute"><mimic joint="FL_abad"/>')
    path = tmp_path / "mimic.urdf"
    path.write_text(text)
    with pytest.raises(lagrgen.ModelError, match="mimic=False"):
        lagrgen.from_urdf(path, base="free")
    with pytest.raises(lagrgen.MassMatrixError):
        brick.rhs(0.0, np.zeros(14))
    with pytest.raises(lagrgen.ModelError, match="'fixed', 'floating' or 'free'"):
        lagrgen.from_urdf(BRICK, base="quaternion")


# -- base_state ---------------------------------------------------------------------------------
def test_base_state_writes_pose_velocities_and_joints_and_round_trips(brick, quadruped):
    free, floating = quadruped
    rpy, omega, v = (0.3, -1.2, 2.5), np.array([0.4, -0.7, 1.1]), (0.1, -0.2, 0.3)
    joints = {"FL_knee": -1.1, "HR_abad": 0.2}
    rates = {"FL_knee": 0.5}
    for mod in (free, floating):
        y = lagrgen.base_state(mod, position=(1, 2, 3), rpy=rpy, velocity=v,
                               angular_velocity=omega, q=joints, qd=rates)
        n = mod.n_coordinates
        assert y.shape == (2 * n,) and np.array_equal(y[:3], [1, 2, 3])
        assert np.array_equal(y[n:n + 3], v)
        for name, value in joints.items():
            assert y[mod.coordinates.index(name)] == value
        assert y[n + mod.coordinates.index("FL_knee")] == 0.5
        assert np.count_nonzero(y[n + 7 if mod is free else n + 6:]) == 1
        if mod is free:
            z, zd = y[3:7], y[n + 3:n + 7]
            assert np.linalg.norm(z) == pytest.approx(1, abs=1e-15) and z @ zd == pytest.approx(
                0, abs=1e-15)
            assert np.allclose(rotation_of(z), rpy_matrix(rpy), atol=1e-15)
            back = 2 * quaternion_product(zd, z * [-1, -1, -1, 1])[:3]
            assert np.allclose(back, omega, atol=1e-15)
            roll_pitch_yaw = mod.outputs(0.0, y)[:3]
            assert np.allclose(roll_pitch_yaw, rpy, atol=1e-14)
        else:
            assert np.array_equal(y[3:6], rpy)
            roll, pitch, yaw = rpy
            rd, pd, yd = y[n + 3:n + 6]
            Rz = np.array(rpy_matrix((0, 0, yaw)))
            Rzy = np.array(rpy_matrix((0, pitch, yaw)))
            assert np.allclose(yd * np.eye(3)[2] + Rz @ [0, pd, 0] + Rzy @ [rd, 0, 0], omega,
                               atol=1e-14)
    # the quaternion of every rotation (w ≥ 0, Shepperd's branches)
    rng = np.random.default_rng(2)
    for angles in [(np.pi, 0, 0), (0, np.pi, 0), (0, 0, np.pi), (0.1, 0.2, 3.1)] + \
            list(rng.uniform(-np.pi, np.pi, (20, 3))):
        R = np.array(rpy_matrix(angles))
        z = quaternion_of(R)
        assert z[3] >= 0 and np.allclose(rotation_of(z), R, atol=1e-14)
    with pytest.raises(lagrgen.ModelError, match="not a joint"):
        lagrgen.base_state(free, q={"base_qw": 1.0})
    with pytest.raises(lagrgen.ModelError, match=r"at pitch 1\.5707963267948966 .*gimbal lock"):
        lagrgen.base_state(floating, rpy=(0, np.pi / 2, 0), angular_velocity=(1, 0, 0))
    locked = lagrgen.base_state(floating, rpy=(0.2, np.pi / 2, 0.1))   # at rest: zero rates
    n = floating.n_coordinates
    assert np.allclose(locked[3:6], [0.2, np.pi / 2, 0.1]) and not locked[n:].any()
    with pytest.raises(lagrgen.ModelError, match="3 numbers"):
        lagrgen.base_state(brick, position=(0, 0))
    arm = lagrgen.from_urdf(ROOT / "examples" / "robots" / "arm7.urdf")
    with pytest.raises(lagrgen.ModelError, match="floating base"):
        lagrgen.base_state(arm)


# -- accuracy through pitch = π/2 ------------------------------------------------------------------
@pytest.mark.parametrize("engine", ["native", "scipy"])
def test_a_free_brick_spun_through_gimbal_lock_keeps_the_requested_accuracy(brick, engine):
    """Spun about its major axis (body y) from pitch π/2 − 1e-6: a steady rotation, R(t) =
    R0·exp(t·[ω]×), while the centre falls. (Roll–pitch–yaw coordinates: M singular on the way,
    or, passing 1e-6 beside the singularity, 1e-5 off after 4e7 steps.)"""
    rpy0, wb, T = (0.0, np.pi / 2 - 1e-6, 0.4), np.array([0.0, 5.0, 0.0]), 3.0
    R0 = np.array(rpy_matrix(rpy0))
    y0 = lagrgen.base_state(brick, position=(0, 0, 1), rpy=rpy0, velocity=(0.1, 0, 0),
                            angular_velocity=R0 @ wb)
    sol = lagrgen.simulate(brick, (0.0, T), y0, method="DOP853", rtol=1e-9, atol=1e-9,
                           engine=engine)
    assert sol.success
    y = sol.y[:, -1]
    assert np.abs(rotation_of(y[3:7]) - R0 @ expm(T * hat(wb))).max() < 2e-8
    assert np.allclose(y[:3], [0.1 * T, 0.0, 1 - 9.81 * T * T / 2], atol=1e-9)
    assert abs(np.linalg.norm(y[3:7]) - 1) < 1e-8


def test_a_tumbling_brick_matches_an_independent_integration(brick):
    """Torque-free tumbling (ω not along a principal axis): the orientation against Euler's
    equations in body rates with R' = R·[ω]×, integrated at 1e-13."""
    from scipy.integrate import solve_ivp
    I = MOMENTS
    R0, wb, T = np.array(rpy_matrix((0.4, 1.5, -0.7))), np.array([1.0, 0.3, 4.0]), 2.0

    def euler(t, x):
        R, w = x[:9].reshape(3, 3), x[9:]
        return np.concatenate([(R @ hat(w)).ravel(), (np.cross(I * w, w)) / I])
    ref = solve_ivp(euler, (0, T), np.concatenate([R0.ravel(), wb]), method="DOP853",
                    rtol=1e-13, atol=1e-13).y[:9, -1].reshape(3, 3)
    y0 = lagrgen.base_state(brick, rpy=(0.4, 1.5, -0.7), angular_velocity=R0 @ wb)
    sol = lagrgen.simulate(brick, (0.0, T), y0, method="DOP853", rtol=1e-11, atol=1e-11)
    assert np.abs(rotation_of(sol.y[3:7, -1]) - ref).max() < 1e-9
    energy = [brick.outputs(t, y)[brick.output_names.index("total_energy")]
              for t, y in zip(sol.t, sol.y.T)]
    kinetic = 0.5 * wb @ (I * wb)
    assert abs(energy[0] - kinetic) < 1e-12 * kinetic
    assert np.ptp(energy) < 1e-9 * kinetic


# -- the recursion in the chart ----------------------------------------------------------------
def random_state(mod, rng, scale=0.7):
    """A state with a quaternion of length ≠ 1 and rates off the sphere (the equations hold for
    any nonzero quaternion)."""
    y = rng.normal(size=2 * mod.n_coordinates) * scale
    y[3:7] *= 1.3
    return y


def test_the_recursion_equals_the_dense_lagrangian_of_a_free_brick(out):
    """Every function of the recursive formulation (C and Python) against the dense formulation
    of the same Lagrangian (quaternion coordinates, the length's inertia), inertial parameters
    included."""
    model = lagrgen.from_urdf(BRICK, base="free", parameters="inertial", name="brick_pi")
    dense = lagrgen.build(model, backend="python", formulation="dense")
    recursive = [lagrgen.build(model, out_dir=out, quiet=True),
                 lagrgen.build(model, backend="python", formulation="recursive")]
    rng = np.random.default_rng(4)
    n, k = 7, len(model.parameter_names)
    for _ in range(3):
        y, a, u = random_state(dense, rng), rng.normal(size=7), rng.normal(size=6)
        dy, dp = rng.normal(size=(2, 14)), rng.normal(size=(2, k))
        for mod in recursive:
            assert mod.formulation == "recursive"
            for name, args in (("mass_matrix", (y[:n],)), ("forcing", (y[:n], y[n:])),
                               ("rhs", (0.0, y)), ("jacobian", (0.0, y)),
                               ("parameter_jacobian", (0.0, y)), ("linear_terms", (y[:n], y[n:])),
                               ("residual_terms", (y[:n], y[n:], a)),
                               ("regressor", (y[:n], y[n:], a)),
                               ("directional_derivatives", (0.0, y, dy, dp)),
                               ("outputs", (0.0, y))):
                ours = getattr(mod, name)(*args, u=u)
                theirs = getattr(dense, name)(*args, u=u)
                for x1, x2 in zip(*(r if isinstance(r, tuple) else (r,) for r in (ours, theirs))):
                    scale = max(1.0, np.abs(x2).max())
                    assert np.allclose(x1, x2, rtol=1e-11, atol=1e-11 * scale), name


def test_the_free_quadrupeds_jacobians_equal_finite_differences(quadruped):
    free, _ = quadruped
    rng = np.random.default_rng(7)
    n = free.n_coordinates
    u = rng.normal(size=len(free.inputs))
    for _ in range(2):
        y = random_state(free, rng, 0.5)
        J = free.jacobian(0.0, y, u=u)
        h = 1e-6
        fd = np.column_stack([(free.rhs(0.0, y + h * e, u=u) - free.rhs(0.0, y - h * e, u=u))
                              / (2 * h) for e in np.eye(2 * n)])
        assert np.abs(J - fd).max() < 1e-6 * max(1, np.abs(fd).max())
        a = rng.normal(size=n)
        r, dr_dy, dr_da, dr_du = free.residual_terms(y[:n], y[n:], a, u=u)
        fd = np.column_stack([(free.residual_terms(*np.split(y + h * e, 2), a, u=u)[0]
                               - free.residual_terms(*np.split(y - h * e, 2), a, u=u)[0])
                              / (2 * h) for e in np.eye(2 * n)])
        assert np.abs(dr_dy - fd).max() < 1e-6 * max(1, np.abs(fd).max())
        M = free.mass_matrix(y[:n])
        assert np.allclose(dr_da, M) and np.allclose(r, M @ a - free.forcing(y[:n], y[n:], u=u))


def floating_of_free(y, n_free):
    """The floating (roll–pitch–yaw) state of a free base's state (unit quaternion)."""
    n = n_free - 1
    z, zd = y[3:7], y[n_free + 3:n_free + 7]
    R = rotation_of(z)
    roll, pitch, yaw = np.arctan2(R[2, 1], R[2, 2]), np.arcsin(-R[2, 0]), np.arctan2(R[1, 0],
                                                                                        R[0, 0])
    omega = 2 * quaternion_product(zd, z * [-1, -1, -1, 1])[:3]
    from lagrgen.base_state import rpy_rates
    out = np.zeros(2 * n)
    out[:3], out[3:6], out[6:n] = y[:3], (roll, pitch, yaw), y[7:n_free]
    out[n:n + 3], out[n + 3:n + 6] = y[n_free:n_free + 3], rpy_rates((roll, pitch, yaw), omega)
    out[n + 6:] = y[n_free + 7:]
    return out


def test_the_free_quadruped_moves_as_the_floating_one_away_from_gimbal_lock(quadruped):
    """A pure NumPy check: the same motion integrated in both coordinates, the states converted."""
    free, floating = quadruped
    joints = [c for c in free.coordinates[7:]]
    rng = np.random.default_rng(3)
    start = dict(position=(0.1, -0.2, 0.5), rpy=(0.3, -0.4, 1.0), velocity=(0.5, 0.2, 1.0),
                 angular_velocity=(0.6, -0.8, 0.4), q=dict(zip(joints, rng.uniform(-0.4, 0.4, 12))),
                 qd=dict(zip(joints, rng.uniform(-1, 1, 12))))
    ours = lagrgen.simulate(free, (0, 0.5), lagrgen.base_state(free, **start), method="DOP853",
                            rtol=1e-11, atol=1e-11)
    theirs = lagrgen.simulate(floating, (0, 0.5), lagrgen.base_state(floating, **start),
                              method="DOP853", rtol=1e-11, atol=1e-11)
    assert abs(theirs.y[4, -1]) < 1.2        # far from pitch ±π/2
    assert np.allclose(floating_of_free(ours.y[:, -1], 19), theirs.y[:, -1], atol=1e-8)
    y = ours.y[:, 3]
    assert np.allclose(free.outputs(0.0, y)[:3], floating_of_free(y, 19)[3:6], atol=1e-12)
    energies = floating.outputs(0.0, floating_of_free(y, 19))[-3:]
    assert abs(energies[0]) > 1.0
    assert np.allclose(free.outputs(0.0, y)[-3:], energies, rtol=1e-9, atol=1e-9)


def pinocchio_tumble(path, mod, T=1.0):
    """(ours, Pinocchio's) final states of a robot tumbling from pitch 1.57: Pinocchio's
    free-flyer (its aba, the quaternion's kinematics with the local velocity) integrated at 1e-12,
    ours at 1e-11."""
    pin = pytest.importorskip("pinocchio")
    free_base = benchmark("free_base")
    pm = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    assert mod.coordinates[7:] == tuple(pm.names[2:])
    y0 = lagrgen.base_state(mod, **free_base.tumble_start(mod.coordinates[7:]))
    ref = free_base.pinocchio_reference(pm, y0, T)
    sol = lagrgen.simulate(mod, (0, T), y0, method="DOP853", rtol=1e-11, atol=1e-11)
    assert sol.success
    return sol.y[:, -1], ref


def assert_same_motion(ours, ref, n):
    assert np.abs(ours[:3] - ref[:3]).max() < 1e-8
    assert np.abs(rotation_of(ours[3:7]) - rotation_of(ref[3:7])).max() < 1e-8
    assert np.abs(ours[7:n] - ref[7:n]).max() < 1e-8


def test_the_quadruped_tumbling_from_pitch_157_equals_pinocchios_free_flyer(quadruped):
    mod, _ = quadruped
    ours, ref = pinocchio_tumble(QUADRUPED, mod)
    assert_same_motion(ours, ref, mod.n_coordinates)


def test_solo12_tumbling_from_pitch_157_equals_pinocchios_free_flyer(out):
    pytest.importorskip("pinocchio")
    try:
        root = benchmark("robots").robots_dir()
    except SystemExit:
        pytest.skip("example-robot-data is not installed")
    path = root / "solo_description" / "robots" / "solo12.urdf"
    mod = lagrgen.build(lagrgen.from_urdf(path, base="free", joint_dynamics=False),
                        out_dir=out, quiet=True)
    ours, ref = pinocchio_tumble(path, mod)
    assert_same_motion(ours, ref, mod.n_coordinates)


def test_a_tumbling_quadruped_keeps_its_energy_and_runs_as_an_ensemble(quadruped):
    free, _ = quadruped
    rng = np.random.default_rng(5)
    joints = free.coordinates[7:]
    starts = [lagrgen.base_state(free, rpy=tuple(rng.uniform(-3, 3, 3)),
                                 angular_velocity=tuple(rng.uniform(-4, 4, 3)),
                                 qd=dict(zip(joints, rng.uniform(-2, 2, 12)))) for _ in range(3)]
    runs = [lagrgen.simulate(free, (0, 1.0), y0, method="DOP853", rtol=1e-10, atol=1e-10)
            for y0 in starts]
    index = free.output_names.index("total_energy")
    for sol in runs:
        energy = [free.outputs(t, y)[index] for t, y in zip(sol.t, sol.y.T)]
        assert np.ptp(energy) < 1e-8 * max(1, abs(energy[0]))
    batch = lagrgen.simulate_many(free, (0, 1.0), np.array(starts), method="DOP853", rtol=1e-10,
                                  atol=1e-10, t_eval=[1.0])
    for k, sol in enumerate(runs):
        assert np.allclose(np.asarray(batch.y)[k, :, -1], sol.y[:, -1], atol=1e-12)


# -- analysis, optimization, export ------------------------------------------------------------
def test_linearize_about_a_hovering_quadruped(quadruped):
    """Held up by a force on its base and its joints' torques at rest, tilted: an equilibrium;
    A and B against finite differences of the rhs."""
    free, _ = quadruped
    n, k = free.n_coordinates, len(free.inputs)
    y = lagrgen.base_state(free, position=(0, 0, 0.4), rpy=(0.3, 0.5, -0.2),
                           q={"FL_knee": -1.0, "HR_hip_joint": 0.6})
    M, dF_dq, dF_dqd, dF_du = free.linear_terms(y[:n], y[n:])
    F0 = free.forcing(y[:n], y[n:])
    u = np.linalg.lstsq(dF_du, -F0, rcond=None)[0]
    assert np.abs(free.rhs(0.0, y, u=u)).max() < 1e-10
    with warnings.catch_warnings():
        warnings.simplefilter("error", lagrgen.NotAnEquilibriumWarning)
        lin = lagrgen.linearize(free, y[:n], y[n:], u=u)
    h = 1e-6
    A = np.column_stack([(free.rhs(0.0, y + h * e, u=u) - free.rhs(0.0, y - h * e, u=u)) / (2 * h)
                         for e in np.eye(2 * n)])
    B = np.column_stack([(free.rhs(0.0, y, u=u + h * e) - free.rhs(0.0, y, u=u - h * e)) / (2 * h)
                         for e in np.eye(k)])
    assert lin.A.shape == (2 * n, 2 * n) and np.abs(lin.A - A).max() < 1e-6 * np.abs(A).max()
    assert np.abs(lin.B_state - B).max() < 1e-6 * np.abs(B).max()


def test_collocation_turns_a_free_brick_upside_down_through_pitch_pi_over_2(tmp_path):
    """Without gravity, rest to rest from upright to upside down about y in 1 s with the least
    ∫ (torque² + force²): the closed form θ(s) = π·(3s² − 2s³), ∫τ² = 12·I_yy²·π²."""
    pytest.importorskip("cyipopt")
    model = lagrgen.from_urdf(BRICK, base="free", gravity=(0, 0, 0), name="brick_flip")
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    prob = lagrgen.Collocation(mod, nodes=21, duration=1.0, scheme="hermite-simpson")
    start = lagrgen.base_state(mod)
    end = lagrgen.base_state(mod, rpy=(0.0, np.pi, 0.0))
    prob.initial(q=start[:7], qd=start[7:])
    prob.final(q=end[:7], qd=end[7:])
    forces = model.input_functions
    prob.minimize(integral=sum(f ** 2 for f in forces))
    res = prob.solve(progress=False)
    assert res.success and res.error < 1e-6
    assert res.objective == pytest.approx(12 * MOMENTS[1] ** 2 * np.pi ** 2, rel=1e-4)
    pitch = [mod.outputs(t, y)[1] for t, y in zip(res.t, res.y.T)]
    assert max(pitch) == pytest.approx(np.pi / 2, abs=1e-3)     # through the lock at t = ½
    assert np.allclose(np.linalg.norm(res.y[3:7], axis=0), 1, atol=1e-6)


def test_a_free_base_exports_warning_free_c_and_a_valid_fmu(tmp_path, brick):
    from lagrgen.build import export_c
    model = lagrgen.from_urdf(QUADRUPED, base="free", parameters="inertial", name="quad_export")
    files = export_c(model, out_dir=tmp_path)
    source = next(f for f in files if str(f).endswith(".c"))
    if shutil.which("gcc"):
        compiled = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror",
                                   "-c", str(source), "-o", str(tmp_path / "quad.o")],
                                  capture_output=True, text=True)
        assert compiled.returncode == 0, compiled.stderr[-3000:]
    fmpy = pytest.importorskip("fmpy")
    from fmpy.validation import validate_fmu
    fmu = lagrgen.export_fmu(lagrgen.from_urdf(BRICK, base="free"), tmp_path)
    assert validate_fmu(str(fmu)) == []
    start = {"base_qx": 0.0, "base_qy": np.sin(0.7), "base_qz": 0.0, "base_qw": np.cos(0.7),
             "base_qy_dot": np.cos(0.7), "base_qw_dot": -np.sin(0.7)}
    result = fmpy.simulate_fmu(str(fmu), stop_time=0.4, output_interval=0.1, start_values=start)
    y0 = np.zeros(14)
    y0[3:7] = [0, np.sin(0.7), 0, np.cos(0.7)]
    y0[10:14] = [0, np.cos(0.7), 0, -np.sin(0.7)]
    sol = lagrgen.simulate(brick, (0, 0.4), y0, t_eval=[0.4], rtol=1e-10, atol=1e-10)
    last = result[-1]
    for k, name in enumerate(FREE_BASE):
        assert last[name] == pytest.approx(sol.y[k, -1], abs=1e-5)


def test_the_command_line_shows_and_simulates_a_free_base(tmp_path):
    import sys
    run = lambda *args: subprocess.run([sys.executable, "-m", "lagrgen", *map(str, args)],
                                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    shown = run("show", QUADRUPED, "--base", "free")
    assert shown.returncode == 0, shown.stderr
    assert "19 coordinates" in shown.stdout and "free base: base_x" in shown.stdout
    ran = run("simulate", BRICK, "--base", "free", "--t-end", "0.5", "--csv", "brick.csv")
    assert ran.returncode == 0, ran.stderr
    lines = (tmp_path / "brick.csv").read_text().splitlines()
    names = (h.split(" [")[0] for h in lines[0].split(","))
    last = dict(zip(names, map(float, lines[-1].split(","))))
    assert last["base_z"] == pytest.approx(-9.81 / 8, rel=1e-6) and last["base_qw"] == 1.0
    assert last["base_pitch"] == 0.0


# -- link kinematics --------------------------------------------------------------------------------
def test_a_free_bases_link_frames_equal_the_floating_ones_finite_differences_and_pinocchio(
        quadruped, out):
    """link_pose and link_jacobian of the free quadruped (compiled and Python): the floating
    model's at the same state, J·q̇ (q̇ ∋ ζ̇) the velocities of finite differences along q̇ and
    Pinocchio's frame velocities (LOCAL_WORLD_ALIGNED) of its free-flyer."""
    free, floating = quadruped
    python = lagrgen.build(lagrgen.from_urdf(QUADRUPED, base="free", joint_dynamics=False,
                                             name="quad_free", limits=False),
                           backend="python", out_dir=out, quiet=True)
    joints = list(free.coordinates[7:])
    rng = np.random.default_rng(11)
    start = dict(position=(0.1, -0.2, 0.5), rpy=(0.3, -0.4, 1.0), velocity=(0.5, 0.2, 1.0),
                 angular_velocity=(0.6, -0.8, 0.4), q=dict(zip(joints, rng.uniform(-0.4, 0.4, 12))),
                 qd=dict(zip(joints, rng.uniform(-1, 1, 12))))
    y, yf = lagrgen.base_state(free, **start), lagrgen.base_state(floating, **start)
    n, nf = free.n_coordinates, floating.n_coordinates
    q, qd = y[:n], y[n:]
    point, h = np.array([0.05, -0.02, 0.03]), 1e-6
    assert free.link_names == floating.link_names == python.link_names
    for link in free.link_names:
        x, R = free.link_pose(link, q, point)
        J = free.link_jacobian(link, q, point)
        xf, Rf = floating.link_pose(link, yf[:nf], point)
        assert np.allclose(x, xf, atol=1e-14) and np.allclose(R, Rf, atol=1e-14)
        assert np.allclose(J @ qd, floating.link_jacobian(link, yf[:nf], point) @ yf[nf:],
                           atol=1e-13)
        for mine, theirs in zip(python.link_pose(link, q, point) + (python.link_jacobian(
                link, q, point),), (x, R, J)):
            assert np.allclose(mine, theirs, atol=1e-14)
        (xp, Rp), (xm, Rm) = (free.link_pose(link, q + s * h * qd, point) for s in (1, -1))
        W = (Rp - Rm) / (2 * h) @ R.T
        assert np.allclose((xp - xm) / (2 * h), J[:3] @ qd, atol=1e-8)
        assert np.allclose([W[2, 1], W[0, 2], W[1, 0]], J[3:] @ qd, atol=1e-8)
    with pytest.raises(ValueError, match="quaternion"):
        free.link_jacobian("trunk", np.zeros(n))
    with pytest.raises(ValueError, match="quaternion"):
        python.link_pose("FL_foot", np.zeros(n))
    pin = pytest.importorskip("pinocchio")
    pm = pin.buildModelFromUrdf(str(QUADRUPED), pin.JointModelFreeFlyer())
    data = pm.createData()
    Rb = rotation_of(q[3:7])
    omega = start["angular_velocity"]
    v = np.concatenate([Rb.T @ qd[:3], Rb.T @ omega, qd[7:]])
    pin.forwardKinematics(pm, data, q, v)
    pin.updateFramePlacements(pm, data)
    for link in ("trunk", "FL_foot", "HR_shank"):
        frame = pm.getFrameId(link)
        pin.computeJointJacobians(pm, data, q)
        Jp = pin.getFrameJacobian(pm, data, frame, pin.LOCAL_WORLD_ALIGNED)
        x, R = free.link_pose(link, q)
        assert np.allclose(x, data.oMf[frame].translation, atol=1e-12)
        assert np.allclose(R, data.oMf[frame].rotation, atol=1e-12)
        assert np.allclose(free.link_jacobian(link, q) @ qd, Jp @ v, atol=1e-12)


def rpy_matrix_of(roll, pitch, yaw):
    """Rz(yaw)·Ry(pitch)·Rx(roll)."""
    cr, sr, cp, sp_, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                               np.cos(yaw), np.sin(yaw))
    return (np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
            @ np.array([[cp, 0, sp_], [0, 1, 0], [-sp_, 0, cp]])
            @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))


@pytest.mark.parametrize("rpy", [(0.0, np.pi / 2, 0.3), (0.5, np.pi / 2, 0.3),
                                 (0.2, -np.pi / 2, np.pi), (0.5, np.pi / 2 - 1e-9, 0.3),
                                 (0.0, np.pi, 0.0), (3.0, 0.1, -3.0)])
def test_the_roll_pitch_yaw_outputs_give_the_orientation_back_at_gimbal_lock_too(
        brick, brick_python, rpy):
    """base_roll, base_pitch and base_yaw rebuild the base's rotation to round-off everywhere,
    on both backends: at pitch ±π/2 the yaw read off the first column was round-off of its own
    (R(rpy) 1.96 off at (0, π/2, 0.3)); it now follows the roll through R·Rx(−roll)."""
    for mod in (brick, brick_python):
        y = lagrgen.base_state(mod, rpy=rpy)
        i = mod.output_names.index("base_roll")
        roll, pitch, yaw = mod.outputs(0.0, y)[i:i + 3]
        assert np.abs(rpy_matrix_of(roll, pitch, yaw) - rotation_of(y[3:7])).max() < 1e-14
        assert np.abs(rotation_of(y[3:7]) - rpy_matrix_of(*rpy)).max() < 1e-14


def test_a_zero_quaternion_in_a_start_says_how_to_give_the_orientation(brick):
    """A y0 dict naming base_z alone left the quaternion 0: a MassMatrixError about masses and
    inertias; now a ValueError that says to give base_qw=1 or use base_state, in simulate and
    simulate_many."""
    with pytest.raises(ValueError, match="quaternion.*is zero.*base_qw=1.*base_state"):
        lagrgen.simulate(brick, (0.0, 0.1), {"base_z": 1.0})
    with pytest.raises(ValueError, match="quaternion.*is zero"):
        lagrgen.simulate_many(brick, (0.0, 0.1), [{"base_z": 1.0}, {"base_qw": 1.0}],
                              t_eval=[0.0, 0.1])
    sol = lagrgen.simulate(brick, (0.0, 0.1), {"base_z": 1.0, "base_qw": 1.0})
    assert sol.success and sol.y[2, -1] == pytest.approx(1.0 - 9.81 * 0.01 / 2, rel=1e-9)
