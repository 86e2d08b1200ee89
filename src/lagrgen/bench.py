"""Benchmarks of lagrgen's two paths on one model: build, per-call and solve_ivp timings as a table.

Used by `python -m lagrgen bench MODEL.py` and by the scripts in `benchmarks/`. Every figure is a
median (or best, for per-call times) of repeats measured in the same run.
"""
import statistics
import sys
import tempfile
import time
import timeit

import numpy as np

from .build import build
from .methods import BENCH_METHODS, NATIVE_METHODS
from .simulate import simulate


def per_call_seconds(fn, *args, budget=0.2):
    """Best time of one call of fn(*args) over repeats, each loop taking about `budget` seconds."""
    timer = timeit.Timer(lambda: fn(*args))
    number, elapsed = timer.autorange()
    number = max(1, int(number * budget / max(elapsed, 1e-9)))
    return min(timer.repeat(repeat=5, number=number)) / number


def build_seconds(make_model, out_dir=None, repeats=3):
    """Cold build (forced) split into derive / cse+emit / compile, and cached build.

    `make_model()` returns a fresh, identical Model each time (so nothing is cached in memory).
    """
    colds, steps, cached = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            start = time.perf_counter()
            mod = build(make_model(), out_dir=out_dir or tmp, force=True)
            colds.append(time.perf_counter() - start)
            steps.append(mod.build_info)
        for _ in range(repeats):
            start = time.perf_counter()
            build(make_model(), out_dir=out_dir or tmp)
            cached.append(time.perf_counter() - start)
    return {
        "cold": statistics.median(colds),
        "derive": statistics.median(s["derive"] for s in steps),
        "cse+emit": statistics.median(s["cse+emit"] for s in steps),
        "compile": statistics.median(s["compile"] for s in steps),
        "cached": statistics.median(cached),
    }


#: The guard of every timed solve: a solve that needs more steps or wall time than this stops
#: (and is reported as stopped) instead of running on for minutes and growing without bound.
MAX_STEPS = 200_000
MAX_WALL_TIME = 60.0


def note(text):
    """Progress on a terminal (stderr), so a long benchmark is never silent."""
    if sys.stderr.isatty():
        print(f"[bench] {text}", file=sys.stderr, flush=True)


def solve_seconds(mod, y0, method, t_span=(0.0, 10.0), rtol=1e-8, atol=1e-8, repeats=3,
                  params=None, inputs=None, max_steps=MAX_STEPS, max_wall_time=MAX_WALL_TIME):
    """Median wall time of `lagrgen.simulate` and its counters (nfev, njev, nlu, success);
    `stopped` holds the guard's message when the step or wall-time limit ended the solve."""
    times, sol = [], None
    for _ in range(repeats):
        note(f"{mod.name}: {method} on the {mod.backend} path ...")
        start = time.perf_counter()
        sol = simulate(mod, t_span, y0, method=method, rtol=rtol, atol=atol, params=params,
                       inputs=inputs, max_steps=max_steps, max_wall_time=max_wall_time)
        times.append(time.perf_counter() - start)
        if sol.guard is not None:
            print(f"bench: {mod.name} {method}: {sol.guard} at t = {sol.t[-1]:.4g}",
                  file=sys.stderr, flush=True)
            break
    return {"seconds": statistics.median(times), "nfev": sol.nfev, "njev": sol.njev,
            "nlu": sol.nlu, "success": bool(sol.success), "stopped": sol.guard}


def call_seconds(mod, y0, t=0.0):
    """Per-call rhs and jacobian time from Python; inside C as well for a compiled model."""
    y0 = np.asarray(y0, dtype=float)
    out = {"rhs": per_call_seconds(mod.rhs, t, y0),
           "jacobian": per_call_seconds(mod.jacobian, t, y0)}
    if mod.backend == "c":
        for which in ("rhs", "jacobian"):
            single = mod.time_in_c(which, t, y0, repeat=10)
            repeat = max(10, int(0.1 / max(single, 1e-9)))
            out[f"{which}_in_c"] = min(mod.time_in_c(which, t, y0, repeat=repeat)
                                       for _ in range(5))
    return out


def default_state(mod):
    """y0 = [q0, q̇0] with every coordinate 0.1 and every speed 0; for a constrained model
    q0 = 0.1, 0.2, ... (equal values often make a linkage singular) projected onto the
    constraints by `lagrgen.consistent_state`."""
    n = mod.n_coordinates
    if not mod.n_constraints:
        return np.concatenate([np.full(n, 0.1), np.zeros(n)])
    from .constraints import consistent_state
    return consistent_state(mod, np.concatenate([0.1 * np.arange(1, n + 1), np.zeros(n)]))


def bench_model(make_model, y0=None, methods=BENCH_METHODS, t_span=(0.0, 10.0), rtol=1e-8, atol=1e-8,
                repeats=3, python_solve_limit=60.0, out_dir=None):
    """All figures for one model on both paths, as a dict (see `markdown`)."""
    builds = build_seconds(make_model, out_dir=out_dir, repeats=repeats)
    with tempfile.TemporaryDirectory() as tmp:
        c = build(make_model(), out_dir=out_dir or tmp)
        py = build(make_model(), backend="python")
        y0 = default_state(c) if y0 is None else np.asarray(y0, dtype=float)
        calls = {"c": call_seconds(c, y0, t_span[0]), "python": call_seconds(py, y0, t_span[0])}
        solves = {"c": {}, "python": {}}
        runnable, skipped = runnable_methods(c, methods)
        for method in runnable:
            solves["c"][method] = solve_seconds(c, y0, method, t_span, rtol, atol, repeats)
            estimate = solves["c"][method]["nfev"] * calls["python"]["rhs"] * 1.5
            if solves["c"][method].get("stopped"):
                solves["python"][method] = {"skipped": "the C solve was stopped by the guard"}
            elif estimate > python_solve_limit:
                solves["python"][method] = {"skipped": f"estimated {estimate:.0f} s"}
            else:
                solves["python"][method] = solve_seconds(py, y0, method, t_span, rtol, atol,
                                                         max(1, repeats - 2))
    return {"name": c.name, "n": c.n_coordinates, "build": builds, "calls": calls,
            "solves": solves, "t_span": list(t_span), "rtol": rtol, "atol": atol,
            "skipped": skipped}


def runnable_methods(mod, methods):
    """(the methods that can solve `mod`, {method: why not} for the others): a model with
    impacts or frictions runs its hybrid solve with the native methods only (not LSODA)."""
    from .hybrid import is_hybrid
    if not is_hybrid(mod):
        return list(methods), {}
    runnable = [m for m in methods if m in NATIVE_METHODS]
    return runnable, {m: "a model with impacts or frictions runs with "
                         f"{', '.join(NATIVE_METHODS)}" for m in methods if m not in runnable}


def _us(seconds):
    return f"{seconds * 1e6:.3g} µs"


def _s(seconds):
    return f"{seconds:.3g} s"


def markdown(result):
    """A markdown report of one `bench_model` result: build, per call, solve_ivp."""
    b, c, py = result["build"], result["calls"]["c"], result["calls"]["python"]
    lines = [f"### {result['name']} (n = {result['n']})", "",
             "| build | cold | derive | CSE + emit | compile | cached |", "|---|---|---|---|---|---|",
             f"| C path | {_s(b['cold'])} | {_s(b['derive'])} | {_s(b['cse+emit'])} | "
             f"{_s(b['compile'])} | {_s(b['cached'])} |", "",
             "| per call | C from Python | C inside C | Python path | C speed-up |",
             "|---|---|---|---|---|"]
    for which in ("rhs", "jacobian"):
        lines.append(f"| {which} | {_us(c[which])} | {_us(c[which + '_in_c'])} | "
                     f"{_us(py[which])} | {py[which] / c[which]:.0f}× |")
    t0, t1 = result["t_span"]
    lines += ["", f"| solve_ivp t = {t0:g}..{t1:g}, rtol = {result['rtol']:g}, "
                  f"atol = {result['atol']:g} | C path | nfev / njev / nlu | Python path | "
                  "C speed-up |", "|---|---|---|---|---|"]
    for method, cs in result["solves"]["c"].items():
        ps = result["solves"]["python"][method]
        counts = f"{cs['nfev']} / {cs['njev']} / {cs['nlu']}"
        if cs.get("stopped"):
            counts += f" (stopped: {cs['stopped']})"
        if "skipped" in ps:
            lines.append(f"| {method} | {_s(cs['seconds'])} | {counts} | skipped "
                         f"({ps['skipped']}) | — |")
        else:
            lines.append(f"| {method} | {_s(cs['seconds'])} | {counts} | {_s(ps['seconds'])} | "
                         f"{ps['seconds'] / cs['seconds']:.0f}× |")
    for method, why in result.get("skipped", {}).items():
        lines.append(f"| {method} | skipped ({why}) | — | — | — |")
    return "\n".join(lines) + "\n"
