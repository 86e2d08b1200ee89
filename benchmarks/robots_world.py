"""Robots in the world (issue 44): link kinematics per call against Pinocchio, and a legged robot
landing and standing against MuJoCo.

1. Link pose and frame Jacobian per call from Python, best of 3 rounds timing every call in turn:
   the seven-joint arm's tool frame (examples/robots/arm7.urdf, the hand's frame 0.1034 m out,
   a Franka's tool point), Panda's hand (example-robot-data, if installed) and solo12's four feet
   (floating base; Pinocchio's free-flyer). lagrgen: `mod.link_pose(link, q, point)` and
   `mod.link_jacobian(link, q, point)`; Pinocchio: `forwardKinematics` + `updateFramePlacements`
   and the frame's placement, and `computeFrameJacobian(..., LOCAL_WORLD_ALIGNED)` (for the four
   feet also `computeJointJacobians` once + `getFrameJacobian` per foot). The values are checked
   equal first (arm and Panda: to 1e-12; solo12: against Pinocchio's model with the same six
   one-axis base joints).
2. solo12 (example-robot-data) under joint PD control (a spring 5 N·m/rad toward a standing
   posture and a damper 0.1 N·m·s/rad on each joint), four ground contacts at its feet (μ = 1),
   dropped with its lowest foot 0.3 m above the floor and simulated 5 s (landing, then standing):
   `lagrgen.simulate` on the native engine (RK45, rtol 1e-6, atol 1e-8), wall time against the
   5 s simulated; MuJoCo on the same URDF (a free joint on the base, the same springs and
   dampers as joint stiffness and damping, a sphere of 1 mm at each foot, elliptic friction cones
   μ = 1 with its no-slip pass, soft contacts of time constant 5 ms), `mj_step` 5 s at 1 ms and
   at 2 ms (its default) with its Euler integrator, and the final base height and joint angles
   of both.

    python benchmarks/robots_world.py            # writes benchmarks/results/robots_world.md, .json

Needs `pin` (Pinocchio 4.1), `mujoco` and `example-robot-data` for their parts (skipped if absent).
"""
import json
import os
import platform
import sys
import tempfile
import time
import timeit
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))
from robots import robots_dir      # noqa: E402
ARM = ROOT / "examples" / "robots" / "arm7.urdf"
TOOL = np.array([0.0, 0.0, 0.1034])
G = 9.81
SOLO_STAND = {"FL": (0.0, 0.8, -1.6), "FR": (0.0, 0.8, -1.6), "HL": (0.0, -0.8, 1.6),
              "HR": (0.0, -0.8, 1.6)}
SOLO_JOINTS = ("HAA", "HFE", "KFE")
KP, KD = 5.0, 0.1


def best_per_call(f, repeats=3):
    timer = timeit.Timer(f)
    number, _ = timer.autorange()
    return min(timer.repeat(repeats, number)) / number


def interleaved_best(calls, rounds=3):
    """{name: seconds per call}, the best of `rounds` rounds that time every call in turn."""
    best = dict.fromkeys(calls, float("inf"))
    for _ in range(rounds):
        for name, call in calls.items():
            best[name] = min(best[name], best_per_call(call))
    return best


# -- 1. kinematics -------------------------------------------------------------------------------
def arm_case(out, say):
    """The arm's tool frame: lagrgen and Pinocchio (a frame added at the tool point)."""
    import pinocchio as pin

    import lagrgen
    mod = lagrgen.build(lagrgen.from_urdf(ARM, joint_dynamics=False, name="arm7_links"),
                        out_dir=out, quiet=True)
    pm = pin.buildModelFromUrdf(str(ARM))
    hand = pm.getFrameId("hand")
    tool = pm.addFrame(pin.Frame("tool", pm.frames[hand].parentJoint, hand,
                                 pm.frames[hand].placement * pin.SE3(np.eye(3), TOOL),
                                 pin.FrameType.OP_FRAME))
    return single_frame(mod, pm, "hand", tool, TOOL, "arm7 tool frame (7 joints)", say)


def panda_case(root, out, say):
    import pinocchio as pin

    import lagrgen
    path = root / "panda_description" / "urdf" / "panda.urdf"
    mod = lagrgen.build(lagrgen.from_urdf(path, joint_dynamics=False, mimic=False,
                                          name="panda_links"), out_dir=out, quiet=True)
    pm = pin.buildModelFromUrdf(str(path))
    return single_frame(mod, pm, "panda_hand", pm.getFrameId("panda_hand"), np.zeros(3),
                        f"Panda hand ({mod.n_coordinates} joints)", say)


def single_frame(mod, pm, link, fid, point, label, say):
    """Check then time one frame's pose and Jacobian."""
    import pinocchio as pin
    data = pm.createData()
    rng = np.random.default_rng(1)
    q = rng.uniform(-1, 1, mod.n_coordinates)
    assert pm.nq == mod.n_coordinates
    pin.forwardKinematics(pm, data, q)
    pin.updateFramePlacements(pm, data)
    x, R = mod.link_pose(link, q, point)
    J = pin.computeFrameJacobian(pm, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
    error = max(np.abs(x - data.oMf[fid].translation).max(),
                np.abs(R - data.oMf[fid].rotation).max(),
                np.abs(mod.link_jacobian(link, q, point) - J).max())

    def pin_pose():
        pin.forwardKinematics(pm, data, q)
        pin.updateFramePlacements(pm, data)
        placement = data.oMf[fid]
        return placement.translation, placement.rotation

    times = interleaved_best({
        "lagrgen pose": lambda: mod.link_pose(link, q, point),
        "Pinocchio pose": pin_pose,
        "lagrgen Jacobian": lambda: mod.link_jacobian(link, q, point),
        "Pinocchio Jacobian": lambda: pin.computeFrameJacobian(pm, data, q, fid,
                                                               pin.LOCAL_WORLD_ALIGNED)})
    say(f"{label}: difference {error:.1e}; " + ", ".join(f"{k} {v * 1e6:.2f} µs"
                                                        for k, v in times.items()))
    return {"case": label, "difference": error, "times": times}


def solo_model(path, name, contacts=True):
    """solo12, floating base, joint PD control, four feet on the ground."""
    import lagrgen
    model = lagrgen.from_urdf(path, base="floating", name=name, joint_dynamics=False)
    for leg, angles in SOLO_STAND.items():
        for joint, rest in zip(SOLO_JOINTS, angles):
            q = model.q[model.coordinate_names.index(f"{leg}_{joint}")]
            model.spring(KP, q, rest=rest)
            model.damper(KD, q)
    if contacts:
        for leg in SOLO_STAND:
            model.ground_contact(f"{leg}_foot", f"{leg}_FOOT", mu=1.0)
    return model


def solo_feet_case(root, out, say):
    """solo12's four feet: lagrgen (roll–pitch–yaw base) against Pinocchio's free-flyer, after
    checking against Pinocchio's model with the same six one-axis base joints."""
    import pinocchio as pin

    import lagrgen
    path = root / "solo_description" / "robots" / "solo12.urdf"
    mod = lagrgen.build(solo_model(path, "solo_links", contacts=False), out_dir=out, quiet=True)
    feet = [f"{leg}_FOOT" for leg in SOLO_STAND]
    chain = pin.JointModelComposite()
    for joint in (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelPZ(),
                  pin.JointModelRZ(), pin.JointModelRY(), pin.JointModelRX()):
        chain.addJoint(joint)
    same = pin.buildModelFromUrdf(str(path), chain)
    data = same.createData()
    rng = np.random.default_rng(2)
    q = rng.uniform(-1, 1, 18)
    qp = np.concatenate([q[:3], q[[5, 4, 3]], q[6:]])    # base yaw, pitch, roll in Pinocchio's
    pin.forwardKinematics(same, data, qp)
    pin.updateFramePlacements(same, data)
    error = 0.0
    columns = [0, 1, 2, 5, 4, 3] + list(range(6, 18))
    for foot in feet:
        fid = same.getFrameId(foot)
        x, R = mod.link_pose(foot, q)
        J = pin.computeFrameJacobian(same, data, qp, fid, pin.LOCAL_WORLD_ALIGNED)
        Jl = np.empty_like(J)
        Jl[:, columns] = mod.link_jacobian(foot, q)
        error = max(error, np.abs(x - data.oMf[fid].translation).max(),
                    np.abs(R - data.oMf[fid].rotation).max(), np.abs(Jl - J).max())
    free = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    fdata = free.createData()
    fids = [free.getFrameId(foot) for foot in feet]
    qf = pin.randomConfiguration(free, -np.ones(free.nq), np.ones(free.nq))

    def pin_poses():
        pin.forwardKinematics(free, fdata, qf)
        pin.updateFramePlacements(free, fdata)
        return [(fdata.oMf[f].translation, fdata.oMf[f].rotation) for f in fids]

    def pin_jacobians():
        return [pin.computeFrameJacobian(free, fdata, qf, f, pin.LOCAL_WORLD_ALIGNED)
                for f in fids]

    def pin_joint_jacobians():
        pin.computeJointJacobians(free, fdata, qf)
        pin.updateFramePlacements(free, fdata)
        return [pin.getFrameJacobian(free, fdata, f, pin.LOCAL_WORLD_ALIGNED) for f in fids]

    times = interleaved_best({
        "lagrgen pose": lambda: [mod.link_pose(f, q) for f in feet],
        "Pinocchio pose": pin_poses,
        "lagrgen Jacobian": lambda: [mod.link_jacobian(f, q) for f in feet],
        "Pinocchio Jacobian": pin_jacobians,
        "Pinocchio Jacobian (joint Jacobians once)": pin_joint_jacobians})
    say(f"solo12 four feet: difference {error:.1e}; " + ", ".join(
        f"{k} {v * 1e6:.2f} µs" for k, v in times.items()))
    return {"case": "solo12 four feet (18 coordinates)", "difference": error, "times": times}


# -- 2. landing and standing ------------------------------------------------------------------------
def standing_state(mod, height):
    y0 = np.zeros(36)
    for leg, angles in SOLO_STAND.items():
        for joint, rest in zip(SOLO_JOINTS, angles):
            y0[mod.coordinates.index(f"{leg}_{joint}")] = rest
    lowest = min(mod.link_pose(f"{leg}_FOOT", y0[:18])[0][2] for leg in SOLO_STAND)
    y0[2] = height - lowest
    return y0


def landing_case(root, out, say, t_end=5.0):
    import lagrgen
    path = root / "solo_description" / "robots" / "solo12.urdf"
    start = time.perf_counter()
    mod = lagrgen.build(solo_model(path, "solo_world"), out_dir=out, quiet=True)
    build = time.perf_counter() - start
    y0 = standing_state(mod, 0.3)
    lagrgen.simulate(mod, (0.0, 0.01), y0)                  # load the module's functions once
    walls, sol = [], None
    for _ in range(3):
        start = time.perf_counter()
        sol = lagrgen.simulate(mod, (0.0, t_end), y0, rtol=1e-6, atol=1e-8)
        walls.append(time.perf_counter() - start)
    feet = [f"{leg}_foot" for leg in SOLO_STAND]
    weight = mod.mass_matrix(y0[:18])[0, 0] * G
    normal = sum(sol.multipliers[f][-1] for f in feet)
    wall = min(walls)
    row = {"build_s": build, "wall_s": wall, "real_time_factor": t_end / wall,
           "nfev": int(sol.nfev), "segments": int(sol.n_segments),
           "transitions": len(sol.transitions), "success": bool(sol.success),
           "touchdown_s": next(t for t, _, k in sol.transitions if k == "contact"),
           "normal_over_weight_minus_1": normal / weight - 1.0,
           "base_z": float(sol.y[2, -1]), "joints": sol.y[6:18, -1].tolist()}
    say(f"solo12 landing + standing {t_end:g} s (native): {wall * 1e3:.1f} ms "
        f"({t_end / wall:.0f}× real time), nfev {sol.nfev}, {len(sol.transitions)} transitions, "
        f"Σ normal / m·g − 1 = {normal / weight - 1:.1e}")
    return mod, y0, row


def mujoco_model(path, radius=1e-3, timestep=1e-3):
    import mujoco
    text = Path(path).read_text()
    spec = mujoco.MjSpec.from_string(strip_meshes(text))
    spec.option.timestep = timestep
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.body("base_link").add_freejoint()
    return legged_contacts(mujoco, spec, SOLO_STAND, SOLO_JOINTS, "{leg}_FOOT", KP, KD, radius)


def legged_contacts(mujoco, spec, stand, joints, foot, kp, kd, radius):
    """MuJoCo's legged robot of `spec` compiled (model, data): its hinges <leg>_<joint> as springs
    of stiffness kp about the posture `stand` ({leg: one angle per name of `joints`}) with damping
    kd, no friction loss or armature; a sphere of `radius` at each foot (body `foot` formatted
    with leg=) and the floor `radius` below z = 0, μ = 1, the no-slip pass, soft contacts of time
    constant 5 ms."""
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
            leg, name = joint.name.split("_", 1)
            set_coefficient(joint, "stiffness", kp)
            joint.springref = stand[leg][joints.index(name)]
            set_coefficient(joint, "damping", kd)
            joint.frictionloss = 0.0
            joint.armature = 0.0
    for leg in stand:
        spec.body(foot.format(leg=leg)).add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE,
                                                 size=[radius, 0, 0], friction=[1.0, 0, 0])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1],
                            pos=[0, 0, -radius], friction=[1.0, 0, 0])
    model = spec.compile()
    model.opt.noslip_iterations = 10          # no creep of the sticking feet
    model.geom_solref[:] = (0.005, 1.0)       # stiffer soft contacts than the default 0.02 s
    return model, mujoco.MjData(model)


def strip_meshes(text):
    """The URDF without its <visual> and <collision> elements (MuJoCo would load their meshes)."""
    import re
    return re.sub(r"<(visual|collision)\b.*?</\1>", "", text, flags=re.S)


def set_coefficient(joint, name, value):
    """Set a joint's stiffness or damping: a polynomial's coefficients in MuJoCo 4, a number
    before."""
    try:
        setattr(joint, name, [value, 0.0, 0.0])         # MuJoCo 4: polynomial coefficients
    except TypeError:
        setattr(joint, name, value)


def rpy_quaternion(roll, pitch, yaw):
    """The unit quaternion (w, x, y, z), MuJoCo's order, of R = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def mujoco_case(root, mod, y0, say, t_end=5.0):
    import mujoco
    path = root / "solo_description" / "robots" / "solo12.urdf"
    rows = []
    for dt in (1e-3, 2e-3):
        m, d = mujoco_model(path, timestep=dt)
        joints = [m.joint(j).name for j in range(1, m.njnt)]
        assert joints == list(mod.coordinates[6:]), joints
        steps = int(round(t_end / dt))
        walls = []
        for _ in range(3):
            mujoco.mj_resetData(m, d)
            d.qpos[:] = np.concatenate([y0[:3], rpy_quaternion(*y0[3:6]), y0[6:18]])
            mujoco.mj_forward(m, d)
            start = time.perf_counter()
            mujoco.mj_step(m, d, nstep=steps)
            walls.append(time.perf_counter() - start)
        wall = min(walls)
        rows.append({"timestep": dt, "wall_s": wall, "real_time_factor": t_end / wall,
                     "contacts": int(d.ncon), "base_z": float(d.qpos[2]),
                     "joints": d.qpos[7:].tolist()})
        say(f"MuJoCo {mujoco.__version__} mj_step at {dt * 1e3:g} ms: {wall * 1e3:.1f} ms "
            f"({t_end / wall:.0f}× real time), {d.ncon} contacts at the end, base z "
            f"{d.qpos[2]:.5f} m")
    return rows


def load():
    return os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3


def markdown(report):
    lines = ["# Robots in the world: link kinematics and a legged robot on the ground",
             "", f"{report['machine']}; load average {report['load_before'][0]:.2f} before, "
             f"{report['load_after'][0]:.2f} after. Per call from Python, best of 3 rounds of "
             "`timeit` timing every call in turn (benchmarks/robots_world.py).", "",
             "## Link pose and frame Jacobian per call", "",
             "| frames | lagrgen pose | Pinocchio FK + frame placements | ratio | lagrgen "
             "Jacobian | Pinocchio computeFrameJacobian | ratio | max difference |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in report["kinematics"]:
        t = row["times"]
        lines.append(f"| {row['case']} | {t['lagrgen pose'] * 1e6:.2f} µs | "
                     f"{t['Pinocchio pose'] * 1e6:.2f} µs | "
                     f"{t['lagrgen pose'] / t['Pinocchio pose']:.2f}× | "
                     f"{t['lagrgen Jacobian'] * 1e6:.2f} µs | "
                     f"{t['Pinocchio Jacobian'] * 1e6:.2f} µs | "
                     f"{t['lagrgen Jacobian'] / t['Pinocchio Jacobian']:.2f}× | "
                     f"{row['difference']:.1e} |")
        if "Pinocchio Jacobian (joint Jacobians once)" in t:
            once = t["Pinocchio Jacobian (joint Jacobians once)"]
            lines += ["", f"solo12's four feet with Pinocchio's `computeJointJacobians` once and "
                      f"`getFrameJacobian` per foot: {once * 1e6:.2f} µs (lagrgen "
                      f"{t['lagrgen Jacobian'] / once:.2f}× that)."]
    if report.get("landing"):
        row = report["landing"]
        lines += ["", "## solo12 dropped from 0.3 m, landing and standing 5 s", "",
                  "| engine | wall time | × real time | notes |", "| --- | --- | --- | --- |",
                  f"| lagrgen native (RK45, rtol 1e-6; hybrid: impacts, resting contact, "
                  f"stick/slip friction) | {row['wall_s'] * 1e3:.1f} ms | "
                  f"{row['real_time_factor']:.0f}× | touchdown at {row['touchdown_s']:.4f} s, "
                  f"{row['transitions']} transitions, nfev {row['nfev']}; Σ normal force / m·g "
                  f"− 1 = {row['normal_over_weight_minus_1']:.1e} at the end; base z "
                  f"{row['base_z']:.5f} m |"]
        for m in report.get("mujoco", []):
            joints = np.max(np.abs(np.array(m["joints"]) - np.array(row["joints"])))
            lines.append(f"| MuJoCo mj_step, {m['timestep'] * 1e3:g} ms (soft contacts) | "
                         f"{m['wall_s'] * 1e3:.1f} ms | {m['real_time_factor']:.0f}× | base z "
                         f"{m['base_z']:.5f} m ({(m['base_z'] - row['base_z']) * 1e3:+.2f} mm: "
                         f"its contacts sink), joints within {joints:.1e} rad of lagrgen's |")
        lines += ["", "lagrgen's contacts are rigid (a foot on the floor has gap 0 and is held "
                  "by a force ≥ 0; friction sticks exactly within its disk) and its steps are "
                  "chosen by error control, few and long while the robot stands; MuJoCo's are "
                  "soft (a spring-damper in the constraint: the feet sink a little) and it takes "
                  "fixed steps. Build of the model (cold): "
                  f"{row['build_s']:.1f} s."]
    return "\n".join(lines) + "\n"


def main():
    say = print
    report = {"machine": f"{platform.processor() or platform.machine()}, Python "
                         f"{platform.python_version()}", "load_before": load(),
              "kinematics": []}
    out = Path(tempfile.gettempdir()) / "lagrgen-robots-world"
    try:
        root = robots_dir()
    except SystemExit:                      # example-robot-data is not installed
        root = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            import pinocchio  # noqa: F401
            report["kinematics"].append(arm_case(out, say))
            if root is not None:
                report["kinematics"].append(panda_case(root, out, say))
                report["kinematics"].append(solo_feet_case(root, out, say))
        except ImportError:
            say("pinocchio is not installed: no kinematics comparison")
        if root is not None:
            mod, y0, report["landing"] = landing_case(root, out, say)
            try:
                report["mujoco"] = mujoco_case(root, mod, y0, say)
            except ImportError:
                say("mujoco is not installed: no MuJoCo comparison")
    report["load_after"] = load()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "robots_world.md").write_text(markdown(report))
    (RESULTS / "robots_world.json").write_text(json.dumps(report, indent=1))
    say(markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
