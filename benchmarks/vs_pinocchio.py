"""lagrgen against Pinocchio, per call from Python: rhs against `pin.aba`, the Jacobian (2n×2n)
against `pin.computeABADerivatives`, the mass matrix against `pin.crba`, on the planar n-link
pendulum (both lagrgen formulations: the dense Cholesky path and the recursion over the kinematic
tree) and on a 33-coordinate humanoid-like 3-D tree; every result is cross-checked first.

    python benchmarks/vs_pinocchio.py                       # n = 2 5 10 20 40 60 80 100, humanoid
    python benchmarks/vs_pinocchio.py --n 2 10 20 --no-humanoid
    python benchmarks/vs_pinocchio.py --help

Prints a markdown table and writes benchmarks/results/pinocchio.md and pinocchio.json. Builds go
to --out (default: a folder in the system's temporary directory), so a second run reuses them;
the dense build of the 100-link chain compiles for minutes. Pinocchio is not a lagrgen
dependency: `pip install pin` (the `peers` extra) first. See benchmarks/README.md.
"""
import argparse
import json
import os
import platform
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import _pinocchio  # noqa: E402

SIZES = (2, 5, 10, 20, 40, 60, 80, 100)
#: Largest relative difference allowed between lagrgen and Pinocchio (q̈; M and the Jacobian are
#: compared too and reported).
AGREE = 1e-12


def best_per_call(f, repeats):
    """Best of `repeats` timeit runs (each long enough to time), seconds per call."""
    timer = timeit.Timer(f)
    number, _ = timer.autorange()
    return min(timer.repeat(repeats, number)) / number


def relative(a, b):
    """max |a − b| / max |b|."""
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(b).max(), 1e-300))


def build_lagrgen(model, out_dir, formulation):
    """(built model, seconds, cache hit) of lagrgen.build in `formulation`."""
    import lagrgen
    start = time.perf_counter()
    mod = lagrgen.build(model, out_dir=out_dir, formulation=formulation, quiet=True)
    return mod, time.perf_counter() - start, bool(mod.build_info.get("cache_hit"))


def chain_row(n, out_dir, repeats, say):
    """Build, cross-check and time one chain size; return its record."""
    import pinocchio as pin
    nlink = _load_example("nlink_pendulum")
    row = {"n": n, "lagrgen": {}}
    pm = _pinocchio.chain(n)
    data = pm.createData()
    rng = np.random.default_rng(100 + n)
    state = _pinocchio.ChainState.of(rng.uniform(-1.0, 1.0, 2 * n))
    reference = _pinocchio.chain_results(pm, data, state)
    tau = np.zeros(n)
    row["pinocchio"] = {
        "rhs": best_per_call(lambda: pin.aba(pm, data, state.q, state.v, tau), repeats),
        "jacobian": best_per_call(
            lambda: pin.computeABADerivatives(pm, data, state.q, state.v, tau), repeats),
        "mass_matrix": best_per_call(lambda: pin.crba(pm, data, state.q), repeats)}
    for formulation in ("dense", "recursive"):
        say(f"  n = {n}: lagrgen {formulation} ...")
        mod, seconds, hit = build_lagrgen(nlink.make(n), out_dir, formulation)
        y, q = state.y, state.y[:n]
        J = mod.jacobian(0.0, y)
        check = {"qdd": relative(mod.rhs(0.0, y)[n:], reference[0]),
                 "jacobian": max(relative(J[n:, :n], reference[1]),
                                 relative(J[n:, n:], reference[2])),
                 "mass_matrix": relative(mod.mass_matrix(q), reference[3])}
        if check["qdd"] > AGREE:
            raise RuntimeError(f"lagrgen ({formulation}) and Pinocchio disagree at n = {n}: {check}")
        row["lagrgen"][formulation] = {
            "build": seconds, "cache_hit": hit, "check": check,
            "rhs": best_per_call(lambda: mod.rhs(0.0, y), repeats),
            "jacobian": best_per_call(lambda: mod.jacobian(0.0, y), repeats),
            "mass_matrix": best_per_call(lambda: mod.mass_matrix(q), repeats)}
    row["auto"] = _auto(n)
    return row


def _auto(n):
    """The formulation lagrgen chooses for the n-link chain (without building it)."""
    from lagrgen.lagrange import derived
    from lagrgen.tree import choose
    return choose(derived(_load_example("nlink_pendulum").make(n).spec()), None)


def humanoid_row(out_dir, repeats, say):
    """Build, cross-check and time the humanoid (lagrgen's automatic formulation)."""
    import pinocchio as pin
    say("  humanoid: lagrgen ...")
    mod, seconds, hit = build_lagrgen(_pinocchio.humanoid_lagrgen(), out_dir, None)
    pm = _pinocchio.humanoid_pinocchio()
    data = pm.createData()
    n = pm.nq
    y = np.random.default_rng(7).uniform(-0.6, 0.6, 2 * n)
    q, v, tau = y[:n], y[n:], np.zeros(n)
    qdd = pin.aba(pm, data, q, v, tau).copy()
    pin.computeABADerivatives(pm, data, q, v, tau)
    dq, dv = data.ddq_dq.copy(), data.ddq_dv.copy()
    M = np.triu(pin.crba(pm, data, q))
    M = M + np.triu(M, 1).T
    J = mod.jacobian(0.0, y)
    check = {"qdd": relative(mod.rhs(0.0, y)[n:], qdd),
             "jacobian": max(relative(J[n:, :n], dq), relative(J[n:, n:], dv)),
             "mass_matrix": relative(mod.mass_matrix(q), M)}
    if check["qdd"] > AGREE:
        raise RuntimeError(f"lagrgen and Pinocchio disagree on the humanoid: {check}")
    return {"n": n, "formulation": mod.formulation, "build": seconds, "cache_hit": hit,
            "check": check,
            "lagrgen": {"rhs": best_per_call(lambda: mod.rhs(0.0, y), repeats),
                        "jacobian": best_per_call(lambda: mod.jacobian(0.0, y), repeats),
                        "mass_matrix": best_per_call(lambda: mod.mass_matrix(q), repeats)},
            "pinocchio": {"rhs": best_per_call(lambda: pin.aba(pm, data, q, v, tau), repeats),
                          "jacobian": best_per_call(
                              lambda: pin.computeABADerivatives(pm, data, q, v, tau), repeats),
                          "mass_matrix": best_per_call(lambda: pin.crba(pm, data, q), repeats)}}


def _load_example(stem):
    import importlib.util
    spec = importlib.util.spec_from_file_location(stem, HERE.parent / "examples" / f"{stem}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- the report --------------------------------------------------------------------------------------
def us(seconds):
    return f"{seconds * 1e6:.3g}"


def ratio(ours, theirs):
    """ours / theirs as "0.25×" (below 1: lagrgen is faster)."""
    return f"{ours / theirs:.2f}×"


def chain_table(rows):
    head = ("| n | lagrgen rhs dense / recursive | `pin.aba` | best ÷ aba | jacobian dense / recursive "
            "| `computeABADerivatives` | best ÷ derivatives | mass matrix dense / recursive | "
            "`pin.crba` | automatic |")
    lines = [head, "|" + " --: |" * 9 + " :-- |"]
    for row in rows:
        d, r, p = row["lagrgen"]["dense"], row["lagrgen"]["recursive"], row["pinocchio"]
        best = {k: min(d[k], r[k]) for k in ("rhs", "jacobian", "mass_matrix")}
        lines.append(
            f"| {row['n']} | {us(d['rhs'])} / {us(r['rhs'])} | {us(p['rhs'])} | "
            f"{ratio(best['rhs'], p['rhs'])} | {us(d['jacobian'])} / {us(r['jacobian'])} | "
            f"{us(p['jacobian'])} | {ratio(best['jacobian'], p['jacobian'])} | "
            f"{us(d['mass_matrix'])} / {us(r['mass_matrix'])} | {us(p['mass_matrix'])} | "
            f"{row['auto']} |")
    return "\n".join(lines)


def check_table(rows):
    lines = ["| n | q̈ dense / recursive | Jacobian dense / recursive | M dense / recursive |",
             "| --: | --: | --: | --: |"]
    for row in rows:
        d, r = row["lagrgen"]["dense"]["check"], row["lagrgen"]["recursive"]["check"]
        lines.append(f"| {row['n']} | {d['qdd']:.1e} / {r['qdd']:.1e} | "
                     f"{d['jacobian']:.1e} / {r['jacobian']:.1e} | "
                     f"{d['mass_matrix']:.1e} / {r['mass_matrix']:.1e} |")
    return "\n".join(lines)


def build_table(rows):
    lines = ["| n | dense | recursive |", "| --: | --: | --: |"]
    for row in rows:
        cells = []
        for formulation in ("dense", "recursive"):
            entry = row["lagrgen"][formulation]
            cells.append("cached" if entry["cache_hit"] else f"{entry['build']:.1f} s")
        lines.append(f"| {row['n']} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)


def humanoid_section(h):
    build = "cached" if h["cache_hit"] else f"{h['build']:.1f} s"
    lines = [f"Humanoid ({h['n']} coordinates, lagrgen formulation: {h['formulation']}, build "
             f"{build}); agreement q̈ {h['check']['qdd']:.1e}, Jacobian "
             f"{h['check']['jacobian']:.1e}, M {h['check']['mass_matrix']:.1e}:", "",
             "| per call (µs) | lagrgen | Pinocchio | lagrgen ÷ Pinocchio |",
             "| :-- | --: | --: | --: |"]
    for key, label in (("rhs", "rhs / `aba`"), ("jacobian", "jacobian / `computeABADerivatives`"),
                       ("mass_matrix", "mass matrix / `crba`")):
        lines.append(f"| {label} | {us(h['lagrgen'][key])} | {us(h['pinocchio'][key])} | "
                     f"{ratio(h['lagrgen'][key], h['pinocchio'][key])} |")
    return "\n".join(lines)


def markdown(result):
    meta = result["meta"]
    parts = [
        "# lagrgen against Pinocchio", "",
        f"{meta['date']}, {meta['machine']}, Python {meta['python']}, pin {meta['pin']}, "
        f"lagrgen {meta['lagrgen']}; load average {meta['load_before']} before, "
        f"{meta['load_after']} after (a shared machine: per-call figures up to ~2× high).", "",
        "Planar n-link pendulum (examples/nlink_pendulum.py; Pinocchio: revolute joints about z, "
        "relative angles, states converted), per call from Python in µs, best of "
        f"{meta['repeats']}; ratios: the faster lagrgen formulation divided by Pinocchio "
        "(below 1: lagrgen is faster). \"automatic\" is the formulation `build` chooses.", "",
        chain_table(result["chain"]), "",
        "Largest relative difference from Pinocchio (q̈, ∂q̈/∂y, M) at a random state:", "",
        check_table(result["chain"]), "",
        "Build (cold unless cached from an earlier run):", "", build_table(result["chain"]), ""]
    if result.get("humanoid"):
        parts += [humanoid_section(result["humanoid"]), ""]
    return "\n".join(parts)


def load_average():
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "?"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=list(SIZES), help="chain sizes")
    parser.add_argument("--no-humanoid", action="store_true", help="skip the 3-D humanoid")
    parser.add_argument("--repeats", type=int, default=7, help="timeit repeats (best of)")
    parser.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "lagrgen-pinocchio"),
                        help="build directory (reused across runs)")
    parser.add_argument("--results", default=str(HERE / "results"), help="where to write")
    args = parser.parse_args(argv)
    version = _pinocchio.available()
    if version is None:
        print("Pinocchio is not installed: pip install pin (or the `peers` extra)")
        return 1

    def say(text):
        print(text, file=sys.stderr, flush=True)

    import lagrgen
    result = {"meta": {"date": time.strftime("%Y-%m-%d %H:%M"), "machine": platform.machine(),
                       "python": platform.python_version(), "pin": version,
                       "lagrgen": lagrgen.__version__, "repeats": args.repeats,
                       "load_before": load_average()}, "chain": []}
    for n in args.n:
        result["chain"].append(chain_row(n, args.out, args.repeats, say))
    if not args.no_humanoid:
        result["humanoid"] = humanoid_row(args.out, args.repeats, say)
    result["meta"]["load_after"] = load_average()
    text = markdown(result)
    print(text)
    results = Path(args.results)
    results.mkdir(parents=True, exist_ok=True)
    (results / "pinocchio.md").write_text(text)
    (results / "pinocchio.json").write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
