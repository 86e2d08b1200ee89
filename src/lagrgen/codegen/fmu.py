"""FMI 2.0 Model Exchange export: the standalone C model, an FMI glue file, modelDescription.xml,
compiled and zipped into `<name>.fmu`.

The FMU's continuous states are x = [q, q̇] with ẋ = rhs(t, x, p, u); `providesDirectionalDerivative`
is backed by the analytic Jacobian ∂ẋ/∂x and by ∂ẋ/∂u = [0; M⁻¹·∂F/∂u].
"""
import io
import math
import platform
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path
from string import Template
from xml.etree import ElementTree as ET

from .._version import __version__
from ..errors import BuildError, CompileError, ModelError
from .c_model import TEMPLATES, read_template, standalone_files, substitutions

FMI_HEADERS = TEMPLATES / "fmi2"
HEADER_FILES = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
FMU_CFLAGS = ("-shared", "-fPIC", "-O2", "-fno-math-errno", "-std=gnu11", "-fvisibility=hidden")


def platform_folder():
    """(binaries folder, shared library suffix) of this platform in FMI 2.0's naming."""
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
    system = platform.system()
    names = {"Linux": ("linux", ".so"), "Darwin": ("darwin", ".dylib"), "Windows": ("win", ".dll")}
    if system not in names:
        raise BuildError(f"FMI 2.0 names no binaries folder for the platform {system!r}")
    folder, suffix = names[system]
    return folder + bits, suffix


def variable_names(info):
    """The FMU's variable names in value-reference order: q, q̇ (`<q>_dot`), der(q), der(q̇),
    parameters, inputs; ModelError if two coincide."""
    q = info["coordinates"]
    qd = [f"{c}_dot" for c in q]
    names = [*q, *qd, *(f"der({c})" for c in q + qd), *info["parameters"], *info["inputs"]]
    seen = set()
    for name in names:
        if name in seen:
            raise ModelError(
                f"model {info['name']!r}: the FMU variable name {name!r} would be used twice (the "
                "velocities are named <coordinate>_dot): rename the coordinate, parameter or input")
        seen.add(name)
    return names


def parameter_start_values(info, params=None):
    """Start values of the parameters: the defaults, overridden by `params` (name -> value);
    ModelError for a parameter that has neither or an unknown or non-finite value."""
    names = info["parameters"]
    values = dict(zip(names, info["defaults"]))
    for key, value in (params or {}).items():
        if key not in values:
            raise ModelError(f"params: model {info['name']!r} has no parameter {key!r} (its "
                             f"parameters are {', '.join(names) or 'none'})")
        values[key] = value
    out = []
    for name in names:
        value = values[name]
        if value is None:
            raise ModelError(f"parameter {name!r} of model {info['name']!r} has no default, and an "
                             "FMU needs a start value for every parameter: give it a default or "
                             "a value at export (params={...} or --params)")
        value = float(value)
        if not math.isfinite(value):
            raise ModelError(f"parameter {name!r}: start value {value} is not finite")
        out.append(value)
    return out


def fmu_guid(info, start_values, start_time, stop_time):
    """A GUID determined by the model's content hash and what the description adds to it."""
    text = repr((info["content_hash"], start_values, start_time, stop_time, __version__))
    return "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "lagrgen:" + text)) + "}"


def _number(value):
    return repr(float(value))


def model_description(info, guid, start_values, start_time=0.0, stop_time=10.0, tolerance=None):
    """The text of modelDescription.xml (FMI 2.0, Model Exchange). Variables are listed in
    value-reference order, so a variable's index is its value reference + 1."""
    name, q = info["name"], info["coordinates"]
    n, names = len(q), variable_names(info)
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": name, "guid": guid,
        "description": f"{name}: M(q, t)·q'' = F(q, q', t, u), states q and q'",
        "generationTool": f"lagrgen {__version__}", "variableNamingConvention": "flat",
        "numberOfEventIndicators": "0"})
    me = ET.SubElement(root, "ModelExchange", {
        "modelIdentifier": name, "providesDirectionalDerivative": "true",
        "canGetAndSetFMUstate": "false", "canSerializeFMUstate": "false",
        "completedIntegratorStepNotNeeded": "true", "canNotUseMemoryManagementFunctions": "false"})
    sources = ET.SubElement(me, "SourceFiles")
    ET.SubElement(sources, "File", {"name": f"{name}_fmu.c"})
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", {"name": "logStatusError",
                                           "description": "errors"})
    experiment = {"startTime": _number(start_time), "stopTime": _number(stop_time)}
    if tolerance is not None:
        experiment["tolerance"] = _number(tolerance)
    ET.SubElement(root, "DefaultExperiment", experiment)
    variables = ET.SubElement(root, "ModelVariables")

    def variable(vr, attributes, real, description):
        sv = ET.SubElement(variables, "ScalarVariable", {
            "name": names[vr], "valueReference": str(vr), "description": description,
            **attributes})
        ET.SubElement(sv, "Real", real)

    for i, c in enumerate(q):
        variable(i, {"causality": "output", "variability": "continuous", "initial": "exact"},
                 {"start": "0.0"}, f"coordinate {c} (a state)")
    for i, c in enumerate(q):
        variable(n + i, {"causality": "local", "variability": "continuous", "initial": "exact"},
                 {"start": "0.0"}, f"rate of {c} (a state)")
    for i in range(2 * n):
        variable(2 * n + i, {"causality": "local", "variability": "continuous",
                             "initial": "calculated"},
                 {"derivative": str(i + 1)}, f"time derivative of {names[i]}")
    base = 4 * n
    for j, (p, value) in enumerate(zip(info["parameters"], start_values)):
        variable(base + j, {"causality": "parameter", "variability": "tunable",
                            "initial": "exact"}, {"start": _number(value)}, f"parameter {p}")
    base += len(info["parameters"])
    for k, u in enumerate(info["inputs"]):
        variable(base + k, {"causality": "input", "variability": "continuous"},
                 {"start": "0.0"}, f"input {u}")
    structure = ET.SubElement(root, "ModelStructure")
    outputs = ET.SubElement(structure, "Outputs")
    for i in range(n):
        ET.SubElement(outputs, "Unknown", {"index": str(i + 1)})
    derivatives = ET.SubElement(structure, "Derivatives")
    initial = ET.SubElement(structure, "InitialUnknowns")
    for i in range(2 * n):
        ET.SubElement(derivatives, "Unknown", {"index": str(2 * n + i + 1)})
        ET.SubElement(initial, "Unknown", {"index": str(2 * n + i + 1)})
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") \
        + "\n"


def fmu_glue(info, n, guid, start_values):
    """`<name>_fmu.c`: the FMI 2.0 functions, around `<name>_model.c` (which it includes)."""
    return Template(read_template("fmu.c.in")).substitute(
        substitutions(info, n), guid=guid,
        start_parameters=", ".join(_number(v) for v in start_values) or "0.0")


def fmu_sources(model, params=None, start_time=0.0, stop_time=10.0, tolerance=None):
    """{file name: text}: the standalone model, the FMI glue and modelDescription.xml."""
    from ..build import model_info
    equations = model.equations()
    info = model_info(model.spec(), equations)
    if info.get("nonsmooth"):
        raise ModelError(f"model {info['name']!r} has impacts or frictions "
                         f"({', '.join(e['name'] for e in info['nonsmooth'])}): an FMU would "
                         "integrate it without its switches; simulate it with lagrgen.simulate")
    if not stop_time > start_time:
        raise ModelError(f"stop time {stop_time} must be greater than the start time {start_time}")
    start_values = parameter_start_values(info, params)
    guid = fmu_guid(info, start_values, start_time, stop_time)
    files = standalone_files(info, equations)
    files[f"{info['name']}_fmu.c"] = fmu_glue(info, equations.n, guid, start_values)
    files["modelDescription.xml"] = model_description(info, guid, start_values, start_time,
                                                      stop_time, tolerance)
    return files


def export_fmu(model, out_dir=".", params=None, start_time=0.0, stop_time=10.0, tolerance=None,
               cflags=()):
    """Write `<out_dir>/<name>.fmu`, an FMI 2.0 Model Exchange FMU of `model` for this platform.

    Its states are x = [q, q̇] (variables named like the coordinates and `<coordinate>_dot`), with
    ẋ = [q̇, M⁻¹·F]; parameters are tunable parameters, inputs continuous inputs, the coordinates
    outputs; directional derivatives come from the analytic Jacobian.

    Parameters
    ----------
    model : lagrgen.Model
    out_dir : str or pathlib.Path
    params : dict, optional
        Parameter start values (name -> value) replacing the defaults; required for parameters
        without a default.
    start_time, stop_time, tolerance : the DefaultExperiment
    cflags : extra compiler flags (a list)

    Returns
    -------
    pathlib.Path of the FMU.
    """
    from ..build import compiler_command, write_atomic
    from ..model import Model
    if not isinstance(model, Model):
        raise TypeError(f"export_fmu() takes a lagrgen.Model, got {type(model).__name__}")
    name = model.name
    files = fmu_sources(model, params, start_time, stop_time, tolerance)
    folder, suffix = platform_folder()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"lagrgen-fmu-{name}-"))
    try:
        for file_name, text in files.items():
            (work / file_name).write_text(text, encoding="utf-8")
        library = work / f"{name}{suffix}"
        cmd = [*compiler_command(), *FMU_CFLAGS, *cflags, "-I", str(work), "-I", str(FMI_HEADERS),
               str(work / f"{name}_fmu.c"), "-o", str(library), "-lm"]
        try:
            result = subprocess.run(cmd, capture_output=True, text=True)
        except FileNotFoundError:
            raise BuildError(f"no C compiler found (tried {cmd[0]!r}): install one or set $CC") \
                from None
        if result.returncode != 0:
            message = "\n".join((result.stderr or result.stdout).strip().splitlines()[:60])
            raise CompileError(f"the C compiler failed on {name}_fmu.c:\n{message}\ncommand: "
                               + " ".join(cmd))
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.writestr("modelDescription.xml", files["modelDescription.xml"])
            fmu.write(library, f"binaries/{folder}/{name}{suffix}")
            for file_name in (f"{name}_fmu.c", f"{name}_model.c", f"{name}_model.h"):
                fmu.writestr(f"sources/{file_name}", files[file_name])
            for header in HEADER_FILES:
                fmu.write(FMI_HEADERS / header, f"sources/{header}")
            fmu.write(FMI_HEADERS / "LICENSE.txt", "documentation/licenses/fmi2-headers.txt")
        path = out_dir / f"{name}.fmu"
        write_atomic(path, buffer.getvalue())
        return path
    finally:
        shutil.rmtree(work, ignore_errors=True)
