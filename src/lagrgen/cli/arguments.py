"""What the commands share: declaring a command and its common options, and reading the
arguments (model files, NAME=VALUE items, numbers, parameters, inputs, initial states, sweep
ranges, CSV records).

A command is a module of this package with `add(subparsers)`, which declares its parser
through `command_parser` (so its `--help` ends with an example), and `run(args)`, which returns
the exit status; `lagrgen.cli.COMMANDS` lists the modules. A reader raises LagrgenError with a message
that names the option, which `main` prints as one line.
"""
import argparse
import csv
import runpy
import sys
from pathlib import Path

import numpy as np

from ..errors import LagrgenError


# -- declaring a command -----------------------------------------------------------------------
class ExampleFormatter(argparse.HelpFormatter):
    """argparse's formatter, except that an epilog starting with "example" keeps its lines."""

    def _fill_text(self, text, width, indent):
        if text.startswith("example"):
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


def command_parser(subparsers, name, help, description, example):
    """The parser of the command `name`, whose `--help` ends with `example`: a command line (a
    long one continued by " \\" and a newline), or a tuple of them, shown as written."""
    examples = (example,) if isinstance(example, str) else tuple(example)
    lines = [line for text in examples for line in text.strip().splitlines()]
    epilog = ("examples:\n" if len(examples) > 1 else "example:\n") + \
        "\n".join(f"  {line}" for line in lines)
    return subparsers.add_parser(name, help=help, description=description, epilog=epilog,
                                 formatter_class=ExampleFormatter)


def add_model_file(parser):
    parser.add_argument("model_file", help="a Python file that defines lagrgen.Model objects, "
                        "or a robot's URDF file (.urdf)")
    parser.add_argument("--model", action="append",
                        help="only the model of this name (may be repeated; default: all)")
    parser.add_argument("--base", choices=("fixed", "floating", "free"), default="fixed",
                        help="a URDF file's root link: fixed (default), floating (six "
                        "coordinates base_x … base_yaw, singular at pitch ±π/2) or free (a "
                        "quaternion: base_x … base_qw, no singularity)")
    parser.add_argument("--no-joint-dynamics", dest="joint_dynamics", action="store_false",
                        help="a URDF file: leave out its joints' <dynamics> damping and friction")
    parser.add_argument("--no-check-inertias", dest="check_inertias", action="store_false",
                        help="a URDF file: take an inertia no mass distribution has (not positive "
                        "semi-definite, or breaking the triangle inequality) as it is, with a "
                        "warning")
    parser.add_argument("--no-mimic", dest="mimic", action="store_false",
                        help="a URDF file: read <mimic> joints as independent joints")
    parser.add_argument("--massless", choices=("error", "fixed"), default="error",
                        help="a URDF file's joints that move no mass: an error (default) or held "
                        "fixed at 0")


def add_common(parser):
    add_model_file(parser)
    parser.add_argument("--out", default="generated", help="output directory (default: generated)")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    parser.add_argument("--verbose", action="store_true",
                        help="report each build step's time, code size and compiler flags")


def add_run_options(parser):
    """Options shared by the commands that run a model: backend, parameters, inputs."""
    add_common(parser)
    parser.add_argument("--backend", choices=("c", "python"), default="c",
                        help="compiled C (default, cached in --out) or pure Python")
    parser.add_argument("--params", action="append", metavar="NAME=VALUE,...",
                        help="parameter values (others keep their defaults); repeat the flag or "
                        "separate items with ';' or ','")


# -- numeric options ---------------------------------------------------------------------------
#: The run options a command may take (its attribute, its flag, the rule of lagrgen.options).
NUMERIC_OPTIONS = (("rtol", "--rtol", "relative_tolerance"),
                   ("atol", "--atol", "absolute_tolerance"),
                   ("max_step", "--max-step", "max_step"),
                   ("max_steps", "--max-steps", "count"),
                   ("max_time", "--max-time", "seconds"))


def check_numeric_options(args):
    """LagrgenError naming the flag when a numeric run option is out of its range: the rules of
    `lagrgen.options`, which `simulate`, ensembles and the FMU's settings apply too."""
    from .. import options
    for attribute, flag, rule in NUMERIC_OPTIONS:
        value = getattr(args, attribute, None)
        if value is None:
            continue
        try:
            if rule == "max_step":
                options.max_step(value)
            else:
                getattr(options, rule)(value, flag)
        except ValueError as exc:
            text = str(exc)
            raise LagrgenError(text if text.startswith(flag) else f"{flag}: {text}") from None


# -- model files -------------------------------------------------------------------------------
def run_file(path, what):
    """The top-level namespace of the Python file `path` (a `what` file: "model", "problem"), run
    with its own directory on sys.path; a missing file or a syntax error is one LagrgenError."""
    path = Path(path)
    if not path.is_file():
        raise LagrgenError(f"no {what} file {str(path)!r}")
    sys.path.insert(0, str(path.resolve().parent))
    try:
        return runpy.run_path(str(path), run_name=f"lagrgen_{what}_file_{path.stem}")
    except SyntaxError as exc:
        raise LagrgenError(f"{exc.filename}, line {exc.lineno}: {exc.msg}") from None
    except LagrgenError:
        raise
    except Exception as exc:                        # noqa: BLE001 — the user's code, said in one line
        raise LagrgenError(f"{path}{_line_in(exc, path)}: the {what} file raised "
                           f"{type(exc).__name__}: {exc}") from None
    finally:
        sys.path.pop(0)


def _line_in(exc, path):
    """", line N" of the last frame of `exc`'s traceback in the file `path`, else ""."""
    import traceback
    lines = [frame.lineno for frame in traceback.extract_tb(exc.__traceback__)
             if Path(frame.filename).resolve() == path.resolve()]
    return f", line {lines[-1]}" if lines else ""


def is_urdf(path):
    """True for a robot's URDF file (by its suffix)."""
    return Path(path).suffix.lower() == ".urdf"


#: The flag of each from_urdf option a URDFError may suggest: {(option, value): flag}.
URDF_FLAGS = {("check_inertias", False): "--no-check-inertias", ("mimic", False): "--no-mimic",
              ("massless", "fixed"): "--massless fixed", ("base", "floating"): "--base floating"}


def urdf_options(args):
    """The from_urdf options of a command's arguments (`add_model_file`)."""
    return {"base": getattr(args, "base", "fixed"),
            "joint_dynamics": getattr(args, "joint_dynamics", True),
            "check_inertias": getattr(args, "check_inertias", True),
            "mimic": getattr(args, "mimic", True),
            "massless": getattr(args, "massless", "error")}


def read_urdf(path, reader, **options):
    """`reader(path, **options)` (from_urdf, or urdf.read), its URDFError's suggestion of a
    from_urdf option spelled as the command line's flag."""
    from ..urdf import URDFError, suggestion
    if not Path(path).is_file():
        raise LagrgenError(f"no URDF file {str(path)!r}")
    try:
        return reader(path, **options)
    except URDFError as exc:
        if exc.option not in URDF_FLAGS:
            raise
        raise URDFError(str(exc).replace(suggestion(*exc.option), URDF_FLAGS[exc.option]),
                        exc.option) from None


def models_in(path, names=None, urdf=None):
    """The Model objects defined at top level of the model file `path` (optionally by name), or
    the robot of a URDF file (`lagrgen.from_urdf` with the options `urdf`)."""
    from ..model import Model
    if is_urdf(path):
        from ..urdf import from_urdf
        found = [read_urdf(path, from_urdf, **(urdf or {}))]
    else:
        namespace = run_file(path, "model")
        found, seen = [], set()
        for value in namespace.values():
            if isinstance(value, Model) and id(value) not in seen:
                seen.add(id(value))
                found.append(value)
    if not found:
        raise LagrgenError(
            f"{path} defines no lagrgen.Model at top level: a model file must create one, "
            "e.g. `model = Model('my_system')`")
    all_names = [m.name for m in found]
    twice = sorted({n for n in all_names if all_names.count(n) > 1})
    if twice:
        raise LagrgenError(f"{path} defines more than one model named {', '.join(twice)}: "
                           "model names name compiled modules, so each must be unique")
    if names:
        missing = sorted(set(names) - set(all_names))
        if missing:
            raise LagrgenError(f"{path} defines no model named {', '.join(missing)}; "
                               f"it defines {', '.join(all_names)}")
        found = [m for m in found if m.name in names]
    return found


def single_model(args):
    models = models_in(args.model_file, args.model, urdf_options(args))
    if len(models) > 1:
        raise LagrgenError(f"{args.model_file} defines several models "
                           f"({', '.join(m.name for m in models)}): choose one with --model NAME")
    return models[0]


def build_for(model, args):
    """The built model for the chosen --backend (C builds are cached in --out)."""
    from ..build import build
    if args.backend == "python":
        return build(model, backend="python")
    return build(model, out_dir=args.out, verbose=args.verbose, quiet=args.quiet)


# -- NAME=VALUE items and numbers --------------------------------------------------------------
def split_items(text):
    """The NAME=VALUE items of one option value: separated by ';', or by ',' outside brackets, so
    `F=Max(0,t-0.5);G=1` and `a=1,b=2` both work."""
    items, depth, current = [], 0, []
    for ch in text:
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth = max(depth - 1, 0)
        if ch == ";" or (ch == "," and depth == 0):
            items.append("".join(current))
            current = []
        else:
            current.append(ch)
    items.append("".join(current))
    return items


def assignments(texts, what):
    """{name: text} from ["a=1,b=2", "c=Max(0,t);d=3"] (the values of a repeatable NAME=VALUE
    option: items separated by ';' or by commas outside brackets)."""
    out = {}
    for text in texts or ():
        for item in split_items(text):
            if not item.strip():
                continue
            name, sep, value = item.partition("=")
            if not sep or not name.strip() or not value.strip():
                raise LagrgenError(f"{what}: expected NAME=VALUE, got {item.strip()!r}")
            out[name.strip()] = value.strip()
    return out


def number(text, what):
    """The value of a number or a constant expression such as `2*pi` (restricted reader)."""
    from ..expressions import ExpressionError, parse_number
    try:
        return parse_number(text)
    except ExpressionError as exc:
        raise LagrgenError(f"{what}: {exc}") from None


def known_names(values, option, model, what, names):
    """`values` (a dict), after checking each key is one of the model's `names` (its `what`s)."""
    from ..runtime.arguments import unknown_name
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise LagrgenError(f"{option}: {unknown_name(what, unknown[0], names)}")
    return values


# -- parameters, inputs, initial states --------------------------------------------------------
def parameters_option(args, model):
    """The --params values as a dict name -> float, checked against the model's parameters."""
    values = {k: number(v, f"--params {k}") for k, v in assignments(args.params, "--params").items()}
    return known_names(values, "--params", model, "parameter", model.parameter_names)


def input_value(name, text):
    """A constant, or a function of t, from an expression such as `0.5*sin(2*t)`."""
    from ..expressions import ExpressionError, parse_time_function
    try:
        return parse_time_function(text)
    except ExpressionError as exc:
        raise LagrgenError(f"--inputs {name}: {exc}") from None


def inputs_option(args, model, constant=False):
    """The --inputs values: name -> constant or function of t (constants only if `constant`)."""
    values = known_names(assignments(args.inputs, "--inputs"), "--inputs", model, "input",
                         model.input_names)
    out = {name: input_value(name, text) for name, text in values.items()}
    varying = [name for name, v in out.items() if callable(v)]
    if constant and varying:
        raise LagrgenError(f"--inputs {varying[0]}: the operating point needs a constant value")
    return out


def initial_state(text, model):
    """y0 = [q0, q̇0] from "v1,v2,..." (n or 2n numbers) or "name=v,name'=v,..." (others 0);
    without text, the model's initial state (`model.initial_state`, else zeros)."""
    names = model.coordinate_names
    n = len(names)
    if not text:
        return np.array(model.initial_values or [0.0] * (2 * n), dtype=float)
    y0 = np.zeros(2 * n)
    if "=" not in text:
        values = [number(v, "--y0") for v in text.split(",") if v.strip()]
        if len(values) not in (n, 2 * n):
            raise LagrgenError(f"--y0: expected {n} positions or {2 * n} values [q, q'] for the "
                               f"coordinates {', '.join(names)}, got {len(values)}")
        y0[:len(values)] = values
        return y0
    slots = {c: i for i, c in enumerate(names)}
    for i, c in enumerate(names):
        slots.setdefault(f"{c}'", n + i)
        slots.setdefault(f"{c}_dot", n + i)
    for name, value in assignments([text], "--y0").items():
        if name not in slots:
            raise LagrgenError(f"--y0: {name!r} is not a coordinate or a velocity (use "
                               f"{names[0]}=... and {names[0]}'=... or {names[0]}_dot=...)")
        y0[slots[name]] = number(value, f"--y0 {name}")
    return y0


# -- sweep ranges ------------------------------------------------------------------------------
def sweep_range(text, option="--param"):
    """(name, values) from NAME=START:STOP:N (the value of `option`), N at most
    `lagrgen.sweep.MAX_SWEEP_VALUES`."""
    from ..sweep import MAX_SWEEP_VALUES
    name, sep, spec = text.partition("=")
    parts = spec.split(":")
    if not sep or len(parts) != 3 or not name.strip().isidentifier():
        raise LagrgenError(f"{option}: expected NAME=START:STOP:N, got {text[:80]!r}")
    start, stop = number(parts[0], f"{option} START"), number(parts[1], f"{option} STOP")
    count = parts[2].strip()
    if not (count.isdigit() and len(count) <= 9 and 1 <= int(count) <= MAX_SWEEP_VALUES):
        raise LagrgenError(f"{option}: N must be a whole number from 1 to {MAX_SWEEP_VALUES}, "
                           f"got {count[:20]!r}{'...' if len(count) > 20 else ''}")
    return name.strip(), np.linspace(start, stop, int(count))


# -- CSV records -------------------------------------------------------------------------------
def read_record(path):
    """(column names without their units, values (rows, columns)) of a CSV with a header row,
    as `simulate --csv` writes it (t first); UTF-8, with or without a byte-order mark. A field
    longer than the csv module's limit, or bytes that are not UTF-8, are one-line errors."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as stream:
            reader = csv.reader(stream)
            try:
                rows = list(reader)
            except csv.Error as exc:
                raise LagrgenError(f"{path}, line {reader.line_num}: not a CSV record of numbers "
                                   f"({exc})") from None
    except UnicodeDecodeError as exc:
        raise LagrgenError(f"{path}: not a UTF-8 text file (byte {exc.start}: "
                           f"{exc.reason})") from None
    except OSError as exc:
        raise LagrgenError(f"cannot read the record {path}: {exc.strerror or exc}") from None
    if len(rows) < 3:
        raise LagrgenError(f"{path}: a header row and at least two rows of samples are needed")
    names = [cell.split(" [")[0].strip() for cell in rows[0]]
    try:
        values = np.array([[float(v) for v in row] for row in rows[1:] if row], dtype=float)
    except ValueError as exc:
        raise LagrgenError(f"{path}: every sample must be a number ({str(exc)[:80]})") from None
    if values.ndim != 2 or values.shape[1] != len(names):
        raise LagrgenError(f"{path}: every row must have {len(names)} values like the header")
    return names, values


def column(name, units):
    """A CSV header: 'x [m]' when the name has a unit, else the name."""
    unit = (units or {}).get(name)
    return f"{name} [{unit}]" if unit else name
