"""Joint limits that hold in simulation (issue 44 item 2, API §22): a URDF joint's position limits
act as unilateral contacts of the hybrid solve (stops <joint>_lower and <joint>_upper, inelastic
unless limit_restitution), on both engines and in ensembles; limits=False leaves them declared
but not enforced; a start beyond a limit is refused saying so."""

import numpy as np
import pytest

import lagrgen
from conftest import native_free_mode_pair, robots_dir
from lagrgen import ContactError, Signal

G = 9.81
TOL = dict(rtol=1e-10, atol=1e-12)
ENGINES = ("native", "scipy")

#: A pendulum on a revolute joint about y: a 1 kg point 0.5 m below the axis (inertia about it
#: 0.25 + 0.001 kg·m²), its stops at 0.2 and 0.6 rad, so that gravity (the torque −m·g·l·sin q
#: toward 0) holds it on the lower one.
PENDULUM = """<?xml version="1.0"?><robot name="stop_pendulum">
<link name="base"/>
<link name="arm"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/>
  <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
<joint name="hinge" type="revolute"><parent link="base"/><child link="arm"/>
  <axis xyz="0 1 0"/><limit lower="0.2" upper="0.6" velocity="5" effort="10"/></joint>
</robot>"""
#: A 10 kg wheel hub on a vertical suspension of ±5 mm (tiago_dual's), falling under gravity.
SUSPENSION = """<?xml version="1.0"?><robot name="suspension">
<link name="base_link"/>
<link name="hub"><inertial><origin xyz="0 0 -0.02"/><mass value="10"/>
  <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
<link name="wheel"><inertial><mass value="1.5"/>
  <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.007"/></inertial></link>
<joint name="suspension_joint" type="prismatic"><parent link="base_link"/><child link="hub"/>
  <axis xyz="0 0 1"/><limit effort="100" lower="-0.005" upper="0.005" velocity="1"/>
  <dynamics damping="100"/></joint>
<joint name="wheel_joint" type="continuous"><parent link="hub"/><child link="wheel"/>
  <origin xyz="0 -0.2 0" rpy="-1.5707963267948966 0 0"/><axis xyz="0 0 1"/></joint>
</robot>"""
INERTIA = 0.25 + 0.001          # about the hinge
TORQUE = G * 0.5                # m·g·l


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("limits")
    for name, text in (("pendulum", PENDULUM), ("suspension", SUSPENSION)):
        (folder / f"{name}.urdf").write_text(text)
    return folder


@pytest.fixture(scope="module")
def pendulums(files, tmp_path_factory):
    """The pendulum with its stops inelastic, with restitution 0.5, and not enforced."""
    out = tmp_path_factory.mktemp("limit_builds")
    path = files / "pendulum.urdf"
    return {key: lagrgen.build(lagrgen.from_urdf(path, name=f"pendulum_{key}", **options),
                               out_dir=out, quiet=True)
            for key, options in (("inelastic", {}), ("elastic", {"limit_restitution": 0.5}),
                                 ("free", {"limits": False}))}


def test_limits_become_stops_named_after_their_joints(files):
    model = lagrgen.from_urdf(files / "pendulum.urdf")
    assert model.limits == {"hinge": (0.2, 0.6, 5.0, 10.0)}
    assert model.stops == {"hinge": 0.0}
    assert lagrgen.from_urdf(files / "pendulum.urdf", limits=False).stops == {}
    mod = lagrgen.build(model, backend="python")
    assert mod.info.limit_stops == (("hinge_lower", 0, 1, 0.2, 0.0),
                                    ("hinge_upper", 0, -1, 0.6, 0.0))
    assert mod.nonsmooth_definitions == ()        # a model of its own: smooth for other tools
    with pytest.raises(lagrgen.ModelError, match="restitution"):
        lagrgen.from_urdf(files / "pendulum.urdf", limit_restitution=1.5)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_joint_falls_onto_its_stop_rests_against_it_and_leaves_it_when_driven_away(
        pendulums, engine):
    """From 0.4 rad at rest gravity swings the arm down onto its lower stop at 0.2 rad, where it
    rests (inelastic) with the stop's torque m·g·l·sin 0.2; a torque rising to 4 N·m from
    t = 1 s drives it off the stop (as the torque passes m·g·l·sin 0.2), onto the upper one at
    0.6 rad; as the torque falls after t = 2 s it leaves that one and falls back."""
    mod = pendulums["inelastic"]
    tau = Signal([0.0, 1.0, 1.01, 2.0, 2.01, 3.0], [0.0, 0.0, 4.0, 4.0, 0.0, 0.0])
    sol = lagrgen.simulate(mod, (0.0, 3.0), [0.4, 0.0], inputs={"tau_hinge": tau},
                           engine=engine, **TOL)
    assert sol.success, sol.message
    kinds = [(name, kind) for _, name, kind in sol.transitions]
    assert kinds[:5] == [("hinge_lower", "contact"), ("hinge_lower", "release"),
                         ("hinge_upper", "contact"), ("hinge_upper", "release"),
                         ("hinge_lower", "contact")]
    lift = TORQUE * np.sin(0.2) / 4.0 * 0.01                 # the torque's rise passes it
    assert sol.transitions[1][0] == pytest.approx(1.0 + lift, abs=1e-9)
    hold = (4.0 - TORQUE * np.sin(0.6)) / 4.0 * 0.01         # its fall passes the upper one's
    assert sol.transitions[3][0] == pytest.approx(2.0 + hold, abs=1e-9)
    assert np.all(sol.y[0] >= 0.2 - 1e-9) and np.all(sol.y[0] <= 0.6 + 1e-9)
    # the time to fall from 0.4 to 0.2 rad: a pendulum's, by quadrature of the energy
    s = np.linspace(0.0, np.sqrt(0.2), 200001)[1:]       # q = 0.4 − s², dq = −2s·ds
    speed = np.sqrt(2 * TORQUE * (np.cos(0.4 - s ** 2) - np.cos(0.4)) / INERTIA)
    integrand = np.concatenate([[2 / np.sqrt(2 * TORQUE * np.sin(0.4) / INERTIA)], 2 * s / speed])
    fall = np.trapezoid(integrand, np.concatenate([[0.0], s]))
    assert sol.transitions[0][0] == pytest.approx(fall, rel=1e-6)
    resting = (sol.t > sol.transitions[0][0] + 1e-3) & (sol.t < 1.0)
    assert np.all(sol.y[0, resting] == pytest.approx(0.2, abs=1e-9))
    np.testing.assert_allclose(sol.multipliers["hinge_lower"][resting], TORQUE * np.sin(0.2),
                               rtol=1e-9)
    on_upper = (sol.t > sol.transitions[2][0] + 1e-3) & (sol.t < 2.0)
    np.testing.assert_allclose(sol.multipliers["hinge_upper"][on_upper],
                               4.0 - TORQUE * np.sin(0.6), rtol=1e-9)
    assert sol.mode == {"hinge_lower": "contact", "hinge_upper": "open"}


@pytest.mark.parametrize("engine", ENGINES)
def test_a_stop_with_restitution_bounces_and_an_unenforced_limit_is_passed(pendulums, engine):
    elastic = lagrgen.simulate(pendulums["elastic"], (0.0, 0.4), [0.4, 0.0], engine=engine,
                               **TOL)
    t_hit = elastic.transitions[0][0]
    assert elastic.transitions[0][1:] == ("hinge_lower", "impact")
    before = elastic.y[1][elastic.t == t_hit]
    assert before[1] == pytest.approx(-0.5 * before[0], rel=1e-9)      # saved before and after
    free = lagrgen.simulate(pendulums["free"], (0.0, 2.0), [0.4, 0.0], engine=engine, **TOL)
    assert free.transitions == [] and free.mode == {} and free.y[0].min() < -0.39


def test_both_engines_and_an_ensemble_agree(pendulums):
    mod = pendulums["inelastic"]
    t_eval = np.linspace(0.0, 1.0, 11)
    starts = [[0.3, 0.0], [0.5, -1.0], [0.59, 2.0]]
    runs = [lagrgen.simulate(mod, (0.0, 1.0), y0, t_eval=t_eval, engine=engine, **TOL)
            for y0 in starts for engine in ENGINES]
    for native, scipy in zip(runs[::2], runs[1::2]):
        np.testing.assert_allclose(native.y, scipy.y, atol=1e-7)
        assert [(n, k) for _, n, k in native.transitions] == \
            [(n, k) for _, n, k in scipy.transitions]
    ens = lagrgen.simulate_many(mod, (0.0, 1.0), starts, t_eval=t_eval, workers=2, **TOL)
    assert ens.success.all()
    for run, sol in enumerate(runs[::2]):
        np.testing.assert_allclose(ens.y[run], sol.y, rtol=1e-12, atol=1e-14)
    assert "hinge_lower" in ens.to_xarray()["multipliers"].coords["constraint"].values
    np.testing.assert_allclose(ens.multipliers[0], runs[0].contact_forces, atol=1e-9)


def test_a_start_beyond_a_limit_is_refused_naming_the_joint(pendulums):
    for engine in ENGINES:
        with pytest.raises(ContactError, match="hinge = 0.7, beyond its upper limit 0.6"):
            lagrgen.simulate(pendulums["inelastic"], (0, 1), [0.7, 0.0], engine=engine)
    with pytest.raises(ContactError, match="run 1: .*hinge = 0.1, beyond its lower limit"):
        lagrgen.simulate_many(pendulums["inelastic"], (0, 1), [[0.3, 0.0], [0.1, 0.0]],
                              t_eval=[0.5])


def test_a_hand_written_model_enforces_its_limits():
    import sympy as sp
    model = lagrgen.Model("slider_stop")
    x, = model.coordinates("x")
    model.particle(2.0, sp.Matrix([x]))
    model.potential_energy(2.0 * G * x)
    model.limit(x, lower=-0.1, enforce=True, restitution=0.0)
    mod = lagrgen.build(model, backend="python")
    sol = lagrgen.simulate(mod, (0, 1), [0.0, 0.0], **TOL)
    assert sol.transitions[0][1:] == ("x_lower", "contact")
    assert sol.transitions[0][0] == pytest.approx(np.sqrt(2 * 0.1 / G), rel=1e-9)
    assert sol.y[0, -1] == pytest.approx(-0.1) and sol.multipliers["x_lower"][-1] == \
        pytest.approx(2.0 * G)
    with pytest.raises(lagrgen.ModelError, match="restitution"):
        model.limit(x, lower=-0.1, enforce=True, restitution=-0.2)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_suspension_stays_within_its_five_millimetres(files, engine, tmp_path):
    """tiago_dual's suspension slid 2.2 m through its ±5 mm range under gravity: now it lands on
    its lower stop and stays there, holding the hub's weight."""
    mod = lagrgen.build(lagrgen.from_urdf(files / "suspension.urdf"), out_dir=tmp_path,
                        quiet=True)
    sol = lagrgen.simulate(mod, (0.0, 2.0), np.zeros(4), engine=engine, **TOL)
    z = sol.y[0]
    assert z.min() >= -0.005 - 1e-9 and z.max() <= 0.005
    assert sol.mode["suspension_joint_lower"] == "contact"
    assert sol.multipliers["suspension_joint_lower"][-1] == pytest.approx(11.5 * G, rel=1e-9)


@pytest.mark.skipif(robots_dir() is None, reason="example-robot-data is not installed")
def test_tiago_duals_suspension_stays_within_its_range(tmp_path):
    path = robots_dir() / "tiago_description" / "robots" / "tiago_dual.urdf"
    """tiago_dual (101 joints, 182 stops; rigid-body dynamics alone), its joints mid-range, the
    suspension at 0: the suspension lands on its lower stops and holds there."""
    with pytest.warns(lagrgen.URDFWarning):
        model = lagrgen.from_urdf(path, massless="fixed", check_inertias=False, mimic=False,
                                  joint_dynamics=False)
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    n = mod.n_coordinates
    y0 = np.zeros(2 * n)
    for name, (lower, upper, *_) in mod.limits.items():
        if lower is not None and upper is not None and not name.startswith("suspension"):
            y0[mod.coordinates.index(name)] = (lower + upper) / 2
    sol = lagrgen.simulate(mod, (0.0, 0.15), y0, rtol=1e-6, atol=1e-8)
    assert sol.success, sol.message
    for side in ("left", "right"):
        z = sol.y[mod.coordinates.index(f"suspension_{side}_joint")]
        assert z.min() >= -0.005 - 1e-9 and z.max() <= 0.005
        assert sol.mode[f"suspension_{side}_joint_lower"] == "contact"


def test_the_native_free_mode_is_the_mode_equations(pendulums, monkeypatch):
    """Between its stops a robot runs on the native engine from the model's own rhs (the
    stops' gaps its events, no force), with the motion, the transitions and the forces of the
    mode equations that every mode solves otherwise, to round-off."""
    tau = Signal([0.0, 1.0, 1.01, 2.0, 2.01, 3.0], [0.0, 0.0, 4.0, 4.0, 0.0, 0.0])
    free, _ = native_free_mode_pair(pendulums["inelastic"], monkeypatch, (0.0, 3.0), [0.4, 0.0],
                                    inputs={"tau_hinge": tau}, t_eval=np.linspace(0, 3, 301),
                                    **TOL)
    assert len(free.transitions) >= 5
    flying = free.t < free.transitions[0][0]
    assert flying.sum() > 5 and not np.any(free.contact_forces[:, flying])
