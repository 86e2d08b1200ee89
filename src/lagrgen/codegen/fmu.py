"""FMU export: the standalone C model, the FMU core (`<name>_fmu_core.c`), the FMI glue
(`<name>_fmu.c`), modelDescription.xml and, for co-simulation, lagrgen's native ODE engine,
compiled and zipped into `<name>.fmu`, FMI 2.0 or 3.0, Model Exchange or Co-Simulation. The
model descriptions are in `fmi2.py` (with the variables every FMU shares) and `fmi3.py`.

The FMU's continuous states are x = [q, q̇] with ẋ = rhs(t, x, p, u); directional derivatives
are backed by the analytic Jacobian ∂ẋ/∂x and by ∂ẋ/∂u = [0; M⁻¹·∂F/∂u]. A co-simulation FMU's
communication step is one solve of the native engine (a C port of SciPy's solve_ivp) with the
inputs held, its method and tolerances the parameters solver.method, solver.rtol, solver.atol.
"""
import io
import platform
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path
from string import Template

from ..errors import BuildError, ModelError
from ..methods import NATIVE_CODES, NATIVE_METHODS
from ..options import absolute_tolerance, relative_tolerance
from ..toolchain import compiler_command, run_compiler, write_atomic
from ..functions import MODEL_UNIT, functions_of
from .c_model import TEMPLATES, read_template, standalone_files, substitutions
from .fmi2 import (fmu_guid, model_description, number_text, numbers_text,
                   parameter_start_values, source_file_names, state_start_values)
from .fmi3 import build_description, model_description_fmi3

FMI_HEADERS = {2: TEMPLATES / "fmi2", 3: TEMPLATES / "fmi3"}
HEADER_FILES = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
                3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
NATIVE = Path(__file__).resolve().parent.parent / "native"
NATIVE_FILES = ("lg_ode.c", "lg_ode.h", "lg_ode_tables.h")
KINDS = ("me", "cs")
KIND_TITLES = {"me": "Model Exchange", "cs": "Co-Simulation"}
FMU_CFLAGS = ("-shared", "-fPIC", "-O2", "-fno-math-errno", "-std=gnu11", "-fvisibility=hidden")


def platform_folder(fmi_version=2):
    """(binaries folder, shared library suffix) of this platform in the FMI version's naming
    (FMI 2.0: linux64, darwin64, win64; FMI 3.0: x86_64-linux, aarch64-darwin, ...)."""
    system = platform.system()
    names = {"Linux": ("linux", ".so"), "Darwin": ("darwin", ".dylib"), "Windows": ("win", ".dll")}
    if system not in names:
        raise BuildError(f"FMI {fmi_version}.0 names no binaries folder for the platform "
                         f"{system!r}")
    folder, suffix = names[system]
    if fmi_version == 2:
        return folder + ("64" if sys.maxsize > 2 ** 32 else "32"), suffix
    machine = platform.machine().lower()
    arch = {"amd64": "x86_64", "x86_64": "x86_64", "arm64": "aarch64", "aarch64": "aarch64",
            "i386": "x86", "i686": "x86", "x86": "x86"}.get(machine)
    if arch is None:
        raise BuildError(f"FMI 3.0 names no binaries folder for the machine {machine!r}")
    return f"{arch}-{folder}", suffix


def check_kind(kind, fmi_version):
    """ValueError unless `kind` is "me" or "cs" and `fmi_version` 2 or 3."""
    if kind not in KINDS:
        raise ValueError(f"kind must be 'me' (Model Exchange) or 'cs' (Co-Simulation), got "
                         f"{kind!r}")
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version must be 2 or 3, got {fmi_version!r}")


def solver_start_values(method, rtol, atol):
    """(method index, rtol, atol) of a co-simulation FMU's solver parameters; ValueError for an
    unknown method or a tolerance out of range (`lagrgen.options`: rtol in (0, 1), atol ≥ 0)."""
    if method not in NATIVE_METHODS:
        raise ValueError(f"method {method!r} has no native implementation: use one of "
                         f"{', '.join(NATIVE_METHODS)}")
    return NATIVE_CODES[method], relative_tolerance(rtol), absolute_tolerance(atol)


def fmu_core(info, guid, start_values, solver):
    """`<name>_fmu_core.c`: the variables, derivatives, FMU state and native-engine step."""
    events = info.event_definitions
    method, rtol, atol = solver
    return Template(read_template("fmu_core.c.in")).substitute(
        substitutions(info), guid=guid, start_parameters=numbers_text(start_values),
        start_states=numbers_text(state_start_values(info)),
        n_events_or_1=max(len(events), 1), n_outputs_or_1=max(len(info.output_names), 1),
        event_terminal=numbers_text(terminal for _, terminal, _ in events),
        event_direction=numbers_text(direction for _, _, direction in events),
        start_method=method, start_rtol=number_text(rtol), start_atol=number_text(atol),
        n_methods=len(NATIVE_METHODS), method_names=method_names())


def method_names():
    """The C initializer of the method names indexed by their native codes."""
    names = dict((code, name) for name, code in NATIVE_CODES.items())
    if sorted(names) != list(range(len(names))):
        raise BuildError("the native methods' codes are not 0, 1, ...: fmu_core.c.in indexes "
                         "its name table by them")
    return ", ".join(f'"{names[k]}"' for k in range(len(names)))


def fmu_glue(info, kind, fmi_version):
    """`<name>_fmu.c`: the FMI functions of the version and kind, around `<name>_fmu_core.c`."""
    return Template(read_template(f"fmi{fmi_version}.c.in")).substitute(
        substitutions(info), kind_title=KIND_TITLES[kind],
        cosimulation=int(kind == "cs"),
        fmu_type="fmi2CoSimulation" if kind == "cs" else "fmi2ModelExchange")


def fmu_sources(info, equations, params=None, start_time=0.0, stop_time=10.0, tolerance=None,
                kind="me", fmi_version=2, method="DOP853", rtol=None, atol=None):
    """{file name: text}: the standalone model, the FMU core, the FMI glue and
    modelDescription.xml."""
    check_kind(kind, fmi_version)
    rtol = (tolerance if tolerance is not None else 1e-6) if rtol is None else rtol
    solver = solver_start_values(method, rtol, 1e-3 * rtol if atol is None else atol)
    if info.nonsmooth_definitions:
        raise ModelError(f"model {info.name!r} has impacts or frictions "
                         f"({', '.join(e[0] for e in info.nonsmooth_definitions)}): an FMU would "
                         "integrate it without its switches; simulate it with lagrgen.simulate")
    if not stop_time > start_time:
        raise ModelError(f"stop time {stop_time} must be greater than the start time {start_time}")
    start_values = parameter_start_values(info, params)
    settings = () if (kind, fmi_version) == ("me", 2) else (kind, fmi_version, solver)
    guid = fmu_guid(info, start_values, start_time, stop_time, settings)
    files = standalone_files(info, equations, functions_of(MODEL_UNIT))   # what running needs
    name = info.name
    files[f"{name}_fmu_core.c"] = fmu_core(info, guid, start_values, solver)
    files[f"{name}_fmu.c"] = fmu_glue(info, kind, fmi_version)
    describe = model_description if fmi_version == 2 else model_description_fmi3
    files["modelDescription.xml"] = describe(info, guid, start_values, start_time, stop_time,
                                             tolerance, kind, solver)
    if fmi_version == 3:
        files["buildDescription.xml"] = build_description(name, kind)
    return files


def compile_fmu(work, name, kind, fmi_version, library, cflags=()):
    """Compile `<name>_fmu.c` (and, for co-simulation, the native engine) in `work` into
    `library`; CompileError with the compiler's message when it fails."""
    sources = [str(work / file_name) for file_name in source_file_names(name, kind)]
    run_compiler([*compiler_command(), *FMU_CFLAGS, *cflags, "-I", str(work), "-I",
                  str(FMI_HEADERS[fmi_version]), *sources, "-o", str(library), "-lm"],
                 work / f"{name}_fmu.c")


def write_fmu(info, equations, out_dir=".", params=None, start_time=0.0, stop_time=10.0,
              tolerance=None, cflags=(), *, kind="me", fmi_version=2, method="DOP853", rtol=None,
              atol=None):
    """Write `<out_dir>/<name>.fmu`, an FMU of the model `info` with `equations` for this
    platform (FMI 2.0 or 3.0, Model Exchange or Co-Simulation); the arguments are those of
    `lagrgen.export_fmu`, which describes the FMU. Returns the path of the FMU."""
    name = info.name
    files = fmu_sources(info, equations, params, start_time, stop_time, tolerance, kind,
                        fmi_version, method, rtol, atol)
    folder, suffix = platform_folder(fmi_version)
    if kind == "cs":
        files.update({f: (NATIVE / f).read_text(encoding="utf-8") for f in NATIVE_FILES})
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"lagrgen-fmu-{name}-"))
    try:
        for file_name, text in files.items():
            (work / file_name).write_text(text, encoding="utf-8")
        library = work / f"{name}{suffix}"
        compile_fmu(work, name, kind, fmi_version, library, cflags)
        path = out_dir / f"{name}.fmu"
        write_atomic(path, fmu_archive(files, library, f"binaries/{folder}/{name}{suffix}",
                                       kind, fmi_version))
        return path
    finally:
        shutil.rmtree(work, ignore_errors=True)


def fmu_archive(files, library, library_path, kind, fmi_version):
    """The bytes of the .fmu zip: the description, the binary, the sources and the licences."""
    headers = FMI_HEADERS[fmi_version]
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as fmu:
        fmu.writestr("modelDescription.xml", files["modelDescription.xml"])
        fmu.write(library, library_path)
        for file_name, text in files.items():
            if file_name != "modelDescription.xml":
                fmu.writestr(f"sources/{file_name}", text)
        for header in HEADER_FILES[fmi_version]:
            fmu.write(headers / header, f"sources/{header}")
        fmu.write(headers / "LICENSE.txt",
                  f"documentation/licenses/fmi{fmi_version}-headers.txt")
        if kind == "cs":
            fmu.write(NATIVE / "LICENSE.scipy", "documentation/licenses/scipy-lg_ode.txt")
    return buffer.getvalue()
