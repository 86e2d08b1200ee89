"""Inertial identification (issue 38): the joint-torque regressor Y(q, q̇, q̈) (τ = Y·π) against
Pinocchio's `computeJointTorqueRegressor` and against lagrgen's own rhs at the same n, then the
whole procedure on the seven-joint arm kept in the repository: base parameters, an exciting
trajectory and the identification from 10 s of 1 kHz records.

For each robot (examples/robots/arm7.urdf always; UR5, Panda and Talos from example-robot-data
when installed): `from_urdf(..., parameters="inertial")` built once (the regressor and an rhs
whose masses are parameters) and once plainly (an rhs whose numbers are folded into the code);
the largest difference of the regressor from Pinocchio's (columns matched by body, relative to
the largest entry) at three random states; then per call from Python, best of 3 rounds timing
every call in turn: lagrgen's regressor, both rhs, Pinocchio's regressor and `aba`.

    pip install ".[peers]" example-robot-data
    python benchmarks/inertial.py

Prints a markdown table and writes benchmarks/results/inertial.md (and .json).
"""
import argparse
import json
import os
import platform
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
RESULTS = HERE / "results"
ARM = HERE.parent / "examples" / "robots" / "arm7.urdf"
#: example-robot-data robots timed besides the arm (file stem -> path under its robots folder).
ERD = {"ur5_robot": "ur_description/urdf/ur5_robot.urdf",
       "panda": "panda_description/urdf/panda.urdf",
       "talos_reduced": "talos_data/robots/talos_reduced.urdf"}

import lagrgen  # noqa: E402
from robots import _identifier, interleaved_best, robots_dir  # noqa: E402


def robot_paths():
    """{label: URDF path}: the repository's arm, then the example-robot-data ones installed."""
    paths = {"arm7": ARM}
    try:
        root = robots_dir()
    except SystemExit:
        return paths
    paths.update({label: root / rel for label, rel in ERD.items() if (root / rel).exists()})
    return paths


def pinocchio_columns(mod, pm):
    """Pinocchio's regressor columns in the order of `mod.inertial_parameters` (joint j's ten
    columns are those of the body its child link heads, the links fixed to it merged)."""
    import pinocchio as pin
    names = list(mod.inertial_parameters)
    order = np.empty(len(names), dtype=int)
    for j in range(1, pm.njoints):
        bodies = [_identifier(f.name) for f in pm.frames
                  if f.parentJoint == j and f.type == pin.FrameType.BODY]
        link = next(b for b in bodies if f"m_{b}" in names)
        start = names.index(f"m_{link}")
        order[start:start + 10] = np.arange(10 * (j - 1), 10 * j)
    return order


def regressor_row(label, path, out, say):
    """Agreement and per-call times of one robot's regressor."""
    import pinocchio as pin
    say(f"  {label}: building ...")
    common = dict(joint_dynamics=False, mimic=False, check_inertias=False)
    inertial = lagrgen.build(lagrgen.from_urdf(path, parameters="inertial",
                                               name=f"inertial_{label}", **common),
                             out_dir=out, quiet=True)
    folded = lagrgen.build(lagrgen.from_urdf(path, name=f"folded_{label}", **common),
                           out_dir=out, quiet=True)
    pm = pin.buildModelFromUrdf(str(path))
    pd = pm.createData()
    columns = pinocchio_columns(inertial, pm)
    index = [inertial.coordinates.index(_identifier(pm.names[j])) for j in range(1, pm.njoints)]
    n = inertial.n_coordinates
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(3):
        q, qd, a = rng.uniform(-1, 1, (3, n))
        Y = inertial.regressor(q, qd, a)
        P = pin.computeJointTorqueRegressor(pm, pd, q[index], qd[index], a[index])
        worst = max(worst, float(np.abs(Y[index] - P[:, columns]).max() / np.abs(P).max()))
    q, qd, a = rng.uniform(-1, 1, (3, n))
    y = np.concatenate([q, qd])
    qp, vp, ap = q[index], qd[index], a[index]
    tau = np.zeros(n)
    say(f"  {label}: timing ...")
    times = interleaved_best({
        "regressor": lambda: inertial.regressor(q, qd, a),
        "rhs_inertial": lambda: inertial.rhs(0.0, y),
        "rhs_folded": lambda: folded.rhs(0.0, y),
        "pin_regressor": lambda: pin.computeJointTorqueRegressor(pm, pd, qp, vp, ap),
        "pin_aba": lambda: pin.aba(pm, pd, qp, vp, tau),
    })
    return {"robot": label, "n": n, "parameters": len(inertial.inertial_parameters),
            "difference": worst, **{k: v * 1e6 for k, v in times.items()}}


def identification_row(out, say, duration=10.0, rate=1000.0):
    """Seconds of each step of the procedure on the arm: base parameters, the exciting
    trajectory (5 harmonics, 10 rad/s² added to the file's limits), the identification from
    `duration` s of `rate` Hz records (torques Y·π plus 0.2 N·m of noise)."""
    say("  arm7: identification ...")
    arm = lagrgen.build(lagrgen.from_urdf(ARM, parameters="inertial", joint_dynamics=False,
                                          name="inertial_arm7"), out_dir=out, quiet=True)
    start = time.perf_counter()
    base = lagrgen.base_parameters(arm)
    base_s = time.perf_counter() - start
    limits = {joint: (None, None, None, 10.0) for joint in arm.coordinates}
    start = time.perf_counter()
    traj = lagrgen.exciting_trajectory(arm, duration, harmonics=5, limits=limits, base=base)
    traj_s = time.perf_counter() - start
    t = np.arange(0.0, duration, 1.0 / rate)
    q, qd, qdd = traj.q(t), traj.qd(t), traj.qdd(t)
    truth = dict(zip(arm.parameters, arm.defaults))
    pi = np.array([truth[name] for name in arm.inertial_parameters])
    tau = np.array([arm.regressor(q[:, i], qd[:, i], qdd[:, i]) @ pi for i in range(t.size)]).T
    rng = np.random.default_rng(7)
    tau_measured = tau + 0.2 * rng.standard_normal(tau.shape)
    q_measured = q + 1e-4 * rng.standard_normal(q.shape)
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        est = lagrgen.identify_inertial(arm, t, q_measured, tau_measured, base=base)
        best = min(best, time.perf_counter() - start)
    values = base.values(truth)
    z = max(abs(est.values[name] - v) / est.stderr[name] for name, v in zip(base.names, values))
    return {"base_parameters": len(base.names), "base_seconds": base_s,
            "trajectory_seconds": traj_s, "condition": traj.condition,
            "samples": t.size, "identify_seconds": best, "largest_z": z}


def table(rows, ident, header):
    lines = [header, "",
             "Per call from Python in µs, best of 3 rounds timing every call in turn. "
             "rhs (π) is the rhs of the same build as the regressor (the masses are "
             "parameters); rhs (folded) that of a plain build (the file's numbers folded "
             "into the code). Difference from Pinocchio's regressor relative to its largest "
             "entry, at three random states.", "",
             "| robot | n | π | regressor | rhs (π) | regressor ÷ rhs (π) | rhs (folded) | "
             "Pinocchio regressor | lagrgen ÷ Pinocchio | `aba` | difference |",
             "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: |"]
    for r in rows:
        lines.append(
            f"| {r['robot']} | {r['n']} | {r['parameters']} | {r['regressor']:.3g} | "
            f"{r['rhs_inertial']:.3g} | {r['regressor'] / r['rhs_inertial']:.2f}× | "
            f"{r['rhs_folded']:.3g} | {r['pin_regressor']:.3g} | "
            f"{r['regressor'] / r['pin_regressor']:.2f}× | {r['pin_aba']:.3g} | "
            f"{r['difference']:.1e} |")
    lines += ["", "The seven-joint arm (examples/robots/arm7.urdf), one core:", "",
              "| step | result | seconds |", "| :-- | :-- | --: |",
              f"| `base_parameters` | {ident['base_parameters']} of 70 | "
              f"{ident['base_seconds']:.2f} |",
              f"| `exciting_trajectory` (10 s, 5 harmonics) | condition "
              f"{ident['condition']:.1f} | {ident['trajectory_seconds']:.2f} |",
              f"| `identify_inertial` ({ident['samples']} records, 10 s at 1 kHz) | largest "
              f"|error| / stderr {ident['largest_z']:.2f} | {ident['identify_seconds']:.2f} |"]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=os.path.join(tempfile.gettempdir(), "lagrgen_inertial"))
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore", lagrgen.URDFWarning)
    import pinocchio as pin

    def say(text):
        print(text, file=sys.stderr, flush=True)
    load = os.getloadavg()
    rows = [regressor_row(label, path, args.out, say) for label, path in robot_paths().items()]
    ident = identification_row(args.out, say)
    header = ("# The inertial regressor and identification\n\n"
              f"{time.strftime('%Y-%m-%d %H:%M')}, {platform.machine()}, Python "
              f"{platform.python_version()}, pin {pin.__version__}, lagrgen "
              f"{lagrgen.__version__}; load average {load[0]:.2f} before, "
              f"{os.getloadavg()[0]:.2f} after.")
    text = table(rows, ident, header)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "inertial.md").write_text(text)
    (RESULTS / "inertial.json").write_text(json.dumps({"robots": rows, "arm7": ident}, indent=1))


if __name__ == "__main__":
    main()
