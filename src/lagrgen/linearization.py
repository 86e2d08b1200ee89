"""Linearization about an operating point, exact to first order, on the constraint manifold.

A built model's rhs is ẏ = f(t, y, p, u) with y = [q, q̇], and its analytic Jacobian J = ∂f/∂y
already holds the term ∂(M·q̈0)/∂q, so about any point (q0, q̇0, u0) — an equilibrium, a steady
motion (q̇0 ≠ 0) or neither — δẏ = J·δy + ∂f/∂u·δu to first order.

A constrained model moves on the manifold Φ(q, t) = 0, c = A(q, t)·q̇ + b(q, t) = 0 (holonomic
constraints first, then all velocity-level rows), whose tangent space at y0 is the null space of
G = ∂[Φ; c]/∂y. As in SymPy's `Linearizer`, the state is split into independent and dependent
entries — n − n_h coordinates and n − m rates independent — and the dependent ones follow from
G·δy = 0, so δy = T·δx (T is `basis`, the identity on the independent entries). Then

    δẋ = E·J·T·δx + E·∂f/∂u·δu,

E the rows of the independent states. The Baumgarte terms of the stabilized rhs vanish along the
tangent space (they are multiples of G·δy), so this is the motion on the manifold itself. A
velocity constraint that depends on q (a rolling wheel's heading) enters through ∂c/∂q·δq: the
speed-dependent terms a holonomic treatment would drop.

A second-order form M·δq̈ + C·δq̇ + K·δq = B·δu exists when the independent rates are those of the
independent coordinates, i.e. without velocity constraints (M is then the reduced mass matrix
T_qᵀ·M·T_q, δq = T_q·δq_i, and K, C, B are read from A's lower blocks: A = [[0, I], [−M⁻¹K,
−M⁻¹C]]). At an equilibrium K = −∂F/∂q; elsewhere K = ∂(M·q̈0 − F)/∂q.
"""
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from .errors import ConstraintError, LagrgenError, MassMatrixError, NonFiniteError
from .runtime.arguments import as_vector, input_vector, parameters_from

#: Relative pivot below which the constraint Jacobian counts as rank-deficient (redundant
#: constraints at the operating point).
RANK_TOL = 1e-10
#: Relative size of the constraint residuals above which the operating point is off the manifold.
RESIDUAL_TOL = 1e-8
#: Relative size (of the largest) below which an eigenvalue, a real or imaginary part or an
#: asymmetry counts as zero.
ZERO_TOL = 1e-9


class FrozenTimeWarning(UserWarning):
    """The model depends explicitly on t: a result holds only at the one frozen time t given."""


class SecondOrderFormError(LagrgenError, AttributeError):
    """The linearization has no second-order form M·δq̈ + C·δq̇ + K·δq = B·δu."""


def warn_frozen_time(mod, t, what):
    """Warn (FrozenTimeWarning) that `what` of a rheonomic model `mod` holds only at time t."""
    if mod.explicit_time:
        warnings.warn(
            f"model {mod.name!r} depends explicitly on t: this {what} is for the frozen time "
            f"t = {float(t):g} only (the system has no static equilibrium in general; pass t= to "
            "choose the instant)", FrozenTimeWarning, stacklevel=3)


@dataclass(eq=False)
class SecondOrderForm:
    """M·δq̈ + C·δq̇ + K·δq = B·δu in the independent coordinates, δq = coordinate_basis·δq_i."""
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    B: np.ndarray


@dataclass(eq=False)
class Linearization:
    """The motion about (q0, qd0, t, p, u) to first order: δẋ = A·δx + B_state·δu in the
    independent states x (`states`), δy = basis·δx for y = [q, q̇].

    `A` (k×k) and `eigenvalues` always exist. `M`, `C`, `K` (and `B`, the input matrix of
    M·δq̈ + C·δq̇ + K·δq = B·δu, as the guide's "Vibration" page writes it) exist where a
    second-order form does — models without velocity constraints — and raise
    SecondOrderFormError saying why otherwise; there `B` is the first-order input matrix, which
    `state_matrices()` always returns with A.
    """

    A: np.ndarray
    B_state: np.ndarray
    states: tuple
    basis: np.ndarray
    q0: np.ndarray
    qd0: np.ndarray
    t: float = 0.0
    p: np.ndarray = None
    u: np.ndarray = None
    coordinates: tuple = ()    # the independent coordinates: rows and columns of M, C, K
    inputs: tuple = ()
    name: str = ""
    model_coordinates: tuple = ()
    constraint_forces: np.ndarray = None   # λ0 at the operating point (constrained models)
    qdd0: np.ndarray = None    # q̈ at the operating point: 0 at an equilibrium or a steady motion
    M_full: np.ndarray = None  # M(q0) in all the model's coordinates (n×n)
    F_full: np.ndarray = None  # F(q0, q̇0) in all the model's coordinates (n)
    second_order: SecondOrderForm = field(default=None, repr=False)
    why_not_second_order: str = ""

    def _second(self, what):
        if self.second_order is None:
            raise SecondOrderFormError(
                f"this linearization of model {self.name!r} has no {what}: "
                f"{self.why_not_second_order}. Use lin.A and lin.state_matrices() (δẋ = A·δx + "
                f"B·δu in the states {', '.join(self.states)}) or lin.eigenvalues")
        return self.second_order

    @property
    def M(self):
        """The (reduced) mass matrix of the second-order form."""
        return self._second("mass matrix M").M

    @property
    def C(self):
        """C = −∂F/∂q̇ (reduced): damping and gyroscopic terms."""
        return self._second("damping matrix C").C

    @property
    def K(self):
        """K = ∂(M·q̈0 − F)/∂q (reduced), −∂F/∂q at an equilibrium."""
        return self._second("stiffness matrix K").K

    @property
    def B(self):
        """The input matrix: of the second-order form (n_independent × n_inputs, ∂F/∂u reduced)
        where there is one, else of the first-order form (len(states) × n_inputs)."""
        return self.B_state if self.second_order is None else self.second_order.B

    @property
    def has_second_order_form(self):
        """Whether M, C, K exist."""
        return self.second_order is not None

    @property
    def eigenvalues(self):
        """The eigenvalues of A (complex), ascending by real part (then imaginary part); real
        parts equal within ZERO_TOL of the largest modulus (a conjugate pair; roots on the
        imaginary axis, whose are 0) are made equal, so that the order holds exactly."""
        s, _ = spectrum(self.A)
        return levelled(s[ascending(s)])

    @property
    def n(self):
        """The number of independent coordinates (rows of M)."""
        return len(self.coordinates)

    @property
    def coordinate_basis(self):
        """T_q (n × n_independent): δq = T_q·δq_i, the coordinate block of `basis`."""
        n, k = len(self.q0), self.n
        return self.basis[:n, :k]

    def to_coordinates(self, xi):
        """Vectors or columns in the independent coordinates as all coordinates: T_q·xi."""
        return self.coordinate_basis @ xi

    @property
    def names(self):
        """The independent coordinates, in the order of the rows and columns of M, C, K."""
        return self.coordinates

    @property
    def state_names(self):
        """The names of the states x (`states`)."""
        return self.states

    def state_matrices(self):
        """(A, B, C, D) of δẋ = A·δx + B·δu, y = C·δx + D·δu with x the independent states
        (`states`) and y = x."""
        k = len(self.states)
        return self.A, self.B_state, np.eye(k), np.zeros((k, self.B_state.shape[1]))

    def state_space(self):
        """This linearization as `scipy.signal.StateSpace` (x = `states`, u = δu, y = x); a model
        without inputs gets one zero input column (SciPy needs at least one)."""
        from scipy.signal import StateSpace
        A, B, C, D = self.state_matrices()
        if B.shape[1] == 0:
            B, D = np.zeros((A.shape[0], 1)), np.zeros((A.shape[0], 1))
        return StateSpace(A, B, C, D)


#: Eigenvalues within CLUSTER·eps^(1/k) of the largest modulus of each other, k of them, may be
#: one root of multiplicity k whose Jordan block round-off has split into a ring of that radius
#: (a steadily precessing top's double zero: ±8e-8 real parts at a largest modulus of 23; a
#: rolling disk's triple zero at its critical speed: ±1e-7 at 4.4).
CLUSTER = 10.0


def real_part_tolerance(values):
    """(len(values),) float: how far from 0 each eigenvalue's real part may be from round-off
    alone: ZERO_TOL of the largest modulus (at least 1), or, for one of k eigenvalues within
    2·CLUSTER·eps^(1/k) of it of one another (k = 2, 3: a defective root split by round-off),
    CLUSTER·eps^(1/k). Exact zeros (structural: `spectrum` splits them off) are no part of a
    cluster: round-off does not move them (with them a bicycle's capsize root, 3e-3 near its
    speed, would have been taken for a quadruple zero's round-off)."""
    values = np.asarray(values, dtype=complex)
    scale = max(1.0, np.abs(values).max(initial=0.0))
    tol = np.full(values.shape, ZERO_TOL * scale)
    moved = values != 0
    if np.count_nonzero(moved) < 2:
        return tol
    apart = np.abs(values[:, None] - values[None, :])
    apart[:, ~moved] = np.inf
    for k in (2, 3):
        radius = CLUSTER * np.finfo(float).eps ** (1.0 / k) * scale
        clustered = moved & (np.sum(apart <= 2.0 * radius, axis=1) >= k)
        tol = np.where(clustered, np.maximum(tol, radius), tol)
    return tol


def _real_keys(values):
    """The real parts of complex `values` in units of ZERO_TOL of the largest modulus, rounded:
    equal keys are real parts equal to round-off (a conjugate pair; 0 on the imaginary axis)."""
    scale = ZERO_TOL * max(np.abs(values).max(initial=0.0), np.finfo(float).tiny)
    return np.round(values.real / scale)


def ascending(values):
    """The order of complex `values` by real part (equal within ZERO_TOL of the largest: a
    conjugate pair), then imaginary part."""
    return np.lexsort((values.imag, _real_keys(values)))


def levelled(values):
    """Complex `values` in `ascending` order with the real parts that order takes as equal set
    equal (their mean; 0 for those within ZERO_TOL of 0): round-off no longer breaks it."""
    keys = _real_keys(values)
    real = np.array(values.real)
    for key in np.unique(keys):
        group = keys == key
        real[group] = 0.0 if key == 0 else real[group].mean()
    return real + 1j * values.imag


def spectrum(A):
    """(eigenvalues, unit columns) of A with its structural zeros split off exactly: a state
    whose column of A is zero (an ignorable coordinate: no rate depends on it) gives the
    factor λ of det(λI − A) and is removed with its row, repeatedly; the rest is LAPACK's
    eigen-decomposition of what remains, its vectors padded with zeros (the split-off states
    get their unit vectors). A root passing through zero then keeps a vector of its own."""
    k = A.shape[0]
    keep, zero = list(range(k)), []
    while True:
        idle = [j for j in keep if not np.any(A[keep, j])]
        if not idle:
            break
        keep = [j for j in keep if j not in idle]
        zero += idle
    s, V = np.linalg.eig(A[np.ix_(keep, keep)]) if keep else (np.zeros(0), np.zeros((0, 0)))
    vectors = np.zeros((k, k), dtype=complex)
    vectors[np.ix_(keep, range(len(keep)))] = V / np.maximum(np.linalg.norm(V, axis=0), 1e-300)
    vectors[zero, range(len(keep), k)] = 1.0
    return np.concatenate([s.astype(complex), np.zeros(len(zero), dtype=complex)]), vectors


def structural_zeros(s, vectors):
    """Which roots of `spectrum`'s (s, vectors) it split off as structural zeros: exactly 0 with
    a unit vector (a root kept is never both: its vector e_j would make column j of what
    remains zero, and j split off). Works on stacks: s (..., k), vectors (..., k, k)."""
    return (s == 0) & (np.count_nonzero(vectors, axis=-2) == 1)


def linearize(mod, q0, qd0=None, t=0.0, p=None, u=None, dependent=None):
    """Linearize the built model `mod` about (q0, qd0) at time t, exactly to first order.

    Parameters
    ----------
    mod : a built model (either backend)
    q0, qd0 : the operating point (qd0 None: at rest); any point, not only an equilibrium. A
        constrained model's point must satisfy its constraints (`lagrgen.consistent_state`).
    t : the time at which a model that depends explicitly on t is frozen (FrozenTimeWarning)
    p, u : parameters and constant inputs at the operating point
    dependent : names of the dependent coordinates and `<coordinate>_dot` rates of a constrained
        model (default: chosen from the constraint Jacobian by pivoted QR; a holonomic
        constraint's dependent rate is its dependent coordinate's)

    Returns
    -------
    Linearization: `A`, `B` / `state_matrices()`, `states`, `basis`, `eigenvalues`, and `M`, `C`,
    `K` where a second-order form exists.
    """
    n = mod.n_coordinates
    q0, p, u = operating_point(mod, q0, "q0", p, u)
    qd0 = np.zeros(n) if qd0 is None else finite_point(
        as_vector(qd0, n, "qd0"), [f"{c}_dot" for c in mod.coordinates], "qd0")
    t = float(t)
    warn_frozen_time(mod, t, "linearization")
    y0 = np.concatenate([q0, qd0])
    M, _, dF_dqd, dF_du = mod.linear_terms(q0, qd0, t, p, u)
    check_positive_definite(mod.name, M, t, q0)
    J = mod.jacobian(t, y0, p, u)
    base = dict(q0=q0, qd0=qd0, qdd0=mod.rhs(t, y0, p, u)[n:], M_full=M,
                F_full=mod.forcing(q0, qd0, t, p, u), t=t, p=p, u=u,
                inputs=tuple(mod.inputs), name=mod.name,
                model_coordinates=tuple(mod.coordinates))
    rates = tuple(f"{c}_dot" for c in mod.coordinates)
    if not mod.n_constraints:
        B_state = np.vstack([np.zeros_like(dF_du), np.linalg.solve(M, dF_du)])
        form = SecondOrderForm(M=M, C=-dF_dqd, K=-M @ J[n:, :n], B=dF_du)
        return Linearization(A=J, B_state=B_state, states=tuple(mod.coordinates) + rates,
                             basis=np.eye(2 * n), coordinates=tuple(mod.coordinates),
                             second_order=form, **base)
    G = mod.constraint_residual_jacobian(t, y0, p, u)
    _check_on_manifold(mod, t, y0, p, u, G)
    n_h = G.shape[0] - mod.n_constraints
    dep_q, dep_v = _dependent(mod, G, n_h, dependent, y0, t)
    if len(dep_q) == n:
        raise LagrgenError(
            f"model {mod.name!r} has no independent directions at q0: its {n_h} holonomic "
            f"constraints fix all {n} coordinates, so it has nothing to linearize")
    T, ind_q, ind_v = tangent_basis(G, n, n_h, dep_q, dep_v)
    rows = list(ind_q) + [n + j for j in ind_v]
    A_c = G[n_h:, n:]
    B_state = np.vstack([np.zeros_like(dF_du), constrained_input_response(M, A_c, dF_du)])[rows]
    A = product_with_exact_zeros(J[rows], T)
    names = tuple(mod.coordinates[j] for j in ind_q) + tuple(rates[j] for j in ind_v)
    _, lam, _ = mod.constraint_terms(q0, qd0, t, p, u)
    lin = Linearization(A=A, B_state=B_state, states=names, basis=T,
                        coordinates=tuple(mod.coordinates[j] for j in ind_q),
                        constraint_forces=lam, **base)
    if mod.n_constraints > n_h:
        lin.why_not_second_order = (
            f"its {mod.n_constraints - n_h} velocity (nonholonomic) constraint(s) leave "
            f"{len(ind_q)} independent coordinates but only {len(ind_v)} independent rates")
    else:
        lin.second_order = reduced_second_order(A, T[:n, :len(ind_q)], M, B_state)
    return lin


def product_with_exact_zeros(X, Y):
    """X·Y with the entries that cancel to within their own round-off set to 0:
    abs((X·Y)_ij) ≤ k·eps·(abs(X)·abs(Y))_ij, k the inner dimension (the bound of the error of a
    k-term sum of products). A coupling the model does not have then stays an exact zero of A,
    so `spectrum` splits off the ignorable states it leaves (round-off there would couple a
    zero root to the others and spread a double root by eps^(1/3))."""
    product = X @ Y
    bound = X.shape[1] * np.finfo(float).eps * (np.abs(X) @ np.abs(Y))
    product[np.abs(product) <= bound] = 0.0
    return product


def reduced_second_order(A, Tq, M, B_state):
    """The second-order form of δẋ = A·δx + B·δu with x = [δq_i, δq̇_i] and δq = Tq·δq_i:
    M_r = Tqᵀ·M·Tq, K = −M_r·A_21, C = −M_r·A_22, B = M_r·B_2."""
    k = Tq.shape[1]
    M_r = Tq.T @ M @ Tq
    M_r = (M_r + M_r.T) / 2
    return SecondOrderForm(M=M_r, C=-M_r @ A[k:, k:], K=-M_r @ A[k:, :k], B=M_r @ B_state[k:])


def constrained_input_response(M, A, dF_du):
    """∂q̈/∂u of M·q̈ = F + Aᵀλ, A·q̈ = γ (γ free of u): (M⁻¹ − W·S⁻¹·Wᵀ)·∂F/∂u with W = M⁻¹Aᵀ,
    S = A·W."""
    if dF_du.shape[1] == 0:
        return np.zeros_like(dF_du)
    a = np.linalg.solve(M, dF_du)
    W = np.linalg.solve(M, A.T)
    return a - W @ np.linalg.solve(A @ W, A @ a)


def tangent_basis(G, n, n_h, dep_q, dep_v):
    """(T, independent coordinates, independent rates): T (2n × k) with G·T = 0 and the identity
    on the independent entries of y = [q, q̇], for G = [[Φ_q, 0], [∂c/∂q, A]] (n_h + m rows)."""
    ind_q = [j for j in range(n) if j not in dep_q]
    ind_v = [j for j in range(n) if j not in dep_v]
    kq, kv = len(ind_q), len(ind_v)
    Tq = np.zeros((n, kq))
    Tq[ind_q, np.arange(kq)] = 1.0
    if dep_q:
        Phi_q = G[:n_h, :n]
        Tq[dep_q] = -np.linalg.solve(Phi_q[:, dep_q], Phi_q[:, ind_q])
    C_q, A = G[n_h:, :n], G[n_h:, n:]
    Tv = np.zeros((n, kq + kv))
    Tv[ind_v, kq + np.arange(kv)] = 1.0
    if dep_v:
        rhs = np.hstack([C_q @ Tq, A[:, ind_v]])
        Tv[dep_v] = -np.linalg.solve(A[:, dep_v], rhs)
    T = np.vstack([np.hstack([Tq, np.zeros((n, kv))]), Tv])
    return T, ind_q, ind_v


def _dependent(mod, G, n_h, dependent, y0, t):
    """(dependent coordinate indices, dependent rate indices), given by name or chosen by
    pivoted QR: coordinates from Φ_q, then the holonomic rows' rates are those coordinates' and
    the velocity constraints take the best remaining rates."""
    n = mod.n_coordinates
    Phi_q, A = G[:n_h, :n], G[n_h:, n:]
    if dependent is not None:
        dep_q, dep_v = _named_dependent(mod, dependent, n_h, A.shape[0])
    else:
        dep_q = _pivots(Phi_q, list(range(n)), n_h)
        rest = [j for j in range(n) if j not in dep_q]
        A_v = A[n_h:]
        if n_h and A_v.size:
            A_v = A_v[:, rest] - A_v[:, dep_q] @ np.linalg.solve(Phi_q[:, dep_q], Phi_q[:, rest])
        elif A_v.size:
            A_v = A_v[:, rest]
        dep_v = sorted(dep_q + _pivots(A_v, rest, A.shape[0] - n_h))
    for rows, cols, what in ((Phi_q, dep_q, "coordinates"), (A, dep_v, "rates")):
        if rows.shape[0] and not _well_conditioned(rows[:, cols]):
            _redundant(mod, y0, t, rows, what, cols)
    return sorted(dep_q), sorted(dep_v)


def _pivots(rows, columns, k):
    """The k entries of `columns` whose columns of `rows` pivoted QR takes first."""
    if k == 0:
        return []
    _, _, order = scipy.linalg.qr(rows, mode="economic", pivoting=True)
    return sorted(columns[j] for j in order[:k])


def _named_dependent(mod, names, n_h, m):
    """Indices of the dependent coordinates and rates named in `names`."""
    coordinates = list(mod.coordinates)
    rates = [f"{c}_dot" for c in coordinates]
    names = [names] if isinstance(names, str) else list(names)
    dep_q, dep_v = [], []
    for name in names:
        if name in coordinates:
            dep_q.append(coordinates.index(name))
        elif name in rates:
            dep_v.append(rates.index(name))
        else:
            raise LagrgenError(f"dependent: {name!r} is neither a coordinate nor a "
                               f"`<coordinate>_dot` rate of model {mod.name!r}")
    dep_v = sorted(set(dep_v) | set(dep_q)) if len(dep_v) < m else dep_v
    if len(set(dep_q)) != n_h or len(set(dep_v)) != m:
        raise LagrgenError(
            f"dependent: model {mod.name!r} needs {n_h} dependent coordinate(s) (one per "
            f"holonomic constraint) and {m} dependent rate(s) (one per velocity-level "
            f"constraint, those of the dependent coordinates included), got {names}")
    return sorted(set(dep_q)), sorted(set(dep_v))


def _well_conditioned(square):
    s = np.linalg.svd(square, compute_uv=False)
    return s.size == 0 or s[-1] > RANK_TOL * max(s[0], 1e-300)


def _redundant(mod, y0, t, rows, what, cols):
    names = ", ".join(f"{c}={v:.6g}" for c, v in zip(mod.coordinates, y0))
    chosen = ", ".join(mod.coordinates[j] for j in cols)
    raise ConstraintError(
        f"the constraints of model {mod.name!r} are redundant at the operating point t={t!r}, "
        f"{names}, or do not determine the dependent {what} chosen ({chosen}): the constraint "
        "Jacobian is singular there. Remove dependent constraints, name other dependent "
        "coordinates (dependent=[...]), or linearize away from this singular configuration")


def _check_on_manifold(mod, t, y0, p, u, G):
    """ConstraintError unless the residuals at y0 are zero to RESIDUAL_TOL (relative to |G|·|y0|)."""
    r = mod.constraint_residuals(t, y0, p, u)
    scale = np.abs(G).max(initial=1.0) * max(1.0, np.abs(y0).max())
    if np.abs(r).max(initial=0.0) > RESIDUAL_TOL * scale:
        names = ", ".join(f"{c}={v:.6g}" for c, v in zip(mod.coordinates, y0))
        raise ConstraintError(
            f"the operating point of model {mod.name!r} ({names}, with the rates "
            f"{', '.join(f'{v:.6g}' for v in y0[mod.n_coordinates:])}) violates its constraints "
            f"(largest residual {np.abs(r).max():.3g}): linearize about a state on them, e.g. "
            "lagrgen.consistent_state(mod, [*q0, *qd0]) projects one")


def operating_point(mod, q, name, p, u):
    """(q, p, u) of an operating point as arrays: `q` one value per coordinate (`name` says
    which argument in an error), parameters and inputs as the model takes them."""
    n = mod.n_coordinates
    q = as_vector(q, n, f"{name} (one value per coordinate {', '.join(mod.coordinates)})")
    return finite_point(q, mod.coordinates, name), parameters_from(mod, p), \
        input_vector(u, tuple(mod.inputs))


def finite_point(values, names, what):
    """`values` unchanged, or a ValueError naming the first entry that is NaN or infinite."""
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise ValueError(f"{what}: {names[bad[0]]} is {values[bad[0]]}; an operating point must "
                         "be finite numbers")
    return values


def check_positive_definite(name, M, t, q0):
    """MassMatrixError unless the mass matrix M of model `name` at (t, q0) is symmetric positive
    definite (NonFiniteError when an entry overflowed at a finite q0)."""
    if not np.isfinite(M).all() and np.isfinite(q0).all():
        raise NonFiniteError.in_mass_matrix(name, t, q0)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise MassMatrixError.at(name, t, q0) from None
