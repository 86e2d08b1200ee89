"""`python -m lagrgen sweep MODEL.py`: a steady-state measure against a swept parameter."""
import csv
import sys

import numpy as np

from ..errors import LagrgenError
from .arguments import (add_run_options, assignments, build_for, command_parser, initial_state,
                        known_names, parameters_option, single_model, sweep_range)


def add(sub):
    from ..methods import MEASURES, METHODS
    s = command_parser(sub, "sweep", help="a steady-state measure against a swept parameter",
                       description="Run the model once per value of --param NAME=START:STOP:N "
                       "(a parameter, or a name the --input expressions use, such as a forcing "
                       "frequency) and report the steady-state --measure of each coordinate over "
                       "the last part of each run, as CSV and/or a plot.",
                       example="python -m lagrgen sweep examples/duffing.py --param w=0.5:2:60 "
                       "--input 'F=A*sin(w*t)' \\\n    --t-end 150 --linear 0.3 --plot sweep.png")
    add_run_options(s)
    s.add_argument("--param", required=True, metavar="NAME=START:STOP:N", help="what to sweep")
    s.add_argument("--input", action="append", metavar="NAME=EXPR",
                   help="an input as an expression of t, the swept name and the parameters, "
                   "e.g. F=A*sin(w*t)")
    s.add_argument("--t-end", type=float, required=True, metavar="T", help="end time of each run")
    s.add_argument("--y0", metavar="VALUES", help="initial state, as for simulate (default: the "
                   "model's initial state, else 0)")
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
    s.set_defaults(run=run)


def run(args):
    from ..sweep import sweep
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
        from ..outputs.plotting import plot_sweep
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


def sweep_inputs(texts, model, swept, params):
    """inputs as a function of the swept value: each --input NAME=EXPR may use t, the swept
    name and the model's parameters (their values for the run)."""
    from ..expressions import ExpressionError, parse_time_function
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


def linear_amplitudes(mod, model, args, omegas):
    """AMPLITUDE·|H(ω)| of each coordinate to the one --input, about the equilibrium near 0."""
    from ..vibration import equilibrium, frequency_response
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
