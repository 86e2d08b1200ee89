"""The symbolic side of a collocation problem: the user's expressions in the model's internal
symbols, the structure of the residual's Jacobian, and the second derivatives the exact Hessian of
the Lagrangian needs.

A point's variables are z = [q, q̇, a, u] with a = [q̈, λ] (internal symbols q[i], qd[i], a[i],
u[k]); p[j] are the parameters, t the time, mu[i] the weights of a weighted sum (the NLP's
multipliers of a point's rows). The residual of the implicit form is

    r = [M(q)·q̈ − F(q, q̇, u) − A(q)ᵀλ;  A(q)·q̈ − γ(q, q̇)]

and the Hessian of ℓ = Σ_i w_i·r_i is formed from the derivation's first derivatives (∂F/∂q,
∂(M·a)/∂q, ∂(Aᵀλ)/∂q, G, …): the gradient g = ∂ℓ/∂z is summed once, then each g_r is differentiated
by the z_c, c ≤ r, whose symbols it holds (the lower triangle, in the decision vector's order).
Entries that are identically zero are left out: the sparsity structure is exact.
"""
import symengine as se
import sympy as sp

from ..calculus import diff, internal_symbols
from ..checks import check_expression
from ..errors import ModelError
from ..lagrange import as_piecewise, user_to_internal

ZERO = se.Integer(0)


def weights(count):
    """The weight symbols mu[0] … mu[count−1] (the kernels' argument `mu`; `w` is the printer's
    workspace of a kernel split into parts)."""
    return internal_symbols("mu", count)


def point_variables_of(n, m, nu):
    """z = [q, q̇, q̈, λ, u] as internal symbols (a[i] holds q̈ then λ) for the sizes n, m, nu."""
    return [*internal_symbols("q", n), *internal_symbols("qd", n),
            *internal_symbols("a", n + m), *internal_symbols("u", nu)]


def point_variables(eq):
    """z = [q, q̇, q̈, λ, u] of the equations `eq`."""
    return point_variables_of(eq.n, eq.m, len(eq.u))


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


# -- structure of the residual's first derivatives --------------------------------------------
def _nonzero(expr):
    return expr != 0


def residual_jacobian_structure(eq):
    """Which entries of ∂r/∂[q, q̇], ∂r/∂a, ∂r/∂u and ∂r/∂p are not identically zero, as boolean
    nested lists shaped like `residual_terms`' outputs (and `residual_parameter_jacobian`'s)."""
    n, m = eq.n, eq.m
    dy = [[_nonzero(eq.dF_dq[i][j] - eq.dMa_dq[i][j] - (eq.dAl_dq[i][j] if m else ZERO))
           for j in range(n)] + [_nonzero(e) for e in eq.dF_dqd[i]] for i in range(n)]
    da = [[_nonzero(eq.M[i][j]) for j in range(n)] + [_nonzero(eq.A[k][i]) for k in range(m)]
          for i in range(n)]
    du = [[_nonzero(e) for e in eq.dF_du[i]] for i in range(n)]
    dp = [[_nonzero(eq.dF_dp[i][j] - eq.dMa_dp[i][j] - (eq.dAl_dp[i][j] if m else ZERO))
           for j in range(len(eq.p))] for i in range(n)]
    for k in range(m):
        dy.append([_nonzero(e) for e in eq.G[k]])
        da.append([_nonzero(e) for e in eq.A[k]] + [False] * m)
        du.append([False] * len(eq.u))
        dp.append([_nonzero(e) for e in eq.G_p[k]])
    return {"dr_dy": dy, "dr_da": da, "dr_du": du, "dr_dp": dp}


# -- second derivatives ------------------------------------------------------------------------
def _weighted(terms):
    return se.Add(*terms) if terms else ZERO


def residual_gradient(eq, w):
    """g = ∂(Σ_i w_i·r_i)/∂v for v in z = [q, q̇, q̈, λ, u] and then in p: two lists."""
    n, m = eq.n, eq.m
    mu, nu = w[:n], w[n:]
    dAl_dq = eq.dAl_dq if m else None
    g = []
    for j in range(n):
        terms = [mu[i] * (eq.dMa_dq[i][j] - eq.dF_dq[i][j] + (dAl_dq[i][j] if m else ZERO))
                 for i in range(n)]
        terms += [-nu[k] * eq.G[k][j] for k in range(m)]
        g.append(_weighted(terms))
    for j in range(n):
        terms = [-mu[i] * eq.dF_dqd[i][j] for i in range(n)]
        terms += [-nu[k] * eq.G[k][n + j] for k in range(m)]
        g.append(_weighted(terms))
    for j in range(n):
        terms = [mu[i] * eq.M[i][j] for i in range(n)] + [nu[k] * eq.A[k][j] for k in range(m)]
        g.append(_weighted(terms))
    for k in range(m):
        g.append(_weighted([-mu[i] * eq.A[k][i] for i in range(n)]))
    for j in range(len(eq.u)):
        g.append(_weighted([-mu[i] * eq.dF_du[i][j] for i in range(n)]))
    return g


def residual_parameter_gradient(eq, w):
    """∂(Σ_i w_i·r_i)/∂p_j for every parameter."""
    n, m = eq.n, eq.m
    mu, nu = w[:n], w[n:]
    out = []
    for j in range(len(eq.p)):
        terms = [mu[i] * (eq.dMa_dp[i][j] - eq.dF_dp[i][j] + (eq.dAl_dp[i][j] if m else ZERO))
                 for i in range(n)]
        terms += [-nu[k] * eq.G_p[k][j] for k in range(m)]
        out.append(_weighted(terms))
    return out


def lower_hessian(gradient, variables, row_offset=0, columns=None):
    """[(row, col, ∂g_r/∂v_c)] for the nonzero entries with col ≤ row + row_offset (`gradient[r]`
    the derivative by the variable of index row_offset + r; `columns` the variables to
    differentiate by, default `variables`)."""
    columns = variables if columns is None else columns
    entries = []
    for r, g in enumerate(gradient):
        if g == 0:
            continue
        free = g.free_symbols
        row = row_offset + r
        for c, v in enumerate(columns[:row + 1]):
            if v in free:
                d = diff(g, v)
                if d != 0:
                    entries.append((row, c, d))
    return entries


def residual_hessian(eq):
    """The nonzero lower-triangle entries [(row, col, expr)] of ∇²_z(Σ_i w_i·r_i), z indices."""
    w = weights(eq.n + eq.m)
    z = point_variables(eq)
    return lower_hessian(residual_gradient(eq, w), z)


def residual_parameter_hessian(eq):
    """The nonzero entries [(row, col, expr)] of ∇²(Σ_i w_i·r_i) in the rows of the parameters
    (row = nz + j for p_j) against z (col < nz) and the parameters up to the diagonal
    (col = nz + l, l ≤ j)."""
    w = weights(eq.n + eq.m)
    z = point_variables(eq)
    variables = z + list(eq.p)
    return lower_hessian(residual_parameter_gradient(eq, w), variables, row_offset=len(z))


def scalar_derivatives(expr, variables):
    """(gradient entries [(col, expr)], lower Hessian entries [(row, col, expr)]) of a scalar
    expression in `variables`."""
    free = expr.free_symbols
    gradient = [(c, diff(expr, v)) for c, v in enumerate(variables) if v in free]
    gradient = [(c, d) for c, d in gradient if d != 0]
    hessian = []
    for r, g in gradient:
        gfree = g.free_symbols
        for c, v in enumerate(variables[:r + 1]):
            if v in gfree:
                d = diff(g, v)
                if d != 0:
                    hessian.append((r, c, d))
    return gradient, hessian


def path_derivatives(exprs, variables, w):
    """(Jacobian entries [(row, col, expr)], lower Hessian entries of Σ_k w_k·g_k) of the path
    expressions `exprs` in `variables`."""
    jacobian, gradient = [], [ZERO] * len(variables)
    for k, g in enumerate(exprs):
        free = g.free_symbols
        for c, v in enumerate(variables):
            if v in free:
                d = diff(g, v)
                if d != 0:
                    jacobian.append((k, c, d))
                    gradient[c] = gradient[c] + w[k] * d
    return jacobian, lower_hessian(gradient, variables)


def consistency_derivatives(eq):
    """The constraints' position and velocity levels [Φ; A·q̇ + b] (imposed at the first node):
    (values, Jacobian entries [(row, col, expr)], lower Hessian entries of Σ_k mu_k·row_k), in the
    variables z = [q, q̇, q̈, λ, u] and then every parameter (col = nz + j for p_j)."""
    variables = point_variables(eq) + list(eq.p)
    rows = list(eq.residuals)
    jacobian, hessian = path_derivatives(rows, variables, weights(len(rows)))
    return rows, jacobian, hessian
