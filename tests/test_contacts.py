"""Feet on the ground (issue 44 item 4, API §22): `model.ground_contact` — a point of a link against
a plane, with impacts, resting contact and isotropic Coulomb friction (stick and slip) — and
redundant contacts (a box on four corners) held with least-norm forces, on both engines; solo12
and a quadruped under joint PD control; MuJoCo as a second judge in flight and at rest."""
import importlib.util
import itertools
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import lagrgen
from conftest import benchmark, robots_dir
from lagrgen import Model, rotation

G = 9.81
ROOT = Path(__file__).resolve().parent.parent
QUADRUPED = ROOT / "examples" / "robots" / "quadruped.urdf"
BRICK = ROOT / "examples" / "robots" / "brick.urdf"
ENGINES = ("native", "scipy")
TOL = dict(rtol=1e-9, atol=1e-11)
BOX = (2.0, 0.4, 0.3, 0.1)          # mass, and the lengths along x, y, z
CORNERS = ((1, 1), (1, -1), (-1, 1), (-1, -1))


def box_model(name, mu, normal=(0.0, 0.0, 1.0), restitution=0.0):
    """A free box (x, y, z, roll a, pitch b, yaw c; R = Rz·Ry·Rx) with a ground contact at each
    of its four bottom corners."""
    model = Model(name)
    x, y, z, a, b, c = model.coordinates("x y z a b c")
    mass, lx, ly, lz = BOX
    inertia = [mass * (ly ** 2 + lz ** 2) / 12, mass * (lx ** 2 + lz ** 2) / 12,
               mass * (lx ** 2 + ly ** 2) / 12]
    model.rigid_body_3d(mass, inertia, sp.Matrix([x, y, z]),
                        rotation.z(c) * rotation.y(b) * rotation.x(a), name="box")
    model.potential_energy(mass * G * z)
    for i, (sx, sy) in enumerate(CORNERS):
        model.ground_contact(f"c{i}", "box", (sx * lx / 2, sy * ly / 2, -lz / 2), mu=mu,
                             restitution=restitution, normal=normal)
    return model


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    out = tmp_path_factory.mktemp("contacts")
    made = {}

    def get(key, make, backend):
        if (key, backend) not in made:
            made[key, backend] = lagrgen.build(make(), out_dir=out, quiet=True, backend=backend)
        return made[key, backend]
    return get


def backend_of(engine):
    return "c" if engine == "native" else "python"


def normal_sum(sol, names):
    return sum(sol.multipliers[name] for name in names)


# -- the declaration ------------------------------------------------------------------------------
def test_a_ground_contact_is_an_impact_and_a_planar_friction():
    model = box_model("box_declared", mu=0.5)
    names = [(r.name, type(r).__name__) for r in model.nonsmooth]
    assert names[:2] == [("c0", "Impact"), ("c0_friction", "Friction")]
    friction = model.nonsmooth[1]
    assert friction.planar and friction.normal_force == "c0"
    frictionless = box_model("box_frictionless", mu=0)
    assert [r.name for r in frictionless.nonsmooth] == ["c0", "c1", "c2", "c3"]
    with pytest.raises(lagrgen.UnknownNameError, match="its links are box"):
        frictionless.ground_contact("foot", "lid")
    with pytest.raises(lagrgen.ModelError, match="normal must be 3 finite numbers"):
        frictionless.ground_contact("foot", "box", normal=(0, 0, 0))
    with pytest.raises(lagrgen.ModelError, match="mu"):
        frictionless.ground_contact("foot", "box", mu=-1.0)
    with pytest.raises(lagrgen.ModelError, match="already used"):
        frictionless.ground_contact("c0", "box")
    assert [r.name for r in frictionless.nonsmooth] == ["c0", "c1", "c2", "c3"]   # unchanged


# -- a box on four corners ------------------------------------------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
def test_a_box_dropped_on_its_four_corners_lands_and_rests_level(build, engine):
    """Dropped level from 0.3 m with a sideways speed, the box strikes the floor with its four
    corners at once (eight contact constraints, six freedoms: redundant), sticks there (the
    frictional impulse within μ times the normal one), and rests level, each corner carrying a
    quarter of its weight (the least-norm forces)."""
    mod = build("box", lambda: box_model("box_drop", mu=0.5), backend_of(engine))
    mass, lx, ly, lz = BOX
    y0 = np.zeros(12)
    y0[2], y0[5], y0[6] = 0.3 + lz / 2, 0.2, 0.5
    sol = lagrgen.simulate(mod, (0.0, 1.0), y0, engine=engine, **TOL)
    assert sol.success, sol.message
    landing = np.sqrt(2 * 0.3 / G)
    first = sol.transitions[:4]
    assert {name for _, name, _ in first} == {"c0", "c1", "c2", "c3"}
    assert all(kind == "contact" and t == pytest.approx(landing, rel=1e-9)
               for t, _, kind in first)
    assert set(sol.mode.values()) == {"contact", "stick"}
    end = sol.y[:, -1]
    assert end[0] == pytest.approx(0.5 * landing, rel=1e-9)      # it stuck where it landed
    assert end[2] == pytest.approx(lz / 2, abs=1e-9) and np.abs(end[3:5]).max() < 1e-9
    assert np.abs(end[6:]).max() < 1e-9
    corners = np.array([sol.multipliers[f"c{i}"][-1] for i in range(4)])
    assert corners.sum() == pytest.approx(mass * G, rel=1e-12)
    np.testing.assert_allclose(corners, mass * G / 4, rtol=1e-6)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_tilted_box_rocks_from_corner_to_corner_and_settles_level(build, engine):
    """Dropped tilted, the box lands on its lowest corner, rocks from corner to corner (each
    inelastic landing lifting the last one off) and comes to rest level on the floor."""
    mod = build("box", lambda: box_model("box_drop", mu=0.5), backend_of(engine))
    mass, lx, ly, lz = BOX
    y0 = np.zeros(12)
    y0[2], y0[3], y0[4] = 0.2, 0.15, -0.1
    sol = lagrgen.simulate(mod, (0.0, 0.5), y0, engine=engine, rtol=1e-8, atol=1e-10)
    assert sol.success, sol.message
    assert sol.transitions[0][1:] == ("c3", "contact")                 # the lowest corner
    assert ("c3", "release") in [(n, k) for _, n, k in sol.transitions]
    end = sol.y[:, -1]
    assert end[2] == pytest.approx(lz / 2, abs=2e-9) and np.abs(end[3:5]).max() < 1e-8
    assert np.abs(end[6:]).max() < 1e-9
    assert normal_sum(sol, [f"c{i}" for i in range(4)])[-1] == pytest.approx(mass * G,
                                                                              rel=1e-9)


# -- friction ---------------------------------------------------------------------------------------
def incline(theta):
    return (np.sin(theta), 0.0, np.cos(theta))


@pytest.mark.parametrize("engine", ENGINES)
def test_a_block_on_an_incline_sticks_below_tan_theta_and_slides_above(build, engine):
    """On a plane tilted by θ a block with μ = 0.4 sticks where tan θ < μ (θ = 0.3) and slides
    where tan θ > μ (θ = 0.5) with a = g·(sin θ − μ·cos θ) down the slope, its friction μ times
    its normal force m·g·cos θ."""
    mass, lx, ly, lz = BOX
    mu = 0.4
    for theta in (0.3, 0.5):
        mod = build(f"incline{theta}", lambda: box_model(f"incline_{int(theta * 10)}", mu,
                                                         incline(theta)), backend_of(engine))
        n = np.array(incline(theta))
        y0 = np.zeros(12)
        y0[:3], y0[4] = n * lz / 2, theta
        sol = lagrgen.simulate(mod, (0.0, 1.0), y0, engine=engine, t_eval=[0.0, 0.5, 1.0], **TOL)
        assert sol.success, sol.message
        moved = sol.y[:3, -1] - sol.y[:3, 0]
        frictions = [f"c{i}_friction" for i in range(4)]
        normals = normal_sum(sol, [f"c{i}" for i in range(4)])[-1]
        assert normals == pytest.approx(mass * G * np.cos(theta), rel=1e-9)
        if np.tan(theta) < mu:
            assert np.abs(moved).max() < 1e-12 and sol.transitions == []
            assert {sol.mode[f] for f in frictions} == {"stick"}
        else:
            down = np.array([np.cos(theta), 0.0, -np.sin(theta)])
            a = G * (np.sin(theta) - mu * np.cos(theta))
            np.testing.assert_allclose(moved, 0.5 * a * down, rtol=1e-8, atol=1e-10)
            assert {sol.mode[f] for f in frictions} == {"slip"}
            force = sum(np.hypot(sol.multipliers[f"{f}_1"][-1], sol.multipliers[f"{f}_2"][-1])
                        for f in frictions)
            assert force == pytest.approx(mu * normals, rel=1e-9)


def tip_model(name):
    """A rod of 1 kg and 1 m hinged at its end 1 m above the ground, released horizontal: its tip
    falls onto the ground 0.2 m high, bouncing (restitution 0.5) with friction (μ = 0.5). At rest
    on it the contact holds the rod's one freedom, and the tip's slip is tied to its fall: a
    friction that nothing moves."""
    model = Model(name)
    th, = model.coordinates("theta")
    centre = sp.Matrix([sp.cos(th) / 2, 0, 1 - sp.sin(th) / 2])
    model.rigid_body_3d(1.0, [0.001, 1 / 12, 1 / 12], centre, rotation.y(th), name="rod")
    model.potential_energy(G * (1 - sp.sin(th) / 2))
    model.ground_contact("tip", "rod", (0.5, 0.0, 0.0), mu=0.5, restitution=0.5, height=0.2)
    return model


@pytest.mark.parametrize("engine", ENGINES)
def test_a_tip_that_bounces_to_rest_on_the_ground_stays_there(build, engine):
    """Its bounces accumulate (e = 0.5) and it rests at θ = asin 0.8, on both engines alike: the
    native engine's planar friction at rest, its slip 0 to round-off, fired its event at once
    and never stuck (the contact takes the force), 100 empty segments, and the solve gave up at
    t = 1.204. At rest the split of the tip's force is not determined: the moment about the
    hinge, N·cos θ + F·sin θ = m·g/2·cos θ with |F| ≤ μ·N, puts N between m·g/2 (F = 0) and
    m·g/2·cos θ/(cos θ + μ·sin θ) (F = μ·N)."""
    mod = build("tip", lambda: tip_model("contact_tip"), backend_of(engine))
    sol = lagrgen.simulate(mod, (0.0, 3.0), [0.0, 0.0], engine=engine, **TOL)
    assert sol.success, sol.message
    assert sol.y[0, -1] == pytest.approx(np.arcsin(0.8), abs=1e-9)
    assert abs(sol.y[1, -1]) < 1e-9 and sol.mode["tip"] == "contact"
    c, s = 0.6, 0.8
    least, most = G / 2 * c / (c + 0.5 * s), G / 2
    assert least * (1 - 1e-9) <= sol.multipliers["tip"][-1] <= most * (1 + 1e-9)
    impacts = [t for t, name, kind in sol.transitions if kind == "impact"]
    assert len(impacts) > 10 and sol.transitions[len(impacts)][1:] == ("tip", "contact")


def puck_model(mu):
    """A puck that slides without turning (x, y, z; its frame along the fixed axes), a ground
    contact at its bottom."""
    model = Model("puck_slide")
    x, y, z = model.coordinates("x y z")
    model.rigid_body_3d(0.5, [1e-3, 1e-3, 2e-3], sp.Matrix([x, y, z]), sp.eye(3), name="puck")
    model.potential_energy(0.5 * G * z)
    model.ground_contact("floor", "puck", (0, 0, -0.01), mu=mu)
    return model


@pytest.mark.parametrize("engine", ENGINES)
def test_friction_in_the_plane_is_isotropic(build, engine):
    """A puck sliding at v0 along a slant of the floor decelerates along its line at μ·g (a
    friction disk, not a square: friction along each axis alone would turn it) and sticks after
    v0/(μ·g), v0²/(2·μ·g) further."""
    mu, v0, angle = 0.25, 1.2, 0.6
    mod = build("puck", lambda: puck_model(mu), backend_of(engine))
    y0 = np.array([0.0, 0.0, 0.01, v0 * np.cos(angle), v0 * np.sin(angle), 0.0])
    sol = lagrgen.simulate(mod, (0.0, 1.0), y0, engine=engine, **TOL)
    assert sol.success, sol.message
    assert [(n, k) for _, n, k in sol.transitions] == [("floor_friction", "stick")]
    assert sol.transitions[0][0] == pytest.approx(v0 / (mu * G), rel=1e-9)
    distance = v0 ** 2 / (2 * mu * G)
    np.testing.assert_allclose(sol.y[:2, -1], distance * np.array([np.cos(angle),
                                                                   np.sin(angle)]), rtol=1e-9)
    force = np.hypot(sol.multipliers["floor_friction_1"], sol.multipliers["floor_friction_2"])
    sliding = sol.t < sol.transitions[0][0]
    np.testing.assert_allclose(force[sliding], mu * 0.5 * G, rtol=1e-9)
    assert force[-1] == pytest.approx(0.0, abs=1e-9)


def test_a_two_component_friction_is_planar_on_any_model():
    """model.friction with a slip velocity of two components: a puck on a table (x, y), its
    normal force an expression m·g: it stops along its line after v0/(μ·g)."""
    model = Model("puck")
    x, y = model.coordinates("x y")
    model.particle(1.0, sp.Matrix([x, y]))
    t = model.t
    model.friction("table", [x.diff(t), y.diff(t)], G, mu=0.5)
    mod = lagrgen.build(model, backend="python")
    assert mod.nonsmooth_definitions == (("table", "planar_friction", None),)
    for engine in ("scipy",):
        sol = lagrgen.simulate(mod, (0, 1), [0.0, 0.0, 0.6, -0.8], engine=engine, **TOL)
        assert sol.transitions[0][1:] == ("table", "stick")
        assert sol.transitions[0][0] == pytest.approx(1.0 / (0.5 * G), rel=1e-9)
        np.testing.assert_allclose(sol.y[:2, -1], np.array([0.6, -0.8]) / (2 * 0.5 * G),
                                   rtol=1e-9)


# -- robots ----------------------------------------------------------------------------------------


#: Standing postures: (abduction, hip, knee) per leg.
QUADRUPED_STAND = {leg: (0.0, 0.7, -1.4) for leg in ("FL", "FR", "HL", "HR")}
SOLO_STAND = {"FL": (0.0, 0.8, -1.6), "FR": (0.0, 0.8, -1.6), "HL": (0.0, -0.8, 1.6),
              "HR": (0.0, -0.8, 1.6)}


def legged(path, name, stand, joints, feet, kp, kd, mu=1.0):
    """A floating robot whose joints hold a standing posture under PD control (a spring kp and
    a damper kd on each joint) with a ground contact at each foot."""
    model = lagrgen.from_urdf(path, base="floating", name=name, joint_dynamics=False)
    for leg, angles in stand.items():
        for joint, rest in zip(joints, angles):
            q = model.q[model.coordinate_names.index(joint.format(leg=leg))]
            model.spring(kp, q, rest=rest)
            model.damper(kd, q)
    for leg in stand:
        model.ground_contact(f"{leg}_foot", feet.format(leg=leg), mu=mu)
    return model


def standing_state(mod, stand, joints, feet, height):
    """The standing posture at rest with the lowest foot `height` above the floor."""
    y0 = np.zeros(2 * mod.n_coordinates)
    for leg, angles in stand.items():
        for joint, rest in zip(joints, angles):
            y0[mod.coordinates.index(joint.format(leg=leg))] = rest
    lowest = min(mod.link_pose(feet.format(leg=leg), y0[:mod.n_coordinates])[0][2]
                 for leg in stand)
    y0[2] = height - lowest
    return y0


QUAD_JOINTS, QUAD_FEET = ("{leg}_abad", "{leg}_hip_joint", "{leg}_knee"), "{leg}_foot"
SOLO_JOINTS, SOLO_FEET = ("{leg}_HAA", "{leg}_HFE", "{leg}_KFE"), "{leg}_FOOT"


@pytest.fixture(scope="module")
def quadruped(tmp_path_factory):
    model = legged(QUADRUPED, "quad_pd", QUADRUPED_STAND, QUAD_JOINTS, QUAD_FEET, 8.0, 0.5)
    out = tmp_path_factory.mktemp("quad")
    return model, lagrgen.build(model, out_dir=out, quiet=True)


def test_a_ground_contacts_gap_and_slip_velocity_are_the_compiled_link_frames(quadruped):
    """On a tilted plane n·x = h (n = (0, 0.6, 0.8)) at a point off a foot's origin: the gap is
    n·x and the slip velocity [t1; t2]·ẋ with x and ẋ = J·q̇ from the compiled link_pose and
    link_jacobian, at random states (the declaration differentiates by SymEngine, the
    compiled Jacobian is the recursion's)."""
    _, mod = quadruped
    model = lagrgen.from_urdf(QUADRUPED, base="floating", name="quad_tilted",
                              joint_dynamics=False)
    point, normal, height = (0.01, -0.02, 0.03), np.array([0.0, 0.6, 0.8]), 0.1
    model.ground_contact("foot", "FL_foot", point=point, normal=normal, height=height)
    impact, friction = model.nonsmooth
    t1 = np.array([1.0, 0.0, 0.0])
    t2 = np.cross(normal, t1)
    n = mod.n_coordinates
    q_, qd_ = sp.symbols(f"q:{n}"), sp.symbols(f"qd:{n}")
    plain = {**dict(zip(model.qd, qd_)), **dict(zip(model.q, q_))}
    gap = sp.lambdify([q_], impact.gap.xreplace(plain))
    slip = sp.lambdify([q_, qd_], list(friction.slip_velocity.xreplace(plain)))
    rng = np.random.default_rng(7)
    for _ in range(3):
        q, qd = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
        x = mod.link_pose("FL_foot", q, point)[0]
        xd = mod.link_jacobian("FL_foot", q, point)[:3] @ qd
        assert gap(q) == pytest.approx(normal @ x - height, abs=1e-12)
        np.testing.assert_allclose(slip(q, qd), [t1 @ xd, t2 @ xd], rtol=1e-11, atol=1e-12)


def test_a_quadruped_stands_five_seconds_under_joint_pd_control(quadruped):
    """Put down on its feet, the quadruped sags onto its joints' springs and stands: feet
    sticking where they were, the trunk level, its weight on its feet."""
    _, mod = quadruped
    y0 = standing_state(mod, QUADRUPED_STAND, QUAD_JOINTS, QUAD_FEET, 0.0)
    sol = lagrgen.simulate(mod, (0.0, 5.0), y0, rtol=1e-7, atol=1e-9)
    assert sol.success, sol.message
    feet = [f"{leg}_foot" for leg in QUADRUPED_STAND]
    assert all(sol.mode[f] == "contact" and sol.mode[f"{f}_friction"] == "stick" for f in feet)
    weight = mod.mass_matrix(y0[:18])[0, 0] * G
    assert normal_sum(sol, feet)[-1] == pytest.approx(weight, rel=1e-6)
    end = sol.y[:, -1]
    assert np.abs(end[18:]).max() < 1e-6                    # at rest
    assert np.abs(end[3:6]).max() < 0.05 and 0.5 * y0[2] < end[2] < y0[2]
    for leg in QUADRUPED_STAND:                 # no foot moved sideways
        start = mod.link_pose(f"{leg}_foot", y0[:18])[0]
        np.testing.assert_allclose(mod.link_pose(f"{leg}_foot", end[:18])[0], start,
                                   atol=1e-6)


def test_both_engines_agree_on_a_landing_quadruped(quadruped):
    _, mod = quadruped
    y0 = standing_state(mod, QUADRUPED_STAND, QUAD_JOINTS, QUAD_FEET, 0.05)
    py = lagrgen.build(quadruped[0], backend="python")
    t_eval = np.linspace(0.0, 0.15, 7)
    runs = [lagrgen.simulate(m, (0.0, 0.15), y0, engine=e, t_eval=t_eval, rtol=1e-9, atol=1e-11)
            for m, e in ((mod, "native"), (py, "scipy"))]
    assert all(r.success for r in runs)
    assert [(n, k) for _, n, k in runs[0].transitions] == \
        [(n, k) for _, n, k in runs[1].transitions]
    np.testing.assert_allclose(runs[0].y, runs[1].y, atol=1e-7)


def test_two_feet_that_slip_together_neither_creep_nor_stall(quadruped):
    """Dropped from 30 cm with every knee bent the same way, the quadruped pitches as it lands:
    both front feet reach the edge of their friction disks at the same instant, slip together
    and stick again. With a slip direction blended over 1e-9 m/s (the size of a sticking foot's
    drift) the native engine stalled there and the SciPy one crept. Both engines agree."""
    _, mod = quadruped
    y0 = standing_state(mod, QUADRUPED_STAND, QUAD_JOINTS, QUAD_FEET, 0.3)
    t_eval = np.linspace(0.0, 0.5, 6)
    runs = [lagrgen.simulate(mod, (0.0, 0.5), y0, engine=engine, t_eval=t_eval, rtol=1e-8,
                             atol=1e-10, max_wall_time=120) for engine in ("native", "scipy")]
    for sol in runs:
        assert sol.success, sol.message
        front = [(t, kind) for t, name, kind in sol.transitions
                 if name in ("FL_foot_friction", "FR_foot_friction") and t > 0.3]
        slips = [t for t, kind in front if kind == "slip"]
        sticks = [t for t, kind in front if kind == "stick"]
        assert len(slips) == 2 and len(sticks) == 2 and len(front) == 4, sol.transitions
        assert np.ptp(slips) < 1e-9 and np.ptp(sticks) < 1e-9 and sticks[0] > slips[0] + 0.05
        assert [sol.mode[f"{leg}_foot_friction"] for leg in QUADRUPED_STAND] == ["stick"] * 4
    np.testing.assert_allclose([t for t, *_ in runs[0].transitions],
                               [t for t, *_ in runs[1].transitions], atol=1e-7)
    np.testing.assert_allclose(runs[0].y, runs[1].y, atol=1e-6)


@pytest.mark.skipif(robots_dir() is None, reason="example-robot-data is not installed")
def test_solo12_dropped_from_30_cm_lands_on_its_feet_and_rests_with_its_weight_on_them(
        tmp_path):
    path = robots_dir() / "solo_description" / "robots" / "solo12.urdf"
    model = legged(path, "solo_pd", SOLO_STAND, SOLO_JOINTS, SOLO_FEET, 5.0, 0.1)
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    y0 = standing_state(mod, SOLO_STAND, SOLO_JOINTS, SOLO_FEET, 0.3)
    sol = lagrgen.simulate(mod, (0.0, 5.0), y0, rtol=1e-7, atol=1e-9)
    assert sol.success, sol.message
    feet = [f"{leg}_foot" for leg in SOLO_STAND]
    touchdown = [(t, name) for t, name, kind in sol.transitions if kind == "contact"][:4]
    assert {name for _, name in touchdown} == set(feet)
    assert touchdown[0][0] == pytest.approx(np.sqrt(2 * 0.3 / G), rel=1e-6)
    assert all(sol.mode[f] == "contact" and sol.mode[f"{f}_friction"] == "stick" for f in feet)
    weight = mod.mass_matrix(y0[:18])[0, 0] * G
    assert normal_sum(sol, feet)[-1] == pytest.approx(weight, rel=1e-6)


# -- MuJoCo ----------------------------------------------------------------------------------------
def mujoco_quadruped(mujoco, radius=1e-3, kp=8.0, kd=0.5):
    """MuJoCo's model of the same quadruped: a free joint on the trunk, the joints' springs and
    dampers, a sphere of `radius` at each foot and the floor `radius` below z = 0, elliptic
    friction cones with μ = 1 and its no-slip pass, contacts of time constant 5 ms, RK4 at
    0.1 ms."""
    spec = mujoco.MjSpec.from_file(str(QUADRUPED))
    spec.option.timestep = 1e-4
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.body("trunk").add_freejoint()
    return benchmark("robots_world").legged_contacts(
        mujoco, spec, QUADRUPED_STAND, ("abad", "hip_joint", "knee"), "{leg}_foot", kp, kd, radius)


def mujoco_state(mod, y):
    """qpos of MuJoCo's quadruped at lagrgen's state y (zero velocities)."""
    q = y[:mod.n_coordinates]
    return np.concatenate([q[:3], benchmark("robots_world").rpy_quaternion(*q[3:6]), q[6:]])


@pytest.mark.skipif(importlib.util.find_spec("mujoco") is None, reason="mujoco is not installed")
def test_mujoco_agrees_in_flight_and_at_rest(quadruped):
    """In flight (the joints swinging on their springs, nothing touching) the two agree to the
    accuracy of MuJoCo's RK4 at 0.1 ms; standing at rest, to the fraction of a millimetre its
    soft contacts sink by."""
    import mujoco
    _, mod = quadruped
    m, d = mujoco_quadruped(mujoco)
    joints = [m.joint(j).name for j in range(1, m.njnt)]
    assert joints == list(mod.coordinates[6:])
    y0 = standing_state(mod, QUADRUPED_STAND, QUAD_JOINTS, QUAD_FEET, 0.2)
    y0[6:18] += np.random.default_rng(2).uniform(-0.2, 0.2, 12)
    d.qpos[:] = mujoco_state(mod, y0)
    mujoco.mj_forward(m, d)
    for _ in range(1000):                         # 0.1 s: no foot reaches the floor
        mujoco.mj_step(m, d)
    assert d.ncon == 0
    sol = lagrgen.simulate(mod, (0.0, 0.1), y0, rtol=1e-11, atol=1e-12, t_eval=[0.1])
    assert sol.transitions == []
    np.testing.assert_allclose(d.qpos[7:], sol.y[6:18, -1], atol=1e-6)
    np.testing.assert_allclose(d.qpos[:3], sol.y[:3, -1], atol=1e-6)
    # standing: both settle from the same posture put down on the floor
    y0 = standing_state(mod, QUADRUPED_STAND, QUAD_JOINTS, QUAD_FEET, 0.0)
    d.qpos[:], d.qvel[:] = mujoco_state(mod, y0), 0.0
    mujoco.mj_forward(m, d)
    for _ in range(30000):
        mujoco.mj_step(m, d)
    sol = lagrgen.simulate(mod, (0.0, 3.0), y0, rtol=1e-8, atol=1e-10, t_eval=[3.0])
    np.testing.assert_allclose(d.qpos[7:], sol.y[6:18, -1], atol=1e-3)
    assert d.qpos[2] == pytest.approx(sol.y[2, -1], abs=1e-3)


def thrown_brick(name):
    """examples/robots/brick.urdf (2 kg, 0.4 × 0.2 × 0.6 m) on a free base with a ground contact at
    each of its eight corners, μ = 0.8, restitution 0."""
    model = lagrgen.from_urdf(BRICK, base="free", name=name)
    for k, corner in enumerate(itertools.product((-0.2, 0.2), (-0.1, 0.1), (-0.3, 0.3))):
        model.ground_contact(f"c{k}", "brick", corner, mu=0.8, restitution=0.0)
    return model


def test_a_thrown_brick_lands_and_comes_to_rest_on_a_face(build):
    """Thrown spinning from 0.7 m, the brick lands on corner c6 sliding. Before, its contact was held
    and released 3434 times at that instant on both engines and the solve gave up (no progress):
    held with its friction sticking, the contact's force came out negative; released, the corner
    fell through. A held contact whose force is negative with its frictions sticking now slips
    first (`Switching._slide`), and a landing's impulses follow Coulomb's law for impulses with
    maximal dissipation (`disk_step`; undamped, the sweeps alternated between two answers). The
    brick comes to rest on its largest face (z = 0.1) on four corners, its energy never rises,
    and the engines end at the same state."""
    rng = np.random.default_rng(1)
    rpy, velocity = rng.uniform(-1, 1, 3), (rng.uniform(-1, 1), rng.uniform(-1, 1), 0.0)
    spin = rng.uniform(-3, 3, 3)
    ends = []
    mod = build("brick", lambda: thrown_brick("thrown_brick"), "c")
    for engine in ENGINES:                  # the Python backend's scipy run takes 20 s
        y0 = lagrgen.base_state(mod, position=(0, 0, 0.7), rpy=rpy, velocity=velocity,
                                angular_velocity=spin)
        sol = lagrgen.simulate(mod, (0.0, 0.9), y0, engine=engine, **TOL)
        assert sol.success, sol.message
        assert sol.transitions[:2] == [(sol.transitions[0][0], "c6", "contact"),
                                       (sol.transitions[0][0], "c6_friction", "slip")]
        assert len(sol.transitions) < 60
        energy = np.array([mod.outputs(t, y)[-1] for t, y in zip(sol.t, sol.y.T)])
        assert np.all(np.diff(energy) <= 1e-7 * abs(energy[0]))
        corners = [np.min([mod.link_pose("brick", y[:mod.n_coordinates], c)[0][2]
                           for y in sol.y.T[::10]]) for c in itertools.product(
                               (-0.2, 0.2), (-0.1, 0.1), (-0.3, 0.3))]
        assert min(corners) > -1e-6
        assert sol.y[2, -1] == pytest.approx(0.1, abs=1e-8)
        assert np.abs(sol.y[mod.n_coordinates:, -1]).max() < 1e-8
        assert {k for k, v in sol.mode.items() if v == "contact"} == {"c2", "c3", "c6", "c7"}
        ends.append(sol.y[:, -1])
    np.testing.assert_allclose(ends[0], ends[1], atol=1e-6)
