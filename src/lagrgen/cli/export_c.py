"""`python -m lagrgen export-c MODEL.py`: each model as plain C (`<name>_model.h`, `.c`)."""
from .arguments import add_model_file, command_parser, models_in, urdf_options


def add(sub):
    e = command_parser(sub, "export-c", help="write a model as plain C (<name>_model.h and .c)",
                       description="Write each model of MODEL.py as a standalone C model: "
                       "<name>_model.h and <name>_model.c, which include only <math.h> and "
                       "<string.h> and need no Python (compile with any C99 compiler, link -lm).",
                       example=("python -m lagrgen export-c examples/double_pendulum.py --out "
                                "build_c"))
    add_model_file(e)
    e.add_argument("--out", default=".", help="output directory (default: the current one)")
    e.add_argument("--quiet", action="store_true", help="print nothing but errors")
    e.set_defaults(run=run)


def run(args):
    from ..build import export_c
    for model in models_in(args.model_file, args.model, urdf_options(args)):
        paths = export_c(model, args.out)
        if not args.quiet:
            print(f"{model.name}: wrote {', '.join(str(p) for p in paths)}")
    return 0
