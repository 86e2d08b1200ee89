"""`python -m lagrgen simulate MODEL.py`: time histories as CSV, a plot, an animation."""
import csv
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import LagrgenError
from ..functions import POWER_TERMS
from .arguments import (add_run_options, build_for, column, command_parser, initial_state,
                        inputs_option, parameters_option, single_model)


def add(sub):
    from ..methods import METHODS
    s = command_parser(sub, "simulate",
                       help="integrate the equations of motion; CSV, plot, animation",
                       description="Integrate y = [q, q'] with scipy.integrate.solve_ivp and write "
                       "the time histories as CSV (stdout unless --csv, --plot or --animate is "
                       "given), a plot, and/or an animated GIF of the mechanism. Give negative "
                       "values as --y0=-0.5,0.",
                       example=("python -m lagrgen simulate examples/double_pendulum.py --t-end "
                                "10 --y0 theta1=1.2,theta2=-0.4 --plot run.png --csv run.csv"))
    add_run_options(s)
    s.add_argument("--t-end", type=float, required=True, metavar="T", help="end time")
    s.add_argument("--t-start", type=float, default=0.0, metavar="T0", help="start time (default 0)")
    s.add_argument("--y0", metavar="VALUES",
                   help="initial state: n positions or 2n values q, q' separated by commas, or "
                   "COORD=VALUE,COORD'=VALUE (or COORD_dot=VALUE; the others 0); default the "
                   "model's initial state (model.initial_state), else all zero")
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
    s.set_defaults(run=run)


def run(args):
    from ..simulate import simulate
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
    from ..constraints import consistent_state
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
    from ..outputs import plotting
    from ..simulate import evaluate_outputs
    written = []
    names = model.coordinate_names
    units = model.units if mod is None else mod.units      # the built model's: energies too
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


def write_csv(stream, sol, names, outputs=None, units=None):
    """t, q, q' (as <coordinate>_dot) per saved time; then the multipliers λ of a constrained
    model (M q'' = F + Aᵀλ), one column per constraint name; then the outputs; then, for a model
    with impacts or frictions, a column "transition" naming the switches ("floor:impact", joined
    by ";") on the first row at or after their time (at a switch the result holds the state
    before and after it: the first of the two rows). Headers carry units ('x [m]', 'x_dot [m/s]')."""
    from ..outputs.plotting import rate_unit
    units = dict(units or {})
    for c in names:
        if rate_unit(units.get(c)):
            units[f"{c}_dot"] = rate_unit(units[c])
    out_names = list(outputs.names) if outputs is not None else []
    lam = getattr(sol, "constraint_forces", np.zeros((0, len(sol.t))))
    transitions = sol.transitions if "n_segments" in sol else None     # a hybrid model's
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
