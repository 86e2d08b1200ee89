"""Physically consistent estimates: each link's pseudo-inertia positive definite (Wensing et al.
2017), the estimate nearest the records by an interior-point path on the log-det divergence from
the model's defaults (Lee & Wensing 2020)."""
import numpy as np

from .regressor import FIELDS, links_of


def pseudo_inertia(values):
    """The 4×4 pseudo-inertia [[Σ, h], [hᵀ, m]], Σ = ½tr(I)·1 − I, of a link's parameters
    (dict field -> value, missing fields 0); positive definite exactly when the link is
    physically consistent (m > 0, I_c ≻ 0 with the triangle inequality)."""
    v = {f: float(values.get(f, 0.0)) for f in FIELDS}
    I = np.array([[v["Ixx"], v["Ixy"], v["Ixz"]], [v["Ixy"], v["Iyy"], v["Iyz"]],
                  [v["Ixz"], v["Iyz"], v["Izz"]]])
    J = np.empty((4, 4))
    J[:3, :3] = 0.5 * np.trace(I) * np.eye(3) - I
    J[:3, 3] = J[3, :3] = v["mx"], v["my"], v["mz"]
    J[3, 3] = v["m"]
    return J


#: The pseudo-inertia of each field's unit value: J(π_link) = Σ_i π_i·BASIS[i], (10, 4, 4).
BASIS = np.array([pseudo_inertia({f: 1.0}) for f in FIELDS])

#: The consistent estimates solve the divergence-weighted problems down to this suboptimality,
#: in units of the weighted squared residual, i.e. of the noise variance (statistically nothing:
#: the estimates move by 1e-3 of a standard error at most), or relative to that residual when it
#: is larger (records far from any consistent set of links, whose infimum may lie at infinity).
CONSISTENT_GAP = 1e-3

#: The most Newton steps the consistent estimate takes, all stages of its path together.
NEWTON_STEPS = 3000


def _nearest_consistent(J):
    """J with its eigenvalues raised to at least 1e-6 of the largest: positive definite (the
    unit pseudo-inertia when J has no positive eigenvalue: a model without defaults)."""
    lam, V = np.linalg.eigh(0.5 * (J + J.T))
    if lam.max() <= 0:
        return np.eye(4)
    return (V * np.maximum(lam, 1e-6 * lam.max())) @ V.T


class _Divergence:
    """D(x) = Σ_links tr(J0⁻¹·J) − log det J + Σ_friction f/f0 − log f of x = [π of every link
    (10 each, FIELDS order), friction]: convex, finite exactly where each pseudo-inertia J is
    positive definite and each friction coefficient positive, least at the prior (J0, f0)."""

    def __init__(self, J0, f0):
        self.links, self.f0 = len(J0), f0
        self.linear = np.concatenate([np.einsum("lab,iba->li", np.linalg.inv(J0), BASIS).ravel(),
                                      1.0 / f0])

    def pseudo_inertias(self, x):
        return np.einsum("li,iab->lab", x[:10 * self.links].reshape(-1, 10), BASIS)

    def feasible(self, x):
        return bool(np.all(np.linalg.eigvalsh(self.pseudo_inertias(x))[:, 0] > 0)
                    and np.all(x[10 * self.links:] > 0))

    def value(self, x):
        f = x[10 * self.links:]
        return float(self.linear @ x - np.linalg.slogdet(self.pseudo_inertias(x))[1].sum()
                     - np.log(f).sum())

    def derivatives(self, x):
        """(gradient, G) with the Hessian GᵀG: with J = L·Lᵀ and C_i = L⁻¹·A_i·L⁻ᵀ (A_i =
        BASIS[i]), ∂(−log det J)/∂π_i = −tr(C_i) and ∂² = tr(J⁻¹A_i·J⁻¹A_j) = ⟨C_i, C_j⟩, so
        G's rows for a link are the 16 entries of its C_i; a friction term f adds the row 1/f.
        The Newton steps factor G (square root of the Hessian) rather than form GᵀG."""
        size, f = 10 * self.links, x[10 * self.links:]
        L = np.linalg.cholesky(self.pseudo_inertias(x))
        Linv = np.linalg.inv(L)
        C = np.einsum("lab,ibc,ldc->lida", Linv, BASIS, Linv)           # (links, 10, 4, 4)
        G = np.zeros((16 * self.links + f.size, x.size))
        for link in range(self.links):
            G[16 * link:16 * (link + 1), 10 * link:10 * (link + 1)] = C[link].reshape(10, 16).T
        G[16 * self.links:, size:] = np.diag(1.0 / f)
        gradient = self.linear - np.concatenate([np.einsum("liaa->li", C).ravel(), 1.0 / f])
        return gradient, G


def _consistent(mod, base, result, seen, noise_sum, solution):
    """The physically consistent solution nearest the records (Lee & Wensing 2020): minimize
    Q(x) + γ·D(x) over x = [π of every link, friction], Q(x) = ½‖R·(φ(x) − φ̂)‖², where R
    (`seen`) is the triangular factor of the weighted observation matrix on the directions the
    records see (those they do not see left out), so that Q is the
    weighted sum of squared residuals less its minimum, in units of the noise variance; φ̂ the
    unconstrained solution, φ(x) = [matrix·π; friction]; D the log-det divergence from the
    model's defaults (`_Divergence`: convex, a barrier keeping each pseudo-inertia positive
    definite), along γ → CONSISTENT_GAP/(4·links + friction terms) (`_central_path`). The
    directions of x that Q does not see move only with D, so they stay at the defaults when the
    records agree with them. Fills result.values, .inertial, .unconstrained, .price, .success
    and .message, warns when the path fails or when the price is beyond what noise explains
    (`_price_check`), and returns the consistent solution."""
    r, k = len(base.names), len(base.parameters)
    rows = np.array([[fields.get(f, -1) for f in FIELDS]
                     for _, fields in links_of(base.parameters)])
    select = np.zeros((k, rows.size))
    select[rows[rows >= 0], np.flatnonzero(rows.ravel() >= 0)] = 1.0   # π = select @ x_links
    n_f = solution.size - r
    M = np.zeros((solution.size, rows.size + n_f))
    M[:r, :rows.size] = base.matrix @ select
    M[r:, rows.size:] = np.eye(n_f)
    J0 = np.array([_nearest_consistent(pseudo_inertia({f: p for f, p in zip(FIELDS, row)}))
                   for row in _prior_links(mod, base, rows)])
    f0 = np.maximum(np.abs(solution[r:]), 1e-6 * max(1.0, np.abs(solution[r:]).max(initial=0)))
    divergence = _Divergence(J0, f0)
    x0 = np.concatenate([np.array([_link_parameters(J) for J in J0]).ravel(), f0])
    x, failure = _central_path(seen @ M, seen @ (solution - M @ x0), divergence, x0,
                               CONSISTENT_GAP / (4 * len(J0) + n_f))
    consistent = M @ x
    result.unconstrained = dict(result.values)
    result.values = dict(zip(result.names, map(float, consistent)))
    result.inertial = dict(zip(base.parameters, map(float, select @ x[:rows.size])))
    extra = float(np.sum((seen @ (consistent - solution)) ** 2))   # ‖ρ(x)‖² − ‖ρ(φ̂)‖²
    result.price = extra / noise_sum if noise_sum > 0 else 0.0
    _price_check(result, failure, extra, seen.shape[0])
    return consistent


def _price_check(result, failure, extra, rank):
    """Sets result.success and .message, and warns (FitWarning) when the path failed or when
    the consistent estimate moved further from the records than noise explains: the increase
    of the weighted squared residual, in units of the noise variance, beyond the 0.999 quantile
    of χ² with `rank` degrees of freedom (its law when the truth is consistent)."""
    import warnings
    from scipy.stats import chi2
    from ..identifiability import FitWarning
    limit = float(chi2.ppf(0.999, max(rank, 1)))
    result.success = failure is None
    if failure is not None:
        result.message = (f"the consistent estimate was not reached ({failure}); the values are "
                          "the last consistent iterate")
    elif extra > limit:
        result.message = (f"no physically consistent set of links explains the records: the "
                          f"consistent estimate raises the weighted squared residual by "
                          f"{extra:.3g} noise variances, far beyond the {limit:.3g} that noise "
                          f"explains (price {result.price:.3g}); check the torques' signs and "
                          "units, the joints' friction (friction=True) and the model's links")
    else:
        result.message = "physically consistent within the noise"
        return
    warnings.warn(result.message, FitWarning, stacklevel=4)


def _link_parameters(J):
    """The ten parameters (FIELDS order) of a pseudo-inertia J."""
    S = J[:3, :3]
    I = np.trace(S) * np.eye(3) - S
    return np.array([J[3, 3], J[0, 3], J[1, 3], J[2, 3], I[0, 0], I[0, 1], I[1, 1], I[0, 2],
                     I[1, 2], I[2, 2]])


def _central_path(A, c, divergence, x0, gap):
    """(x, failure): x minimizing Q(x) + γ·D(x), Q(x) = ½‖A·(x − x0) − c‖², over x = x0 + S·V_r·w
    (the directions A sees), for γ from Q(x0) (the divergence weighs as much as the misfit)
    down by tenths until γ ≤ gap·max(1, Q(x)) (a suboptimality of `gap` noise variances, or
    relative to Q when the records are far from any consistent estimate), each stage by Newton
    steps from the previous minimizer; failure None, or what stopped the path (the last
    feasible iterate returned). S scales each parameter to the divergence's curvature at x0 and
    A·S = U·diag(s)·Vᵀ, V_r the right singular vectors of its r nonzero singular values: so Q is
    ½‖s·w − Uᵀc‖² exactly, and the directions A does not see (the parameters the torques do not
    depend on, and the combinations they do not separate) stay at the defaults, at right angles
    to what the records move in the divergence's metric. Q/γ + D is self-concordant, so
    Newton's method with a backtracking line search keeping every iterate feasible converges
    (`_line_search`); a stage ends at λ² ≤ 1e-10 (λ the Newton decrement), or when the
    decrease γ·λ² it predicts is below 1e-12 of Q (round-off)."""
    S = 1.0 / np.linalg.norm(divergence.derivatives(x0)[1], axis=0)
    U, s, Vt = np.linalg.svd(A * S, full_matrices=False)
    rank = int(np.sum(s > 1e-13 * s.max(initial=0.0)))
    s, target = s[:rank], (U.T @ c)[:rank]
    basis = S[:, None] * Vt[:rank].T                                # x = x0 + basis @ w

    def misfit(w):
        return 0.5 * float(np.sum((s * w - target) ** 2))

    def objective(w):
        return misfit(w) / gamma + divergence.value(x0 + basis @ w)
    w = np.zeros(rank)
    gamma = max(misfit(w), 10 * gap)
    steps = 0
    while True:
        while True:
            x = x0 + basis @ w
            step, gradient = _newton_step(basis, s, target, divergence, gamma, x, w)
            decrease = float(-gradient @ step)                   # λ², the decrement squared
            if not np.isfinite(decrease):
                return x, f"a non-finite Newton step at γ = {gamma:.3g}"
            if decrease <= max(1e-10, 1e-12 * misfit(w) / gamma):
                break
            steps += 1
            if steps > NEWTON_STEPS:
                return x, f"no convergence in {NEWTON_STEPS} Newton steps (at γ = {gamma:.3g})"
            w = _line_search(w, step, decrease, objective, divergence.feasible, x0, basis)
            if w is None:
                return x, f"no decreasing feasible step at γ = {gamma:.3g}"
        if gamma <= gap * max(1.0, misfit(w)):
            return x0 + basis @ w, None
        gamma = max(0.1 * gamma, gap * max(1.0, misfit(w)))


def _line_search(w, step, decrease, objective, feasible, x0, basis):
    """w + t·step for the first t of 1, ½, ¼, ... that stays feasible and decreases the
    objective by at least ¼·t·λ² (Armijo); None below t = 1e-12."""
    f0, t = objective(w), 1.0
    while t >= 1e-12:
        trial = w + t * step
        if feasible(x0 + basis @ trial) and objective(trial) <= f0 - 0.25 * t * decrease:
            return trial
        t *= 0.5
    return None


def _newton_step(basis, s, target, divergence, gamma, x, w):
    """(Newton step, gradient) in w of Q/γ + D at x = x0 + basis @ w, Q = ½‖s·w − target‖².
    The Hessian is KᵀK, K = [diag(s/√γ); G·basis] (G the divergence's square root): the step
    solves KᵀK·Δ = −g through the triangular factor of K, columns scaled to unit norm, whose
    accuracy goes with cond(K), not cond(K)² (the pseudo-inertias of an estimate near the
    boundary are nearly singular)."""
    from scipy.linalg import solve_triangular
    g_d, G = divergence.derivatives(x)
    gradient = basis.T @ g_d + s * (s * w - target) / gamma
    K = np.vstack([np.diag(s / np.sqrt(gamma)), np.einsum("ij,jk->ik", G, basis)])
    d = 1.0 / np.linalg.norm(K, axis=0)
    R = _triangular_factor(K * d)
    y = solve_triangular(R, solve_triangular(R, -d * gradient, trans="T"))
    return d * y, gradient


def _triangular_factor(K):
    """R of K = Q·R (K tall, m × n) by Householder reflections in NumPy: the matrices here are a
    few hundred by a hundred, where a threaded LAPACK call costs more than it computes (and
    far more on a loaded machine)."""
    A = np.array(K, dtype=float)
    m, n = A.shape
    for k in range(n):
        column = A[k:, k]
        norm = np.linalg.norm(column)
        if norm == 0.0:
            continue
        v = column.copy()
        v[0] += np.copysign(norm, column[0])
        v /= np.linalg.norm(v)
        A[k:, k:] -= 2.0 * np.outer(v, v @ A[k:, k:])
    return np.triu(A[:n])


def _prior_links(mod, base, rows):
    """Each link's ten parameters from the model's defaults (0 where none or absent)."""
    defaults = dict(zip(mod.parameters, np.nan_to_num(mod.defaults)))
    values = np.array([defaults.get(name, 0.0) for name in base.parameters] + [0.0])
    return values[rows]            # rows: index into base.parameters, -1 (the 0 appended) absent
