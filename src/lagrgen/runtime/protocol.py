"""The interface of a built model (API.md §3), as both backends provide it.

A compiled model is the imported module itself (its attributes are bound by
`lagrgen.runtime._compiled.bind_module`); a Python model is a `PythonModel`. Their model functions
come from one registry, `lagrgen.functions.FUNCTIONS`; this Protocol documents the result for
readers and type checkers.
"""
from typing import Protocol, Tuple

import numpy as np


class BuiltModel(Protocol):
    """What `lagrgen.build` returns, on either backend."""

    name: str
    backend: str                  # "c" or "python"
    coordinates: Tuple[str, ...]
    parameters: Tuple[str, ...]
    inputs: Tuple[str, ...]
    defaults: np.ndarray          # float64, NaN where a value must be given at run time
    n_coordinates: int
    content_hash: str             # of the derived equations and lagrgen's generator
    dimensions: dict              # sizes the output shapes refer to ("n", "2n", "n_inputs", ...)

    def mass_matrix(self, q, t=0.0, p=None, u=None) -> np.ndarray:
        """M(q, t), (n, n)."""

    def forcing(self, q, qd, t=0.0, p=None, u=None) -> np.ndarray:
        """F(q, q̇, t, u), (n,), with M·q̈ = F."""

    def rhs(self, t, y, p=None, u=None) -> np.ndarray:
        """ẏ = [q̇, M⁻¹F] for y = [q, q̇], (2n,)."""

    def jacobian(self, t, y, p=None, u=None) -> np.ndarray:
        """∂ẏ/∂y, (2n, 2n), analytic."""

    def linear_terms(self, q, qd, t=0.0, p=None, u=None) -> tuple:
        """(M, ∂F/∂q, ∂F/∂q̇, ∂F/∂u) at one point."""
