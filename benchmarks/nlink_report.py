"""The n-link benchmark's report: markdown tables (build, per call, solve_ivp), the issue-4
targets with PASS / MISS, notes, the profile, the machine, and the scaling plot.
"""
import datetime
import json
import os
import platform
import subprocess
from pathlib import Path

import numpy as np

import _peers
from nlink_measure import ANGLE, T_SPAN, TOL
from nlink_tools import TOOLS

HERE = Path(__file__).resolve().parent


# ---------------------------------------------------------------------------------------- cells


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


# --------------------------------------------------------------------------------------- tables


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


# -------------------------------------------------------------------------------------- targets


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


# ----------------------------------------------------------------------------------- the report


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


# ----------------------------------------------------------------------------------------- meta


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
            "config": {k: shown_path(v) if k == "model_file" else v for k, v in cfg.items()
                       if not k.startswith("reference")}}


def shown_path(path):
    """A file as the results name it: its path in the repository, else its name alone (results
    hold no machine's absolute path)."""
    path = Path(path).resolve()
    try:
        return path.relative_to(HERE.parent.resolve()).as_posix()
    except ValueError:
        return path.name


def to_json(obj):
    """JSON-safe copy (numpy scalars to floats)."""
    if isinstance(obj, dict):
        return {str(k): to_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_json(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


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
