"""Inertial identification of robots: the regressor, base parameters, identification from joint
records and exciting trajectories (API §21).

The equations of a chain of rigid links are linear in the ten inertial parameters of each link,
π = (m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz) per link (mass, mass times the centre of mass
and the inertia about the link frame's origin, in the link frame):

    M(q)·q̈ − F(q, q̇) = Y(q, q̇, q̈)·π        (inputs, springs and dampers left out of F)

with Y, n × 10·links, the regressor. Some columns of Y are zero (a parameter with no effect) and
others are combinations of earlier ones (a link's mass acting only through its parent's
parameters): only the base parameters π_b = K·π, r of them, are identifiable, and Y·π = Y_b·π_b
with Y_b the r independent columns of Y. Least squares on τ = Y_b·π_b over the samples of a
motion estimates them; a motion whose stacked Y_b is well conditioned (an exciting trajectory)
estimates them well.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import LagrgenError
from .fit import sample_times
from .identifiability import covariance, unseen_directions, warn_unseen
from .runtime.arguments import unknown_name

#: The ten inertial parameters of a link, in Pinocchio's order: m_<link>, mx_<link>, ...
FIELDS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")

#: Which of a link's parameters a dependent one is grouped into first: the inertias, then the
#: first moments, then the mass (so that, as in Khalil's rules, a link's mass and the moments
#: along its joint axis are grouped into the parameters of the links before it).
PREFERENCE = ("Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz", "mx", "my", "mz", "m")

#: Relative size (of the largest, with unit-norm columns) below which a column of the stacked
#: regressor, or the diagonal entry of its QR factor, counts as zero: √ε, far above the
#: round-off of an exact dependency (~1e-15) and far below a genuine one on random states.
BASE_TOL = 1e-8

#: The order of the zero-phase Butterworth low-pass applied to the positions (and torques).
FILTER_ORDER = 4

#: The cut-off is CUTOFF_FACTOR times the highest frequency of the motion: the filter (applied
#: forwards and backwards) then passes the motion with a gain 1 − (1/5)^8 ≈ 1 − 3e-6.
CUTOFF_FACTOR = 5.0

#: How many periods of the cut-off frequency are dropped at each end of filtered records.
EDGE_PERIODS = 4

#: Relative accuracy of a regressor computed from filtered records: directions of the estimates
#: whose singular value (columns scaled to unit norm) is below 10 times this are not determined.
REGRESSOR_ACCURACY = BASE_TOL


# -- the regressor ---------------------------------------------------------------------------------
def inertial_parameters_of(mod):
    """The model's inertial parameter names: `mod.inertial_parameters` when it names some (a
    model built from an articulation, such as a URDF's), else the parameters named
    `<field>_<link>` (FIELDS) of each link with a mass parameter `m_<link>`, by link in
    parameter order."""
    names = _declared_inertial(mod)
    if names:
        return names
    present = set(mod.parameters)
    links = [name[2:] for name in mod.parameters if name.startswith("m_") and len(name) > 2]
    names = tuple(f"{f}_{link}" for link in links for f in FIELDS if f"{f}_{link}" in present)
    if not names:
        raise LagrgenError(
            f"model {mod.name!r} has no inertial parameters: build it with "
            "lagrgen.from_urdf(path, parameters='inertial'), or name its parameters "
            "m_<link>, mx_<link>, my_<link>, mz_<link>, Ixx_<link>, ... (API §21)")
    return names


def links_of(names):
    """[(link, {field: index in names})] of inertial parameter names `<field>_<link>`."""
    links = {}
    for i, name in enumerate(names):
        head, _, link = name.partition("_")
        links.setdefault(link, {})[head] = i
    return list(links.items())


def _declared_inertial(mod):
    """The inertial parameters the built model declares (empty when it declares none)."""
    return tuple(getattr(mod, "inertial_parameters", None) or ())


def _regressor_function(mod):
    """A function (q, qd, qdd) -> Y (n, k): `mod.regressor` when the model declares its inertial
    parameters, else the columns of the inertial parameters of ∂r/∂p, r = M·q̈ − F (the
    equations being linear in π, these are Y itself)."""
    regressor = getattr(mod, "regressor", None)
    if regressor is not None and _declared_inertial(mod):
        return regressor
    if mod.n_constraints:
        raise LagrgenError(
            f"model {mod.name!r} has constraints: the regressor of M·q̈ − F = Y·π needs a chain "
            "or tree in independent coordinates (write the model without constraints)")
    names = inertial_parameters_of(mod)
    columns = [list(mod.parameters).index(name) for name in names]
    p = np.array(mod.defaults, dtype=float)
    p[columns] = np.where(np.isnan(p[columns]), 1.0, p[columns])   # Y does not depend on π
    n = mod.n_coordinates
    jacobian = mod.residual_parameter_jacobian

    def regressor_from_jacobian(q, qd, qdd):
        return jacobian(q, qd, qdd, 0.0, p)[:n, columns]
    return regressor_from_jacobian


def regressor_of(mod, q, qd, qdd):
    """Y(q, q̇, q̈), (n, k) with M·q̈ − F = Y·π, columns in `inertial_parameters_of(mod)` order."""
    return np.asarray(_regressor_function(mod)(q, qd, qdd), dtype=float)


def stacked_regressor(mod, q, qd, qdd):
    """Y at each of N samples, (N, n, k), from states q, qd, qdd of shape (N, n): one regressor
    call per sample."""
    return _stack(_regressor_function(mod), q, qd, qdd)


def _stack(one, q, qd, qdd):
    """`stacked_regressor` with the regressor function `one`."""
    q, qd, qdd = (np.ascontiguousarray(x, dtype=float) for x in (q, qd, qdd))
    first = np.asarray(one(q[0], qd[0], qdd[0]))
    out = np.empty((len(q),) + first.shape)
    out[0] = first
    for i in range(1, len(q)):
        out[i] = one(q[i], qd[i], qdd[i])
    return out


# -- base parameters -------------------------------------------------------------------------------
@dataclass
class BaseParameters:
    """The identifiable combinations of a model's inertial parameters.

    Attributes
    ----------
    names : the base parameters, each named as the combination it is
        (``"Izz_link1 + 0.2025*m_link2 + ..."``)
    matrix : (r, k) array: π_b = matrix @ π, π in the order of `parameters`
    parameters : the k inertial parameters
    independent : the parameter each base parameter is built on (its column of the regressor
        is kept: Y·π = Y[:, columns]·π_b)
    columns : the indices of `independent` in `parameters`
    dependent : the parameters grouped into others (their columns combinations of earlier ones)
    grouping : (r, len(dependent)) array: Y[:, dependent] = Y[:, columns] @ grouping
    unidentifiable : the parameters with no effect on the torques (zero columns)
    """
    names: tuple
    matrix: np.ndarray = field(repr=False)
    parameters: tuple = field(repr=False)
    independent: tuple = field(repr=False)
    columns: tuple = field(repr=False)
    dependent: tuple = field(repr=False)
    grouping: np.ndarray = field(repr=False)
    unidentifiable: tuple = field(repr=False)

    def values(self, pi):
        """π_b = matrix @ π of a full π (array in `parameters` order, or dict name -> value,
        missing names 0)."""
        return self.matrix @ self._full_vector(pi)

    def _full_vector(self, pi):
        if isinstance(pi, dict):
            unknown = [k for k in pi if k not in self.parameters]
            if unknown:
                raise unknown_name("inertial parameter", unknown[0], self.parameters)
            return np.array([float(pi.get(name, 0.0)) for name in self.parameters])
        pi = np.asarray(pi, dtype=float)
        if pi.shape != (len(self.parameters),):
            raise ValueError(f"π must have {len(self.parameters)} entries (in the order of "
                             f"base.parameters), got shape {pi.shape}")
        return pi


def _random_states(mod, samples, seed):
    """(q, qd, qdd), each (samples, n): q uniform within the joints' position limits (±π where
    a joint has none), q̇ and q̈ standard normal."""
    rng = np.random.default_rng(seed)
    n = mod.n_coordinates
    lower, upper, _, _ = _limit_arrays(mod, None)
    lower = np.where(np.isfinite(lower), lower, -np.pi)
    upper = np.where(np.isfinite(upper), upper, np.pi)
    q = rng.uniform(lower, upper, (samples, n))
    return q, rng.standard_normal((samples, n)), rng.standard_normal((samples, n))


def base_parameters(mod, samples=None, seed=0, tol=BASE_TOL):
    """The base (identifiable) inertial parameters of a model, found numerically as Gautier does.

    The regressor is stacked over `samples` random states, W = [Y(q_s, q̇_s, q̈_s)] (N·n × k), and
    its columns scaled to unit norm. A column below `tol` (of the largest) is a parameter with no
    effect. A QR factorization with column pivoting, W·P = Q·R, gives the rank r (the diagonal
    entries abs(R_ii) above tol·abs(R_11)). Which columns are kept follows Gautier: a QR
    factorization of the columns in preference order (link by link from the base; in each link
    the inertias, then the first moments, then the mass, `PREFERENCE`) has abs(R_ii) ≈ 0
    exactly where column i is a combination of the columns before it; those are the dependent
    ones, W_d = W_i·β with β the least-squares solution, and

        Y·π = Y_i·(π_i + β·π_d) = Y_i·π_b,   π_b = [1 β]·P·π = matrix @ π.

    The entries of β are known to about 1e3·ε·cond(W_i) (relative to the column scales): each is
    rounded to that precision, and set to zero below it.

    Parameters
    ----------
    mod : a built model whose inertial parameters are parameters (API §21)
    samples : the number of random states (None: enough for 4 times the rows needed)
    seed : the seed of the random states (reproducible results)
    tol : the relative size below which a column, or a QR diagonal entry, counts as zero

    Returns
    -------
    BaseParameters (names, matrix, independent, dependent, grouping, unidentifiable)
    """
    names = inertial_parameters_of(mod)
    n, k = mod.n_coordinates, len(names)
    samples = samples or max(20, 4 * math.ceil(k / n))
    W = stacked_regressor(mod, *_random_states(mod, samples, seed)).reshape(-1, k)
    scale = np.linalg.norm(W, axis=0)
    moving = np.flatnonzero(scale > tol * scale.max(initial=0.0))
    if moving.size == 0:
        raise LagrgenError(f"no inertial parameter of model {mod.name!r} changes its torques")
    Ws = W[:, moving] / scale[moving]
    order = [list(moving).index(j) for j in _preference_order(names, moving)]
    kept = moving[_kept_in_order(Ws, order, tol, *_pivoted(Ws, tol))]
    dependent = np.array([j for j in moving if j not in set(kept)], dtype=int)
    beta = _grouping(W, scale, kept, dependent)
    return _named_base(names, kept, dependent, beta,
                       np.array([j for j in range(k) if j not in set(moving)], dtype=int))


def _pivoted(Ws, tol):
    """(rank, pivots) of the column-pivoted QR of Ws: the rank counts the diagonal entries of R
    above tol times the first."""
    from scipy.linalg import qr
    R, pivots = qr(Ws, mode="r", pivoting=True)
    d = np.abs(np.diag(R))
    return int(np.sum(d > tol * d[0])), pivots


def _preference_order(names, columns):
    """The columns in the order dependencies are resolved: by link, PREFERENCE within a link."""
    links = [name.partition("_")[2] for name in names]
    link_order = list(dict.fromkeys(links))
    return sorted(columns, key=lambda j: (link_order.index(links[j]),
                                          PREFERENCE.index(names[j].partition("_")[0])))


def _kept_in_order(Ws, order, tol, rank, pivots):
    """Positions (in Ws) of the columns independent of those before them in `order` (Gautier's
    unpivoted QR); the first `rank` pivots of the pivoted QR if the two disagree (a tolerance
    too close to a genuine near-dependency)."""
    from scipy.linalg import qr
    R = qr(Ws[:, order], mode="r")[0]
    d = np.abs(np.diag(R))[:len(order)]
    kept = sorted(order[i] for i in np.flatnonzero(d > tol * d.max()))
    return np.array(kept if len(kept) == rank else sorted(pivots[:rank]), dtype=int)


def _grouping(W, scale, kept, dependent):
    """β with W[:, dependent] = W[:, kept] @ β, each entry rounded to its known precision."""
    if dependent.size == 0:
        return np.zeros((kept.size, 0))
    Wi, Wd = W[:, kept] / scale[kept], W[:, dependent] / scale[dependent]
    beta_s = np.linalg.lstsq(Wi, Wd, rcond=None)[0]
    error = 1e3 * np.finfo(float).eps * np.linalg.cond(Wi) * np.maximum(1.0, np.abs(beta_s))
    beta = beta_s * scale[dependent][None, :] / scale[kept][:, None]
    error = error * scale[dependent][None, :] / scale[kept][:, None]
    decimals = np.floor(-np.log10(error)).astype(int)
    rounded = np.array([[round(b, d) for b, d in zip(row, drow)]
                        for row, drow in zip(beta, decimals)]).reshape(beta.shape)
    return np.where(np.abs(beta) > error, rounded, 0.0)


def _named_base(names, kept, dependent, beta, zero):
    """The BaseParameters of the kept columns, the dependent ones grouped by β."""
    k = len(names)
    matrix = np.zeros((kept.size, k))
    matrix[np.arange(kept.size), kept] = 1.0
    matrix[:, dependent] = beta
    labels = tuple(_combination_name(row, names, j) for row, j in zip(matrix, kept))
    return BaseParameters(names=labels, matrix=matrix, parameters=tuple(names),
                          independent=tuple(names[j] for j in kept),
                          columns=tuple(int(j) for j in kept),
                          dependent=tuple(names[j] for j in dependent), grouping=beta,
                          unidentifiable=tuple(names[j] for j in zero))


def _combination_name(row, names, lead):
    """"Izz_link1 + 0.2025*m_link2 - mx_link3": the lead parameter, then the others in order."""
    text = names[lead]
    for j in np.flatnonzero(row):
        if j == lead:
            continue
        c = row[j]
        magnitude = "" if abs(c) == 1 else f"{abs(c):.12g}*"
        text += f" {'-' if c < 0 else '+'} {magnitude}{names[j]}"
    return text


# -- limits ----------------------------------------------------------------------------------------
def _limit_arrays(mod, limits):
    """(lower, upper, velocity, acceleration), each (n,), inf where a joint has no such limit:
    from `limits` ({coordinate: (lower, upper, velocity, acceleration)}), each None there taken
    from the model's `limits` ({coordinate: (lower, upper, velocity, effort)}, the effort not used)."""
    merged = {c: tuple(entry[:3]) + (None,) for c, entry in mod.limits.items()}
    for coordinate, entry in (limits or {}).items():
        if coordinate not in mod.coordinates:
            raise unknown_name("coordinate", coordinate, tuple(mod.coordinates))
        own = merged.get(coordinate, (None,) * 4)
        merged[coordinate] = tuple(o if value is None else value
                                   for o, value in zip(own, _limit_entry(coordinate, entry)))
    out = np.tile(np.array([[-np.inf], [np.inf], [np.inf], [np.inf]]), (1, mod.n_coordinates))
    for coordinate, entry in merged.items():
        j = mod.coordinates.index(coordinate)
        for row, value in enumerate(entry):
            if value is not None:
                out[row, j] = float(value)
    lower, upper, velocity, acceleration = out
    bad = np.flatnonzero((lower >= upper) | (velocity <= 0) | (acceleration <= 0))
    if bad.size:
        raise ValueError(f"the limits of {mod.coordinates[bad[0]]!r} must have lower < upper "
                         "and positive velocity and acceleration limits")
    return lower, upper, velocity, acceleration


def _limit_entry(coordinate, entry):
    """One joint's (lower, upper, velocity, acceleration), None where absent."""
    entry = tuple(entry) if entry is not None else (None,) * 4
    if len(entry) != 4 or any(v is not None and not np.isfinite(float(v)) for v in entry):
        raise ValueError(f"limits[{coordinate!r}] must be (lower, upper, velocity, acceleration), "
                         f"finite numbers or None, got {entry!r}")
    return entry


# -- records: orientation, velocities and accelerations -------------------------------------------
def _records(mod, t, q, tau, qd, qdd):
    """t (N,), and q, tau, qd, qdd as (n, N) float arrays (qd, qdd None when not given)."""
    t = sample_times(t)
    n, N = mod.n_coordinates, t.size
    arrays = [_joint_record(x, name, n, N) if x is not None else None
              for x, name in ((q, "q"), (tau, "tau"), (qd, "qd"), (qdd, "qdd"))]
    return (t, *arrays)


def _joint_record(x, name, n, N):
    """A record of the n joints at N times as an (n, N) array; a clear error for (N, n)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1 and n == 1:
        x = x[None, :]
    if x.shape != (n, N):
        hint = (f": transpose it ({name}.T)" if x.shape == (N, n) else "")
        raise ValueError(f"{name} must have shape (n, len(t)) = ({n}, {N}), one row per joint "
                         f"as sol.q has, got {x.shape}{hint}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite (drop or interpolate missing samples)")
    return x


def motion_bandwidth(q, rate):
    """The highest frequency (Hz) of the joints' motion: where the Hann-windowed periodogram of
    the detrended positions last exceeds 1e-6 of its peak (the motion's content down to 1e-3 of
    its largest amplitude) and 100 times the noise floor (the median over the upper half of the
    band, where no motion is)."""
    from scipy.signal import detrend
    N = q.shape[1]
    power = np.abs(np.fft.rfft(detrend(q, axis=1) * np.hanning(N), axis=1)) ** 2
    freqs = np.fft.rfftfreq(N, 1.0 / rate)
    floor = np.median(power[:, freqs > rate / 4], axis=1) if N >= 8 else np.zeros(len(q))
    highest = 0.0
    for p, f0 in zip(power, floor):
        if p.max() > 0:
            highest = max(highest, freqs[np.flatnonzero(p > max(1e-6 * p.max(), 100 * f0))].max())
    if highest == 0.0:
        raise ValueError("the positions do not move: identification needs a motion (see "
                         "lagrgen.exciting_trajectory)")
    return float(highest)


def _uniform_rate(t):
    """1/Δt of uniformly sampled times; ValueError otherwise."""
    dt = np.diff(t)
    if np.max(np.abs(dt - dt.mean())) > 1e-6 * dt.mean():
        raise ValueError("t must be uniformly sampled to estimate velocities and accelerations "
                         "(resample the records, or give qd and qdd)")
    return 1.0 / dt.mean()


def _uncorrelated_step(sos, span):
    """The first lag (samples) at which white noise filtered forwards and backwards by the
    second-order sections `sos` is uncorrelated: the first zero of the autocorrelation of its
    impulse response."""
    from scipy.signal import sosfiltfilt
    impulse = np.zeros(4 * span + 1)
    impulse[2 * span] = 1.0
    h = sosfiltfilt(sos, impulse)
    r = np.correlate(h, h, "full")[h.size - 1:]
    crossing = np.flatnonzero(r <= 0)
    return int(crossing[0]) if crossing.size else span


@dataclass
class FilteredRecords:
    """The samples identification uses: times, positions, velocities, accelerations and torques
    (each (n, m)), with the filter's cut-off (Hz, None when unfiltered) and decimation step."""
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    cutoff: float = None
    step: int = 1


def filtered_records(t, q, tau, cutoff=None):
    """Velocities and accelerations from positions, Gautier's way: a zero-phase Butterworth
    low-pass (order FILTER_ORDER, forwards and backwards) of q at `cutoff` Hz (None:
    CUTOFF_FACTOR times `motion_bandwidth`, so the motion passes unchanged and the noise above
    it is removed), then central differences q̇_i = (q_{i+1} − q_{i−1})/2Δt and
    q̈_i = (q_{i+1} − 2q_i + q_{i−1})/Δt². The torques get the same filter, and all records are
    decimated to one sample per first zero of the autocorrelation of white noise through the
    filter (about 0.56/cutoff s): the filtered noise of the samples kept is uncorrelated again,
    so the standard errors stay honest, with fewer regressor calls. The first and last
    EDGE_PERIODS/cutoff seconds are dropped: there the filter has no past or future, and its
    start-up transient (the records' ends reflected oddly) has not decayed below about 1e-4 of
    the motion."""
    from scipy.signal import butter, sosfiltfilt
    rate = _uniform_rate(t)
    cutoff = CUTOFF_FACTOR * motion_bandwidth(q, rate) if cutoff is None else float(cutoff)
    if not 0 < cutoff < 0.45 * rate:
        raise ValueError(f"the filter's cut-off must lie between 0 and 0.45 times the sampling "
                         f"rate ({0.45 * rate:.6g} Hz), got {cutoff:.6g} Hz: sample faster, or "
                         "give cutoff=... (Hz) or qd and qdd")
    sos = butter(FILTER_ORDER, cutoff / (rate / 2), output="sos")
    qf, tauf = sosfiltfilt(sos, q, axis=1), sosfiltfilt(sos, tau, axis=1)
    dt = 1.0 / rate
    qd = (qf[:, 2:] - qf[:, :-2]) / (2 * dt)
    qdd = (qf[:, 2:] - 2 * qf[:, 1:-1] + qf[:, :-2]) / dt ** 2
    step = _uncorrelated_step(sos, int(math.ceil(2 * rate / cutoff)))
    edge = int(math.ceil(EDGE_PERIODS * rate / cutoff))
    keep = np.arange(edge, t.size - 2 - edge, step)
    if keep.size < 2:
        raise ValueError(f"the records are too short for a filter at {cutoff:.6g} Hz: record "
                         f"longer than {3 * EDGE_PERIODS / cutoff:.3g} s, or give qd and qdd")
    inner = keep + 1
    return FilteredRecords(t[inner], qf[:, inner], qd[:, keep], qdd[:, keep], tauf[:, inner],
                           cutoff, step)


# -- identification ------------------------------------------------------------------------------
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
    mod : a built model whose inertial parameters are parameters (API §21)
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
    rank = unseen_directions(R, names, REGRESSOR_ACCURACY)[0]
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
        solution = _consistent(mod, base, result, R, rss, solution)
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


# -- physical consistency --------------------------------------------------------------------------
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

#: The consistent estimates solve the divergence-weighted problems down to this suboptimality
#: (in units of the weighted squared residual, i.e. of the noise variance: negligible).
CONSISTENT_GAP = 1e-8


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
        """(gradient, Hessian): ∂(−log det J)/∂π_i = −tr(J⁻¹A_i), ∂² = tr(J⁻¹A_i·J⁻¹A_j)."""
        B = np.einsum("lab,ibc->liac", np.linalg.inv(self.pseudo_inertias(x)), BASIS)
        f = x[10 * self.links:]
        gradient = self.linear - np.concatenate([np.einsum("liaa->li", B).ravel(), 1.0 / f])
        blocks = np.einsum("liab,ljba->lij", B, B)
        size = 10 * self.links
        hessian = np.zeros((x.size, x.size))
        for link, block in enumerate(blocks):
            hessian[10 * link:10 * (link + 1), 10 * link:10 * (link + 1)] = block
        hessian[size:, size:] = np.diag(1.0 / f ** 2)
        return gradient, hessian


def _consistent(mod, base, result, R, unconstrained_cost, solution):
    """The physically consistent solution nearest the records (Lee & Wensing 2020): minimize
    ½‖R·(φ(x) − φ̂)‖² + γ·D(x) over x = [π of every link, friction], where R is the triangular
    factor of the weighted observation matrix Xw (so the first term is the weighted sum of
    squared residuals less its minimum, in units of the noise variance), φ̂ the unconstrained
    solution, φ(x) = [matrix·π; friction], and D the log-det divergence from the model's
    defaults (`_Divergence`: convex, a barrier keeping each pseudo-inertia positive definite),
    along the central path γ → CONSISTENT_GAP/(4·links + friction terms) (`_central_path`).
    The directions the records do not see stay at the defaults. Fills result.values,
    .inertial, .unconstrained and .price and returns the consistent solution."""
    r, k = len(base.names), len(base.parameters)
    rows = np.array([[fields.get(f, -1) for f in FIELDS]
                     for _, fields in links_of(base.parameters)])
    select = np.zeros((k, rows.size))
    select[rows[rows >= 0], np.flatnonzero(rows.ravel() >= 0)] = 1.0   # π = select @ x_links
    n_f = solution.size - r
    M = np.zeros((solution.size, rows.size + n_f))
    M[:r, :rows.size] = base.matrix @ select
    M[r:, rows.size:] = np.eye(n_f)
    A, b = R @ M, R @ solution                       # Q(x) = ½‖A·x − b‖²
    J0 = np.array([_nearest_consistent(pseudo_inertia({f: p for f, p in zip(FIELDS, row)}))
                   for row in _prior_links(mod, base, rows)])
    f0 = np.maximum(np.abs(solution[r:]), 1e-6 * max(1.0, np.abs(solution[r:]).max(initial=0)))
    divergence = _Divergence(J0, f0)
    x = np.concatenate([np.array([_link_parameters(J) for J in J0]).ravel(), f0])
    x = _central_path(A, b, divergence, x, CONSISTENT_GAP / (4 * len(J0) + n_f))
    consistent = M @ x
    result.unconstrained = dict(result.values)
    result.values = dict(zip(result.names, map(float, consistent)))
    result.inertial = dict(zip(base.parameters, map(float, select @ x[:rows.size])))
    extra = np.sum((R @ (consistent - solution)) ** 2)      # ‖ρ(x)‖² − ‖ρ(φ̂)‖²
    result.price = float(extra / unconstrained_cost) if unconstrained_cost > 0 else 0.0
    return consistent


def _link_parameters(J):
    """The ten parameters (FIELDS order) of a pseudo-inertia J."""
    S = J[:3, :3]
    I = np.trace(S) * np.eye(3) - S
    return np.array([J[3, 3], J[0, 3], J[1, 3], J[2, 3], I[0, 0], I[0, 1], I[1, 1], I[0, 2],
                     I[1, 2], I[2, 2]])


def _central_path(A, b, divergence, x, gamma_final):
    """x minimizing ½‖A·x − b‖² + γ·D(x) for γ from ½‖A·x − b‖² at the start (the divergence
    weighs as much as the misfit) down to gamma_final, by tenths, each by damped Newton steps
    from the previous minimizer. Q/γ + D is self-concordant, so the step t = 1/(1 + λ) (λ the
    Newton decrement) keeps every iterate feasible and converges; a stage ends at λ² ≤ 1e-10."""
    H_q, g_q = A.T @ A, A.T @ b
    _, sv, Vt = np.linalg.svd(A, full_matrices=True)
    seen = int(np.sum(sv > 1e-12 * sv[0])) if sv.size else 0
    gamma = max(0.5 * np.sum((A @ x - b) ** 2), 10 * gamma_final)
    while True:
        for _ in range(200):
            step, gradient = _newton_step(Vt, seen, H_q, g_q, divergence, gamma, x)
            decrement = float(np.sqrt(max(-gradient @ step, 0.0) / gamma))
            if decrement ** 2 <= 1e-10:
                break
            t = 1.0 if decrement < 0.25 else 1.0 / (1.0 + decrement)
            while not divergence.feasible(x + t * step) and t > 1e-12:
                t *= 0.5
            x = x + t * step
        if gamma <= gamma_final:
            return x
        gamma = max(0.1 * gamma, gamma_final)


def _newton_step(Vt, rank, H_q, g_q, divergence, gamma, x):
    """(Newton step, gradient) of ½‖A·x − b‖² + γ·D(x) (H_q = AᵀA, g_q = Aᵀb). Solved in the
    basis Vt of A's right singular vectors, whose last rows (from `rank` on) span its null
    space, with those rows and columns scaled by 1/√γ: there only γ·D curves the objective
    (the directions the records do not see)."""
    g_d, H_d = divergence.derivatives(x)
    gradient = H_q @ x - g_q + gamma * g_d
    scale = np.ones(x.size)
    scale[rank:] = 1.0 / np.sqrt(gamma)
    H = (Vt @ (H_q + gamma * H_d) @ Vt.T) * np.outer(scale, scale)
    return Vt.T @ (scale * np.linalg.solve(H, -scale * (Vt @ gradient))), gradient


def _prior_links(mod, base, rows):
    """Each link's ten parameters from the model's defaults (0 where none or absent)."""
    defaults = dict(zip(mod.parameters, np.nan_to_num(mod.defaults)))
    values = np.array([defaults.get(name, 0.0) for name in base.parameters] + [0.0])
    return values[rows]            # rows: index into base.parameters, -1 (the 0 appended) absent


# -- exciting trajectories -------------------------------------------------------------------------
@dataclass
class ExcitingTrajectory:
    """A periodic joint motion of finite Fourier series (Swevers et al. 1997), per joint i:

        q_i(t) = q0_i + Σ_l a_il/(ω_f·l)·sin(ω_f·l·t) − b_il/(ω_f·l)·cos(ω_f·l·t),  l = 1…L

    with ω_f = 2π/period. `q`, `qd` and `qdd` take a time or an array of times: (n,) or
    (n, len(t)).

    Attributes
    ----------
    coordinates : the joints, in row order
    period : the period (the duration asked for)
    q0 : (n,) the offsets; a, b : (n, L) the coefficients
    condition : the condition number of the stacked base regressor reached
    initial_condition : that of the best random start (what the optimization improved on)
    times : the sample times the condition number is computed at
    """
    coordinates: tuple
    period: float
    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    condition: float = np.nan
    initial_condition: float = np.nan
    times: np.ndarray = field(default=None, repr=False)

    @property
    def omega(self):
        """The fundamental frequency ω_f = 2π/period (rad/s)."""
        return 2 * np.pi / self.period

    def _motion(self, t):
        t = np.asarray(t, dtype=float)
        return _series(self.a, self.b, *_basis(self.omega, self.a.shape[1], t))

    def q(self, t):
        """Positions at t: (n,) or (n, len(t))."""
        dq = self._motion(t)[0]
        return dq + self.q0.reshape((-1,) + (1,) * (dq.ndim - 1))

    def qd(self, t):
        """Velocities at t: (n,) or (n, len(t))."""
        return self._motion(t)[1]

    def qdd(self, t):
        """Accelerations at t: (n,) or (n, len(t))."""
        return self._motion(t)[2]


def _basis(omega, harmonics, t):
    """(ω_l, sin(ω_l·t), cos(ω_l·t)) of the harmonics ω_l = l·ω, l = 1…L; (L,) + t.shape."""
    wl = omega * np.arange(1, harmonics + 1)
    phase = np.multiply.outer(wl, t)
    return wl, np.sin(phase), np.cos(phase)


def _series(a, b, wl, sin, cos):
    """(q − q0, q̇, q̈) of the series with coefficients a, b (n, L) on a basis of `_basis`."""
    return ((a / wl) @ sin - (b / wl) @ cos, a @ cos + b @ sin,
            (b * wl) @ cos - (a * wl) @ sin)


def exciting_trajectory(mod, duration, harmonics=5, limits=None, q0=None, samples=None, seed=0,
                        starts=8, max_iterations=100, base=None):
    """A periodic motion whose stacked base regressor is well conditioned (Swevers et al. 1997).

    Each joint follows a finite Fourier series of `harmonics` harmonics of ω_f = 2π/duration
    about q0 (`ExcitingTrajectory`), periodic in position, velocity and acceleration. The
    coefficients minimize log cond(W_b), W_b the base regressor stacked over `samples` evenly
    spaced times of a period, under the joints' limits: each joint's coefficients are scaled by
    the largest factor that keeps its motion within its position range about q0, its velocity
    and its acceleration limits (checked on a grid of 64 points per period of the highest
    harmonic while optimizing, of 2048 at the end, with a margin of 1e-4), so the search itself
    is unconstrained: the best of `starts` seeded random coefficients, then L-BFGS-B with
    finite-difference gradients until log cond changes by less than 1e-4.

    Parameters
    ----------
    mod : a built model whose inertial parameters are parameters (API §21)
    duration : the period of the motion (s)
    harmonics : the number of harmonics L
    limits : dict coordinate -> (lower, upper, velocity, acceleration), None where absent;
        what is not given (a coordinate, or a None in its entry) is taken from the model's
        `limits` (lower, upper, velocity) when it has them, so `{c: (None, None, None, 10.0)}`
        adds an acceleration limit to a URDF's. Every joint needs at least one finite limit.
    q0 : the offsets (dict or array; None: the middle of each joint's position range, else 0)
    samples : the number of times the condition number is computed at (None: enough for 3
        times the rows the base parameters need, and 2 per harmonic)
    seed, starts, max_iterations : the random starts and the optimizer's iteration limit
    base : the BaseParameters (None: `base_parameters(mod)`)

    Returns
    -------
    ExcitingTrajectory (q(t), qd(t), qdd(t), condition, q0, a, b)
    """
    from scipy.optimize import minimize
    duration = float(duration)
    if not (np.isfinite(duration) and duration > 0) or int(harmonics) != harmonics \
            or harmonics < 1:
        raise ValueError("duration must be a positive time and harmonics a positive integer")
    base = base or base_parameters(mod)
    n, L = mod.n_coordinates, int(harmonics)
    lower, upper, velocity, acceleration = _limit_arrays(mod, limits)
    unbounded = [c for c, *row in zip(mod.coordinates, lower, upper, velocity, acceleration)
                 if np.all(np.isinf(row))]
    if unbounded:
        raise ValueError(f"joint {unbounded[0]!r} has no position, velocity or acceleration "
                         "limit: give limits={coordinate: (lower, upper, velocity, "
                         "acceleration)} (None where absent)")
    offsets = _offsets(mod, q0, lower, upper)
    bounds = (lower - offsets, upper - offsets, velocity, acceleration)
    samples = samples or max(2 * (2 * L + 1), math.ceil(3 * len(base.names) / n))
    times = duration * np.arange(samples) / samples
    omega = 2 * np.pi / duration
    at_times = _basis(omega, L, times)
    on_grid = _basis(omega, L, duration * np.arange(64 * L) / (64 * L))
    condition = _conditioning(mod, base)

    def scaled(x, grid=on_grid, margin=0.0):
        a, b = x[:n * L].reshape(n, L), x[n * L:].reshape(n, L)
        scale = (1 - margin) * _largest_scale(_series(a, b, *grid), *bounds)
        return a * scale[:, None], b * scale[:, None]

    def objective(x):
        dq, qd, qdd = _series(*scaled(x), *at_times)
        return np.log(condition(offsets[:, None] + dq, qd, qdd))

    rng = np.random.default_rng(seed)
    candidates = [rng.standard_normal(2 * n * L) / np.tile(np.arange(1, L + 1), 2 * n)
                  for _ in range(max(1, int(starts)))]
    scores = [objective(x) for x in candidates]
    best = candidates[int(np.argmin(scores))]
    result = minimize(objective, best, method="L-BFGS-B",
                      options={"maxiter": int(max_iterations), "ftol": 1e-4})
    x = result.x if result.fun < min(scores) else best
    a, b = scaled(x, _basis(omega, L, duration * np.arange(2048 * L) / (2048 * L)), 1e-4)
    final = ExcitingTrajectory(tuple(mod.coordinates), duration, offsets, a, b, times=times,
                               initial_condition=float(np.exp(min(scores))))
    final.condition = condition(final.q(times), final.qd(times), final.qdd(times))
    return final


def _offsets(mod, q0, lower, upper):
    """The motion's centre: q0 (dict or array), else the middle of each finite range, else 0."""
    from .runtime.arguments import named_vector
    bounded = np.isfinite(lower) & np.isfinite(upper)
    middle = np.where(bounded, 0.5 * (np.where(bounded, lower, 0) + np.where(bounded, upper, 0)),
                      0.0)
    if q0 is None:
        offsets = middle
    elif isinstance(q0, dict):
        offsets = named_vector(q0, tuple(mod.coordinates), middle, "coordinate")
    else:
        offsets = np.asarray(q0, dtype=float).reshape(-1)
    if offsets.shape != middle.shape or np.any(offsets <= lower) or np.any(offsets >= upper):
        raise ValueError(f"q0 must give the {middle.size} joints' centres strictly within their "
                         "position limits (a joint with one position limit needs its q0 given)")
    return offsets


def _largest_scale(motion, low, high, velocity, acceleration):
    """Per joint, the largest factor s with s·(q − q0) within [low, high] and s·|q̇|, s·|q̈|
    within the velocity and acceleration limits, for a motion (q − q0, q̇, q̈) on a grid."""
    dq, v, acc = motion
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.stack([high / dq.max(1).clip(min=1e-300), low / dq.min(1).clip(max=-1e-300),
                           velocity / np.abs(v).max(1), acceleration / np.abs(acc).max(1)])
    return np.nanmin(np.where(ratios > 0, ratios, np.inf), axis=0)


def _conditioning(mod, base):
    """A function (q, qd, qdd), each (n, m), -> cond of the base regressor stacked over the m
    samples."""
    one = _regressor_function(mod)
    columns = list(base.columns)

    def condition(q, qd, qdd):
        W = _stack(one, q.T, qd.T, qdd.T)[:, :, columns].reshape(-1, len(columns))
        s = np.linalg.svd(W, compute_uv=False)
        return float(s[0] / s[-1]) if s[-1] > 0 else np.inf
    return condition
