"""How lagrgen's generated code and build grow with the model (issues 11, 23, 30).

Two model families, each size in a fresh process (nothing cached in memory, a fresh out_dir):
    nlink    the planar n-link pendulum of examples/nlink_pendulum.py (a chain), n = 2 … 100
    lattice  a planar mass–spring lattice (rows × cols point masses, each with x and y, nonlinear
             springs to the right and lower neighbours and to a wall, gravity): n = 2·rows·cols
Each is built in the formulation lagrgen chooses (`--formulation` forces one: the chain is
recursive from lagrgen.tree.RECURSIVE_FROM coordinates). For each: the cold build's wall time split
into its stages (derive, CSE, emit with the size of the C it compiles, gcc wall and CPU: what
`module.build_info` records), the first use of the analysis unit (the parameter Jacobian,
compiled on first use), operation counts of the kernels that give M,F and the Jacobian in that
formulation, rhs and jacobian per call looped inside C (the process's CPU time per call,
best of 15 loops, so that other processes on a shared machine do not inflate it), growth exponents
fitted over n = 10 … the largest n, and PyDy's cold build (KanesMethod + Cython, no Jacobian) for
the chain when pydy and Cython are installed (CasADi and JiTCODE: see nlink.py).

    python benchmarks/scale.py                    # everything, writes benchmarks/results/scale.{md,json}
    python benchmarks/scale.py --n 2 10 --no-pydy # a quick look
    python benchmarks/scale.py --formulation dense --n 10 20 --families nlink
"""
import argparse
import json
import math
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OP = re.compile(r"(?<![eE])[-+*/](?![=>])")
CALL = re.compile(r"\b(sin|cos|tan|exp|log|sqrt|pow|fabs|lg_sq|lg_cube|lg_sign|atan2)\(")
LATTICE = {2: (1, 1), 10: (1, 5), 20: (2, 5), 30: (3, 5), 40: (4, 5), 60: (6, 5), 80: (8, 5),
           100: (10, 5)}


def nlink(n):
    sys.path.insert(0, str(ROOT / "examples"))
    from nlink_pendulum import make
    return make(n, name=f"nlink{n}")


def lattice(n):
    """rows × cols masses on springs (n = 2·rows·cols coordinates)."""
    import sympy as sp
    from lagrgen import Model
    rows, cols = LATTICE[n]
    model = Model(f"lattice{n}")
    k, L, g = model.parameters(k=50.0, L=1.0, g=9.81)
    masses = model.parameters(**{f"m{i}": 1.0 + 0.1 * i for i in range(rows * cols)})
    pos = {}
    for r in range(rows):
        for c in range(cols):
            x, y = model.coordinates([f"x{r}_{c}", f"y{r}_{c}"])
            pos[r, c] = sp.Matrix([c * L + x, -r * L + y])
            model.particle(masses[r * cols + c], pos[r, c])
            model.potential_energy(masses[r * cols + c] * g * pos[r, c][1])

    def spring(a, b):
        d = a - b
        model.potential_energy(k * (sp.sqrt(d[0] ** 2 + d[1] ** 2) - L) ** 2 / 2)

    for (r, c), p in pos.items():
        if (r, c + 1) in pos:
            spring(p, pos[r, c + 1])
        if (r + 1, c) in pos:
            spring(p, pos[r + 1, c])
        if c == 0:
            spring(p, sp.Matrix([-L, -r * L]))
        if r == 0:
            spring(p, sp.Matrix([c * L, L]))
    return model


FAMILIES = {"nlink": nlink, "lattice": lattice}


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def op_count(text):
    return len(OP.findall(text)) + len(CALL.findall(text))


def cpu_per_call(mod, function, y, p, loops=15, min_time=0.02):
    """CPU seconds per call of the compiled `function` looped inside C: best of `loops` loops."""
    repeat = max(10, int(min_time / max(mod.time_in_c(function, 0.0, y, p, repeat=10), 1e-9)))
    best = math.inf
    for _ in range(loops):
        c0 = time.process_time()
        mod.time_in_c(function, 0.0, y, p, repeat=repeat)
        best = min(best, (time.process_time() - c0) / repeat)
    return best


def one(family, n, formulation=None):
    """Measure one (family, n) in this process (nothing derived or cached before): the cold
    build, split into its stages (`module.build_info`: derive, CSE, emit, compile = gcc wall; the
    compiler processes' CPU), its C, then the first use of the analysis unit (the parameter
    Jacobian, compiled on first use), then per-call times and operation counts."""
    import numpy as np
    import lagrgen
    from lagrgen.codegen.printer import CPrinter, kernel_statements, print_statements
    from lagrgen.kernels import model_kernels

    model = FAMILIES[family](n)
    with tempfile.TemporaryDirectory() as out:
        ch0, w0 = children_cpu(), time.perf_counter()
        mod = lagrgen.build(model, out_dir=out, force=True, quiet=True,
                            formulation=formulation)
        wall_build = time.perf_counter() - w0
        compile_cpu = children_cpu() - ch0
        info = mod.build_info
        c_kib = sum(p.stat().st_size for p in Path(out).glob(f"__lagrgen__/*/{model.name}*.c"))
        y = np.r_[np.full(n, 0.5) if family == "nlink" else np.full(n, 0.05), np.zeros(n)]
        p = np.asarray(mod.defaults, dtype=float)
        w1 = time.perf_counter()
        mod.parameter_jacobian(0.0, y, p)
        analysis_wall = time.perf_counter() - w1
        percall = {f: cpu_per_call(mod, f, y, p) for f in ("forcing", "rhs", "linear_terms",
                                                             "jacobian")}
    eq = model.equations()
    ops = {k.name: op_count(print_statements(CPrinter(), kernel_statements(k)))
           for k in model_kernels(eq, mod.formulation, ("mf", "jacobian_b"))}
    mf = {k.name for k in model_kernels(eq, mod.formulation, ("mf",))}
    ops = {"mf": sum(v for k, v in ops.items() if k in mf),
           "jacobian_b": sum(v for k, v in ops.items() if k not in mf)}
    return {"family": family, "n": n, "formulation": mod.formulation, "ops": ops,
            "c_kib": c_kib / 1024,
            "derive": info["derive"], "cse": info["cse"], "emit": info["emit"],
            "compile_cpu": compile_cpu, "compile_wall": info["compile"],
            "build_wall": wall_build, "analysis_wall": analysis_wall,
            "rhs_us": percall["rhs"] * 1e6, "jacobian_us": percall["jacobian"] * 1e6,
            "mf_us": percall["forcing"] * 1e6, "kernels_us": percall["linear_terms"] * 1e6,
            "load": os.getloadavg()[0]}


def pydy_one(n):
    """PyDy's cold build of the n-link pendulum (KanesMethod + Cython), CPU seconds."""
    sys.path.insert(0, str(HERE))
    import _peers
    with tempfile.TemporaryDirectory() as work:
        c0, ch0, w0 = time.process_time(), children_cpu(), time.perf_counter()
        _peers.build_pydy(n, work, time.monotonic() + 900)
        return {"family": "nlink-pydy", "n": n,
                "build_cpu": time.process_time() - c0 + children_cpu() - ch0,
                "build_wall": time.perf_counter() - w0, "load": os.getloadavg()[0]}


def _installed(module):
    import importlib.util
    return importlib.util.find_spec(module) is not None


def in_fresh_process(args, formulation=None):
    extra = ["--formulation", formulation] if formulation else []
    out = subprocess.run([sys.executable, __file__, "--one", *map(str, args), *extra],
                         capture_output=True, text=True, timeout=1800)
    if out.returncode != 0:
        return {"error": out.stderr.strip().splitlines()[-1:]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def exponent(rows, key, lo=10, hi=math.inf):
    """Least-squares slope of log(key) against log(n) over lo ≤ n ≤ hi."""
    pts = [(math.log(r["n"]), math.log(r[key])) for r in rows
           if lo <= r["n"] <= hi and r.get(key)]
    if len(pts) < 2:
        return None
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)


def table(rows, pydy):
    lines = ["| model | n | formulation | ops M,F | ops Jacobian | derive s | CSE s | emit s | C KiB | "
             "gcc wall s | gcc CPU s | cold build wall s | analysis unit on first use, wall s | "
             "rhs in C µs | jacobian in C µs | PyDy cold build wall s | load |",
             "|" + "---|" * 17]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r.get('family')} | {r.get('n')} | error: {r['error']} |")
            continue
        py = pydy.get((r["family"], r["n"]))
        lines.append(
            f"| {r['family']} | {r['n']} | {r.get('formulation', 'dense')} | "
            f"{r['ops'].get('mf', 0)} | "
            f"{r['ops'].get('jacobian_b', 0)} | {r['derive']:.2f} | {r['cse']:.2f} | "
            f"{r['emit']:.2f} | {r['c_kib']:.0f} | {r['compile_wall']:.2f} | "
            f"{r['compile_cpu']:.2f} | **{r['build_wall']:.2f}** | {r['analysis_wall']:.2f} | "
            f"{r['rhs_us']:.2f} | {r['jacobian_us']:.2f} | "
            f"{py['build_wall']:.2f} | " if py else
            f"| {r['family']} | {r['n']} | {r.get('formulation', 'dense')} | "
            f"{r['ops'].get('mf', 0)} | "
            f"{r['ops'].get('jacobian_b', 0)} | {r['derive']:.2f} | {r['cse']:.2f} | "
            f"{r['emit']:.2f} | {r['c_kib']:.0f} | {r['compile_wall']:.2f} | "
            f"{r['compile_cpu']:.2f} | **{r['build_wall']:.2f}** | {r['analysis_wall']:.2f} | "
            f"{r['rhs_us']:.2f} | {r['jacobian_us']:.2f} | — | ")
        lines[-1] += f"{r['load']:.1f} |"
    top = max((r["n"] for r in rows if "error" not in r), default=40)
    lines += ["", f"Growth exponents fitted over n = 10 … {top} (log–log least squares):", "",
              "| model | ops M,F | ops Jacobian | C size | derive | CSE | emit | gcc wall | "
              "cold build wall | analysis unit | rhs | jacobian |", "|" + "---|" * 12]
    for family in FAMILIES:
        fam = [dict(r, ops_mf=r["ops"].get("mf"), ops_jac=r["ops"].get("jacobian_b"))
               for r in rows if r.get("family") == family and "error" not in r]
        cells = [exponent(fam, k) for k in ("ops_mf", "ops_jac", "c_kib", "derive", "cse",
                                             "emit", "compile_wall", "build_wall",
                                             "analysis_wall", "rhs_us", "jacobian_us")]
        lines.append(f"| {family} | " + " | ".join("—" if c is None else f"{c:.2f}" for c in cells)
                     + " |")
    return "\n".join(lines)


def targets(rows, pydy):
    """The issue-11 and issue-23 targets against this run (nlink rows)."""
    by_n = {r["n"]: r for r in rows if r.get("family") == "nlink" and "error" not in r}
    fam = [r for r in by_n.values()]

    def cell(n, key):
        return by_n[n][key] if n in by_n else None
    ratio = (pydy[("nlink", 20)]["build_wall"] / by_n[20]["build_wall"]
             if ("nlink", 20) in pydy and 20 in by_n else None)
    checks = [
        ("issue 30: cold build n=20 (wall s)", cell(20, "build_wall"), 1.5),
        ("issue 30: cold build n=80 (wall s, 2 cores)", cell(80, "build_wall"), 20.0),
        ("issue 30: cold build n=100 (wall s)", cell(100, "build_wall"), 30.0),
        (f"issue 30: growth exponent of the cold build wall, n=10…{max(by_n, default=100)}",
         exponent(fam, "build_wall"), 2.0),
        ("PyDy cold build / ours, n=20", ratio, -2.5),
        ("rhs in C n=20 (µs)", cell(20, "rhs_us"), 2.4),
        ("rhs in C n=40 (µs)", cell(40, "rhs_us"), 10.0),
        ("issue 23: jacobian in C n=20 (µs)", cell(20, "jacobian_us"), 5.0),
        ("issue 23: rhs in C n=40 (µs)", cell(40, "rhs_us"), 6.0),
    ]
    lines = ["| target (nlink) | measured | bound | met |", "|---|---|---|---|"]
    for label, value, bound in checks:
        if value is None:
            lines.append(f"| {label} | — | {abs(bound)} | — |")
            continue
        met = value >= -bound if bound < 0 else value <= bound
        lines.append(f"| {label} | {value:.2f} | {'≥' if bound < 0 else '≤'} {abs(bound)} | "
                     f"{'yes' if met else 'no'} |")
    lines += ["", "Where the per-call time goes (nlink, µs, best of 15): `forcing` runs the M,F "
              "kernel alone (recursive: M by the composite-body sums), `linear_terms` the M,F and "
              "Jacobian kernels (no solves); the rest of rhs and jacobian is the dense Cholesky "
              "factorization and solves (recursive: the articulated-body recursion and its solve), "
              "with 2n right-hand sides for the Jacobian, and copying the (2n)² output.", "",
              "| n | M,F kernel | + Jacobian kernel | rhs | jacobian |", "|---|---|---|---|---|"]
    for n, r in sorted(by_n.items()):
        lines.append(f"| {n} | {r['mf_us']:.2f} | {r['kernels_us']:.2f} | {r['rhs_us']:.2f} | "
                     f"{r['jacobian_us']:.2f} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[2, 10, 20, 40, 80, 100])
    ap.add_argument("--families", nargs="+", default=list(FAMILIES))
    ap.add_argument("--pydy-n", type=int, nargs="*", default=[2, 10, 20])
    ap.add_argument("--no-pydy", action="store_true")
    ap.add_argument("--formulation", choices=("dense", "recursive"), default=None,
                    help="force one (default: lagrgen's choice)")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--out", default=str(HERE / "results" / "scale"))
    args = ap.parse_args(argv)
    if args.one:
        family, n = args.one[0], int(args.one[1])
        print(json.dumps(pydy_one(n) if family == "nlink-pydy" else
                         one(family, n, args.formulation)))
        return
    rows, pydy, load_before = [], {}, os.getloadavg()
    for family in args.families:
        for n in args.n:
            if family == "lattice" and n not in LATTICE:
                continue
            rows.append(in_fresh_process((family, n), args.formulation))
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    if not args.no_pydy:
        for n in args.pydy_n:
            r = in_fresh_process(("nlink-pydy", n))
            print(json.dumps(r), file=sys.stderr, flush=True)
            if "error" not in r:
                pydy["nlink", n] = r
    peers = ("PyDy: " + ("measured (cold build column)" if pydy else
                         "not installed" if args.no_pydy is False and not _installed("pydy")
                         else "not measured") +
             "; CasADi, JiTCODE: " + ", ".join(
                 f"{m} {'installed (see nlink.py)' if _installed(m) else 'not installed'}"
                 for m in ("casadi", "jitcode")) + ".")
    text = (f"# Scaling of lagrgen's build and generated code (issues 11, 23, 30)\n\n"
            f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores. Each "
            f"row is a cold build in a fresh process (nothing derived before), in the "
            f"formulation {args.formulation or 'lagrgen chooses'}, wall seconds of "
            f"its stages (`module.build_info`); the C is all the build compiles (the model's "
            f"module; the analysis unit is compiled on first use and timed apart); per-call "
            f"times are the best of 15 loops inside C (CPU time); load = 1-minute load average "
            f"when the row finished (load average 1, 5, 15 min before the run: "
            f"{' '.join(f'{x:.2f}' for x in load_before)}; after: "
            f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}). Peers: {peers}\n\n"
            + table(rows, pydy) + "\n\n" + targets(rows, pydy) + "\n")
    print(text)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out + ".md").write_text(text)
    Path(args.out + ".json").write_text(json.dumps({"rows": rows, "pydy": list(pydy.values())},
                                                   indent=1))


if __name__ == "__main__":
    main()
