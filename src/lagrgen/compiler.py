"""The compiler driver: C source from templates, compilation, the content-hash cache, loading.

Layout of an output directory:
    <name>.c, <name><EXT_SUFFIX>   the model's C and its module, importable with the directory on sys.path
    __lagrgen__/<name>-<key><EXT>  the cache: one immutable module file per content key
    __lagrgen__/<name>.current     the key of the module last published as <name><EXT>
Everything is written to a temporary file first and renamed into place, so a build that dies halfway
leaves nothing a later load would pick up, and concurrent builds of one model both succeed.
"""
import fcntl
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from string import Template

from . import __version__
from .errors import BuildError, CompileError
from .kernels import all_kernels
from .model import check_model_name
from .printer import c_function, kernel_statements

EXT_SUFFIX = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
CACHE_DIR = "__lagrgen__"
DEFAULT_CFLAGS = ("-fPIC", "-fno-math-errno", "-std=gnu11")
_loaded = {}


def templates_dir():
    """The directory of the C templates (installed as the package lagrgen.templates)."""
    try:
        import lagrgen.templates as templates
        return Path(templates.__file__).parent
    except ImportError:
        return Path(__file__).resolve().parents[2] / "templates"


def read_template(name):
    return (templates_dir() / name).read_text()


# -- C source --------------------------------------------------------------------------------
def c_string(text):
    """`text` as a C string literal."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def legend(metadata):
    """Comment lines saying which array entry holds which of the user's names."""
    lines = [f" *   q[{i}] = {c} (qd[{i}] its rate, a[{i}] its acceleration)"
             for i, c in enumerate(metadata["coordinates"])]
    lines += [f" *   p[{i}] = {name}" for i, name in enumerate(metadata["parameters"])]
    lines += [f" *   u[{i}] = {name}" for i, name in enumerate(metadata["inputs"])]
    return "\n".join(lines)


KERNEL_COMMENTS = {
    "mf": "M (N×N) and F (N), sharing their common subexpressions.",
    "jacobian_b": "B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇], N×2N, for a given a = q̈.",
    "dF_du": "∂F/∂u, N×N_INPUTS.",
}
KERNEL_PARAMS = ("double t, const double *q, const double *qd, const double *a, const double *p, "
                 "const double *u")


def kernel_functions(equations, max_statements=400):
    """The C functions lg_mf, lg_jacobian_b and lg_dF_du (split into parts when long)."""
    chunks = []
    for kernel in all_kernels(equations):
        outputs = list(kernel.outputs)
        params = KERNEL_PARAMS + "".join(f", double *{o}" for o in outputs)
        args = "t, q, qd, a, p, u" + "".join(f", {o}" for o in outputs)
        chunks.append(c_function(f"lg_{kernel.name}", params, args, kernel_statements(kernel),
                                 KERNEL_COMMENTS[kernel.name], max_statements))
    return "\n".join(chunks)


def c_source(metadata, equations, max_statements=400):
    """The complete C source of the model module (equations, linear algebra, module glue)."""
    linalg = Template(read_template("linalg.c.in")).substitute()
    return Template(read_template("model.c.in")).substitute(
        name=metadata["name"], version=__version__, content_hash=metadata["content_hash"],
        legend=legend(metadata), n=equations.n, n_params=len(metadata["parameters"]),
        n_inputs=len(metadata["inputs"]), linalg=linalg,
        metadata=c_string(json.dumps(metadata, sort_keys=True)),
        kernels=kernel_functions(equations, max_statements))


# -- compiling -------------------------------------------------------------------------------
def compiler_command():
    """The C compiler as an argument list (from Python's build configuration, or $CC)."""
    cc = os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    return shlex.split(cc)


def compile_flags(opt_level="-O2", cflags=()):
    return [*DEFAULT_CFLAGS, opt_level, *cflags]


def compile_module(source_path, output_path, flags):
    """Compile `source_path` into the extension module `output_path`; CompileError on failure."""
    include = sysconfig.get_paths()["include"]
    cmd = [*compiler_command(), "-shared", *flags, "-I", include, "-I", str(templates_dir()),
           str(source_path), "-o", str(output_path)]
    try:
        result = subprocess.run(cmd, capture_output=True, text=True)
    except FileNotFoundError:
        raise BuildError(
            f"no C compiler found (tried {cmd[0]!r}): install one (e.g. `apt-get install gcc`), "
            "set $CC, or use lagrgen.build(model, backend='python')") from None
    if result.returncode != 0:
        message = "\n".join((result.stderr or result.stdout).strip().splitlines()[:60])
        raise CompileError(
            f"the C compiler failed on {source_path.name} (exit {result.returncode}):\n{message}\n"
            f"command: {' '.join(shlex.quote(c) for c in cmd)}")


# -- cache -----------------------------------------------------------------------------------
def build_key(model, flags):
    """The cache key: the model's content hash, the compiler flags and the templates."""
    h = hashlib.sha256(model.content_hash().encode())
    h.update(repr((flags, compiler_command(), EXT_SUFFIX)).encode())
    for name in ("model.c.in", "linalg.c.in", "lagrgen_model.h"):
        h.update(read_template(name).encode())
    return h.hexdigest()[:20]


@contextmanager
def locked(path):
    """Hold an exclusive lock on the file `path` (created if missing)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def write_atomic(dest, data, mode=0o644):
    """Write the bytes `data` to `dest` atomically: a reader sees the old or the new file, never a
    part, and a file that is open or mapped elsewhere (a loaded module) keeps its old contents."""
    fd, tmp = tempfile.mkstemp(dir=dest.parent, prefix=f".{dest.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, mode)
        os.replace(tmp, dest)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def publish(src, dest):
    """Copy the file `src` to `dest` atomically, keeping its permissions."""
    write_atomic(dest, src.read_bytes(), os.stat(src).st_mode & 0o777)


def source_of(module_path):
    """The C source kept beside a cached module file."""
    return module_path.parent / f"{module_path.name[:-len(EXT_SUFFIX)]}.c"


def import_extension(name, path):
    """Import the extension module `name` from the file `path` (once per path and process)."""
    path = Path(path).resolve()
    if path in _loaded:
        return _loaded[path]
    loader = importlib.machinery.ExtensionFileLoader(name, str(path))
    spec = importlib.util.spec_from_file_location(name, str(path), loader=loader)
    try:
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
    except ImportError as exc:
        raise BuildError(f"cannot import compiled model {name!r} from {path}: {exc}") from None
    _loaded[path] = module
    return module


# -- build and load --------------------------------------------------------------------------
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


def build_c(model, out_dir, verbose=False, quiet=False, force=False, opt_level="-O2", cflags=()):
    """Derive, generate, compile, cache and import `model`; return the module (the built model).

    Progress lines go to stderr with `verbose`, or when stderr is a terminal unless `quiet`.
    """
    start = time.perf_counter()
    out_dir = Path(out_dir)
    cache = out_dir / CACHE_DIR
    cache.mkdir(parents=True, exist_ok=True)
    flags = compile_flags(opt_level, tuple(cflags))
    key = build_key(model, flags)
    cached = cache / f"{model.name}-{key}{EXT_SUFFIX}"
    progress = _Progress(model.name, verbose or (not quiet and sys.stderr.isatty()))
    with locked(cache / f"{model.name}.lock"):
        hit = cached.exists() and not force
        if not hit:
            _compile_into(model, cached, flags, progress)
        _publish_current(model.name, out_dir, cached, key)
    module = import_extension(model.name, cached)
    module.build_info = {"cache_hit": hit, "seconds": time.perf_counter() - start,
                         **progress.times}
    if hit:
        progress.note(f"cached build {cached.name}")
    return module


def _compile_into(model, cached, flags, progress):
    """Generate the model's C in a private temporary directory and compile it to `cached`."""
    metadata = model.metadata()
    progress.note("deriving the equations of motion ...")
    equations = model.equations().differentiate()
    progress.step("derive", f"{equations.n} coordinates")
    source = c_source(metadata, equations)
    progress.step("cse+emit", f"{len(source) / 1024:.0f} KiB of C")
    progress.note(f"compiling {len(source) / 1024:.0f} KiB of C ({' '.join(flags)}) ...")
    work = Path(tempfile.mkdtemp(dir=cached.parent, prefix=f".build-{model.name}-"))
    try:
        src = work / f"{model.name}.c"
        src.write_text(source)
        os.chmod(src, 0o644)
        lib = work / cached.name
        compile_module(src, lib, flags)
        progress.step("compile", f"{' '.join(flags)}, {lib.stat().st_size / 1024:.0f} KiB module")
        os.replace(src, source_of(cached))
        os.replace(lib, cached)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _publish_current(name, out_dir, cached, key):
    """Make <name><EXT> and <name>.c in out_dir the module of `key` (if they are not already)."""
    marker = cached.parent / f"{name}.current"
    module_file = out_dir / f"{name}{EXT_SUFFIX}"
    if module_file.exists() and marker.exists() and marker.read_text().strip() == key:
        return
    publish(cached, module_file)
    publish(source_of(cached), out_dir / f"{name}.c")
    write_atomic(marker, (key + "\n").encode())


def load_c(name, out_dir):
    """Import the compiled model `name` last built into `out_dir`."""
    check_model_name(name)
    out_dir = Path(out_dir)
    marker = out_dir / CACHE_DIR / f"{name}.current"
    if marker.exists():
        cached = out_dir / CACHE_DIR / f"{name}-{marker.read_text().strip()}{EXT_SUFFIX}"
        if cached.exists():
            return import_extension(name, cached)
    module_file = out_dir / f"{name}{EXT_SUFFIX}"
    if not module_file.exists():
        raise BuildError(
            f"no compiled model {name!r} in {out_dir}: build it first with lagrgen.build(model, "
            f"out_dir={str(out_dir)!r}) or `python -m lagrgen build MODEL.py --out {out_dir}`")
    return import_extension(name, module_file)
