"""Robots from URDF files (issue 35): `lagrgen.from_urdf`, the three-dimensional recursive
formulation (`lagrgen.tree3d`) against the dense one, MuJoCo, finite differences and physics,
on both backends; bad files; the command line."""
import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import lagrgen
from lagrgen.urdf import URDFError

ROOT = Path(__file__).resolve().parent.parent
ARM = ROOT / "examples" / "robots" / "arm7.urdf"
QUADRUPED = ROOT / "examples" / "robots" / "quadruped.urdf"


def link(name, mass=None, com="0 0 0", inertia=(0.01, 0.0, 0.0, 0.02, 0.0, 0.015), rpy="0 0 0"):
    """A <link> element (no <inertial> when mass is None)."""
    if mass is None:
        return f'<link name="{name}"/>'
    ixx, ixy, ixz, iyy, iyz, izz = inertia
    return (f'<link name="{name}"><inertial><origin xyz="{com}" rpy="{rpy}"/>'
            f'<mass value="{mass}"/><inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" '
            f'iyz="{iyz}" izz="{izz}"/></inertial></link>')


def joint(name, kind, parent, child, xyz="0 0 0", rpy="0 0 0", axis="0 0 1", extra=""):
    """A <joint> element."""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>{extra}</joint>')


def robot(*elements, name="bot"):
    return f'<?xml version="1.0"?><robot name="{name}">{"".join(elements)}</robot>'


#: Three moving joints of every kind the recursion handles: a revolute about a skew axis with a
#: rotated placement, a prismatic one, a continuous one; a fixed joint merging a rotated link; a
#: massless link between two joints; off-diagonal inertias and centres away from the origins.
SMALL = robot(
    link("base", 1.0),
    link("upper", 1.3, "0.05 0.02 -0.1", (0.02, 0.001, -0.002, 0.025, 0.003, 0.01), "0.1 0.2 0.3"),
    link("slider", 0.7, "0.0 0.03 0.01", (0.004, 0.0, 0.0005, 0.006, 0.0, 0.005)),
    link("bracket", 0.4, "0.02 0 0", (0.001, 0, 0, 0.002, 0, 0.0015), "0 0.4 0"),
    link("ghost"),
    link("tip", 0.5, "0 0 -0.05", (0.003, 0.0002, 0.0, 0.003, 0.0001, 0.001)),
    joint("shoulder", "revolute", "base", "upper", "0 0 0.3", "0.3 -0.2 0.1", "0 0.6 0.8",
          '<limit lower="-2" upper="2" velocity="3" effort="40"/>'
          '<dynamics damping="0.2" friction="0"/>'),
    joint("slide", "prismatic", "upper", "slider", "0.1 0 -0.25", "0 1.5707963267948966 0",
          "1 0 0", '<limit lower="-0.1" upper="0.2" velocity="1" effort="100"/>'),
    joint("mount", "fixed", "slider", "bracket", "0 0.05 0", "0.5 0 0"),
    joint("spacer", "fixed", "bracket", "ghost", "0 0 -0.05"),
    joint("wrist", "continuous", "ghost", "tip", "0.02 0 -0.1", "0 0 0.7", "1 0 0"),
)


@pytest.fixture(scope="module")
def small_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "small.urdf"
    path.write_text(SMALL)
    return path


@pytest.fixture(scope="module")
def small(small_file, tmp_path_factory):
    """The small robot with inertial parameters, built four ways (its limits not enforced: smooth
    runs, for fits)."""
    out = tmp_path_factory.mktemp("small_builds")
    model = lagrgen.from_urdf(small_file, parameters="inertial", limits=False)
    return {(form, backend): lagrgen.build(model, out_dir=out, backend=backend, quiet=True,
                                           formulation=form)
            for form in ("dense", "recursive") for backend in ("c", "python")}


def states(n, count=3, seed=7):
    rng = np.random.default_rng(seed)
    return [(rng.uniform(-1.2, 1.2, 2 * n), rng.uniform(-2, 2, n)) for _ in range(count)]


def relative(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(b).max(), 1e-300))


# -- the model ------------------------------------------------------------------------------------
def test_a_urdf_becomes_one_coordinate_and_one_input_per_moving_joint(small_file):
    model = lagrgen.from_urdf(small_file)
    assert [str(q.func) for q in model.q] == ["shoulder", "slide", "wrist"]
    assert model.input_names == ("tau_shoulder", "tau_slide", "tau_wrist")
    mod = lagrgen.build(model, backend="python")
    assert mod.formulation == "recursive"
    units = dict(mod.units)
    assert (units["shoulder"], units["slide"], units["tau_slide"]) == ("rad", "m", "N")
    limits = {"shoulder": (-2.0, 2.0, 3.0, 40.0), "slide": (-0.1, 0.2, 1.0, 100.0),
              "wrist": (None, None, None, None)}               # the wrist has no <limit>
    assert model.limits == limits and mod.limits == limits


def test_inertial_parameters_are_named_per_body_with_the_files_values(small_file):
    model = lagrgen.from_urdf(small_file, parameters="inertial")
    names = model.parameter_names
    assert names[:10] == ("m_upper", "mx_upper", "my_upper", "mz_upper", "Ixx_upper",
                          "Ixy_upper", "Iyy_upper", "Ixz_upper", "Iyz_upper", "Izz_upper")
    assert len(names) == 30       # upper, slider (with bracket merged), tip (the ghost is massless)
    defaults = dict(zip(names, model.parameter_defaults))
    assert defaults["m_upper"] == pytest.approx(1.3)
    assert defaults["m_slider"] == pytest.approx(0.7 + 0.4)      # the bracket merged into it
    assert defaults["mz_upper"] == pytest.approx(1.3 * -0.1)


@pytest.mark.parametrize("backend", ["c", "python"])
def test_the_recursive_and_dense_formulations_agree_to_round_off(small, backend):
    dense, rec = small["dense", backend], small["recursive", backend]
    assert (dense.formulation, rec.formulation) == ("dense", "recursive")
    n = rec.n_coordinates
    for y, u in states(n):
        assert relative(rec.rhs(0.0, y, u=u), dense.rhs(0.0, y, u=u)) < 1e-12
        assert relative(rec.mass_matrix(y[:n]), dense.mass_matrix(y[:n])) < 1e-13
        assert relative(rec.forcing(y[:n], y[n:], u=u), dense.forcing(y[:n], y[n:], u=u)) < 1e-12
        assert relative(rec.jacobian(0.0, y, u=u), dense.jacobian(0.0, y, u=u)) < 1e-11
        assert relative(rec.parameter_jacobian(0.0, y, u=u),
                        dense.parameter_jacobian(0.0, y, u=u)) < 1e-11
        assert relative(rec.outputs(0.0, y, u=u), dense.outputs(0.0, y, u=u)) < 1e-12


def test_c_and_python_give_the_same_numbers(small):
    c, py = small["recursive", "c"], small["recursive", "python"]
    n = c.n_coordinates
    for y, u in states(n):
        assert relative(c.rhs(0.0, y, u=u), py.rhs(0.0, y, u=u)) < 1e-13
        assert relative(c.jacobian(0.0, y, u=u), py.jacobian(0.0, y, u=u)) < 1e-12
        assert relative(c.parameter_jacobian(0.0, y, u=u),
                        py.parameter_jacobian(0.0, y, u=u)) < 1e-12
        a = u[::-1] * 3.0                     # any accelerations: r = M·a − F is not zero
        for name in ("residual_terms", "residual_parameter_jacobian", "linear_terms"):
            args = (y[:n], y[n:], a) if name.startswith("residual") else (y[:n], y[n:])
            x, z = getattr(c, name)(*args, u=u), getattr(py, name)(*args, u=u)
            for xi, zi in (zip(x, z) if isinstance(x, tuple) else [(x, z)]):
                assert relative(xi, zi) < 1e-12, name


def test_the_jacobians_are_the_derivatives_of_the_rhs(small):
    mod = small["recursive", "c"]
    n, h = mod.n_coordinates, 1e-6
    y, u = states(n)[0]
    J = mod.jacobian(0.0, y, u=u)
    fd = np.column_stack([(mod.rhs(0, y + h * e, u=u) - mod.rhs(0, y - h * e, u=u)) / (2 * h)
                          for e in np.eye(2 * n)])
    assert relative(J, fd) < 1e-6
    p = mod.defaults
    P = mod.parameter_jacobian(0.0, y, u=u)
    fd = np.column_stack([(mod.rhs(0, y, p=p + h * e, u=u) - mod.rhs(0, y, p=p - h * e, u=u))
                          / (2 * h) for e in np.eye(len(p))])
    assert relative(P, fd) < 1e-6
    dy = np.random.default_rng(3).normal(size=(4, 2 * n))
    dp = np.random.default_rng(4).normal(size=(4, len(p)))
    ydot, D = mod.directional_derivatives(0.0, y, dy, dp, u=u)
    assert relative(D, (J @ dy.T + P @ dp.T).T) < 1e-12
    assert relative(ydot, mod.rhs(0.0, y, u=u)) < 1e-14


# -- against MuJoCo and physics -------------------------------------------------------------------
@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    return lagrgen.build(lagrgen.from_urdf(ARM, joint_dynamics=False, limits=False),
                         out_dir=tmp_path_factory.mktemp("arm"), quiet=True)


def test_the_arm_agrees_with_mujoco(arm):
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_path(str(ARM))
    m.dof_damping[:] = 0.0
    d = mujoco.MjData(m)
    assert arm.formulation == "recursive" and m.nv == arm.n_coordinates == 7
    for y, _ in states(7):
        d.qpos[:], d.qvel[:] = y[:7], y[7:]
        mujoco.mj_forward(m, d)
        M = np.zeros((7, 7))
        try:
            mujoco.mj_fullM(m, d, M)
        except TypeError:                       # MuJoCo before 3.4: (model, dst, qM)
            mujoco.mj_fullM(m, M, d.qM)
        assert relative(arm.mass_matrix(y[:7]), M) < 1e-12
        assert relative(arm.forcing(y[:7], y[7:]), -d.qfrc_bias) < 1e-12


@pytest.fixture(scope="module")
def quadruped(tmp_path_factory):
    out = tmp_path_factory.mktemp("quadruped")
    free = lagrgen.from_urdf(QUADRUPED, base="floating", joint_dynamics=False, name="quad_free",
                             limits=False,
                             gravity=(0.0, 0.0, 0.0))
    return (lagrgen.build(lagrgen.from_urdf(QUADRUPED, base="floating"), out_dir=out, quiet=True),
            lagrgen.build(free, out_dir=out, quiet=True))


def test_a_floating_base_falls_freely_and_its_jacobian_is_exact(quadruped):
    mod, _ = quadruped
    names = mod.coordinates
    assert names[:6] == ("base_x", "base_y", "base_z", "base_roll", "base_pitch", "base_yaw")
    n = mod.n_coordinates
    assert n == 18
    y = np.zeros(2 * n)
    y[3:6] = [0.3, -0.2, 1.1]                   # any orientation, at rest
    qdd = mod.rhs(0.0, y)[n:]
    assert qdd[:3] == pytest.approx([0.0, 0.0, -9.81], abs=1e-12)
    assert np.abs(qdd[3:]).max() < 1e-12       # at rest, nothing but the fall
    y, u = states(n, 1, seed=11)[0]
    J, h = mod.jacobian(0.0, y, u=u), 1e-6
    fd = np.column_stack([(mod.rhs(0, y + h * e, u=u) - mod.rhs(0, y - h * e, u=u)) / (2 * h)
                          for e in np.eye(2 * n)])
    assert relative(J, fd) < 1e-6


def assert_warns_only_near_gimbal_lock(mod, y0):
    """Runs of `mod` (both engines) from y0 rolling at 1.5 rad/s warn NearSingularMassMatrixWarning
    from pitch 1e-6 rad short of π/2 (its roll–pitch–yaw base near gimbal lock), not from 0.3.
    The pivot is least at the start: 2 ms of it are enough (near the lock the steps are short,
    ~14,000 in 50 ms)."""
    n = mod.n_coordinates
    y0 = np.array(y0, dtype=float)
    y0[n + 3] = 1.5
    for pitch, warned in ((np.pi / 2 - 1e-6, True), (0.3, False)):
        y0[4] = pitch
        for engine in ("native", "scipy"):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                sol = lagrgen.simulate(mod, (0.0, 0.002), y0, rtol=1e-9, atol=1e-12,
                                       engine=engine)
            assert sol.success
            found = [w for w in caught
                     if issubclass(w.category, lagrgen.NearSingularMassMatrixWarning)]
            assert bool(found) == warned, (pitch, engine, [str(w.message) for w in caught])


def test_a_floating_base_near_gimbal_lock_warns(quadruped):
    """Issue 45 item 6: the free quadruped tumbling near pitch = π/2 warns on both engines."""
    _, free = quadruped
    assert_warns_only_near_gimbal_lock(free, np.zeros(2 * free.n_coordinates))


def test_a_robot_with_stops_near_gimbal_lock_warns_from_the_hybrid_solve(quadruped):
    """The floating quadruped with its joint limits enforced (from_urdf's default, so run by the
    hybrid driver) warns as the smooth runs do near pitch = π/2, and not at pitch 0.3."""
    stopped, _ = quadruped
    assert stopped.info.limit_stops
    assert_warns_only_near_gimbal_lock(stopped, lagrgen.base_state(stopped, position=(0, 0, 1)))


def test_a_free_robot_keeps_its_energy_and_momentum(quadruped):
    _, free = quadruped
    n = free.n_coordinates
    y0 = np.zeros(2 * n)
    y0[n:] = np.random.default_rng(5).uniform(-1, 1, n)
    sol = lagrgen.simulate(free, (0.0, 1.0), y0, method="DOP853", rtol=1e-11, atol=1e-12,
                           t_eval=np.linspace(0, 1, 11))
    assert sol.success
    energy = np.array([free.outputs(t, y)[free.output_names.index("total_energy")]
                       for t, y in zip(sol.t, sol.y.T)])
    assert np.ptp(energy) < 1e-8 * abs(energy[0])
    # the linear momentum is the base's translational rows of M·q̇ (they are ∂T/∂ẋ, ẏ, ż)
    momentum = np.array([free.mass_matrix(y[:n])[:3] @ y[n:] for y in sol.y.T])
    assert np.abs(momentum - momentum[0]).max() < 1e-8


# -- joint dynamics, mimic joints -------------------------------------------------------------------
def test_joint_damping_and_friction_come_from_dynamics(small_file, tmp_path):
    text = SMALL.replace('<dynamics damping="0.2" friction="0"/>',
                         '<dynamics damping="0.2" friction="50"/>')
    path = tmp_path / "sticky.urdf"
    path.write_text(text)
    model = lagrgen.from_urdf(path)
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    assert mod.formulation == "recursive"
    n = mod.n_coordinates
    y = np.zeros(2 * n)
    y[n] = 0.5
    sol = lagrgen.simulate(mod, (0.0, 0.5), y, method="RK45")
    assert sol.success
    assert any(kind == "stick" for _, name, kind in sol.transitions if name == "friction_shoulder")
    assert sol.y[n, -1] == pytest.approx(0.0, abs=1e-9)    # 50 N m holds the shoulder
    rigid = lagrgen.build(lagrgen.from_urdf(path, joint_dynamics=False, name="rigid"),
                          out_dir=tmp_path, quiet=True)
    y = np.random.default_rng(2).uniform(-1, 1, 2 * n)
    free = lagrgen.build(lagrgen.from_urdf(small_file, name="damped"), out_dir=tmp_path,
                         quiet=True)
    difference = free.forcing(y[:n], y[n:]) - rigid.forcing(y[:n], y[n:])
    assert difference == pytest.approx([-0.2 * y[n], 0.0, 0.0], abs=1e-12)


def test_a_mimic_joint_follows_its_joint(tmp_path):
    text = robot(link("base", 1.0), link("a", 1.0, "0 0 -0.1"), link("b", 0.5, "0 0 -0.1"),
                 link("c", 0.5, "0 0 -0.1"),
                 joint("j1", "revolute", "base", "a", axis="0 1 0"),
                 joint("left", "revolute", "a", "b", "0 0.1 -0.2", axis="1 0 0"),
                 joint("right", "revolute", "a", "c", "0 -0.1 -0.2", axis="1 0 0",
                       extra='<mimic joint="left" multiplier="-1" offset="0.1"/>'))
    path = tmp_path / "gripper.urdf"
    path.write_text(text)
    model = lagrgen.from_urdf(path)
    assert [str(q.func) for q in model.q] == ["j1", "left"]
    dense = lagrgen.build(model, backend="python", formulation="dense")
    for backend in ("c", "python"):            # two joints on one coordinate: assembled M
        rec = lagrgen.build(model, backend=backend, out_dir=tmp_path, quiet=True)
        assert rec.formulation == "recursive"
        for y, u in states(2, count=2, seed=4):
            assert relative(rec.rhs(0.0, y, u=u), dense.rhs(0.0, y, u=u)) < 1e-12
            assert relative(rec.jacobian(0.0, y, u=u), dense.jacobian(0.0, y, u=u)) < 1e-11
            assert relative(rec.mass_matrix(y[:2]), dense.mass_matrix(y[:2])) < 1e-13
    independent = lagrgen.from_urdf(path, mimic=False, name="independent")
    assert len(independent.q) == 3
    full = lagrgen.build(independent, backend="python")
    q = np.array([0.3, 0.2])
    G = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])     # q_full = G·q + (0, 0, 0.1)
    M_full = full.mass_matrix(G @ q + [0.0, 0.0, 0.1])
    assert relative(dense.mass_matrix(q), G.T @ M_full @ G) < 1e-13


# -- bad files ----------------------------------------------------------------------------------------
BAD = {
    "a loop": (robot(link("a", 1), link("b", 1), joint("j1", "revolute", "a", "b"),
                     joint("j2", "revolute", "b", "a")), "loop|child of two"),
    "two roots": (robot(link("a", 1), link("b", 1), link("c", 1),
                        joint("j1", "revolute", "a", "c")), "2 root links"),
    "a missing link": (robot(link("a", 1), joint("j1", "revolute", "a", "nowhere")),
                       "'nowhere', which the file does not define"),
    "a negative mass": (robot(link("a", 1), link("b", -2), joint("j", "revolute", "a", "b")),
                        "mass of link 'b' is -2"),
    "an indefinite inertia": (robot(link("a", 1), link("b", 1, inertia=(0.1, 0.5, 0, 0.1, 0, 0.1)),
                                    joint("j", "revolute", "a", "b")),
                              "inertia of link 'b' is not positive semi-definite"),
    "a broken triangle inequality": (robot(link("a", 1), link("b", 1, inertia=(0.1, 0, 0, 0.1, 0,
                                                                              0.5)),
                                           joint("j", "revolute", "a", "b")),
                                     "triangle inequality"),
    "NaN": (robot(link("a", 1), link("b", 1, com="0 nan 0"), joint("j", "revolute", "a", "b")),
            "xyz must be finite, got nan"),
    "an unsupported joint": (robot(link("a", 1), link("b", 1), joint("j", "planar", "a", "b")),
                             "type 'planar'"),
    "an entity": ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x "y">]><robot name="r"/>',
                  "DOCTYPE"),
    "not XML": ("<robot><link>", "not well-formed"),
    "no link": ('<?xml version="1.0"?><robot name="r"></robot>', "defines no <link>"),
    "a massless joint": (robot(link("a", 1), link("b"), joint("j", "revolute", "a", "b")),
                         "moves no mass"),
    "a zero axis": (robot(link("a", 1), link("b", 1), joint("j", "revolute", "a", "b",
                                                            axis="0 0 0")), "axis"),
    "names that clash": (robot(link("a", 1), link("b", 1), link("c", 1),
                               joint("j-1", "revolute", "a", "b"), joint("j_1", "revolute", "b",
                                                                         "c")),
                         "same coordinate 'j_1'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_files_get_one_error_naming_the_element(case, tmp_path):
    text, message = BAD[case]
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(URDFError, match=message):
        lagrgen.from_urdf(path)


def test_an_unphysical_inertia_can_be_taken_as_it_is(tmp_path):
    path = tmp_path / "odd.urdf"
    path.write_text(BAD["a broken triangle inequality"][0])
    with pytest.raises(URDFError, match="check_inertias=False"):
        lagrgen.from_urdf(path)
    from lagrgen.urdf import URDFWarning
    with pytest.warns(URDFWarning, match="triangle inequality"):
        model = lagrgen.from_urdf(path, check_inertias=False)
    assert len(model.q) == 1
    zero = tmp_path / "point.urdf"        # a point mass: an inertia that is round-off of zero
    zero.write_text(robot(link("a", 1), link("b", 1.3, inertia=(0, 0, 2e-35, 0, 0, 0)),
                          joint("j", "prismatic", "a", "b")))
    assert len(lagrgen.from_urdf(zero).q) == 1


def test_a_joint_that_moves_no_mass_can_be_held_fixed(tmp_path):
    path = tmp_path / "hand.urdf"
    path.write_text(robot(link("a", 1), link("b", 1.0, "0 0 -0.1"), link("finger"), link("tip"),
                          joint("arm", "revolute", "a", "b", axis="0 1 0"),
                          joint("grip", "revolute", "b", "finger", "0 0 -0.2", "0 0 0.3",
                                "1 0 0"),
                          joint("grip2", "revolute", "b", "tip", "0 0 -0.2", axis="1 0 0",
                                extra='<mimic joint="grip" multiplier="-1" offset="0.2"/>')))
    with pytest.raises(URDFError, match="joint 'grip'.*massless='fixed'"):
        lagrgen.from_urdf(path)
    from lagrgen.urdf import URDFWarning
    with pytest.warns(URDFWarning, match="held fixed"):
        model = lagrgen.from_urdf(path, massless="fixed")
    assert [str(q.func) for q in model.q] == ["arm"]
    mod = lagrgen.build(model, backend="python")
    assert np.isfinite(mod.rhs(0.0, [0.3, 0.0])).all()


def test_bad_arguments_are_refused(small_file, tmp_path):
    with pytest.raises(lagrgen.ModelError, match="base must be"):
        lagrgen.from_urdf(small_file, base="flying")
    with pytest.raises(lagrgen.ModelError, match="parameters must be"):
        lagrgen.from_urdf(small_file, parameters="all")
    with pytest.raises(lagrgen.ModelError, match="massless must be"):
        lagrgen.from_urdf(small_file, massless="drop")
    with pytest.raises(lagrgen.ModelError, match="3 components"):
        lagrgen.from_urdf(small_file, gravity=(0, -9.81))
    with pytest.raises(URDFError, match="cannot read"):
        lagrgen.from_urdf(tmp_path / "absent.urdf")


def test_names_become_identifiers():
    from lagrgen.urdf import identifier
    assert identifier("arm/joint-1") == "arm_joint_1"
    assert identifier("2nd") == "_2nd"
    assert identifier("lambda") == "lambda_"


# -- the command line ------------------------------------------------------------------------------
def run_cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "lagrgen", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_every_command_takes_a_urdf(tmp_path):
    shown = run_cli("show", QUADRUPED, "--base", "floating", cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    assert "18 coordinates" in shown.stdout and "FL_knee (revolute about 0 1 0" in shown.stdout
    built = run_cli("build", ARM, "--out", tmp_path / "gen", cwd=tmp_path)
    assert built.returncode == 0, built.stderr
    plot = tmp_path / "arm.png"
    run = run_cli("simulate", ARM, "--t-end", "0.5", "--plot", plot, "--out", tmp_path / "gen",
                  cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert plot.stat().st_size > 10_000
    missing = run_cli("simulate", tmp_path / "none.urdf", "--t-end", "1", cwd=tmp_path)
    assert missing.returncode != 0 and "no URDF file" in missing.stderr


# -- hand-written three-dimensional trees -------------------------------------------------------------
def spatial_arm(name="spatial_arm"):
    """A hand-written tree of `rigid_body_3d`s: a sliding and turning base, a two-joint arm on it
    and a second branch, with parameters in masses, inertias, lengths and gravity."""
    import sympy as sp

    from lagrgen import rotation
    model = lagrgen.Model(name)
    x, yaw, a, b, c = model.coordinates("x yaw a b c")
    m1, m2, L, g = model.parameters(m1=2.0, m2=0.7, L=0.4, g=9.81)
    tau, = model.inputs("tau")
    R0 = rotation.z(yaw)
    p0 = sp.Matrix([x, 0, 0])
    model.rigid_body_3d(m1, [0.1, 0.12, 0.05], p0 + R0 * sp.Matrix([0, 0, 0.1]), R0)
    R1 = R0 * rotation.y(a)
    p1 = p0 + R0 * sp.Matrix([0, 0, 0.2]) + R1 * sp.Matrix([0, 0, L / 2])
    model.rigid_body_3d(m2, [m2 * L ** 2 / 12, m2 * L ** 2 / 12, 0.001], p1, R1)
    R2 = R1 * rotation.x(b) * rotation.z(sp.Rational(1, 3))
    p2 = p0 + R0 * sp.Matrix([0, 0, 0.2]) + R1 * sp.Matrix([0, 0, L]) + R2 * sp.Matrix([0.05, 0, 0.1])
    model.rigid_body_3d(0.5, sp.Matrix([[0.01, 0.001, 0], [0.001, 0.02, 0], [0, 0, 0.015]]), p2, R2)
    R3 = R0 * rotation.x(c)
    p3 = p0 + R0 * sp.Matrix([0.1, 0, 0]) + R3 * sp.Matrix([0, 0.15, 0])
    model.rigid_body_3d(0.3, [0.002, 0.001, 0.002], p3, R3)
    for mass, p in ((m1, p0 + R0 * sp.Matrix([0, 0, 0.1])), (m2, p1), (0.5, p2), (0.3, p3)):
        model.potential_energy(mass * g * p[2])
    model.generalized_force(a, tau)
    model.damper(0.3, b)
    return model


@pytest.fixture(scope="module")
def hand_written(tmp_path_factory):
    out = tmp_path_factory.mktemp("spatial_arm")
    model = spatial_arm()
    return {form: lagrgen.build(model, out_dir=out, quiet=True, formulation=form)
            for form in ("dense", "recursive")}


def test_a_hand_written_3d_tree_takes_the_recursion_and_agrees_with_the_dense_one(hand_written):
    dense, rec = hand_written["dense"], hand_written["recursive"]
    assert rec.formulation == "recursive"
    from lagrgen.lagrange import derived
    from lagrgen.tree import analysed
    tree, _ = analysed(derived(spatial_arm().spec()))
    assert tree.kind == "spatial" and tree.parent == (-1, 0, 1, 2, 1)    # x, yaw, then two branches
    n = rec.n_coordinates
    for y, u in states(n, count=2):
        u = u[:1]
        assert relative(rec.rhs(0.0, y, u=u), dense.rhs(0.0, y, u=u)) < 1e-12
        assert relative(rec.jacobian(0.0, y, u=u), dense.jacobian(0.0, y, u=u)) < 1e-11
        assert relative(rec.parameter_jacobian(0.0, y, u=u),
                        dense.parameter_jacobian(0.0, y, u=u)) < 1e-11
        assert relative(rec.mass_matrix(y[:n]), dense.mass_matrix(y[:n])) < 1e-13


def test_a_3d_body_whose_axis_moves_with_it_is_not_a_tree():
    import sympy as sp

    from lagrgen import rotation
    model = lagrgen.Model("wobble")
    a, b = model.coordinates("a b")
    R = rotation.z(a) * rotation.x(b)
    # the body's centre swings with b about an axis through a point that a moves along x
    model.rigid_body_3d(1.0, [0.1, 0.2, 0.3], sp.Matrix([sp.sin(a) ** 2, 0, 0]) + R * sp.Matrix(
        [0, 0, 0.3]), R)
    with pytest.raises(lagrgen.ModelError, match="formulation='recursive'"):
        lagrgen.build(model, backend="python", formulation="recursive")
    assert lagrgen.build(model, backend="python").formulation == "dense"


# -- everything works on a robot ---------------------------------------------------------------------
def test_a_robot_runs_natively_as_with_scipy_and_linearizes(arm):
    n = arm.n_coordinates
    y0 = np.zeros(2 * n)
    y0[:n] = 0.3
    t = np.linspace(0.0, 0.5, 6)
    # accurate runs: their difference is bounded by the tolerance, not by whether a last-bit
    # difference of the linear algebra flipped one step's acceptance at the default rtol
    native = lagrgen.simulate(arm, (0.0, 0.5), y0, method="Radau", t_eval=t, rtol=1e-10,
                              atol=1e-12)
    scipy = lagrgen.simulate(arm, (0.0, 0.5), y0, method="Radau", t_eval=t, engine="scipy",
                             rtol=1e-10, atol=1e-12)
    assert native.engine == "native" and native.success and scipy.success
    assert np.abs(native.y - scipy.y).max() < 1e-8
    q0, qdd0 = np.full(n, 0.2), arm.rhs(0.0, np.concatenate([np.full(n, 0.2), np.zeros(n)]))[n:]
    with pytest.warns(lagrgen.NotAnEquilibriumWarning):
        lin = lagrgen.modes(arm, q0)
    lin = lagrgen.linearize(arm, q0)
    h = 1e-6

    def residual(q):                 # M(q)·q̈0 − F(q, 0): K is its derivative (q̈0 held)
        return arm.mass_matrix(q) @ qdd0 - arm.forcing(q, np.zeros(n))
    K = np.column_stack([(residual(q0 + h * e) - residual(q0 - h * e)) / (2 * h)
                         for e in np.eye(n)])
    assert relative(lin.K, K) < 1e-7
    assert relative(lin.M, arm.mass_matrix(q0)) < 1e-14



def test_a_robot_moves_between_two_poses_with_least_effort_within_its_limits(small_file,
                                                                            tmp_path):
    """Collocation on a URDF robot (issue 35 item 4): the motion rides the shoulder's velocity
    limit and stays within the file's other limits; the refinement brings the dynamics error
    within the default tolerance."""
    model = lagrgen.from_urdf(small_file, joint_dynamics=False, name="small_move")
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    shoulder, slide, wrist = model.input_functions
    prob = lagrgen.Collocation(mod, nodes=21, duration=0.42).bound_limits()
    goal = [1.0, 0.15, 1.5]
    prob.initial(q=[0, 0, 0], qd=[0, 0, 0]).final(q=goal, qd=[0, 0, 0])
    prob.minimize(integral=(shoulder / 40) ** 2 + (slide / 100) ** 2 + wrist ** 2)
    res = prob.solve(progress=False)
    assert res.success, res.message
    assert res.error <= res.mesh_tol == 1e-6 and len(res.meshes) > 1
    q, qd, slack = res.y[:3], res.y[3:], 1e-7
    (lo0, hi0, v0, e0), (lo1, hi1, v1, e1) = mod.limits["shoulder"], mod.limits["slide"]
    assert np.all((lo0 - slack <= q[0]) & (q[0] <= hi0 + slack) & (lo1 - slack <= q[1])
                  & (q[1] <= hi1 + slack))
    assert np.abs(qd[0]).max() == pytest.approx(v0, rel=1e-4) and np.all(np.abs(qd[1]) <= v1)
    assert np.abs(res.u[0]).max() <= e0 + slack and np.abs(res.u[1]).max() <= e1 + slack
    assert np.allclose(q[:, -1], goal, atol=1e-9) and np.allclose(qd[:, -1], 0, atol=1e-9)
    assert res.check() < 1e-3                 # the found inputs, re-simulated open loop

def test_a_fit_recovers_an_inertial_parameter_of_a_robot(small):
    mod = small["recursive", "c"]
    t = np.linspace(0.0, 0.4, 21)
    y0 = np.concatenate([[0.4, 0.05, 0.2], np.zeros(3)])
    truth = lagrgen.simulate(mod, (0.0, 0.4), y0, t_eval=t, method="DOP853", rtol=1e-11,
                             atol=1e-12)
    fit = lagrgen.fit(mod, t, truth.q, params=["m_slider"], y0=y0, initial={"m_slider": 1.6},
                      method="DOP853", rtol=1e-11, atol=1e-12)
    assert fit.success
    assert fit.params["m_slider"] == pytest.approx(1.1, rel=1e-6)


def test_a_robot_exports_as_plain_c_and_as_a_validated_fmu(tmp_path):
    fmpy = pytest.importorskip("fmpy")
    from fmpy.validation import validate_fmu
    model = lagrgen.from_urdf(ARM, joint_dynamics=False, name="arm_export")
    from lagrgen.build import export_c
    files = export_c(model, out_dir=tmp_path)
    source = next(f for f in files if str(f).endswith(".c"))
    compiled = subprocess.run(["gcc", "-std=c99", "-Wall", "-Werror", "-c", str(source), "-o",
                               str(tmp_path / "arm.o")], capture_output=True, text=True)
    assert compiled.returncode == 0, compiled.stderr[-2000:]
    fmu = lagrgen.export_fmu(model, tmp_path)
    assert validate_fmu(str(fmu)) == []
    n = len(model.q)
    start = {"joint2": 0.4, "joint4": -1.2}
    result = fmpy.simulate_fmu(str(fmu), start_values=start, stop_time=0.3, output_interval=0.1,
                               relative_tolerance=1e-8)   # FMPy's default: ~1e-4 from round-off
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    y0 = np.zeros(2 * n)
    y0[1], y0[3] = 0.4, -1.2
    times = np.clip(result["time"], 0.0, 0.3)
    native = lagrgen.simulate(mod, (0.0, 0.3), y0, method="DOP853", rtol=1e-10, atol=1e-12,
                              t_eval=times)
    assert np.abs(np.array([result[f"joint{k + 1}"] for k in range(n)]) - native.q).max() < 1e-5


# -- the regressor (issue 38) -----------------------------------------------------------------------
@pytest.mark.parametrize("form", ["dense", "recursive"])
@pytest.mark.parametrize("backend", ["c", "python"])
def test_the_regressor_times_the_inertial_parameters_is_the_inverse_dynamics(small, form, backend):
    mod = small[form, backend]
    n = mod.n_coordinates
    assert mod.inertial_parameters == tuple(name for name in mod.parameters)   # all inertial
    assert mod.dimensions["n_inertial"] == 30
    pi = np.asarray(mod.defaults)
    for y, a in states(n, count=2, seed=21):
        q, qd = y[:n], y[n:]
        Y = mod.regressor(q, qd, a)
        assert Y.shape == (n, 30)
        damping = np.array([0.2 * qd[0], 0.0, 0.0])     # the shoulder's damper is left out
        expected = mod.mass_matrix(q) @ a - mod.forcing(q, qd) - damping
        assert relative(Y @ pi, expected) < 1e-13
        assert relative(Y, small["dense", "c"].regressor(q, qd, a)) < 1e-13


def test_a_model_without_inertial_parameters_has_an_empty_regressor(arm):
    assert arm.inertial_parameters == ()
    assert arm.regressor(np.zeros(7), np.zeros(7), np.zeros(7)).shape == (7, 0)


def test_the_regressor_is_pinocchios(tmp_path):
    pin = pytest.importorskip("pinocchio")
    model = lagrgen.from_urdf(ARM, parameters="inertial", joint_dynamics=False, name="arm_pi")
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    pm = pin.buildModelFromUrdf(str(ARM))
    q, qd, a = np.random.default_rng(8).uniform(-1, 1, (3, 7))
    Y = pin.computeJointTorqueRegressor(pm, pm.createData(), q, qd, a)
    assert relative(mod.regressor(q, qd, a), Y) < 1e-13
