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

    @classmethod
    def at(cls, name, t, q):
        """The error for model `name` at (t, q), saying what to check."""
        q = np.asarray(q, dtype=float)
        hint = ("the state contains NaN or infinity" if not np.all(np.isfinite(q)) else
                "check that masses and inertias are positive and that the coordinates are "
                "independent at this configuration")
        return cls(f"the mass matrix of model {name!r} is not positive definite at t={float(t)!r}, "
                   f"q={np.array2string(q, precision=6)}: {hint}")


class NearSingularMassMatrixWarning(RuntimeWarning):
    """A run passed where the mass matrix M is nearly singular: a pivot of its factorization fell
    below `NEAR_SINGULAR` (1e-8) of its diagonal entry, or below eps/rtol, so q̈ = M⁻¹·F lost
    about that many of its digits there, e.g. Euler angles (roll–pitch–yaw coordinates of a
    `rigid_body_3d` or a floating base) near gimbal lock, pitch = ±π/2."""

    @classmethod
    def message(cls, name, least, runs=None):
        """The warning's text for model `name` whose least relative pivot was `least` (in the
        runs `runs` of an ensemble, if given)."""
        lost = max(0.0, -np.log10(max(least, 1e-300)))
        which = "a run" if runs is None else (
            f"run{'s' if len(runs) > 1 else ''} {', '.join(map(str, runs[:10]))}"
            f"{' …' if len(runs) > 10 else ''}")
        return (f"{which} of model {name!r} passed where its mass matrix is nearly singular: the "
                f"least pivot of M reached {least:.2g} of its diagonal entry, so about {lost:.0f} "
                "of the 16 digits of q̈ = M⁻¹·F were lost there and the result may be inaccurate "
                "beyond the tolerances. Euler angles near gimbal lock (pitch = ±π/2) do this: "
                "choose other angles for this motion, or start it elsewhere")


#: The relative pivot of M below which a run warns (NearSingularMassMatrixWarning).
NEAR_SINGULAR = 1e-8


def near_singular_limit(rtol=None):
    """The relative pivot of M below which a run warns: NEAR_SINGULAR, or eps/rtol when that is
    larger (the digits lost then exceed those the tolerance asks for), rtol clipped to 100·eps
    as the solvers clip it (below, eps/rtol would exceed every pivot and always warn)."""
    eps = np.finfo(float).eps
    if rtol is not None and np.ndim(rtol) == 0 and rtol > 0:
        return max(NEAR_SINGULAR, eps / max(float(rtol), 100 * eps))
    return NEAR_SINGULAR


def warn_near_singular(mod, least, rtol=None, runs=None):
    """Warn (NearSingularMassMatrixWarning) when the least relative pivot `least` a run's
    factorizations of M reached is below `near_singular_limit(rtol)`."""
    import warnings
    if least < near_singular_limit(rtol):
        warnings.warn(NearSingularMassMatrixWarning.message(mod.name, least, runs),
                      NearSingularMassMatrixWarning, stacklevel=3)


class ConstraintError(LagrgenError, np.linalg.LinAlgError):
    """The constraints are dependent (A·M⁻¹·Aᵀ singular) or cannot be satisfied at a state."""

    @classmethod
    def at(cls, name, t, y, n):
        """The error for model `name` at (t, y = [q, q̇]) with n coordinates."""
        y = np.asarray(y, dtype=float)
        q, qd = y[:n], y[n:2 * n]
        hint = ("the state contains NaN or infinity" if not np.all(np.isfinite(y)) else
                "the constraint Jacobian A = [Φ_q; A_v] is rank-deficient there: the constraints "
                "are redundant (remove the dependent ones) or the mechanism is at a singular "
                "configuration (a dead point)")
        return cls(f"the constraints of model {name!r} are not independent at t={t!r}, "
                   f"q={np.array2string(q, precision=6)}, qd={np.array2string(qd, precision=6)} "
                   f"(A·M⁻¹·Aᵀ is singular): {hint}")


class ContactError(LagrgenError, ValueError):
    """An impact or friction cannot be run as given: a start inside a contact surface, a
    restitution outside [0, 1] or a friction coefficient out of range at a run's values, two
    contacts on one surface."""


class StoreError(LagrgenError, ValueError):
    """An ensemble store cannot be read: its metadata or chunk records are damaged."""


class StoreWarning(UserWarning):
    """Some runs of an ensemble store are damaged (missing or corrupt chunks): they read as
    failed."""


class NotATree(Exception):
    """Why a model is not (provably) a kinematic tree: raised and caught inside the derivation
    (`lagrgen.tree`), which then keeps the dense formulation and says why when asked for the
    recursive one."""


class BuildError(LagrgenError, RuntimeError):
    """Generating, compiling or loading a compiled model failed."""


class CompileError(BuildError):
    """The C compiler rejected the generated code; the message carries its output."""


class NonFiniteError(LagrgenError, FloatingPointError):
    """The derivative became NaN or infinite during a simulation."""

    @classmethod
    def at(cls, name, t, y):
        """The error for model `name` whose derivative is not finite at (t, y)."""
        y = np.asarray(y, dtype=float)
        return cls(f"the derivative of model {name!r} is not finite at t={float(t)!r}, "
                   f"y={np.array2string(y, precision=6)}: the simulation stopped there; check the "
                   "model's domain (sqrt, log, division) and the parameters")

    @classmethod
    def in_mass_matrix(cls, name, t, q):
        """The error for model `name` whose mass matrix has an infinite or NaN entry at finite
        (t, q): an overflow (|x| > 1.8e308) or an undefined operation, not a singular M."""
        q = np.asarray(q, dtype=float)
        return cls(f"the mass matrix of model {name!r} has an entry that is not finite at "
                   f"t={float(t)!r}, q={np.array2string(q, precision=6)}: a product of its "
                   "parameters or coordinates overflows the range of a double (|x| up to "
                   "1.8e308) or is undefined there; rescale the model's units or parameters")
