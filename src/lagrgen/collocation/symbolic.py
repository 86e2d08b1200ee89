"""The symbolic side of a collocation problem: the user's expressions (path constraints,
objective integrands, terminal expressions) in the model's internal symbols (t, q[i], qd[i], a[i]
with a = [q̈, λ], u[k], p[j]), and the constraints' position and velocity levels imposed at the
first node. The model's own second derivatives are `lagrgen.hessians`'.
"""
import symengine as se
import sympy as sp

from ..checks import check_expression
from ..errors import ModelError
from ..hessians import path_derivatives, point_variables, weights
from ..lagrange import as_piecewise, user_to_internal


# -- the user's expressions --------------------------------------------------------------------
def internal_expression(model, expr, where, allow_time=True):
    """`expr` (SymPy, in the model's symbols: coordinates, their first and second time
    derivatives, parameters, inputs, t) as a SymEngine expression in the internal symbols."""
    spec = model.spec()
    t = spec.t
    try:
        expr = sp.sympify(expr)
    except (sp.SympifyError, TypeError) as exc:
        raise ModelError(f"{where}: cannot read {expr!r} as a SymPy expression ({exc})") from None
    if isinstance(expr, sp.MatrixBase) and expr.shape == (1, 1):
        expr = expr[0, 0]
    accelerations = {sp.Derivative(q, (t, 2)): sp.Symbol(f"a[{i}]")
                     for i, q in enumerate(spec.coordinates)}
    if isinstance(expr, sp.Basic):
        for d in expr.atoms(sp.Derivative):
            if d.variables == (t, t) and d not in accelerations:
                raise ModelError(f"{where}: {d} is not the acceleration of a coordinate of "
                                 f"model {spec.name!r}")
        check_expression(model, expr.xreplace({d: t for d in accelerations}), where)
    else:
        check_expression(model, expr, where)
    mapping = dict(user_to_internal(spec))
    mapping[t] = sp.Symbol("t")
    internal = as_piecewise(expr).xreplace(accelerations).xreplace(mapping)
    try:
        result = se.sympify(internal)
    except Exception as exc:   # SymEngine raises several types for what it cannot read
        raise ModelError(f"{where}: cannot convert {expr} for differentiation: {exc}") from None
    if not allow_time and se.Symbol("t") in result.free_symbols:
        raise ModelError(f"{where} depends on t explicitly, which a free duration does not "
                         "allow (the node times move with the duration): fix the duration or "
                         "write the expression without t")
    return result


def consistency_derivatives(eq):
    """The constraints' position and velocity levels [Φ; A·q̇ + b] (imposed at the first node):
    (values, Jacobian entries [(row, col, expr)], lower Hessian entries of Σ_k mu_k·row_k), in the
    variables z = [q, q̇, q̈, λ, u] and then every parameter (col = nz + j for p_j)."""
    variables = point_variables(eq) + list(eq.p)
    rows = list(eq.residuals)
    jacobian, hessian = path_derivatives(rows, variables, weights(len(rows)))
    return rows, jacobian, hessian
