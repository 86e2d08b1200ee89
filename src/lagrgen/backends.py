"""`build` and `load`: from a Model to a built model of either backend."""
from pathlib import Path

from .errors import ModelError
from .model import Model

BACKENDS = ("c", "python")


def build(model, out_dir="generated", backend="c", **options):
    """Derive, generate and (for backend "c") compile and import `model`; return the built model.

    The C backend caches by content hash in `out_dir`; options: `verbose`, `quiet`, `force`,
    `opt_level`. The Python backend ignores `out_dir`.
    """
    if not isinstance(model, Model):
        raise TypeError(f"build() takes a lagrgen.Model, got {type(model).__name__}")
    if backend == "python":
        from .pybackend import PythonModel
        return PythonModel(model.equations(), model.metadata())
    if backend == "c":
        from .compiler import build_c
        return build_c(model, Path(out_dir), **options)
    raise ModelError(f"unknown backend {backend!r}: use one of {', '.join(map(repr, BACKENDS))}")


def load(name, out_dir="generated"):
    """Import the compiled model `name` built earlier into `out_dir`."""
    from .compiler import load_c
    return load_c(name, Path(out_dir))
