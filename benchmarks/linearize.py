"""Linearizing a KanesMethod model at one operating point (issue 27): SymPy's own
`KanesMethod.linearize` (its Linearizer, then the numbers substituted) against
`lagrgen.linearize` on the compiled model, on the rolling disk (examples/rolling_disk.py) and the
Whipple bicycle (examples/bicycle.py, the largest Kane model here), and the eigenvalues of both.

    python benchmarks/linearize.py [--repeats 200] [--sympy-repeats 1]

Prints a table and writes it to benchmarks/results/linearize.md (and .json). One-time costs
(forming Kane's equations in SymPy, `from_sympy`, the cold build) are reported beside the
per-point figures; SymPy's figure is per point as well (its Linearizer starts again for every
operating point given in numbers).
"""
import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples"))
RESULTS = ROOT / "benchmarks" / "results" / "linearize"

import lagrgen  # noqa: E402


def rolling_disk():
    """(label, KanesMethod, parameter values, lagrgen point, SymPy point) of the rolling disk
    rolling upright at 1.5 m/s."""
    import rolling_disk
    km = rolling_disk.rolling_disk_kane()
    r, m, g = sp.symbols("r m g", positive=True)
    values = {r: 0.3, m: 2.0, g: 9.81}
    spin = 1.5 / 0.3
    w_lean, u_spin, w_up = km.u
    op = {**dict.fromkeys(km.q, 0), w_lean: 0, u_spin: spin, w_up: 0}
    return ("rolling disk (2 q, 3 u)", km, values, ([0, 0, 0], [0, 0, spin]), op,
            rolling_disk.model)


def bicycle():
    """The same for the Whipple bicycle rolling upright at 5 m/s."""
    import bicycle as example
    km, symbols = example.whipple_bicycle()
    values = dict(zip(symbols, example.benchmark_parameters().values()))
    q0, qd0, _ = example.upright(5.0)
    speeds = {u.func.__name__: u for u in km.u}
    op = {**dict.fromkeys(km.q, 0), **dict.fromkeys(km.u, 0),
          speeds["rear_spin"]: 5.0 / 0.3, speeds["front_spin"]: 5.0 / 0.35}
    return ("Whipple bicycle (4 q, 6 u, 1 + 3 constraints)", km, values, (q0, qd0), op,
            example.model)


def sympy_point(km, op, values):
    """Seconds and eigenvalues of SymPy's linearization at one numeric operating point (as
    SymPy's own bicycle test does it: Cramer's rule, LU gives 0/0 at the upright bicycle)."""
    start = time.perf_counter()
    op = {**op, **{u.diff(): 0 for u in km.u}}
    A, _, _ = km.linearize(op_point=op, A_and_B=True, linear_solver="CRAMER")
    A = np.array(me.msubs(A, values).evalf(), dtype=float)
    return time.perf_counter() - start, np.linalg.eigvals(A)


def lagrgen_point(mod, point, repeats):
    """Median seconds of lagrgen.linearize at the point, and the eigenvalues."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        lin = lagrgen.linearize(mod, *point)
        times.append(time.perf_counter() - start)
    return statistics.median(times), lin.eigenvalues


def spectrum_gap(ours, theirs):
    """max over SymPy's eigenvalues of the distance to the nearest of ours (ours also hold the
    zeros of the ignorable coordinates SymPy's state has not)."""
    return max(np.abs(ours - s).min() for s in theirs)


def measure(case, out, repeats, sympy_repeats):
    label, km, values, point, op, model = case
    start = time.perf_counter()
    rebuilt = lagrgen.from_sympy(km, model.name + "_bench",
                                 defaults={s.name: v for s, v in values.items()})
    from_sympy_s = time.perf_counter() - start
    start = time.perf_counter()
    mod = lagrgen.build(rebuilt, out_dir=out, quiet=True)
    build_s = time.perf_counter() - start
    ours_s, ours = lagrgen_point(mod, point, repeats)
    sympy_runs = [sympy_point(km, op, values) for _ in range(sympy_repeats)]
    sympy_s = statistics.median(t for t, _ in sympy_runs)
    return {"model": label, "states": len(lagrgen.linearize(mod, *point).states),
            "sympy_s": sympy_s, "lagrgen_s": ours_s, "speedup": sympy_s / ours_s,
            "from_sympy_s": from_sympy_s, "build_s": build_s,
            "eigenvalue_gap": spectrum_gap(ours, sympy_runs[0][1])}


def table(rows, load):
    lines = [f"Linearizing at one operating point (load {load})", "",
             "| model | states | SymPy `KanesMethod.linearize` + numbers | `lagrgen.linearize` | "
             "speed-up | one-time: `from_sympy` / cold build | max eigenvalue difference |",
             "|---|--:|--:|--:|--:|--:|--:|"]
    for r in rows:
        lines.append(f"| {r['model']} | {r['states']} | {r['sympy_s']:.2f} s | "
                     f"{r['lagrgen_s'] * 1e3:.3f} ms | {r['speedup']:,.0f}× | "
                     f"{r['from_sympy_s']:.2f} s / {r['build_s']:.1f} s | "
                     f"{r['eigenvalue_gap']:.1e} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--sympy-repeats", type=int, default=1)
    args = parser.parse_args()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    with tempfile.TemporaryDirectory() as out:
        rows = [measure(case(), out, args.repeats, args.sympy_repeats)
                for case in (rolling_disk, bicycle)]
    text = table(rows, load)
    print(text)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.with_suffix(".md").write_text(text + "\n")
    RESULTS.with_suffix(".json").write_text(json.dumps({"load": load, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
