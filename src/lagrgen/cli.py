"""The command line: `python -m lagrgen COMMAND MODEL.py [options]`."""
import argparse
import runpy
import sys
from pathlib import Path

from .errors import LagrgenError
from .model import Model


def models_in(path, names=None):
    """The Model objects defined at top level of the model file `path` (optionally by name)."""
    path = Path(path)
    if not path.is_file():
        raise LagrgenError(f"no model file {str(path)!r}")
    sys.path.insert(0, str(path.resolve().parent))
    try:
        namespace = runpy.run_path(str(path), run_name=f"lagrgen_model_file_{path.stem}")
    finally:
        sys.path.pop(0)
    found, seen = [], set()
    for value in namespace.values():
        if isinstance(value, Model) and id(value) not in seen:
            seen.add(id(value))
            found.append(value)
    if names:
        found = [m for m in found if m.name in names]
        missing = set(names) - {m.name for m in found}
        if missing:
            raise LagrgenError(f"{path} defines no model named {', '.join(sorted(missing))}")
    if not found:
        raise LagrgenError(
            f"{path} defines no lagrgen.Model at top level: a model file must create one, "
            "e.g. `model = Model('my_system')`")
    return found


def command_build(args):
    from .backends import build
    for model in models_in(args.model_file, args.model):
        module = build(model, out_dir=args.out, verbose=args.verbose, force=args.force)
        info = module.build_info
        state = "cached" if info["cache_hit"] else "built"
        if not args.quiet:
            print(f"{model.name}: {state} in {info['seconds']:.2f} s -> {args.out}/")
    return 0


def add_common(parser):
    parser.add_argument("model_file", help="a Python file that defines lagrgen.Model objects")
    parser.add_argument("--model", action="append",
                        help="only the model of this name (may be repeated; default: all)")
    parser.add_argument("--out", default="generated", help="output directory (default: generated)")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    parser.add_argument("--verbose", action="store_true",
                        help="report each build step's time, code size and compiler flags")


def parser():
    top = argparse.ArgumentParser(
        prog="python -m lagrgen",
        description="Derive Lagrange's equations of motion and compile them to C.")
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")
    b = sub.add_parser("build", help="build every model in a model file (C backend, cached)",
                       description="Derive, generate C, compile and cache every model in MODEL.py.")
    add_common(b)
    b.add_argument("--force", action="store_true", help="rebuild even if a cached build matches")
    b.set_defaults(run=command_build)
    return top


def main(argv=None):
    args = parser().parse_args(argv)
    try:
        return args.run(args)
    except LagrgenError as exc:
        print(f"lagrgen: error: {exc}", file=sys.stderr)
        return 1
