"""Link kinematics (issue 44 item 1, API §22): `model.link_position`, `model.link_rotation` as
SymPy expressions and the compiled `mod.link_pose`, `mod.link_jacobian` of every tree model, on
both backends and formulations; against the expressions, finite differences and Pinocchio's
updateFramePlacements / computeFrameJacobian(LOCAL_WORLD_ALIGNED)."""
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import lagrgen
from conftest import robots_dir
from lagrgen import rotation

ROOT = Path(__file__).resolve().parent.parent
ARM = ROOT / "examples" / "robots" / "arm7.urdf"
QUADRUPED = ROOT / "examples" / "robots" / "quadruped.urdf"

#: A robot with every kind of joint and placement: a revolute joint about a skew axis with a
#: rotated placement, a prismatic one, a continuous one; a fixed joint merging a rotated link and a
#: massless link between two joints (their frames are links of their own).
SMALL = """<?xml version="1.0"?><robot name="small">
<link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.02" izz="0.015"
  ixy="0" ixz="0" iyz="0"/></inertial></link>
<link name="upper"><inertial><origin xyz="0.05 0.02 -0.1" rpy="0.1 0.2 0.3"/><mass value="1.3"/>
  <inertia ixx="0.02" ixy="0.001" ixz="-0.002" iyy="0.025" iyz="0.003" izz="0.01"/></inertial></link>
<link name="slider"><inertial><mass value="0.7"/><inertia ixx="0.004" ixy="0" ixz="0.0005"
  iyy="0.006" iyz="0" izz="0.005"/></inertial></link>
<link name="bracket"><inertial><mass value="0.4"/><inertia ixx="0.001" ixy="0" ixz="0"
  iyy="0.002" iyz="0" izz="0.0015"/></inertial></link>
<link name="ghost"/>
<link name="tip"><inertial><origin xyz="0 0 -0.05"/><mass value="0.5"/><inertia ixx="0.003"
  ixy="0.0002" ixz="0" iyy="0.003" iyz="0.0001" izz="0.001"/></inertial></link>
<joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
  <origin xyz="0 0 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="0 0.6 0.8"/>
  <limit lower="-2" upper="2" velocity="3" effort="40"/></joint>
<joint name="slide" type="prismatic"><parent link="upper"/><child link="slider"/>
  <origin xyz="0.1 0 -0.25" rpy="0 1.5707963267948966 0"/><axis xyz="1 0 0"/>
  <limit lower="-0.1" upper="0.2" velocity="1" effort="100"/></joint>
<joint name="mount" type="fixed"><parent link="slider"/><child link="bracket"/>
  <origin xyz="0 0.05 0" rpy="0.5 0 0"/></joint>
<joint name="spacer" type="fixed"><parent link="bracket"/><child link="ghost"/>
  <origin xyz="0 0 -0.05"/></joint>
<joint name="wrist" type="continuous"><parent link="ghost"/><child link="tip"/>
  <origin xyz="0.02 0 -0.1" rpy="0 0 0.7"/><axis xyz="1 0 0"/></joint>
</robot>"""
POINT = (0.03, -0.02, 0.05)


@pytest.fixture(scope="module")
def small_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "small.urdf"
    path.write_text(SMALL)
    return path


def small_model(path):
    return lagrgen.from_urdf(path, name="small_links")


def hand_tree(name="hand_tree"):
    """A hand-written tree of rigid_body_3d's: a sliding, turning base with two branches."""
    model = lagrgen.Model(name)
    x, yaw, a, b, c = model.coordinates("x yaw a b c")
    L, = model.parameters(L=0.4)
    R0 = rotation.z(yaw)
    p0 = sp.Matrix([x, 0, 0])
    model.rigid_body_3d(2.0, [0.1, 0.12, 0.05], p0 + R0 * sp.Matrix([0, 0, 0.1]), R0, name="cart")
    R1 = R0 * rotation.y(a)
    p1 = p0 + R0 * sp.Matrix([0, 0, 0.2]) + R1 * sp.Matrix([0, 0, L / 2])
    model.rigid_body_3d(0.7, [0.01, 0.01, 0.001], p1, R1, name="upper")
    R2 = R1 * rotation.x(b) * rotation.z(sp.Rational(1, 3))
    p2 = p0 + R0 * sp.Matrix([0, 0, 0.2]) + R1 * sp.Matrix([0, 0, L]) + R2 * sp.Matrix(
        [0.05, 0, 0.1])
    model.rigid_body_3d(0.5, [0.01, 0.02, 0.015], p2, R2)
    R3 = R0 * rotation.x(c)
    model.rigid_body_3d(0.3, [0.002, 0.001, 0.002], p0 + R0 * sp.Matrix([0.1, 0, 0])
                        + R3 * sp.Matrix([0, 0.15, 0]), R3, name="side")
    return model


@pytest.fixture(scope="module")
def built(small_file, tmp_path_factory):
    """({key: model}, {(key, formulation, backend): built model})."""
    out = tmp_path_factory.mktemp("links")
    models = {"small": small_model(small_file), "hand": hand_tree(),
              "quadruped": lagrgen.from_urdf(QUADRUPED, base="floating", name="quad_links")}
    result = {}
    for key, model in models.items():
        for form in ("recursive", "dense") if key != "quadruped" else ("recursive",):
            for backend in ("c", "python"):
                result[key, form, backend] = lagrgen.build(model, out_dir=out, backend=backend,
                                                           quiet=True, formulation=form)
    return models, result


def numeric(model, expr):
    """A function of q (array) evaluating a SymPy expression in the model's coordinates (its
    parameters at their defaults)."""
    expr = sp.Matrix(expr).subs(dict(zip(model.parameter_symbols, model.parameter_defaults)))
    q = sp.symbols(f"q0:{len(model.q)}")
    f = sp.lambdify([q], expr.subs(dict(zip(model.q, q))), "numpy")
    return lambda values: np.array(f(values), dtype=float)


def angular_velocity(mod, link, q, qd, h=1e-6):
    """ω from central differences of the link's rotation along q̇: [ω]× = Ṙ·Rᵀ."""
    R = mod.link_pose(link, q)[1]
    Rd = (mod.link_pose(link, q + h * qd)[1] - mod.link_pose(link, q - h * qd)[1]) / (2 * h)
    W = Rd @ R.T
    return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2


def test_link_names_of_a_urdf_and_of_a_hand_written_tree(small_file):
    assert small_model(small_file).link_names == ("base", "upper", "slider", "bracket", "ghost", "tip")
    assert hand_tree().link_names == ("cart", "upper", "body2", "side")
    assert lagrgen.from_urdf(QUADRUPED, base="floating").link_names[:3] == \
        ("trunk", "FL_hip", "FL_thigh")


@pytest.mark.parametrize("key", ["small", "hand", "quadruped"])
def test_compiled_poses_equal_the_expressions_on_both_backends(built, key):
    models, mods = built
    model = models[key]
    rng = np.random.default_rng(3)
    expected = {link: (numeric(model, model.link_position(link, POINT)),
                       numeric(model, model.link_rotation(link))) for link in model.link_names}
    for (k, form, backend), mod in mods.items():
        if k != key:
            continue
        assert mod.link_names == model.link_names
        for _ in range(2):
            q = rng.uniform(-1, 1, mod.n_coordinates)
            for link, (position, rotation_of) in expected.items():
                x, R = mod.link_pose(link, q, POINT)
                assert x.shape == (3,) and R.shape == (3, 3)
                np.testing.assert_allclose(x, position(q).ravel(), atol=1e-13)
                np.testing.assert_allclose(R, rotation_of(q), atol=1e-13)
                np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-13)


@pytest.mark.parametrize("key", ["small", "hand", "quadruped"])
def test_link_jacobians_are_the_derivatives_of_the_poses(built, key):
    """J·q̇ = [ẋ; ω] by central differences of x and R along q̇, every link, both backends."""
    models, mods = built
    rng = np.random.default_rng(5)
    for (k, form, backend), mod in mods.items():
        if k != key:
            continue
        n = mod.n_coordinates
        q, qd = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
        for link in models[key].link_names:
            J = mod.link_jacobian(link, q, POINT)
            assert J.shape == (6, n)
            h = 1e-6
            xd = (mod.link_pose(link, q + h * qd, POINT)[0]
                  - mod.link_pose(link, q - h * qd, POINT)[0]) / (2 * h)
            np.testing.assert_allclose(J[:3] @ qd, xd, atol=1e-8)
            np.testing.assert_allclose(J[3:] @ qd, angular_velocity(mod, link, q, qd), atol=1e-8)


def test_c_and_python_and_both_formulations_agree_to_round_off(built):
    models, mods = built
    rng = np.random.default_rng(9)
    for key in ("small", "hand"):
        runs = [mods[key, form, backend] for form in ("recursive", "dense")
                for backend in ("c", "python")]
        q = rng.uniform(-1, 1, runs[0].n_coordinates)
        for link in models[key].link_names:
            ref_x, ref_R = runs[0].link_pose(link, q, POINT)
            ref_J = runs[0].link_jacobian(link, q, POINT)
            for mod in runs[1:]:
                x, R = mod.link_pose(link, q, POINT)
                assert np.abs(x - ref_x).max() < 1e-14 and np.abs(R - ref_R).max() < 1e-14
                assert np.abs(mod.link_jacobian(link, q, POINT) - ref_J).max() < 1e-14


def test_each_links_own_functions_equal_the_walk_over_all_frames(tmp_path, monkeypatch):
    """The compiled links of a small tree have functions of their own, computing only their
    chain (kernels.link_chains); a tree beyond LINK_CHAIN_MAX_DEPTHS (here forced) walks the
    twists of all its nodes (lg_link_frames), as the Python backend does: all three agree to
    round-off on every link, with a free base and with a hand-written tree."""
    from lagrgen import kernels
    rng = np.random.default_rng(11)
    for make in (lambda name: lagrgen.from_urdf(QUADRUPED, base="floating", name=name),
                 hand_tree):
        mods, sources = {}, {}
        for way, limit in (("own", kernels.LINK_CHAIN_MAX_DEPTHS), ("walk", 0)):
            model = make(f"chains_{way}")
            with monkeypatch.context() as patch:
                patch.setattr(kernels, "LINK_CHAIN_MAX_DEPTHS", limit)
                kernels.link_chains.cache_clear()
                mods[way] = lagrgen.build(model, out_dir=tmp_path / way, quiet=True)
                mods[way].link_pose(model.link_names[0], np.zeros(len(model.q)))  # its unit
            sources[way] = "".join(path.read_text() for path in
                                   (tmp_path / way).glob("__lagrgen__/*/links-*/*_model.c"))
        kernels.link_chains.cache_clear()
        assert "#define LG_LINK_CHAINS 1" in sources["own"] and "lg_link_frames" not in \
            sources["own"].split("#define LG_LINK_CHAINS 1")[0]
        assert "#define LG_LINK_CHAINS 0" in sources["walk"]
        mods["python"] = lagrgen.build(make("chains_python"), backend="python")
        for _ in range(2):
            q = rng.uniform(-1, 1, mods["own"].n_coordinates)
            for link in mods["own"].link_names:
                x, R = mods["own"].link_pose(link, q, POINT)
                J = mods["own"].link_jacobian(link, q, POINT)
                for way in ("walk", "python"):
                    other_x, other_R = mods[way].link_pose(link, q, POINT)
                    assert np.abs(other_x - x).max() < 1e-14
                    assert np.abs(other_R - R).max() < 1e-14
                    assert np.abs(mods[way].link_jacobian(link, q, POINT) - J).max() < 1e-14


def test_the_fixed_frame_links_do_not_move(built):
    """A fixed base's root link sits at the origin; its Jacobian is zero."""
    _, mods = built
    mod = mods["small", "recursive", "c"]
    q = np.array([0.4, 0.1, -0.3])
    x, R = mod.link_pose("base", q, POINT)
    np.testing.assert_allclose(x, POINT)
    np.testing.assert_allclose(R, np.eye(3))
    assert not mod.link_jacobian("base", q).any()
    # the slider's columns: the shoulder turns it, the slide moves it, the wrist does not
    J = mod.link_jacobian("slider", q)
    assert J[:, 0].any() and J[:3, 1].any() and not J[3:, 1].any() and not J[:, 2].any()


def test_parameters_move_the_links(built):
    """A hand-written tree's lengths are parameters: p changes the poses."""
    _, mods = built
    mod = mods["hand", "recursive", "c"]
    q = np.zeros(5)
    top = mod.link_pose("upper", q)[0][2]
    assert top == pytest.approx(0.2 + 0.2)
    assert mod.link_pose("upper", q, p=[0.8])[0][2] == pytest.approx(0.2 + 0.4)
    assert mod.link_pose("upper", q, p={"L": 0.8})[0][2] == pytest.approx(0.2 + 0.4)


def test_bad_link_names_and_points_get_clear_errors(built, small_file):
    _, mods = built
    for backend in ("c", "python"):
        mod = mods["small", "recursive", backend]
        with pytest.raises(lagrgen.UnknownNameError, match="'hand' is not a link of model .* "
                           "its links are base, upper, slider, bracket, ghost, tip"):
            mod.link_pose("hand", np.zeros(3))
        with pytest.raises(lagrgen.UnknownNameError, match="its links are"):
            mod.link_jacobian(3, np.zeros(3))
        with pytest.raises(ValueError, match="point"):
            mod.link_pose("tip", np.zeros(3), (0, 1))
        with pytest.raises(ValueError, match="finite"):
            mod.link_jacobian("tip", np.zeros(3), (0, np.nan, 0))
        with pytest.raises(ValueError, match="q"):
            mod.link_pose("tip", np.zeros(4))
    with pytest.raises(lagrgen.UnknownNameError, match="its links are base, upper"):
        small_model(small_file).link_position("hand")
    with pytest.raises(lagrgen.ModelError, match="fixed in its link"):
        model = small_model(small_file)
        model.link_position("tip", (model.q[0], 0, 0))


def test_a_point_is_read_alike_in_every_form(built):
    """The compiled link functions read a point given as a tuple of numbers or a float64 array
    without converting it; every other form (a list, a strided, byte-swapped, float32 or integer
    array) gives the same numbers, and a non-finite point is refused in each."""
    _, mods = built
    mod = mods["small", "recursive", "c"]
    q = np.array([0.3, -0.2, 0.5])
    reference = [f("tip", q, (0.1, -0.2, 0.3)) for f in (mod.link_pose, mod.link_jacobian)]
    strided = np.array([0.1, 9.0, -0.2, 9.0, 0.3])[::2]
    for point in ((0.1, -0.2, 0.3), [0.1, -0.2, 0.3], np.array([0.1, -0.2, 0.3]), strided,
                  np.array([0.1, -0.2, 0.3], dtype=">f8")):
        pose, jac = mod.link_pose("tip", q, point), mod.link_jacobian("tip", q, point)
        assert np.array_equal(pose[0], reference[0][0]) and np.array_equal(jac, reference[1])
    for same in (np.array([0, 1, 0]), np.array([0, 1, 0], dtype=np.float32)):
        assert np.array_equal(mod.link_pose("tip", q, (0, 1, 0))[0],
                              mod.link_pose("tip", q, same)[0])
    for bad in ((0.0, np.inf, 0.0), np.array([0.0, 0.0, np.nan]), (0, 0, 10 ** 400)):
        with pytest.raises((ValueError, OverflowError)):
            mod.link_jacobian("tip", q, bad)


def test_a_model_without_links_says_so(tmp_path):
    model = lagrgen.Model("no_links")
    x, = model.coordinates("x")
    model.particle(1.0, sp.Matrix([x]))
    assert model.link_names == ()
    with pytest.raises(lagrgen.UnknownNameError, match="has no links"):
        model.link_position("base")
    mod = lagrgen.build(model, backend="python")
    assert mod.link_names == ()
    with pytest.raises(lagrgen.UnknownNameError, match="has no links"):
        mod.link_pose("base", [0.0])


def test_link_positions_are_expressions_for_outputs_and_gaps(tmp_path):
    """A tool point's height as an output, evaluated by simulate's outputs."""
    model = lagrgen.from_urdf(ARM, joint_dynamics=False, name="arm_tool")
    model.output("tool_z", model.link_position("hand", (0, 0, 0.1))[2])
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    q = np.linspace(0.1, 0.7, 7)
    y = np.concatenate([q, np.zeros(7)])
    z = mod.outputs(0.0, y)[mod.output_names.index("tool_z")]
    assert z == pytest.approx(mod.link_pose("hand", q, (0, 0, 0.1))[0][2], abs=1e-14)


# -- Pinocchio ------------------------------------------------------------------------------------


def pinocchio_frames(path, coordinates, links, states, point):
    """Pinocchio's (x, R, J (LOCAL_WORLD_ALIGNED), columns in lagrgen's coordinate order) of each
    link's body frame at each q (a continuous joint's angle as its cosine and sine)."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    joints = [(coordinates.index(model.names[j]), model.joints[j]) for j in range(1, model.njoints)]
    columns = [0] * len(joints)
    for k, joint in joints:
        columns[k] = joint.idx_v
    out = []
    for q in states:
        qp = pin.neutral(model)
        for k, joint in joints:
            qp[joint.idx_q:joint.idx_q + joint.nq] = \
                [q[k]] if joint.nq == 1 else [np.cos(q[k]), np.sin(q[k])]
        pin.forwardKinematics(model, data, qp)
        pin.updateFramePlacements(model, data)
        row = {}
        for link in links:
            fid = model.getFrameId(link)
            M = data.oMf[fid]
            J = pin.computeFrameJacobian(model, data, qp, fid, pin.LOCAL_WORLD_ALIGNED)[:, columns]
            # the Jacobian at a point r (world axes) away from the frame's origin: v += ω × r
            r = M.rotation @ point
            J[:3] += -np.cross(r, J[3:].T).T
            row[link] = (M.translation + r, M.rotation.copy(), J)
        out.append(row)
    return model, out


def pinocchio_urdfs():
    found = [("small", None), ("arm7", ARM)]
    root = robots_dir()
    if root is not None:
        found += [("ur5", root / "ur_description" / "urdf" / "ur5_robot.urdf"),
                  ("panda", root / "panda_description" / "urdf" / "panda.urdf")]
    return found


@pytest.mark.parametrize("name,path", pinocchio_urdfs())
def test_link_poses_and_jacobians_equal_pinocchios(name, path, small_file, tmp_path):
    pytest.importorskip("pinocchio")
    path = small_file if path is None else path
    model = lagrgen.from_urdf(path, name=f"pin_{name}", joint_dynamics=False, mimic=False,
                              check_inertias=False, massless="fixed")
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    rng = np.random.default_rng(11)
    states = [rng.uniform(-1, 1, mod.n_coordinates) for _ in range(3)]
    pm, expected = pinocchio_frames(path, mod.coordinates, model.link_names, states,
                                    np.array(POINT))
    assert pm.nv == mod.n_coordinates
    for q, row in zip(states, expected):
        for link, (x, R, J) in row.items():
            ours_x, ours_R = mod.link_pose(link, q, POINT)
            assert np.abs(ours_x - x).max() < 1e-12
            assert np.abs(ours_R - R).max() < 1e-12
            assert np.abs(mod.link_jacobian(link, q, POINT) - J).max() < 1e-12
