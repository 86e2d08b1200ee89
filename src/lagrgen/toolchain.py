"""The C toolchain: the compiler command and flags, running the compiler, and durable atomic writes.

Under both the build (`lagrgen.build`) and the FMU writer (`lagrgen.codegen.fmu`), so that no writer
reaches into the build. Imports nothing of lagrgen but the exceptions.
"""
import os
import shlex
import subprocess
import sysconfig
import tempfile
import time
from pathlib import Path

from .errors import BuildError, CompileError

DEFAULT_CFLAGS = ("-fPIC", "-fno-math-errno", "-std=gnu11")
#: The headers generated code includes (lagrgen_model.h, the FMI headers' folder).
TEMPLATES = Path(__file__).resolve().parent / "codegen" / "templates"


def compiler_command():
    """The C compiler as an argument list (from Python's build configuration, or $CC)."""
    cc = os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    return shlex.split(cc)


def compile_flags(opt_level="-O2", cflags=()):
    """The compiler flags: lagrgen's defaults, the optimization level and the user's extra flags
    (a list of separate flags; one string is split like a shell would)."""
    if isinstance(cflags, str):
        cflags = shlex.split(cflags)
    return [*DEFAULT_CFLAGS, opt_level, *cflags]


def compile_module(source_path, output_path, flags):
    """Compile `source_path` into the extension module `output_path`; CompileError on failure."""
    compile_units([source_path], output_path, flags)


#: Flags that, given when linking, make GCC add startup code (crtfastmath.o) that switches the
#: whole process to flush subnormals to zero the moment the module is loaded; they are kept for
#: compiling, where they act on the model's own code only.
PROCESS_WIDE_FLAGS = ("-ffast-math", "-Ofast", "-funsafe-math-optimizations")


def link_flags(flags):
    """`flags` without those that would change the floating-point mode of the whole process."""
    return [f for f in flags if f not in PROCESS_WIDE_FLAGS]


def run_compiler(cmd, source_path):
    """Run the compiler command `cmd` on `source_path`; BuildError or CompileError on failure."""
    run_compilers([(cmd, source_path)], 1)


def compile_jobs():
    """How many compiler processes run at once: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def compile_units(sources, output_path, flags, unit_flags=None):
    """Compile the translation units `sources` (paths; the first is the module glue) to objects,
    `compile_jobs()` compilers at once, and link them into the extension module `output_path`.
    `unit_flags(path)` may return the flags of one unit (default: `flags`)."""
    include = sysconfig.get_paths()["include"]
    templates = str(TEMPLATES)

    def command(source):
        own = unit_flags(source) if unit_flags else flags
        return [*compiler_command(), "-c", *own, "-I", include, "-I", templates,
                _path_argument(source), "-o", _path_argument(source.with_suffix(".o"))]

    run_compilers([(command(source), source) for source in sources], compile_jobs())
    run_compiler([*compiler_command(), "-shared", *link_flags(flags),
                  *(_path_argument(path.with_suffix(".o")) for path in sources), "-o",
                  _path_argument(output_path)], output_path)


#: Seconds between looks at the running compilers.
POLL_SECONDS = 0.005


def run_compilers(jobs, at_once):
    """Run the compiler commands of `jobs`, (command, source path) pairs, `at_once` at a time;
    BuildError or CompileError on the first failure.

    The compilers are processes started and watched from the calling thread, without worker
    threads: an interrupt (Ctrl-C) or a failed unit kills the ones running and raises at once,
    and no lock is ever held that an interrupt could leave taken (a ThreadPoolExecutor's could,
    and hang the build or the interpreter's exit)."""
    pending, running = list(jobs), []
    try:
        while pending or running:
            while pending and len(running) < at_once:
                running.append(_Compiler(*pending.pop(0)))
            finished = [job for job in running if job.process.poll() is not None]
            if not finished:
                time.sleep(POLL_SECONDS)
            for job in finished:
                running.remove(job)
                job.check()
    finally:
        for job in running:
            job.kill()


class _Compiler:
    """One compiler process, its output kept in a temporary file."""

    def __init__(self, cmd, source_path):
        self.cmd, self.source_path = cmd, source_path
        self.log = tempfile.TemporaryFile()
        try:
            self.process = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=self.log,
                                            stderr=subprocess.STDOUT)
        except BaseException as exc:
            self.log.close()
            if isinstance(exc, FileNotFoundError):
                raise BuildError(
                    f"no C compiler found (tried {cmd[0]!r}): install one (e.g. `apt-get "
                    "install gcc`), set $CC, or use lagrgen.build(model, backend='python')"
                ) from None
            raise

    def check(self):
        """CompileError with the compiler's first 60 lines when it failed."""
        code = self.process.returncode
        self.log.seek(0)
        text = self.log.read().decode(errors="replace")
        self.log.close()
        if code != 0:
            message = "\n".join(text.strip().splitlines()[:60])
            raise CompileError(
                f"the C compiler failed on {self.source_path.name} (exit {code}):\n{message}\n"
                f"command: {' '.join(shlex.quote(c) for c in self.cmd)}")

    def kill(self):
        """Kill and reap the process with bounded waits only (an interrupt inside Popen.poll
        can leave Popen's own lock held: then it is reaped directly)."""
        try:
            self.process.kill()
        except OSError:
            pass
        try:
            self.process.wait(timeout=1)
        except subprocess.TimeoutExpired:
            try:
                os.waitpid(self.process.pid, 0)
            except (ChildProcessError, OSError):
                pass
        finally:
            self.log.close()


def _path_argument(path):
    """`path` absolute, so that a folder named like an option (``-O3``, ``--x``) is read as a
    file by the compiler."""
    return os.path.abspath(path)


# -- files -----------------------------------------------------------------------------------
def _fsync_dir(path):
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_atomic(dest, data, mode=0o644):
    """Write the bytes `data` to `dest` atomically and durably: a reader sees the old or the new
    file, never a part, and a file open or mapped elsewhere (a loaded module) keeps its contents."""
    fd, tmp = tempfile.mkstemp(dir=dest.parent, prefix=f".{dest.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, dest)
        _fsync_dir(dest.parent)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
