"""Exceptions raised by lagrgen. Each says what is wrong and how to fix it."""
import numpy as np


class LagrgenError(Exception):
    """Base class of every error lagrgen raises on purpose."""


class ModelError(LagrgenError, ValueError):
    """The model description is invalid (bad name, unknown symbol, unsupported function...)."""


class UnknownNameError(LagrgenError, ValueError, KeyError):
    """A parameter or input name given at run time is not one of the model's."""

    def __str__(self):
        return str(self.args[0]) if self.args else ""


class MassMatrixError(LagrgenError, np.linalg.LinAlgError):
    """The mass matrix is not symmetric positive definite at the state asked for."""


class BuildError(LagrgenError, RuntimeError):
    """Generating, compiling or loading a compiled model failed."""


class CompileError(BuildError):
    """The C compiler rejected the generated code; the message carries its output."""
