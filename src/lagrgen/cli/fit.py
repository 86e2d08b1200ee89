"""`python -m lagrgen fit MODEL.py`: parameters estimated from a measured record (CSV)."""
import sys

import numpy as np

from ..errors import LagrgenError
from ..methods import METHODS
from .arguments import (add_common, assignments, build_for, command_parser, number,
                        read_record, single_model)


def add(sub):
    f = command_parser(sub, "fit", help="estimate parameters from a measured response",
                       description="Least-squares estimates of the named parameters (and "
                       "initial states y0:<state>) from a CSV record with columns t, then "
                       "coordinates and <coordinate>_dot (as `simulate --csv` writes it), with "
                       "the exact gradient from forward sensitivities; prints the estimates "
                       "with their standard errors. The initial state is the record's first row "
                       "(velocities 0 unless given): with noisy data, fit it too with y0:<state>.",
                       example=("python -m lagrgen fit examples/two_mass_chain.py --model "
                                "two_mass_absolute --data run.csv --params k1,k2,c1,c2 --plot "
                                "fit.png"))
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
    f.add_argument("--method", choices=METHODS, default="DOP853",
                   help="integration method (default DOP853)")
    f.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance (default 1e-8)")
    f.add_argument("--atol", type=float, default=1e-10, help="absolute tolerance (default 1e-10)")
    f.add_argument("--plot", metavar="OUT.png", help="plot the measured and fitted responses")
    f.set_defaults(run=run)


def run(args):
    from ..fit import fit
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
        from ..outputs.plotting import plot_fit
        fitted_run = fitted_response(mod, model, t, y0, result, measured, args)
        plot_fit(t, data, fitted_run, measured, args.plot, title=f"{model.name}: fit",
                 units=model.units)
        print(f"plot -> {args.plot}", file=sys.stderr)
    return 0 if result.success else 1


def fitted_response(mod, model, t, y0, result, measured, args):
    """The measured names' histories of the model at the estimates."""
    from ..simulate import simulate
    states = list(model.coordinate_names) + [f"{c}_dot" for c in model.coordinate_names]
    params = {k: v for k, v in result.params.items() if not k.startswith("y0:")}
    start = dict(y0, **{k[3:]: v for k, v in result.params.items() if k.startswith("y0:")})
    sol = simulate(mod, (t[0], t[-1]), start, method=args.method, params=params, t_eval=t,
                   rtol=args.rtol, atol=args.atol)
    return np.array([sol.y[states.index(m)] for m in measured])
