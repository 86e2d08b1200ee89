"""The collocation NLP: constraint values, their sparse Jacobian, the objective and its gradient,
and the exact Hessian of the Lagrangian, for IPOPT (through `cyipopt`).

Constraints, in order: the residual r(z_j) = 0 at every point (`residual_terms` of the model's
function table, called from C for all points at once); the path constraints at every point (a
compiled unit); a constrained model's position and velocity levels at the first node; the
defects (linear, or bilinear in T for a free duration; rows scaled as Δx/h − f); the linear
instance constraints (periodicity, values between nodes); with a free duration, each bounded
state's hull between the points (bilinear in T, `grid.state_hulls`). The objective is
h·Σ_j w_j·L(z_j) + T (minimum time) + Σ ω·(C·x − d)² (data). The Hessian of σ·f + Σ μ·g is
assembled from per-point kernels (∇²(μᵀr) of the model, ∇²(μᵀg) of the path, σ·h·w_j·∇²L), the
cross terms with T and the data term's constant 2σ·CᵀΩC; contributions to one entry are summed
(`np.bincount`).
"""
import copy

import numpy as np

from ..calculus import internal_symbols
from ..errors import LagrgenError
from ._points import kernel_rows, residual_rows, weighted_rows
from .grid import (defect_intervals, defects, interpolation, quadrature, state_hulls,
                   variable_names)
from ..hessians import (path_derivatives, point_variables_of, residual_hessian,
                        residual_jacobian_structure, residual_parameter_hessian,
                        scalar_derivatives, weights)
from .symbolic import consistency_derivatives
from .sparsity import hessian_entries, jacobian_structure
from .units import compiled_unit

#: An instance value outside its bounds by at most this much (relative to max(1, the bound)) is
#: clipped onto the bound, with a note: a state read off a solution that rides a limit exceeds
#: it by the solver's bound tolerance (IPOPT's: 1e-8).
BOUND_SLACK = 1e-6


class Transcription:
    """The NLP of a `Collocation` problem on one mesh (`layout`, default the problem's grid), with
    the callbacks IPOPT calls; `controls` (a `ControlMesh`) ties the inputs of a refined mesh to
    their polynomials on the control intervals."""

    def __init__(self, problem, hessian_kind, layout=None, controls=None):
        self.problem, self.hessian_kind, self.controls = problem, hessian_kind, controls
        L = self.layout = problem.layout if layout is None else layout
        self.mod = problem.mod
        self.quad = quadrature(L)
        self.n_path = len(problem._path)
        self.n_term = len(problem._terminal)
        self.integrand = problem._objective_integrand()
        self.exact = hessian_kind == "exact"
        #: A spatial tree's residual derivatives by its recursion, their sparsity from its
        #: structure (`.sparsity`): no symbolic equations (unknown parameters take the symbolic
        #: path).
        self.recursive = bool(self.mod.info.tree_structure) and not L.unknown
        if self.exact:
            self._hessian_units()
        self._residual_structure()
        self._problem_unit()
        self._consistency()
        self._defect_structure()
        self._linear_rows()
        self._hull_structure()
        self._data_term()
        self._variable_bounds()
        self.bounds_stamp = problem._values_stamp
        self._jacobian_structure()
        if self.exact:
            self._hessian_structure()
        self._entry = None          # (x, the values at x): one tuple, read and replaced whole
        self.scale_defects(problem.duration_bounds[0])
        self.evaluations = {"constraints": 0, "jacobian": 0, "hessian": 0, "objective": 0}

    def refresh_bounds(self):
        """The bounds again from the problem's instance values (changed by `resolve`; the
        structure is the same)."""
        self._variable_bounds()
        self.bounds_stamp = self.problem._values_stamp

    def bound(self, duration):
        """A copy of this NLP for one solve, its defect rows scaled by 1/h_k at the starting
        point's `duration` (rows Δx/h_k − f), with its own evaluation cache and counts; the
        structure is shared (nothing of it is written after construction)."""
        other = copy.copy(self)
        other.scale_defects(duration)
        other._entry = None
        other.evaluations = dict.fromkeys(self.evaluations, 0)
        return other

    def scale_defects(self, duration):
        """Scale each defect row by 1/h_k, h_k its interval's length at `duration`."""
        L = self.layout
        h = max(float(duration), 1e-12) * L.steps[defect_intervals(L)]
        self.defect_scale = 1.0 / h
        self.defect_entry_scale = self.defect_scale[self.def_rows]

    # -- structure ---------------------------------------------------------------------------
    def _residual_structure(self):
        L, mod = self.layout, self.mod
        n, m, nu, ni, nz = L.n, L.m, L.nu, L.ni, L.nz
        n_params = len(mod.parameters)
        if self.recursive:
            s = jacobian_structure(mod.info.tree_structure, n, nu, n_params)
        elif self.exact:
            s = self.hessian_unit.structure["jacobian"]
        else:
            s = residual_jacobian_structure(_equations(self.problem.model))
        size1 = ni + ni * 2 * n + ni * ni + ni * nu
        rows, cols, pick = [], [], []
        for i in range(ni):
            for c in range(2 * n):
                if s["dr_dy"][i][c]:
                    rows.append(i), cols.append(c), pick.append(ni + i * 2 * n + c)
            for c in range(ni):
                if s["dr_da"][i][c]:
                    rows.append(i), cols.append(2 * n + c)
                    pick.append(ni + ni * 2 * n + i * ni + c)
            for c in range(nu):
                if s["dr_du"][i][c]:
                    rows.append(i), cols.append(3 * n + m + c)
                    pick.append(ni + ni * 2 * n + ni * ni + i * nu + c)
            for k, j in enumerate(L.unknown):
                if s["dr_dp"][i][j]:
                    rows.append(i), cols.append(nz + k), pick.append(size1 + i * n_params + j)
        self.dyn_rows = np.array(rows, dtype=np.int64)
        self.dyn_cols = np.array(cols, dtype=np.int64)
        self.dyn_pick = np.array(pick, dtype=np.int64)
        self.terms = mod.function_address("residual_terms")
        self.parameter_terms = mod.function_address("residual_parameter_jacobian") \
            if L.unknown else 0

    def _problem_unit(self):
        """The compiled path and terminal constraints, objective integrand and terminal cost
        (None when there are none)."""
        problem, L = self.problem, self.layout
        exprs = [e for _, e, _, _ in problem._path]
        terminal = [e for _, e, _, _ in problem._terminal]
        integrand, cost = problem._objective_integrand(), problem._terminal_cost
        self.unit = None
        if not exprs and integrand is None and not terminal and cost is None:
            return
        key = repr((L.n, L.m, L.nu, L.unknown, [str(e) for e in exprs], str(integrand),
                    [str(e) for e in terminal], str(cost)))
        self.unit = compiled_unit(self.mod, "problem", key,
                                  lambda: _problem_unit(L, exprs, integrand, terminal, cost))
        s = self.unit.structure
        pairs = {k: np.array(s.get(k, []), dtype=np.int64).reshape(-1, 2)
                 for k in ("path_jacobian", "path_hessian", "objective_hessian",
                           "terminal_jacobian", "terminal_hessian", "terminal_cost_hessian")}
        self.path_jac, self.path_hess = pairs["path_jacobian"], pairs["path_hessian"]
        self.obj_grad = np.array(s["objective_gradient"], dtype=np.int64)
        self.obj_hess = pairs["objective_hessian"]
        self.term_jac, self.term_hess = pairs["terminal_jacobian"], pairs["terminal_hessian"]
        self.cost_grad = np.array(s.get("terminal_cost_gradient", []), dtype=np.int64)
        self.cost_hess = pairs["terminal_cost_hessian"]

    def _consistency(self):
        """The constraints' position and velocity levels at the first node (the acceleration
        level holds at every point), except rows the initial instance values already satisfy:
        those are checked, not imposed twice."""
        L, problem, mod = self.layout, self.problem, self.mod
        self.n_cons = 0
        if not L.m:
            return
        self.cons_unit = compiled_unit(mod, "consistency", "",
                                       lambda: _consistency_unit(problem.model))
        s = self.cons_unit.structure
        rows_total, nh = s["rows"], mod.dimensions["n_holonomic"]
        jac = np.array(s["jacobian"], dtype=np.int64).reshape(-1, 2)
        hess = np.array(s["hessian"], dtype=np.int64).reshape(-1, 2)
        position = {j: k for k, j in enumerate(L.unknown)}

        def local(c):      # z column, an unknown parameter's column, or None (a known one)
            return c if c < L.nz else (L.nz + position[c - L.nz] if c - L.nz in position
                                       else None)
        unknown_rows = {r for r, c in jac if c >= L.nz and c - L.nz in position}
        fixed_q = all((0, "q", i) in problem._fixed for i in range(L.n))
        fixed_qd = all((0, "qd", i) in problem._fixed for i in range(L.n))
        z = np.zeros((1, L.nz))
        for (point, kind, i), value in problem._fixed.items():
            if point == 0:
                z[0, L.offset(kind) + i] = value
        values = np.empty((1, rows_total))
        kernel_rows(self.cons_unit.address("consistency"), np.array([problem.t0]), z,
                    np.nan_to_num(np.array(problem.params, dtype=float), nan=1.0), L.n, L.m,
                    L.nu, np.zeros((1, 0)), values)
        keep = []
        for r in range(rows_total):
            settled = fixed_q if r < nh else (fixed_q and fixed_qd)
            if settled and r not in unknown_rows:
                if abs(values[0, r]) > 1e-8:
                    name = mod.constraint_names[r if r < nh else r - nh]
                    level = "position" if r < nh else "velocity"
                    raise LagrgenError(
                        f"the initial state violates the {level} level of constraint {name!r} "
                        f"by {values[0, r]:.3g}: give a consistent one (lagrgen.consistent_state) "
                        "or leave some coordinates free")
                continue
            keep.append(r)
        self.cons_keep = np.array(keep, dtype=np.int64)
        self.n_cons = len(keep)
        row_of = {r: k for k, r in enumerate(keep)}
        entries = [(e, row_of[r], local(c)) for e, (r, c) in enumerate(jac)
                   if r in row_of and local(c) is not None]
        self.cons_jac_pick = np.array([e for e, _, _ in entries], dtype=np.int64)
        self.cons_jac = np.array([(r, c) for _, r, c in entries], dtype=np.int64).reshape(-1, 2)
        pairs = [(e, local(r), local(c)) for e, (r, c) in enumerate(hess)]
        pairs = [(e, r, c) for e, r, c in pairs if r is not None and c is not None]
        self.cons_hess_pick = np.array([e for e, _, _ in pairs], dtype=np.int64)
        self.cons_hess = np.array([(r, c) for _, r, c in pairs], dtype=np.int64).reshape(-1, 2)
        self.cons_sizes = (rows_total, len(jac), len(hess))

    def _first_point(self, state):
        return {"t": state["t"][:1], "Z": state["Z"][:1], "p": state["p"]}

    def _hessian_units(self):
        L, model = self.layout, self.problem.model
        if self.recursive:
            self.hessian_function = self.mod.function_address("residual_hessian")
            self.res_hess = hessian_entries(self.mod.info.tree_structure, L.n, L.nu)
            width = L.nz
            self.res_hess_pick = self.res_hess[:, 0] * width + self.res_hess[:, 1]
            self.parameter_unit = None
            return
        self.hessian_unit = compiled_unit(self.mod, "hessian", "",
                                          lambda: _hessian_unit(model))
        self.res_hess = np.array(self.hessian_unit.structure["entries"],
                                 dtype=np.int64).reshape(-1, 2)
        self.parameter_unit = None
        if L.unknown:
            self.parameter_unit = compiled_unit(self.mod, "parameter_hessian", "",
                                                lambda: _parameter_hessian_unit(model))
            entries = np.array(self.parameter_unit.structure["entries"],
                               dtype=np.int64).reshape(-1, 2)
            position = {j: k for k, j in enumerate(L.unknown)}
            keep, local = [], []
            for e, (r, c) in enumerate(entries):
                pr = position.get(r - L.nz)
                if pr is None:
                    continue
                if c < L.nz:
                    keep.append(e), local.append((L.nz + pr, c))
                elif c - L.nz in position:
                    keep.append(e), local.append((L.nz + pr, L.nz + position[c - L.nz]))
            self.par_keep = np.array(keep, dtype=np.int64)
            self.par_hess = np.array(local, dtype=np.int64).reshape(-1, 2)

    def _defect_structure(self):
        L = self.layout
        rows, cols, c0, c1, count = defects(L)
        self.n_defects = count
        self.def_rows, self.def_cols, self.def_c0, self.def_c1 = rows, cols, c0, c1
        self.D0 = Linear(rows, cols, c0, (count, L.size))
        self.D1 = Linear(rows, cols, c1, (count, L.size))
        self.def_T_rows = np.unique(rows[c1 != 0]) if L.free else np.zeros(0, dtype=np.int64)
        self.D1_cols = np.unique(cols[c1 != 0]) if L.free else np.zeros(0, dtype=np.int64)

    def _linear_rows(self):
        """The linear rows e_lo ≤ E·x ≤ e_hi: periodicity, instance values between this mesh's
        nodes, the inputs tied to their control intervals (`controls`), all equalities; and
        each bounded input's envelope on each Hermite–Simpson interval (`envelope_rows`)."""
        L, problem = self.layout, self.problem
        T = problem.duration_bounds[0]
        entries = [([L.index(L.points - 1, kind, i), L.index(0, kind, i)], [1.0, -1.0], 0.0,
                    0.0) for kind, i in problem._periodic]
        entries += [(*interpolation(L, kind, i, s, T), value, value)
                    for s, kind, i, value in problem._interpolated
                    if L.node_at(s / T) is None]     # on a node: a bound (`_variable_bounds`)
        self.ties = []
        if self.controls is not None:
            free = [k for k in range(L.nu) if k not in problem._given]
            self.ties = self.controls.ties(L, free)
            entries += [(c, v, 0.0, 0.0) for c, v in self.ties]
        self.n_envelope = 0
        if L.stride == 2:
            envelope = envelope_rows(L, problem)
            self.n_envelope = len(envelope)
            entries += envelope
        counts = [len(c) for c, _, _, _ in entries]
        self.E = Linear(np.repeat(np.arange(len(entries)), counts),
                        np.concatenate([np.asarray(c) for c, _, _, _ in entries] or [[]]),
                        np.concatenate([np.asarray(v, float) for _, v, _, _ in entries] or [[]]),
                        (len(entries), L.size))
        self.e_lo = np.array([lo for _, _, lo, _ in entries])
        self.e_hi = np.array([hi for _, _, _, hi in entries])

    def _hull_structure(self):
        """A free duration's rows holding each bounded state within its bounds between the
        points (`grid.state_hulls`: bilinear in T and the rates, hence not linear rows); none
        for a fixed duration, whose refinement shrinks what leaves the bounds there. The hulls
        bound the points between the ends too (a midpoint is its cubic's value; a node lies
        within the hull of the interval its rate points into), so those points lose their own
        bounds (`_variable_bounds`): with both, an arc riding a limit has more active
        constraints than variables (a = 0 at each node twice over) and IPOPT's steps stall."""
        L, problem = self.layout, self.problem
        bounded = [(kind, i) for kind in ("q", "qd") for i in range(L.n)
                   if L.free and L.stride == 2
                   and np.isfinite(problem._bounds.get((kind, i), (-np.inf, np.inf))).any()]
        rows, cols, c0, c1, count = state_hulls(L, bounded)
        self.hull_states, self.n_hull = bounded, count
        self.H0 = Linear(rows, cols, c0, (count, L.size))
        self.H1 = Linear(rows, cols, c1, (count, L.size))
        self.H1_cols = np.unique(cols[c1 != 0])
        per = 2 * (L.nodes - 1)
        self.hull_lo = np.repeat([problem._bounds[b][0] for b in bounded], per)
        self.hull_hi = np.repeat([problem._bounds[b][1] for b in bounded], per)

    def _data_term(self):
        """Σ ω·(C·x − d)² over every present sample of every track."""
        L, problem = self.layout, self.problem
        T = problem.duration_bounds[0]
        rows, cols, vals, d, w = [], [], [], [], []
        for times, data, names, weights_, present, _ in problem._tracks:
            for r, (kind, i) in enumerate(names):
                for k in np.flatnonzero(present[r]):
                    c, v = interpolation(L, kind, i, times[k], T)
                    row = len(d)
                    rows += [row] * len(c)
                    cols += list(c)
                    vals += list(v)
                    d.append(data[r, k])
                    w.append(weights_[r, k])
        self.n_data = len(d)
        self.C = Linear(rows, cols, vals, (len(d), L.size))
        self.d, self.omega = np.array(d), np.array(w)
        if self.n_data:
            self.data_hess = self.C.weighted_gram(2.0 * self.omega)

    def _variable_bounds(self):
        """lo ≤ x ≤ hi (the bounds, instance values as lo = hi, given inputs) and the
        constraints' bounds g_lo, g_hi; `notes` of what was adjusted."""
        L, problem, mod = self.layout, self.problem, self.mod
        self.notes = []
        if problem._integrand is None and self.integrand is not None:
            self.notes.append(problem.regularization_note())
        lo, hi = np.full(L.size, -np.inf), np.full(L.size, np.inf)
        blo, bhi = lo[:L.p_start].reshape(L.points, L.nz), hi[:L.p_start].reshape(L.points, L.nz)
        for (kind, i), (a, b) in problem._bounds.items():
            if kind == "p":
                lo[L.p_start + i], hi[L.p_start + i] = a, b
            else:
                col = L.offset(kind) + i
                blo[:, col], bhi[:, col] = a, b
        for kind, i in self.hull_states:     # inside the hulls on either side of them
            col = L.offset(kind) + i
            blo[1:-1, col], bhi[1:-1, col] = -np.inf, np.inf
        times = self.point_times(problem.duration_bounds[0])
        for k, values in problem._given.items():
            col = L.offset("u") + k
            v = problem.given_values(k, times)
            if np.any(v < blo[:, col] - 1e-12) or np.any(v > bhi[:, col] + 1e-12):
                raise LagrgenError(
                    f"the given values of input {mod.inputs[k]!r} (from {np.min(v):g} to "
                    f"{np.max(v):g}) lie outside its bounds [{blo[0, col]}, {bhi[0, col]}]: drop "
                    "the bound or the given values")
            blo[:, col], bhi[:, col] = v, v
        names = variable_names(mod)
        T = problem.duration_bounds[0]
        fixed = [((L.node_at(fraction), kind, i), value)
                 for (fraction, kind, i), value in problem._fixed.items()]
        fixed += [((L.node_at(s / T), kind, i), value) for s, kind, i, value
                  in problem._interpolated if L.node_at(s / T) is not None]
        given = {}
        for (point, kind, i), value in fixed:
            j = L.index(point, kind, i)
            where = f"{names[kind][i]} at t = {times[point]:.6g}"
            if j in given and given[j] != value:
                raise LagrgenError(f"the instance values {given[j]} and {value} of {where} "
                                   "contradict each other: give one")
            if not lo[j] - 1e-12 <= value <= hi[j] + 1e-12:
                clipped = min(max(value, lo[j]), hi[j])
                if abs(clipped - value) > BOUND_SLACK * max(1.0, abs(clipped)):
                    raise LagrgenError(f"the instance value {value} of {where} lies outside "
                                       f"its bounds [{lo[j]}, {hi[j]}]")
                self.notes.append(f"the instance value {float(value)!r} of {where} lies "
                                  f"{abs(clipped - value):.2g} outside its bounds (a solver's "
                                  f"tolerance): taken as {float(clipped)!r}")
                value = clipped
            lo[j] = hi[j] = given[j] = value
        if L.free:
            lo[L.T_index], hi[L.T_index] = np.array(problem.duration_bounds) / L.T_scale
        self.lo, self.hi = lo, hi
        self.g_lo = np.concatenate([np.zeros(L.points * L.ni),
                                    np.tile([lo_ for _, _, lo_, _ in problem._path], L.points),
                                    np.zeros(self.n_cons),
                                    [lo_ for _, _, lo_, _ in problem._terminal],
                                    np.zeros(self.n_defects), self.e_lo, self.hull_lo])
        self.g_hi = np.concatenate([np.zeros(L.points * L.ni),
                                    np.tile([hi_ for _, _, _, hi_ in problem._path], L.points),
                                    np.zeros(self.n_cons),
                                    [hi_ for _, _, _, hi_ in problem._terminal],
                                    np.zeros(self.n_defects), self.e_hi, self.hull_hi])

    def _columns(self, local):
        """Global columns of per-point local columns (local < nz: the point's own variables,
        nz + k: unknown parameter k): an array (points, len(local))."""
        L = self.layout
        j = np.arange(L.points)[:, None] * L.nz
        local = np.asarray(local, dtype=np.int64)[None, :]
        return np.where(local < L.nz, j + local, L.p_start + local - L.nz)

    @property
    def defect_row(self):
        """The first defect row."""
        L = self.layout
        return L.points * (L.ni + self.n_path) + self.n_cons + self.n_term

    @property
    def terminal_row(self):
        """The first terminal constraint's row."""
        L = self.layout
        return L.points * (L.ni + self.n_path) + self.n_cons

    @property
    def hull_row(self):
        """The first row of the states' hulls (after the linear rows)."""
        return self.defect_row + self.n_defects + self.E.shape[0]

    def _last_columns(self, local):
        """Global columns of the last point's local columns (or unknown parameters')."""
        return self._columns(local)[-1]
    def _jacobian_structure(self):
        L = self.layout
        P, ni = L.points, L.ni
        rows = [(np.arange(P)[:, None] * ni + self.dyn_rows[None, :]).ravel()]
        cols = [self._columns(self.dyn_cols).ravel()]
        if self.n_path:
            rows.append((P * ni + np.arange(P)[:, None] * self.n_path
                         + self.path_jac[None, :, 0]).ravel())
            cols.append(self._columns(self.path_jac[:, 1]).ravel())
        if self.n_cons:
            rows.append(P * (ni + self.n_path) + self.cons_jac[:, 0])
            cols.append(np.where(self.cons_jac[:, 1] < L.nz, self.cons_jac[:, 1],
                                 L.p_start + self.cons_jac[:, 1] - L.nz))
        if self.n_term:
            rows.append(self.terminal_row + self.term_jac[:, 0])
            cols.append(self._last_columns(self.term_jac[:, 1]))
        base = self.defect_row
        rows.append(base + self.def_rows), cols.append(self.def_cols)
        if L.free:
            rows.append(base + self.def_T_rows)
            cols.append(np.full(self.def_T_rows.size, L.T_index))
        self.E_values = self.E.values
        rows.append(base + self.n_defects + self.E.rows), cols.append(self.E.cols)
        if self.n_hull:
            rows += [self.hull_row + self.H0.rows, self.hull_row + np.arange(self.n_hull)]
            cols += [self.H0.cols, np.full(self.n_hull, L.T_index)]
        self.jac_rows = np.concatenate(rows).astype(np.int64)
        self.jac_cols = np.concatenate(cols).astype(np.int64)
        self.n_constraints = self.hull_row + self.n_hull

    def _hessian_structure(self):
        """The union of every contribution's (row, col) in the lower triangle, and each
        contribution's place in it."""
        L = self.layout
        parts = []

        def per_point(local_pairs):
            r = self._columns(local_pairs[:, 0])
            c = self._columns(local_pairs[:, 1])
            parts.append((r.ravel(), c.ravel()))

        per_point(self.res_hess)
        if self.parameter_unit is not None:
            per_point(self.par_hess)
        if self.unit is not None and self.n_path:
            per_point(self.path_hess)
        if self.unit is not None and self.integrand is not None:
            per_point(self.obj_hess)
            if L.free:
                c = self._columns(self.obj_grad).ravel()
                parts.append((np.full(c.size, L.T_index), c))
        if L.free:
            parts.append((np.full(self.D1_cols.size, L.T_index), self.D1_cols))
        if self.n_hull:
            parts.append((np.full(self.H1_cols.size, L.T_index), self.H1_cols))
        if self.n_cons:
            first = np.where(self.cons_hess < L.nz, self.cons_hess,
                             L.p_start + self.cons_hess - L.nz)
            parts.append((first[:, 0], first[:, 1]))
        if self.n_data:
            parts.append(self.data_hess[:2])
        for local in ((self.term_hess if self.n_term else None),
                      (self.cost_hess if self.problem._terminal_cost is not None else None)):
            if local is not None:
                parts.append((self._last_columns(local[:, 0]), self._last_columns(local[:, 1])))
        rows = np.concatenate([np.maximum(r, c) for r, c in parts]).astype(np.int64)
        cols = np.concatenate([np.minimum(r, c) for r, c in parts]).astype(np.int64)
        key = rows * L.size + cols
        unique, where = np.unique(key, return_inverse=True)
        self.hess_rows, self.hess_cols = unique // L.size, unique % L.size
        self.hess_map = where.astype(np.int64)

    # -- evaluation --------------------------------------------------------------------------
    def point_times(self, T):
        return self.problem.t0 + T * self.layout.fractions

    def _state(self, x):
        """(Z, p, T, t) at x."""
        L = self.layout
        Z = L.point_block(x)
        p = np.array(self.problem.params)
        if L.unknown:
            p[list(L.unknown)] = x[L.p_start:L.p_start + len(L.unknown)]
        T = L.duration(x) if L.free else self.problem.duration_bounds[0]
        return Z, p, T, self.point_times(T)

    def _at(self, x):
        """The residuals and their Jacobian entries at x (computed once per x)."""
        entry = self._entry
        if entry is not None and np.array_equal(x, entry[0]):
            return entry[1]
        L = self.layout
        Z, p, T, t = self._state(x)
        Z = np.ascontiguousarray(Z)
        r = np.empty((L.points, L.ni))
        jac = np.empty((L.points, self.dyn_pick.size))
        failed = residual_rows(self.terms, self.parameter_terms, t, Z, p, L.n, L.m, L.nu,
                                       len(p), self.dyn_pick, r, jac)
        if failed:
            raise LagrgenError("the model's residual failed at a collocation point")
        state = {"Z": Z, "p": p, "T": T, "t": t, "r": r, "jac": jac}
        self._entry = (np.array(x), state)
        return state

    def _kernel(self, name, state, width, W=None, unit=None):
        """(points, width) outputs of kernel `name` of `unit` (default: the problem's unit) at
        every point, with the per-point weights W."""
        L = self.layout
        out = np.empty((L.points, width))
        W = np.zeros((L.points, 0)) if W is None else np.ascontiguousarray(W)
        kernel_rows((unit or self.unit).address(name), state["t"], state["Z"], state["p"],
                    L.n, L.m, L.nu, W, out)
        return out

    def _consistency_kernel(self, name, state, which, weights=None):
        """A kernel of the consistency unit at the first point (which: 0 values, 1 Jacobian, 2
        Hessian entries)."""
        L = self.layout
        out = np.empty((1, self.cons_sizes[which]))
        W = np.zeros((1, 0)) if weights is None else np.ascontiguousarray(weights[None, :])
        first = self._first_point(state)
        kernel_rows(self.cons_unit.address(name), first["t"], np.ascontiguousarray(first["Z"]),
                    first["p"], L.n, L.m, L.nu, W, out)
        return out[0]

    def _residual_hessian(self, state, W):
        """The residual's weighted Hessian entries at every point (flat), weights W (P, ni)."""
        L = self.layout
        if not self.recursive:
            return self._kernel("residual_hessian", state, len(self.res_hess), W,
                                self.hessian_unit).ravel()
        out = np.empty((L.points, len(self.res_hess)))
        if weighted_rows(self.hessian_function, state["t"], state["Z"], state["p"], L.n, L.m,
                         L.nu, W, self.res_hess_pick, out):
            raise LagrgenError("the model's residual Hessian failed at a collocation point")
        return out.ravel()

    def _last(self, name, state, width, W=None):
        """Kernel `name` of the problem's unit at the last point (weights W (width_w,))."""
        last = {"t": state["t"][-1:], "Z": np.ascontiguousarray(state["Z"][-1:]),
                "p": state["p"]}
        return self._kernel(name, last, width, None if W is None else
                            np.asarray(W, dtype=float)[None, :])[0]

    def _terminal_values(self, state):
        if "terminal" not in state:
            state["terminal"] = self._last("terminal_values", state, self.n_term)
        return state["terminal"]

    def _terminal_cost(self, state):
        if "cost" not in state:
            state["cost"] = float(self._last("terminal_cost", state, 1)[0])
        return state["cost"]

    def _path_values(self, state):
        if "path" not in state:
            state["path"] = self._kernel("path_values", state, self.n_path)
        return state["path"]

    def _integrand(self, state):
        if "L" not in state:
            state["L"] = self._kernel("objective", state, 1)[:, 0]
        return state["L"]

    def _integrand_gradient(self, state):
        if "dL" not in state:
            state["dL"] = self._kernel("objective_gradient", state, self.obj_grad.size)
        return state["dL"]

    # -- the callbacks ------------------------------------------------------------------------
    def objective(self, x):
        self.evaluations["objective"] += 1
        state = self._at(x)
        f = 0.0
        if self.integrand is not None:
            f += state["T"] * float(self.quad @ self._integrand(state))
        if self.problem._minimize_time:
            f += state["T"]
        if self.problem._terminal_cost is not None:
            f += self._terminal_cost(state)
        if self.n_data:
            res = self.C.dot(x) - self.d
            f += float(self.omega @ (res * res))
        return f

    def gradient(self, x):
        state = self._at(x)
        L = self.layout
        g = np.zeros(L.size)
        if self.integrand is not None:
            dL = self._integrand_gradient(state)
            cols = self._columns(self.obj_grad)
            g += np.bincount(cols.ravel(), (state["T"] * self.quad[:, None] * dL).ravel(),
                             minlength=L.size)
            if L.free:
                g[L.T_index] += float(self.quad @ self._integrand(state)) * L.T_scale
        if self.problem._minimize_time:
            g[L.T_index] += L.T_scale
        if self.problem._terminal_cost is not None:
            np.add.at(g, self._last_columns(self.cost_grad),
                      self._last("terminal_cost_gradient", state, self.cost_grad.size))
        if self.n_data:
            g += 2.0 * self.C.tdot(self.omega * (self.C.dot(x) - self.d))
        return g

    def constraints(self, x):
        self.evaluations["constraints"] += 1
        state = self._at(x)
        parts = [state["r"].ravel()]
        if self.n_path:
            parts.append(self._path_values(state).ravel())
        if self.n_cons:
            parts.append(self._consistency_kernel("consistency", state, 0)[self.cons_keep])
        if self.n_term:
            parts.append(self._terminal_values(state))
        parts.append(self.defect_scale * (self.D0.dot(x) + state["T"] * self.D1.dot(x)))
        parts.append(self.E.dot(x))
        if self.n_hull:
            parts.append(self.H0.dot(x) + state["T"] * self.H1.dot(x))
        return np.concatenate(parts)

    def jacobianstructure(self):
        return self.jac_rows, self.jac_cols

    def jacobian(self, x):
        self.evaluations["jacobian"] += 1
        state = self._at(x)
        L = self.layout
        parts = [state["jac"].ravel()]
        if self.n_path:
            if "path_jac" not in state:
                state["path_jac"] = self._kernel("path_jacobian", state, len(self.path_jac))
            parts.append(state["path_jac"].ravel())
        if self.n_cons:
            parts.append(self._consistency_kernel("consistency_jacobian", state,
                                                  1)[self.cons_jac_pick])
        if self.n_term:
            parts.append(self._last("terminal_jacobian", state, len(self.term_jac)))
        parts.append(self.defect_entry_scale * (self.def_c0 + state["T"] * self.def_c1))
        if L.free:
            parts.append((self.defect_scale * L.T_scale * self.D1.dot(x))[self.def_T_rows])
        parts.append(self.E_values)
        if self.n_hull:
            parts += [self.H0.values + state["T"] * self.H1.values, L.T_scale * self.H1.dot(x)]
        return np.concatenate(parts)

    def hessianstructure(self):
        return self.hess_rows, self.hess_cols

    def hessian(self, x, lagrange, obj_factor):
        self.evaluations["hessian"] += 1
        state = self._at(x)
        L = self.layout
        P, ni = L.points, L.ni
        mu = np.asarray(lagrange)
        parts = [self._residual_hessian(state, np.ascontiguousarray(mu[:P * ni].reshape(P, ni)))]
        if self.parameter_unit is not None:
            full = self._kernel("residual_parameter_hessian", state,
                                len(self.parameter_unit.structure["entries"]),
                                mu[:P * ni].reshape(P, ni), self.parameter_unit)
            parts.append(full[:, self.par_keep].ravel())
        if self.unit is not None and self.n_path:
            W = mu[P * ni:P * (ni + self.n_path)].reshape(P, self.n_path)
            parts.append(self._kernel("path_hessian", state, len(self.path_hess), W).ravel())
        if self.unit is not None and self.integrand is not None:
            W = (obj_factor * state["T"] * self.quad)[:, None]
            parts.append(self._kernel("objective_hessian", state, len(self.obj_hess), W).ravel())
            if L.free:
                parts.append((obj_factor * L.T_scale * self.quad[:, None]
                              * self._integrand_gradient(state)).ravel())
        if L.free:
            base = self.defect_row
            mu_def = mu[base:base + self.n_defects]
            parts.append(L.T_scale * self.D1.tdot(self.defect_scale * mu_def)[self.D1_cols])
        if self.n_hull:
            mu_hull = mu[self.hull_row:self.hull_row + self.n_hull]
            parts.append(L.T_scale * self.H1.tdot(mu_hull)[self.H1_cols])
        if self.n_cons:
            weights_ = np.zeros(self.cons_sizes[0])
            start = P * (ni + self.n_path)
            weights_[self.cons_keep] = mu[start:start + self.n_cons]
            parts.append(self._consistency_kernel("consistency_hessian", state, 2,
                                                  weights_)[self.cons_hess_pick])
        if self.n_data:
            parts.append(obj_factor * self.data_hess[2])
        if self.n_term:
            start = self.terminal_row
            parts.append(self._last("terminal_hessian", state, len(self.term_hess),
                                    mu[start:start + self.n_term]))
        if self.problem._terminal_cost is not None:
            parts.append(self._last("terminal_cost_hessian", state, len(self.cost_hess),
                                    [obj_factor]))
        values = np.concatenate(parts)
        return np.bincount(self.hess_map, values, minlength=self.hess_rows.size)


    # -- per point (the stage-structured solver, `sqp`) -------------------------------------------
    def point_hessians(self, x, lagrange):
        """(points, nz, nz): each point's block of the Lagrangian's Hessian (objective factor 1)
        at x, for a problem whose Hessian is block-diagonal by points (`sqp.unsupported`)."""
        state = self._at(x)
        L = self.layout
        P, ni, nz = L.points, L.ni, L.nz
        W = np.zeros((P, nz * nz))
        mu = np.ascontiguousarray(np.asarray(lagrange)[:P * ni].reshape(P, ni))
        add_symmetric(W, nz, self.res_hess, self._residual_hessian(state, mu).reshape(P, -1))
        if self.unit is not None and self.integrand is not None:
            local = self.obj_hess
            add_symmetric(W, nz, local, self._kernel("objective_hessian", state, len(local),
                                                     (state["T"] * self.quad)[:, None]))
        return W.reshape(P, nz, nz)

    def point_gradients(self, x):
        """(points, nz): each point's share of the objective's gradient."""
        state = self._at(x)
        L = self.layout
        g = np.zeros((L.points, L.nz))
        if self.integrand is not None:
            g[:, self.obj_grad] = state["T"] * self.quad[:, None] * \
                self._integrand_gradient(state)
        return g

    def point_residuals(self, x):
        """(r (points, ni), R (points, ni, nz)): each point's residual and its Jacobian."""
        state = self._at(x)
        L = self.layout
        R = np.zeros((L.points, L.ni, L.nz))
        R[:, self.dyn_rows, self.dyn_cols] = state["jac"]
        return state["r"], R


def add_symmetric(W, nz, pairs, values):
    """W (points, nz·nz, each point's block by rows) plus the symmetric blocks whose lower
    triangle holds `values` (points, len(pairs)) at `pairs` (row ≥ col), written in place at
    both places of each entry: no symmetrizing copy of W (on Talos's 735-node mesh three of
    48 MB each, ~1 s of first-touched pages in a first solve). Repeated pairs add up."""
    lower = pairs[:, 0] * nz + pairs[:, 1]
    inner = pairs[:, 0] != pairs[:, 1]
    upper = pairs[inner, 1] * nz + pairs[inner, 0]
    repeated = np.unique(lower).size < lower.size       # then its mirror repeats too
    for places, part in ((lower, values), (upper, values[:, inner])):
        if repeated:
            np.add.at(W, (slice(None), places), part)
        else:
            W[:, places] += part


def envelope_rows(layout, problem):
    """Rows (cols, coefficients, lo, hi) holding each bounded input within its bounds between
    the points of each Hermite–Simpson interval: its quadratic through (u_s, u_m, u_e) lies in
    the hull of its Bernstein coefficients u_s, 2·u_m − (u_s + u_e)/2, u_e, so with the points'
    bounds lo ≤ 2·u_m − (u_s + u_e)/2 ≤ hi keeps all of it within [lo, hi] (a condition that
    only excludes a quadratic overshooting between the points)."""
    L = layout
    rows = []
    for k in range(L.nu):
        lo, hi = problem._bounds.get(("u", k), (-np.inf, np.inf))
        if k in problem._given or not (np.isfinite(lo) or np.isfinite(hi)):
            continue
        for interval in range(L.nodes - 1):
            s = 2 * interval
            rows.append(([L.index(s, "u", k), L.index(s + 1, "u", k), L.index(s + 2, "u", k)],
                         [-0.5, 2.0, -0.5], lo, hi))
    return rows


class Linear:
    """A sparse matrix as triplets (rows, cols, values) of a given shape, for the NLP's linear
    parts (defects, instance rows, data samples): A·x and Aᵀ·y as sums of the entries' products
    (duplicates add), with no SciPy on the solver's path."""

    def __init__(self, rows, cols, values, shape):
        self.rows = np.asarray(rows, dtype=np.int64).ravel()
        self.cols = np.asarray(cols, dtype=np.int64).ravel()
        self.values = np.asarray(values, dtype=float).ravel()
        self.shape = tuple(shape)

    def dot(self, x):
        """A·x."""
        return np.bincount(self.rows, self.values * x[self.cols], minlength=self.shape[0])

    def tdot(self, y):
        """Aᵀ·y."""
        return np.bincount(self.cols, self.values * y[self.rows], minlength=self.shape[1])

    def weighted_gram(self, w):
        """The lower-triangle entries (rows, cols, values) of Aᵀ·diag(w)·A: one for each ordered
        pair of entries of a row whose first column is not left of the second (duplicates add)."""
        order = np.argsort(self.rows, kind="stable")
        r, c, v = self.rows[order], self.cols[order], self.values[order]
        first, second = [np.arange(r.size)], [np.arange(r.size)]
        for gap in range(1, r.size):         # rows sorted: entries of a row are neighbours
            same = np.flatnonzero(r[gap:] == r[:-gap])
            if not same.size:
                break
            first += [same, same + gap]
            second += [same + gap, same]
        first, second = np.concatenate(first), np.concatenate(second)
        keep = c[first] >= c[second]
        first, second = first[keep], second[keep]
        return c[first], c[second], w[r[first]] * v[first] * v[second]


# -- the units -------------------------------------------------------------------------------
def _equations(model):
    from ..lagrange import derived
    return derived(model.spec())


def _hessian_unit(model):
    """The residual's weighted Hessian in z (and, in the structure, which entries of the
    residual's Jacobian are not identically zero)."""
    eq = _equations(model)
    entries = residual_hessian(eq)
    return (f"{model.name}: ∇²_z(Σ w_i·r_i), z = [q, q̇, q̈, λ, u], lower triangle",
            [("residual_hessian", "the residual's weighted Hessian, nonzero lower entries",
              [e for _, _, e in entries])],
            {"entries": [[r, c] for r, c, _ in entries],
             "jacobian": residual_jacobian_structure(eq)})


def _consistency_unit(model):
    """[Φ; A·q̇ + b], its Jacobian and weighted Hessian in z and every parameter."""
    eq = _equations(model)
    rows, jac, hess = consistency_derivatives(eq)
    return (f"{model.name}: the constraints' position and velocity levels",
            [("consistency", "[Φ; A·q̇ + b]", rows),
             ("consistency_jacobian", "their Jacobian's nonzero entries", [e for _, _, e in jac]),
             ("consistency_hessian", "Σ mu_k·∇²row_k, lower entries", [e for _, _, e in hess])],
            {"rows": len(rows), "jacobian": [[r, c] for r, c, _ in jac],
             "hessian": [[r, c] for r, c, _ in hess]})


def _parameter_hessian_unit(model):
    eq = _equations(model)
    entries = residual_parameter_hessian(eq)
    return (f"{model.name}: ∇²(Σ w_i·r_i) in the rows of the parameters",
            [("residual_parameter_hessian", "the residual's weighted Hessian, parameter rows",
              [e for _, _, e in entries])],
            {"entries": [[r, c] for r, c, _ in entries]})


def _problem_unit(layout, path, integrand, terminal=(), cost=None):
    """The path constraints' values, Jacobian and weighted Hessian, and the integrand's value,
    gradient and Hessian, in the variables z (per point) and the unknown parameters; the same of
    the terminal constraints and the terminal cost (evaluated at the last point)."""
    variables = point_variables_of(layout.n, layout.m, layout.nu) + \
        [internal_symbols("p", max(layout.unknown) + 1)[j] for j in layout.unknown]
    kernels, structure = [], {"path_jacobian": [], "path_hessian": [],
                              "objective_gradient": [], "objective_hessian": []}
    if path:
        jac, hess = path_derivatives(path, variables, weights(len(path)))
        kernels += [("path_values", "the path constraints", path),
                    ("path_jacobian", "their Jacobian's nonzero entries", [e for _, _, e in jac]),
                    ("path_hessian", "Σ w_k·∇²g_k, lower entries", [e for _, _, e in hess])]
        structure["path_jacobian"] = [[r, c] for r, c, _ in jac]
        structure["path_hessian"] = [[r, c] for r, c, _ in hess]
    if integrand is not None:
        grad, hess = scalar_derivatives(integrand, variables)
        w = weights(1)[0]
        kernels += [("objective", "the objective's integrand L", [integrand]),
                    ("objective_gradient", "∇L, nonzero entries", [e for _, e in grad]),
                    ("objective_hessian", "w·∇²L, lower entries", [w * e for _, _, e in hess])]
        structure["objective_gradient"] = [c for c, _ in grad]
        structure["objective_hessian"] = [[r, c] for r, c, _ in hess]
    if terminal:
        jac, hess = path_derivatives(terminal, variables, weights(len(terminal)))
        kernels += [("terminal_values", "the terminal constraints", terminal),
                    ("terminal_jacobian", "their Jacobian's nonzero entries",
                     [e for _, _, e in jac]),
                    ("terminal_hessian", "Σ w_k·∇²h_k, lower entries", [e for _, _, e in hess])]
        structure["terminal_jacobian"] = [[r, c] for r, c, _ in jac]
        structure["terminal_hessian"] = [[r, c] for r, c, _ in hess]
    if cost is not None:
        grad, hess = scalar_derivatives(cost, variables)
        w = weights(1)[0]
        kernels += [("terminal_cost", "the terminal cost", [cost]),
                    ("terminal_cost_gradient", "its gradient's nonzero entries",
                     [e for _, e in grad]),
                    ("terminal_cost_hessian", "w·its Hessian, lower entries",
                     [w * e for _, _, e in hess])]
        structure["terminal_cost_gradient"] = [c for c, _ in grad]
        structure["terminal_cost_hessian"] = [[r, c] for r, c, _ in hess]
    return ("collocation problem: path and terminal constraints, objective integrand and "
            "terminal cost", kernels, structure)

