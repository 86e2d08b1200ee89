"""Estimation of the base parameters from joint records: weighted least squares (Gautier's
per-joint weights) with fit's standard errors and identifiability warnings; the physically
consistent estimates through `consistency`."""
from dataclasses import dataclass, field

import numpy as np

from ..identifiability import covariance, unseen_directions, warn_unseen
from .base import BASE_TOL, BaseParameters, base_parameters
from .consistency import _consistent
from .records import FilteredRecords, _records, filtered_records
from .regressor import stacked_regressor

#: Relative accuracy of a regressor computed from filtered records: directions of the estimates
#: whose singular value (columns scaled to unit norm) is below 10 times this are not determined.
REGRESSOR_ACCURACY = BASE_TOL


@dataclass
class InertialEstimate:
    """Estimates of the base parameters (and joint friction) from joint records.

    Attributes
    ----------
    values, stderr : dict name -> estimate, and its standard error (base parameters, then
        `fv_<joint>`, `fc_<joint>` with friction=True); for consistent=True the values are the
        consistent ones and the standard errors those of the unconstrained estimates
    names : the estimated names, in the order of `cov`
    cov : covariance of the (unconstrained) estimates
    base : the BaseParameters the names come from
    rms : dict joint -> root mean square of the torque residual
    sigma : dict joint -> the noise level of the joint's torque (its weight is 1/sigma)
    condition : condition number of the weighted observation matrix
    t, tau, predicted : the samples used: times (m,), torques and predicted torques (n, m)
    cutoff, step : the filter's cut-off (Hz; None when qd and qdd were given) and decimation
    inertial : consistent=True: dict of a physically consistent full π with these base values
    unconstrained : consistent=True: the unconstrained estimates (dict)
    price : consistent=True: the relative increase of the weighted sum of squared residuals
        (relative to the share of noise when the records fit exactly)
    success, message : consistent=True: whether the consistent estimate was reached, and what
        was found (a FitWarning is given when it was not, or when it moved further from the
        records than their noise explains)
    unidentified, unseen : the names the records do not determine, and those directions
    """
    values: dict
    stderr: dict
    names: tuple
    cov: np.ndarray = field(repr=False)
    base: BaseParameters = field(repr=False)
    rms: dict = field(default_factory=dict)
    sigma: dict = field(default_factory=dict, repr=False)
    condition: float = np.nan
    t: np.ndarray = field(default=None, repr=False)
    tau: np.ndarray = field(default=None, repr=False)
    predicted: np.ndarray = field(default=None, repr=False)
    cutoff: float = None
    step: int = 1
    inertial: dict = field(default=None, repr=False)
    unconstrained: dict = field(default=None, repr=False)
    price: float = None
    success: bool = True
    message: str = ""
    unidentified: tuple = ()
    unseen: list = field(default_factory=list, repr=False)

    def summary(self):
        """A table of the estimates with their standard errors, and how well they fit."""
        width = max(len(name) for name in self.names)
        lines = [f"{'parameter':<{width}}  {'estimate':>12}  {'stderr':>10}  {'rel.':>7}"]
        for name in self.names:
            value, err = self.values[name], self.stderr[name]
            rel = f"{100 * err / abs(value):6.2f}%" if value else "      -"
            lines.append(f"{name:<{width}}  {value:12.6g}  {err:10.3g}  {rel}")
        rms = ", ".join(f"{j} {v:.3g}" for j, v in self.rms.items())
        lines.append(f"torque residual RMS: {rms}")
        source = (f"filtered at {self.cutoff:.3g} Hz, one sample in {self.step}"
                  if self.cutoff else "given velocities and accelerations")
        lines.append(f"condition number {self.condition:.4g}; {self.t.size} samples ({source})")
        if self.price is not None:
            lines.append(f"physically consistent: residual +{100 * self.price:.3g} %")
        return "\n".join(lines)


def identify_inertial(mod, t, q, tau, qd=None, qdd=None, consistent=False, friction=False,
                      cutoff=None, base=None):
    """Estimate the base inertial parameters from records of joint positions and torques.

    The torques are τ = Y_b(q, q̇, q̈)·π_b (+ F_v·q̇ + F_c·sign(q̇) with friction=True), stacked
    over the samples. As Gautier does: ordinary least squares first; the noise level of each
    joint from its residual, σ_j² = ‖ρ_j‖²/(m − c_j) (m samples, c_j columns acting on joint j);
    then least squares with the rows of joint j weighted by 1/σ_j, the covariance s²·(WᵀW)⁻¹
    of the weighted matrix W (directions it does not see get an infinite variance and an
    IdentifiabilityWarning, as `lagrgen.fit` gives them).

    Parameters
    ----------
    mod : a built model whose inertial parameters are parameters (a URDF read with
        parameters="inertial", or parameters named m_<link>, mx_<link>, ...)
    t : (N,) increasing sample times
    q, tau : (n, N) joint positions and torques (one row per joint, as `sol.q`; (N, n) is
        refused with a ValueError saying to transpose)
    qd, qdd : (n, N) velocities and accelerations; when either is None both come from the
        positions through `filtered_records` (a zero-phase low-pass at `cutoff` Hz, central
        differences; the torques filtered alike, all decimated)
    consistent : return physically consistent estimates: positive masses, inertias positive
        definite and satisfying the triangle inequality, i.e. each link's pseudo-inertia
        [[½tr(I)·1 − I, h], [hᵀ, m]] positive definite (Wensing et al. 2017), friction
        coefficients positive; the nearest to the records in the weighted residual, found by
        an interior-point path on the log-det divergence from the model's defaults (Lee &
        Wensing 2020), which also keeps the directions the records do not see at the defaults
        (`est.inertial`, `est.unconstrained`, `est.price`)
    friction : add a viscous and a Coulomb friction coefficient per joint (`fv_<joint>`,
        `fc_<joint>`)
    cutoff : the filter's cut-off in Hz (None: 5 times the motion's highest frequency)
    base : the BaseParameters to estimate (None: `base_parameters(mod)`)

    Returns
    -------
    InertialEstimate (values, stderr, cov, rms, condition, summary(), ...)
    """
    base = base or base_parameters(mod)
    t, q, tau, qd, qdd = _records(mod, t, q, tau, qd, qdd)
    records = (filtered_records(t, q, tau, cutoff) if qd is None or qdd is None else
               FilteredRecords(t, q, qd, qdd, tau))
    Y = _observation_blocks(mod, base, records, friction)
    names = base.names + (_friction_names(mod) if friction else ())
    factors = _joint_factors(Y, records.tau.T)
    sigma = _joint_noise(factors, Y)
    solution, R, rss = _stacked_solution(factors / sigma[:, None, None])
    rank, _, Vt, s, scale = unseen_directions(R, names, REGRESSOR_ACCURACY)
    rows = Y.shape[0] * Y.shape[1]
    s2 = rss / (rows - rank) if rows > rank else np.nan
    cov, unidentified, directions = covariance(R, s2, list(names), REGRESSOR_ACCURACY)
    if directions:
        warn_unseen(directions, rank, len(names),
                    advice="Record a motion that excites them (lagrgen.exciting_trajectory)")
    result = InertialEstimate(
        values=dict(zip(names, map(float, solution))),
        stderr=dict(zip(names, map(float, np.sqrt(np.diag(cov))))), names=names, cov=cov,
        base=base, sigma=dict(zip(mod.coordinates, map(float, sigma))),
        condition=float(np.linalg.cond(R)), t=records.t, tau=records.tau,
        cutoff=records.cutoff, step=records.step, unidentified=unidentified,
        unseen=directions)
    if consistent:
        seen = (s[:rank, None] * Vt[:rank]) * np.where(scale > 0, scale, 1.0)   # R on what it sees
        solution = _consistent(mod, base, result, seen, max(rss, rows - rank), solution)
    result.predicted = (Y @ solution).T
    result.rms = dict(zip(mod.coordinates,
                          map(float, np.sqrt(np.mean((result.predicted - records.tau) ** 2, 1)))))
    return result


def _friction_names(mod):
    return (tuple(f"fv_{c}" for c in mod.coordinates) + tuple(f"fc_{c}" for c in mod.coordinates))


def _observation_blocks(mod, base, records, friction):
    """The base regressor at each sample, (m, n, p), with the friction columns q̇_j and
    sign(q̇_j) acting on joint j (friction=True). A column below BASE_TOL of the largest is
    round-off of a parameter the records do not excite (the recursive formulation's sums leave
    1e-17 where a product with q̇ = 0 would give 0): it is set to zero, so that the covariance,
    which scales columns to unit norm, sees that the records do not determine it."""
    Y = stacked_regressor(mod, records.q.T, records.qd.T, records.qdd.T)[:, :, list(base.columns)]
    if friction:
        eye = np.eye(mod.n_coordinates)
        qd = records.qd.T[:, :, None]
        Y = np.concatenate([Y, qd * eye, np.sign(qd) * eye], axis=2)
    norms = np.sqrt(np.einsum("mnp,mnp->p", Y, Y))
    Y[:, :, norms <= BASE_TOL * norms.max(initial=0.0)] = 0.0
    return Y


def _joint_factors(Y, tau):
    """The triangular factors R_j, (n, p + 1, p + 1), of each joint's augmented observations
    [Y_j, τ_j] = Q_j·R_j (Y_j = Y[:, j, :]): ‖[Y_j, τ_j]·v‖ = ‖R_j·v‖ for every v, so least
    squares over all joints, with any weight per joint, work on the stacked R_j alone."""
    from scipy.linalg import qr
    m, n, p = Y.shape
    factors = np.zeros((n, p + 1, p + 1))
    for j in range(n):
        block = np.asfortranarray(np.column_stack([Y[:, j, :], tau[:, j]]))
        R = qr(block, mode="r", overwrite_a=True, check_finite=False)[0]
        factors[j, :min(m, p + 1)] = R[:p + 1]
    return factors


def _stacked_solution(factors):
    """(θ, R, ρ²) of the least squares Σ_j ‖Y_j·θ − τ_j‖² given the joints' factors: θ of least
    norm, R (p × p) the triangular factor of the stacked Y (its singular values and right
    singular vectors), ρ² the least sum of squared residuals."""
    from scipy.linalg import qr
    p = factors.shape[2] - 1
    T = qr(factors.reshape(-1, p + 1), mode="r", check_finite=False)[0]
    R, z = T[:p, :p], T[:p, p]
    theta = np.linalg.lstsq(R, z, rcond=None)[0]
    return theta, R, float(T[p, p] ** 2 + np.sum((R @ theta - z) ** 2))


def _joint_noise(factors, Y):
    """σ_j of each joint's torque from the ordinary least-squares residual, Gautier's
    σ_j² = ‖ρ_j‖²/(m − c_j) (c_j the parameters acting on joint j); a joint fitted exactly
    (noise-free records) takes the largest σ."""
    theta = _stacked_solution(factors)[0]
    rho2 = np.sum((factors @ np.append(theta, -1.0)) ** 2, axis=1)
    acting = np.count_nonzero(np.any(Y != 0, axis=0), axis=1)
    dof = Y.shape[0] - acting
    if np.any(dof <= 0):
        raise ValueError(f"{Y.shape[0]} samples do not leave a residual to estimate the "
                         f"torque noise of {int(acting.max())} parameters: record longer")
    sigma = np.sqrt(rho2 / dof)
    scale = max(sigma.max(), np.abs(factors[:, :, -1]).max())
    tiny = 1e-12 * scale
    return np.where(sigma > tiny, sigma, max(sigma.max(), tiny, np.finfo(float).tiny))
