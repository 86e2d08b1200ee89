"""What the n-link benchmark measures of one built tool: its states, per-call and solve_ivp
timings, its agreement with lagrgen-C, and a profile of Radau on lagrgen's C path.

A built tool is a `_peers.Built` (rhs, jac, args, optional in-C timers and simulate); every
timing is a median (and best) over repeats measured in the same process.
"""
import cProfile
import importlib.util
import io
import pstats
import statistics
import tempfile
import time
import timeit

import numpy as np

from lagrgen.methods import BENCH_METHODS, STIFF_METHODS

METHODS = BENCH_METHODS
STIFF = STIFF_METHODS
T_SPAN = (0.0, 10.0)
TOL = 1e-8
ANGLE = 0.5
CHECK_TOL = 1e-8


# --------------------------------------------------------------------------------------- states


def benchmark_state(n):
    """All angles 0.5 rad, zero speeds."""
    return np.r_[np.full(n, ANGLE), np.zeros(n)]


def check_state(n):
    """A fixed state with non-zero speeds, so the velocity terms are checked too."""
    return np.random.default_rng(12345 + n).uniform(-1.0, 1.0, 2 * n)


def load_model_module(path):
    """Import the shared benchmark model file (which defines `make(n)`)."""
    spec = importlib.util.spec_from_file_location("nlink_pendulum", str(path))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# --------------------------------------------------------------------------------------- timing


def median(values):
    """The median, or None for no values."""
    return statistics.median(values) if values else None


def timed(fn, *args, **kwargs):
    """(seconds, result) of one call."""
    start = time.perf_counter()
    result = fn(*args, **kwargs)
    return time.perf_counter() - start, result


def per_call(fn, t, y, args, repeats, min_time):
    """Seconds per call of fn(t, y, *args) from Python: timeit, best and median of `repeats`."""
    names = {f"a{i}": a for i, a in enumerate(args)}
    stmt = "f(t, y" + "".join(f", {k}" for k in names) + ")"
    timer = timeit.Timer(stmt, globals={"f": fn, "t": t, "y": y, **names})
    number = 1
    while (elapsed := timer.timeit(number)) < min_time / 10 and number < 10 ** 7:
        number *= 10
    number = max(1, round(number * min_time / max(elapsed, 1e-9)))
    times = [s / number for s in timer.repeat(repeats, number)]
    return {"best": min(times), "median": median(times), "number": number, "repeats": repeats}


def in_c(timer, t, y, repeats, min_time):
    """Seconds per call looped inside C by `timer(t, y, repeat)`: best and median of `repeats`."""
    first = timer(t, y, 100)
    repeat = max(100, int(min_time / max(first, 1e-10)))
    times = [timer(t, y, repeat) for _ in range(repeats)]
    return {"best": min(times), "median": median(times), "number": repeat, "repeats": repeats}


def estimate_solve(reference, percall, n):
    """Rough solve_ivp seconds for a tool from lagrgen-C's counts and wall and the tool's call costs."""
    if not reference or reference.get("wall") is None or not percall.get("rhs"):
        return None
    rhs = percall["rhs"]["median"]
    jac = percall["jac"]["median"] if percall.get("jac") else 2 * n * rhs
    return reference["wall"] + reference["nfev"] * rhs + reference.get("njev", 0) * jac


def solve(built, method, y0, cfg):
    """Run solve_ivp (median of up to cfg solve_runs, within cfg solve_budget seconds)."""
    from scipy.integrate import solve_ivp

    walls, sol = [], None
    for _ in range(cfg["solve_runs"]):
        start = time.perf_counter()
        if built.simulate is not None:
            sol = built.simulate(method, T_SPAN, y0, TOL, TOL)
        else:
            jac = built.jac if method in STIFF else None
            sol = solve_ivp(built.rhs, T_SPAN, y0, method=method, rtol=TOL, atol=TOL,
                            jac=jac, args=built.args or None)
        walls.append(time.perf_counter() - start)
        if not sol.success or sum(walls) > cfg["solve_budget"]:
            break
    return {"wall": median(walls), "best": min(walls), "runs": len(walls), "nfev": int(sol.nfev),
            "njev": int(sol.njev), "nlu": int(sol.nlu), "success": bool(sol.success),
            "message": str(sol.message), "n_steps": len(sol.t) - 1, "y_end": sol.y[:, -1].tolist()}


def measure_percall(built, n, cfg):
    """rhs and Jacobian per call from Python and inside C, at the benchmark state."""
    y = benchmark_state(n)
    reps, min_time = cfg["percall_repeats"], cfg["percall_min_time"]
    out = {"rhs": per_call(built.rhs, 0.0, y, built.args, reps, min_time)}
    if built.jac is not None:
        out["jac"] = per_call(built.jac, 0.0, y, built.args, reps, min_time)
    if built.rhs_in_c is not None:
        out["rhs_in_c"] = in_c(built.rhs_in_c, 0.0, y, reps, min_time)
    if built.jac_in_c is not None:
        out["jac_in_c"] = in_c(built.jac_in_c, 0.0, y, reps, min_time)
    return out


# ------------------------------------------------------------------------------------ agreement


def relative_error(a, b):
    """max |a - b| scaled by max(1, max |b|)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def values_at_states(built, n):
    """rhs and Jacobian (None if the tool has none) at the benchmark state and the check state."""
    states = (benchmark_state(n), check_state(n))
    return {"rhs": [np.asarray(built.rhs(0.0, y, *built.args), dtype=float).tolist() for y in states],
            "jac": None if built.jac is None else
            [np.asarray(built.jac(0.0, y, *built.args), dtype=float).tolist() for y in states]}


def check_against(values, reference):
    """Largest relative error of rhs and Jacobian against lagrgen-C's values (None: no reference)."""
    if reference is None:
        return None
    out = {"rhs": max(relative_error(a, b) for a, b in zip(values["rhs"], reference["rhs"]))}
    if values["jac"] is not None and reference.get("jac") is not None:
        out["jac"] = max(relative_error(a, b) for a, b in zip(values["jac"], reference["jac"]))
    out["ok"] = all(v <= CHECK_TOL for v in out.values())
    return out


# -------------------------------------------------------------------------------------- profile

PROFILE_PARTS = (("rhs (solve_ivp's callback, incl. the C call)",
                  (("runner.py", "fun"), ("~", "<method 'rhs' of 'lagrgen._runtime.CompiledModel' objects>"))),
                 ("jacobian (callback, incl. the C call)",
                  (("runner.py", "jac"),
                   ("~", "<method 'jacobian' of 'lagrgen._runtime.CompiledModel' objects>"))),
                 ("LU solve, lagrgen.solvers (LAPACK getrs directly)", (("solvers.py", "_direct_solve"),)),
                 ("LU factor, lagrgen.solvers (LAPACK getrf directly)", (("solvers.py", "_direct_lu"),)),
                 ("LU solve, scipy.linalg.lu_solve (incl. its wrappers)", (("_decomp_lu.py", "lu_solve"),)),
                 ("LU factor, scipy.linalg.lu_factor (incl. its wrappers)",
                  (("_decomp_lu.py", "lu_factor"),)),
                 ("Radau's solve_collocation_system (Newton loop, incl. the calls above)",
                  (("radau.py", "solve_collocation_system"),)),
                 ("Radau's _step_impl (a whole step, incl. everything above)", (("radau.py", "_step_impl"),)))
"""(label, candidate (file, function) keys): a part's time is the largest cumulative time among its
candidates, which are alternative places the same work shows up in a profile."""


def profile_radau(model_file, n, top=20):
    """cProfile of lagrgen.simulate(Radau) on lagrgen's C path at n: (summary dict, top-entries text)."""
    import lagrgen

    make = load_model_module(model_file).make
    mod = lagrgen.build(make(n), out_dir=tempfile.mkdtemp(prefix="nlink-profile-"))
    y0 = benchmark_state(n)
    walls = [timed(lagrgen.simulate, mod, T_SPAN, y0, method="Radau", rtol=TOL, atol=TOL)[0]
             for _ in range(3)]
    profiler = cProfile.Profile()
    profiler.enable()
    sol = lagrgen.simulate(mod, T_SPAN, y0, method="Radau", rtol=TOL, atol=TOL)
    profiler.disable()
    stats = pstats.Stats(profiler).strip_dirs()
    cumulative = {}
    for (file, _, func), (_, _, _, cum, _) in stats.stats.items():
        cumulative[(file, func)] = cumulative.get((file, func), 0.0) + cum
    total = cumulative.get(("runner.py", "simulate"), 0.0)
    parts = {label: max(cumulative.get(key, 0.0) for key in keys) / total
             for label, keys in PROFILE_PARTS if total}
    parts = {label: share for label, share in parts.items() if share > 0}
    stream = io.StringIO()
    stats.stream = stream
    stats.sort_stats("tottime").print_stats(top)
    text = "\n".join(line for line in stream.getvalue().splitlines()
                     if line.strip() and not line.lstrip().startswith(("Ordered by", "List reduced")))
    summary = {"n": n, "wall_unprofiled": median(walls), "wall_profiled": total,
               "nfev": int(sol.nfev), "njev": int(sol.njev), "nlu": int(sol.nlu),
               "steps": len(sol.t) - 1, "shares_of_profiled_time": parts}
    return summary, text
