"""`python -m lagrgen stability MODEL.py --sweep NAME=a:b:n`: the eigenvalues of the
linearization across a parameter, where stability changes, and the root locus."""
import numpy as np

from ..errors import LagrgenError
from .arguments import (add_run_options, assignments, build_for, command_parser, known_names,
                        number, parameters_option, single_model, sweep_range)


def add(sub):
    s = command_parser(
        sub, "stability", help="eigenvalues across a swept parameter: stability boundaries",
        description="Linearize the model at each value of --sweep NAME=START:STOP:N (a "
        "parameter, or a name the --qd0 expressions use, such as a forward speed) and follow "
        "each eigenvalue by continuity. The operating point is the equilibrium at rest near "
        "--at, or, with --qd0, the configuration --at moving with the rates --qd0 (expressions "
        "of the swept name and the parameters; a constrained model's other rates follow from "
        "its constraints). Prints where a branch's real part changes sign.",
        example="python -m lagrgen stability examples/rolling_disk.py --sweep v=0.2:3:57 \\\n"
                "    --qd0 int_spin=v/r --plot root_locus.png")
    add_run_options(s)
    s.add_argument("--sweep", required=True, metavar="NAME=START:STOP:N", help="what to sweep")
    s.add_argument("--at", action="append", metavar="COORD=VALUE,...",
                   help="the configuration (with --qd0) or the guess of the equilibrium "
                   "(unnamed coordinates: 0)")
    s.add_argument("--qd0", action="append", metavar="COORD=EXPR,...",
                   help="rates of a steady motion, e.g. int_spin=v/r (default: at rest)")
    s.add_argument("--plot", metavar="OUT.png", help="draw the root locus to this image")
    s.add_argument("--csv", metavar="OUT.csv",
                   help="write value, stable and the real and imaginary part of each branch")
    s.set_defaults(run=run)


def run(args):
    from ..stability import eigenvalue_sweep
    model = single_model(args)
    name, values = sweep_range(args.sweep, "--sweep")
    if len(values) < 2:
        raise LagrgenError("--sweep: N must be at least 2")
    params = parameters_option(args, model)
    coordinates = model.coordinate_names
    at = known_names({c: number(v, f"--at {c}") for c, v in assignments(args.at, "--at").items()},
                     "--at", model, "coordinate", coordinates)
    rates = known_names(assignments(args.qd0, "--qd0"), "--qd0", model, "coordinate",
                        coordinates)
    if name not in model.parameter_names and not rates:
        raise LagrgenError(f"--sweep {name}: not a parameter of {model.name!r} (its parameters "
                           f"are {', '.join(model.parameter_names)}) and no --qd0 uses it")
    mod = build_for(model, args)
    point = operating_point(mod, model, name, params, [at.get(c, 0.0) for c in coordinates],
                            rates)
    result = eigenvalue_sweep(mod, values, point, label=name)
    if not args.quiet:
        print(report(model, name, result))
    if args.csv:
        write_csv(args.csv, name, result)
        if not args.quiet:
            print(f"table -> {args.csv}")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        ax = result.plot()
        ax[0].set_title(f"{model.name}: eigenvalues against {name} (shaded: stable)")
        plt.savefig(args.plot, dpi=110, bbox_inches="tight")
        plt.close(ax[0].figure)
        if not args.quiet:
            print(f"root locus -> {args.plot}")
    return 0


def operating_point(mod, model, name, params, q_at, rate_texts):
    """value -> (q0, qd0, p): the equilibrium at rest near q_at (continued from the previous
    value), or q_at with the rates `rate_texts` evaluated at the value."""
    from ..expressions import ExpressionError, parse_time_function
    from ..vibration import equilibrium
    defaults = dict(zip(model.parameter_names, model.parameter_defaults))
    last = {"q": np.asarray(q_at, dtype=float)}

    def parameters(value):
        p = {**{k: v for k, v in defaults.items() if v is not None}, **params}
        if name in model.parameter_names:
            p[name] = value
        return p

    def rates_at(value, p):
        names = {**p, name: value}
        qd = {}
        for c, text in rate_texts.items():
            try:
                v = parse_time_function(text, names)
            except ExpressionError as exc:
                raise LagrgenError(f"--qd0 {c}: {exc}") from None
            if callable(v):
                raise LagrgenError(f"--qd0 {c}: a rate of the operating point cannot depend on t")
            qd[c] = v
        return qd

    def point(value):
        p = parameters(value)
        if not rate_texts:
            last["q"] = equilibrium(mod, last["q"], p=p)
            return last["q"], None, p
        return last["q"], steady_rates(mod, last["q"], rates_at(value, p), p), p
    return point


def steady_rates(mod, q0, given, p):
    """q̇0 with the `given` rates (by coordinate name); a constrained model's other rates solved
    from A·q̇ + b = 0 (least change), the given ones kept."""
    from ..constraints import velocity_terms
    from ..runtime.arguments import parameters_from
    names = list(mod.coordinates)
    qd = np.zeros(len(names))
    for c, v in given.items():
        qd[names.index(c)] = v
    if not mod.n_constraints:
        return qd
    _, A, b = velocity_terms(mod, 0.0, np.asarray(q0, dtype=float), parameters_from(mod, p))
    free = [j for j, c in enumerate(names) if c not in given]
    fixed = [j for j, c in enumerate(names) if c in given]
    target = -(A[:, fixed] @ qd[fixed] + b)
    if free:
        qd[free] = np.linalg.lstsq(A[:, free], target, rcond=None)[0]
    residual = A @ qd + b
    if np.abs(residual).max(initial=0.0) > 1e-9 * max(1.0, np.abs(qd).max()):
        raise LagrgenError(f"--qd0: the rates given ({', '.join(given)}) violate the constraints "
                           f"of {mod.name!r} whatever the other rates are; give fewer rates")
    return qd


def report(model, name, result):
    """The crossings (a complex pair's on one line), then a line per value: stable or not, the
    largest real part and the frequency of its root."""
    lines = [f"{model.name}: {len(result.states)} states ({', '.join(result.states)})"]
    crossings = [c for c in result.crossings() if c.pair is None or c.branch < c.pair]
    for c in crossings:
        if c.pair is None:
            lines.append(f"  {name} = {c.value:.10g}: branch {c.branch} (a real root) {c.kind}")
        else:
            lines.append(f"  {name} = {c.value:.10g}: branches {c.branch} and {c.pair} (a complex "
                         f"pair: Hopf) {c.kind}")
    if not crossings:
        lines.append("  no eigenvalue crosses the imaginary axis in this range")
    lines.append(f"{name:>14}  {'stable':>6}  {'max Re s':>12}  {'|Im s| of it':>12}")
    for v, s, stable in zip(result.values, result.leading_roots(), result.stable):
        lines.append(f"{v:>14.6g}  {'yes' if stable else 'no':>6}  {s.real:>12.5g}  "
                     f"{abs(s.imag):>12.5g}")
    return "\n".join(lines)


def write_csv(path, name, result):
    header = [name, "stable"] + [f"{part}_{b}" for b in range(result.eigenvalues.shape[1])
                                 for part in ("re", "im")]
    with open(path, "w") as stream:
        stream.write(",".join(header) + "\n")
        for v, row, stable in zip(result.values, result.eigenvalues, result.stable):
            cells = [repr(float(v)), str(int(stable))]
            cells += [repr(float(x)) for s in row for x in (s.real, s.imag)]
            stream.write(",".join(cells) + "\n")
