"""Sequential quadratic programming on a collocation NLP's stage structure: the solver that profits
from a warm start (re-planning, refined meshes), where IPOPT's interior point walks its barrier
path again.

The NLP of a fixed-duration problem without unknown parameters is stage-structured: every point
j has its variables z_j = [x_j, a_j, u_j] (x = [q, q̇], a = q̈), its residual r(z_j) = 0 and its
Lagrangian Hessian block W_j; the defects of interval k tie its start s, its midpoint m (if any)
and its end e linearly. Each SQP step solves the QP

    min ½·dᵀ·W·d + ∇fᵀ·d   s.t.   c(x) + J·d = 0,   lo ≤ x + d ≤ hi

by eliminating, per point, the accelerations with the linearized residual (a block pivot with the
mass matrix: da = −R_a⁻¹·(r + R_x·dx + R_u·du), so y_j = [dx_j, du_j] remain), then, per
interval, the states of its midpoint and end with its defect rows (a square system: they are
affine in the start's y_s and the inputs v_k = [u_m, u_e]), which leaves a discrete-time optimal
control problem in X_k = y_s, solved by a Riccati recursion (backward: the quadratic cost-to-go
V_k(X) = ½·Xᵀ·P_k·X + p_kᵀ·X; forward: the steps). Bounds are held by a primal-dual active set:
each active bound is an augmented-Lagrangian term ½·ρ·(d_i − δ_i)² + z_i·(d_i − δ_i) in its
point's block, its multiplier z_i updated from the violation with the factorization kept, the set
updated from the multipliers' signs and the steps' violations; the linear rows confined to one
interval (an input's envelope between its points, a value between nodes) are affine in that
interval's X_k and v_k and held alike, their terms added to its stage. When the set does not
settle, a primal-dual interior point on the same recursion solves the QP (Mehrotra's
predictor-corrector, the barrier's Hessian on the same diagonals and stages), and its solution
is made exact by the active set's passes from the constraints it found active (those whose
multiplier exceeds their slack), or, where they do not settle, taken as it stands with its
multipliers of every bound (μ/s on those it leaves inactive: the KKT error then counts their
complementarity), as are the later QPs of the solve (and of the next mesh's: `solve`'s
purify=False); far from the solution (the first steps of
a re-plan) the interior point's solution at a loose tolerance is the step, the active set not
tried there nor in the step after, and elsewhere abandoned for the interior point as soon as
its changes shrink too slowly to settle. The defects' and
residuals' multipliers come back from the recursion (the costates), in the NLP's sign
convention (∇f + Jᵀλ + z = 0, W = ∇²f + Σ λ_i·∇²c_i), for the next step's Hessian. A step is
accepted by IPOPT's filter line search (`_Filter`), and the solve converges where the
constraints hold to tol and the stationarity residual (complementarity included) is within tol,
as IPOPT's; anything the structure does not cover, or a step that fails, is reported so the
caller can fall back to IPOPT, and a solve that stalls within STALLED_NEAR·tol stops there for
the caller to finish.
"""
from dataclasses import dataclass, field, fields

import numpy as np

from ..errors import LagrgenError
from ._riccati import factor as riccati_factor, forward as riccati_forward, \
    diagonal_hessians, point_hessians, stage_gradients, stage_hessians, \
    vectors as riccati_vectors

#: An active bound's penalty ρ relative to its point's Hessian scale: the augmented Lagrangian
#: converges by about this factor per pass, and the recursion stays well conditioned. The
#: point's Hessian understates how stiff a velocity is once the defects tie it to its
#: neighbours: at 1e4 the Panda's velocity limits held 3e-7 off after 20 passes, ~150 of them
#: with multipliers of the wrong sign that a stiffer penalty revealed.
PENALTY = 1e8
#: The interior point's penalty on fixed variables (no multiplier updates there: the SQP's step
#: is clipped onto them, and the next linearization corrects what is left).
PIN_PENALTY = 1e8
#: Multiplier updates that put the fixed variables onto their values after the interior point.
PIN_UPDATES = 6
#: A full step that changes the objective by at most STALL (relative) on a feasible point whose
#: stationarity residual is below STALL_DUAL ends the iterations: the motion moves along a flat
#: valley of the objective (an optimum that is not unique to the last digits), where the
#: residual, quadratic in the step, does not fall further.
STALL, STALL_DUAL = 1e-10, 1e-2
#: At a point stationary to tol (the residual and complementarity of `kkt_error`), a step
#: that takes the constraints' violation to RESTORING of it or less is taken though the merit
#: function does not fall: with the interior point's QP solutions taken as it left them, the
#: line search on Talos's 615-node mesh failed at a violation of 9.9e-11 and a stationarity of
#: 4.4e-9, one step from convergence.
RESTORING = 0.5
#: The inertia correction's regularizations (`Inertia`): the grid's first, its last and its
#: ratio.
FIRST_REGULARIZATION, MAX_REGULARIZATION, GROWTH = 1e-8, 1e4, 10.0
#: SQP iterations by default.
SQP_ITERATIONS = 30
#: The filter line search's constants (`_Filter`, IPOPT's defaults): θ_max and θ_min as
#: multiples of max(1, θ at the start), the margins γ_θ = γ_φ, Armijo's η, the switching
#: condition's exponents s_φ and s_θ, the largest rise of φ relative to max(1, |φ|), and the
#: shortest step tried.
FILTER_THETA_MAX, FILTER_THETA_MIN, FILTER_GAMMA, FILTER_ETA = 1e4, 1e-4, 1e-5, 1e-4
FILTER_S_PHI, FILTER_S_THETA, FILTER_PHI_RISE, SMALLEST_STEP = 2.3, 1.1, 1e5, 1e-3
#: Passes of the active set before the QP turns to the interior point (QUICK_PASSES after a QP
#: the active set did not settle); the interior point's iterations.
ACTIVE_PASSES, QUICK_PASSES, IPM_ITERATIONS = 8, 2, 60
#: The most passes of an active set that is settling (each changing no more constraints than the
#: one before, or than 1/SETTLING of the first's): a pass costs one factor, the interior point a
#: dozen.
SETTLING_PASSES, SETTLING = 20, 4
#: Far from the solution (the KKT error above LOOSE_ABOVE), a QP the active set does not solve
#: is solved by the interior point to LOOSE_TOL (relative to its first gap) and taken as it is:
#: the steps there are long and the next linearization corrects them (on the Panda's re-plans
#: the first two QPs; 8–10 factors each instead of 16–20, with the same iterations).
LOOSE_ABOVE, LOOSE_TOL = 30.0, 1e-5
#: An active set changing more constraints a pass than this is abandoned for the interior point
#: when its changes do not shrink fast enough to settle within SETTLING_PASSES (`_hopeless`).
HOPELESS_FEW = 16
#: A solve that may hand over (`solve`'s `hand_over`) gives up once the constraints hold to
#: STALLED_PRIMAL and its stationarity residual, still above tol, fell less than STALLED_DROP
#: times in each of STALLED_ITERATIONS full steps in a row (Newton's steps would square it).
#: Before the interior point's multipliers were kept (`bound_multipliers`), Talos's 615-node
#: mesh stayed near 5e-5 (4.4e-5, 6.7e-5, 5.6e-5, 5.3e-5, at 7 s an iteration); one damped
#: step that lifts the residual (an active set changing) is no stall.
STALLED_PRIMAL, STALLED_DROP, STALLED_ITERATIONS = 1e-6, 10.0, 2
#: A stall within STALLED_NEAR·tol ends the solve as a flat optimum does (the caller finishes
#: from its answer) rather than handing the mesh over from its start: on a 578-node mesh of
#: Talos the residual held at 1.1e-8 (tol 1e-8: the size of the interior point's rounding of
#: its multipliers), and IPOPT from the mesh's start then took 19 iterations and 47 s.
STALLED_NEAR = 100.0
#: A solve that may hand over also gives up once its KKT error (the larger of the constraints'
#: violation and the stationarity residual), within NEAR_SOLUTION, fell less than STALLED_DROP
#: times in each of CRAWL_ITERATIONS iterations in a row, full steps or not: the caller finishes
#: from its last iterate (`Outcome.near`). The Panda's re-plan from a state 0.01 rad off its plan
#: (130 nodes, velocities riding their limits) crept from 5e-5 to 1e-8 over 25 damped steps and
#: did not converge in 30 (3.5 s), and IPOPT from the re-plan's start then took 1549 iterations
#: (238 s); handed over at iteration 8, IPOPT finished in 3 (1.05 s in all).
NEAR_SOLUTION, CRAWL_ITERATIONS = 1e-3, 3
DEBUG = False


def scatter_add(target, index, values):
    """target[index[r]] += values[r] for every r, repeated indices summed (np.add.at's result,
    by segments of the sorted indices: np.add.at is slow on blocks)."""
    order = np.argsort(index, kind="stable")
    ordered = index[order]
    heads = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]]) if ordered.size else ordered
    if ordered.size:
        target[ordered[heads]] += np.add.reduceat(values[order], heads, axis=0)


class Unsupported(LagrgenError):
    """The problem has a part the stage-structured SQP does not cover (said in the message)."""


class StepFailed(Unsupported):
    """The SQP covers the problem, but one of its steps failed (said in the message: a QP
    whose interior point stalled, a line search, a singular block), or it stalled or ran out of
    iterations: then `outcome` is its last iterate (an `Outcome`), else None."""

    def __init__(self, message, outcome=None):
        super().__init__(message)
        self.outcome = outcome


def unsupported(tr):
    """Why the SQP cannot solve the transcription `tr` (None when it can)."""
    L, problem = tr.layout, tr.problem
    if L.m:
        return "a constrained model"
    if L.unknown:
        return "unknown parameters"
    if L.free:
        return "a free duration"
    if tr.n_path:
        return "path constraints"
    if tr.n_data:
        return "data to track"
    if tr.E.shape[0] and Rows.spanning(tr):
        return "linear rows across intervals (periodicity, inputs tied to a coarser grid)"
    if tr.n_cons:
        return "consistency rows"
    if tr.n_term or tr.problem._terminal_cost is not None:
        return "terminal constraints or a terminal cost"
    if not tr.recursive and not tr.exact:
        return "no exact Hessian"
    return None


@dataclass
class Stages:
    """The defect blocks of every interval, from the transcription's (scaled) defect rows:
    D[k, p] (per × nz) the coefficients of the interval's p-th point (0: start, then the
    midpoint, last: the end), `points[k, p]` their point indices."""
    D: np.ndarray
    points: np.ndarray
    per: int

    @classmethod
    def of(cls, tr):
        L = tr.layout
        intervals, stride, nz = L.nodes - 1, L.stride, L.nz
        per = tr.n_defects // intervals
        rows, cols = tr.def_rows, tr.def_cols
        values = tr.def_c0 * tr.defect_entry_scale + 1.0 * tr.def_c1 * \
            tr.defect_entry_scale * tr.problem.duration_bounds[0]
        k = rows // per
        point = cols // nz
        shape = (intervals, stride + 1, per, nz)
        place = np.ravel_multi_index((k, point - k * stride, rows % per, cols % nz), shape)
        D = np.bincount(place, values, minlength=int(np.prod(shape))).reshape(shape)
        points = (np.arange(intervals)[:, None] * stride
                  + np.arange(stride + 1)[None, :]).astype(np.int64)
        return cls(D, points, per)


@dataclass
class Rows:
    """The linear rows of the NLP (tr.E) confined to one interval: `interval` (R,), their
    coefficients per point of it `coef` (R, points of an interval, nz), their bounds lo, hi on
    E·x (R,), and `index` their rows in E; `slot` (R,) each row's place among its interval's
    rows, `width` the most rows of an interval (the stages' row blocks are padded to it)."""
    interval: np.ndarray
    coef: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    index: np.ndarray
    slot: np.ndarray = field(init=False)
    width: int = field(init=False)

    def __post_init__(self):
        order = np.argsort(self.interval, kind="stable")
        first = np.searchsorted(self.interval[order], self.interval[order])
        self.slot = np.empty(self.interval.size, dtype=np.int64)
        self.slot[order] = np.arange(self.interval.size) - first
        self.width = int(self.slot.max()) + 1 if self.slot.size else 0

    def padded(self, values, count):
        """values (R, ...) placed per interval: (count, width, ...), zero where an interval has
        fewer rows."""
        out = np.zeros((count, self.width) + values.shape[1:])
        out[self.interval, self.slot] = values
        return out

    @staticmethod
    def spanning(tr):
        """True if a row of tr.E involves the points of more than one interval."""
        return Rows._places(tr) is None

    @staticmethod
    def _places(tr):
        """(interval of each row, position within it of each entry) or None."""
        L, E = tr.layout, tr.E
        if not E.shape[0]:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        point = E.cols // L.nz
        if np.any(E.cols >= L.p_start):
            return None
        stride = L.stride
        lowest = np.full(E.shape[0], np.iinfo(np.int64).max)
        highest = np.full(E.shape[0], -1)
        np.minimum.at(lowest, E.rows, point)
        np.maximum.at(highest, E.rows, point)
        interval = np.minimum(lowest // stride, L.nodes - 2)
        if np.any(highest > (interval + 1) * stride) or np.any(lowest < interval * stride):
            return None
        return interval, point - interval[E.rows] * stride

    @classmethod
    def of(cls, tr):
        L, E = tr.layout, tr.E
        interval, position = cls._places(tr)
        shape = (E.shape[0], L.stride + 1, L.nz)
        place = np.ravel_multi_index((E.rows, position, E.cols % L.nz), shape)
        coef = np.bincount(place, E.values, minlength=int(np.prod(shape))).reshape(shape)
        return cls(interval, coef, tr.e_lo, tr.e_hi, np.arange(E.shape[0]))


@dataclass
class Linearization:
    """The QP's data at x: per point the Hessian block W (P, nz, nz), the objective's gradient g
    (P, nz), the residual r (P, n) and its Jacobian R (P, n, nz); the defects' values d
    (intervals, per); the bounds as steps lo, hi (P, nz); the rows' bounds on E·d, row_lo and
    row_hi (R,)."""
    W: np.ndarray
    g: np.ndarray
    r: np.ndarray
    R: np.ndarray
    d: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    row_lo: np.ndarray
    row_hi: np.ndarray


def linearize(tr, x, lam, stages, rows):
    """The `Linearization` of the transcription's NLP at x with the constraints' multipliers
    lam (the Hessian's weights)."""
    L = tr.layout
    P, nz, n = L.points, L.nz, L.n
    W = tr.point_hessians(x, lam)
    g = tr.point_gradients(x)
    r, R = tr.point_residuals(x)
    c = tr.constraints(x)
    base = tr.defect_row
    d = c[base:base + tr.n_defects].reshape(-1, stages.per)
    lo = (tr.lo[:L.p_start] - x[:L.p_start]).reshape(P, nz)
    hi = (tr.hi[:L.p_start] - x[:L.p_start]).reshape(P, nz)
    Ex = tr.E.dot(x) if rows.index.size else np.zeros(0)
    return Linearization(W, g, r, R, d, lo, hi, rows.lo - Ex, rows.hi - Ex)


@dataclass
class ActiveSet:
    """Active bounds: flat indices into (P, nz), their sides (−1 lower, +1 upper) and
    multipliers z (> 0 at an upper bound, < 0 at a lower one: ∇f + Jᵀλ + z = 0); the same of
    the rows (row_side, row_z, row_fixed: equalities)."""
    side: np.ndarray             # (P·nz,) 0 inactive, ±1 active
    z: np.ndarray                # (P·nz,)
    fixed: np.ndarray            # (P·nz,) bool: lo == hi, never released
    row_side: np.ndarray         # (R,)
    row_z: np.ndarray            # (R,)
    row_fixed: np.ndarray        # (R,)

    @classmethod
    def start(cls, lin, z0=None, row_z0=None, tol=1e-9):
        """The set of a warm start: with its multipliers z0 (row_z0), the bounds (rows) whose
        multiplier is not negligible (on the side of its sign); without, those the point sits
        on (within tol of their scale); and every fixed variable and equality row."""
        side, z, fixed = _start_sides(lin.lo.ravel(), lin.hi.ravel(), z0, tol)
        row_side, row_z, row_fixed = _start_sides(lin.row_lo, lin.row_hi, row_z0, tol)
        return cls(side, z, fixed, row_side, row_z, row_fixed)

    def targets(self, lin):
        """δ_i: the step that puts each variable on its active bound."""
        return np.where(self.side > 0, lin.hi.ravel(), lin.lo.ravel())

    def row_targets(self, lin):
        """The value of E·d that puts each row on its active bound."""
        return np.where(self.row_side > 0, lin.row_hi, lin.row_lo)

    def copy(self):
        """A set of its own with this one's sides and multipliers."""
        return ActiveSet(*(np.array(getattr(self, f.name)) for f in fields(self)))

    def take(self, other):
        """This set made `other`'s (in place)."""
        for f in fields(self):
            getattr(self, f.name)[...] = getattr(other, f.name)

    def reset(self):
        """Only the fixed variables and equality rows active."""
        self.side[:] = np.where(self.fixed, 1, 0)
        self.z[~self.fixed] = 0.0
        self.row_side[:] = np.where(self.row_fixed, 1, 0)
        self.row_z[~self.row_fixed] = 0.0


def _start_sides(lo, hi, z0, tol):
    """(sides, multipliers, fixed) of constraints lo ≤ · ≤ hi at a start (see ActiveSet.start)."""
    finite = np.isfinite(lo) & np.isfinite(hi)
    scale = np.where(finite, np.maximum(1.0, np.minimum(np.abs(lo), np.abs(hi))), 1.0)
    fixed = finite & ((hi - lo) <= 1e-14 * scale)
    side = np.zeros(lo.size, dtype=np.int8)
    if z0 is None:
        z = np.zeros(lo.size)
        side[hi <= tol * scale] = 1
        side[lo >= -tol * scale] = -1
    else:
        z = np.array(z0, dtype=float)
        significant = np.abs(z) > 1e-6 * max(1.0, float(np.max(np.abs(z), initial=0.0)))
        side[significant & (z > 0) & np.isfinite(hi)] = 1
        side[significant & (z < 0) & np.isfinite(lo)] = -1
    side[fixed & (side == 0)] = 1
    z[side == 0] = 0.0
    return side, z, fixed


class StructuredQP:
    """The QP of one SQP step, eliminated point by point and interval by interval, solved by a
    Riccati recursion for a given set of penalized bounds."""

    def __init__(self, tr, stages, rows, lin):
        L = tr.layout
        self.L, self.stages, self.rows, self.lin = L, stages, rows, lin
        n, nu = L.n, L.nu
        self.nx, self.ny = 2 * n, 2 * n + nu
        self._eliminate_accelerations()
        self._plain_G, self._Wt, self.G = None, None, None
        self._G_buffers, self._stage_Q, self._factors, self.P = None, None, None, None
        self._kept = np.r_[0:2 * n, 3 * n:3 * n + nu]      # T's identity rows: states, inputs
        self.interval_maps()
        self.row_maps()

    # -- per point: the accelerations -----------------------------------------------------------
    def _eliminate_accelerations(self):
        """T (P, nz, ny), t (P, nz): dz = T·y + t on the linearized residual, y = [dx, du]."""
        L, lin = self.L, self.lin
        n, nu, P = L.n, L.nu, L.points
        R = lin.R
        Ra = R[:, :, 2 * n:3 * n]
        Rxu = np.concatenate([R[:, :, :2 * n], R[:, :, 3 * n:]], axis=2)
        try:
            sol = np.linalg.solve(Ra, np.concatenate([Rxu, lin.r[:, :, None]], axis=2))
        except np.linalg.LinAlgError:
            raise Unsupported("a mass matrix is singular at a collocation point") from None
        T = np.zeros((P, L.nz, self.ny))
        T[:, :2 * n, :2 * n] = np.eye(2 * n)
        T[:, 2 * n:3 * n, :] = -sol[:, :, :-1]
        T[:, 3 * n:, 2 * n:] = np.eye(nu)
        self.T, self.t = T, np.zeros((P, L.nz))
        self.t[:, 2 * n:3 * n] = -sol[:, :, -1]
        self.Ra = Ra

    def point_costs(self, W, g):
        """(G, γ): each point's cost ½·yᵀ·G·y + γᵀ·y in y from its block W and gradient g."""
        return self.eliminated_hessians(W), self.point_gradients(W, g)

    def eliminated_hessians(self, W):
        """G = Tᵀ·W·T of each point (`point_costs`' quadratic part alone)."""
        G = np.empty((self.T.shape[0], self.ny, self.ny))
        point_hessians(self.T, np.ascontiguousarray(W), G)
        return G

    def point_gradients(self, W, g):
        """γ = Tᵀ·(W·t + g) of each point (`point_costs`' linear part alone)."""
        return self._transposed((W @ self.t[:, :, None])[:, :, 0] + g)

    def _transposed(self, v):
        """Tᵀ·v of each point (v: (P, nz)), T's identity rows read off."""
        n = self.L.n
        Ta = self.T[:, 2 * n:3 * n, :]
        return v[:, self._kept] + (Ta.transpose(0, 2, 1) @ v[:, 2 * n:3 * n, None])[:, :, 0]

    def diagonal_costs(self, add):
        """G of each point for the blocks W + diag(add) (add: (P·nz,)): TᵀWT, formed once per
        QP, plus Tᵀ·diag(add)·T, which is diagonal on the states and inputs (T's identity
        rows) and rank-one terms of the acceleration rows whose add is not 0. The array is one
        of two the QP keeps: the next call but one overwrites it (the last factor's G is never
        the one written)."""
        if self._plain_G is None:
            self._plain_G = self.eliminated_hessians(self.lin.W)
            self._G_buffers = (np.empty_like(self._plain_G), np.empty_like(self._plain_G))
        G = _unheld(self._G_buffers, self.G)
        diagonal_hessians(self._plain_G, self.T,
                          np.ascontiguousarray(add).reshape(self.T.shape[0], self.L.nz),
                          self.L.n, G)
        return G

    def diagonal_gradients(self, add, g):
        """γ of each point for the blocks W + diag(add) and gradients g (P, nz):
        Tᵀ·(W·t + g + add·t), with W·t formed once per QP."""
        if self._Wt is None:
            self._Wt = (self.lin.W @ self.t[:, :, None])[:, :, 0]
        return self._transposed(self._Wt + g + add.reshape(g.shape) * self.t)

    # -- per interval: the states of its inner points and end -------------------------------------
    def interval_maps(self):
        """The states of each interval's inner points and end as affine maps of X = y_s and the
        inputs v = [u of the inner points, u_e]: `maps`, one (C, E, e) per point after the start
        (y = C·X + E·v + e; the last is the end: the transition A, B, b), and K, the defects'
        Jacobian in those states (for the costates)."""
        L, st, lin = self.L, self.stages, self.lin
        nx, ny, nu = self.nx, self.ny, L.nu
        later = st.points.shape[1] - 1
        pts = st.points
        Dhat = st.D @ self.T[pts]                                     # (k, p, per, ny)
        rho = lin.d + (st.D @ self.t[pts][:, :, :, None])[:, :, :, 0].sum(axis=1)
        K = np.concatenate([Dhat[:, p, :, :nx] for p in range(1, later + 1)], axis=2)
        rhs = np.concatenate([Dhat[:, 0]] + [Dhat[:, p, :, nx:] for p in range(1, later + 1)]
                             + [rho[:, :, None]], axis=2)
        try:
            solved = -np.linalg.solve(K, rhs)
        except np.linalg.LinAlgError:
            raise Unsupported("an interval's defects do not determine its states") from None
        self.K, self.later, self.nv = K, later, later * nu
        count = pts.shape[0]
        C = np.zeros((later, count, ny, ny))
        E = np.zeros((later, count, ny, self.nv))
        e = np.zeros((later, count, ny))
        for p in range(later):
            rows = slice(p * nx, (p + 1) * nx)
            C[p, :, :nx] = solved[:, rows, :ny]
            E[p, :, :nx] = solved[:, rows, ny:ny + self.nv]
            E[p, :, nx:, p * nu:(p + 1) * nu] = np.eye(nu)
            e[p, :, :nx] = solved[:, rows, -1]
        self.maps = [(C[p], E[p], e[p]) for p in range(later)]
        self.inner_C, self.inner_E, self.inner_e = C[:-1], E[:-1], e[:-1]
        self.A, self.B, self.b = C[-1], E[-1], e[-1]

    def row_maps(self):
        """Each row's E·d = α·X_k + β·v_k + c on its interval k: alpha (R, ny), beta (R, nv),
        const (R,)."""
        rows, pts = self.rows, self.stages.points
        R, count = rows.index.size, pts.shape[0]
        alpha = np.zeros((count, rows.width, self.ny))
        beta = np.zeros((count, rows.width, self.nv))
        const = np.zeros((count, rows.width))
        for p in range(pts.shape[1] if R else 0):
            a = rows.padded(rows.coef[:, p], count)                     # (k, width, nz)
            T, t = self.T[pts[:, p]], self.t[pts[:, p]]
            hat = a @ T                                                 # (k, width, ny)
            const += np.einsum("kwi,ki->kw", a, t)
            if p == 0:
                alpha += hat
                continue
            C, E, e = self.maps[p - 1]
            alpha += hat @ C
            beta += hat @ E
            const += np.einsum("kwi,ki->kw", hat, e)
        self.alpha_pad, self.beta_pad = alpha, beta                     # (k, width, ·)
        self.alpha = alpha[rows.interval, rows.slot]
        self.beta = beta[rows.interval, rows.slot]
        self.const = const[rows.interval, rows.slot]

    # -- the recursion ------------------------------------------------------------------------------
    def factor(self, G, regularize=0.0, row_weights=None):
        """The backward Riccati pass of the matrices for the point Hessians G (`_riccati.factor`)
        and the rows' terms w_r·[α; β]·[α; β]ᵀ in their stages, the inputs' Hessians plus
        regularize·1. False when one is not positive definite (the QP not convex along them),
        and the last factor kept. The QP keeps two sets of the factor's arrays and writes the
        one the last factor does not hold (fresh arrays cost Talos's 735-node mesh 66 MB of
        page faults a factor)."""
        pts = self.stages.points
        count, ny, nv = pts.shape[0], self.ny, self.nv
        G = np.ascontiguousarray(G)
        if self._stage_Q is None:
            self._stage_Q = (np.zeros((count, ny, ny)), np.zeros((count, ny, nv)),
                             np.zeros((count, nv, nv)))
            self._factors = [tuple(np.zeros(shape) for shape in
                                   ((count + 1, ny, ny), (count, ny, nv), (count, nv, nv),
                                    (count, nv, ny))) for _ in range(2)]
        Qxx, Qxv, Qvv = self._stage_Q
        if not self.inner_C.shape[0]:       # stage_hessians writes Qxv, Qvv from inner points
            Qxv.fill(0.0)
            Qvv.fill(0.0)
        stage_hessians(G, pts, self.inner_C, self.inner_E, Qxx, Qxv, Qvv, self.nx)
        if row_weights is not None and np.any(row_weights):
            w = self.rows.padded(row_weights, count)[:, :, None]
            alpha_t = self.alpha_pad.transpose(0, 2, 1)
            Qxx += alpha_t @ (w * self.alpha_pad)
            Qxv += alpha_t @ (w * self.beta_pad)
            Qvv += self.beta_pad.transpose(0, 2, 1) @ (w * self.beta_pad)
        P, Hxv, chol, gain = _unheld(self._factors, self.P, lambda arrays: arrays[0])
        status = riccati_factor(Qxx, Qxv, Qvv, self.A, self.B,
                                np.ascontiguousarray(G[pts[-1, -1]]), float(regularize),
                                P, Hxv, chol, gain, self.nx)
        if status:
            return False
        self.P, self.Hxv, self.chol, self.gain, self.G = P, Hxv, chol, gain, G
        return True

    def factored(self):
        """The arrays of the last successful `factor`: P, Hxv, chol, gain, G."""
        return self.P, self.Hxv, self.chol, self.gain, self.G

    def vectors(self, gamma, row_gradients=None):
        """The backward pass of the affine parts for the point gradients γ and the rows' terms
        g_r·[α; β] in their stages (after `factor`)."""
        pts, count = self.stages.points, self.stages.points.shape[0]
        gamma = np.ascontiguousarray(gamma)
        qx, qv = np.empty((count, self.ny)), np.empty((count, self.nv))
        stage_gradients(self.G, gamma, pts, self.inner_C, self.inner_E, self.inner_e, qx, qv,
                        self.nx)
        if row_gradients is not None and np.any(row_gradients):
            gr = self.rows.padded(row_gradients, count)[:, :, None]
            qx += (self.alpha_pad.transpose(0, 2, 1) @ gr)[:, :, 0]
            qv += (self.beta_pad.transpose(0, 2, 1) @ gr)[:, :, 0]
        self.p = np.zeros((count + 1, self.ny))
        self.ff = np.zeros((count, self.nv))
        riccati_vectors(qx, qv, self.A, self.B, self.b,
                         np.ascontiguousarray(gamma[pts[-1, -1]]), self.P, self.Hxv, self.chol,
                         self.p, self.ff, self.nx)
        self.gamma = gamma

    def solve(self):
        """The steps y of every point (P, ny) after `factor` and `vectors`: X_0 minimizes V_0;
        then each interval's inputs by its gain and feedforward."""
        try:
            X0 = -np.linalg.solve(self.P[0], self.p[0])
        except np.linalg.LinAlgError:
            raise Unsupported("the first node's cost-to-go is singular") from None
        pts = self.stages.points
        count = pts.shape[0]
        X, v = np.zeros((count + 1, self.ny)), np.zeros((count, self.nv))
        riccati_forward(np.ascontiguousarray(X0), self.A, self.B, self.b, self.gain, self.ff,
                        X, v, self.nx)
        self.X, self.v = X, v
        y = np.zeros((self.L.points, self.ny))
        y[pts[:, 0]] = X[:-1]
        y[pts[-1, -1]] = X[-1]
        for p, (C, E, e) in enumerate(self.maps[:-1]):
            y[pts[:, p + 1]] = (C @ X[:-1, :, None] + E @ v[:, :, None])[:, :, 0] + e
        return y

    def row_values(self):
        """E·d of each row at the last `solve`."""
        k = self.rows.interval
        return (np.einsum("ri,ri->r", self.alpha, self.X[k])
                + np.einsum("ri,ri->r", self.beta, self.v[k]) + self.const)

    def steps(self, y):
        """dz (P, nz) from y."""
        return (self.T @ y[:, :, None])[:, :, 0] + self.t

    def multipliers(self, y, dz, W, g, zb, row_z=None):
        """(μ (P, n), ν (intervals, per)): the residuals' and defects' multipliers of the QP's
        solution (the NLP's convention: ∇f + Jᵀλ + z = 0), from the recursion's costates; zb
        the bounds' multipliers (P, nz), row_z the rows' (R,)."""
        L, st = self.L, self.stages
        n, nx = L.n, self.nx
        pts = st.points
        count = pts.shape[0]
        rows_z = np.zeros((count, pts.shape[1], L.nz))            # Σ_r ζ_r·a_r per place
        rows_y = np.zeros((count, pts.shape[1], self.ny))
        if row_z is not None and np.any(row_z):
            scatter_add(rows_z, self.rows.interval, row_z[:, None, None] * self.rows.coef)
            rows_y = (self.T[pts].transpose(0, 1, 3, 2) @ rows_z[..., None])[..., 0]
        grad_y = (self.G @ y[:, :, None])[:, :, 0] + self.gamma   # ∂(cost)/∂y at the point
        later = []
        for p in range(1, self.later + 1):
            if p < self.later:
                later.append(grad_y[pts[:, p], :nx] + rows_y[:, p, :nx])
            else:
                costate = (self.P[1:] @ y[pts[:, -1]][:, :, None])[:, :, 0] + self.p[1:]
                later.append(costate[:, :nx] + rows_y[:, p, :nx])
        rhs = np.concatenate(later, axis=1)                         # (k, later·nx)
        nu_ = -np.linalg.solve(self.K.transpose(0, 2, 1), rhs[:, :, None])[:, :, 0]
        # μ from each point's acceleration rows: (W·dz + g + Dᵀν + z + Σζ·a)_a + R_aᵀ·μ = 0
        grad_z = (W @ dz[:, :, None])[:, :, 0] + g + zb
        scatter_add(grad_z, pts.ravel(),
                  (st.D.transpose(0, 1, 3, 2) @ nu_[:, None, :, None])[..., 0].reshape(-1, L.nz)
                  + rows_z.reshape(-1, L.nz))
        rhs_a = grad_z[:, 2 * n:3 * n]
        mu = -np.linalg.solve(self.Ra.transpose(0, 2, 1), rhs_a[:, :, None])[:, :, 0]
        return mu, nu_


def _unheld(pair, held, first=lambda arrays: arrays):
    """The one of two alternating buffers whose array (`first` of it) is not `held`."""
    return pair[first(pair[0]) is held]


@dataclass
class QPResult:
    dz: np.ndarray          # (P, nz) the step
    mu: np.ndarray          # (P, n) residual multipliers
    nu: np.ndarray          # (intervals, per) defect multipliers
    active: ActiveSet
    passes: int
    interior: bool = False  # solved by the interior point (the active set did not settle)
    z_all: np.ndarray = None    # (P·nz,) the interior point's multipliers of every bound
    as_left: bool = False       # taken as the interior point left it, not made exact (`_purified`)


def solve_qp(tr, stages, rows, lin, active, inertia=None, tol=1e-10, passes=ACTIVE_PASSES,
             loose=False, purify=True):
    """The QP of `lin`: by the active set when it settles within `passes` (a warm start's
    set, updated in place; 0: not tried), else by the interior point (`solve_qp_interior`),
    to LOOSE_TOL and as it stands when `loose` (a step far from the solution, which the next
    ones correct), else
    to its tolerance and made exact (`_purified`) when `purify`, or as it stands with its
    multipliers; the inputs' Hessians regularized where they are not positive definite
    (`inertia`, an `Inertia`, keeps the last regularization). `QPResult`."""
    inertia = Inertia() if inertia is None else inertia
    qp = StructuredQP(tr, stages, rows, lin)
    if passes:
        try:
            return solve_qp_active(qp, lin, active, inertia, tol, passes)
        except Unsupported:
            if DEBUG:
                print("    the active set did not settle: interior point")
    active.reset()
    if loose:
        return solve_qp_interior(qp, lin, active, inertia, LOOSE_TOL)
    found = solve_qp_interior(qp, lin, active, inertia)
    if not purify:
        found.as_left = True
        return found
    return _purified(qp, lin, active, inertia, tol, found)


def _purified(qp, lin, active, inertia, tol, found):
    """The interior point's solution `found` made exact: the active set's passes from the set
    it identified (its constraints on their bounds, the rest free; `active` updated), or `found`
    as it is where they do not settle (QUICK_PASSES, more while the set is settling: an interior
    point's solution keeps its inactive bounds' multipliers at μ/s, and the SQP's stationarity
    would stall at that size)."""
    trial = active.copy()
    try:
        exact = solve_qp_active(qp, lin, trial, inertia, tol, QUICK_PASSES, patient=True)
    except Unsupported:
        found.as_left = True
        return found
    active.take(trial)
    return QPResult(exact.dz, exact.mu, exact.nu, active, found.passes + exact.passes,
                    interior=True)


def _penalties(lin):
    """ρ per variable: PENALTY times its point's Hessian scale (at least 1)."""
    P, nz = lin.W.shape[:2]
    return np.repeat(PENALTY * _point_scale(lin), nz)


def _point_scale(lin):
    return np.maximum(1.0, np.abs(np.diagonal(lin.W, axis1=1, axis2=2)).max(axis=1))


def _row_penalties(qp, lin):
    """ρ per row: PENALTY times the Hessian scale of its interval's start."""
    start = qp.stages.points[qp.rows.interval, 0]
    return PENALTY * _point_scale(lin)[start]


@dataclass
class Inertia:
    """The regularization δ of the inputs' Hessians that made the last factor positive definite
    (IPOPT's inertia correction, its δ_w), kept from factor to factor of a solve: the least δ
    of the grid FIRST_REGULARIZATION·GROWTHᵏ that serves is searched from the last one, down
    while it serves and up while it does not (two or three factors where a search up from the
    grid's first took eight)."""
    last: float = 0.0


def _factored(qp, G, inertia, row_weights=None):
    """qp factored for the point Hessians G and the rows' weights, the inputs' Hessians
    regularized by the least δ (0, or of `inertia`'s grid) that makes them positive definite:
    δ."""
    if qp.factor(G, 0.0, row_weights):
        return 0.0
    delta = max(inertia.last, FIRST_REGULARIZATION)
    if qp.factor(G, delta, row_weights):
        while delta / GROWTH >= FIRST_REGULARIZATION * (1 - 1e-9) and \
                qp.factor(G, delta / GROWTH, row_weights):      # a failed one keeps the last
            delta /= GROWTH
    else:
        while True:
            delta *= GROWTH
            if delta > MAX_REGULARIZATION:
                raise Unsupported("the QP is not convex along its inputs (inertia)")
            if qp.factor(G, delta, row_weights):
                break
    inertia.last = delta
    return delta


def _set_changes(on, side, z, fixed, value, lo, hi, tol):
    """(release, cross_hi, cross_lo) of a primal-dual active set's pass."""
    release = on & ~fixed & (side * z < 0)
    cross_hi = ~on & (value > hi + tol * np.maximum(1.0, np.abs(hi)))
    cross_lo = ~on & (value < lo - tol * np.maximum(1.0, np.abs(lo)))
    return release, cross_hi, cross_lo


def _apply_changes(side, z, release, cross_hi, cross_lo):
    side[release] = 0
    z[release] = 0.0
    side[cross_hi] = 1
    side[cross_lo] = -1


def solve_qp_active(qp, lin, active, inertia, tol=1e-10, passes=None, patient=False):
    """The QP by a primal-dual active set with augmented-Lagrangian terms for the active bounds
    and rows (the factor kept while only their multipliers change); Unsupported when the set
    does not settle within `passes` (default ACTIVE_PASSES), or within SETTLING_PASSES while each
    pass changes no more constraints than the one before or a SETTLING-th of the first's (a set
    that is settling) or only the multipliers change, and, unless `patient` (the interior
    point's set made exact: there is nothing cheaper to turn to), as soon as its changes do not
    shrink fast enough to settle within SETTLING_PASSES (`_hopeless`)."""
    P, nz = lin.W.shape[:2]
    rho, row_rho = _penalties(lin), _row_penalties(qp, lin)
    refactor = True
    lo, hi = lin.lo.ravel(), lin.hi.ravel()
    limit, changed, first = passes or ACTIVE_PASSES, np.inf, 0
    count = 0
    while count < limit:
        count += 1
        delta, row_delta = active.targets(lin), active.row_targets(lin)
        on, row_on = active.side != 0, active.row_side != 0
        g = (lin.g.ravel() + np.where(on, active.z - rho * delta, 0.0)).reshape(P, nz)
        row_g = np.where(row_on, active.row_z + row_rho * (qp.const - row_delta), 0.0)
        add = np.where(on, rho, 0.0)
        if refactor:
            _factored(qp, qp.diagonal_costs(add), inertia, np.where(row_on, row_rho, 0.0))
            refactor = False
        gamma = qp.diagonal_gradients(add, g)
        qp.vectors(gamma, row_g)
        y = qp.solve()
        dz = qp.steps(y)
        flat, row_value = dz.ravel(), qp.row_values()
        violation = np.where(on, flat - delta, 0.0)
        row_violation = np.where(row_on, row_value - row_delta, 0.0)
        active.z = np.where(on, active.z + rho * violation, 0.0)
        active.row_z = np.where(row_on, active.row_z + row_rho * row_violation, 0.0)
        changes = _set_changes(on, active.side, active.z, active.fixed, flat, lo, hi, tol)
        row_changes = _set_changes(row_on, active.row_side, active.row_z, active.row_fixed,
                                   row_value, lin.row_lo, lin.row_hi, tol)
        now = sum(int(c.sum()) for c in changes + row_changes)
        if DEBUG:
            print(f"    pass {count}: active {int(on.sum())}+{int(row_on.sum())} changes {now} "
                  f"violation {np.max(np.abs(violation), initial=0):.2e} "
                  f"|dz| {np.max(np.abs(flat)):.2e}")
        if now:
            if _hopeless_on_average(now, first, count, SETTLING_PASSES - count) if patient \
                    else _hopeless(now, changed, SETTLING_PASSES - count):
                raise Unsupported(f"the QP's active set is not settling ({changed} then {now} "
                                  f"changes in passes {count - 1} and {count})")
            _apply_changes(active.side, active.z, *changes)
            _apply_changes(active.row_side, active.row_z, *row_changes)
            refactor = True
            first = first or now
            if count == limit and (now <= changed or SETTLING * now <= first):
                limit = min(limit + 1, SETTLING_PASSES)
            changed = now
            continue
        scale = max(1e-6, np.max(np.abs(flat)))
        if max(np.max(np.abs(violation), initial=0.0),
               np.max(np.abs(row_violation), initial=0.0)) <= tol * scale:
            zb = np.where(on, active.z, 0.0).reshape(P, nz)
            mu, nu_ = qp.multipliers(y, dz, lin.W, lin.g, zb, active.row_z)
            return QPResult(dz, mu, nu_, active, count)
        if count == limit:
            limit = min(limit + 1, SETTLING_PASSES)
    raise Unsupported(f"the QP's active set did not settle in {count} passes")


def _hopeless(now, before, left):
    """Whether an active set whose passes changed `before` then `now` constraints would not
    settle within `left` more passes were its changes to keep shrinking at that ratio (the
    interior point then costs fewer factors); sets changing at most HOPELESS_FEW constraints are
    always given their passes."""
    if now <= HOPELESS_FEW or not np.isfinite(before):
        return False
    if now >= before:
        return True
    return np.log(now) / np.log(before / now) > left


def _hopeless_on_average(now, first, count, left):
    """`_hopeless` for the interior point's set made exact (`solve_qp_active`'s `patient`), by
    the changes' average shrinking since the first pass (one pass that changes more is no
    verdict): on Talos's 615-node mesh they went 1485, 840, 792, 582, ... 47, 76, 47 and the
    set had not settled after 20 passes, twenty factors for nothing."""
    if count < 3 or now <= HOPELESS_FEW:
        return False
    return _hopeless(now, now * (first / now) ** (1.0 / (count - 1)), left)


class _Barrier:
    """The interior point's side of constraints lo ≤ value ≤ hi that are not fixed: slacks
    s_l = value − lo, s_u = hi − value and their multipliers y_l, y_u (> 0). A side a
    constraint lacks keeps s = 1 and y = 0 (its masks `on_lo`, `on_hi` are 0 there), so that its
    terms vanish from every product below without selecting."""

    def __init__(self, lo, hi, fixed, value):
        self.has_lo = np.isfinite(lo) & ~fixed
        self.has_hi = np.isfinite(hi) & ~fixed
        self.on_lo, self.on_hi = self.has_lo.astype(float), self.has_hi.astype(float)
        self.s_l = np.where(self.has_lo, value - lo, 1.0)
        self.s_u = np.where(self.has_hi, hi - value, 1.0)
        self.y_l, self.y_u = self.on_lo.copy(), self.on_hi.copy()
        self.count = int(self.has_lo.sum() + self.has_hi.sum())
        self._weights = None

    @staticmethod
    def start_values(lo, hi, fixed, value):
        """`value` moved inside its bounds by a margin (the interior point's start)."""
        has_lo, has_hi = np.isfinite(lo) & ~fixed, np.isfinite(hi) & ~fixed
        width = np.where(has_lo & has_hi, hi - lo, np.inf)
        margin = np.minimum(1e-2 * np.maximum(1.0, np.minimum(np.abs(lo), np.abs(hi))),
                            0.25 * width)
        margin = np.where(np.isfinite(margin), margin, 1e-2)
        value = np.where(has_lo, np.maximum(value, lo + margin), value)
        return np.where(has_hi, np.minimum(value, hi - margin), value)

    def gap_sum(self, s_l=None, y_l=None, s_u=None, y_u=None):
        """Σ s·y over both sides (of the given slacks and multipliers, 0 on absent sides)."""
        s_l = self.s_l if s_l is None else s_l
        y_l = self.y_l if y_l is None else y_l
        s_u = self.s_u if s_u is None else s_u
        y_u = self.y_u if y_u is None else y_u
        return float(np.sum(s_l * y_l) + np.sum(s_u * y_u))     # not BLAS's dot (threads)

    def largest_gap(self):
        """The largest complementarity product s·y."""
        return float(max(np.max(self.s_l * self.y_l, initial=0.0),
                         np.max(self.s_u * self.y_u, initial=0.0)))

    def weights(self):
        """Σ = y_l/s_l + y_u/s_u (kept until the next `move`)."""
        if self._weights is None:
            self._weights = self.y_l / self.s_l + self.y_u / self.s_u
        return self._weights

    def gradient(self, value, t_l, t_u):
        """The barrier's linear term at `value` for complementarity targets t_l, t_u (0 on
        absent sides)."""
        return t_u / self.s_u - t_l / self.s_l - self.weights() * value

    def duals(self, step, t_l, t_u):
        """(Δy_l, Δy_u) of a step of the values."""
        return ((t_l - self.y_l * step) / self.s_l - self.y_l,
                (t_u + self.y_u * step) / self.s_u - self.y_u)

    def targets(self, sigma_mu, step, dy_l, dy_u):
        """Mehrotra's corrector targets."""
        return (self.on_lo * sigma_mu - step * dy_l, self.on_hi * sigma_mu + step * dy_u)

    def move(self, a_p, a_d, step, dy_l, dy_u):
        self.s_l = self.s_l + a_p * self.on_lo * step
        self.s_u = self.s_u - a_p * self.on_hi * step
        self.y_l = self.y_l + a_d * dy_l
        self.y_u = self.y_u + a_d * dy_u
        self._weights = None

    def sides(self):
        """-1 / +1 where the lower / upper bound is active, 0 elsewhere: active where its
        multiplier exceeds its slack (y > s: the limit of y·s = μ → 0 splits the bounds by
        which factor vanishes, whatever the multipliers' scale)."""
        lower = self.has_lo & (self.y_l > self.s_l)
        upper = self.has_hi & (self.y_u > self.s_u)
        return np.where(upper, 1, np.where(lower, -1, 0))

    def max_steps(self, step, dy_l, dy_u, fraction):
        """The longest primal and dual steps (at most 1) keeping s and y positive, by
        `fraction`."""
        return (_fraction_to_boundary(fraction, (self.s_l, self.on_lo * step),
                                      (self.s_u, -self.on_hi * step)),
                _fraction_to_boundary(fraction, (self.y_l, dy_l), (self.y_u, dy_u)))


def solve_qp_interior(qp, lin, active, inertia, tol=1e-9, iterations=IPM_ITERATIONS):
    """The QP by a primal-dual interior point (Mehrotra's predictor-corrector) on the bounds and
    rows that are not fixed, the fixed ones (variables, equality rows) held by a penalty made
    exact at the end by multiplier updates; each iteration one factor of the recursion with the
    barrier's Σ = y_l/s_l + y_u/s_u on the diagonals and stages, and two solves. The active set
    is set from the solution (the constraints whose multiplier is not negligible)."""
    P, nz = lin.W.shape[:2]
    lo, hi = lin.lo.ravel(), lin.hi.ravel()
    fixed, row_fixed = active.fixed, active.row_fixed
    pin = np.where(fixed, PIN_PENALTY * _penalties(lin) / PENALTY, 0.0)
    row_pin = np.where(row_fixed, PIN_PENALTY * _row_penalties(qp, lin) / PENALTY, 0.0)
    target, row_target = np.where(fixed, lo, 0.0), np.where(row_fixed, lin.row_lo, 0.0)
    d = _Barrier.start_values(lo, hi, fixed, np.zeros(P * nz))
    w = _Barrier.start_values(lin.row_lo, lin.row_hi, row_fixed, qp.const.copy())
    bounds = _Barrier(lo, hi, fixed, d)
    rows = _Barrier(lin.row_lo, lin.row_hi, row_fixed, w)
    count = max(bounds.count + rows.count, 1)
    zeros, row_zeros = np.zeros(P * nz), np.zeros(rows.has_lo.size)

    def gap(*states):
        return sum(b.gap_sum(*st) for b, st in zip((bounds, rows), states)) / count

    def system(pins, row_pins):
        """The solve of the barrier's Newton system about the current point for complementarity
        targets (t_l, t_u) of the bounds and of the rows, after factoring."""
        add = bounds.weights() + pin
        row_w = rows.weights() + row_pin
        factored = [False]

        def solve(targets, row_targets, extra=zeros, row_extra=row_zeros):
            g = (lin.g.ravel() + bounds.gradient(d, *targets) - pin * target + pins
                 + extra).reshape(P, nz)
            row_g = (rows.gradient(w, *row_targets) + rows.weights() * qp.const
                     + row_pin * (qp.const - row_target) + row_pins + row_extra)
            if not factored[0]:
                _factored(qp, qp.diagonal_costs(add), inertia, row_w)
                factored[0] = True
            gamma = qp.diagonal_gradients(add, g)
            qp.vectors(gamma, row_g)
            y = qp.solve()
            dz, value = qp.steps(y).ravel(), qp.row_values()
            step, row_step = dz - d, value - w
            return (y, dz, value, step, bounds.duals(step, *targets), row_step,
                    rows.duals(row_step, *row_targets))
        return solve

    first_gap = max(gap((), ()), 1.0)
    for iteration in range(1, iterations + 1):
        mu_gap = gap((), ())
        solve = system(zeros, row_zeros)
        none = (zeros, zeros)
        _, _, _, step, (dy_l, dy_u), row_step, (ry_l, ry_u) = solve(none, (row_zeros, row_zeros))
        a_p, a_d = bounds.max_steps(step, dy_l, dy_u, 1.0)
        r_p, r_d = rows.max_steps(row_step, ry_l, ry_u, 1.0)
        a_p, a_d = min(a_p, r_p), min(a_d, r_d)
        gap_aff = gap((bounds.s_l + a_p * step, bounds.y_l + a_d * dy_l,
                       bounds.s_u - a_p * step, bounds.y_u + a_d * dy_u),
                      (rows.s_l + a_p * row_step, rows.y_l + a_d * ry_l,
                       rows.s_u - a_p * row_step, rows.y_u + a_d * ry_u))
        sigma_mu = min(1.0, (gap_aff / max(mu_gap, 1e-300)) ** 3) * mu_gap
        targets = bounds.targets(sigma_mu, step, dy_l, dy_u)
        row_targets = rows.targets(sigma_mu, row_step, ry_l, ry_u)
        _, _, _, step, (dy_l, dy_u), row_step, (ry_l, ry_u) = solve(targets, row_targets)
        a_p, a_d = bounds.max_steps(step, dy_l, dy_u, 0.995)
        r_p, r_d = rows.max_steps(row_step, ry_l, ry_u, 0.995)
        a_p, a_d = min(a_p, r_p), min(a_d, r_d)
        d, w = d + a_p * step, w + a_p * row_step
        bounds.move(a_p, a_d, step, dy_l, dy_u)
        rows.move(a_p, a_d, row_step, ry_l, ry_u)
        now = gap((), ())
        if DEBUG:
            print(f"    interior {iteration}: gap {now:.2e} steps {a_p:.2f} {a_d:.2f} "
                  f"|d| {np.max(np.abs(d)):.2e}")
        if now <= tol * first_gap and a_p > 0.5 and \
                max(bounds.largest_gap(), rows.largest_gap()) <= tol * first_gap:
            break
    else:
        if not now <= 1e-6 * first_gap:
            raise Unsupported(f"the QP's interior point did not converge in {iterations} "
                              "iterations")
    # the fixed variables and equality rows onto their values: Newton steps of the barrier
    # system about the solution, the penalty's multipliers updated with one factor
    zp, row_zp = pin * (d - target), row_pin * (w - row_target)
    solve = system(zp, row_zp)
    targets = (bounds.s_l * bounds.y_l * bounds.has_lo, bounds.s_u * bounds.y_u * bounds.has_hi)
    row_targets = (rows.s_l * rows.y_l * rows.has_lo, rows.s_u * rows.y_u * rows.has_hi)
    extra, row_extra = zeros, row_zeros
    for _ in range(PIN_UPDATES):
        y, dz, value, _, (dy_l, dy_u), _, (ry_l, ry_u) = solve(targets, row_targets, extra,
                                                               row_extra)
        extra = extra + pin * (dz - target)
        row_extra = row_extra + row_pin * (value - row_target)
        off = max(np.max(np.abs(np.where(fixed, dz - target, 0.0)), initial=0.0),
                  np.max(np.abs(np.where(row_fixed, value - row_target, 0.0)), initial=0.0))
        if off <= 1e-12 * max(1.0, float(np.max(np.abs(dz)))):
            break
    z = np.where(fixed, zp + extra, (bounds.y_u + dy_u) - (bounds.y_l + dy_l))
    row_z = np.where(row_fixed, row_zp + row_extra, (rows.y_u + ry_u) - (rows.y_l + ry_l))
    for side, mult, fix, values, barrier in ((active.side, active.z, fixed, z, bounds),
                                             (active.row_side, active.row_z, row_fixed, row_z,
                                              rows)):
        side[:] = np.where(fix, 1, barrier.sides()).astype(np.int8)
        mult[:] = np.where(side != 0, values, 0.0)
    dz = dz.reshape(P, nz)
    mu, nu_ = qp.multipliers(y, dz, lin.W, lin.g, z.reshape(P, nz), row_z)
    return QPResult(dz, mu, nu_, active, iteration, interior=True, z_all=z)


def _fraction_to_boundary(fraction, *pairs):
    """The largest step in (0, 1] keeping each v + α·dv of the (v, dv) `pairs` positive (by
    `fraction`): fraction over the largest −dv/v (v > 0; an absent side's v = dv = 0 counts
    for nothing)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        fastest = max(float(np.fmax.reduce(-dv / v, initial=0.0)) for v, dv in pairs)
    return min(1.0, fraction / fastest) if fastest > 0.0 else 1.0


@dataclass
class Outcome:
    """An SQP solve: the solution x, the constraints' multipliers lam and the bounds' z (the
    NLP's convention), the iterations, whether it converged, why it stopped, the QP passes."""
    x: np.ndarray
    lam: np.ndarray
    z: np.ndarray
    iterations: int
    converged: bool
    message: str
    passes: int
    dual: float             # the stationarity residual at x (kkt_error's)
    as_left: bool = False   # its QPs taken as the interior point left them (`QPResult`)
    primal: float = 0.0     # the constraints' largest violation at x

    @property
    def near(self):
        """Whether x is within NEAR_SOLUTION of a solution by its KKT error: a point another
        solver finishes from, with its multipliers, rather than from the SQP's start."""
        return max(self.primal, self.dual) <= NEAR_SOLUTION


def constraint_multipliers(tr, qp, rows):
    """The multipliers of every constraint row of `tr` from a QP's residual, defect and row
    ones."""
    lam = np.zeros(tr.n_constraints)
    L = tr.layout
    lam[:L.points * L.ni] = qp.mu.ravel()
    base = tr.defect_row
    lam[base:base + tr.n_defects] = qp.nu.ravel()
    lam[base + tr.n_defects + rows.index] = qp.active.row_z
    return lam


def bound_multipliers(L, active, z_all=None):
    """The bounds' multipliers z of every variable (the NLP's convention) from an active set:
    its multipliers where a bound is active, 0 elsewhere; or the interior point's `z_all` of a
    QP taken as it left it (μ/s on the bounds it left inactive, which its step's stationarity
    holds)."""
    z = np.zeros(L.size)
    z[:L.points * L.nz] = np.where(active.side != 0, active.z, 0.0) if z_all is None else z_all
    return z


def violation(tr, c):
    """Each constraint's violation of its bounds (0 within them)."""
    return np.maximum(np.maximum(tr.g_lo - c, c - tr.g_hi), 0.0)


def kkt_error(tr, x, lam, z):
    """(the largest constraint violation, the larger of the stationarity residual
    |∇f + Jᵀλ + z| and the complementarity |z_i|·(x_i's distance to its bound), largest over the
    variables, each scaled like IPOPT's by the multipliers' size)."""
    primal = float(np.max(violation(tr, tr.constraints(x)), initial=0.0))
    grad = tr.gradient(x)
    jt = np.bincount(tr.jac_cols, tr.jacobian(x) * lam[tr.jac_rows], minlength=x.size)
    dual = np.max(np.abs(grad + jt + z), initial=0.0)
    scale = max(100.0, (np.sum(np.abs(lam)) + np.sum(np.abs(z))) / max(1, lam.size + x.size))
    gap = np.where(z > 0, tr.hi - x, x - tr.lo)
    products = np.abs(z) * np.where(np.isfinite(gap), gap, 0.0)
    compl = np.max(products, initial=0.0) / (max(100.0, np.sum(np.abs(z)) / x.size) / 100.0)
    if DEBUG:
        print(f"    stationarity {float(dual) / (scale / 100.0):.2e} complementarity {compl:.2e}")
    return primal, max(float(dual) / (scale / 100.0), float(compl))


def solve(tr, x0, lam0=None, z0=None, tol=1e-8, max_iter=SQP_ITERATIONS, monitor=None,
          hand_over=False, purify=True):
    """SQP from (x0, lam0, z0) on the transcription `tr` (its `bound` copy): an `Outcome`;
    Unsupported when the problem has a part the structure does not cover, StepFailed when a
    step fails (the caller then solves with IPOPT), and with `hand_over` also where its
    stationarity residual stalls above tol (STALLED_PRIMAL). purify=False: the interior point's
    QP solutions are taken as they stand from the first (`Outcome.as_left` of a solve before
    whose active sets did not make them exact)."""
    reason = unsupported(tr)
    if reason:
        raise Unsupported(f"the SQP does not handle {reason}")
    try:
        return _iterate(tr, x0, lam0, z0, tol, max_iter, monitor, hand_over, purify)
    except StepFailed:
        raise
    except Unsupported as exc:
        raise StepFailed(str(exc)) from None


def _active_passes(last, skipped):
    """The active set's passes for the next QP: none where it is `skipped` (the QPs are taken as
    the interior point leaves them; a step far from the solution, or the one after it, whose
    set is a loose interior point's: on the Panda's re-plans those passes changed 145-1869
    constraints each and never settled, 2-4 factors a QP for nothing), QUICK_PASSES after a QP
    the interior point solved (`last`), else ACTIVE_PASSES."""
    if skipped:
        return 0
    return QUICK_PASSES if last is not None and last.interior else ACTIVE_PASSES


class _Filter:
    """The line search's acceptance of a trial point by its objective φ and its constraints'
    violation θ (Σ of each one's violation), IPOPT's filter (Wächter & Biegler 2006): a step
    is taken where the point is not dominated by an earlier pair of the filter and lowers θ or φ
    enough against the current point; near feasibility (θ ≤ θ_min), a step along which φ falls
    fast enough against θ (the switching condition) needs Armijo's decrease of φ instead, and
    does not add the current pair to the filter. A trial θ above θ_max, or a φ that rises by more
    than FILTER_PHI_RISE·max(1, |φ|) (IPOPT's obj_max_inc), or a value that is not finite, is
    never taken.
    (An ℓ1 merit function cut the Panda's steps from a cold start to 1/32–1/8 for 30
    iterations; with the filter the SQP solves it in 8 where IPOPT takes 27.)"""

    def __init__(self, theta_max, theta_min):
        self.theta_max, self.theta_min, self.pairs = theta_max, theta_min, []

    @classmethod
    def at(cls, theta0):
        """The filter of a solve whose start violates its constraints by θ0."""
        scale = max(1.0, float(theta0))
        return cls(FILTER_THETA_MAX * scale, FILTER_THETA_MIN * scale)

    def _refused(self, phi, trial_phi, trial_theta):
        """Whether a trial is out whatever the step: a value not finite, θ above θ_max, φ risen
        by more than FILTER_PHI_RISE·max(1, |φ|), or a pair of the filter dominating it."""
        if not (np.isfinite(trial_phi) and np.isfinite(trial_theta)):
            return True
        return (trial_theta > self.theta_max
                or trial_phi - phi > FILTER_PHI_RISE * max(1.0, abs(phi))
                or any(trial_theta >= t and trial_phi >= f for t, f in self.pairs))

    def takes(self, phi, theta, slope, alpha, trial_phi, trial_theta):
        """Whether the point (trial_phi, trial_theta) at step alpha along a direction of slope
        ∇φᵀd is taken from (phi, theta); a taken step that is not φ-type adds (phi, theta),
        moved by the margins, to the filter."""
        if self._refused(phi, trial_phi, trial_theta):
            return False
        switching = slope < 0 and alpha * (-slope) ** FILTER_S_PHI > theta ** FILTER_S_THETA
        rounding = 1e-14 * abs(phi)                 # φ's round-off, where the steps are tiny
        armijo = trial_phi <= phi + FILTER_ETA * alpha * slope + rounding
        if switching and theta <= self.theta_min:
            return armijo
        margin = FILTER_GAMMA * theta
        if trial_theta <= theta - margin or trial_phi <= phi - margin + rounding:
            if not (switching and armijo):
                self.pairs.append((theta - margin, phi - margin))
            return True
        return False


def _iterate(tr, x0, lam0, z0, tol, max_iter, monitor, hand_over=False, purify=True):
    """`solve`'s iterations on a problem the structure covers, until the constraints hold to tol
    and the stationarity residual is within it (IPOPT's test). Once the active set did not
    make an interior point's solution exact (`_purified`), the later QPs go to the interior
    point without trying the active set and take its solution as it stands, with its
    multipliers of every bound: on Talos's refined meshes the sets never settled, and their
    passes cost 2-3 factors a QP, 20 where a purification was allowed SETTLING_PASSES."""
    L = tr.layout
    stages, rows = Stages.of(tr), Rows.of(tr)
    x = np.clip(np.asarray(x0, dtype=float), tr.lo, tr.hi)
    lam = np.zeros(tr.n_constraints) if lam0 is None else np.array(lam0, dtype=float)
    P, nz = L.points, L.nz
    lin = linearize(tr, x, lam, stages, rows)
    row_z0 = None if lam0 is None else lam[tr.defect_row + tr.n_defects + rows.index]
    active = ActiveSet.start(lin, None if z0 is None else np.asarray(z0)[:P * nz], row_z0)
    passes, inertia, qp, stalls = 0, Inertia(), None, 0
    accepted = _Filter.at(np.sum(violation(tr, tr.constraints(x))))
    as_left, was_loose = not purify, False
    z_now = bound_multipliers(L, active)
    primal_now, dual_now = kkt_error(tr, x, lam, z_now)
    crawls, error_before = 0, max(primal_now, dual_now)
    for iteration in range(1, max_iter + 1):
        loose = max(primal_now, dual_now) > LOOSE_ABOVE
        qp = solve_qp(tr, stages, rows, lin, active, inertia,
                      passes=_active_passes(qp, as_left or loose or was_loose),
                      loose=loose, purify=not as_left)
        was_loose = loose
        as_left = as_left or qp.as_left
        passes += qp.passes
        step = np.zeros(L.size)
        step[:P * nz] = qp.dz.ravel()
        lam_qp = constraint_multipliers(tr, qp, rows)
        z = bound_multipliers(L, active, qp.z_all)
        f, c, grad = tr.objective(x), tr.constraints(x), tr.gradient(x)
        infeasibility = np.sum(violation(tr, c))
        slope = float(np.sum(grad * step))          # not BLAS's dot (its threads)
        alpha = 1.0
        while True:
            trial = np.clip(x + alpha * step, tr.lo, tr.hi)
            trial_infeasibility = np.sum(violation(tr, tr.constraints(trial)))
            if accepted.takes(f, infeasibility, slope, alpha, tr.objective(trial),
                              trial_infeasibility):
                break
            if dual_now <= tol and trial_infeasibility <= RESTORING * infeasibility:
                break
            alpha *= 0.5
            if alpha < SMALLEST_STEP:
                if primal_now <= tol and dual_now <= STALL_DUAL:
                    return Outcome(x, lam, z_now, iteration - 1, True,
                                   "converged (no step lowers the objective or the violation "
                                   "further)", passes, dual_now, as_left, primal_now)
                raise StepFailed("the SQP's line search failed",
                                 Outcome(x, lam, z_now, iteration - 1, False, "line search",
                                         passes, dual_now, as_left, primal_now))
        x = trial
        lam, z = lam + alpha * (lam_qp - lam), z_now + alpha * (z - z_now)
        primal, dual = kkt_error(tr, x, lam, z)
        dual_before = dual_now
        primal_now, dual_now, z_now = primal, dual, z
        value = tr.objective(x)
        if monitor is not None:
            monitor(iteration, value, primal, dual, alpha)
        settled = alpha == 1.0 and abs(value - f) <= STALL * max(1.0, abs(f))
        # the constraints to tol, not 1e-3·tol: with QPs taken as they stand a bound whose
        # multiplier vanishes stays ~√gap off its value, and the constraints fell linearly
        # (Talos's 615-node mesh: 1e-7, 2e-9, 1e-10, 6e-12), 2 iterations of ~17 factors a mesh
        if primal <= tol and (dual <= tol or (settled and dual <= STALL_DUAL)):
            return Outcome(x, lam, z, iteration, True, "converged", passes, dual, as_left,
                           primal)
        stalls = stalls + 1 if (iteration > 1 and alpha == 1.0 and primal <= STALLED_PRIMAL
                                and dual > max(tol, dual_before / STALLED_DROP)) else 0
        if hand_over and stalls >= STALLED_ITERATIONS:
            if dual <= STALLED_NEAR * tol and primal <= tol:
                return Outcome(x, lam, z, iteration, True, "converged (its stationarity "
                               "residual stalled near tol)", passes, dual, as_left,
                               primal)
            raise StepFailed(f"its stationarity residual stalled at {dual:.1e} in iteration "
                             f"{iteration}, above tol {tol:g}",
                             Outcome(x, lam, z, iteration, False, "stalled", passes, dual,
                                     as_left, primal))
        error = max(primal, dual)
        crawls = crawls + 1 if (iteration > 1 and error <= NEAR_SOLUTION
                                and error > max(tol, error_before / STALLED_DROP)) else 0
        error_before = error
        if hand_over and crawls >= CRAWL_ITERATIONS:
            raise StepFailed(f"its KKT error fell less than {STALLED_DROP:g} times an iteration "
                             f"near the solution ({error:.1e} in iteration {iteration})",
                             Outcome(x, lam, z, iteration, False, "crawled", passes, dual,
                                     as_left, primal))
        lin = linearize(tr, x, lam, stages, rows)
    return Outcome(x, lam, z_now, max_iter, False,
                   f"not converged in {max_iter} iterations", passes, dual_now,
                   as_left, primal_now)
