"""lagrgen against Pinocchio on real robots: every URDF of example-robot-data with at most
--max-joints joints (fixed base, as `pinocchio.buildModelFromUrdf` reads them; mimic joints as
independent joints and inertias no mass distribution has taken as they are, as Pinocchio does;
joints that move no mass held fixed, in both), and Solo12 with a floating base.

For each robot: `lagrgen.from_urdf` + cold build time; q̈, M and the Jacobian of the rhs against
Pinocchio's `aba`, `crba` and `computeABADerivatives` at random states (largest relative
difference; the floating base against a Pinocchio model whose base is the same six 1-DOF joints,
its Jacobian against central differences of lagrgen's rhs, since Pinocchio differentiates such a
joint on its Lie group); then per call from Python,
best of 3 rounds timing each call in turn, in the same process: lagrgen's rhs, jacobian (2n×2n) and mass_matrix against `aba`,
`computeABADerivatives` and `crba` (Pinocchio's free-flyer model for the floating base).

Then 3-D serial chains of --chains joints (benchmarks/_chains.py: random placements, axes
cycling through z, y, x) measured the same way; the planar 20-link chain's Jacobian
(examples/nlink_pendulum.py, the issue-43 floor: ≤ 5 µs); and the cold `from_urdf` + build of
chains of --builds joints and of tiago_dual, each in a fresh process with a fresh folder, with
the growth exponent of the build time (the slope of log time against log n).

    pip install ".[peers]" example-robot-data       # Pinocchio 4.1 and the robots (400 MB)
    python benchmarks/robots.py                     # all robots up to 60 joints
    python benchmarks/robots.py --robots ur5_robot panda talos_reduced solo12
    python benchmarks/robots.py --robots talos_reduced --update   # measure again, replace its row
    python benchmarks/robots.py --robots none --chains 50 100 200 --builds 100 200 500

Prints a markdown table and writes benchmarks/results/robots.md and robots.json. Builds go to
--out (default: a folder in the system's temporary directory).
"""
import argparse
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
RESULTS = HERE / "results"
#: Robots reported first (the issue's), then the rest in name order.
FIRST = ("ur5_robot", "panda", "talos_reduced", "solo12")


def robots_dir():
    """The robots folder of the example-robot-data package."""
    import importlib.metadata
    try:
        files = importlib.metadata.files("example-robot-data") or ()
    except importlib.metadata.PackageNotFoundError:
        files = ()
    for f in files:
        if str(f).endswith("robots/ur_description/urdf/ur5_robot.urdf"):
            return Path(f.locate()).parents[2]
    raise SystemExit("example-robot-data is not installed: pip install example-robot-data")


def urdf_files(root):
    return sorted(root.glob("*/*/*.urdf"))


def row_name(path, root):
    """A robot's row: its file's path under the robots folder, without .urdf (two files share
    the stem anymal)."""
    return Path(path).relative_to(root).with_suffix("").as_posix()


def without_root(text, root):
    """`text` with the robots folder's absolute path left out (results name no machine's path)."""
    return str(text).replace(str(root) + os.sep, "").replace(str(root), "robots")


def best_per_call(f, repeats=7):
    timer = timeit.Timer(f)
    number, _ = timer.autorange()
    return min(timer.repeat(repeats, number)) / number


def interleaved_best(calls, rounds=3):
    """{name: seconds per call}: the best over `rounds` rounds that time every call in turn, so
    that a burst of load on a shared machine does not fall on one side of a comparison alone."""
    best = dict.fromkeys(calls, float("inf"))
    for _ in range(rounds):
        for name, call in calls.items():
            best[name] = min(best[name], best_per_call(call, repeats=3))
    return best


def relative(a, b):
    """Largest difference over b's largest entry (absolute where every entry is below 1)."""
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(b).max(), 1.0))


def central_differences(mod, y, h=1e-6):
    """∂ẏ/∂y by central differences of mod.rhs (the floating base's check: ~1e-8 relative)."""
    return np.column_stack([(mod.rhs(0.0, y + h * e) - mod.rhs(0.0, y - h * e)) / (2 * h)
                            for e in np.eye(len(y))])


def pinocchio_models(path, floating, coordinates):
    """(model for agreement, model for timing): both plain for a fixed base; for a floating one
    a composite base of six 1-DOF joints (lagrgen's coordinates: q̈ and M compared) and the
    free-flyer (timed). Joints lagrgen holds fixed (moving no mass) are locked at zero."""
    import pinocchio as pin
    if not floating:
        m = pin.buildModelFromUrdf(str(path))
        locked = [j for j in range(1, m.njoints) if _identifier(m.names[j]) not in coordinates]
        if locked:
            m = pin.buildReducedModel(m, locked, pin.neutral(m))
        return m, m
    chain = pin.JointModelComposite()
    for joint in (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelPZ(),
                  pin.JointModelRZ(), pin.JointModelRY(), pin.JointModelRX()):
        chain.addJoint(joint)
    return (pin.buildModelFromUrdf(str(path), chain),
            pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()))


class Mapping:
    """lagrgen's coordinates and Pinocchio's configurations and velocities of one robot."""

    def __init__(self, mod, pm, floating):
        self.n = mod.n_coordinates
        self.order, self.slots = [], []          # lagrgen index per Pinocchio velocity
        for j in range(1, pm.njoints):
            name = pm.names[j]
            names = (["base_x", "base_y", "base_z", "base_yaw", "base_pitch", "base_roll"]
                     if floating and j == 1 else [_identifier(name)])
            jm = pm.joints[j]
            self.order += [mod.coordinates.index(c) for c in names]
            self.slots.append((jm.idx_q, jm.nq, jm.idx_v, jm.nv, [mod.coordinates.index(c)
                                                                  for c in names]))

    def q(self, q, pm):
        out = np.zeros(pm.nq)
        for idx_q, nq, _, nv, coords in self.slots:
            if nq == 2 * nv:                       # continuous joint: (cos θ, sin θ)
                out[idx_q:idx_q + 2] = np.cos(q[coords[0]]), np.sin(q[coords[0]])
            else:
                out[idx_q:idx_q + nq] = q[coords]
        return out

    def v(self, v):
        return np.asarray(v)[self.order]


def _identifier(name):
    from lagrgen.urdf import identifier
    return identifier(name)


def robot_row(path, root, floating, out_dir, say):
    """Build, cross-check and time one robot; its record."""
    import pinocchio as pin

    import lagrgen
    name = row_name(path, root) + ("" if not floating else " (floating base)")
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lagrgen.URDFWarning)
        model = lagrgen.from_urdf(path, joint_dynamics=False, mimic=False, check_inertias=False,
                                  massless="fixed", base="floating" if floating else "fixed",
                                  name=_identifier(path.stem) + ("_floating" if floating else ""))
    described = time.perf_counter() - start
    mod = lagrgen.build(model, out_dir=out_dir, quiet=True, force=True)
    cold = time.perf_counter() - start
    n = mod.n_coordinates
    exact_model, timed_model = pinocchio_models(path, floating, mod.coordinates)
    ed, td = exact_model.createData(), timed_model.createData()
    mapping = Mapping(mod, exact_model, floating)
    rng = np.random.default_rng(42)
    worst = {"qdd": 0.0, "jacobian": 0.0, "mass_matrix": 0.0}
    for _ in range(3):
        q, v = rng.uniform(-1.0, 1.0, n), rng.uniform(-1.0, 1.0, n)
        y = np.concatenate([q, v])
        qp, vp, tau = mapping.q(q, exact_model), mapping.v(v), np.zeros(exact_model.nv)
        qdd = pin.aba(exact_model, ed, qp, vp, tau)
        worst["qdd"] = max(worst["qdd"], relative(mod.rhs(0.0, y)[n:][mapping.order], qdd))
        M = pin.crba(exact_model, ed, qp)
        M = np.triu(M) + np.triu(M, 1).T
        worst["mass_matrix"] = max(worst["mass_matrix"], relative(
            mod.mass_matrix(q)[np.ix_(mapping.order, mapping.order)], M))
        J = mod.jacobian(0.0, y)
        if floating:      # Pinocchio differentiates a composite joint on its Lie group
            worst["jacobian"] = max(worst["jacobian"], relative(J, central_differences(mod, y)))
            continue
        pin.computeABADerivatives(exact_model, ed, qp, vp, tau)
        o = mapping.order
        worst["jacobian"] = max(worst["jacobian"],
                                relative(J[n:, :n][np.ix_(o, o)], ed.ddq_dq),
                                relative(J[n:, n:][np.ix_(o, o)], ed.ddq_dv))
    q, v = rng.uniform(-1.0, 1.0, n), rng.uniform(-1.0, 1.0, n)
    y = np.concatenate([q, v])
    if floating:
        qp, vp = pin.randomConfiguration(timed_model, -np.ones(timed_model.nq),
                                         np.ones(timed_model.nq)), v[mapping.order]
    else:
        qp, vp = mapping.q(q, timed_model), mapping.v(v)
    tau = np.zeros(timed_model.nv)
    say(f"  {name}: n = {n}, timing ...")
    calls = {
        "rhs": lambda: mod.rhs(0.0, y),
        "aba": lambda: pin.aba(timed_model, td, qp, vp, tau),
        "jacobian": lambda: mod.jacobian(0.0, y),
        "derivatives": lambda: pin.computeABADerivatives(timed_model, td, qp, vp, tau),
        "mass_matrix": lambda: mod.mass_matrix(q),
        "crba": lambda: pin.crba(timed_model, td, qp),
    }
    times = interleaved_best(calls)
    return {"robot": name, "n": n, "describe_s": described, "cold_build_s": cold,
            "formulation": mod.formulation, "agreement": worst,
            "us": {k: v * 1e6 for k, v in times.items()}}


def table(rows):
    lines = ["| robot | n | from_urdf + cold build | rhs / `aba` µs | ratio | jacobian / "
             "`computeABADerivatives` µs | ratio | M / `crba` µs | ratio | largest difference "
             "q̈ / J / M |",
             "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | :-- |"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['robot']} | | {r['error']} | | | | | | | |")
            continue
        t, a = r["us"], r["agreement"]
        lines.append(
            f"| {r['robot']} | {r['n']} | {r['cold_build_s']:.2f} s | {t['rhs']:.3g} / "
            f"{t['aba']:.3g} | {t['rhs'] / t['aba']:.2f}× | {t['jacobian']:.3g} / "
            f"{t['derivatives']:.3g} | {t['jacobian'] / t['derivatives']:.2f}× | "
            f"{t['mass_matrix']:.3g} / {t['crba']:.3g} | {t['mass_matrix'] / t['crba']:.2f}× | "
            f"{a['qdd']:.1e} / {a['jacobian']:.1e} / {a['mass_matrix']:.1e} |")
    return "\n".join(lines)


def chain_rows(sizes, out_dir, say):
    """The rows of 3-D serial chains of `sizes` joints (benchmarks/_chains.py)."""
    from _chains import chain_urdf
    rows = []
    folder = Path(tempfile.mkdtemp(prefix="lagrgen_chains_"))
    for n in sizes:
        path = folder / f"chain{n}.urdf"
        path.write_text(chain_urdf(n))
        say(f"  chain{n} ...")
        rows.append(robot_row(path, False, out_dir, say))
    return rows


def planar_row(out_dir):
    """The planar 20-link chain's Jacobian per call from Python (µs), against Pinocchio's."""
    import pinocchio as pin

    import _pinocchio
    import lagrgen
    sys.path.insert(0, str(HERE.parent))
    from examples.nlink_pendulum import make
    n = 20
    mod = lagrgen.build(make(n), out_dir=out_dir, quiet=True)
    pm = _pinocchio.chain(n)
    data = pm.createData()
    state = _pinocchio.ChainState.of(np.random.default_rng(120).uniform(-1.0, 1.0, 2 * n))
    tau = np.zeros(n)
    times = interleaved_best({
        "jacobian": lambda: mod.jacobian(0.0, state.y),
        "derivatives": lambda: pin.computeABADerivatives(pm, data, state.q, state.v, tau)})
    return {"n": n, "formulation": mod.formulation, "us": {k: v * 1e6 for k, v in times.items()}}


BUILD_SCRIPT = """
import sys, tempfile, time, warnings
start = time.perf_counter()
import lagrgen
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    model = lagrgen.from_urdf(sys.argv[1], joint_dynamics=False, mimic=False,
                              check_inertias=False, massless="fixed", name=sys.argv[2])
mod = lagrgen.build(model, out_dir=tempfile.mkdtemp(), quiet=True, force=True)
print(time.perf_counter() - start, mod.n_coordinates,
      " ".join(f"{k}={v:.2f}" for k, v in mod.build_info.items() if k != "cache_hit"))
"""


def build_rows(sizes, robots_root, say):
    """Cold `import lagrgen` + `from_urdf` + build, each in a fresh process and folder: chains of
    `sizes` joints, then tiago_dual; and the growth exponent over the chains."""
    import subprocess

    from _chains import chain_urdf
    folder = Path(tempfile.mkdtemp(prefix="lagrgen_builds_"))
    cases = []
    for n in sizes:
        path = folder / f"chain{n}.urdf"
        path.write_text(chain_urdf(n))
        cases.append((f"chain{n}", path))
    dual = next(iter(sorted(robots_root.glob("*/*/tiago_dual.urdf"))), None)
    if dual is not None:
        cases.append(("tiago_dual", dual))
    rows = []
    for name, path in cases:
        say(f"  cold build of {name} ...")
        done = subprocess.run([sys.executable, "-c", BUILD_SCRIPT, str(path), name],
                              capture_output=True, text=True)
        if done.returncode:
            rows.append({"robot": name, "error": done.stderr.strip().splitlines()[-1][:160]})
            continue
        seconds, n, stages = done.stdout.split(maxsplit=2)
        rows.append({"robot": name, "n": int(n), "seconds": float(seconds),
                     "stages": stages.strip()})
    chains = [r for r in rows if r["robot"].startswith("chain") and "seconds" in r]
    exponent = None
    if len(chains) > 1:
        exponent = float(np.polyfit(np.log([r["n"] for r in chains]),
                                    np.log([r["seconds"] for r in chains]), 1)[0])
    return rows, exponent


def extras_text(chains, planar, builds, exponent):
    """The markdown of the chains' table, the planar row and the build times."""
    parts = []
    if chains:
        parts += ["## 3-D serial chains (benchmarks/_chains.py)", "", table(chains), ""]
    if planar:
        t = planar["us"]
        parts += ["## The planar 20-link chain (examples/nlink_pendulum.py)", "",
                  f"Jacobian per call from Python: {t['jacobian']:.2f} µs ({planar['formulation']}"
                  f" formulation; target ≤ 5 µs), Pinocchio's `computeABADerivatives` "
                  f"{t['derivatives']:.2f} µs: {t['jacobian'] / t['derivatives']:.2f}×.", ""]
    if builds:
        parts += ["## Cold `from_urdf` + build (a fresh process each, `import lagrgen` included)",
                  "", "| robot | n | seconds | stages (s) |", "| :-- | --: | --: | :-- |"]
        for r in builds:
            if "error" in r:
                parts.append(f"| {r['robot']} | | {r['error']} | |")
            else:
                parts.append(f"| {r['robot']} | {r['n']} | {r['seconds']:.1f} | {r['stages']} |")
        if exponent is not None:
            parts += ["", f"Growth exponent of the chains' build time: {exponent:.2f} "
                      "(the slope of log seconds against log n)."]
        parts.append("")
    return "\n".join(parts)


def joints_of(path):
    from lagrgen.urdf import MOVING, read
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = read(path, check_inertias=False)
    return sum(1 for j in robot.joints if j.kind in MOVING)


def updated(old, new):
    """The rows of `old` with those of the same robots replaced by `new`'s (new ones appended)."""
    fresh = {row["robot"]: row for row in new}
    rows = [fresh.pop(row["robot"], row) for row in old]
    return rows + list(fresh.values())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="*",
                        help="file stems, or paths under the robots folder without .urdf "
                        "(default: all)")
    parser.add_argument("--max-joints", type=int, default=60)
    parser.add_argument("--out", default=os.path.join(tempfile.gettempdir(), "lagrgen_robots"))
    parser.add_argument("--no-write", action="store_true", help="print only")
    parser.add_argument("--update", action="store_true",
                        help="measure the --robots again and replace their rows in the results")
    parser.add_argument("--chains", nargs="*", type=int, default=[50, 100, 200],
                        help="3-D serial chains measured like the robots")
    parser.add_argument("--builds", nargs="*", type=int, default=[100, 200, 500],
                        help="chains whose cold from_urdf + build is timed (and tiago_dual)")
    parser.add_argument("--no-planar", action="store_true")
    args = parser.parse_args(argv)
    import pinocchio

    import lagrgen
    root = robots_dir()
    files = urdf_files(root)
    if args.robots:
        files = [f for f in files if f.stem in args.robots or row_name(f, root) in args.robots]
    chosen = []
    for f in files:
        try:
            count = joints_of(f)
        except lagrgen.LagrgenError as exc:
            chosen.append((f, False, without_root(str(exc).splitlines()[0], root)[:120]))
            continue
        if 0 < count <= args.max_joints:
            chosen.append((f, False, None))
    if not args.robots or {"solo12", "solo_description/robots/solo12"} & set(args.robots):
        solo = next((f for f in files if f.stem == "solo12"), None)
        if solo:
            chosen.append((solo, True, None))
    chosen.sort(key=lambda c: (c[0].stem not in FIRST or c[1],
                               FIRST.index(c[0].stem) if c[0].stem in FIRST else 0, c[0].stem))
    load = os.getloadavg()
    rows = []
    for path, floating, error in chosen:
        if error:
            rows.append({"robot": row_name(path, root), "error": f"not read: {error}"})
            continue
        try:
            rows.append(robot_row(path, root, floating, args.out,
                                  lambda s: print(s, file=sys.stderr)))
        except Exception as exc:            # a robot lagrgen or Pinocchio cannot take: say so
            first = without_root(str(exc).splitlines()[0], root)[:120]
            rows.append({"robot": row_name(path, root), "error": f"{type(exc).__name__}: {first}"})
    say = lambda text: print(text, file=sys.stderr)      # noqa: E731
    chains = chain_rows(args.chains, args.out, say)
    planar = None if args.no_planar else planar_row(args.out)
    builds, exponent = build_rows(args.builds, root, say) if args.builds else ([], None)
    after = os.getloadavg()
    if args.update:
        rows = updated(json.loads((RESULTS / "robots.json").read_text()), rows)
    header = (f"# lagrgen against Pinocchio on example-robot-data\n\n"
              f"{time.strftime('%Y-%m-%d %H:%M')}, {platform.machine()}, Python "
              f"{platform.python_version()}, pin {pinocchio.__version__}, lagrgen "
              f"{lagrgen.__version__}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} "
              f"before, {after[0]:.2f} {after[1]:.2f} {after[2]:.2f} after (a shared machine: "
              "per-call figures up to ~2× high; the ratios were measured side by side).\n\n"
              "Per call from Python in µs, the best of 3 rounds that time each call in turn; "
              "ratio = lagrgen ÷ Pinocchio (below 1: "
              "lagrgen is faster). Fixed bases as `buildModelFromUrdf` reads them, mimic joints "
              "independent; Solo12 also with a floating base (lagrgen: base_x … base_yaw; "
              "Pinocchio timed with its free-flyer); joints that move no mass (romeo's hands) "
              "locked in both. Largest difference from Pinocchio, relative to the largest "
              "entry (absolute below 1), at three random states (the floating base's Jacobian: from central "
              "differences of the rhs, h = 1e-6).\n")
    if args.update:
        header += (f"The rows of {', '.join(args.robots)} were measured again at that time, "
                   "the others earlier (robots.json keeps no date per row).\n")
    text = header + "\n" + table(rows) + "\n\n" + extras_text(chains, planar, builds, exponent)
    print(text)
    if not args.no_write:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "robots.md").write_text(text)
        (RESULTS / "robots.json").write_text(json.dumps(rows, indent=1))
        (RESULTS / "robots_scaling.json").write_text(json.dumps(
            {"chains": chains, "planar": planar, "builds": builds,
             "build_exponent": exponent}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
