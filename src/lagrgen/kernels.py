"""Kernels: the quantities each generated function computes, with common subexpressions eliminated.

A kernel is a list of stages; between two stages the caller's printer inserts the numeric solve
M·a = F (a = q̈). Each stage is CSE temporaries followed by named, row-major output arrays. One CSE
runs over all outputs of a kernel together, so a stage after the solve reuses the temporaries of the
stage before it.
"""
from dataclasses import dataclass, field

import symengine as se


@dataclass
class Stage:
    temporaries: list = field(default_factory=list)   # [(symbol, expression)], in dependency order
    outputs: dict = field(default_factory=dict)       # name -> [expression] (row-major)


@dataclass
class Kernel:
    name: str
    stages: list

    @property
    def temporary_count(self):
        return sum(len(s.temporaries) for s in self.stages)

    def op_count(self):
        """Number of +, *, / and function applications (a measure of the work per call)."""
        exprs = [e for s in self.stages for _, e in s.temporaries]
        exprs += [e for s in self.stages for out in s.outputs.values() for e in out]
        return sum(_ops(e) for e in exprs)


def _ops(expr):
    if not expr.args:
        return 0
    return max(len(expr.args) - 1, 1) + sum(_ops(a) for a in expr.args)


def flatten(matrix):
    """Row-major list of the entries of a list of lists."""
    return [e for row in matrix for e in row]


def temporary_symbols(prefix="x"):
    """An endless supply of CSE temporaries x0, x1, ... (no internal symbol has such a name)."""
    i = 0
    while True:
        yield se.Symbol(f"{prefix}{i}")
        i += 1


def cse_stages(groups, late_symbols=()):
    """Run one CSE over every output of `groups`, a list of {name: [expr]} per stage.

    Temporaries go to the first stage whose outputs need them, except those that depend on
    `late_symbols` (values only known after the solve), which move to the later stage.
    """
    names = [(i, name, len(exprs)) for i, g in enumerate(groups) for name, exprs in g.items()]
    everything = [e for g in groups for exprs in g.values() for e in exprs]
    replacements, reduced = se.cse(everything) if everything else ([], [])
    late = set(late_symbols)
    stages = [Stage() for _ in groups]
    for sym, expr in replacements:
        if expr.free_symbols & late:
            late.add(sym)
            stages[-1].temporaries.append((sym, expr))
        else:
            stages[0].temporaries.append((sym, expr))
    pos = 0
    for i, name, size in names:
        stages[i].outputs[name] = list(reduced[pos:pos + size])
        pos += size
    return stages


def mass_matrix_kernel(eq):
    """M(q, t), n×n."""
    return Kernel("mass_matrix", cse_stages([{"M": flatten(eq.M)}]))


def forcing_kernel(eq):
    """F(q, q̇, t, u), n."""
    return Kernel("forcing", cse_stages([{"F": list(eq.F)}]))


def rhs_kernel(eq):
    """M and F together; the printer solves M·q̈ = F after them."""
    return Kernel("rhs", cse_stages([{"M": flatten(eq.M), "F": list(eq.F)}, {}]))


def jacobian_kernel(eq):
    """M, F; then (after the solve for a = q̈) B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇], n×2n.

    The bottom half of ∂rhs/∂y is M⁻¹·B.
    """
    n = eq.n
    B = []
    for i in range(n):
        B.extend(eq.dF_dq[i][j] - eq.dMa_dq[i][j] for j in range(n))
        B.extend(eq.dF_dqd[i])
    return Kernel("jacobian", cse_stages([{"M": flatten(eq.M), "F": list(eq.F)}, {"B": B}],
                                         late_symbols=eq.a))


def linear_terms_kernel(eq):
    """M, ∂F/∂q, ∂F/∂q̇ (n×n) and ∂F/∂u (n×n_inputs): the linearization about a point."""
    return Kernel("linear_terms", cse_stages([{
        "M": flatten(eq.M), "dF_dq": flatten(eq.dF_dq), "dF_dqd": flatten(eq.dF_dqd),
        "dF_du": flatten(eq.dF_du)}]))


def all_kernels(eq):
    """The kernels every backend provides, in a fixed order."""
    return [mass_matrix_kernel(eq), forcing_kernel(eq), rhs_kernel(eq), jacobian_kernel(eq),
            linear_terms_kernel(eq)]
