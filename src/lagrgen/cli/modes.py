"""`python -m lagrgen modes MODEL.py`: equilibrium, natural frequencies, damping ratios and mode
shapes."""
import sys
from pathlib import Path

import numpy as np

from .arguments import (add_run_options, assignments, build_for, column, command_parser,
                        inputs_option, known_names, models_in, number, parameters_option,
                        urdf_options)


def add(sub):
    m = command_parser(sub, "modes", help="natural frequencies, damping ratios and mode shapes",
                       description="Find the static equilibrium near --at (default: all "
                       "coordinates zero), linearize there and print the natural frequencies "
                       "(rad/s and Hz), damping ratios and mass-normalized mode shapes.",
                       example=("python -m lagrgen modes examples/double_pendulum.py --params "
                                "L1=0.8,L2=0.8 --plot modes.png"))
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
    m.set_defaults(run=run)


def run(args):
    from ..outputs.plotting import plot_modes
    import warnings
    from ..errors import MassMatrixError
    from ..vibration import FrozenTimeWarning, equilibrium, modes
    models = models_in(args.model_file, args.model, urdf_options(args))
    for k, model in enumerate(models):
        params = parameters_option(args, model)
        inputs = inputs_option(args, model, constant=True)
        at = known_names({c: number(v, f"--at {c}") for c, v in assignments(args.at, "--at").items()},
                         "--at", model, "coordinate", model.coordinate_names)
        mod = build_for(model, args)
        declared = np.asarray(mod.initial_state, dtype=float)
        start = declared[:mod.n_coordinates] if declared.size else np.zeros(mod.n_coordinates)
        guess = [at.get(c, start[i]) for i, c in enumerate(model.coordinate_names)]
        u = inputs or None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FrozenTimeWarning)
            try:
                q0 = equilibrium(mod, guess, p=params, u=u, t=args.t)
            except MassMatrixError as exc:
                raise MassMatrixError(f"{exc} (the search starts from the model's initial state, "
                                      "else zeros: give a start with --at NAME=VALUE)") from None
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


def modes_table(model, q0, result):
    """The operating point, then one row per mode: ω (rad/s), f (Hz), ζ; whether it is stable;
    then the mode shapes."""
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
            lam = np.real(result.omega_squared[i])
            lines.append(f"{i + 1:>4}  {'unstable':>14}  {'':>12}  {'':>13}  (omega^2 = {lam:.6g})")
    lines.append("stable" if result.stable else
                 f"unstable: an eigenvalue has real part {result.eigenvalues.real.max():.6g} > 0")
    rows = [column(c, units) for c in names]
    width = max(len(r) for r in rows)
    complex_shapes = np.iscomplexobj(result.shapes)
    scaling = ("largest entry 1, magnitude@phase in degrees" if complex_shapes else
               "mass-normalized" if result.kind == "classical" else "largest entry 1")
    lines.append(f"mode shapes ({scaling}, one column per mode):")
    for j, r in enumerate(rows):
        cells = [f"{abs(v):>7.4g}@{np.degrees(np.angle(v)):>5.0f}" if complex_shapes
                 else f"{np.real(v):>10.5g}" for v in result.shapes[j]]
        lines.append(f"{r:>{width}}  " + "  ".join(cells))
    return "\n".join(lines)
