"""The n-link pendulum benchmark of issue 4: lagrgen (C and Python paths) against PyDy and CasADi.

For each n it measures cold and cached build times, rhs and Jacobian per call (from Python and inside
C) and solve_ivp wall time for RK45, DOP853, Radau, BDF and LSODA; prints markdown tables, checks the
issue-4 targets, and writes benchmarks/results/nlink.{md,json} and nlink_scaling.png.

    python benchmarks/nlink.py                  # n = 2 5 10 20, all tools
    python benchmarks/nlink.py --quick          # smoke run: n = 2 5, fewer repeats, *_quick files
    python benchmarks/nlink.py --n 2 10 --tools lagrgen-C PyDy

Every (tool, n) runs in its own spawned process with a time cap, so a peer that crashes, hangs or is
not installed costs a table cell, not the run. This file is the runner; the tools are in
nlink_tools.py (with _peers.py), what is measured of each in nlink_measure.py, the report in
nlink_report.py. See benchmarks/README.md.
"""
import argparse
import multiprocessing as mp
import os
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import _peers  # noqa: E402
from nlink_measure import (METHODS, benchmark_state, check_against, estimate_solve,  # noqa: E402
                           load_model_module, measure_percall, profile_radau, solve,
                           values_at_states)
from nlink_report import load_results, machine_meta, solve_cell, write_report  # noqa: E402
from nlink_tools import BUILDERS, TOOLS  # noqa: E402

DEFAULT_MODEL_FILE = HERE.parent / "examples" / "nlink_pendulum.py"

FULL = {"percall_repeats": 7, "percall_min_time": 0.1, "solve_runs": 3, "solve_budget": 30.0,
        "cold_runs": 3, "cold_budget": 60.0, "cached_runs": 5, "fresh_process_runs": 3}
QUICK = {"percall_repeats": 3, "percall_min_time": 0.02, "solve_runs": 1, "solve_budget": 5.0,
         "cold_runs": 1, "cold_budget": 0.0, "cached_runs": 3, "fresh_process_runs": 1}


# ----------------------------------------------------------------------------------- the worker


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


# ----------------------------------------------------------------------------------- the parent


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


# ---------------------------------------------------------------------------------- the command


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
