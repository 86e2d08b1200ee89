"""The native engine against the SciPy engine on the n-link pendulum (issue 10, part 6, partial).

n = 2, 5, 10, 20 links, t = 0..10 s, rtol = atol = 1e-8, all angles 0.5 rad, zero speeds. For each
n a fresh process loads the (cached) compiled model and times RK23, RK45, DOP853, Radau and BDF on
`lagrgen.simulate(..., engine="native")` and `engine="scipy"` (medians of several runs after one
warm-up), checks that nfev/njev/nlu are equal, and times the rhs and the Jacobian inside C for
the floor nfev x rhs + njev x jacobian (what the model's evaluations alone cost; issue 30 asks
Radau <= 1.4 x and BDF <= 1.6 x of it at n = 10). Prints the table and writes
benchmarks/results/native.{md,json}.

    python benchmarks/native.py             # n = 2 5 10 20
    python benchmarks/native.py --n 2 10    # a subset

JiTCODE, odeint and the ensemble/Dask figures of the issue are not measured here.
"""
import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from lagrgen.methods import NATIVE_METHODS

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OUT_DIR = HERE / "results" / "native_models"
METHODS = NATIVE_METHODS
T_SPAN = (0.0, 10.0)
TOL = 1e-8
TARGETS = {("DOP853", 10): 2.5, ("DOP853", 20): 12.0, ("Radau", 10): 20.0, ("BDF", 10): 6.0}
#: native / floor targets (issue 30)
FLOOR_TARGETS = {("RK45", 10): 1.2, ("Radau", 10): 1.4, ("BDF", 10): 1.6}


def model_for(n):
    """Build (or load from the cache) the n-link pendulum."""
    sys.path.insert(0, str(ROOT))
    import lagrgen
    from examples.nlink_pendulum import make
    return lagrgen.build(make(n), out_dir=OUT_DIR)


def timed(fn, runs):
    """(median, min) wall time in ms of fn() over `runs` runs after one warm-up, and its result."""
    result = fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), min(times), result


def worker(n):
    """Run in a fresh process: time every method on both engines for the n-link pendulum."""
    import lagrgen
    mod = model_for(n)
    y0 = np.r_[np.full(n, 0.5), np.zeros(n)]
    rows = []
    for method in METHODS:
        def run(engine):
            return lagrgen.simulate(mod, T_SPAN, y0, method=method, rtol=TOL, atol=TOL,
                                    engine=engine)
        nat_ms, nat_min, nat = timed(lambda: run("native"), 21)
        sci_runs = 3 if method in ("Radau", "BDF", "RK23") or n >= 10 else 5
        sci_ms, _, sci = timed(lambda: run("scipy"), sci_runs)
        rows.append(dict(
            n=n, method=method, native_ms=nat_ms, native_min_ms=nat_min, scipy_ms=sci_ms,
            ratio=sci_ms / nat_ms,
            nfev=int(nat.nfev), njev=int(nat.njev), nlu=int(nat.nlu), steps=int(nat.t.size - 1),
            same_counts=(nat.nfev, nat.njev, nat.nlu, nat.t.size)
            == (sci.nfev, sci.njev, sci.nlu, sci.t.size),
            max_rel_diff_final=float(np.max(np.abs(nat.y[:, -1] - sci.y[:, -1]))
                                     / np.max(np.abs(sci.y[:, -1]))),
        ))
    rhs_s = min(mod.time_in_c("rhs", 0.0, y0, repeat=20000) for _ in range(15))
    jac_s = min(mod.time_in_c("jacobian", 0.0, y0, repeat=5000) for _ in range(15))
    for r in rows:
        r["rhs_in_c_us"] = rhs_s * 1e6
        r["jacobian_in_c_us"] = jac_s * 1e6
        r["floor_ms"] = (r["nfev"] * rhs_s + r["njev"] * jac_s) * 1e3
    print(json.dumps(rows))


def markdown(rows, load_before, load_after):
    lines = [
        "# Native engine vs SciPy engine: n-link pendulum",
        "",
        f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; load average (1, 5, 15 min) before "
        f"{load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f}, after "
        f"{load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}.",
        "",
        "t = 0..10 s, rtol = atol = 1e-8, angles 0.5 rad, zero speeds; one fresh process per n, "
        "medians (native 21 runs, scipy 3-5) after a warm-up, and the native minimum. "
        "`floor` = nfev x rhs + njev x jacobian (their times in C, the best of 15 loops). "
        "Targets are judged on the median.",
        "",
        "| n | method | native ms (median / min) | scipy ms | speed-up | nfev | njev | nlu | "
        "same counts | floor ms | native / floor | target |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        key = (r["method"], r["n"])
        targets = []
        if key in TARGETS:
            ok = r["native_ms"] <= TARGETS[key]
            targets.append(f"<= {TARGETS[key]:g} ms: {'met' if ok else 'missed'}")
        if key in FLOOR_TARGETS:
            bound = FLOOR_TARGETS[key]
            ok = r["native_ms"] <= bound * r["floor_ms"]
            targets.append(f"<= {bound:g} x floor = {bound * r['floor_ms']:.2f} ms: "
                           f"{'met' if ok else 'missed'}")
        target = "; ".join(targets)
        lines.append(
            f"| {r['n']} | {r['method']} | {r['native_ms']:.3f} / {r['native_min_ms']:.3f} | "
            f"{r['scipy_ms']:.1f} | "
            f"{r['ratio']:.0f}x | {r['nfev']} | {r['njev']} | {r['nlu']} | "
            f"{'yes' if r['same_counts'] else 'NO'} | {r['floor_ms']:.3f} | "
            f"{r['native_ms'] / r['floor_ms']:.2f} | {target} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[2, 5, 10, 20])
    ap.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker)
        return
    for n in args.n:          # build/cache every model first, so timing processes only load
        model_for(n)
    load_before = os.getloadavg()
    rows = []
    for n in args.n:
        out = subprocess.run([sys.executable, __file__, "--worker", str(n)], check=True,
                             capture_output=True, text=True)
        rows.extend(json.loads(out.stdout.strip().splitlines()[-1]))
        print(f"n = {n} done", file=sys.stderr)
    load_after = os.getloadavg()
    md = markdown(rows, load_before, load_after)
    print(md)
    results = HERE / "results"
    (results / "native.md").write_text(md)
    (results / "native.json").write_text(json.dumps(
        dict(rows=rows, load_before=load_before, load_after=load_after), indent=1))


if __name__ == "__main__":
    main()
