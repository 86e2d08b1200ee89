"""What recording the least relative pivot of M costs (issue 45 item 6: NearSingularMassMatrixWarning).

Every factorization of M in a compiled model records its least pivot relative to its diagonal
entry on a thread-local of the model's module (one multiply and compare per pivot). This builds
each model twice, as lagrgen builds it and with `-DLG_NO_PIVOT_RECORD` (nothing recorded), and
counts the instructions of one rhs call on both (callgrind, when valgrind is installed: exact
whatever the load) and times the rhs looped inside C and a whole native solve (several rounds, the
two builds interleaved so that the load of a shared machine falls on both alike; the best round
of each, the least disturbed by the load). Prints the table
and writes benchmarks/results/pivot_record.{md,json}.

    nice python benchmarks/pivot_record.py
"""
import datetime
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OUT_DIR = HERE / "results" / "pivot_record_models"
ROUNDS = 21


def models():
    """(label, Model, formulation, y0, t_span) of the models timed."""
    sys.path.insert(0, str(ROOT))
    import lagrgen
    from examples.nlink_pendulum import make
    brick = lagrgen.Model("pivot_brick")
    roll, pitch, yaw = brick.coordinates("roll pitch yaw")
    brick.rigid_body_3d(1.0, (3.0, 2.0, 1.0), [0, 0, 0], lagrgen.rotation.z(yaw)
                        * lagrgen.rotation.y(pitch) * lagrgen.rotation.x(roll))
    chain = make(10)
    quad = lagrgen.from_urdf(ROOT / "examples" / "robots" / "quadruped.urdf", base="floating")
    out = [("brick (3, dense)", brick, "dense", [0, 0.3, 0, 2, 0, 0], (0, 10)),
           ("brick (3, recursive)", brick, "recursive", [0, 0.3, 0, 2, 0, 0], (0, 10)),
           ("10-link pendulum (dense)", chain, "dense", [0.5] * 10 + [0] * 10, (0, 10)),
           ("quadruped, floating base (18, recursive)", quad, "recursive",
            np.r_[np.zeros(3), 0.2, 0.3, 0.1, np.zeros(12), np.full(18, 0.5)], (0, 1))]
    return out


def build_pair(model, formulation):
    """{False: the model as lagrgen builds it, True: built with -DLG_NO_PIVOT_RECORD}."""
    import lagrgen
    return {flag: lagrgen.build(model, out_dir=OUT_DIR / ("off" if flag else "on"),
                                formulation=formulation, quiet=True,
                                cflags=["-DLG_NO_PIVOT_RECORD"] if flag else [])
            for flag in (False, True)}


def count_calls(index, flag, calls):
    """(In a child under callgrind) `calls` rhs calls of model `index`, build `flag`."""
    _, model, formulation, y0, _ = models()[index]
    mod = build_pair(model, formulation)[flag == "off"]
    mod.time_in_c("rhs", 0.0, np.asarray(y0, dtype=float), repeat=calls)


def instructions(index, name, flag, calls=1000):
    """Instructions per rhs call (callgrind, collected inside `<name>_rhs` only: exact and
    independent of the load), or None without valgrind."""
    import shutil
    import subprocess
    import tempfile
    if shutil.which("valgrind") is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/cg",
                              f"--toggle-collect={name}_rhs", sys.executable, __file__,
                              "--count", str(index), flag, str(calls)],
                             capture_output=True, text=True)
    found = [line for line in out.stderr.splitlines() if "Collected :" in line]
    return int(found[-1].split(":")[-1]) / calls if found else None


def timed(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main():
    import lagrgen
    rows = []
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    for index, (label, model, formulation, y0, span) in enumerate(models()):
        pair = build_pair(model, formulation)
        y0 = np.asarray(y0, dtype=float)
        rhs = {k: [] for k in pair}
        solve = {k: [] for k in pair}
        for _ in range(ROUNDS):
            for flag, mod in pair.items():
                rhs[flag].append(mod.time_in_c("rhs", 0.0, y0, repeat=20000) * 1e9)
                solve[flag].append(timed(lambda: lagrgen.simulate(
                    mod, span, y0, method="DOP853", rtol=1e-8, atol=1e-10)) * 1e3)
        on, off = min(rhs[False]), min(rhs[True])             # the least loaded round
        son, soff = min(solve[False]), min(solve[True])
        counts = [instructions(index, model.name, flag) for flag in ("on", "off")]
        rows.append(dict(model=label, rhs_ns_recorded=on, rhs_ns_not=off, rhs_ratio=on / off,
                         solve_ms_recorded=son, solve_ms_not=soff, solve_ratio=son / soff,
                         rhs_instructions_recorded=counts[0], rhs_instructions_not=counts[1]))
    load = os.getloadavg()
    lines = ["# Recording the least relative pivot of M (NearSingularMassMatrixWarning)", "",
             f"{datetime.date.today()}, load average {load[0]:.1f} / {load[1]:.1f} on "
             f"{os.cpu_count()} cores; best of {ROUNDS} interleaved rounds; the solve is "
             "simulate(..., method='DOP853', rtol=1e-8, atol=1e-10) on the native engine.", "",
             "Instructions per rhs call: callgrind, inside the model's rhs only (exact, whatever "
             "the load; the timings on a loaded machine vary by tens of per cent between runs).",
             "", "| model | rhs instructions, recorded / not | rhs in C, recorded / not (ns) | "
             "ratio | native solve, recorded / not (ms) | ratio |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        a, b = r["rhs_instructions_recorded"], r["rhs_instructions_not"]
        counted = "—" if a is None or b is None else f"{a:.0f} / {b:.0f} ({a / b - 1:+.2%})"
        lines.append(f"| {r['model']} | {counted} | {r['rhs_ns_recorded']:.0f} / "
                     f"{r['rhs_ns_not']:.0f} | {r['rhs_ratio']:.3f} | "
                     f"{r['solve_ms_recorded']:.2f} / {r['solve_ms_not']:.2f} | "
                     f"{r['solve_ratio']:.3f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    (HERE / "results" / "pivot_record.md").write_text(text)
    (HERE / "results" / "pivot_record.json").write_text(json.dumps(
        {"load": load, "rounds": ROUNDS, "rows": rows}, indent=1))


if __name__ == "__main__":
    if sys.argv[1:2] == ["--count"]:
        count_calls(int(sys.argv[2]), sys.argv[3], int(sys.argv[4]))
    else:
        main()
