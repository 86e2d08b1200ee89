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
