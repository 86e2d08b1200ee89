"""The interface of a built model (`BuiltModel` in the API reference), as both backends provide it.

A compiled model is the imported module itself (its attributes are bound by
`lagrgen.runtime._compiled.bind_module`); a Python model is a `PythonModel`. Both take their names,
sizes and flags from one `ModelInfo` (`INFO_ATTRIBUTES`) and their model functions from one
registry, `lagrgen.functions.FUNCTIONS`. These Protocols list every public name of the result, so
code that holds a built model reads them without guards (tests/test_structure.py checks both
backends against them).
"""
from typing import Dict, Protocol, Tuple

import numpy as np

from .info import ModelInfo


class BuiltModel(Protocol):
    """What `lagrgen.build` returns, on either backend."""

    info: ModelInfo               # the record the attributes below are read from
    name: str
    backend: str                  # "c" or "python"
    coordinates: Tuple[str, ...]
    parameters: Tuple[str, ...]
    inputs: Tuple[str, ...]
    defaults: np.ndarray          # float64, read-only, NaN where a value must be given at run time
    initial_state: np.ndarray     # float64 (2n,), read-only: the declared [q0, q̇0], or zeros
    units: Dict[str, str]         # name -> unit label, for the names that have one
    output_names: Tuple[str, ...]  # the user's outputs, then the three energies
    constraint_names: Tuple[str, ...]  # one per multiplier λ: holonomic, then velocity constraints
    event_definitions: Tuple[Tuple[str, int, int], ...]  # (name, terminal, direction)
    nonsmooth_definitions: Tuple[tuple, ...]  # (name, "impact" | "friction", normal), §13
    explicit_time: bool           # M or F depends on t explicitly
    formulation: str              # "dense" (Cholesky of M) or "recursive" (over the kinematic tree)
    inertial_parameters: Tuple[str, ...]  # the bodies' inertial parameters π, 10 per body (§21)
    limits: Dict[str, tuple]      # coordinate -> (lower, upper, velocity, effort), None if absent
    link_names: Tuple[str, ...]   # the links of a three-dimensional tree (§22), else ()
    content_hash: str             # of the derived equations and lagrgen's generator
    lagrgen_version: str
    n_coordinates: int
    n_constraints: int
    dimensions: Dict[str, int]    # sizes the output shapes refer to ("n", "2n", "n_inputs", ...)
    build_info: dict              # how the build went: cache_hit, seconds (and step times for C)

    def pivot_record(self) -> float:
        """The least pivot of M relative to its diagonal entry (1 for a diagonal M, tending to
        0 near a singular one) that the factorizations of M on this thread reached since the
        previous call, or 1.0 when none fell below 1e-3; resets the record (the engines read it
        around each solve)."""

    # -- one callable per entry of lagrgen.functions.FUNCTIONS --------------------------------
    def mass_matrix(self, q, t=0.0, p=None, u=None) -> np.ndarray:
        """M(q, t), (n, n)."""

    def forcing(self, q, qd, t=0.0, p=None, u=None) -> np.ndarray:
        """F(q, q̇, t, u), (n,), with M·q̈ = F."""

    def rhs(self, t, y, p=None, u=None) -> np.ndarray:
        """ẏ = [q̇, M⁻¹F] for y = [q, q̇], (2n,)."""

    def jacobian(self, t, y, p=None, u=None) -> np.ndarray:
        """∂ẏ/∂y, (2n, 2n), analytic."""

    def parameter_jacobian(self, t, y, p=None, u=None) -> np.ndarray:
        """∂ẏ/∂p, (2n, n_params), analytic."""

    def directional_derivatives(self, t, y, dy, dp=None, p=None, u=None) -> tuple:
        """(ẏ, J·dy + ∂ẏ/∂p·dp) for one direction (2n,) or k of them (k, 2n)."""

    def linear_terms(self, q, qd, t=0.0, p=None, u=None) -> tuple:
        """(M, ∂F/∂q, ∂F/∂q̇, ∂F/∂u) at one point."""

    def power_terms(self, t, y, p=None, u=None) -> np.ndarray:
        """[Σ Q_j·q̇_j, R], (n_power,)."""

    def outputs(self, t, y, p=None, u=None) -> np.ndarray:
        """The outputs (the user's, then T, V, T + V), (n_outputs,)."""

    def constraint_forces(self, t, y, p=None, u=None) -> np.ndarray:
        """λ, (n_constraints,)."""

    def constraint_residuals(self, t, y, p=None, u=None) -> np.ndarray:
        """Φ, then A·q̇ + b, (n_residuals,)."""

    def constraint_residual_jacobian(self, t, y, p=None, u=None) -> np.ndarray:
        """∂[Φ; A·q̇ + b]/∂[q, q̇], (n_residuals, 2n)."""

    def constraint_terms(self, q, qd, t=0.0, p=None, u=None) -> tuple:
        """(A, λ, ∂(Aᵀλ)/∂q) at one point."""

    def events(self, t, y, p=None, u=None) -> np.ndarray:
        """g_k, (n_events,)."""

    def hybrid_terms(self, t, y, p=None, u=None) -> tuple:
        """(M, F, A, γ, terms): what the hybrid drivers assemble each mode from (n_hybrid terms
        of the impacts and frictions, layout in lagrgen.nonsmooth)."""

    def residual_terms(self, q, qd, a, t=0.0, p=None, u=None) -> tuple:
        """(r, ∂r/∂[q, q̇], ∂r/∂a, ∂r/∂u) of r = [M·q̈ − F − Aᵀλ; A·q̈ − γ], a = [q̈, λ]."""

    def residual_hessian(self, q, qd, a, mu, t=0.0, p=None, u=None) -> np.ndarray:
        """∇²_z(Σ mu_i·r_i), (n_point, n_point), z = [q, q̇, q̈, λ, u]: exact second derivatives."""

    def regressor(self, q, qd, a, t=0.0, p=None, u=None) -> np.ndarray:
        """Y, (n, len(inertial_parameters)), with M·q̈ − F = Y·π at q̈ = a (§21); for a free
        base without the term J·r̈·ζ/r of the inertia J of the quaternion's length r, which moves
        no body and vanishes on every motion that keeps that length (r̈ = 0)."""

    def link_pose(self, link, q, point=(0, 0, 0), p=None) -> tuple:
        """(x (3,), R (3, 3)): the world position of a point fixed in a link and the link's
        rotation (§22)."""

    def link_jacobian(self, link, q, point=(0, 0, 0), p=None) -> np.ndarray:
        """J (6, n) with [velocity of the point; angular velocity] = J @ q̇, world axes (§22)."""

    def residual_parameter_jacobian(self, q, qd, a, t=0.0, p=None, u=None) -> np.ndarray:
        """∂r/∂p, (n + n_constraints, n_params), of the same r."""


class CompiledBuiltModel(BuiltModel, Protocol):
    """What the C backend adds: its compiled runtime object and the addresses of its C functions."""

    compiled_model: object        # lagrgen.runtime._compiled.CompiledModel

    def time_in_c(self, which, t, y, p=None, u=None, repeat=10000) -> float:
        """Seconds per call of the C function `which`, looped inside C."""

    def function_address(self, name) -> int:
        """The address of the C function `name`."""


class PythonBuiltModel(BuiltModel, Protocol):
    """What the Python backend adds: the printed source of its kernels."""

    source: str
