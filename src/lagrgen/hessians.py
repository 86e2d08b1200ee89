"""Second derivatives of the implicit form's residual, the exact Hessians direct collocation needs.

A point's variables are z = [q, q̇, a, u] with a = [q̈, λ] (internal symbols q[i], qd[i], a[i],
u[k]); p[j] are the parameters, mu[i] the weights of a weighted sum (the NLP's multipliers of a
point's rows). The residual of the implicit form is

    r = [M(q)·q̈ − F(q, q̇, u) − A(q)ᵀλ;  A(q)·q̈ − γ(q, q̇)]

and the Hessian of ℓ = Σ_i w_i·r_i is formed from the derivation's first derivatives (∂F/∂q,
∂(M·a)/∂q, ∂(Aᵀλ)/∂q, G, …): the gradient g = ∂ℓ/∂z is summed once, then each g_r is differentiated
by the z_c, c ≤ r, whose symbols it holds (the lower triangle, in the decision vector's order).
Entries that are identically zero are left out: the sparsity structure is exact. A
three-dimensional tree forms none of this: its τ part comes from the second-order derivatives of
the recursion (`lg_tree_hessian` of `codegen/templates/tree3d.c.in`), and only its generalized
forces Q are differentiated here (`q_hessian`).
"""
import symengine as se

from .calculus import diff, internal_symbols

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


def point_size(eq):
    """The number of a point's variables z = [q, q̇, q̈, λ, u]."""
    return 3 * eq.n + eq.m + len(eq.u)


def full_matrix(entries, size):
    """The row-major size×size list of the symmetric matrix whose lower entries are `entries`
    [(row, col, expr)], the upper triangle mirrored, zeros elsewhere."""
    out = [ZERO] * (size * size)
    for r, c, e in entries:
        out[r * size + c] = e
        out[c * size + r] = e
    return out


def q_hessian(Q, eq):
    """The nonzero lower entries [(row, col, expr)] of ∇²_z(Σ_i mu_i·Q_i) for the generalized
    forces Q (a tree's other forces: inputs, springs, dampers), z indices (q, q̇, then u after
    q̈ and λ)."""
    n, m = eq.n, eq.m
    mu = weights(len(Q))
    variables = list(eq.q) + list(eq.qd) + list(eq.u)
    index = list(range(2 * n)) + [3 * n + m + k for k in range(len(eq.u))]
    gradient = []
    for v in variables:
        gradient.append(_weighted([mu[i] * diff(Qi, v) for i, Qi in enumerate(Q)
                                   if v in Qi.free_symbols]))
    return [(index[r], index[c], e) for r, c, e in lower_hessian(gradient, variables)]
