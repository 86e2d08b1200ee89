"""The command line: `python -m lagrgen COMMAND MODEL.py [options]` (and the `lagrgen` script).

Each command is one module of this package, named like the command (`export-fmu`:
`export_fmu.py`), with `add(subparsers)` declaring its options (through
`arguments.command_parser`, so `--help` shows an example) and `run(args)` running it; `COMMANDS`
lists the modules in the order `--help` shows them. A new command is a new module and one line
in `COMMANDS`. The readers of the arguments the commands share are in `arguments.py`.
"""
import argparse
import importlib
import sys

import numpy as np

from ..errors import LagrgenError
from .arguments import check_numeric_options

#: The command modules, in the order `python -m lagrgen --help` lists them.
COMMANDS = (
    "build",
    "export_c",
    "export_fmu",
    "show",
    "modes",
    "stability",
    "simulate",
    "bench",
    "sweep",
    "fit",
    "optimize",
)


def parser():
    """The argument parser: one subparser per module of `COMMANDS`."""
    top = argparse.ArgumentParser(
        prog="python -m lagrgen",
        description="Derive Lagrange's equations of motion, compile them to C, and run them.")
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f".{name}", __name__).add(sub)
    return top


def main(argv=None):
    """Run the command line `argv` (default: sys.argv[1:]); return the exit status."""
    args = parser().parse_args(argv)
    try:
        check_numeric_options(args)
        return args.run(args)
    except BrokenPipeError:
        return closed_pipe()
    except (LagrgenError, ValueError, OSError, np.linalg.LinAlgError) as exc:
        print(f"lagrgen: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("lagrgen: interrupted", file=sys.stderr)
        return 130


def closed_pipe():
    """The reader of stdout went away (`... | head`): end quietly. stdout is pointed at devnull so
    the interpreter's final flush does not complain either."""
    import os
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 0
