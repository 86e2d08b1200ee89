"""`python -m lagrgen build MODEL.py`: derive, generate C, compile and cache every model."""
from .arguments import add_common, command_parser, models_in, urdf_options


def add(sub):
    b = command_parser(sub, "build", help="build every model in a model file (C backend, cached)",
                       description="Derive, generate C, compile and cache every model in MODEL.py.",
                       example=("python -m lagrgen build examples/double_pendulum.py --out "
                                "generated"))
    add_common(b)
    b.add_argument("--force", action="store_true", help="rebuild even if a cached build matches")
    b.set_defaults(run=run)


def run(args):
    from ..build import build
    for model in models_in(args.model_file, args.model, urdf_options(args)):
        module = build(model, out_dir=args.out, verbose=args.verbose, quiet=args.quiet,
                       force=args.force)
        info = module.build_info
        state = "cached" if info["cache_hit"] else "built"
        if not args.quiet:
            print(f"{model.name}: {state} in {info['seconds']:.2f} s, {module.formulation} "
                  f"formulation -> {args.out}/")
    return 0
