"""The integration methods, each declared once, and the measures of a sweep. Importable without
SciPy: the command line, `simulate`, the native engine and its Cython all read this table.

A method is SciPy's `solve_ivp` method of the same name; `native` is its code in the native C core
(`LG_RK23`... in native/lg_ode.h, None when it runs on the SciPy engine only), `stiff` says whether
it is handed the analytic Jacobian, and `dense` names the dense-output interpolant of a step.
"""
from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class Method:
    """One integration method: name, native code (None: SciPy only), stiff, dense-output kind."""
    name: str
    native: Optional[int]
    stiff: bool
    dense: Optional[str]


TABLE = (
    Method("RK23", 0, False, "rk"),
    Method("RK45", 1, False, "rk"),
    Method("DOP853", 2, False, "dop853"),
    Method("Radau", 3, True, "radau"),
    Method("BDF", 4, True, "bdf"),
    Method("LSODA", None, True, None),
)

BY_NAME = {m.name: m for m in TABLE}
METHODS = tuple(m.name for m in TABLE)
#: The methods handed the analytic Jacobian.
STIFF_METHODS = tuple(m.name for m in TABLE if m.stiff)
#: The methods the native engine runs, and their codes in the C core.
NATIVE_METHODS = tuple(m.name for m in TABLE if m.native is not None)
NATIVE_CODES = {m.name: m.native for m in TABLE if m.native is not None}
#: What `lagrgen.sweep` measures of each coordinate over the steady window.
MEASURES = ("amplitude", "max", "final")
