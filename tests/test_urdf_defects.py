"""Defects of `from_urdf` and the link kinematics found from outside (issue 42's wave): a floating
base whose massless root has one joint below it (a singular mass matrix) is refused; a mimic joint's
own limits narrow its leader's and act as stops; names the model refuses are URDFErrors of the
file; a NaN gravity is refused; a link point may be a NumPy array; an optimal motion stays within
the stops of enforced limits."""
import numpy as np
import pytest

import lagrgen
from lagrgen.errors import ModelError
from lagrgen.urdf import URDFError

INERTIAL = ('<inertial><origin xyz="0.1 0 0.2"/><mass value="{m}"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.015"/></inertial>')


def robot(name, root_mass=None, joints=(("j1", "base", "a", "0 0 1"),), mimic="", limit=3.0):
    """A small robot: root link `base` (massless unless root_mass), a massive link per joint."""
    base = INERTIAL.format(m=root_mass) if root_mass else ""
    links = [f'<link name="base">{base}</link>'] + [
        f'<link name="{child}">{INERTIAL.format(m=1.0)}</link>' for _, _, child, _ in joints]
    body = [f'<joint name="{j}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0 0 0.3"/><axis xyz="{axis}"/>'
            f'<limit lower="-{limit}" upper="{limit}" effort="10" velocity="2"/>'
            + (mimic if j == "j3" else "") + "</joint>" for j, parent, child, axis in joints]
    return f'<?xml version="1.0"?><robot name="{name}">{"".join(links + body)}</robot>'


def write(tmp_path, text, name):
    path = tmp_path / f"{name}.urdf"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("base", ["floating", "free"])
def test_a_floating_base_whose_massless_root_has_one_joint_below_is_refused(tmp_path, base):
    """The base turning about the one joint's axis moves what the joint moves: M is singular
    (its smallest eigenvalue was 3e-16, and the free base's accelerations took a null vector).
    With two joints below, or a massive root, the file is read."""
    one = write(tmp_path, robot("one_below"), "one")
    with pytest.raises(URDFError, match="'base' of 'one_below' has no mass.*'j1'.*<inertial>"):
        lagrgen.from_urdf(one, base=base)
    lagrgen.from_urdf(one, base="fixed")
    two = write(tmp_path, robot("two_below", joints=(("j1", "base", "a", "0 0 1"),
                                                     ("j2", "base", "b", "0 1 0"))), "two")
    massive = write(tmp_path, robot("massive", root_mass=2.0), "massive")
    for path, joints in ((two, 2), (massive, 1)):
        model = lagrgen.from_urdf(path, base=base)
        assert len(model.q) == (6 if base == "floating" else 7) + joints


def test_a_mimic_joints_limits_narrow_its_leaders_and_stop_it(tmp_path):
    """j3 = −2·j1 + 0.3 within [−3, 3] puts j1 within [−1.35, 1.65] and |q̇1| ≤ 1: model.limits
    says so and a simulation driving j1 up stops it where j3 meets its limit (it went on to
    j3 = −5.7 before)."""
    joints = (("j1", "base", "a", "0 0 1"), ("j2", "a", "b", "0 1 0"), ("j3", "b", "c", "1 0 0"))
    path = write(tmp_path, robot("mimicked", joints=joints,
                                 mimic='<mimic joint="j1" multiplier="-2" offset="0.3"/>'),
                 "mimicked")
    model = lagrgen.from_urdf(path)
    lower, upper, velocity, effort = model.limits["j1"]
    assert (lower, upper, velocity, effort) == pytest.approx((-1.35, 1.65, 1.0, 10.0))
    assert model.limits["j2"] == pytest.approx((-3.0, 3.0, 2.0, 10.0))
    mod = lagrgen.build(model, out_dir=str(tmp_path / "gen"), quiet=True)
    sol = lagrgen.simulate(mod, (0.0, 3.0), np.zeros(4), inputs={"tau_j1": 10.0}, rtol=1e-9,
                           atol=1e-9)
    assert sol.y[0].max() == pytest.approx(1.65, abs=1e-9)
    assert -2.0 * sol.y[0].max() + 0.3 >= -3.0 - 1e-8
    free = lagrgen.from_urdf(path, mimic=False)
    assert free.limits["j1"] == pytest.approx((-3.0, 3.0, 2.0, 10.0))


def test_names_the_model_refuses_are_urdf_errors_of_the_file(tmp_path):
    """A joint named as the time, or whose input name another joint takes, is the file's error
    (URDFError, a ModelError), as a clash of coordinate names already was."""
    timed = write(tmp_path, robot("timed", joints=(("t", "base", "a", "0 0 1"),)), "timed")
    with pytest.raises(URDFError, match="'t'"):
        lagrgen.from_urdf(timed)
    both = write(tmp_path, robot("both", joints=(("x", "base", "a", "0 0 1"),
                                                 ("tau_x", "a", "b", "0 1 0"))), "both")
    with pytest.raises(URDFError, match="tau_x"):
        lagrgen.from_urdf(both)
    assert issubclass(URDFError, ModelError)


def test_a_gravity_that_is_not_finite_is_refused(tmp_path):
    path = write(tmp_path, robot("grav"), "grav")
    for bad in ((0.0, 0.0, float("nan")), (0.0, float("inf"), -9.81)):
        with pytest.raises(ModelError, match="gravity must be finite"):
            lagrgen.from_urdf(path, gravity=bad)


def test_a_link_point_may_be_a_numpy_array(tmp_path):
    """link_position and ground_contact take an array as they take a tuple (a (3, 3)·(1, 3)
    shape error before)."""
    path = write(tmp_path, robot("arrays"), "arrays")
    model = lagrgen.from_urdf(path)
    point = np.array([0.03, -0.02, 0.05])
    assert model.link_position("a", point) == model.link_position("a", tuple(point))
    model.ground_contact("tip", "a", point=point, normal=np.array([0.0, 1.0, 0.0]))


def test_an_optimal_motion_stays_within_the_stops_of_enforced_limits(tmp_path):
    """from_urdf(..., limits=True) makes the limits stops; collocation cannot bounce off them, so
    they are the coordinates' bounds from the start: a goal beyond one is refused (it was
    solved through the stop with success=True), and a move within them stays within them."""
    joints = (("j1", "base", "a", "0 0 1"), ("j2", "a", "b", "0 1 0"))
    path = write(tmp_path, robot("stopped", joints=joints, limit=1.0), "stopped")
    mod = lagrgen.build(lagrgen.from_urdf(path), out_dir=str(tmp_path / "gen"), quiet=True)
    model = mod._source_model
    prob = lagrgen.Collocation(mod, nodes=11, duration=1.0)
    assert prob._bounds[("q", 0)] == (-1.0, 1.0) and prob._bounds[("q", 1)] == (-1.0, 1.0)
    prob.initial(q=[0.0, 0.0], qd=[0.0, 0.0]).final(q=[1.5, 0.0], qd=[0.0, 0.0])
    prob.minimize(integral=sum(u ** 2 for u in model.input_functions))
    with pytest.raises(lagrgen.errors.LagrgenError, match="outside"):
        prob.solve(progress=False, mesh_tol=None)
    within = lagrgen.Collocation(mod, nodes=11, duration=1.0)
    within.initial(q=[0.0, 0.0], qd=[0.0, 0.0]).final(q=[0.9, -0.5], qd=[0.0, 0.0])
    within.minimize(integral=sum(u ** 2 for u in model.input_functions))
    res = within.solve(progress=False, mesh_tol=None)
    assert res.success and np.abs(res.y[:2]).max() <= 1.0 + 1e-8
    free = lagrgen.build(lagrgen.from_urdf(path, limits=False, name="unstopped"),
                         out_dir=str(tmp_path / "gen"), quiet=True)
    assert lagrgen.Collocation(free, nodes=11, duration=1.0)._bounds == {}


def test_a_collocation_of_a_robot_with_joint_friction_says_how_to_leave_it_out(tmp_path):
    """Coulomb friction from a URDF's <dynamics friction> cannot be collocated: the error names
    the frictions and says that from_urdf(..., joint_dynamics=False) builds the robot without
    them; so built, the problem is made."""
    text = robot("rubbing").replace("</joint>", '<dynamics damping="0.1" friction="0.5"/></joint>')
    path = write(tmp_path, text, "rubbing")
    out_dir = str(tmp_path / "gen")
    mod = lagrgen.build(lagrgen.from_urdf(path), out_dir=out_dir, quiet=True)
    with pytest.raises(lagrgen.errors.LagrgenError,
                       match=r"friction \(friction_j1\).*joint_dynamics=False"):
        lagrgen.Collocation(mod, nodes=11, duration=1.0)
    smooth = lagrgen.build(lagrgen.from_urdf(path, name="rubbing_smooth", joint_dynamics=False),
                           out_dir=out_dir, quiet=True)
    assert lagrgen.Collocation(smooth, nodes=11, duration=1.0).layout.nodes == 11


def test_every_joint_is_in_model_limits_with_none_where_the_file_gives_none(tmp_path):
    """model.limits lists each moving joint, a continuous joint without <limit> as
    (None, None, None, None) (it was left out); the built model keeps it, bound_limits() bounds
    the others only, and a robot with no limit at all is refused by bound_limits()."""
    text = robot("spinning", joints=(("j1", "base", "a", "0 0 1"), ("j2", "a", "b", "0 1 0")))
    text = text.replace('<joint name="j2" type="revolute">', '<joint name="j2" type="continuous">')
    text = text.replace('<limit lower="-3.0" upper="3.0" effort="10" velocity="2"/></joint>'
                        '</robot>', '</joint></robot>')
    model = lagrgen.from_urdf(write(tmp_path, text, "spinning"), base="fixed")
    assert model.limits == {"j1": (-3.0, 3.0, 2.0, 10.0), "j2": (None, None, None, None)}
    assert model.stops == {"j1": 0.0}
    mod = lagrgen.build(model, out_dir=str(tmp_path / "gen"), quiet=True)
    assert mod.limits["j2"] == (None, None, None, None)
    prob = lagrgen.Collocation(mod, nodes=5, duration=1.0).bound_limits()
    assert ("q", 1) not in prob._bounds and prob._bounds[("q", 0)] == (-3.0, 3.0)
    bare = text.replace('<limit lower="-3.0" upper="3.0" effort="10" velocity="2"/>', "")
    bare = bare.replace('type="revolute"', 'type="continuous"')
    loose = lagrgen.build(lagrgen.from_urdf(write(tmp_path, bare, "bare"), name="bare"),
                          out_dir=str(tmp_path / "gen"), quiet=True)
    assert set(loose.limits) == {"j1", "j2"}
    with pytest.raises(lagrgen.errors.LagrgenError, match="declares no limits"):
        lagrgen.Collocation(loose, nodes=5, duration=1.0).bound_limits()


@pytest.mark.parametrize("inertial, said", [
    ('<inertial><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.015"/></inertial>',
     r"link 'a'.*has no <mass>"),
    ('<inertial><mass value="1"/><inertia iyy="0.02" izz="0.015"/></inertial>',
     r"<inertia> of link 'a' gives no ixx"),
    ('<inertial><mass/><inertia ixx="0.01" iyy="0.02" izz="0.015"/></inertial>',
     r"the mass of link 'a'")])
def test_an_inertial_without_its_mass_or_moments_is_refused(tmp_path, inertial, said):
    """An <inertial> with no <mass> was read as mass 0 (the link then did not fall), and an
    <inertia> without a moment as 0: both are URDFErrors (urdfdom refuses them too); products of
    inertia left out are 0."""
    text = robot("partial").replace(INERTIAL.format(m=1.0), inertial, 1)
    with pytest.raises(URDFError, match=said):
        lagrgen.from_urdf(write(tmp_path, text, "partial"))
    lax = robot("lax").replace(INERTIAL.format(m=1.0),
                               '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.02" '
                               'izz="0.015"/></inertial>', 1)
    model = lagrgen.from_urdf(write(tmp_path, lax, "lax"))
    assert model.urdf.links["a"].mass == 1.0
