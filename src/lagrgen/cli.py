"""The command line: `python -m lagrgen COMMAND MODEL.py [options]`.

Each command is a pair: `add_NAME(subparsers)` declares its options and `command_NAME(args)` runs
it; `COMMANDS` lists the `add_` functions in the order `--help` shows them.
"""
import argparse
import csv
import runpy
import sys
import time
from pathlib import Path

import numpy as np

from .errors import LagrgenError
from .functions import POWER_TERMS
from .methods import METHODS as METHOD_CHOICES


def models_in(path, names=None):
    """The Model objects defined at top level of the model file `path` (optionally by name)."""
    from .model import Model
    path = Path(path)
    if not path.is_file():
        raise LagrgenError(f"no model file {str(path)!r}")
    sys.path.insert(0, str(path.resolve().parent))
    try:
        namespace = runpy.run_path(str(path), run_name=f"lagrgen_model_file_{path.stem}")
    except SyntaxError as exc:
        raise LagrgenError(f"{exc.filename}, line {exc.lineno}: {exc.msg}") from None
    finally:
        sys.path.pop(0)
    found, seen = [], set()
    for value in namespace.values():
        if isinstance(value, Model) and id(value) not in seen:
            seen.add(id(value))
            found.append(value)
    if not found:
        raise LagrgenError(
            f"{path} defines no lagrgen.Model at top level: a model file must create one, "
            "e.g. `model = Model('my_system')`")
    all_names = [m.name for m in found]
    twice = sorted({n for n in all_names if all_names.count(n) > 1})
    if twice:
        raise LagrgenError(f"{path} defines more than one model named {', '.join(twice)}: "
                           "model names name compiled modules, so each must be unique")
    if names:
        missing = sorted(set(names) - set(all_names))
        if missing:
            raise LagrgenError(f"{path} defines no model named {', '.join(missing)}; "
                               f"it defines {', '.join(all_names)}")
        found = [m for m in found if m.name in names]
    return found


def command_build(args):
    from .build import build
    for model in models_in(args.model_file, args.model):
        module = build(model, out_dir=args.out, verbose=args.verbose, quiet=args.quiet,
                       force=args.force)
        info = module.build_info
        state = "cached" if info["cache_hit"] else "built"
        if not args.quiet:
            print(f"{model.name}: {state} in {info['seconds']:.2f} s -> {args.out}/")
    return 0


def add_model_file(parser):
    parser.add_argument("model_file", help="a Python file that defines lagrgen.Model objects")
    parser.add_argument("--model", action="append",
                        help="only the model of this name (may be repeated; default: all)")


def add_common(parser):
    add_model_file(parser)
    parser.add_argument("--out", default="generated", help="output directory (default: generated)")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    parser.add_argument("--verbose", action="store_true",
                        help="report each build step's time, code size and compiler flags")


def add_build(sub):
    b = sub.add_parser("build", help="build every model in a model file (C backend, cached)",
                       description="Derive, generate C, compile and cache every model in MODEL.py.")
    add_common(b)
    b.add_argument("--force", action="store_true", help="rebuild even if a cached build matches")
    b.set_defaults(run=command_build)


def command_export_c(args):
    from .build import export_c
    for model in models_in(args.model_file, args.model):
        paths = export_c(model, args.out)
        if not args.quiet:
            print(f"{model.name}: wrote {', '.join(str(p) for p in paths)}")
    return 0


def add_export_c(sub):
    e = sub.add_parser("export-c", help="write a model as plain C (<name>_model.h and .c)",
                       description="Write each model of MODEL.py as a standalone C model: "
                       "<name>_model.h and <name>_model.c, which include only <math.h> and "
                       "<string.h> and need no Python (compile with any C99 compiler, link -lm).")
    add_model_file(e)
    e.add_argument("--out", default=".", help="output directory (default: the current one)")
    e.add_argument("--quiet", action="store_true", help="print nothing but errors")
    e.set_defaults(run=command_export_c)


# -- show -------------------------------------------------------------------------------------
def command_show(args):
    from .outputs.display import render
    texts = [render(model, latex=args.latex, matrices=args.matrices, simplify=not args.raw)
             for model in models_in(args.model_file, args.model)]
    print("\n\n".join(texts))
    return 0


def add_show(sub):
    s = sub.add_parser("show", help="print the equations of motion (plain text or LaTeX)",
                       description="Print each model's equations of motion, one line per "
                       "coordinate: sum_j M_ij q_j'' = F_i, with q' and q'' for the velocities and "
                       "accelerations (LaTeX: \\dot{q}, \\ddot{q}).")
    add_model_file(s)
    s.add_argument("--latex", action="store_true", help="print LaTeX (an aligned environment)")
    s.add_argument("--matrices", action="store_true", help="also print M and F entry by entry")
    s.add_argument("--raw", action="store_true", help="skip the (cheap) trigonometric simplification")
    s.set_defaults(run=command_show)


# -- shared by modes and simulate ------------------------------------------------------------
def split_items(text):
    """The NAME=VALUE items of one option value: separated by ';', or by ',' outside brackets, so
    `F=Max(0,t-0.5);G=1` and `a=1,b=2` both work."""
    items, depth, current = [], 0, []
    for ch in text:
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth = max(depth - 1, 0)
        if ch == ";" or (ch == "," and depth == 0):
            items.append("".join(current))
            current = []
        else:
            current.append(ch)
    items.append("".join(current))
    return items


def assignments(texts, what):
    """{name: text} from ["a=1,b=2", "c=Max(0,t);d=3"] (the values of a repeatable NAME=VALUE
    option: items separated by ';' or by commas outside brackets)."""
    out = {}
    for text in texts or ():
        for item in split_items(text):
            if not item.strip():
                continue
            name, sep, value = item.partition("=")
            if not sep or not name.strip() or not value.strip():
                raise LagrgenError(f"{what}: expected NAME=VALUE, got {item.strip()!r}")
            out[name.strip()] = value.strip()
    return out


def number(text, what):
    """The value of a number or a constant expression such as `2*pi` (restricted reader)."""
    from .expressions import ExpressionError, parse_number
    try:
        return parse_number(text)
    except ExpressionError as exc:
        raise LagrgenError(f"{what}: {exc}") from None


def known_names(values, option, model, what, names):
    """`values` (a dict), after checking each key is one of the model's `names` (its `what`s)."""
    from .runtime.arguments import unknown_name
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise LagrgenError(f"{option}: {unknown_name(what, unknown[0], names)}")
    return values


def parameters_option(args, model):
    """The --params values as a dict name -> float, checked against the model's parameters."""
    values = {k: number(v, f"--params {k}") for k, v in assignments(args.params, "--params").items()}
    return known_names(values, "--params", model, "parameter", model.parameter_names)


def input_value(name, text):
    """A constant, or a function of t, from an expression such as `0.5*sin(2*t)`."""
    from .expressions import ExpressionError, parse_time_function
    try:
        return parse_time_function(text)
    except ExpressionError as exc:
        raise LagrgenError(f"--inputs {name}: {exc}") from None


def inputs_option(args, model, constant=False):
    """The --inputs values: name -> constant or function of t (constants only if `constant`)."""
    values = known_names(assignments(args.inputs, "--inputs"), "--inputs", model, "input",
                         model.input_names)
    out = {name: input_value(name, text) for name, text in values.items()}
    varying = [name for name, v in out.items() if callable(v)]
    if constant and varying:
        raise LagrgenError(f"--inputs {varying[0]}: the operating point needs a constant value")
    return out


def build_for(model, args):
    """The built model for the chosen --backend (C builds are cached in --out)."""
    from .build import build
    if args.backend == "python":
        return build(model, backend="python")
    return build(model, out_dir=args.out, verbose=args.verbose, quiet=args.quiet)


def add_run_options(parser):
    """Options shared by the commands that run a model: backend, parameters, inputs."""
    add_common(parser)
    parser.add_argument("--backend", choices=("c", "python"), default="c",
                        help="compiled C (default, cached in --out) or pure Python")
    parser.add_argument("--params", action="append", metavar="NAME=VALUE,...",
                        help="parameter values (others keep their defaults); repeat the flag or "
                        "separate items with ';' or ','")


# -- modes ------------------------------------------------------------------------------------
def modes_table(model, q0, result):
    """The equilibrium, then one row per mode: ω (rad/s), f (Hz), ζ; then the mode shapes."""
    names = model.coordinate_names
    units = model.units

    def with_unit(c, v):
        return f"{c} = {v:.6g}" + (f" {units[c]}" if units.get(c) else "")
    lines = [f"{model.name}: equilibrium " + ", ".join(with_unit(c, v) for c, v in zip(names, q0)),
             f"{'mode':>4}  {'omega [rad/s]':>14}  {'f [Hz]':>12}  {'damping ratio':>13}"]
    for i, w in enumerate(result.omega):
        zeta = result.damping_ratios[i]
        if np.isfinite(w):
            lines.append(f"{i + 1:>4}  {w:>14.6g}  {w / (2 * np.pi):>12.6g}  {zeta:>13.6g}")
        else:
            lam = np.real(result.eigenvalues[i])
            lines.append(f"{i + 1:>4}  {'unstable':>14}  {'':>12}  {'':>13}  (omega^2 = {lam:.6g})")
    rows = [column(c, units) for c in names]
    width = max(len(r) for r in rows)
    lines.append("mode shapes (mass-normalized, one column per mode):")
    for j, r in enumerate(rows):
        lines.append(f"{r:>{width}}  " + "  ".join(f"{np.real(v):>10.5g}" for v in result.shapes[j]))
    return "\n".join(lines)


def command_modes(args):
    from .outputs.plotting import plot_modes
    import warnings
    from .vibration import FrozenTimeWarning, equilibrium, modes
    models = models_in(args.model_file, args.model)
    for k, model in enumerate(models):
        params = parameters_option(args, model)
        inputs = inputs_option(args, model, constant=True)
        at = known_names({c: number(v, f"--at {c}") for c, v in assignments(args.at, "--at").items()},
                         "--at", model, "coordinate", model.coordinate_names)
        mod = build_for(model, args)
        guess = [at.get(c, 0.0) for c in model.coordinate_names]
        u = inputs or None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FrozenTimeWarning)
            q0 = equilibrium(mod, guess, p=params, u=u, t=args.t)
            result = modes(mod, q0, p=params, u=u, t=args.t)
        if caught and not args.quiet:
            print(f"lagrgen: warning: {caught[-1].message}", file=sys.stderr)
        if not args.quiet:
            print(("\n" if k else "") + modes_table(model, q0, result))
        if args.plot:
            path = Path(args.plot)
            if len(models) > 1:
                path = path.with_name(f"{path.stem}_{model.name}{path.suffix}")
            plot_modes(result, model.coordinate_names, path, title=f"{model.name}: mode shapes")
            if not args.quiet:
                print(f"mode shapes -> {path}")
        if args.animate:
            Path(args.animate).mkdir(parents=True, exist_ok=True)
            for i in range(len(result)):
                path = result.animate(i, Path(args.animate) / f"{model.name}_mode{i + 1}.gif",
                                      model=model)
                if not args.quiet:
                    print(f"mode {i + 1} animation -> {path}")
    return 0


def add_modes(sub):
    m = sub.add_parser("modes", help="natural frequencies, damping ratios and mode shapes",
                       description="Find the static equilibrium near --at (default: all "
                       "coordinates zero), linearize there and print the natural frequencies "
                       "(rad/s and Hz), damping ratios and mass-normalized mode shapes.")
    add_run_options(m)
    m.add_argument("--at", action="append", metavar="COORD=VALUE,...",
                   help="starting guess of the equilibrium (unnamed coordinates: 0)")
    m.add_argument("--inputs", action="append", metavar="NAME=VALUE,...",
                   help="constant inputs at the operating point (default: 0)")
    m.add_argument("--plot", metavar="OUT.png", help="also plot the mode shapes to this image")
    m.add_argument("--animate", metavar="DIR", help="also write each mode shape moving on the "
                   "mechanism to DIR/<model>_mode<k>.gif")
    m.add_argument("--t", type=float, default=0.0, metavar="T",
                   help="the frozen time of a model that depends explicitly on t (default 0; "
                   "the result holds at that instant only, and a warning says so)")
    m.set_defaults(run=command_modes)


# -- simulate ---------------------------------------------------------------------------------
def single_model(args):
    models = models_in(args.model_file, args.model)
    if len(models) > 1:
        raise LagrgenError(f"{args.model_file} defines several models "
                           f"({', '.join(m.name for m in models)}): choose one with --model NAME")
    return models[0]


def initial_state(text, model):
    """y0 = [q0, q̇0] from "v1,v2,..." (n or 2n numbers) or "name=v,name'=v,..." (others 0)."""
    names = model.coordinate_names
    n = len(names)
    y0 = np.zeros(2 * n)
    if not text:
        return y0
    if "=" not in text:
        values = [number(v, "--y0") for v in text.split(",") if v.strip()]
        if len(values) not in (n, 2 * n):
            raise LagrgenError(f"--y0: expected {n} positions or {2 * n} values [q, q'] for the "
                               f"coordinates {', '.join(names)}, got {len(values)}")
        y0[:len(values)] = values
        return y0
    slots = {c: i for i, c in enumerate(names)}
    for i, c in enumerate(names):
        slots.setdefault(f"{c}'", n + i)
        slots.setdefault(f"{c}_dot", n + i)
    for name, value in assignments([text], "--y0").items():
        if name not in slots:
            raise LagrgenError(f"--y0: {name!r} is not a coordinate or a velocity (use "
                               f"{names[0]}=... and {names[0]}'=... or {names[0]}_dot=...)")
        y0[slots[name]] = number(value, f"--y0 {name}")
    return y0


def column(name, units):
    """A CSV header: 'x [m]' when the name has a unit, else the name."""
    unit = (units or {}).get(name)
    return f"{name} [{unit}]" if unit else name


def write_csv(stream, sol, names, outputs=None, units=None):
    """t, q, q' (as <coordinate>_dot) per saved time; then the multipliers λ of a constrained
    model (M q'' = F + Aᵀλ), one column per constraint name; then the outputs; then, for a model
    with impacts or frictions, a column "transition" naming the switches ("floor:impact", joined
    by ";") on the first row at or after their time (at a switch the result holds the state
    before and after it: the first of the two rows). Headers carry units ('x [m]', 'x_dot [m/s]')."""
    from .outputs.plotting import rate_unit
    units = dict(units or {})
    for c in names:
        if rate_unit(units.get(c)):
            units[f"{c}_dot"] = rate_unit(units[c])
    out_names = list(outputs.names) if outputs is not None else []
    lam = getattr(sol, "constraint_forces", np.zeros((0, len(sol.t))))
    transitions = getattr(sol, "transitions", None)
    marks = {}
    for t, name, kind in transitions or ():
        k = int(np.searchsorted(sol.t, t, side="left"))
        if k < len(sol.t):
            marks.setdefault(k, []).append(f"{name}:{kind}")
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow([column("t", {"t": "s"} if units else {}),
                     *(column(c, units) for c in names),
                     *(column(f"{c}_dot", units) for c in names),
                     *getattr(sol, "constraint_names", ()),
                     *(column(o, units) for o in out_names),
                     *(["transition"] if transitions is not None else [])])
    for k, t in enumerate(sol.t):
        values = [*sol.y[:, k], *lam[:, k]]
        if outputs is not None:
            values += list(np.asarray(outputs)[:, k])
        row = [repr(float(t)), *(repr(float(v)) for v in values)]
        if transitions is not None:
            row.append(";".join(marks.get(k, ())))
        writer.writerow(row)


def command_simulate(args):
    from .simulate import simulate
    model = single_model(args)
    params = parameters_option(args, model)
    inputs = inputs_option(args, model)
    y0 = initial_state(args.y0, model)
    if not args.t_end > args.t_start:
        raise LagrgenError(f"--t-end ({args.t_end}) must be greater than --t-start ({args.t_start})")
    if args.samples < 2:
        raise LagrgenError("--samples must be at least 2")
    mod = build_for(model, args)
    if mod.n_constraints:
        y0 = consistent_start(mod, y0, args, params)
    progress = True if args.progress else (False if args.quiet else "auto")
    t_eval = np.linspace(args.t_start, args.t_end, args.samples)
    options = {} if args.max_step is None else {"max_step": args.max_step}
    if args.max_steps <= 0 or (args.max_time is not None and args.max_time <= 0):
        raise LagrgenError("--max-steps and --max-time must be positive")
    plot_outputs = output_choice(args.plot_outputs, mod)
    started = time.perf_counter()
    sol = simulate(mod, (args.t_start, args.t_end), y0, method=args.method,
                   params=params or None, inputs=inputs or None, rtol=args.rtol, atol=args.atol,
                   t_eval=t_eval, max_steps=args.max_steps, max_wall_time=args.max_time,
                   progress=progress, **options)
    seconds = time.perf_counter() - started
    if not sol.success and sol.guard is None:
        reached = sol.t[-1] if len(sol.t) else args.t_start
        raise LagrgenError(f"the integration stopped at t = {reached:.6g}: {sol.message}")
    written = write_outputs(args, model, sol, params, mod, plot_outputs)
    if sol.guard is not None:
        for what, path in written:
            print(f"{what} (partial) -> {path}", file=sys.stderr)
        raise LagrgenError(f"{sol.message} (raise --max-steps or --max-time to go further)")
    if not args.quiet:
        print(f"{model.name}: {args.method} from t = {args.t_start:g} to {args.t_end:g}, "
              f"{sol.nfev} rhs calls, {seconds:.3f} s ({mod.backend} backend, {sol.engine} "
              "engine)", file=sys.stderr)
        for what, path in written:
            print(f"{what} -> {path}", file=sys.stderr)
    return 0


def consistent_start(mod, y0, args, params):
    """y0 projected onto the constraints (`lagrgen.consistent_state`), saying so if it moved."""
    from .constraints import consistent_state
    y = consistent_state(mod, y0, args.t_start, params or None)
    if np.abs(y - y0).max() > 1e-12 * max(1.0, np.abs(y0).max()) and not args.quiet:
        print(f"{mod.name}: initial state projected onto the constraints: y0 = "
              f"{','.join(repr(float(v)) for v in y)}", file=sys.stderr)
    return y


def output_choice(text, mod):
    """The output names chosen by --plot-outputs ("energy" stands for T, V and T + V)."""
    if not text:
        return []
    chosen = []
    for name in (n.strip() for n in text.split(",")):
        if not name:
            continue
        names = ENERGIES if name == "energy" else (name,)
        for n in names:
            known = tuple(mod.output_names) + POWER_TERMS
            if n not in known:
                raise LagrgenError(f"--plot-outputs: model {mod.name!r} has no output {n!r} "
                                   f"(its outputs are energy, {', '.join(known)})")
            if n not in chosen:
                chosen.append(n)
    return chosen


ENERGIES = ("kinetic_energy", "potential_energy", "total_energy")


def write_outputs(args, model, sol, params, mod=None, plot_outputs=()):
    """The CSV (stdout if no output is asked for, or with --csv -), plot and animation;
    [(what, path)]."""
    from .outputs import plotting
    from .simulate import evaluate_outputs
    written = []
    names = model.coordinate_names
    units = model.units
    outputs = evaluate_outputs(mod, sol) if mod is not None and len(sol.t) else None
    if args.csv == "-":
        write_csv(sys.stdout, sol, names, outputs, units)
        sys.stdout.flush()
    elif args.csv:
        with open(args.csv, "w", newline="") as stream:
            write_csv(stream, sol, names, outputs, units)
        written.append(("time histories (CSV)", args.csv))
    if args.plot:
        plotting.plot_time_history(sol, names, args.plot, title=model.name, units=units)
        written.append(("plot", args.plot))
    if plot_outputs:
        path = Path(args.plot_to or (Path(args.plot).with_name(Path(args.plot).stem + "_outputs.png")
                                     if args.plot else f"{model.name}_outputs.png"))
        plotting.plot_series(sol.t, [outputs[n] for n in plot_outputs], plot_outputs, units,
                             path, title=f"{model.name}: outputs")
        written.append(("outputs plot", str(path)))
    if args.animate:
        plotting.animate(model, sol, args.animate, params=params or None, fps=args.fps,
                         max_frames=args.frames)
        written.append(("animation", args.animate))
    if not written and args.csv != "-":
        write_csv(sys.stdout, sol, names, outputs, units)
    return written


def add_simulate(sub):
    from .methods import METHODS
    s = sub.add_parser("simulate", help="integrate the equations of motion; CSV, plot, animation",
                       description="Integrate y = [q, q'] with scipy.integrate.solve_ivp and write "
                       "the time histories as CSV (stdout unless --csv, --plot or --animate is "
                       "given), a plot, and/or an animated GIF of the mechanism. Give negative "
                       "values as --y0=-0.5,0.")
    add_run_options(s)
    s.add_argument("--t-end", type=float, required=True, metavar="T", help="end time")
    s.add_argument("--t-start", type=float, default=0.0, metavar="T0", help="start time (default 0)")
    s.add_argument("--y0", metavar="VALUES",
                   help="initial state: n positions or 2n values q, q' separated by commas, or "
                   "COORD=VALUE,COORD'=VALUE (or COORD_dot=VALUE); default all zero")
    s.add_argument("--inputs", action="append", metavar="NAME=VALUE,...",
                   help="inputs: numbers or expressions of t, e.g. F=0.5*sin(2*t) (default 0); "
                   "repeat the flag or separate items with ';' (commas inside brackets stay: "
                   "--inputs 'F=Max(0,t-0.5)')")
    s.add_argument("--method", choices=METHODS, default="RK45", help="solve_ivp method (default RK45)")
    s.add_argument("--rtol", type=float, default=1e-6, help="relative tolerance (default 1e-6)")
    s.add_argument("--atol", type=float, default=1e-9, help="absolute tolerance (default 1e-9)")
    s.add_argument("--max-step", type=float, help="largest step solve_ivp may take")
    s.add_argument("--samples", type=int, default=501,
                   help="number of equally spaced output times (default 501)")
    s.add_argument("--csv", metavar="OUT.csv",
                   help="write t, q, q', the multipliers of a constrained model and the outputs "
                   "(one row per output time; headers carry units); '-' writes to stdout")
    s.add_argument("--plot-outputs", metavar="NAME,...",
                   help="plot these outputs ('energy' = kinetic, potential and total energy; or "
                   "names from model.output) to --plot-outputs-to (default: <plot>_outputs.png)")
    s.add_argument("--plot-outputs-to", dest="plot_to", metavar="OUT.png",
                   help="where --plot-outputs writes its figure")
    s.add_argument("--max-steps", type=int, default=1_000_000,
                   help="stop after this many solver steps, keeping the result so far "
                   "(default 1000000)")
    s.add_argument("--max-time", type=float, metavar="SECONDS",
                   help="stop after this much wall time, keeping the result so far")
    s.add_argument("--plot", metavar="OUT.png", help="plot q(t) and q'(t) to this image")
    s.add_argument("--animate", metavar="OUT.gif", help="animate the mechanism to this GIF")
    s.add_argument("--fps", type=int, default=20,
                   help="animation frames per simulated second (default 20)")
    s.add_argument("--frames", type=int, default=120, help="most animation frames (default 120)")
    s.add_argument("--progress", action="store_true",
                   help="report progress on stderr even when it is not a terminal")
    s.set_defaults(run=command_simulate)


# -- bench ------------------------------------------------------------------------------------
def command_bench(args):
    from .bench import METHODS, bench_model, markdown
    methods = args.methods or METHODS
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise LagrgenError(f"--methods: unknown method {unknown[0]!r} (use {', '.join(METHODS)})")
    reports = []
    for model in models_in(args.model_file, args.model):
        def fresh(name=model.name):
            return models_in(args.model_file, [name])[0]
        y0 = initial_state(args.y0, model) if args.y0 else None
        if y0 is not None and model.constraint_names:
            from .build import build
            from .constraints import consistent_state
            y0 = consistent_state(build(model, backend="python"), y0, 0.0)
        result = bench_model(fresh, y0=y0, methods=methods, t_span=(0.0, args.t_end),
                             rtol=args.rtol, atol=args.atol, repeats=args.repeats)
        reports.append(markdown(result))
        print(reports[-1], flush=True)
    if args.output:
        Path(args.output).write_text("\n".join(reports))
    return 0


def add_bench(sub):
    b = sub.add_parser(
        "bench", help="time the compiled and pure-Python paths of each model (a markdown table)",
        description="Cold and cached build, rhs and jacobian per call (from Python and inside "
                    "C), and solve_ivp wall time with nfev/njev/nlu, on lagrgen's C and Python "
                    "paths.")
    add_model_file(b)
    b.add_argument("--y0", metavar="VALUES", help="initial state (default: every q = 0.1, q' = 0)")
    b.add_argument("--t-end", type=float, default=10.0, help="end time of the solve (default 10)")
    b.add_argument("--methods", nargs="+", metavar="METHOD",
                   help="solve_ivp methods (default: RK45 DOP853 Radau BDF LSODA)")
    b.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance (default 1e-8)")
    b.add_argument("--atol", type=float, default=1e-8, help="absolute tolerance (default 1e-8)")
    b.add_argument("--repeats", type=int, default=3, help="repeats per figure (default 3)")
    b.add_argument("--output", metavar="FILE.md", help="also write the table to this file")
    b.set_defaults(run=command_bench)


# -- export-fmu -------------------------------------------------------------------------------
def command_export_fmu(args):
    from .build import export_fmu
    from .codegen.fmu import KIND_TITLES
    for model in models_in(args.model_file, args.model):
        params = parameters_option(args, model)
        path = export_fmu(model, args.out, params=params, start_time=args.start_time,
                          stop_time=args.stop_time, tolerance=args.tolerance, kind=args.kind,
                          fmi_version=args.fmi_version, method=args.method, rtol=args.rtol,
                          atol=args.atol)
        if not args.quiet:
            print(f"{model.name}: FMI {args.fmi_version}.0 {KIND_TITLES[args.kind]} FMU -> {path}")
    return 0


def add_export_fmu(sub):
    from .methods import NATIVE_METHODS
    e = sub.add_parser("export-fmu", help="write each model as an FMU (FMI 2.0 or 3.0, Model "
                       "Exchange or Co-Simulation)",
                       description="Compile every model in MODEL.py into DIR/<name>.fmu, an FMU "
                       "for this platform (default: FMI 2.0 Model Exchange): states q and q' "
                       "(named like the coordinates and <coordinate>_dot), parameters (tunable, "
                       "starting at their defaults), inputs, the coordinates as outputs, "
                       "directional derivatives from the analytic Jacobian, and FMU states that "
                       "can be saved, restored and serialized. A Co-Simulation FMU (--kind cs) "
                       "steps itself with lagrgen's native engine; its method and tolerances are "
                       "the parameters solver.method, solver.rtol and solver.atol.")
    add_model_file(e)
    e.add_argument("--out", default=".", help="output directory (default: the current one)")
    e.add_argument("--kind", choices=("me", "cs"), default="me",
                   help="me: Model Exchange (the importer integrates); cs: Co-Simulation (the "
                   "FMU integrates with the native engine). Default me")
    e.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="FMI version (default 2)")
    e.add_argument("--method", choices=NATIVE_METHODS,
                   default="DOP853", help="co-simulation: the native engine's method (DOP853)")
    e.add_argument("--rtol", type=float, help="co-simulation: relative tolerance (default "
                   "--tolerance, or 1e-6)")
    e.add_argument("--atol", type=float, help="co-simulation: absolute tolerance (rtol/1000)")
    e.add_argument("--params", action="append", metavar="NAME=VALUE,...",
                   help="parameter start values in place of the defaults")
    e.add_argument("--start-time", type=float, default=0.0, help="DefaultExperiment start (0)")
    e.add_argument("--stop-time", type=float, default=10.0, help="DefaultExperiment stop (10)")
    e.add_argument("--tolerance", type=float, help="DefaultExperiment relative tolerance")
    e.add_argument("--quiet", action="store_true", help="print nothing but errors")
    e.set_defaults(run=command_export_fmu)


#: The subcommands, in the order `--help` lists them: each adds its parser to the subparsers.
# -- sweep ------------------------------------------------------------------------------------
def sweep_range(text):
    """(name, values) from NAME=START:STOP:N."""
    name, sep, spec = text.partition("=")
    parts = spec.split(":")
    if not sep or len(parts) != 3 or not name.strip().isidentifier():
        raise LagrgenError(f"--param: expected NAME=START:STOP:N, got {text!r}")
    start, stop = number(parts[0], "--param START"), number(parts[1], "--param STOP")
    try:
        count = int(parts[2])
    except ValueError:
        count = 0
    if count < 1:
        raise LagrgenError(f"--param: N must be a positive whole number, got {parts[2]!r}")
    return name.strip(), np.linspace(start, stop, count)


def sweep_inputs(texts, model, swept, params):
    """inputs as a function of the swept value: each --input NAME=EXPR may use t, the swept
    name and the model's parameters (their values for the run)."""
    from .expressions import ExpressionError, parse_time_function
    given = known_names(assignments(texts, "--input"), "--input", model, "input",
                        model.input_names)
    if not given:
        return None
    defaults = dict(zip(model.parameter_names, model.parameter_defaults))
    constants = {k: v for k, v in {**defaults, **params}.items() if v is not None}

    def inputs(value):
        names = {**constants, swept: value}
        try:
            return {k: parse_time_function(text, names) for k, text in given.items()}
        except ExpressionError as exc:
            raise LagrgenError(f"--input: {exc}") from None
    inputs(0.0)
    return inputs


def command_sweep(args):
    from .sweep import sweep
    model = single_model(args)
    name, values = sweep_range(args.param)
    params = parameters_option(args, model)
    inputs = sweep_inputs(args.input, model, name, params)
    if name not in model.parameter_names and inputs is None:
        raise LagrgenError(f"--param {name}: not a parameter of {model.name!r} (its parameters are "
                           f"{', '.join(model.parameter_names)}) and no --input uses it")
    mod = build_for(model, args)
    result = sweep(mod, name, values, (0.0, args.t_end), y0=initial_state(args.y0, model),
                   inputs=inputs, params=params or None, measure=args.measure,
                   settle=args.settle, method=args.method, rtol=args.rtol, atol=args.atol,
                   workers=args.workers, progress=not args.quiet and sys.stderr.isatty())
    header = [name] + [f"{c}_{args.measure}" for c in model.coordinate_names]
    rows = np.column_stack([result.values, result.table])
    if args.csv:
        with open(args.csv, "w", newline="") as stream:
            write_rows(stream, header, rows)
    if args.plot:
        from .outputs.plotting import plot_sweep
        linear = None
        if args.linear is not None:
            linear = linear_amplitudes(mod, model, args, result.values)
        plot_sweep(result, args.plot, title=model.name, linear=linear)
    if not (args.csv or args.plot):
        write_rows(sys.stdout, header, rows)
    failed = int((~result.success).sum())
    if failed and not args.quiet:
        print(f"{model.name}: {failed} of {len(values)} runs failed", file=sys.stderr)
    return 0


def linear_amplitudes(mod, model, args, omegas):
    """AMPLITUDE·|H(ω)| of each coordinate to the one --input, about the equilibrium near 0."""
    from .vibration import equilibrium, frequency_response
    if len(model.input_names) < 1:
        raise LagrgenError("--linear needs a model with an input")
    forced = list(assignments(args.input, "--input"))[:1] or [model.input_names[0]]
    q0 = equilibrium(mod, np.zeros(mod.n_coordinates))
    H = frequency_response(mod, q0, np.asarray(omegas) / (2 * np.pi), input=forced[0])
    return args.linear * np.abs(H)


def write_rows(stream, header, rows):
    writer = csv.writer(stream)
    writer.writerow(header)
    writer.writerows([[f"{v:.10g}" for v in row] for row in rows])


def add_sweep(sub):
    from .methods import MEASURES, METHODS
    s = sub.add_parser("sweep", help="a steady-state measure against a swept parameter",
                       description="Run the model once per value of --param NAME=START:STOP:N "
                       "(a parameter, or a name the --input expressions use, such as a forcing "
                       "frequency) and report the steady-state --measure of each coordinate over "
                       "the last part of each run, as CSV and/or a plot.")
    add_run_options(s)
    s.add_argument("--param", required=True, metavar="NAME=START:STOP:N", help="what to sweep")
    s.add_argument("--input", action="append", metavar="NAME=EXPR",
                   help="an input as an expression of t, the swept name and the parameters, "
                   "e.g. F=A*sin(w*t)")
    s.add_argument("--t-end", type=float, required=True, metavar="T", help="end time of each run")
    s.add_argument("--y0", metavar="VALUES", help="initial state, as for simulate (default 0)")
    s.add_argument("--measure", choices=MEASURES, default="amplitude",
                   help="amplitude (half peak-to-peak), max (largest |q|) or final (default "
                   "amplitude), over the steady window")
    s.add_argument("--settle", type=float, default=0.5,
                   help="fraction of each run left out as transient (default 0.5)")
    s.add_argument("--method", choices=METHODS, default="RK45", help="solve_ivp method")
    s.add_argument("--rtol", type=float, default=1e-6, help="relative tolerance (default 1e-6)")
    s.add_argument("--atol", type=float, default=1e-9, help="absolute tolerance (default 1e-9)")
    s.add_argument("--workers", type=int, help="threads (default: every core for C)")
    s.add_argument("--linear", type=float, metavar="AMPLITUDE",
                   help="also plot AMPLITUDE·|H(ω)| of the linearized model to the input, with "
                   "the swept values as ω in rad/s")
    s.add_argument("--csv", metavar="OUT.csv", help="write the table")
    s.add_argument("--plot", metavar="OUT.png", help="plot the measure against the swept value")
    s.set_defaults(run=command_sweep)


# -- fit --------------------------------------------------------------------------------------
def read_record(path):
    """(column names without their units, values (rows, columns)) of a CSV with a header row,
    as `simulate --csv` writes it (t first)."""
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    if len(rows) < 3:
        raise LagrgenError(f"{path}: a header row and at least two rows of samples are needed")
    names = [cell.split(" [")[0].strip() for cell in rows[0]]
    try:
        values = np.array([[float(v) for v in row] for row in rows[1:] if row], dtype=float)
    except ValueError as exc:
        raise LagrgenError(f"{path}: every sample must be a number ({exc})") from None
    if values.ndim != 2 or values.shape[1] != len(names):
        raise LagrgenError(f"{path}: every row must have {len(names)} values like the header")
    return names, values


def command_fit(args):
    from .fit import fit
    model = single_model(args)
    names, values = read_record(args.data)
    if names[0] != "t":
        raise LagrgenError(f"{args.data}: the first column must be the time t, not {names[0]!r}")
    fitted = [n.strip() for n in args.params.split(",") if n.strip()]
    states = list(model.coordinate_names) + [f"{c}_dot" for c in model.coordinate_names]
    measured = ([m.strip() for m in args.measured.split(",") if m.strip()] if args.measured
                else [n for n in names[1:] if n in model.coordinate_names])
    missing = [m for m in measured if m not in names]
    if missing or not measured:
        raise LagrgenError(f"{args.data} has no column {missing[0] if missing else 'of a coordinate'}"
                           f" (its columns are {', '.join(names)})")
    t = values[:, 0]
    y0 = {n: values[0, names.index(n)] for n in states if n in names}
    mod = build_for(model, args)
    data = np.array([values[:, names.index(m)] for m in measured])
    initial = {k: number(v, f"--initial {k}") for k, v in assignments(args.initial, "--initial").items()}
    result = fit(mod, t, data, fitted, y0, measured=measured, initial=initial or None,
                 method=args.method, rtol=args.rtol, atol=args.atol)
    print(f"{model.name}: fit of {', '.join(fitted)} to {', '.join(measured)} "
          f"({data.size} samples, {result.nfev} iterations, rms residual "
          f"{np.sqrt(2 * result.cost / data.size):.3g}{'' if result.success else ', NOT converged'})")
    width = max(len(n) for n in fitted)
    for n in fitted:
        print(f"  {n:<{width}} = {result.params[n]:.6g} ± {result.stderr[n]:.2g}")
    if args.plot:
        from .outputs.plotting import plot_fit
        fitted_run = fitted_response(mod, model, t, y0, result, measured, args)
        plot_fit(t, data, fitted_run, measured, args.plot, title=f"{model.name}: fit",
                 units=model.units)
        print(f"plot -> {args.plot}", file=sys.stderr)
    return 0 if result.success else 1


def fitted_response(mod, model, t, y0, result, measured, args):
    """The measured names' histories of the model at the estimates."""
    from .simulate import simulate
    states = list(model.coordinate_names) + [f"{c}_dot" for c in model.coordinate_names]
    params = {k: v for k, v in result.params.items() if not k.startswith("y0:")}
    start = dict(y0, **{k[3:]: v for k, v in result.params.items() if k.startswith("y0:")})
    sol = simulate(mod, (t[0], t[-1]), start, method=args.method, params=params, t_eval=t,
                   rtol=args.rtol, atol=args.atol)
    return np.array([sol.y[states.index(m)] for m in measured])


def add_fit(sub):
    f = sub.add_parser("fit", help="estimate parameters from a measured response",
                       description="Least-squares estimates of the named parameters (and "
                       "initial states y0:<state>) from a CSV record with columns t, then "
                       "coordinates and <coordinate>_dot (as `simulate --csv` writes it), with "
                       "the exact gradient from forward sensitivities; prints the estimates "
                       "with their standard errors. The initial state is the record's first row "
                       "(velocities 0 unless given): with noisy data, fit it too with y0:<state>.")
    add_common(f)
    f.add_argument("--backend", choices=("c", "python"), default="c",
                   help="compiled C (default, cached in --out) or pure Python")
    f.add_argument("--data", required=True, metavar="RUN.csv", help="the measured record")
    f.add_argument("--params", required=True, metavar="NAME,...",
                   help="the names to estimate: parameters, or y0:<state>")
    f.add_argument("--measured", metavar="NAME,...",
                   help="the measured columns to fit (default: every coordinate in the record)")
    f.add_argument("--initial", action="append", metavar="NAME=VALUE,...",
                   help="start values (default: the model's defaults)")
    f.add_argument("--method", choices=METHOD_CHOICES, default="DOP853",
                   help="integration method (default DOP853)")
    f.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance (default 1e-8)")
    f.add_argument("--atol", type=float, default=1e-10, help="absolute tolerance (default 1e-10)")
    f.add_argument("--plot", metavar="OUT.png", help="plot the measured and fitted responses")
    f.set_defaults(run=command_fit)


COMMANDS = [add_build, add_export_c, add_export_fmu, add_show, add_modes, add_simulate, add_bench,
            add_sweep, add_fit]


def parser():
    top = argparse.ArgumentParser(
        prog="python -m lagrgen",
        description="Derive Lagrange's equations of motion, compile them to C, and run them.")
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(sub)
    return top


def main(argv=None):
    args = parser().parse_args(argv)
    try:
        return args.run(args)
    except BrokenPipeError:
        return closed_pipe()
    except (LagrgenError, ValueError, OSError, np.linalg.LinAlgError) as exc:
        print(f"lagrgen: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("lagrgen: interrupted", file=sys.stderr)
        return 130


def closed_pipe():
    """The reader of stdout went away (`... | head`): end quietly. stdout is pointed at devnull so
    the interpreter's final flush does not complain either."""
    import os
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 0
