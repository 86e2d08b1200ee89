"""`Built`: a model built by one of the compared tools, as the benchmark harness sees it (shared by
`_peers` and `_pinocchio`, which import it, not each other)."""
from dataclasses import dataclass, field
from typing import Callable, Optional


@dataclass
class Built:
    """A built model as the harness sees it, whichever tool made it.

    `rhs(t, y, *args)` returns a new array (what `solve_ivp` is given, with `args`); `jac(t, y, *args)`
    the (2n, 2n) Jacobian, or None when the tool has none (SciPy then uses finite differences).
    `rhs_in_c(t, y, repeat)` and `jac_in_c` return seconds per call looped inside C, or are None.
    `simulate(method, t_span, y0, rtol, atol)`, when set, replaces the plain `solve_ivp` call.
    `build` holds build times in seconds (keys derive, cse+emit, compile, cold, cached, ...) and
    `notes` what a reader of the table must know.
    """
    tool: str
    rhs: Callable
    jac: Optional[Callable] = None
    args: tuple = ()
    rhs_in_c: Optional[Callable] = None
    jac_in_c: Optional[Callable] = None
    simulate: Optional[Callable] = None
    build: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
