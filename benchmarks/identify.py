"""Identification (issues 21, 30): lagrgen.fit with the exact Jacobian from forward sensitivities
(the model's directional derivatives, forward mode on its kernels) against the finite-difference
loop (scipy.optimize.least_squares with jac="2-point" over lagrgen.simulate), on noisy synthetic
responses of a 2-DOF damped chain and a 5-link pendulum. The sensitivities' unit is compiled
(on first use) before anything is timed.

    python benchmarks/identify.py [--repeats 3]

Prints a table and writes it to benchmarks/results/identify.md (and .json).
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
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples"))
RESULTS = ROOT / "benchmarks" / "results" / "identify"

import lagrgen  # noqa: E402


def problems(out):
    """(label, built model, t, y0, fitted names, measured names, noise) of each case."""
    from nlink_pendulum import make
    from two_mass_chain import absolute
    chain = lagrgen.build(absolute, out_dir=out, quiet=True)
    pendulum = lagrgen.build(make(5, "identify_nlink5"), out_dir=out, quiet=True)
    for mod in (chain, pendulum):    # compile the sensitivities' unit (on first use) untimed
        mod.directional_derivatives(0.0, np.zeros(2 * mod.n_coordinates),
                                    np.zeros(2 * mod.n_coordinates))
    return [
        ("2-DOF damped chain", chain, np.linspace(0, 10, 201), [0.1, -0.05, 0, 0],
         ["k1", "k2", "c1", "c2"], ["x1", "x2"], 1e-3),
        ("5-link pendulum", pendulum, np.linspace(0, 5, 101), [0.4] * 5 + [0.0] * 5,
         ["m0", "m2", "l1", "l3"], [f"q{i}" for i in range(5)], 1e-3),
    ]


def synthetic(mod, t, y0, measured, noise, seed=1):
    truth = lagrgen.simulate(mod, (t[0], t[-1]), y0, method="DOP853", t_eval=t, rtol=1e-11,
                             atol=1e-13)
    rows = [list(mod.coordinates).index(m) for m in measured]
    return truth.y[rows] + noise * np.random.default_rng(seed).standard_normal((len(rows), t.size))


def finite_difference_fit(mod, t, data, names, y0, measured, initial, rtol, atol):
    """least_squares with SciPy's 2-point Jacobian over whole simulations (native engine)."""
    rows = [list(mod.coordinates).index(m) for m in measured]
    index = [list(mod.parameters).index(n) for n in names]
    base = np.asarray(mod.defaults, dtype=float)

    def residuals(theta):
        p = base.copy()
        p[index] = theta
        sol = lagrgen.simulate(mod, (t[0], t[-1]), y0, method="DOP853", params=p, t_eval=t,
                               rtol=rtol, atol=atol)
        return (sol.y[rows] - data).ravel()

    result = least_squares(residuals, initial, jac="2-point", x_scale="jac")
    return result.x, result.nfev, result.njev


TOLERANCES = ((1e-9, 1e-11), (1e-6, 1e-9))


def measure(repeats):
    rows = []
    with tempfile.TemporaryDirectory() as out:
        for (label, mod, t, y0, names, measured, noise), (rtol, atol) in (
                (case, tol) for case in problems(out) for tol in TOLERANCES):
            data = synthetic(mod, t, y0, measured, noise)
            true = np.array([mod.defaults[list(mod.parameters).index(n)] for n in names])
            start = 1.2 * true
            exact_s, fd_s = [], []
            for _ in range(repeats):
                t0 = time.perf_counter()
                fit = lagrgen.fit(mod, t, data, names, y0, measured=measured,
                                  initial=dict(zip(names, start)), method="DOP853", rtol=rtol,
                                  atol=atol)
                exact_s.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                fd_x, fd_nfev, fd_njev = finite_difference_fit(mod, t, data, names, y0, measured,
                                                               start, rtol, atol)
                fd_s.append(time.perf_counter() - t0)
            estimate = np.array([fit.params[n] for n in names])
            stderr = np.array([fit.stderr[n] for n in names])
            rows.append({
                "problem": label, "parameters": names, "rtol": rtol,
                "exact_seconds": statistics.median(exact_s), "exact_nfev": fit.nfev,
                "exact_max_error_over_stderr": float(np.max(np.abs(estimate - true) / stderr)),
                "exact_max_relative_error": float(np.max(np.abs(estimate / true - 1))),
                "fd_seconds": statistics.median(fd_s), "fd_nfev": int(fd_nfev),
                "fd_simulations": int(fd_nfev + len(names) * (fd_njev or 0)),
                "fd_max_relative_error": float(np.max(np.abs(fd_x / true - 1))),
            })
    return rows


def markdown(rows, repeats):
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [f"Identification from noisy responses (noise 1e-3, start at 1.2 × the true values; "
             f"DOP853, native engine; median of {repeats}; load {load:.2f})", "",
             "| problem | fitted | rtol | exact-gradient fit: s, iterations, max |error|/stderr, "
             "max rel. error | finite-difference loop: s, iterations, simulations, max rel. error "
             "| speed-up |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['problem']} | {', '.join(r['parameters'])} | {r['rtol']:g} | "
            f"{r['exact_seconds']:.3f} s, "
            f"{r['exact_nfev']}, {r['exact_max_error_over_stderr']:.2f}, "
            f"{r['exact_max_relative_error']:.1e} | {r['fd_seconds']:.3f} s, {r['fd_nfev']}, "
            f"{r['fd_simulations']}, {r['fd_max_relative_error']:.1e} | "
            f"{r['fd_seconds'] / r['exact_seconds']:.1f}× |")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rows = measure(args.repeats)
    table = markdown(rows, args.repeats)
    print(table)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.with_suffix(".md").write_text(table)
    RESULTS.with_suffix(".json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
