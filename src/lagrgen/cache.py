"""The build cache of an output directory: what identifies a build (digests and the key), its
immutable entries, their lock, how an entry is stored, checked, repaired, published and imported.

Layout of an output directory:
    <name>_model.h, <name>_model.c  the standalone C model (plain C, no Python)
    <name><EXT_SUFFIX>              the model's module, importable with the directory on sys.path
    __lagrgen__/<name>-<key>/       the cache: one immutable entry per key
    __lagrgen__/<name>.current      the key of the entry last published into the directory
    __lagrgen__/<name>.lock         held while an entry of <name> is made or published

The key is a hash of what is compiled: the frozen model description (every symbol with its
assumptions; or the equations themselves when M and F come from outside, as from `from_sympy`),
lagrgen's generator sources and version, the versions of SymPy and SymEngine, the compiler and
flags. So no change to a model, and no change to lagrgen, can be served stale, and a cache hit
derives nothing.

An entry holds compiled *units*. A unit is a directory with the sources it was compiled from,
its extension module `<module><EXT_SUFFIX>`, `module.sha256`, the digest of that module taken
when it was made, and (the model's own unit and its units compiled on first use)
`content.sha256`, the content digest of the model it was compiled from, which the module also
carries in its metadata (`content_hash`): a unit is sound when its module is whole (an ELF file
cut short is not, whatever its digest says: `whole_module`), matches its digest and carries the
content digest expected of it, so a module copied from another model (with its digests) or cut
short is never imported, and an imported module whose `content_hash` differs is refused. The model's own module is the entry's main unit: the
entry directory itself, module `<name>`. Further units (say an analysis compiled on first use)
live inside the entry, each in its own directory `<entry>/<label>-<key of its own digest>/` with
module `<name>_<label>` (`Entry.unit(label, digest)`), so one entry may hold any number of them,
each looked up, made, checked and repaired like the main unit, and discarded with its entry.

Every unit is made in a private directory beside its final place and renamed into place after an
fsync (`store`), so a build that dies halfway leaves nothing a later lookup would pick up; a unit
that is not sound (`lookup`), or does not import, is discarded and made again
(`import_or_repair`). Publishing copies the main unit's module and standalone C into the output
directory by atomic writes and then records the key (`publish`).

A marker that is not a key (damaged, binary junk) counts as absent; `load` imports only a module
it has verified so (never a published file it cannot check: a truncated module would crash the
process at import), and publishing repairs every published file (module and standalone C) that
differs from its entry's.

The interface: `key` (the cache key of a build), `Entry` (where an entry and its units live),
`writing` (the entry's lock), `lookup` (is a unit there and sound), `store`, `import_or_repair`,
`publish`, and `load` (the module last published into a directory).
"""
import dataclasses
import functools
import hashlib
import importlib.machinery
import importlib.util
import os
import re
import shutil
import sys
import sysconfig
import tempfile
import time
import weakref
from contextlib import contextmanager
from pathlib import Path

from ._version import __version__
from .caching import once_per
from .errors import BuildError
from .names import check_model_name
from .toolchain import _fsync_dir, compiler_command, write_atomic

EXT_SUFFIX = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
CACHE_DIR = "__lagrgen__"
PACKAGE = Path(__file__).resolve().parent
#: The sources that determine generated code: a change to any of them changes every key.
GENERATOR_SOURCES = ("_version.py", "functions.py", "calculus.py", "terms.py", "contributions.py",
                     "lagrange.py", "nonsmooth.py", "tree.py", "tree3d.py", "frames.py",
                     "kernels.py", "trace.py", "lean3d.py", "dimensions.py",
                     "runtime/info.py",
                     "codegen/*.py", "codegen/templates/*", "codegen/templates/functions/*")
#: Imported extension modules by resolved path: a file is imported once per process.
_loaded = {}
#: What a key looks like (`key`): a marker holding anything else counts as absent.
KEY_PATTERN = re.compile(r"[0-9a-f]{20}")
#: The file of a unit recording the content digest of what it was compiled from.
CONTENT_FILE = "content.sha256"


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
             hybrid_description(spec, equations), spec.initial_state]
    for part in parts:
        h.update(repr(part).encode() + b"\0")
    return h.hexdigest()


def hybrid_description(spec, equations):
    """The impacts' and frictions' records and terms, for the content hash."""
    if not spec.nonsmooth:
        return []
    from . import nonsmooth
    return [nonsmooth.describe(spec), [str(e) for e in nonsmooth.terms(equations)]]


def key(digest, flags):
    """The cache key: the content digest, the compiler, its flags and the module suffix."""
    h = hashlib.sha256(digest.encode())
    h.update(repr((flags, compiler_command(), EXT_SUFFIX)).encode())
    return h.hexdigest()[:20]


def file_digest(path):
    """sha256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# -- entries and units -----------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Unit:
    """One compiled module in the cache: the directory holding it and the module's name."""
    directory: Path
    module: str

    @property
    def module_file(self):
        """The extension module's file: `<directory>/<module><EXT_SUFFIX>`."""
        return self.directory / f"{self.module}{EXT_SUFFIX}"


@dataclasses.dataclass(frozen=True)
class Entry:
    """The cache entry of the model `name` with the key `key` in `out_dir`."""
    out_dir: Path
    name: str
    key: str

    @property
    def cache(self):
        """The cache directory `<out_dir>/__lagrgen__`."""
        return Path(self.out_dir) / CACHE_DIR

    @property
    def directory(self):
        return self.cache / f"{self.name}-{self.key}"

    @property
    def main(self):
        """The model's own module: the entry directory itself."""
        return Unit(self.directory, self.name)

    def unit(self, label, digest):
        """A further compiled unit of this entry, identified by its own content `digest`:
        `<entry>/<label>-<key>/`, module `<name>_<label>`. Make it with `store` under `writing`."""
        check_model_name(f"{self.name}_{label}")
        return Unit(self.directory / f"{label}-{hashlib.sha256(digest.encode()).hexdigest()[:20]}",
                    f"{self.name}_{label}")

    @property
    def marker(self):
        """The file naming the key last published into out_dir."""
        return self.cache / f"{self.name}.current"

    @property
    def lock_file(self):
        return self.cache / f"{self.name}.lock"


#: What a model's entry keeps for its units compiled on first use: the frozen description
#: (pickled; SymPy objects pickle with their assumptions), the compiler flags of the build and
#: the generator's digest (which tells a description of another model from one another version
#: of lagrgen or SymPy made).
DESCRIPTION, FLAGS, GENERATOR = "description.pickle", "flags.json", "generator.sha256"


def keep_description(directory, spec, flags):
    """Write the description `spec`, the build's `flags` and the generator's digest into an
    entry's `directory`."""
    import json
    import pickle
    write_atomic(Path(directory) / DESCRIPTION, pickle.dumps(spec, pickle.HIGHEST_PROTOCOL))
    write_atomic(Path(directory) / FLAGS, json.dumps(list(flags)).encode())
    write_atomic(Path(directory) / GENERATOR, (generator_digest() + "\n").encode())


#: Descriptions built in this process, by content hash (held weakly).
_described = weakref.WeakValueDictionary()


def remember_description(content_hash, spec):
    """Note that `spec` is the description of the model with `content_hash` (see `described`)."""
    _described[content_hash] = spec


def described(content_hash):
    """The description of that content hash built in this process, or None."""
    return _described.get(content_hash)


def kept_description(entry):
    """The description kept in `entry` by `keep_description`."""
    import pickle
    return _kept(entry, DESCRIPTION, pickle.loads)


def kept_flags(entry):
    """The build's compiler flags kept in `entry` by `keep_description`."""
    import json
    return _kept(entry, FLAGS, json.loads)


def kept_generator(entry):
    """The generator digest kept in `entry` by `keep_description` (None: none readable)."""
    return read_text_file(entry.directory / GENERATOR)


def _kept(entry, file_name, read):
    """`read(bytes)` of the entry's file; BuildError when it is missing (an entry made by an
    older lagrgen) or unreadable."""
    try:
        return read((entry.directory / file_name).read_bytes())
    except Exception as exc:   # OSError, or whatever unpickling or parsing raises
        raise BuildError(f"the cache entry {entry.directory} does not keep the {file_name} of "
                         f"model {entry.name!r} ({type(exc).__name__}: {exc}): rebuild it with "
                         "this lagrgen") from None


def read_text_file(path):
    """The stripped ASCII text of a small file, or None if it is missing, unreadable or not
    ASCII text."""
    try:
        return Path(path).read_bytes().decode("ascii").strip()
    except (OSError, UnicodeDecodeError):
        return None


def recorded_content(unit):
    """The content digest recorded in the unit when it was made (None: none recorded)."""
    text = read_text_file(unit.directory / CONTENT_FILE)
    return text if text and re.fullmatch(r"[0-9a-f]{64}", text) else None


def lookup(unit, content_hash=None):
    """True if the unit's module exists, is whole (`whole_module`) and matches the digest recorded
    when it was made, and, when a content digest is expected (`content_hash`, or the one the unit
    records), the unit records that digest and its module carries it."""
    try:
        data = unit.module_file.read_bytes()
    except OSError:
        return False
    if read_text_file(unit.directory / "module.sha256") != hashlib.sha256(data).hexdigest():
        return False
    if not whole_module(data):
        return False
    recorded = recorded_content(unit)
    expected = content_hash or recorded
    if expected is None:
        return True
    return recorded == expected and f'"content_hash": "{expected}"'.encode() in data


#: ELF: (the header's struct format, the offsets in a program header of p_offset and p_filesz and
#: their format), by EI_CLASS (1: 32-bit, 2: 64-bit).
_ELF_LAYOUT = {1: ("16xHHIIIIIHHHHHH", 4, 16, "I"), 2: ("16xHHIQQQIHHHHHH", 8, 32, "Q")}
_PT_LOAD = 1


def whole_module(data):
    """False when `data`, a shared library's bytes, is an ELF file cut short: its program or
    section header table, or a segment the dynamic loader maps, reaches past its end (the loader
    does not check, and the process dies of SIGBUS when it touches the missing pages, even when
    the digest recorded beside it matches). Other formats are True: the loaders of Mach-O and PE
    refuse a file shorter than its segments."""
    import struct
    if data[:4] != b"\x7fELF" or len(data) < 6 or data[4] not in _ELF_LAYOUT \
            or data[5] not in (1, 2):
        return data[:4] != b"\x7fELF"
    header, p_offset, p_filesz, word = _ELF_LAYOUT[data[4]]
    order = "<" if data[5] == 1 else ">"
    try:
        (_, _, _, _, phoff, shoff, _, _, phentsize, phnum, shentsize, shnum,
         _) = struct.unpack_from(order + header, data)
        if phoff + phnum * phentsize > len(data) or shoff + shnum * shentsize > len(data):
            return False
        for k in range(phnum):
            at = phoff + k * phentsize
            kind, = struct.unpack_from(order + "I", data, at)
            offset, = struct.unpack_from(order + word, data, at + p_offset)
            size, = struct.unpack_from(order + word, data, at + p_filesz)
            if kind == _PT_LOAD and offset + size > len(data):
                return False
    except struct.error:
        return False
    return True


def check_content(module, content_hash, where):
    """`module` if it carries `content_hash` (its metadata's), else BuildError saying so."""
    found = getattr(module, "content_hash", None)
    if content_hash is not None and found != content_hash:
        raise BuildError(f"the compiled module {where} is not the model it should be (content "
                         f"hash {found!r}, expected {content_hash!r}): it was copied from "
                         "another model; rebuild with lagrgen.build(model, out_dir=..., "
                         "force=True)")
    return module


def discard(directory):
    """Remove a unit's directory (renamed away first, so no reader sees it half-deleted)."""
    if directory.exists():
        trash = directory.with_name(
            f".trash-{directory.name}-{os.getpid()}-{time.monotonic_ns()}")
        os.replace(directory, trash)
        shutil.rmtree(trash, ignore_errors=True)


#: A unit's work directory untouched this long is a build that was killed (kill -9, a power cut).
ABANDONED_SECONDS = 3600.0


def remove_abandoned(unit):
    """Remove the work directories of earlier builds of `unit` (`.build-<module>-*`) that were
    left behind by a killed process, untouched for ABANDONED_SECONDS: they stayed for good."""
    now = time.time()
    for stale in unit.directory.parent.glob(f".build-{unit.module}-*"):
        try:
            if now - stale.stat().st_mtime > ABANDONED_SECONDS:
                shutil.rmtree(stale, ignore_errors=True)
        except OSError:
            pass


def store(unit, make, content_hash=None):
    """Make `unit`: `make(work)` writes the sources into the private directory `work` and
    compiles `work/<module><EXT_SUFFIX>`; then its digest (and the `content_hash` of what it was
    compiled from, when given) is recorded, the module fsynced and the directory renamed into
    place (replacing any earlier one). Call it under `writing`."""
    unit.directory.parent.mkdir(parents=True, exist_ok=True)
    remove_abandoned(unit)
    work = Path(tempfile.mkdtemp(dir=unit.directory.parent, prefix=f".build-{unit.module}-"))
    try:
        made = Unit(work, unit.module)
        make(work)
        lib = made.module_file
        for obj in work.glob("*.o"):
            obj.unlink()
        write_atomic(work / "module.sha256", (file_digest(lib) + "\n").encode())
        if content_hash is not None:
            write_atomic(work / CONTENT_FILE, (content_hash + "\n").encode())
        for path in work.iterdir():
            os.chmod(path, 0o755 if path == lib else 0o644)
        with open(lib, "rb") as fh:
            os.fsync(fh.fileno())
        discard(unit.directory)
        os.replace(work, unit.directory)
        _fsync_dir(unit.directory.parent)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def import_or_repair(unit, make, note=lambda text: None, content_hash=None):
    """Import the unit's module; if that fails, make it again with `make` (see `store`) and
    import that; BuildError if the imported module does not carry `content_hash`. Call it under
    `writing`."""
    try:
        module = import_extension(unit.module, unit.module_file)
    except BuildError as first:
        note(f"cached module did not import ({first}); compiling again")
        store(unit, make, content_hash)
        module = import_extension(unit.module, unit.module_file)
    return check_content(module, content_hash, str(unit.module_file))


@contextmanager
def locked(path):
    """Hold an exclusive lock on the file `path` (created if missing) against other processes and
    threads, on any platform (`filelock`: flock on POSIX, msvcrt on Windows; imported here, so
    importing lagrgen needs neither)."""
    from filelock import FileLock
    with FileLock(str(path)):
        yield


class ReadOnlyCache(BuildError):
    """The cache of an output directory cannot be written (no lock can be taken there)."""


@contextmanager
def writing(entry):
    """Hold the lock of `entry`'s model in its out_dir while entries are made and published;
    ReadOnlyCache when the cache cannot be written (then only what is published can be read)."""
    try:
        entry.cache.mkdir(parents=True, exist_ok=True)
        lock = locked(entry.lock_file)
        lock.__enter__()
    except OSError as exc:
        raise ReadOnlyCache(f"cannot write the build of {entry.name!r} into {entry.out_dir}: "
                            f"{exc}") from None
    try:
        yield
    finally:
        lock.__exit__(None, None, None)


def read_marker(path):
    """The key a marker file names, or None when it is missing or holds anything but a key."""
    text = read_text_file(path)
    return text if text is not None and KEY_PATTERN.fullmatch(text) else None


def is_published(entry):
    """True if `entry` is what out_dir's module and marker are, as far as the marker says."""
    return (Path(entry.out_dir) / f"{entry.name}{EXT_SUFFIX}").exists() and \
        read_marker(entry.marker) == entry.key


def published_files(entry):
    """{published file in out_dir: its source in the entry}: the module and the standalone C."""
    out_dir, name = Path(entry.out_dir), entry.name
    files = {out_dir / f"{name}{EXT_SUFFIX}": entry.main.module_file}
    files.update({out_dir / f: entry.directory / f for f in (f"{name}_model.h",
                                                              f"{name}_model.c")})
    return files


def same_file(a, b):
    """True if the files `a` and `b` hold the same bytes (a missing `a` holds none)."""
    try:
        return a.stat().st_size == b.stat().st_size and file_digest(a) == file_digest(b)
    except OSError:
        return False


def publish(entry, force=False):
    """Make `<name><EXT>`, `<name>_model.h` and `<name>_model.c` in out_dir the files of `entry`
    (each that differs from its entry's: a damaged one is repaired), then record its key. Call
    it under `writing`."""
    published = is_published(entry)
    for target, source in published_files(entry).items():
        if force or not published or not same_file(target, source):
            mode = 0o755 if target.name.endswith(EXT_SUFFIX) else 0o644
            write_atomic(target, source.read_bytes(), mode)
    if not published:
        write_atomic(entry.marker, (entry.key + "\n").encode())


def load(name, out_dir="generated"):
    """Import the compiled model `name` built earlier into `out_dir`.

    Parameters
    ----------
    name : str
        The model's name.
    out_dir : str or pathlib.Path
        The directory it was built into.

    Returns
    -------
    module
        The built model (`runtime.protocol.BuiltModel` in the API reference), from the cache
        entry last published into `out_dir`, after checking its module against the digest and the
        content hash recorded when it was made.

    Raises
    ------
    BuildError
        If no such model was built into `out_dir`, its build cannot be verified (no cache entry,
        a damaged one, or a module of another model), or it does not import.
    """
    check_model_name(name)
    out_dir = Path(out_dir)
    key = read_marker(out_dir / CACHE_DIR / f"{name}.current")
    rebuild = (f"rebuild it with lagrgen.build(model, out_dir={str(out_dir)!r}) or `python -m "
               f"lagrgen build MODEL.py --out {out_dir}`")
    if key is not None:
        entry = Entry(out_dir, name, key)
        content_hash = recorded_content(entry.main)
        if content_hash is not None and lookup(entry.main, content_hash):
            return check_content(import_extension(name, entry.main.module_file), content_hash,
                                 str(entry.main.module_file))
        raise BuildError(f"the build of {name!r} in {out_dir} cannot be verified: its cache "
                         f"entry {entry.directory.name} is missing, damaged or holds another "
                         f"model's module; {rebuild}")
    if (out_dir / f"{name}{EXT_SUFFIX}").exists():
        raise BuildError(f"the compiled model {name!r} in {out_dir} has no readable record of "
                         f"its build ({CACHE_DIR}/{name}.current), so its module cannot be "
                         f"verified before import; {rebuild}")
    raise BuildError(
        f"no compiled model {name!r} in {out_dir}: build it first with lagrgen.build(model, "
        f"out_dir={str(out_dir)!r}) or `python -m lagrgen build MODEL.py --out {out_dir}`")


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
