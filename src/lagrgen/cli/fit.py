"""`python -m lagrgen fit MODEL.py`: parameters estimated from a measured record (CSV)."""
import sys
import warnings

import numpy as np

from ..errors import LagrgenError
from ..methods import METHODS
from .arguments import (add_common, assignments, build_for, command_parser, initial_state,
                        inputs_option, number, read_record, single_model)


def add(sub):
    f = command_parser(sub, "fit", help="estimate parameters from a measured response",
                       description="Least-squares estimates of the named parameters (and "
                       "initial states y0:<state>) from a CSV record with columns t, then "
                       "coordinates and <coordinate>_dot (as `simulate --csv` writes it), with "
                       "the exact gradient from forward sensitivities; prints the estimates "
                       "with their standard errors. The initial state is the record's first row "
                       "(velocities 0 unless given), --y0 for what the record lacks or to "
                       "replace it; a coordinate with neither is an error. With noisy data, fit "
                       "the initial state too with y0:<state>.",
                       example=("python -m lagrgen fit examples/two_mass_chain.py --model "
                                "two_mass_absolute --data run.csv --params k1,k2,c1,c2 \\\n"
                                "    --bounds k1=0:,k2=0: --weights x1=1,x2=2 --plot fit.png"))
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
    f.add_argument("--bounds", action="append", metavar="NAME=LOW:HIGH,...",
                   help="bounds of fitted names; leave a side empty for none, e.g. k1=0:,c1=0:5")
    f.add_argument("--weights", action="append", metavar="NAME=VALUE,...",
                   help="a weight per measured name (default 1), e.g. to fit x2 twice as "
                   "closely: x2=2")
    f.add_argument("--y0", metavar="VALUES",
                   help="initial state, as for simulate: for coordinates and velocities the "
                   "record lacks, or to replace its first row")
    f.add_argument("--inputs", action="append", metavar="NAME=VALUE,...",
                   help="inputs during the record: numbers or expressions of t (default 0)")
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
    measured = ([m.strip() for m in args.measured.split(",") if m.strip()] if args.measured
                else [n for n in names[1:] if n in model.coordinate_names])
    missing = [m for m in measured if m not in names]
    if missing or not measured:
        raise LagrgenError(f"{args.data} has no column {missing[0] if missing else 'of a coordinate'}"
                           f" (its columns are {', '.join(names)})")
    t = values[:, 0]
    y0 = start_state(args, model, names, values, fitted)
    inputs = inputs_option(args, model) or None
    data = np.array([values[:, names.index(m)] for m in measured])
    initial = {k: number(v, f"--initial {k}") for k, v in assignments(args.initial, "--initial").items()}
    bounds = bounds_option(args.bounds, fitted)
    weights = weights_option(args.weights, measured)
    mod = build_for(model, args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fit(mod, t, data, fitted, y0, measured=measured, initial=initial or None,
                     bounds=bounds or None, weights=weights, method=args.method,
                     rtol=args.rtol, atol=args.atol, inputs=inputs)
    print(f"{model.name}: fit of {', '.join(fitted)} to {', '.join(measured)} "
          f"({data.size} samples, {result.nfev} iterations, rms residual "
          f"{np.sqrt(2 * result.cost / data.size):.3g}{'' if result.success else ', NOT converged'})")
    width = max(len(n) for n in fitted)
    for n in fitted:
        note = ("  (not determined by the data)" if n in result.unidentified else
                "  (on its bound)" if n in result.at_bounds else "")
        print(f"  {n:<{width}} = {result.params[n]:.6g} ± {result.stderr[n]:.2g}{note}")
    for warning in caught:
        print(f"lagrgen: warning: {warning.message}", file=sys.stderr)
    if args.plot:
        from ..outputs.plotting import plot_fit
        fitted_run = fitted_response(mod, model, t, y0, result, measured, args, inputs)
        plot_fit(t, data, fitted_run, measured, args.plot, title=f"{model.name}: fit",
                 units=model.units)
        print(f"plot -> {args.plot}", file=sys.stderr)
    return 0 if result.success else 1


def start_state(args, model, names, values, fitted):
    """The initial state {state: value}: --y0 where it gives a value, else the record's first
    row, velocities 0; LagrgenError for a coordinate that has neither and is not fitted."""
    coordinates = list(model.coordinate_names)
    states = coordinates + [f"{c}_dot" for c in coordinates]
    given = given_states(args.y0, states)
    from_y0 = initial_state(args.y0, model) if args.y0 else np.zeros(len(states))
    y0 = {}
    for i, state in enumerate(states):
        if state in given:
            y0[state] = float(from_y0[i])
        elif state in names:
            y0[state] = float(values[0, names.index(state)])
        elif state in coordinates and f"y0:{state}" not in fitted:
            raise LagrgenError(
                f"{args.data} has no column {state!r} and --y0 does not give its start: give "
                f"--y0 {state}=VALUE, or fit it with --params ...,y0:{state} (and --initial "
                f"y0:{state}=GUESS)")
        else:
            y0[state] = 0.0
    return y0


def given_states(text, states):
    """The state names a --y0 text gives a value: all for a list of numbers, else those named
    (`x'` read as `x_dot`)."""
    if not text:
        return set()
    if "=" not in text:
        return set(states)
    return {name[:-1] + "_dot" if name.endswith("'") else name
            for name in assignments([text], "--y0")}


def bounds_option(texts, fitted):
    """{name: (low, high)} from NAME=LOW:HIGH items (an empty side: no bound)."""
    out = {}
    for name, text in assignments(texts, "--bounds").items():
        if name not in fitted:
            raise LagrgenError(f"--bounds {name}: not one of the fitted names "
                               f"({', '.join(fitted)})")
        low, sep, high = text.partition(":")
        if not sep:
            raise LagrgenError(f"--bounds {name}: expected LOW:HIGH (a side may be empty), "
                               f"got {text!r}")
        out[name] = (number(low, f"--bounds {name} LOW") if low.strip() else -np.inf,
                     number(high, f"--bounds {name} HIGH") if high.strip() else np.inf)
        if not out[name][0] < out[name][1]:
            raise LagrgenError(f"--bounds {name}: LOW must be below HIGH, got {text!r}")
    return out


def weights_option(texts, measured):
    """One weight per measured name (default 1) from NAME=VALUE items, or None."""
    given = assignments(texts, "--weights")
    if not given:
        return None
    unknown = [n for n in given if n not in measured]
    if unknown:
        raise LagrgenError(f"--weights {unknown[0]}: not one of the measured names "
                           f"({', '.join(measured)})")
    weights = [number(given[m], f"--weights {m}") if m in given else 1.0 for m in measured]
    if any(w < 0 for w in weights) or not any(weights):
        raise LagrgenError("--weights: weights must be >= 0, and one at least positive")
    return np.array(weights)


def fitted_response(mod, model, t, y0, result, measured, args, inputs=None):
    """The measured names' histories of the model at the estimates."""
    from ..simulate import evaluate_outputs, simulate
    states = list(model.coordinate_names) + [f"{c}_dot" for c in model.coordinate_names]
    params = {k: v for k, v in result.params.items() if not k.startswith("y0:")}
    start = dict(y0, **{k[3:]: v for k, v in result.params.items() if k.startswith("y0:")})
    sol = simulate(mod, (t[0], t[-1]), start, method=args.method, params=params, t_eval=t,
                   rtol=args.rtol, atol=args.atol, inputs=inputs)
    outputs = evaluate_outputs(mod, sol) if any(m not in states for m in measured) else None
    return np.array([sol.y[states.index(m)] if m in states else outputs[m] for m in measured])
