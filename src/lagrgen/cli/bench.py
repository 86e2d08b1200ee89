"""`python -m lagrgen bench MODEL.py`: the compiled and pure-Python paths timed, as a table."""
from pathlib import Path

from ..errors import LagrgenError
from ..methods import BENCH_METHODS
from .arguments import (add_model_file, command_parser, initial_state, models_in,
                        urdf_options)


def add(sub):
    b = command_parser(
        sub, "bench",
        help="time the compiled and pure-Python paths of each model (a markdown table)",
        description="Cold and cached build, rhs and jacobian per call (from Python and inside "
                    "C), and solve_ivp wall time with nfev/njev/nlu, on lagrgen's C and Python "
                    "paths.",
        example="python -m lagrgen bench examples/double_pendulum.py --methods RK45 Radau "
                "--output bench.md")
    add_model_file(b)
    b.add_argument("--y0", metavar="VALUES", help="initial state (default: the model's initial "
                   "state, else every q = 0.1, q' = 0)")
    b.add_argument("--t-end", type=float, default=10.0, help="end time of the solve (default 10)")
    b.add_argument("--methods", nargs="+", metavar="METHOD",
                   help=f"solve_ivp methods (default: {' '.join(BENCH_METHODS)})")
    b.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance (default 1e-8)")
    b.add_argument("--atol", type=float, default=1e-8, help="absolute tolerance (default 1e-8)")
    b.add_argument("--repeats", type=int, default=3, help="repeats per figure (default 3)")
    b.add_argument("--output", metavar="FILE.md", help="also write the table to this file")
    b.set_defaults(run=run)


def run(args):
    from ..bench import bench_model, markdown
    methods = args.methods or BENCH_METHODS
    unknown = [m for m in methods if m not in BENCH_METHODS]
    if unknown:
        raise LagrgenError(f"--methods: unknown method {unknown[0]!r} (use {', '.join(BENCH_METHODS)})")
    reports = []
    for model in models_in(args.model_file, args.model, urdf_options(args)):
        def fresh(name=model.name):
            return models_in(args.model_file, [name], urdf_options(args))[0]
        y0 = initial_state(args.y0, model) if args.y0 or model.initial_values else None
        if y0 is not None and model.constraint_names:
            from ..build import build
            from ..constraints import consistent_state
            y0 = consistent_state(build(model, backend="python"), y0, 0.0)
        result = bench_model(fresh, y0=y0, methods=methods, t_span=(0.0, args.t_end),
                             rtol=args.rtol, atol=args.atol, repeats=args.repeats)
        reports.append(markdown(result))
        print(reports[-1], flush=True)
    if args.output:
        Path(args.output).write_text("\n".join(reports))
    return 0
