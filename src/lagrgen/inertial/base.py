"""Base parameters: the identifiable combinations π_b = K·π of a model's inertial parameters,
found numerically as Gautier does (QR of the regressor stacked over random states). Some columns
of Y are zero (a parameter with no effect) and others combinations of earlier ones (a link's mass
acting only through its parent's parameters): Y·π = Y_b·π_b with Y_b the r independent columns."""
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import LagrgenError
from ..runtime.arguments import unknown_name
from .limits import _limit_arrays
from .regressor import inertial_parameters_of, stacked_regressor

#: Which of a link's parameters a dependent one is grouped into first: the inertias, then the
#: first moments, then the mass (so that, as in Khalil's rules, a link's mass and the moments
#: along its joint axis are grouped into the parameters of the links before it).
PREFERENCE = ("Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz", "mx", "my", "mz", "m")

#: Relative size (of the largest, with unit-norm columns) below which a column of the stacked
#: regressor, or the diagonal entry of its QR factor, counts as zero: √ε, far above the
#: round-off of an exact dependency (~1e-15) and far below a genuine one on random states.
BASE_TOL = 1e-8


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
    mod : a built model whose inertial parameters are parameters (a URDF read with
        parameters="inertial", or parameters named m_<link>, mx_<link>, ...)
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


#: The significant digits of a coefficient in a base parameter's name.
NAME_DIGITS = 6


def _combination_name(row, names, lead):
    """"Izz_link1 + 0.2025*m_link2 - mx_link3": the lead parameter, then the others in order,
    coefficients to NAME_DIGITS significant digits (their last digits change with the random
    states of `base_parameters`, and the names are the keys of the estimates)."""
    text = names[lead]
    for j in np.flatnonzero(row):
        if j == lead:
            continue
        c = row[j]
        magnitude = "" if abs(c) == 1 else f"{abs(c):.{NAME_DIGITS}g}*"
        text += f" {'-' if c < 0 else '+'} {magnitude}{names[j]}"
    return text
