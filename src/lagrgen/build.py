"""`build` and `load`: from a Model to a built model of either backend (derive, generate, compile,
cache, import).

Layout of an output directory:
    <name>_model.h, <name>_model.c  the standalone C model (plain C, no Python)
    <name><EXT_SUFFIX>              the model's module, importable with the directory on sys.path
    __lagrgen__/<name>-<key>/       the cache: one immutable entry per key (sources, module, digest)
    __lagrgen__/<name>.current      the key of the entry last published into the directory
The key is a hash of what is compiled: the frozen model description (every symbol with its
assumptions; or the equations themselves when M and F come from outside, as from `from_sympy`),
lagrgen's generator sources and version, the versions of SymPy and SymEngine, the compiler and
flags. So no change to a model, and no change to lagrgen, can be served stale, and a cache hit
derives nothing. Everything is written to a temporary file or directory first and renamed into place after an
fsync, so a build that dies halfway leaves nothing a later load would pick up; a cache entry whose
module does not match its recorded digest, or does not import, is discarded and compiled again.
"""
import dataclasses
import functools
import hashlib
import importlib.machinery
import importlib.util
import os
import shutil
import sys
import sysconfig
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

from ._version import __version__
from .caching import once_per
from .errors import BuildError, ModelError
from .names import check_model_name
from .runtime.info import ModelInfo
from .toolchain import (_fsync_dir, compile_flags, compile_module, compile_units,  # noqa: F401
                        compiler_command, write_atomic)

EXT_SUFFIX = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
CACHE_DIR = "__lagrgen__"
BACKENDS = ("c", "python")
PACKAGE = Path(__file__).resolve().parent
#: The sources that determine generated code: a change to any of them changes every key.
GENERATOR_SOURCES = ("_version.py", "functions.py", "calculus.py", "terms.py", "contributions.py",
                     "lagrange.py", "nonsmooth.py", "tree.py", "kernels.py", "runtime/info.py",
                     "codegen/*.py", "codegen/templates/*", "codegen/templates/functions/*")
_loaded = {}


def build(model, out_dir="generated", backend="c", **options):
    """Derive, generate and (for backend "c") compile and import `model`; return the built model.

    Parameters
    ----------
    model : lagrgen.Model
    out_dir : str or pathlib.Path
        Where the C backend writes and caches; the Python backend ignores it.
    backend : "c" or "python"
    **options
        Both backends: formulation — "dense" (q̈ through the Cholesky factor of M), "recursive"
        (the articulated-body recursion over a kinematic tree, `lagrgen.tree`; ModelError if the
        model is not one) or None (default: recursive for a tree of at least
        `lagrgen.tree.RECURSIVE_FROM` coordinates). C backend: verbose, quiet, force (rebuild and
        republish), opt_level ("-O2"), cflags (a list of extra compiler flags).

    Returns
    -------
    The built model (API.md §3): a module for "c", a `PythonModel` for "python".
    """
    from .description import Description
    if not isinstance(model, Description):
        raise TypeError(f"build() takes a lagrgen.Model, got {type(model).__name__}")
    if backend not in BACKENDS:
        raise ModelError(f"unknown backend {backend!r}: use one of {', '.join(map(repr, BACKENDS))}")
    start = time.perf_counter()
    spec = model.spec()
    formulation = options.pop("formulation", None)
    if formulation not in (None, "dense", "recursive"):
        raise ModelError(f"unknown formulation {formulation!r}: use 'dense', 'recursive' or None")
    if backend == "python":
        from .codegen.python_module import python_source
        from .runtime.pymodel import PythonModel
        from .runtime.tree import RecursivePythonModel
        equations = derived(spec)
        info = model_info(spec, equations, formulation)
        kind = RecursivePythonModel if info.formulation == "recursive" else PythonModel
        built = kind(info, python_source(equations, info.formulation))
        built.build_info = {"cache_hit": False, "seconds": time.perf_counter() - start}
        built._source_model = model
        return built
    unknown = set(options) - {"verbose", "quiet", "force", "opt_level", "cflags"}
    if unknown:
        raise TypeError(f"build() got unknown option(s) {', '.join(sorted(unknown))}")
    digest = content_digest(spec, lambda: derived(spec))
    if formulation is not None:
        digest = hashlib.sha256(f"{digest} {formulation}".encode()).hexdigest()
    built = build_c(spec.name, digest,
                    lambda: (model_info(spec, derived(spec), formulation), derived(spec)),
                    Path(out_dir), **options)
    built._source_model = model      # the description it was built from: what animations draw
    return built


def load(name, out_dir="generated"):
    """Import the compiled model `name` built earlier into `out_dir`."""
    check_model_name(name)
    out_dir = Path(out_dir)
    marker = out_dir / CACHE_DIR / f"{name}.current"
    if marker.exists():
        entry = out_dir / CACHE_DIR / f"{name}-{marker.read_text().strip()}"
        if entry_is_valid(entry, name):
            return import_extension(name, module_path(entry, name))
    module_file = out_dir / f"{name}{EXT_SUFFIX}"
    if not module_file.exists():
        raise BuildError(
            f"no compiled model {name!r} in {out_dir}: build it first with lagrgen.build(model, "
            f"out_dir={str(out_dir)!r}) or `python -m lagrgen build MODEL.py --out {out_dir}`")
    return import_extension(name, module_file)


def export_c(model, out_dir):
    """Write just the standalone C model `<name>_model.h` and `<name>_model.c` into `out_dir`;
    return their paths."""
    from .codegen.c_model import standalone_files
    equations = derived(model.spec())
    info = model_info(model.spec(), equations)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for file_name, text in standalone_files(info, equations).items():
        write_atomic(out_dir / file_name, text.encode())
        paths.append(out_dir / file_name)
    return paths


def export_fmu(model, out_dir=".", params=None, start_time=0.0, stop_time=10.0, tolerance=None,
               cflags=(), *, kind="me", fmi_version=2, method="DOP853", rtol=None, atol=None):
    """Write `<out_dir>/<name>.fmu`, an FMU of `model` for this platform: FMI 2.0 or 3.0, Model
    Exchange or Co-Simulation.

    Its states are x = [q, q̇] (variables named like the coordinates and `<coordinate>_dot`), with
    ẋ = [q̇, M⁻¹·F]; parameters are tunable parameters, inputs continuous inputs, the coordinates
    outputs; directional derivatives come from the analytic Jacobian; the FMU state can be got,
    set and serialized. A Model Exchange FMU's event indicators are the model's compiled events.
    A co-simulation FMU advances each communication step with lagrgen's native engine; its method
    and tolerances are the tunable parameters `solver.method`, `solver.rtol` and `solver.atol`.

    Parameters
    ----------
    model : lagrgen.Model
    out_dir : str or pathlib.Path
    params : dict, optional
        Parameter start values (name -> value) replacing the defaults; required for parameters
        without a default.
    start_time, stop_time, tolerance : the DefaultExperiment
    cflags : extra compiler flags (a list)
    kind : "me" (Model Exchange) or "cs" (Co-Simulation)
    fmi_version : 2 or 3
    method, rtol, atol : the co-simulation solver's start values (one of RK23, RK45, DOP853,
        Radau, BDF; rtol defaults to `tolerance` or 1e-6, atol to rtol/1000)

    Returns
    -------
    pathlib.Path of the FMU.
    """
    from .codegen.fmu import write_fmu
    from .description import Description
    if not isinstance(model, Description):
        raise TypeError(f"export_fmu() takes a lagrgen.Model, got {type(model).__name__}")
    equations = derived(model.spec())
    return write_fmu(model_info(model.spec(), equations), equations, Path(out_dir), params,
                     start_time, stop_time, tolerance, cflags, kind=kind,
                     fmi_version=fmi_version, method=method, rtol=rtol, atol=atol)


def derived(spec):
    """The `Equations` of the frozen description `spec`, derived once per spec (SymPy and
    SymEngine are imported here, when first needed: `load` needs neither)."""
    from .lagrange import derived as derived_once
    return derived_once(spec)


# -- what identifies a build -----------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def generator_digest():
    """sha256 of lagrgen's generator sources (derivation, kernels, printers, templates) and of
    the versions of the symbolic libraries that derive the equations."""
    from importlib.metadata import PackageNotFoundError, version
    h = hashlib.sha256(__version__.encode())
    for library in ("sympy", "symengine"):
        try:
            h.update(f"{library} {version(library)}\0".encode())
        except PackageNotFoundError:
            pass
    for pattern in GENERATOR_SOURCES:
        for path in sorted(PACKAGE.glob(pattern)):
            if path.is_file():
                h.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0")
                h.update(path.read_bytes())
    return h.hexdigest()


def content_digest(spec, equations):
    """sha256 identifying what a build compiles: of the frozen description `spec` and the
    generator, or — when M and F come from outside (`spec.external`) — of the derived equations
    (`equations()` is then called)."""
    if spec.external is not None:
        return equations_digest(equations())
    return description_digest(spec)


@once_per
def description_digest(spec):
    """sha256 of the generator and every field of the frozen description `spec`, SymPy objects by
    `srepr` (which keeps the assumptions of symbols, unlike `str`)."""
    h = hashlib.sha256(generator_digest().encode())
    h.update(_canonical(spec).encode())
    return h.hexdigest()


def _canonical(obj, memo=None):
    """A text that identifies `obj`: SymPy objects by their tree (class names, symbol names with
    their assumptions, exact numbers), dataclasses, tuples, lists and dicts by their parts,
    anything else by repr. Shared subexpressions are spelled once per call (`memo`)."""
    import sympy as sp
    memo = {} if memo is None else memo
    if isinstance(obj, (sp.Basic, sp.MatrixBase)):
        return _expression_text(obj, memo)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        parts = (f"{f.name}={_canonical(getattr(obj, f.name), memo)}"
                 for f in dataclasses.fields(obj))
        return f"{type(obj).__name__}({', '.join(parts)})"
    if isinstance(obj, (tuple, list)):
        return f"{type(obj).__name__}[{', '.join(_canonical(x, memo) for x in obj)}]"
    if isinstance(obj, dict):
        items = sorted(obj.items(), key=lambda kv: repr(kv[0]))
        return "{" + ", ".join(f"{_canonical(k, memo)}: {_canonical(v, memo)}"
                               for k, v in items) + "}"
    return repr(obj)


def _expression_text(expr, memo):
    """The tree of a SymPy expression or matrix as text (see `_canonical`)."""
    import sympy as sp
    if isinstance(expr, sp.MatrixBase):
        rows = (",".join(_expression_text(e, memo) for e in expr.row(i))
                for i in range(expr.rows))
        return f"Matrix[{';'.join(rows)}]"
    try:
        return memo[expr]
    except KeyError:
        pass
    if expr.is_Symbol:
        text = f"Symbol({expr.name!r}, {sorted(expr.assumptions0.items())})"
    elif expr.is_Number or not expr.args:
        text = sp.srepr(expr)
    else:
        head = type(expr).__name__
        if isinstance(expr, sp.core.function.AppliedUndef):
            head = f"Function({expr.func.__name__!r})"
        text = f"{head}({','.join(_expression_text(a, memo) for a in expr.args)})"
    memo[expr] = text
    return text


@once_per
def equations_digest(equations):
    """sha256 of what is compiled: names, defaults, the derived equations and the generator."""
    spec = equations.spec
    h = hashlib.sha256(generator_digest().encode())
    parts = [spec.name, spec.coordinate_names, spec.parameter_names, spec.defaults,
             spec.input_names, [[str(e) for e in row] for row in equations.M],
             [str(f) for f in equations.F], [str(e) for e in equations.residuals],
             spec.stabilization, spec.constraint_names, [str(g) for g in equations.events],
             [(name, terminal, direction) for name, _, terminal, direction in spec.events],
             spec.output_names, [str(e) for e in equations.outputs], spec.units,
             hybrid_description(spec, equations)]
    for part in parts:
        h.update(repr(part).encode() + b"\0")
    return h.hexdigest()


def model_info(spec, equations, formulation=None):
    """The `ModelInfo` of a built model: names, defaults, units, sizes, flags, hash, version, and
    the formulation `formulation` resolves to (`lagrgen.tree.choose`)."""
    from .tree import choose, explicit_time, analysed
    formulation = choose(equations, formulation)
    if formulation == "recursive":
        time_dependent = explicit_time(analysed(equations)[0], equations)
    else:
        time_dependent = equations.explicit_time
    return ModelInfo(
        name=spec.name, coordinates=spec.coordinate_names, parameters=spec.parameter_names,
        inputs=spec.input_names, defaults=spec.defaults, units=dict(spec.units),
        output_names=spec.output_names, constraint_names=spec.constraint_names,
        n_holonomic=equations.n_holonomic,
        event_definitions=[(name, terminal, direction)
                           for name, _, terminal, direction in spec.events],
        explicit_time=bool(time_dependent), formulation=formulation,
        content_hash=content_digest(spec, lambda: equations), lagrgen_version=__version__,
        nonsmooth_definitions=[(e["name"], e["kind"], e["normal"])
                               for e in _nonsmooth().describe(spec)])


def hybrid_description(spec, equations):
    """The impacts' and frictions' records and terms, for the content hash."""
    if not spec.nonsmooth:
        return []
    return [_nonsmooth().describe(spec), [str(e) for e in _nonsmooth().terms(equations)]]


def _nonsmooth():
    from . import nonsmooth
    return nonsmooth


# -- compiling -------------------------------------------------------------------------------
def build_key(digest, flags):
    """The cache key: the content digest, the compiler, its flags and the module suffix."""
    h = hashlib.sha256(digest.encode())
    h.update(repr((flags, compiler_command(), EXT_SUFFIX)).encode())
    return h.hexdigest()[:20]


# -- files -----------------------------------------------------------------------------------
def module_path(entry, name):
    return entry / f"{name}{EXT_SUFFIX}"


def file_digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def entry_is_valid(entry, name):
    """True if the cache entry's module exists and matches the digest recorded when it was made."""
    module, digest = module_path(entry, name), entry / "module.sha256"
    try:
        return module.is_file() and digest.read_text().strip() == file_digest(module)
    except OSError:
        return False


def discard(entry):
    """Remove a cache entry (renamed away first, so no reader sees it half-deleted)."""
    if entry.exists():
        trash = entry.with_name(f".trash-{entry.name}-{os.getpid()}-{time.monotonic_ns()}")
        os.replace(entry, trash)
        shutil.rmtree(trash, ignore_errors=True)


@contextmanager
def locked(path):
    """Hold an exclusive lock on the file `path` (created if missing) against other processes and
    threads, on any platform (`filelock`: flock on POSIX, msvcrt on Windows; imported here, so
    importing lagrgen needs neither)."""
    from filelock import FileLock
    with FileLock(str(path)):
        yield


def import_extension(name, path):
    """Import the extension module `name` from the file `path` (once per path and process),
    leaving any entry `name` of sys.modules as it was."""
    path = Path(path).resolve()
    if path in _loaded:
        return _loaded[path]
    loader = importlib.machinery.ExtensionFileLoader(name, str(path))
    spec = importlib.util.spec_from_file_location(name, str(path), loader=loader)
    missing = object()
    previous = sys.modules.get(name, missing)
    try:
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
    except ImportError as exc:
        raise BuildError(f"cannot import compiled model {name!r} from {path}: {exc}") from None
    finally:
        if previous is missing:
            sys.modules.pop(name, None)
        else:
            sys.modules[name] = previous
    _loaded[path] = module
    return module


# -- build -----------------------------------------------------------------------------------
class _Progress:
    """Times the build steps; reports them on stderr when `verbose`."""

    def __init__(self, name, verbose):
        self.name, self.verbose, self.times = name, verbose, {}
        self._t = time.perf_counter()

    def note(self, text):
        if self.verbose:
            print(f"[lagrgen] {self.name}: {text}", file=sys.stderr, flush=True)

    def step(self, what, detail=""):
        now = time.perf_counter()
        self.times[what] = now - self._t
        self._t = now
        if self.verbose:
            extra = f" ({detail})" if detail else ""
            print(f"[lagrgen] {self.name}: {what} {self.times[what]:.2f} s{extra}",
                  file=sys.stderr, flush=True)


def build_c(name, digest, derive, out_dir, verbose=False, quiet=False, force=False,
            opt_level="-O2", cflags=()):
    """Generate, compile, cache, publish and import the model `name` whose content digest is
    `digest`; `derive()` gives (info, equations) and is called only when something must be
    compiled. Returns the module (the built model). Progress goes to stderr with `verbose`, or on
    a terminal unless `quiet`."""
    start = time.perf_counter()
    flags = compile_flags(opt_level, cflags)
    key = build_key(digest, flags)
    cache = Path(out_dir) / CACHE_DIR
    entry = cache / f"{name}-{key}"
    progress = _Progress(name, verbose or (not quiet and sys.stderr.isatty()))
    try:
        cache.mkdir(parents=True, exist_ok=True)
        lock = locked(cache / f"{name}.lock")
        lock.__enter__()
    except OSError as exc:
        if force or not (entry_is_valid(entry, name) and _is_published(out_dir, name, key)):
            raise BuildError(f"cannot write the build of {name!r} into {out_dir}: {exc}") from None
        return _finish(import_extension(name, module_path(entry, name)), True, start, progress)
    try:
        hit = not force and entry_is_valid(entry, name)
        if not hit:
            _compile_entry(*derive(), entry, flags, progress)
        module = _import_or_rebuild(name, derive, entry, flags, progress)
        _publish(out_dir, name, entry, key, force)
    finally:
        lock.__exit__(None, None, None)
    if hit:
        progress.note(f"cached build {entry.name}")
    return _finish(module, hit, start, progress)


def _finish(module, hit, start, progress):
    module.build_info = {"cache_hit": hit, "seconds": time.perf_counter() - start,
                         **progress.times}
    return module


def _import_or_rebuild(name, derive, entry, flags, progress):
    """Import the entry's module; if that fails, discard the entry, compile it again, import."""
    try:
        return import_extension(name, module_path(entry, name))
    except BuildError as first:
        progress.note(f"cached module did not import ({first}); compiling again")
        _compile_entry(*derive(), entry, flags, progress)
        return import_extension(name, module_path(entry, name))


def _compile_entry(info, equations, entry, flags, progress):
    """Generate the model's C in a private directory, compile it, and rename it to `entry`."""
    from .codegen.c_model import (module_source, standalone_files, translation_units,
                                  unit_sources)
    name = info.name
    progress.note("deriving the equations of motion ...")
    if info.formulation == "dense":
        equations.differentiate()
    progress.step("derive", f"{equations.n} coordinates")
    files = standalone_files(info, equations)
    units = translation_units(files[f"{name}_model.c"])
    files[f"{name}_module.c"] = module_source(info, units)
    files.update(unit_sources(name, units))
    size = sum(len(text) for text in files.values())
    progress.step("cse+emit", f"{size / 1024:.0f} KiB of C")
    progress.note(f"compiling {size / 1024:.0f} KiB of C ({' '.join(flags)}) ...")
    work = Path(tempfile.mkdtemp(dir=entry.parent, prefix=f".build-{name}-"))
    try:
        for file_name, text in files.items():
            (work / file_name).write_text(text)
        lib = module_path(work, name)
        if units:
            compile_units([work / f"{name}_module.c", *(work / f for f in unit_sources(name, units))],
                          lib, flags)
        else:
            compile_module(work / f"{name}_module.c", lib, flags)
        for obj in work.glob("*.o"):
            obj.unlink()
        progress.step("compile", f"{' '.join(flags)}, {lib.stat().st_size / 1024:.0f} KiB module")
        write_atomic(work / "module.sha256", (file_digest(lib) + "\n").encode())
        for path in work.iterdir():
            os.chmod(path, 0o755 if path == lib else 0o644)
        with open(lib, "rb") as fh:
            os.fsync(fh.fileno())
        discard(entry)
        os.replace(work, entry)
        _fsync_dir(entry.parent)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _is_published(out_dir, name, key):
    marker = Path(out_dir) / CACHE_DIR / f"{name}.current"
    try:
        return (Path(out_dir) / f"{name}{EXT_SUFFIX}").exists() and \
            marker.read_text().strip() == key
    except OSError:
        return False


def _publish(out_dir, name, entry, key, force=False):
    """Make <name><EXT>, <name>_model.h and <name>_model.c in out_dir the files of `entry`."""
    out_dir = Path(out_dir)
    if not force and _is_published(out_dir, name, key) and \
            file_digest(out_dir / f"{name}{EXT_SUFFIX}") == file_digest(module_path(entry, name)):
        return
    for file_name in (f"{name}_model.h", f"{name}_model.c"):
        write_atomic(out_dir / file_name, (entry / file_name).read_bytes())
    write_atomic(out_dir / f"{name}{EXT_SUFFIX}", module_path(entry, name).read_bytes(), 0o755)
    write_atomic(out_dir / CACHE_DIR / f"{name}.current", (key + "\n").encode())

