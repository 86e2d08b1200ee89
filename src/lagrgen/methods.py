"""The integration methods, each declared once, and the measures of a sweep. Importable without
SciPy: the command line, `simulate`, the native engine and its Cython all read this table.

A method is SciPy's `solve_ivp` method of the same name; `native` is its code in the native C core
(`LG_RK23`... in native/lg_ode.h, None when it runs on the SciPy engine only), `stiff` says whether
it is handed the analytic Jacobian, `dense` names the dense-output interpolant of a step,
`description` says what it is (an FMU's `solver.method` items show it), and `bench` whether
`lagrgen.bench` (and `python -m lagrgen bench`) times it by default.
"""
from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class Method:
    """One integration method: name, native code (None: SciPy only), stiff, dense-output kind,
    what it is, and whether the benchmarks time it by default."""
    name: str
    native: Optional[int]
    stiff: bool
    dense: Optional[str]
    description: str
    bench: bool


TABLE = (
    Method("RK23", 0, False, "rk", "explicit Runge-Kutta 3(2)", False),
    Method("RK45", 1, False, "rk", "explicit Runge-Kutta 5(4) (Dormand-Prince)", True),
    Method("DOP853", 2, False, "dop853", "explicit Runge-Kutta 8(5,3)", True),
    Method("Radau", 3, True, "radau", "implicit Radau IIA order 5 (stiff)", True),
    Method("BDF", 4, True, "bdf", "implicit BDF orders 1-5 (stiff)", True),
    Method("LSODA", None, True, None, "Adams/BDF switching on stiffness (ODEPACK, SciPy only)",
           True),
)

BY_NAME = {m.name: m for m in TABLE}
METHODS = tuple(m.name for m in TABLE)
#: The methods handed the analytic Jacobian.
STIFF_METHODS = tuple(m.name for m in TABLE if m.stiff)
#: The methods the native engine runs, and their codes in the C core.
NATIVE_METHODS = tuple(m.name for m in TABLE if m.native is not None)
NATIVE_CODES = {m.name: m.native for m in TABLE if m.native is not None}
#: The methods `lagrgen.bench` times by default.
BENCH_METHODS = tuple(m.name for m in TABLE if m.bench)
#: What `lagrgen.sweep` measures of each coordinate over the steady window.
MEASURES = ("amplitude", "max", "final")
