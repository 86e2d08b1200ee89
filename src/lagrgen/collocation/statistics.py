"""Standard errors of the parameters a collocation problem estimates from data.

At the solution the free variables move on the manifold of the active constraints (J·δx = 0). The
data term Σ ω·(C·x − d)² is linear in x, so its Gauss–Newton Hessian is H = 2·CᵀΩC. What the data
hold about the parameters θ once every other free variable (the motion, the initial state, ...) is
fitted with them is the reduced Gauss–Newton matrix R = ([K⁻¹]_θθ)⁻¹/2 of the KKT matrix
K = [[H + εI, Jᵀ], [J, 0]] (one sparse factorization, one solve per parameter), formed with J's
rows of unit norm and each parameter in units of its value: the ridge εI keeps K regular where
neither data nor constraints hold a direction, and its direct share of R on the parameters, εI/2,
is taken off again. R = AᵀA with A its k × k square root, read as `lagrgen.fit`
reads its Jacobian (`lagrgen.identifiability`): a parameter in no equation is a column of zeros, a
combination the data cannot tell apart (mass, stiffness and damping of a free vibration scaled
together) a null direction; both get infinite standard errors and an `IdentifiabilityWarning`
naming the combination, and information at the ridge's level (below RIDGE_SEEN·ε) counts as none.
The covariance on the rest is s²·(AᵀA)⁻¹ with s² = Σ ω·e² / (samples − the fitted manifold's
dimension); estimates on their bounds are flagged. Variables other than the parameters at a bound
count as fixed.
"""
import numpy as np

from ..identifiability import covariance, on_bounds, warn_unseen

#: The ridge on the Gauss–Newton Hessian, relative to its largest diagonal entry.
RIDGE = 1e-9
#: A parameter whose information is below RIDGE_SEEN times the ridge is seen by the ridge alone.
RIDGE_SEEN = 1e3
#: The relative accuracy of the reduced matrix's square root (the ridge's level, √RIDGE, and the
#: factorization's): singular values below ten times it are zero (`identifiability`).
ACCURACY = 1e-4


def parameter_errors(tr, x, stacklevel=2):
    """({name: standard error}, covariance (k, k), unidentified names, unseen directions,
    names on bounds) of the unknown parameters, or ({}, None, (), [], ()) when the problem has
    no data term or no unknown parameter."""
    L = tr.layout
    names = [tr.mod.parameters[j] for j in L.unknown]
    if not names or not tr.n_data:
        return {}, None, (), [], ()
    k = len(names)
    p = x[L.p_start:L.p_start + k]
    scale = np.where(p != 0, np.abs(p), 1.0)      # the parameters in units of their values
    columns, free, K, ridge = _kkt(tr, x, scale)
    R = _reduced_matrix(K, columns, ridge) / np.outer(scale, scale)
    residual = tr.C.dot(x) - tr.d
    dof = tr.n_data - (free - (K.shape[0] - free))
    s2 = float(tr.omega @ residual ** 2) / dof if dof > 0 else np.nan
    cov, unidentified, directions = covariance(_square_root(R), s2, names, ACCURACY)
    if directions:
        rank = k - len(directions)
        warn_unseen(directions, rank, k, advice="List fewer names in unknown_params, give "
                    "known values with params={...}, or track more of the motion",
                    stacklevel=stacklevel + 2)
    at_bounds = on_bounds(p, tr.lo[L.p_start:L.p_start + k], tr.hi[L.p_start:L.p_start + k],
                          names, stacklevel=stacklevel + 2)
    stderr = {name: float(np.sqrt(cov[i, i])) if cov[i, i] >= 0 else np.nan
              for i, name in enumerate(names)}
    return stderr, cov, unidentified, directions, at_bounds


def _kkt(tr, x, scale):
    """(the parameters' columns in K, the number of free variables, K, the ridge ε), the
    parameters' columns of the constraints multiplied by `scale` (each parameter in units of
    its value, so that the ridge is small beside a small parameter's information)."""
    import scipy.sparse as sps
    L = tr.layout
    near = 1e-8 * (1.0 + np.abs(x))
    at_bound = (tr.hi - tr.lo <= 0) | (x - tr.lo <= near) | (tr.hi - x <= near)
    at_bound[L.p_start:L.p_start + len(L.unknown)] = False     # parameters: flagged, not fixed
    free = np.flatnonzero(~at_bound)
    position = -np.ones(L.size, dtype=np.int64)
    position[free] = np.arange(free.size)
    g = tr.constraints(x)
    values = tr.jacobian(x)
    parameter = tr.jac_cols - L.p_start
    inside = (parameter >= 0) & (parameter < len(L.unknown))
    values = np.where(inside, values * scale[np.clip(parameter, 0, len(scale) - 1)], values)
    tol = 1e-6 * (1.0 + np.abs(g))
    active = (tr.g_hi - tr.g_lo <= 0) | (np.abs(g - tr.g_lo) <= tol) | (np.abs(g - tr.g_hi) <= tol)
    rows = np.flatnonzero(active)
    row_position = -np.ones(g.size, dtype=np.int64)
    row_position[rows] = np.arange(rows.size)
    keep = (row_position[tr.jac_rows] >= 0) & (position[tr.jac_cols] >= 0)
    J = sps.csr_matrix((values[keep], (row_position[tr.jac_rows[keep]],
                                       position[tr.jac_cols[keep]])),
                       shape=(rows.size, free.size))
    norms = np.sqrt(np.asarray(J.multiply(J).sum(axis=1)).ravel())
    J = sps.diags(1.0 / np.where(norms > 0, norms, 1.0)) @ J     # rows of unit norm: the same
    # manifold, whatever the scale of a residual (its parameters shrunk together, say)
    C = sps.csr_matrix((tr.C.values, (tr.C.rows, tr.C.cols)), shape=tr.C.shape)[:, free]
    H = (C.T @ sps.diags(2.0 * tr.omega) @ C).tocsc()
    ridge = RIDGE * max(1.0, float(np.max(H.diagonal(), initial=0.0)))
    H = H + ridge * sps.identity(free.size, format="csc")
    K = sps.bmat([[H, J.T], [J, None]], format="csc")
    columns = [int(position[L.p_start + i]) for i in range(len(L.unknown))]
    return columns, free.size, K, ridge


def _reduced_matrix(K, columns, ridge):
    """R = ([K⁻¹]_θθ)⁻¹/2 − ε/2·I for the parameters' `columns`: their Gauss–Newton matrix with
    everything else fitted; rows and columns at the ridge's level are zero."""
    from scipy.sparse.linalg import splu
    k = len(columns)
    try:
        lu = splu(K)
    except RuntimeError:          # singular even with the ridge: the constraints are dependent
        return np.zeros((k, k))
    block = np.empty((k, k))
    for i, col in enumerate(columns):
        e = np.zeros(K.shape[0])
        e[col] = 1.0
        block[:, i] = lu.solve(e)[columns]
    block = 0.5 * (block + block.T)
    R = 0.5 * (np.linalg.inv(block) - ridge * np.eye(k))
    seen = np.diag(R) > 0.5 * RIDGE_SEEN * ridge
    R[~seen, :] = R[:, ~seen] = 0.0
    return 0.5 * (R + R.T)


def _square_root(R):
    """A with AᵀA = R (R symmetric, its negative round-off taken as zero)."""
    values, vectors = np.linalg.eigh(R)
    return (vectors * np.sqrt(np.clip(values, 0.0, None))).T
