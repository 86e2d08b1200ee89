"""`build`: from a Model to a built model of either backend, through the pipeline
describe → derive → generate → compile → publish; `export_c` and `export_fmu` stop after
generating (the FMU writer compiles its own).

A C build is a cache lookup first: `lagrgen.cache` keys the build by what it compiles, and on a
hit nothing is derived. On a miss the equations are derived, printed as C, compiled into a new
cache entry and published into out_dir (see `lagrgen.cache` for the layout and the guarantees).
"""
import hashlib
import sys
import time
from pathlib import Path

from . import cache
from ._version import __version__
from .errors import ModelError
from .functions import MODEL_UNIT, functions_of
from .runtime.info import ModelInfo
from .toolchain import compile_flags, compile_module, compile_units, write_atomic

BACKENDS = ("c", "python")


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
        republish), opt_level ("-O2"), cflags (a list of extra compiler flags); the Python
        backend accepts and ignores these. Any other option is a TypeError.

    Returns
    -------
    The built model (`runtime.protocol.BuiltModel` in the API reference): a module for "c", a
    `PythonModel` for "python".
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
    unknown = set(options) - {"verbose", "quiet", "force", "opt_level", "cflags"}
    if unknown:
        raise TypeError(f"build() got unknown option(s) {', '.join(sorted(unknown))}")
    if backend == "python":
        from .codegen.python_module import python_source
        from .runtime.pymodel import PythonModel
        from .runtime.tree import RecursivePythonModel
        from .runtime.free_base import FreeBasePythonModel
        from .runtime.tree3d import SpatialPythonModel
        from .tree import analyse
        equations = derived(spec)
        info = model_info(spec, equations, formulation)
        kind = PythonModel
        if info.formulation == "recursive":
            tree = analyse(equations)
            kind = RecursivePythonModel if tree.kind != "spatial" else \
                FreeBasePythonModel if tree.free else SpatialPythonModel
        built = kind(info, python_source(equations, info.formulation))
        built.build_info = {"cache_hit": False, "seconds": time.perf_counter() - start}
        built._source_model = model
        return built
    digest = content_digest(spec, formulation, lambda: derived(spec))
    cache.remember_description(digest, spec)
    built = build_c(spec.name, digest,
                    lambda: (model_info(spec, derived(spec), formulation), derived(spec)),
                    Path(out_dir), **options)
    built._source_model = model      # the description it was built from: what animations draw
    return built


def build_c(name, digest, derive, out_dir, verbose=False, quiet=False, force=False,
            opt_level="-O2", cflags=()):
    """Look up, or generate, compile and store, the model `name` whose content digest is
    `digest`; publish it into `out_dir` and import it. `derive()` gives (info, equations) and is
    called only when something must be compiled. Returns the module (the built model). Progress
    goes to stderr with `verbose`, or on a terminal unless `quiet`."""
    start = time.perf_counter()
    flags = compile_flags(opt_level, cflags)
    entry = cache.Entry(Path(out_dir), name, cache.key(digest, flags))
    progress = Progress(name, verbose or (not quiet and sys.stderr.isatty()))

    def make(work):
        """derive → generate → compile, into the private directory `work` of a new entry, with
        the description its units compiled on first use derive their code from (lagrgen.units)."""
        info, equations = derive()
        progress.note("deriving the equations of motion ...")
        if info.formulation == "dense":
            equations.differentiate(parameters=False)
        progress.step("derive", f"{equations.n} coordinates, {info.formulation} formulation")
        compile_model(generate(info, equations, progress), work, name, flags, progress,
                      kernel_part_flags)
        cache.keep_description(work, equations.spec, flags)

    try:
        with cache.writing(entry):
            hit = not force and cache.lookup(entry.main, digest)
            if not hit:
                cache.store(entry.main, make, digest)
            module = cache.import_or_repair(entry.main, make, progress.note, digest)
            cache.publish(entry, force)
    except cache.ReadOnlyCache:
        if force or not (cache.lookup(entry.main, digest) and cache.is_published(entry)):
            raise
        module = cache.check_content(cache.import_extension(name, entry.main.module_file),
                                     digest, str(entry.main.module_file))
        hit = True
    if hit:
        progress.note(f"cached build {entry.directory.name} ({module.formulation} formulation)")
    times = dict(progress.times)
    if "cse" in times:
        times["cse+emit"] = times["cse"] + times["emit"]
    module.build_info = {"cache_hit": hit, "seconds": time.perf_counter() - start, **times}
    return module


def derived(spec):
    """The `Equations` of the frozen description `spec`, derived once per spec (SymPy and
    SymEngine are imported here, when first needed: `load` needs neither)."""
    from .lagrange import derived as derived_once
    return derived_once(spec)


def content_digest(spec, formulation, equations):
    """`cache.content_digest` of what a build compiles, with the formulation asked for (None:
    lagrgen's choice, which follows from the description)."""
    digest = cache.content_digest(spec, equations)
    if formulation is None:
        return digest
    return hashlib.sha256(f"{digest} formulation={formulation}".encode()).hexdigest()


def model_info(spec, equations, formulation=None):
    """The `ModelInfo` of a built model: names, defaults, units (the energies' read from the
    labels, `lagrgen.dimensions`), sizes, flags, hash, version, and the formulation `formulation`
    resolves to (`lagrgen.tree.choose`)."""
    from .dimensions import energy_units
    from .tree import analysed, choose, explicit_time
    from .tree3d import inertial_parameters
    asked, formulation = formulation, choose(equations, formulation)
    if formulation == "recursive":
        time_dependent = explicit_time(analysed(equations)[0], equations)
    else:
        time_dependent = equations.explicit_time
    return ModelInfo(
        name=spec.name, coordinates=spec.coordinate_names, parameters=spec.parameter_names,
        inputs=spec.input_names, defaults=spec.defaults,
        units={**energy_units(equations), **dict(spec.units)},
        output_names=spec.output_names, constraint_names=spec.constraint_names,
        n_holonomic=equations.n_holonomic,
        event_definitions=[(name, terminal, direction)
                           for name, _, terminal, direction in spec.events],
        explicit_time=bool(time_dependent), formulation=formulation,
        content_hash=content_digest(spec, asked, lambda: equations), lagrgen_version=__version__,
        nonsmooth_definitions=[(e["name"], e["kind"], e["normal"])
                               for e in _nonsmooth().describe(spec)],
        inertial_parameters=inertial_parameters(spec),
        initial_state=spec.initial_state, coordinate_limits=spec.limits,
        link_names=tree_links(equations), limit_stops=limit_stops(spec),
        tree_structure=_tree_structure(equations) if formulation == "recursive" else {})


def limit_stops(spec):
    """The enforced limits of `spec` as (name, coordinate index, sign, bound, restitution): a stop
    <coordinate>_lower at the lower limit (sign +1), <coordinate>_upper at the upper (−1)."""
    limits = {name: (lower, upper) for name, lower, upper, *_ in spec.limits}
    out = []
    for name, restitution in spec.stops:
        j = spec.coordinate_names.index(name)
        for side, sign, bound in (("lower", 1, limits[name][0]), ("upper", -1, limits[name][1])):
            if bound is not None:
                out.append((f"{name}_{side}", j, sign, float(bound), float(restitution)))
    return tuple(out)


def tree_links(equations):
    """The names of the links of a three-dimensional tree (none for any other model)."""
    from .kernels import has_links
    from .tree import analysed
    return tuple(name for name, _ in analysed(equations)[0].links) \
        if has_links(equations) else ()


def _tree_structure(equations):
    """`ModelInfo.tree_structure` of a spatial tree (its recursion's tables, see
    `lagrgen.codegen.tree_code.structure`); empty for a planar one."""
    from .codegen.tree_code import structure
    return structure(equations)


def _nonsmooth():
    from . import nonsmooth
    return nonsmooth


# -- generate and compile ---------------------------------------------------------------------
def generate(info, equations, progress, functions=functions_of(MODEL_UNIT),
             glue="module.c.in"):
    """The C files of a module with the registered `functions` (the model's own by default):
    {file name: text} (the standalone model, the module glue `glue`, and the kernels'
    translation units when the model is long enough to be split)."""
    from .codegen.c_model import (kernels_of, module_source, standalone_files,
                                  translation_units, unit_sources)
    from .kernels import model_kernels
    name = info.name
    kernels = model_kernels(equations, info.formulation, kernels_of(functions))
    progress.step("cse", f"{sum(len(k.temporaries) for k in kernels)} temporaries")
    files = standalone_files(info, equations, functions)
    parts = translation_units(files[f"{name}_model.c"])
    files[f"{name}_module.c"] = module_source(info, parts, functions, glue)
    files.update(unit_sources(name, parts))
    progress.step("emit", f"{sum(len(text) for text in files.values()) / 1024:.0f} KiB of C")
    return files


def compile_model(files, work, name, flags, progress, part_flags=None):
    """Write `files` into the directory `work` and compile the module glue `<name>_module.c`
    (which includes the model) and any kernel units into `work/<name><EXT_SUFFIX>`, the units
    of the kernels' parts with `part_flags(flags)` when given (the traced functions' with
    `flags`: they are the hot path of q̈)."""
    size = sum(len(text) for text in files.values())
    progress.note(f"compiling {size / 1024:.0f} KiB of C ({' '.join(flags)}) ...")
    for file_name, text in files.items():
        (work / file_name).write_text(text)
    from .codegen.c_model import traced_unit_numbers, unit_file
    lib = cache.Unit(work, name).module_file
    sources = [work / f for f in files if f.endswith(".c") and f != f"{name}_model.c"]
    if len(sources) > 1:                       # the module glue, then the kernels' units
        kept = {sources[0]} | {work / unit_file(name, k)
                               for k in traced_unit_numbers(files[f"{name}_model.c"])}
        compile_units(sources, lib, flags,
                      lambda path: flags if path in kept or part_flags is None
                      else part_flags(flags))
    else:
        compile_module(sources[0], lib, flags)
    progress.step("compile", f"{' '.join(flags)}, {lib.stat().st_size / 1024:.0f} KiB module")


def kernel_part_flags(flags):
    """The flags of the separately compiled parts of a model module's long kernels: `flags` with
    the default -O2 lowered to -O1 (another level the user asked for is kept). Measured on the
    n-link chain at n = 20 and 40: -O1 compiles those parts (straight-line code, no loop to
    vectorize) with 23 % less compiler time for rhs and jacobian within 3 %; the module glue
    with the solves keeps -O2, and so do the units compiled on first use, whose tangents in
    lanes are vectorized loops (-O1 there: 45 % less compiler time, 12-16 % slower)."""
    return ["-O1" if f == "-O2" else f for f in flags]


class Progress:
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


# -- export: generated files without the cache -----------------------------------------------
def export_c(model, out_dir):
    """Write just the standalone C model `<name>_model.h` and `<name>_model.c` into `out_dir`,
    with every exported function (a build's own `<name>_model.c` holds those of the model's
    module); return their paths."""
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
    method, rtol, atol : the co-simulation solver's start values (a method of the native engine,
        `lagrgen.methods.NATIVE_METHODS`; rtol defaults to `tolerance` or 1e-6, atol to
        rtol/1000)

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
