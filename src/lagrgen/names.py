"""What may name a model and the things in it. Imports no SymPy: `lagrgen.load` checks a model's
name here before importing its module, and the runtime reads a user's keys with `key_name`."""
import keyword
import sys

from .errors import ModelError

#: Names a model cannot take: lagrgen and the packages it runs on (besides the standard library's).
RESERVED_NAMES = frozenset({"lagrgen", "numpy", "scipy", "sympy", "symengine", "matplotlib",
                            "Cython", "setuptools", "pytest", "dask", "distributed", "fmpy",
                            "mujoco", "filelock", "mpmath", "PIL"})
MAX_NAME_LENGTH = 100


def check_name(name, what="name"):
    """Return `name` if it is a valid, non-keyword Python identifier, else raise ModelError."""
    if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
        raise ModelError(
            f"invalid {what} {name!r}: names must be valid Python identifiers "
            "(letters, digits and underscores, not starting with a digit, not a Python keyword)")
    return name


def check_model_name(name):
    """Return `name` if it can name a compiled module: an ASCII identifier other than 'lagrgen'."""
    check_name(name, "model name")
    if not name.isascii():
        raise ModelError(f"invalid model name {name!r}: it becomes the name of a compiled Python "
                         "module, so use ASCII letters, digits and underscores only")
    if len(name) > MAX_NAME_LENGTH:
        raise ModelError(f"model name {name[:20]}... is {len(name)} characters long: it names "
                         f"files, so use at most {MAX_NAME_LENGTH}")
    if name in RESERVED_NAMES or name in getattr(sys, "stdlib_module_names", ()):
        raise ModelError(f"a model cannot be called {name!r}: that is the name of a module Python "
                         "or lagrgen needs, which the compiled model would hide; choose another name")
    return name


def key_name(key):
    """The name a user's key stands for: a str, a SymPy Symbol, or an applied function u(t)."""
    if isinstance(key, str):
        return key
    if getattr(key, "is_Symbol", False):
        return key.name
    func = getattr(key, "func", None)
    if getattr(key, "is_Function", False) and getattr(func, "__name__", None):
        return func.__name__
    raise TypeError(f"keys must be names (str) or the SymPy symbols/functions the model returned, "
                    f"got {key!r} of type {type(key).__name__}")
