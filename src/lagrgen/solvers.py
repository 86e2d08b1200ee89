"""SciPy's implicit solvers with their dense LU done by LAPACK directly.

`Radau` and `BDF` are SciPy's own classes, step for step; only the factorization and solve of the
Newton iteration matrices call LAPACK's getrf/getrs without SciPy's per-call argument checking, which
dominates the wall time of small and mid-sized systems. A sparse Jacobian keeps SciPy's path.
"""
from scipy.integrate import BDF as ScipyBDF
from scipy.integrate import Radau as ScipyRadau
from scipy.linalg import lapack


class DirectLU:
    """Mixin: after the solver's __init__, replace its lu/solve_lu with direct LAPACK calls."""

    def _use_direct_lu(self):
        if not hasattr(self.I, "toarray"):
            self.lu = self._direct_lu
            self.solve_lu = self._direct_solve

    def _direct_lu(self, A):
        """LU factors (lu, piv) of the square matrix A, overwriting it (real or complex)."""
        self.nlu += 1
        getrf = lapack.zgetrf if A.dtype.kind == "c" else lapack.dgetrf
        lu, piv, _ = getrf(A, overwrite_a=True)
        return lu, piv

    @staticmethod
    def _direct_solve(LU, b):
        """x with A·x = b from the factors of A."""
        lu, piv = LU
        getrs = lapack.zgetrs if lu.dtype.kind == "c" else lapack.dgetrs
        return getrs(lu, piv, b, overwrite_b=True)[0]


class Radau(DirectLU, ScipyRadau):
    """SciPy's Radau IIA (order 5) with direct LAPACK LU."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._use_direct_lu()


class BDF(DirectLU, ScipyBDF):
    """SciPy's variable-order BDF with direct LAPACK LU."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._use_direct_lu()


SOLVERS = {"Radau": Radau, "BDF": BDF}
