"""The n-link pendulum benchmark of issue 4: lagrgen (C and Python paths) against PyDy and CasADi.

For each n it measures cold and cached build times, rhs and Jacobian per call (from Python and inside
C) and solve_ivp wall time for RK45, DOP853, Radau, BDF and LSODA; prints markdown tables, checks the
issue-4 targets, and writes benchmarks/results/nlink.{md,json} and nlink_scaling.png.

    python benchmarks/nlink.py                  # n = 2 5 10 20, all tools
    python benchmarks/nlink.py --quick          # smoke run: n = 2 5, fewer repeats, *_quick files
    python benchmarks/nlink.py --n 2 10 --tools lagrgen-C PyDy

Every (tool, n) runs in its own spawned process with a time cap, so a peer that crashes, hangs or is
not installed costs a table cell, not the run. See benchmarks/README.md.
"""
import argparse
import cProfile
import datetime
import importlib.util
import io
import json
import multiprocessing as mp
import os
import platform
import pstats
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
import traceback
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import _peers  # noqa: E402

TOOLS = ("lagrgen-C", "lagrgen-Python", "PyDy", "CasADi")
METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
STIFF = ("Radau", "BDF", "LSODA")
T_SPAN = (0.0, 10.0)
TOL = 1e-8
ANGLE = 0.5
CHECK_TOL = 1e-8
DEFAULT_MODEL_FILE = HERE.parent / "examples" / "nlink_pendulum.py"

FULL = {"percall_repeats": 7, "percall_min_time": 0.1, "solve_runs": 3, "solve_budget": 30.0,
        "cold_runs": 3, "cold_budget": 60.0, "cached_runs": 5, "fresh_process_runs": 3}
QUICK = {"percall_repeats": 3, "percall_min_time": 0.02, "solve_runs": 1, "solve_budget": 5.0,
         "cold_runs": 1, "cold_budget": 0.0, "cached_runs": 3, "fresh_process_runs": 1}


# ------------------------------------------------------------------------------------------ states

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


# ----------------------------------------------------------------------------------------- timing

def median(values):
    """The median, or None for no values."""
    return statistics.median(values) if values else None


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


# --------------------------------------------------------------------------------- lagrgen builds

def timed(fn, *args, **kwargs):
    """(seconds, result) of one call."""
    start = time.perf_counter()
    result = fn(*args, **kwargs)
    return time.perf_counter() - start, result


def cached_in_fresh_process(model_file, n, out_dir):
    """Seconds of lagrgen.build for an already built model, in a new Python process."""
    code = ("import importlib.util, json, sys, time\n"
            f"spec = importlib.util.spec_from_file_location('nlink_pendulum', {str(model_file)!r})\n"
            "m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)\n"
            "import lagrgen\n"
            f"model = m.make({n})\n"
            "start = time.perf_counter()\n"
            f"mod = lagrgen.build(model, out_dir={str(out_dir)!r})\n"
            "print(json.dumps([time.perf_counter() - start, mod.build_info.get('cache_hit')]))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seconds, hit = json.loads(out.stdout.strip().splitlines()[-1])
    if not hit:
        raise RuntimeError("the build in a fresh process was not a cache hit")
    return seconds


def solver_notes():
    """What lagrgen.simulate runs that plain solve_ivp (the peers) does not."""
    try:
        from lagrgen.solvers import SOLVERS
    except ImportError:
        return []
    return [f"lagrgen.simulate runs {' and '.join(SOLVERS)} as lagrgen.solvers classes (SciPy's, "
            "with LAPACK LU called directly); the peers run SciPy's own classes via solve_ivp"]


def build_lagrgen_c(n, work, cfg, make):
    """lagrgen's C path: cold builds into fresh out_dirs (force=True), then cached builds."""
    import lagrgen

    colds, mod, out_dir = [], None, None
    for k in range(max(1, cfg["cold_runs"])):
        out_dir = Path(work) / f"cold{k}"
        seconds, mod = timed(lagrgen.build, make(n), out_dir=out_dir, force=True)
        colds.append({**mod.build_info, "wall": seconds})
        if sum(c["wall"] for c in colds) > cfg["cold_budget"]:
            break
    cached = []
    for _ in range(cfg["cached_runs"]):
        model = make(n)
        seconds, again = timed(lagrgen.build, model, out_dir=out_dir)
        if not again.build_info.get("cache_hit"):
            raise RuntimeError("second build of an identical model was not a cache hit")
        cached.append(seconds)
    fresh = [cached_in_fresh_process(cfg["model_file"], n, out_dir)
             for _ in range(cfg["fresh_process_runs"])]
    build = {key: median([c[key] for c in colds if key in c]) for key in ("derive", "cse+emit", "compile")}
    build.update(cold=median([c["wall"] for c in colds]), cold_runs=len(colds), cached=median(cached),
                 cached_fresh_process=median(fresh), cold_all=[c["wall"] for c in colds])
    p = np.asarray(mod.defaults, dtype=float)

    def simulate(method, t_span, y0, rtol, atol):
        return lagrgen.simulate(mod, t_span, y0, method=method, rtol=rtol, atol=atol)

    return _peers.Built(
        "lagrgen-C", mod.rhs, mod.jacobian, args=(p,), notes=solver_notes(),
        rhs_in_c=lambda t, y, r: mod.time_in_c("rhs", t, y, p, repeat=r),
        jac_in_c=lambda t, y, r: mod.time_in_c("jacobian", t, y, p, repeat=r),
        simulate=simulate, build=build)


def build_lagrgen_python(n, work, cfg, make):
    """lagrgen's pure-Python (NumPy) path."""
    import lagrgen

    walls, mod = [], None
    for _ in range(max(1, cfg["cold_runs"])):
        seconds, mod = timed(lagrgen.build, make(n), backend="python")
        walls.append(seconds)
        if sum(walls) > cfg["cold_budget"]:
            break
    info = getattr(mod, "build_info", None) or {}
    build = {key: info.get(key) for key in ("derive", "cse+emit", "compile")}
    build.update(cold=median(walls), cold_runs=len(walls))
    p = np.asarray(mod.defaults, dtype=float)

    def simulate(method, t_span, y0, rtol, atol):
        return lagrgen.simulate(mod, t_span, y0, method=method, rtol=rtol, atol=atol)

    return _peers.Built("lagrgen-Python", mod.rhs, mod.jacobian, args=(p,), simulate=simulate,
                        build=build, notes=solver_notes())


def build_peer(tool):
    """A builder for the peer `tool` with the time cap of cfg peer_timeout."""
    def build(n, work, cfg, make):
        deadline = time.perf_counter() + cfg["peer_timeout"]
        return _peers.BUILDERS[tool](n, work, deadline)
    return build


BUILDERS = {"lagrgen-C": build_lagrgen_c, "lagrgen-Python": build_lagrgen_python,
            "PyDy": build_peer("PyDy"), "CasADi": build_peer("CasADi")}


# -------------------------------------------------------------------------------------- the worker

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


def worker(conn, tool, n, cfg):
    """Build and measure one (tool, n) in this process, sending each result to `conn` as it comes."""
    os.setsid()
    log = open(cfg["log"], "w")
    os.dup2(log.fileno(), 1)
    os.dup2(log.fileno(), 2)
    phase = "build"
    try:
        make = load_model_module(cfg["model_file"]).make
        work = tempfile.mkdtemp(prefix=f"nlink-{tool}-{n}-")
        built = BUILDERS[tool](n, work, cfg, make)
        conn.send({"kind": "build", "build": built.build, "notes": built.notes})
        phase = "check"
        values = values_at_states(built, n)
        check = check_against(values, cfg.get("reference_values"))
        conn.send({"kind": "values", "values": values, "check": check})
        if check is not None and not check["ok"]:
            raise RuntimeError(f"disagrees with lagrgen-C: {check}; not timed")
        phase = "per call"
        percall = measure_percall(built, n, cfg)
        conn.send({"kind": "percall", "percall": percall})
        for method in cfg["methods"]:
            phase = f"solve_ivp {method}"
            reference = (cfg.get("reference_solve") or {}).get(method)
            estimate = estimate_solve(reference, percall, n) if tool != "lagrgen-C" else None
            if estimate is not None and estimate > cfg["solve_cap"]:
                result = {"skipped": True, "estimate": estimate}
            else:
                try:
                    result = {**solve(built, method, benchmark_state(n), cfg), "estimate": estimate}
                except Exception as exc:
                    traceback.print_exc()
                    result = {"error": f"{type(exc).__name__}: {exc}"}
            conn.send({"kind": "solve", "method": method, "result": result})
        conn.send({"kind": "done"})
    except _peers.BuildTimeout as exc:
        conn.send({"kind": "error", "phase": phase, "timeout": True, "message": str(exc)})
    except Exception as exc:
        traceback.print_exc()
        conn.send({"kind": "error", "phase": phase, "message": f"{type(exc).__name__}: {exc}"})
    finally:
        conn.close()


# -------------------------------------------------------------------------------------- the parent

def log_tail(path, lines=15):
    """The last lines of a worker's log file."""
    try:
        return "\n".join(Path(path).read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


def kill_group(proc):
    """Kill the worker `proc` and everything it started (it leads its own process group)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def run_tool(tool, n, cfg, say):
    """Run one (tool, n) in a spawned worker under the build and total time caps; return its record."""
    record = {"tool": tool, "n": n, "status": "ok", "solve": {}}
    ctx = mp.get_context("spawn")
    receiver, sender = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=worker, args=(sender, tool, n, cfg))
    start = time.perf_counter()
    proc.start()
    sender.close()
    try:
        receive(record, receiver, proc, start, tool, cfg, say)
    finally:
        proc.join(0 if record["status"] == "timeout" else 10)
        if proc.is_alive():
            kill_group(proc)
            proc.join(5)
    record["seconds"] = time.perf_counter() - start
    return record


def receive(record, receiver, proc, start, tool, cfg, say):
    """Collect a worker's messages into `record` until it is done, fails or runs out of time."""
    build_cap = cfg["peer_timeout"] + 15 if tool in _peers.BUILDERS else cfg["total_cap"]
    built = False
    while True:
        cap = cfg["total_cap"] if built else build_cap
        left = start + cap - time.perf_counter()
        try:
            ready = left > 0 and receiver.poll(left)
            msg = receiver.recv() if ready else None
        except (EOFError, OSError):
            record.update(status="crashed", error=f"worker died (exit code {proc.exitcode}); "
                                                  f"log tail:\n{log_tail(cfg['log'])}")
            break
        if msg is None:
            record.update(status="timeout", error=f"no answer within {cap:.0f} s "
                                                  f"({'measuring' if built else 'building'})")
            if not built:
                record["build"] = {"timeout": True}
            break
        kind = msg["kind"]
        if kind == "build":
            built = True
            record["build"], record["notes"] = msg["build"], msg["notes"]
            say(f"  built in {msg['build'].get('cold', float('nan')):.2f} s")
        elif kind == "values":
            record["values"], record["check"] = msg["values"], msg["check"]
        elif kind == "percall":
            record["percall"] = msg["percall"]
        elif kind == "solve":
            record["solve"][msg["method"]] = msg["result"]
            res = msg["result"]
            say(f"  {msg['method']}: {solve_cell(res)}")
        elif kind == "error":
            status = "timeout" if msg.get("timeout") else "error"
            record.update(status=status, error=f"{msg['phase']}: {msg['message']}")
            if msg.get("timeout") and msg["phase"] == "build":
                record["build"] = {"timeout": True}
            break
        elif kind == "done":
            break


def run_all(args, cfg, say):
    """Every tool for every n, lagrgen-C first (its values and counts are the reference)."""
    runs = {}
    installed = {tool: not _peers.missing(tool) for tool in _peers.BUILDERS}
    log_dir = Path(tempfile.mkdtemp(prefix="nlink-logs-"))
    for n in args.n:
        runs[n] = {}
        reference_values = reference_solve = None
        for tool in args.tools:
            if tool in installed and not installed[tool]:
                runs[n][tool] = {"tool": tool, "n": n, "status": "not installed",
                                 "error": f"missing {', '.join(_peers.missing(tool))}", "solve": {}}
                continue
            say(f"[n={n}] {tool}")
            tool_cfg = {**cfg, "log": str(log_dir / f"{tool}-{n}.log"),
                        "reference_values": reference_values, "reference_solve": reference_solve}
            record = run_tool(tool, n, tool_cfg, say)
            if record["status"] != "ok":
                say(f"  {record['status']}: {record.get('error', '')[:300]}")
            say(f"  ({record['seconds']:.0f} s)")
            runs[n][tool] = record
            if tool == "lagrgen-C" and "values" in record:
                reference_values = record["values"]
                reference_solve = {m: r for m, r in record["solve"].items() if not r.get("skipped")}
    return runs


# ----------------------------------------------------------------------------------------- profile

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


# ----------------------------------------------------------------------------------------- reports

def fmt(x, scale=1.0, digits=3):
    """A number for a table cell, or an em dash."""
    if x is None:
        return "—"
    v = x * scale
    if v == 0:
        return "0"
    if abs(v) >= 10 ** digits:
        return f"{v:.0f}"
    return f"{v:.{digits}g}"


def get(record, *keys):
    """record[k1][k2]... or None anywhere along the way."""
    for key in keys:
        if not isinstance(record, dict) or record.get(key) is None:
            return None
        record = record[key]
    return record


def ratio(base, value):
    """base / value formatted as a speed-up, or an em dash."""
    if base is None or value is None or value == 0:
        return "—"
    r = base / value
    return f"{r:.0f}×" if r >= 100 else f"{r:.3g}×"


def status_cell(record):
    """A short note for a tool that did not produce everything."""
    if record.get("status") in (None, "ok"):
        return ""
    return f"{record['status']}: {record.get('error', '')}".splitlines()[0][:120]


def check_cell(record):
    """The agreement with lagrgen-C's rhs (and Jacobian) at the benchmark and check states."""
    if record.get("tool") == "lagrgen-C":
        return "reference" if record.get("values") else "—"
    check = record.get("check")
    if not check:
        return "unchecked" if record.get("values") else "—"
    worst = max(v for k, v in check.items() if k != "ok")
    return f"{'ok' if check['ok'] else 'FAIL'} {worst:.0e}"


def build_table(runs, tools):
    """Markdown: cold build split and cached builds."""
    rows = ["| n | tool | derive s | CSE+emit s | compile s | cold build s (runs) | cached build s | "
            "cached, new process s | note |",
            "|---|---|---|---|---|---|---|---|---|"]
    for n, by_tool in runs.items():
        for tool in tools:
            r = by_tool.get(tool, {})
            b = r.get("build") or {}
            cold = "timeout" if b.get("timeout") is True else fmt(b.get("cold"))
            if isinstance(b.get("timeout"), list):
                cold = f"timeout ({', '.join(b['timeout'])} C > cap)"
            elif b.get("cold_runs"):
                cold += f" ({b['cold_runs']})"
            rows.append(f"| {n} | {tool} | {fmt(b.get('derive'))} | {fmt(b.get('cse+emit'))} | "
                        f"{fmt(b.get('compile'))} | {cold} | {fmt(b.get('cached'))} | "
                        f"{fmt(b.get('cached_fresh_process'))} | {status_cell(r)} |")
    return "\n".join(rows)


def percall_table(runs, tools):
    """Markdown: rhs and Jacobian per call, from Python and inside C, with speed-ups."""
    rows = ["| n | tool | check | rhs from Python µs, median (best) | × vs lagrgen-Python | "
            "rhs in C µs | jacobian from Python µs, median (best) | × vs lagrgen-Python | "
            "jacobian in C µs |",
            "|---|---|---|---|---|---|---|---|---|"]
    for n, by_tool in runs.items():
        base = by_tool.get("lagrgen-Python", {})
        for tool in tools:
            r = by_tool.get(tool, {})
            pc = r.get("percall") or {}

            def cell(key):
                if key not in pc:
                    return "none (finite differences)" if key == "jac" and r.get("values") \
                        and r["values"].get("jac") is None else "—"
                timed_out = (r.get("build") or {}).get("timeout")
                vm = " SX VM" if isinstance(timed_out, list) and key in timed_out else ""
                return f"{fmt(pc[key]['median'], 1e6)} ({fmt(pc[key]['best'], 1e6)}){vm}"
            rows.append(
                f"| {n} | {tool} | {check_cell(r)} | {cell('rhs')} | "
                f"{ratio(get(base, 'percall', 'rhs', 'median'), get(pc, 'rhs', 'median'))} | "
                f"{fmt(get(pc, 'rhs_in_c', 'median'), 1e6)} | {cell('jac')} | "
                f"{ratio(get(base, 'percall', 'jac', 'median'), get(pc, 'jac', 'median'))} | "
                f"{fmt(get(pc, 'jac_in_c', 'median'), 1e6)} |")
    return "\n".join(rows)


def solve_cell(result):
    """Wall time of one solve_ivp entry, or why there is none."""
    if not result:
        return "—"
    if result.get("skipped"):
        return f"skipped (est. {result['estimate']:.0f} s > cap)"
    if result.get("error"):
        return "error"
    cell = fmt(result["wall"])
    if not result["success"]:
        cell += " (failed)"
    return cell


def solve_overview(runs, tools, methods):
    """Markdown: solve_ivp wall time per (n, method), one column per tool."""
    rows = ["| n | method | " + " | ".join(f"{t} s" for t in tools) + " | lagrgen-C speed-up "
            "vs lagrgen-Python | nfev / njev / nlu (lagrgen-C) |",
            "|---|---|" + "---|" * len(tools) + "---|---|"]
    for n, by_tool in runs.items():
        for method in methods:
            res = {t: get(by_tool.get(t, {}), "solve", method) for t in tools}
            c = res.get("lagrgen-C") or {}
            counts = f"{c['nfev']} / {c['njev']} / {c['nlu']}" if c.get("nfev") is not None else "—"
            rows.append(f"| {n} | {method} | " + " | ".join(solve_cell(res[t]) for t in tools)
                        + f" | {ratio(get(res, 'lagrgen-Python', 'wall'), get(res, 'lagrgen-C', 'wall'))}"
                        + f" | {counts} |")
    return "\n".join(rows)


def solve_detail(runs, tools, methods):
    """Markdown: every solve_ivp run with its counts."""
    rows = ["| n | method | tool | wall s (median of runs) | runs | × vs lagrgen-Python | nfev | njev "
            "| nlu | steps |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for n, by_tool in runs.items():
        for method in methods:
            base = get(by_tool.get("lagrgen-Python", {}), "solve", method, "wall")
            for tool in tools:
                r = get(by_tool.get(tool, {}), "solve", method)
                if not r:
                    continue
                if r.get("skipped") or r.get("error"):
                    rows.append(f"| {n} | {method} | {tool} | {solve_cell(r)} | 0 | — | — | — | — | — |")
                    continue
                rows.append(f"| {n} | {method} | {tool} | {solve_cell(r)} | {r['runs']} | "
                            f"{ratio(base, r['wall'])} | {r['nfev']} | {r['njev']} | {r['nlu']} | "
                            f"{r['n_steps']} |")
    return "\n".join(rows)


def target_list():
    """The issue-4 targets: (label, path into runs, limit, unit scale, unit, 'le' or 'ge')."""
    t = [(f"cold build n={n}", (n, "lagrgen-C", "build", "cold"), lim, 1, "s", "le")
         for n, lim in ((2, 1.5), (10, 4.0), (20, 15.0))]
    t.append(("cached build (worst n)", ("max", "lagrgen-C", "build", "cached"), 0.2, 1, "s", "le"))
    t.append(("rhs per call from Python n=2", (2, "lagrgen-C", "percall", "rhs", "median"),
              0.3e-6, 1e6, "µs", "le"))
    t.append(("rhs from Python n=2 vs lagrgen-Python", ("ratio", 2, "rhs"), 100, 1, "×", "ge"))
    t += [(f"rhs inside C n={n}", (n, "lagrgen-C", "percall", "rhs_in_c", "median"), lim, 1e6,
           "µs", "le") for n, lim in ((10, 1.5e-6), (20, 5e-6))]
    t.append(("jacobian inside C n=10", (10, "lagrgen-C", "percall", "jac_in_c", "median"), 6e-6,
              1e6, "µs", "le"))
    t.append(("solve_ivp RK45 n=10", (10, "lagrgen-C", "solve", "RK45", "wall"), 0.05, 1, "s", "le"))
    t.append(("solve_ivp Radau n=10", (10, "lagrgen-C", "solve", "Radau", "wall"), 0.25, 1, "s", "le"))
    return t


def target_value(runs, path):
    """The measured value a target refers to, or None."""
    if path[0] == "max":
        values = [get(by_tool.get(path[1], {}), *path[2:]) for by_tool in runs.values()]
        values = [v for v in values if v is not None]
        return max(values) if values else None
    if path[0] == "ratio":
        by_tool = runs.get(path[1], {})
        py = get(by_tool.get("lagrgen-Python", {}), "percall", path[2], "median")
        c = get(by_tool.get("lagrgen-C", {}), "percall", path[2], "median")
        return py / c if py and c else None
    return get(runs.get(path[0], {}).get(path[1], {}), *path[2:])


def evaluate_targets(runs):
    """Each target with its measured value and PASS / MISS (or n/a when not measured)."""
    out = []
    for label, path, limit, scale, unit, sense in target_list():
        value = target_value(runs, path)
        verdict = "n/a" if value is None else \
            ("PASS" if (value <= limit if sense == "le" else value >= limit) else "MISS")
        out.append({"target": label, "limit": f"{'≤' if sense == 'le' else '≥'} {fmt(limit, scale)} {unit}",
                    "value": value, "measured": "—" if value is None else f"{fmt(value, scale)} {unit}",
                    "result": verdict})
    return out


def targets_table(targets):
    """Markdown: the issue-4 targets with PASS / MISS."""
    rows = ["| issue-4 target | limit | measured (median) | result |", "|---|---|---|---|"]
    rows += [f"| {t['target']} | {t['limit']} | {t['measured']} | {t['result']} |" for t in targets]
    return "\n".join(rows)


def notes_section(runs):
    """Distinct notes from the tools, and every failure."""
    notes, problems = [], []
    for n, by_tool in runs.items():
        for tool, r in by_tool.items():
            for note in r.get("notes") or []:
                if note not in notes:
                    notes.append(note)
            if r.get("status") not in (None, "ok"):
                problems.append(f"n={n} {tool}: {r['status']}: {r.get('error', '')}")
            for method, res in (r.get("solve") or {}).items():
                if res.get("skipped"):
                    problems.append(f"n={n} {tool} {method}: skipped, estimated "
                                    f"{res['estimate']:.0f} s (from lagrgen-C's counts and this "
                                    f"tool's per-call times) exceeds the cap")
                elif res.get("error"):
                    problems.append(f"n={n} {tool} {method}: {res['error']}")
                elif not res.get("success", True):
                    problems.append(f"n={n} {tool} {method}: solver failed: {res['message']}")
    lines = [f"- {x}" for x in notes]
    lines += [f"- {x.splitlines()[0][:400]}" for x in problems]
    return "\n".join(lines)


def profile_section(profile):
    """Markdown: where Radau's time goes, from the cProfile run."""
    if not profile:
        return ""
    s = profile["summary"]
    shares = "\n".join(f"| {label} | {share:.0%} |" for label, share in s["shares_of_profiled_time"].items())
    return (f"## Where Radau's time goes (lagrgen-C, n={s['n']}, cProfile)\n\n"
            f"{s['steps']} steps, nfev {s['nfev']}, njev {s['njev']}, nlu {s['nlu']}; "
            f"{s['wall_unprofiled']:.3f} s without the profiler (median of 3), "
            f"{s['wall_profiled']:.3f} s under it.\n\n"
            f"| part (cumulative time) | share of profiled time |\n|---|---|\n{shares}\n\n"
            f"Top entries by own time:\n\n```\n{profile['text']}\n```\n")


def meta_section(meta):
    """The paragraph on machine, versions and method."""
    peers = ", ".join(f"{k} {v}" for tool in meta["peers"].values() for k, v in tool.items())
    return (f"Run {meta['date']} on {meta['cpu']} ({meta['cores']} cores), load average "
            f"{meta['load_start']} at start, {meta.get('load_end', '?')} at end. Python "
            f"{meta['python']}, lagrgen {meta['lagrgen']}, NumPy {meta['numpy']}, SciPy "
            f"{meta['scipy']}, SymPy {meta['sympy']}, SymEngine {meta['symengine']}, {peers}; "
            f"{meta['gcc']}. Benchmark: all angles {ANGLE} rad, zero speeds, t = {T_SPAN[0]:g}..{T_SPAN[1]:g} s, "
            f"rtol = atol = {TOL:g}. Per-call times: timeit, median (best) of {meta['config']['percall_repeats']} "
            f"repeats; solve_ivp: median of up to {meta['config']['solve_runs']} runs; the skip cap for a "
            f"solve_ivp run is {meta['config']['solve_cap']:.0f} s, the build cap for a peer "
            f"{meta['config']['peer_timeout']:.0f} s.")


def markdown(results, tools, methods):
    """The whole report."""
    runs = results["runs"]
    parts = ["# n-link pendulum benchmark (issue 4)", meta_section(results["meta"]),
             "## Issue-4 targets (lagrgen C path)", targets_table(results["targets"]),
             "## Build", build_table(runs, tools),
             "## rhs and Jacobian per call", percall_table(runs, tools),
             "## solve_ivp wall time", solve_overview(runs, tools, methods),
             "### Every solve_ivp run", solve_detail(runs, tools, methods),
             "## Notes", notes_section(runs), profile_section(results.get("profile"))]
    return "\n\n".join(p for p in parts if p) + "\n"


def plot_flag(record, keys):
    """A label for a plotted point that is not what its panel says (a timeout, a peer's SX VM)."""
    timed_out = get(record, "build", "timeout")
    if not isinstance(timed_out, list):
        return ""
    if keys[0] == "build":
        return f"cap ({', '.join(timed_out)} C timed out)"
    slot = keys[1].replace("_in_c", "")
    return "SX VM, no C" if slot in timed_out else ""


def plot(results, tools, path):
    """Time vs n on log scales: rhs and Jacobian per call, cold build, Radau wall time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullLocator

    runs = results["runs"]
    panels = (("rhs per call (solid: from Python, dashed: inside C)", ("percall", "rhs", "median"),
               ("percall", "rhs_in_c", "median")),
              ("jacobian per call (solid: from Python, dashed: inside C)", ("percall", "jac", "median"),
               ("percall", "jac_in_c", "median")),
              ("cold build", ("build", "cold"), None),
              ("solve_ivp Radau wall time", ("solve", "Radau", "wall"), None))
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    colors = dict(zip(TOOLS, ("tab:blue", "tab:orange", "tab:green", "tab:red")))
    for ax, (title, solid, dashed) in zip(axes.flat, panels):
        for tool in tools:
            for keys, style, label in ((solid, "-o", tool), (dashed, "--s", f"{tool} in C")):
                if keys is None:
                    continue
                pts = [(n, get(runs[n].get(tool, {}), *keys)) for n in runs]
                pts = [(n, v) for n, v in pts if isinstance(v, (int, float))]
                if pts:
                    ax.plot(*zip(*pts), style, color=colors.get(tool), label=label)
                for n, v in pts:
                    flag = plot_flag(runs[n].get(tool, {}), keys)
                    if flag:
                        ax.annotate(flag, (n, v), textcoords="offset points", xytext=(-7, -3), ha="right",
                                    fontsize=7, color=colors.get(tool))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(list(runs))
        ax.set_xticklabels([str(n) for n in runs])
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xlabel("n (links)")
        ax.set_ylabel("seconds")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle("n-link pendulum: time vs n")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# -------------------------------------------------------------------------------------------- meta

def command_output(cmd):
    """stdout of a short command, empty if it cannot run."""
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=20).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def package_version(name):
    """Installed version of a distribution, or 'not installed'."""
    from importlib import metadata
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "not installed"


def machine_meta(cfg):
    """Versions, machine and configuration for the report."""
    cpu = next((line.split(":", 1)[1].strip() for line in
                Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")),
               platform.processor()) if Path("/proc/cpuinfo").exists() else platform.processor()
    repo = HERE.parent
    rev = command_output(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"])
    dirty = command_output(["git", "-C", str(repo), "status", "--porcelain", "--", "src"])
    return {"date": datetime.datetime.now().isoformat(timespec="seconds"), "cpu": cpu,
            "cores": os.cpu_count(), "load_start": " ".join(f"{x:.2f}" for x in os.getloadavg()),
            "python": platform.python_version(),
            "lagrgen": f"{package_version('lagrgen')} (git {rev}{' + local changes' if dirty else ''})",
            "numpy": package_version("numpy"), "scipy": package_version("scipy"),
            "sympy": package_version("sympy"), "symengine": package_version("symengine"),
            "peers": _peers.versions(), "gcc": command_output(["gcc", "--version"]).split("\n")[0],
            "config": {k: v for k, v in cfg.items() if not k.startswith("reference")}}


def to_json(obj):
    """JSON-safe copy (numpy scalars to floats)."""
    if isinstance(obj, dict):
        return {str(k): to_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_json(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def parse_args(argv=None):
    """The command line, with the --quick defaults filled in."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, nargs="+", help="numbers of links (default 2 5 10 20; "
                        "with --quick 2 5)")
    parser.add_argument("--quick", action="store_true", help="smoke run: fewer repeats, n = 2 5, "
                        "results to nlink_quick.*")
    parser.add_argument("--tools", nargs="+", choices=TOOLS, default=list(TOOLS))
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    parser.add_argument("--peer-timeout", type=float, default=120.0,
                        help="cap in seconds on each peer build (default 120)")
    parser.add_argument("--solve-cap", type=float, default=60.0, help="skip a solve_ivp run whose "
                        "estimated wall time exceeds this many seconds (default 60)")
    parser.add_argument("--total-cap", type=float, default=1800.0,
                        help="cap in seconds on one (tool, n) altogether (default 1800)")
    parser.add_argument("--profile-n", type=int, default=None, help="profile Radau on lagrgen-C "
                        "at this n (default 10 if measured, else the largest n; 0: no profile)")
    parser.add_argument("--model-file", type=Path, default=DEFAULT_MODEL_FILE,
                        help=f"the benchmark model (default {DEFAULT_MODEL_FILE})")
    parser.add_argument("--out", type=Path, default=HERE / "results", help="results directory")
    parser.add_argument("--name", help="results file stem (default nlink, nlink_quick with --quick)")
    parser.add_argument("--from-json", type=Path, metavar="JSON", help="measure nothing: rewrite the "
                        "report and plot from a results file of an earlier run")
    args = parser.parse_args(argv)
    args.n = args.n or ([2, 5] if args.quick else [2, 5, 10, 20])
    args.name = args.name or ("nlink_quick" if args.quick else "nlink")
    if args.profile_n is None:
        args.profile_n = 10 if 10 in args.n else max(args.n)
    return args


def load_results(path):
    """An earlier run's results file, with the n keys back to ints."""
    results = json.loads(Path(path).read_text())
    results["runs"] = {int(n): by_tool for n, by_tool in results["runs"].items()}
    return results


def write_report(results, args, say):
    """Print the markdown report and write it, the JSON and the plot under args.out."""
    results["targets"] = evaluate_targets(results["runs"])
    tools = [t for t in args.tools if any(t in by_tool for by_tool in results["runs"].values())]
    report = markdown(results, tools, args.methods)
    print(report)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.md").write_text(report)
    (args.out / f"{args.name}.json").write_text(json.dumps(to_json(results), indent=1) + "\n")
    try:
        plot(results, tools, args.out / f"{args.name}_scaling.png")
    except Exception as exc:
        say(f"plot failed: {type(exc).__name__}: {exc}")
    say(f"wrote {args.out / args.name}.md, .json, _scaling.png")


def main(argv=None):
    """Measure (or reload with --from-json), then print and write the report."""
    args = parse_args(argv)

    def say(text):
        print(text, file=sys.stderr, flush=True)

    if args.from_json:
        write_report(load_results(args.from_json), args, say)
        return
    if not args.model_file.exists():
        sys.exit(f"benchmark model not found: {args.model_file} (give --model-file)")

    cfg = {**(QUICK if args.quick else FULL), "peer_timeout": args.peer_timeout,
           "solve_cap": args.solve_cap, "total_cap": args.total_cap, "methods": args.methods,
           "model_file": str(args.model_file.resolve())}
    meta = machine_meta(cfg)
    started = time.perf_counter()
    runs = run_all(args, cfg, say)
    results = {"meta": meta, "runs": runs}
    if args.profile_n and "lagrgen-C" in args.tools:
        say(f"profiling Radau at n={args.profile_n}")
        try:
            summary, text = profile_radau(args.model_file, args.profile_n)
            results["profile"] = {"summary": summary, "text": text}
        except Exception as exc:
            results["profile_error"] = f"{type(exc).__name__}: {exc}"
            say(f"  profile failed: {results['profile_error']}")
    meta["load_end"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    meta["seconds"] = time.perf_counter() - started
    say(f"measured in {meta['seconds']:.0f} s")
    write_report(results, args, say)


if __name__ == "__main__":
    main()
