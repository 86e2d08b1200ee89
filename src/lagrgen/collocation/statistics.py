"""Standard errors of the parameters a collocation problem estimates from data.

At the solution the free variables move on the manifold of the active constraints, x = x̂ + Z·θ
(Z a basis of the null space of their Jacobian J). The data term Σ ω·(C·x − d)² is linear in x, so
its Gauss–Newton Hessian is H = 2·CᵀΩC and the covariance of θ̂ is s²·(ZᵀCᵀΩCZ)⁻¹, with
s² = Σ ω·e² / (samples − dim θ). The covariance of x̂ is then 2·s²·[K⁻¹]_xx for the KKT matrix
K = [[H, Jᵀ], [J, 0]] (the top-left block of K⁻¹ is Z·(ZᵀHZ)⁻¹·Zᵀ): one sparse factorization and
one solve per parameter, never a dense null-space basis. Variables at a bound (and given inputs)
count as fixed; directions the data do not see get a tiny regularization, so they leave the
parameters' errors unchanged unless the parameters depend on them (then the errors are huge and
flagged: the data cannot identify them).
"""
import warnings

import numpy as np


def parameter_errors(tr, x):
    """{name: standard error} of the unknown parameters and their covariance (k, k), or ({}, None)
    when the problem has no data term or no unknown parameter."""
    L = tr.layout
    names = [tr.mod.parameters[j] for j in L.unknown]
    if not names or not tr.n_data:
        return {}, None
    import scipy.sparse as sps
    from scipy.sparse.linalg import splu
    scale = 1e-8 * (1.0 + np.abs(x))
    at_bound = (tr.hi - tr.lo <= 0) | (x - tr.lo <= scale) | (tr.hi - x <= scale)
    free = np.flatnonzero(~at_bound)
    position = -np.ones(L.size, dtype=np.int64)
    position[free] = np.arange(free.size)
    g = tr.constraints(x)
    values = tr.jacobian(x)
    tol = 1e-6 * (1.0 + np.abs(g))
    active = (tr.g_hi - tr.g_lo <= 0) | (np.abs(g - tr.g_lo) <= tol) | (np.abs(g - tr.g_hi) <= tol)
    rows = np.flatnonzero(active)
    row_position = -np.ones(g.size, dtype=np.int64)
    row_position[rows] = np.arange(rows.size)
    keep = (row_position[tr.jac_rows] >= 0) & (position[tr.jac_cols] >= 0)
    J = sps.csr_matrix((values[keep], (row_position[tr.jac_rows[keep]],
                                       position[tr.jac_cols[keep]])),
                       shape=(rows.size, free.size))
    C = sps.csr_matrix((tr.C.values, (tr.C.rows, tr.C.cols)), shape=tr.C.shape)[:, free]
    H = (C.T @ sps.diags(2.0 * tr.omega) @ C).tocsc()
    ridge = 1e-9 * max(1.0, float(np.max(H.diagonal(), initial=0.0)))
    H = H + ridge * sps.identity(free.size, format="csc")
    K = sps.bmat([[H, J.T], [J, None]], format="csc")
    residual = tr.C.dot(x) - tr.d
    dof = tr.n_data - (free.size - rows.size)
    s2 = float(tr.omega @ residual ** 2) / dof if dof > 0 else np.nan
    k = len(names)
    cov = np.full((k, k), np.nan)
    columns = [position[L.p_start + i] for i in range(k)]
    try:
        lu = splu(K)
    except RuntimeError:
        warnings.warn("the data do not determine the unknown parameters (the KKT matrix of the "
                      "data fit is singular): standard errors are infinite", RuntimeWarning)
        return {name: np.inf for name in names}, np.full((k, k), np.inf)
    solved = {}
    for i, col in enumerate(columns):
        if col < 0:
            continue
        e = np.zeros(K.shape[0])
        e[col] = 1.0
        solved[i] = lu.solve(e)
    for i, a in solved.items():
        for j in solved:
            cov[i, j] = 2.0 * s2 * a[columns[j]]
    stderr = {}
    for i, name in enumerate(names):
        stderr[name] = float(np.sqrt(cov[i, i])) if cov[i, i] >= 0 else np.nan
        if columns[i] < 0:
            warnings.warn(f"parameter {name!r} ended on a bound: its standard error is not "
                          "defined (NaN)", RuntimeWarning)
    value = x[L.p_start:L.p_start + k]
    weak = [n for n, v in zip(names, value) if stderr[n] > 1e6 * max(abs(v), 1.0)]
    if weak:
        warnings.warn(f"the data barely determine {', '.join(weak)} (standard errors over 10⁶ "
                      "times the estimates)", RuntimeWarning)
    return stderr, cov
