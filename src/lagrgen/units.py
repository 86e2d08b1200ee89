"""Units compiled on first use: the functions of a built model that running it does not need
(those of `lagrgen.functions.FUNCTIONS` whose `unit` is not `MODEL_UNIT`: the parameter Jacobian,
the directional derivatives of the sensitivities, ...), compiled the first time one of them is
called, each unit into its own module `<model>_<label>` kept in the model's cache entry
(`cache.Entry.unit`), keyed by its own digest.

Their code is derived from the description the model's entry keeps (`cache.keep_description`; in
the process that built the model, the description itself), after checking it is the one the model
was built from (its content hash, which also covers lagrgen's generator and the SymPy version).
So a unit works the same after `lagrgen.load()` or `import <name>` in a fresh process. The runtime
asks for units through `lagrgen.runtime.units`, where this module registers its provider.
"""
import atexit
import dataclasses
import hashlib
import shutil
import sys
import tempfile
from pathlib import Path

from . import cache
from .build import Progress, compile_model, content_digest, derived, generate
from .errors import BuildError
from .functions import functions_of
from .runtime import units as runtime_units

#: Units that came with a copy of a model's module (a Dask worker's, `lagrgen.ensemble`):
#: (the module file, resolved; label) -> (the unit's module name, its file).
_PROVIDED = {}


def provide(model_file, label, module, unit_file):
    """Serve the unit `label` of the compiled model module `model_file` from `unit_file` (the
    module `module`), a copy shipped with it, instead of looking for the model's cache entry."""
    _PROVIDED[(str(Path(model_file).resolve()), label)] = (module, Path(unit_file))


def unit_module(model_file, info, label):
    """The module of the unit `label` of the compiled model whose module file is `model_file` and
    whose `ModelInfo` is `info`: one provided with the module (`provide`), else looked up in the
    model's cache entry, or compiled into it (into a private directory when the cache cannot be
    written). A unit is sound like a model's module (`cache.lookup`: whole, matching its digest,
    carrying the model's content hash); one that is not (damaged, or another model's) is never
    imported: it is discarded and compiled again."""
    provided = _PROVIDED.get((str(Path(model_file).resolve()), label))
    if provided is not None:
        return cache.import_extension(*provided)
    entry = entry_of(Path(model_file), info.name)
    flags = cache.kept_flags(entry)
    unit = entry.unit(label, unit_digest(info.content_hash, label, flags))
    content = info.content_hash

    def make(work):
        compile_unit(description_of(entry, info), info, label, unit.module, work, flags)

    try:
        with cache.writing(entry):
            if not cache.lookup(unit, content):
                cache.store(unit, make, content)
            return cache.import_or_repair(unit, make, content_hash=content)
    except cache.ReadOnlyCache:
        if cache.lookup(unit, content):
            return cache.check_content(cache.import_extension(unit.module, unit.module_file),
                                       content, str(unit.module_file))
        return private_unit(unit, make, content)


def private_unit(unit, make, content_hash):
    """The unit made by `make` in a private temporary directory (its cache cannot be written),
    imported, and the directory removed (the loaded module stays mapped; where the platform
    keeps a loaded module's file, what is left is removed at exit)."""
    private = Path(tempfile.mkdtemp(prefix=f"lagrgen-{unit.module}-"))
    try:
        make(private)
        module = cache.import_extension(unit.module, cache.Unit(private, unit.module).module_file)
    finally:
        shutil.rmtree(private, ignore_errors=True)
        if private.exists():
            atexit.register(shutil.rmtree, private, ignore_errors=True)
    return cache.check_content(module, content_hash, unit.module)


def unit_digest(content_hash, label, flags):
    """What identifies a unit: the model's content hash, the unit's label and its flags."""
    return hashlib.sha256(repr((content_hash, label, list(flags))).encode()).hexdigest()


def compile_unit(spec, info, label, module, work, flags):
    """derive → generate → compile the functions of unit `label` of the model `spec` (whose
    compiled module's `ModelInfo` is `info`, in its formulation) into the module `module` in the
    directory `work`."""
    progress = Progress(module, sys.stderr.isatty())
    progress.note(f"compiling the {label} functions on first use ...")
    equations = derived(spec)
    files = generate(dataclasses.replace(info, name=module), equations, progress,
                     functions_of(label), "unit_module.c.in")
    compile_model(files, work, module, flags, progress)


def entry_of(path, name):
    """The cache entry holding the model module `path`: the entry it lies in, or, for the copy
    published into an output directory, the entry of that directory whose module it is."""
    path = path.resolve()
    directory = path.parent
    if directory.parent.name == cache.CACHE_DIR and directory.name.startswith(f"{name}-"):
        return cache.Entry(directory.parent.parent, name, directory.name[len(name) + 1:])
    digest = cache.file_digest(path)
    for candidate in sorted((directory / cache.CACHE_DIR).glob(f"{name}-*")):
        try:
            if (candidate / "module.sha256").read_text().strip() == digest:
                return cache.Entry(directory, name, candidate.name[len(name) + 1:])
        except OSError:
            continue
    raise BuildError(
        f"the analysis functions of compiled model {name!r} are compiled on first use from its "
        f"cache entry, and none in {directory / cache.CACHE_DIR} holds {path.name}: build the "
        f"model again into the directory it is loaded from (lagrgen.build(model, "
        f"out_dir={str(directory)!r}))")


def description_of(entry, info):
    """The description of the model of `entry`: the one built in this process if any, else the
    one the entry keeps, checked against the model's content hash (of the formulation asked for:
    None, lagrgen's choice, or the one the model uses)."""
    built = cache.described(info.content_hash)
    if built is not None:
        return built
    spec = cache.kept_description(entry)
    digests = {content_digest(spec, asked, lambda: derived(spec))
               for asked in (None, info.formulation)}
    if info.content_hash in digests:
        return spec
    if cache.kept_generator(entry) == cache.generator_digest():
        raise BuildError(
            f"the cache entry {entry.directory} keeps the {cache.DESCRIPTION} of another model "
            f"({spec.name!r} with coordinates {', '.join(spec.coordinate_names)}) than compiled "
            f"model {info.name!r} (content hash {info.content_hash}), so its analysis units "
            "cannot be compiled from it: rebuild the model with lagrgen.build(model, "
            f"out_dir={str(entry.out_dir)!r}, force=True)")
    raise BuildError(
        f"compiled model {info.name!r} was built by another version of lagrgen or SymPy than "
        f"the one running, which cannot compile its {entry.directory.name} analysis units "
        "to match: rebuild the model")


runtime_units.register(unit_module)
