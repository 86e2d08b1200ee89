"""lagrgen: Lagrange's equations of motion, derived symbolically and compiled to C.

The package face is lazy (PEP 562): `import lagrgen` loads only the version and the exceptions;
SymPy, SciPy and matplotlib are imported when a function that needs them is first used, and a
module of the package (`lagrgen.tree`, `lagrgen.options`, ...) when it is first named.
"""
import importlib
import importlib.util
import sys
import types

from ._version import __version__
from .errors import (BuildError, CompileError, ConstraintError, ContactError, LagrgenError,
                     MassMatrixError, ModelError, NearSingularMassMatrixWarning,
                     NonFiniteError, StoreError, StoreWarning, UnknownNameError)

#: Public name -> the module that defines it.
_LAZY = {
    "Model": "model",
    "build": "build", "load": "cache",
    "simulate": "simulate", "evaluate_outputs": "simulate", "output_event": "simulate",
    "Signal": "signals",
    "simulate_many": "ensemble", "EnsembleResult": "ensemble",
    "open_ensemble": "ensemble_store",
    "sweep": "sweep",
    "fit": "fit", "fit_modes": "fit", "FitWarning": "fit",
    "IdentifiabilityWarning": "identifiability",
    "base_parameters": "inertial", "identify_inertial": "inertial",
    "exciting_trajectory": "inertial",
    "equilibrium": "vibration", "linearize": "linearization", "modes": "vibration",
    "frequency_response": "vibration", "FrozenTimeWarning": "vibration",
    "UnstableModeWarning": "vibration", "NotAnEquilibriumWarning": "vibration",
    "eigenvalue_sweep": "stability",
    "consistent_state": "constraints", "ConstraintWarning": "constraints",
    "from_sympy": "sympy_interop", "from_urdf": "urdf", "base_state": "base_state",
    "URDFError": "urdf", "URDFWarning": "urdf",
    "UntrackedEventsWarning": "hybrid",
    "export_fmu": "build",
    "Collocation": "collocation", "CollocationResult": "collocation",
    "rotation": None,
}

__all__ = ["Model", "build", "load", "simulate", "evaluate_outputs", "output_event", "Signal",
           "simulate_many", "EnsembleResult", "open_ensemble", "sweep", "equilibrium", "linearize",
           "modes", "eigenvalue_sweep",
           "frequency_response", "FrozenTimeWarning", "UnstableModeWarning", "NotAnEquilibriumWarning",
           "FitWarning", "IdentifiabilityWarning", "base_parameters", "identify_inertial",
           "exciting_trajectory", "consistent_state",
           "from_sympy", "from_urdf", "base_state", "URDFError", "URDFWarning", "export_fmu", "rotation", "Collocation", "CollocationResult",
           "UntrackedEventsWarning", "ConstraintWarning",
           "LagrgenError", "ConstraintError", "ModelError", "UnknownNameError", "MassMatrixError",
           "BuildError", "CompileError", "NonFiniteError", "ContactError", "StoreError", "StoreWarning",
           "NearSingularMassMatrixWarning", "__version__"]


class _Package(types.ModuleType):
    """The package module. `build` and `simulate` are both functions of the face and the modules
    that define them; importing such a module must not replace the function on the package."""

    def __setattr__(self, name, value):
        if isinstance(value, types.ModuleType) and _LAZY.get(name) == name:
            return  # the module stays importable: `from lagrgen.build import ...`
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name):
    if name not in _LAZY:
        if not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}"):
            return importlib.import_module(f".{name}", __name__)
        raise AttributeError(f"module 'lagrgen' has no attribute {name!r}")
    module_name = _LAZY[name]
    if module_name is None:
        value = importlib.import_module(f".{name}", __name__)
    else:
        value = getattr(importlib.import_module(f".{module_name}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
