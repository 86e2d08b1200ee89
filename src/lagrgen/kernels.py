"""Kernels: the quantities each generated function computes, with common subexpressions eliminated.

Three kernels cover every quantity of a built model:
    mf           M(q, t) and F(q, q̇, t, u) together (one CSE over both)
    jacobian_b   B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇] for a given a (= q̈); ∂ẏ/∂y's bottom half is M⁻¹·B.
                 At a = 0 it is [∂F/∂q | ∂F/∂q̇], the linearization's −K and −C.
    dF_du        ∂F/∂u, the linearization's input matrix
Mass matrix, forcing, rhs, jacobian and linear terms are assembled from these by the backends.
"""
import weakref
from dataclasses import dataclass

import symengine as se

_computed = weakref.WeakKeyDictionary()


@dataclass
class Kernel:
    name: str
    temporaries: list   # [(symbol, expression)], in dependency order
    outputs: dict       # name -> [expression], row-major


def flatten(matrix):
    """Row-major list of the entries of a list of lists."""
    return [e for row in matrix for e in row]


def cse_kernel(name, outputs):
    """A kernel computing `outputs` ({name: [expr]}) after one CSE over all of them together."""
    everything = [e for exprs in outputs.values() for e in exprs]
    replacements, reduced = se.cse(everything) if everything else ([], [])
    result, pos = {}, 0
    for key, exprs in outputs.items():
        result[key] = list(reduced[pos:pos + len(exprs)])
        pos += len(exprs)
    return Kernel(name, list(replacements), result)


def mf_kernel(eq):
    """M (n×n) and F (n)."""
    return cse_kernel("mf", {"M": flatten(eq.M), "F": list(eq.F)})


def jacobian_b_kernel(eq):
    """B = [∂F/∂q − ∂(M·a)/∂q | ∂F/∂q̇], n×2n, with a = q̈ an input."""
    B = []
    for i in range(eq.n):
        B.extend(eq.dF_dq[i][j] - eq.dMa_dq[i][j] for j in range(eq.n))
        B.extend(eq.dF_dqd[i])
    return cse_kernel("jacobian_b", {"B": B})


def dF_du_kernel(eq):
    """∂F/∂u, n×n_inputs."""
    return cse_kernel("dF_du", {"dF_du": flatten(eq.dF_du)})


def all_kernels(eq):
    """The kernels every backend compiles, in a fixed order (computed once per Equations)."""
    if eq not in _computed:
        _computed[eq] = [mf_kernel(eq), jacobian_b_kernel(eq), dF_du_kernel(eq)]
    return _computed[eq]
