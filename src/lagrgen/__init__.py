"""lagrgen: Lagrange's equations of motion, derived symbolically and compiled to C."""
__version__ = "0.1.0"

from .errors import (BuildError, CompileError, LagrgenError, MassMatrixError, ModelError,  # noqa: E402
                     UnknownNameError)
from .model import Model  # noqa: E402
from .backends import build, load  # noqa: E402
from .runner import simulate  # noqa: E402
from .vibration import equilibrium, frequency_response, linearize, modes  # noqa: E402
from . import rotation  # noqa: E402

__all__ = ["Model", "build", "load", "simulate", "equilibrium", "linearize", "modes",
           "frequency_response", "rotation", "LagrgenError", "ModelError", "UnknownNameError",
           "MassMatrixError", "BuildError", "CompileError", "__version__"]
