"""Hybrid simulation of impacts, resting contact and Coulomb friction with sticking.

A solve is a sequence of smooth segments. In a segment every impact is `open` or in `contact`
(gap = 0 held) and every friction `slips` in a fixed direction s = ±1 or `sticks` (v = 0 held); the
held rows join the model's own constraints in

    M·q̈ = F + Σ_slip (−μ_j·|N_j|·s_j)·w_jᵀ + Rᵀ·λ,    R·q̈ = γ_R,

solved as one linear system (N_j the value of an expression, or |λ| of the constraint or contact
it names). A segment ends at the first terminal event: an open gap closing (g ↓ 0), a contact force
turning negative (λ ↓ 0), a slip velocity reaching zero (s·v ↓ 0), a sticking force reaching its
limit (μ_s·|N| − |λ| ↓ 0). Then:

* Impacts. The closing contacts C (g ≤ gap_tol, ġ < 0) and the held contacts H take impulses
  Λ ≥ 0 by the generalized Newton law: ġ⁺ = ġ⁻ + D·Λ with the Delassus matrix D = W·P·Wᵀ (P the
  inverse mass on the model's constraints), ġ⁺_i + e_i·ġ⁻_i ≥ 0 complementary to Λ_i (e = 0 for
  H) — a small LCP solved by projected Gauss–Seidel; the planar frictions of those contacts take
  tangential impulses by Coulomb's law for impulses (within μ·Λ_n, on the rim against the
  slip: `disk_step`); q̇⁺ = q̇⁻ + P·Wᵀ·Λ. For one contact this is
  q̇⁺ = q̇⁻ − (1 + e)·M⁻¹∇g·ġ⁻/(∇gᵀM⁻¹∇g). Simultaneous impacts are therefore simultaneous (not
  sequential): a symmetric body landing on two supports keeps its symmetry.
* Resting contact. When the rebound velocity e·|ġ⁻| is at most `rest_velocity` (default 10⁻⁶
  times the largest impact speed of that contact so far, so e = 0 always rests) the contact is
  held ("contact") if its force is then ≥ 0; a Zeno sequence of bounces ends there.
* Release when a contact force turns negative (where its frictions stick, they slip first, away
  from their sticking forces: a corner that would pull while sticking may hold while sliding;
  `Switching._slide`); a planar friction that starts to slip from rest starts at v = 0 along its
  anchor (`Switching._start_from_rest`); stick when a slip velocity reaches 0 and the
  sticking force is within μ_s·|N|, else slip on in the direction −sign(λ) ("slip"); a sticking
  contact slips when its force reaches μ_s·|N|. The mode is made consistent (forces ≥ 0, sticking
  forces within their cones) before the next segment; `max_transitions` bounds chattering.
* A friction whose normal force is an impact's multiplier is inactive while that contact is open
  (N = 0: no force, no sticking row, an event value of 1, mode "open"); when the contact is held
  at a switch, it sticks or slips by the rules above (`Switching._engage`, recorded).
* Tolerances. A gap counts as closed within `gap_tol` (default 1e-9), and its speed as zero at the
  start within the speed of a fall through gap_tol; a slip velocity counts as zero within
  1000·gap_tol (at the start, and for frictions stopping together with the one whose event
  fired).
* The start is classified as any switch: a closed gap at rest — abs(ġ) at most √(2·gap_tol·abs(g̈)),
  the speed of a fall through gap_tol (g̈ with every contact open) — is held if its force is
  ≥ 0, with ġ set to 0 by an inelastic impulse; one closing faster is struck at t0; any other
  is free; a gap below −gap_tol, a restitution outside
  [0, 1], μ < 0 or μ_s < μ (at the start and at every switch) and two closed impacts with
  parallel gradients (duplicate contacts) are `ContactError`s. A solve whose segments stop
  advancing (STALL_SEGMENTS in a row shorter than ten spacings of doubles at the far end of the
  span) ends with a message saying so; max_steps and max_wall_time hold within a segment and
  between segments on both engines (on the SciPy engine by an event, `_Guard`).
* Forces. Every saved state carries the forces of its mode (`HybridSystem.forces`): the model's
  constraint multipliers, each impact's contact force, each friction's force along its slip
  velocity.
* A free mode (a model without constraints, every contact open, no friction acting: a robot
  between its joint limits) adds nothing to the model's equations: `HybridSystem` then takes q̈
  from the model's own rhs, the events from the gaps and the forces as 0.

`HybridSystem` holds that logic; `simulate_hybrid` runs it with `solve_ivp` (engine "scipy") or in
C (`lagrgen.native._ode.solve_hybrid`, `native/lg_hybrid.c`, the same rules).
"""
import math
import threading
import time
import warnings
from contextlib import contextmanager

import numpy as np
import scipy.linalg

from .errors import ContactError, warn_near_singular
from .methods import NATIVE_METHODS

OPEN, CONTACT, STICK, SLIP = "open", "contact", "stick", "slip"
#: Defaults of the switching tolerances (see `simulate_hybrid`).
GAP_TOL = 1e-9
REST_FACTOR = 1e-6
MAX_TRANSITIONS = 100000
PGS_SWEEPS = 1000
#: The share of its step a normal impulse takes per sweep where frictions take impulses too, and
#: the Newton steps of a friction disk's rim (`projected_gauss_seidel`, `disk_step`).
PGS_RELAXATION = 0.5
DISK_NEWTON = 60
DISK_FLAT = 1e-12
#: Segments in a row that may end within ten spacings of doubles (at the far end of the span)
#: of their start before the solve stops as making no progress (native/lg_hybrid.h).
STALL_SEGMENTS = 100


class Solution(tuple):
    """What `HybridSystem.solve` returns: the tuple (q̈, λ of the impacts, λ of the frictions, N
    of the frictions, (M, A, impact rows, friction rows)[, λ of the constraints]), and the planar
    frictions' part as attributes: `planar_force` (npf × 2: the sticking multipliers, or
    −μ·N·û while slipping), `planar_normal` (npf), `planar_rows` (npf × (7 + 2n)) and
    `planar_slip` (npf × 2: v)."""
    planar_force = planar_normal = planar_rows = planar_slip = None


class HybridSystem:
    """The impacts and frictions of a built model, assembled for one mode at a state.

    The impacts are the model's (`model.impact`) and then its enforced limits' stops
    (`mod.info.limit_stops`: gap sign·(q_j − bound), whose rows this class writes itself).
    Elements are numbered impacts, frictions, planar frictions (events and transitions).

    Parameters
    ----------
    mod : built model with impacts, frictions or stops
    p : parameter vector
    u_at : t -> input vector
    """

    def __init__(self, mod, p, u_at):
        self.mod, self.p, self.u_at = mod, p, u_at
        self.least_pivot = 1.0          # the least D_kk/M_kk of M met by `solve` (LDLᵀ)
        self.n = n = mod.n_coordinates
        self.m = mod.n_constraints
        defs = mod.nonsmooth_definitions
        self.stops = tuple(mod.info.limit_stops)
        self.impacts = [d for d in defs if d[1] == "impact"] + \
            [(s[0], "impact", None) for s in self.stops]
        self.frictions = [d for d in defs if d[1] == "friction"]
        self.planars = [d for d in defs if d[1] == "planar_friction"]
        self.names = [d[0] for d in self.impacts + self.frictions + self.planars]
        self.ni, self.nf, self.npf = len(self.impacts), len(self.frictions), len(self.planars)
        self.n_model_impacts = self.ni - len(self.stops)
        self.normal = [d[2] for d in self.frictions]
        self.planar_normal = [d[2] for d in self.planars]
        self.n_events = self.ni + self.nf + self.npf
        self._impact_size, self._friction_size = 4 + n, 5 + n
        self._planar_size = 7 + 2 * n
        self._stop_index = np.array([s[1] for s in self.stops], dtype=int)
        self._stop_sign = np.array([s[2] for s in self.stops], dtype=float)
        self._stop_bound = np.array([s[3] for s in self.stops], dtype=float)
        self._stop_restitution = np.array([s[4] for s in self.stops], dtype=float)
        self._free = {}

    # -- the model's terms ----------------------------------------------------------------------
    def terms(self, t, y):
        """(M, F, A, γ, impacts, frictions) at (t, y): impacts (ni, 4 + n) rows [g, ġ, γ, e, W],
        the stops' after the model's; frictions (nf, 5 + n) rows [v, γ, μ, μ_s, N, w]."""
        return self.all_terms(t, y)[:6]

    def all_terms(self, t, y):
        """`terms` and the planar frictions' rows (npf, 7 + 2n) [v1, v2, γ1, γ2, μ, μ_s, N, w1,
        w2]."""
        n = self.n
        M, F, A, gamma, terms = self.mod.hybrid_terms(t, y, self.p, self.u_at(t))
        k = self.n_model_impacts * self._impact_size
        impacts = terms[:k].reshape(self.n_model_impacts, self._impact_size)
        if self.stops:
            impacts = np.vstack([impacts, self.stop_rows(y)])
        frictions = terms[k:k + self.nf * self._friction_size].reshape(self.nf,
                                                                       self._friction_size)
        planars = terms[k + self.nf * self._friction_size:].reshape(self.npf, self._planar_size)
        return M, F, A, gamma, impacts, frictions, planars

    def solve(self, t, y, contact, slip, constraint_forces=False, planar=None):
        """Accelerations and forces in the mode (contact: bool per impact; slip: per friction
        +1/−1 slipping in that direction, 0 sticking; planar: (per planar friction −1 inactive,
        0 sticking, 1 slipping; its anchor direction d) or None for all inactive).

        Returns
        -------
        `Solution`: (q̈, λ of the impacts (0 where open), λ of the frictions (0 where
        slipping), N of the frictions, the terms), and with `constraint_forces` also λ of the
        model's constraints
        """
        n, m = self.n, self.m
        M, F, A, gamma, imp, fr, pf = self.all_terms(t, y)
        solve_M = self.factored(M)
        pmode, anchor = planar if planar is not None else ((-1,) * self.npf, ((1.0, 0.0),) *
                                                            self.npf)
        rows = [A[k] for k in range(m)]
        rhs = list(gamma)
        impact_row, friction_row, planar_row = {}, {}, {}
        for i in range(self.ni):
            if contact[i]:
                impact_row[i] = len(rows)
                rows.append(imp[i, 4:])
                rhs.append(imp[i, 2])
        for j in range(self.nf):
            if slip[j] == 0 and self.active(j, contact):
                friction_row[j] = len(rows)
                rows.append(fr[j, 5:])
                rhs.append(fr[j, 1])
        for k in range(self.npf):
            if pmode[k] == 0:
                planar_row[k] = len(rows)
                rows += [pf[k, 7:7 + n], pf[k, 7 + n:]]
                rhs += [pf[k, 2], pf[k, 3]]
        r = len(rows)
        R = np.array(rows).reshape(r, n)
        force = F.copy()
        linked = []            # (row of the normal force, its force per unit |N|)
        for j in range(self.nf):
            if slip[j] == 0:
                continue
            c = -fr[j, 2] * slip[j]
            row = self._normal_row(self.normal[j], impact_row)
            if row is None:
                if self.normal[j] is None:
                    force += c * abs(fr[j, 4]) * fr[j, 5:]
            else:
                linked.append((row, c * fr[j, 5:]))
        directions = np.zeros((self.npf, 2))
        for k in range(self.npf):
            if pmode[k] != 1:
                continue
            directions[k] = slip_direction(pf[k, :2], anchor[k])
            per_unit = -pf[k, 4] * (directions[k, 0] * pf[k, 7:7 + n]
                                    + directions[k, 1] * pf[k, 7 + n:])
            row = self._normal_row(self.planar_normal[k], impact_row)
            if row is None:
                if self.planar_normal[k] is None:
                    force += abs(pf[k, 6]) * per_unit
            else:
                linked.append((row, per_unit))
        regularized = np.arange(r) >= m
        sigma = np.ones(r)
        for _ in range(4):
            B = R.T.copy()
            for row, per_unit in linked:
                B[:, row] += sigma[row] * per_unit
            qdd, lam = saddle_solve(solve_M, R, B, force, np.array(rhs, dtype=float),
                                    regularized)
            new_sigma = np.where(lam < 0, -1.0, 1.0)
            if all(new_sigma[row] == sigma[row] for row, _ in linked):
                break
            sigma = new_sigma
        lam_impact = np.array([lam[impact_row[i]] if i in impact_row else 0.0
                               for i in range(self.ni)])
        lam_friction = np.array([lam[friction_row[j]] if j in friction_row else 0.0
                                 for j in range(self.nf)])
        normal = np.array([self._normal_value(self.normal[j], fr[j, 4], impact_row, lam)
                           for j in range(self.nf)])
        out = Solution((qdd, lam_impact, lam_friction, normal, (M, A, imp, fr)) +
                       ((lam[:m].copy(),) if constraint_forces else ()))
        out.planar_normal = np.array([self._normal_value(self.planar_normal[k], pf[k, 6],
                                                         impact_row, lam)
                                      for k in range(self.npf)])
        out.planar_force = np.array([lam[planar_row[k]:planar_row[k] + 2] if k in planar_row
                                     else -pf[k, 4] * out.planar_normal[k] * directions[k]
                                     for k in range(self.npf)]).reshape(self.npf, 2)
        out.planar_rows, out.planar_slip = pf, pf[:, :2]
        out.planar_acceleration = np.column_stack([pf[:, 7:7 + n] @ qdd - pf[:, 2],
                                                   pf[:, 7 + n:] @ qdd - pf[:, 3]])
        return out

    def factored(self, M):
        """X ↦ M⁻¹·X by one Cholesky factorization M = L·Lᵀ, its least relative pivot
        D_kk/M_kk = L_kk²/M_kk kept in `least_pivot`; by LU where M is not positive definite
        (pivot 0: the warning says so; a singular M raises LinAlgError in the solve)."""
        try:
            factor = scipy.linalg.cho_factor(M, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            self.least_pivot = 0.0
            return lambda X: np.linalg.solve(M, X)
        pivots = np.diag(factor[0]) ** 2 / np.diag(M)
        self.least_pivot = min(self.least_pivot, float(np.min(pivots)))
        return lambda X: scipy.linalg.cho_solve(factor, X, check_finite=False)

    def forces(self, t, y, contact, slip, planar=None):
        """The forces of the mode at (t, y): λ of the model's constraints, then each impact's
        contact force (its multiplier; 0 while open), then each friction's force along its slip
        direction (the sticking multiplier, or −μ·|N|·s while slipping), then each planar
        friction's two components; NaN where the mode equations are singular. All 0 in a free
        mode (`is_free`)."""
        if self.is_free(contact, planar):
            return np.zeros(self.m + self.ni + self.nf + 2 * self.npf)
        try:
            out = self.solve(t, y, contact, slip, True, planar)
        except np.linalg.LinAlgError:
            return np.full(self.m + self.ni + self.nf + 2 * self.npf, np.nan)
        _, lam_i, lam_f, normal, (_, _, _, fr), lam_m = out
        along = [lam_f[j] if slip[j] == 0 else -fr[j, 2] * slip[j] * normal[j]
                 for j in range(self.nf)]
        return np.concatenate([lam_m, lam_i, along, out.planar_force.ravel()])

    def active(self, j, contact):
        """Whether friction j acts in a mode with these contacts (`acts`)."""
        return acts(self.normal[j], contact)

    def planar_active(self, k, contact):
        """Whether planar friction k acts in a mode with these contacts (`acts`)."""
        return acts(self.planar_normal[k], contact)

    def _normal_row(self, ref, impact_row):
        """The row of R whose multiplier is a friction's normal force (`ref`), or None."""
        if ref is None:
            return None
        kind, k = ref
        if kind == "constraint":
            return k
        return impact_row.get(k)

    def _normal_value(self, ref, expression, impact_row, lam):
        """A friction's normal force: abs(λ) of its row, abs(the expression), or 0 (its
        contact is open)."""
        row = self._normal_row(ref, impact_row)
        if row is not None:
            return abs(lam[row])
        return abs(expression) if ref is None else 0.0

    def is_free(self, contact, planar=None):
        """Whether the mode adds nothing to the model's own equations: a model without
        constraints, no contact closed, and no friction of either kind acting (each one's normal
        force an open contact's). Its q̈ is then M⁻¹·F, the model's rhs, and its events are the
        contacts' gaps alone."""
        key = (tuple(contact), None if planar is None else tuple(planar[0]))
        free = self._free.get(key)
        if free is None:
            free = (self.m == 0 and not any(contact)
                    and not any(self.active(j, contact) for j in range(self.nf))
                    and (planar is None or all(k < 0 for k in planar[0])))
            self._free[key] = free
        return free

    def rhs(self, t, y, contact, slip, planar=None):
        """ẏ = [q̇, q̈] in the mode (in a free mode, `is_free`, the model's own rhs)."""
        if self.is_free(contact, planar):
            return self.mod.rhs(t, y, self.p, self.u_at(t))
        qdd = self.solve(t, y, contact, slip, planar=planar)[0]
        return np.concatenate([y[self.n:], qdd])

    def stop_gaps(self, y):
        """The stops' gaps g = sign·(q_j − bound)."""
        return self._stop_sign * (y[self._stop_index] - self._stop_bound)

    def stop_rows(self, y):
        """The impact rows [g, ġ, γ, e, W] of the stops: g = sign·(q_j − bound),
        ġ = sign·q̇_j, γ = 0, W = sign·e_j."""
        n = self.n
        rows = np.zeros((len(self.stops), 4 + n))
        rows[:, 0] = self.stop_gaps(y)
        rows[:, 1] = self._stop_sign * y[n + self._stop_index]
        rows[:, 3] = self._stop_restitution
        rows[np.arange(len(self.stops)), 4 + self._stop_index] = self._stop_sign
        return rows

    def gaps(self, t, y):
        """The gap g of every impact: the model's (from its compiled terms, where it has any),
        then the stops' (`stop_gaps`)."""
        stops = self.stop_gaps(y)
        if not self.n_model_impacts:
            return stops
        return np.concatenate([self.all_terms(t, y)[4][:self.n_model_impacts, 0], stops])

    def events(self, t, y, contact, slip, planar=None, offsets=None):
        """The event values of the mode, all falling through zero at a switch: g (open; g plus
        its offset for a contact left open at rest at its surface, see `Switching._touching`),
        λ (contact), s·v (slipping; plus its offset for one at rest that nothing moves, see
        `Switching._touching`), μ_s·|N| − |λ| (sticking); for a planar friction
        μ_s·|N| − ‖λ‖ (sticking), d·v (slipping along its anchor d; offset alike); 1 for a friction
        of either kind whose contact is open (it has none)."""
        if self.is_free(contact, planar):
            values = np.ones(self.n_events)
            values[:self.ni] = self.gaps(t, y) + (0.0 if offsets is None else offsets[:self.ni])
            return values
        out = self.solve(t, y, contact, slip, planar=planar)
        _, lam_i, lam_f, normal, (_, _, imp, fr) = out
        values = np.empty(self.n_events)
        for i in range(self.ni):
            values[i] = lam_i[i] if contact[i] else imp[i, 0] + (
                0.0 if offsets is None else offsets[i])
        for j in range(self.nf):
            values[self.ni + j] = (1.0 if not self.active(j, contact)
                                   else fr[j, 3] * normal[j] - abs(lam_f[j]) if slip[j] == 0
                                   else slip[j] * fr[j, 0] + (
                                       0.0 if offsets is None else offsets[self.ni + j]))
        pmode, anchor = planar if planar is not None else ((-1,) * self.npf, None)
        for k in range(self.npf):
            values[self.ni + self.nf + k] = (
                1.0 if pmode[k] < 0 else
                out.planar_rows[k, 5] * out.planar_normal[k] - np.hypot(*out.planar_force[k])
                if pmode[k] == 0 else np.dot(anchor[k], out.planar_slip[k]) + (
                    0.0 if offsets is None else offsets[self.ni + self.nf + k]))
        return values

    # -- the reset map --------------------------------------------------------------------------
    def inverse_mass(self, M, A):
        """P = M⁻¹ − M⁻¹Aᵀ(AM⁻¹Aᵀ)⁻¹AM⁻¹: the velocity change per generalized impulse that keeps
        the model's constraints A·q̇ = const."""
        Minv = np.linalg.inv(M)
        if not self.m:
            return Minv
        X = Minv @ A.T
        return Minv - X @ np.linalg.solve(A @ X, X.T)

    def impact(self, t, y, contact, closing, rebound, planar=None):
        """q̇⁺ by the generalized Newton law (see the module) for the closing impacts (indices)
        and the held ones; `rebound` gives e per closing impact. The planar frictions of those
        contacts that act or will act (whose normal force is one of them) take tangential
        impulses within their friction disks, μ times the normal impulse (Coulomb's law for
        impulses: sticking where it can). Returns (y⁺, ġ⁻ of each closing impact)."""
        involved = list(closing) + [i for i in range(self.ni) if contact[i] and i not in closing]
        e = np.array([rebound[i] if i in closing else 0.0 for i in involved])
        M, _, A, _, imp, _, pf = self.all_terms(t, y)
        n = self.n
        W = [imp[i, 4:] for i in involved]
        before = [imp[i, 1] for i in involved]
        target = list(-e * np.minimum(before, 0.0))
        cones = []
        for k in range(self.npf):
            ref = self.planar_normal[k]
            if ref is None or ref[0] != "impact" or ref[1] not in involved:
                continue
            cones.append((involved.index(ref[1]), len(W), len(W) + 1, pf[k, 4]))
            W += [pf[k, 7:7 + n], pf[k, 7 + n:]]
            before += [pf[k, 0], pf[k, 1]]
            target += [0.0, 0.0]
        W = np.array(W).reshape(len(W), n)
        PW = self.inverse_mass(M, A) @ W.T
        impulse = projected_gauss_seidel(W @ PW, np.array(before), np.array(target),
                                         cones=cones)
        y_plus = y.copy()
        y_plus[n:] = y[n:] + PW @ impulse
        return y_plus, np.array(before[:len(closing)])

    def delassus(self, t, y, rows, planars=()):
        """(ġ, P·Wᵀ, D = W·P·Wᵀ) of the impacts `rows` and the slip velocities (v1, v2) of the
        planar frictions `planars` at (t, y): a generalized impulse Λ along their gradients W
        changes q̇ by P·Wᵀ·Λ and their velocities by D·Λ."""
        M, _, A, _, imp, _, pf = self.all_terms(t, y)
        n = self.n
        W = np.vstack([imp[rows, 4:]] + [pf[k, 7:].reshape(2, n) for k in planars])
        before = np.concatenate([imp[rows, 1]] + [pf[k, :2] for k in planars])
        PW = self.inverse_mass(M, A) @ W.T
        return before, PW, W @ PW

    def hold(self, t, y, rows, planars=()):
        """y after the inelastic impulses that set ġ = 0 for the impacts `rows` (held
        contacts) and v = 0 for the planar frictions `planars`: D·Λ = −(ġ, v) (the least-norm
        impulses of redundant rows), q̇⁺ = q̇ + P·Wᵀ·Λ."""
        before, PW, D = self.delassus(t, y, list(rows), planars)
        y_plus = y.copy()
        y_plus[self.n:] = y[self.n:] + PW @ regularized_solve(D, -before)
        return y_plus

    def rest_speeds(self, t, y, slip, gap_tol):
        """√(2·gap_tol·abs(g̈)) per impact, g̈ = W·q̈ − γ with every contact open: the speed a
        gap gains falling through gap_tol (or loses rising within it), below which a closed gap
        counts as at rest."""
        qdd, _, _, _, (_, _, imp, _) = self.solve(t, y, [False] * self.ni, slip)
        return np.sqrt(2.0 * gap_tol * np.abs(imp[:, 4:] @ qdd - imp[:, 2]))


#: The Tikhonov weight of the contact rows of the mode equations, relative to the largest
#: diagonal entry of their Delassus matrix, and the refinements after it (see `saddle_solve`).
REGULARIZATION = 1e-7
REFINEMENTS = 3
#: A planar friction slips along (v + PLANAR_BLEND·d)/‖v + PLANAR_BLEND·d‖ (m/s): the direction
#: of its slip velocity, and its anchor d where v is 0 (as it starts to slip). It is 100× the
#: drift of a sticking point's velocity (sticking holds v̇ = 0, so v drifts by the integration
#: error, ~1e-9 m/s at rtol 1e-8): at 1e-9 that drift, not the anchor, set the direction in which
#: two coupled feet began to slip, and the run crept. The motion differs from the limit b → 0 by
#: about b (6e-8 m between b = 1e-6 and 1e-7 on the landing quadruped).
PLANAR_BLEND = 1e-7
#: The event of a contact left open at rest at its surface fires this fraction of gap_tol past
#: it (`Switching.offsets`).
TOUCH_OFFSET = 1e-3


def slip_direction(v, anchor):
    """The unit direction of slip û = (v + b·d)/‖v + b·d‖ (b = PLANAR_BLEND, d the anchor)."""
    u = np.asarray(v, dtype=float) + PLANAR_BLEND * np.asarray(anchor, dtype=float)
    norm = np.hypot(*u)
    return u / norm if norm > 0 else np.asarray(anchor, dtype=float)


def saddle_solve(solve_M, R, B, force, rhs, regularized):
    """(q̈, λ) of M·q̈ = force + B·λ, R·q̈ = rhs (solve_M: X ↦ M⁻¹·X; B = Rᵀ, or Rᵀ with the
    columns of slipping frictions' forces per unit normal force added) through the Delassus matrix
    D = R·M⁻¹·B: D·λ = rhs − R·M⁻¹·force. Redundant contacts (a box on four corners, the
    sticking feet of a walker) make D singular, and their forces are not unique: the rows
    `regularized` get a small weight ε (REGULARIZATION times D's largest diagonal entry of
    them) on D's diagonal, and REFINEMENTS steps λ += (D + ε)⁻¹·(rhs' − D·λ) take its bias
    off: λ tends to the least-norm solution (exact where the rows are independent), and q̈ is
    the same for every solution."""
    if not len(rhs):
        return solve_M(force), np.zeros(0)
    X = solve_M(np.column_stack([B, force]))
    r = len(rhs)
    XB, xf = X[:, :r], X[:, r]
    D = R @ XB
    lam = regularized_solve(D, rhs - R @ xf, regularized)
    return xf + XB @ lam, lam


def regularized_solve(D, b, regularized=None):
    """λ with D·λ = b, least-norm where D is singular on the `regularized` rows (all by
    default): see `saddle_solve`."""
    regularized = np.ones(len(b), dtype=bool) if regularized is None else regularized
    diagonal = np.abs(np.diag(D))[regularized]
    scale = diagonal.max() if diagonal.size and diagonal.max() > 0 else 1.0
    K = D + np.diag(np.where(regularized, REGULARIZATION * scale, 0.0))
    lam = np.linalg.solve(K, b)
    for _ in range(REFINEMENTS):
        lam = lam + np.linalg.solve(K, b - D @ lam)
    return lam


def acts(ref, contact):
    """Whether a friction whose normal force is `ref` (None: an expression; (kind, index): a
    constraint's or an impact's multiplier) acts with these contacts: not while it is the
    multiplier of an open contact (N = 0: no force, no sticking row, no events). One rule for
    the frictions and the planar frictions."""
    return ref is None or ref[0] != "impact" or bool(contact[ref[1]])


def mode_names(system, contact, slip, pmode=None):
    """{name: "open" | "contact" | "stick" | "slip"} of the mode (contact, slip, and the planar
    frictions' pmode: −1 inactive, 0 stick, 1 slip); a friction of either kind whose contact is
    open is "open"."""
    out = {d[0]: CONTACT if c else OPEN for d, c in zip(system.impacts, contact)}
    out.update({d[0]: OPEN if not system.active(j, contact) else STICK if v == 0 else SLIP
                for j, (d, v) in enumerate(zip(system.frictions, slip))})
    pmode = (-1,) * system.npf if pmode is None else pmode
    out.update({d[0]: OPEN if not system.planar_active(k, contact) else (OPEN, STICK, SLIP)[
        int(v) + 1] for k, (d, v) in enumerate(zip(system.planars, pmode))})
    return out


def projected_gauss_seidel(D, before, target, sweeps=PGS_SWEEPS, cones=()):
    """Λ with after = before + D·Λ: Λ_i ≥ 0, after_i ≥ target_i, Λ_i·(after_i − target_i) = 0
    (an LCP) for every row but the friction rows of `cones` ((normal row, t1 row, t2 row, μ)),
    whose pair Λ_t = (Λ_t1, Λ_t2) is Coulomb's law for impulses: after_t = target_t within the
    disk ‖Λ_t‖ ≤ μ·Λ_normal, else on its rim against after_t (`disk_step`). By nonsmooth
    Gauss–Seidel sweeps: one row at a time for the LCP, one disk at a time for the frictions
    (exact in one sweep for one frictionless contact); with frictions, each normal row moves
    PGS_RELAXATION of its step (undamped, the normal and friction impulses of a quadruped's
    landing foot alternated between two answers without end)."""
    k = len(before)
    impulse = np.zeros(k)
    after = before.astype(float).copy()
    tangent = {i for _, a, b, _ in cones for i in (a, b)}
    relax = PGS_RELAXATION if cones else 1.0

    def move(i, new):
        delta = new - impulse[i]
        if delta:
            after[:] += D[:, i] * delta
            impulse[i] = new
        return abs(delta) * D[i, i]

    for _ in range(sweeps):
        change = 0.0
        for i in range(k):
            if i in tangent or D[i, i] <= 0:
                continue
            change = max(change, move(i, max(0.0, impulse[i]
                                             - relax * (after[i] - target[i]) / D[i, i])))
        for normal, a, b, mu in cones:
            pair = [a, b]
            block = D[np.ix_(pair, pair)]
            step = disk_step(block, after[pair] - target[pair] - block @ impulse[pair],
                             mu * impulse[normal])
            change = max(change, move(a, step[0]), move(b, step[1]))
        if change <= 1e-15 * (1.0 + np.abs(before).max(initial=0.0)):
            break
    return impulse


def disk_step(B, c, radius):
    """x minimizing ½·xᵀ·B·x + cᵀ·x over the disk ‖x‖ ≤ radius (B a 2×2 symmetric positive
    semi-definite block): −B⁻¹·c where that is inside, else x(ν) = −(B + ν·I)⁻¹·c with
    ‖x(ν)‖ = radius, ν > 0 (`rim_shift`). On the rim B·x + c = −ν·x: the change of velocity
    opposes the impulse (maximal dissipation). Where B is singular (a direction no impulse
    moves, such as the sideways slip of a hinged rod's tip), that direction takes no impulse
    when c has no part along it (relative to DISK_FLAT): the least-norm minimizer. In B's
    eigenbasis, in closed form (as native/lg_hybrid.c's hy_disk_step)."""
    if not radius > 0:
        return np.zeros(2)
    b0, b1, b2 = float(B[0, 0]), float(B[0, 1]), float(B[1, 1])
    mean, half = 0.5 * (b0 + b2), 0.5 * (b0 - b2)
    root = math.hypot(half, b1)
    values = (max(mean - root, 0.0), max(mean + root, 0.0))
    if root == 0:
        v0 = (1.0, 0.0)
    elif half <= 0:
        size = math.hypot(root - half, b1)
        v0 = ((root - half) / size, -b1 / size)
    else:
        size = math.hypot(b1, root + half)
        v0 = (b1 / size, -(root + half) / size)
    g0, g1 = float(c[0]), float(c[1])
    cc = [v0[0] * g0 + v0[1] * g1, -v0[1] * g0 + v0[0] * g1]
    largest = max(abs(cc[0]), abs(cc[1]))
    unbounded, z = False, [0.0, 0.0]
    for d in range(2):
        flat = values[d] <= DISK_FLAT * values[1]
        if flat and abs(cc[d]) <= DISK_FLAT * largest:
            cc[d] = 0.0
        unbounded |= flat and cc[d] != 0
        z[d] = 0.0 if flat else -cc[d] / values[d]
    if unbounded or math.hypot(*z) > radius:
        nu = rim_shift(values, cc, radius)
        z = [-cc[d] / (values[d] + nu) if cc[d] != 0 else 0.0 for d in range(2)]
    return np.array([v0[0] * z[0] - v0[1] * z[1], v0[1] * z[0] + v0[0] * z[1]])


def rim_shift(values, cc, radius):
    """ν > 0 with ‖(cc_d/(values_d + ν))‖ = radius (values ≥ 0, the minimizer outside the
    disk): Newton steps on 1/‖x(ν)‖ − 1/radius (increasing in ν), bisection where a step leaves
    the bracket [0, ‖cc‖/radius] (at its top every values_d + ν ≥ ‖cc‖/radius: ‖x‖ ≤ radius)."""
    lo, hi = 0.0, math.hypot(*cc) / radius
    nu = hi
    for _ in range(DISK_NEWTON):
        shifted = [v + nu for v in values]
        if any(e <= 0 and g != 0 for e, g in zip(shifted, cc)):
            lo, nu = nu, 0.5 * (nu + hi)
            continue
        size = math.hypot(*[g / e if g != 0 else 0.0 for e, g in zip(shifted, cc)])
        phi = 1.0 / size - 1.0 / radius
        if phi < 0:
            lo = nu
        else:
            hi = nu
        slope = sum(g * g / e ** 3 if g != 0 else 0.0 for e, g in zip(shifted, cc)) / size ** 3
        step = nu - phi / slope if slope > 0 else 0.5 * (lo + hi)
        new = step if lo < step < hi else 0.5 * (lo + hi)
        if abs(new - nu) <= 1e-15 * nu:
            return new
        nu = new
    return nu


class Switching:
    """The mode of every element and the rules that change it at a switching time."""

    def __init__(self, system, contact=None, slip=None, rest_velocity=None, gap_tol=GAP_TOL,
                 max_transitions=MAX_TRANSITIONS):
        self.system = system
        self.contact = [False] * system.ni if contact is None else list(contact)
        self.slip = [1] * system.nf if slip is None else list(slip)
        self.rest_velocity = rest_velocity
        self.gap_tol = gap_tol
        self.max_transitions = max_transitions
        self.fastest = [0.0] * system.ni
        self.bounced = []          # the impacts that just bounced (for `lift_off`)
        self.transitions = []
        self.pmode = [-1] * system.npf             # planar frictions: −1 inactive, 0 stick, 1 slip
        self.anchor = [(1.0, 0.0)] * system.npf    # and the direction each slips along
        self.gap_offsets = [0.0] * system.ni       # of the impact events (`_touching`)
        self.slip_offsets = [0.0] * (system.nf + system.npf)   # of the slipping frictions'
        self.sticking = set()      # the planar frictions sticking as the switch began

    def offsets(self):
        """The offsets of the impact events, then of the frictions' and the planar frictions'
        (`_touching`)."""
        return tuple(self.gap_offsets) + tuple(self.slip_offsets)

    def _touching(self, out):
        """The gap offsets of the impact events from the solution `out` of the settled mode: −g
        where an open gap g is below 0 (within gap_tol, struck or released there: its event
        starts at 0, not below), plus TOUCH_OFFSET·gap_tol for a contact left open at rest at its
        surface (g ≤ gap_tol, ġ² ≤ 2·gap_tol·abs(g̈): it rises no higher than gap_tol, and
        g̈ ≥ −1000·gap_tol: nothing presses it back; not one that has just bounced), so that a
        contact resting there without force (a redundant one that a least-norm solution
        releases, a body wedged between two walls) does not fire its event on a gap that stays 0
        to round-off; it strikes when it closes past the offset. A friction slipping at rest that
        nothing moves along its slip (|v| and |v̇| ≤ 1000·gap_tol: one redundant with its
        contact, such as a pendulum's tip resting on the plane it fell on; planar ones alike) gets
        TOUCH_OFFSET·gap_tol on its event likewise: its s·v, 0 to round-off, fired the event at
        once and the stick it tried failed on the contact's share of the force, without end."""
        qdd, _, _, _, (_, _, imp, fr) = out
        gdd = imp[:, 4:] @ qdd - imp[:, 2]
        self.gap_offsets = [
            0.0 if c else max(0.0, -g) + (
                TOUCH_OFFSET * self.gap_tol if i not in self.bounced and g <= self.gap_tol
                and gd * gd <= 2 * self.gap_tol * abs(a) and a >= -1e3 * self.gap_tol else 0.0)
            for i, (c, g, gd, a) in enumerate(zip(self.contact, imp[:, 0], imp[:, 1], gdd))]
        still = 1e3 * self.gap_tol
        vdd = fr[:, 5:] @ qdd - fr[:, 1]
        slipping = [s != 0 and self.system.active(j, self.contact) and abs(v) <= still
                    and abs(a) <= still for j, (s, v, a) in enumerate(zip(self.slip, fr[:, 0],
                                                                       vdd))]
        pf, n = out.planar_rows, self.system.n
        for k in range(self.system.npf):
            a = (pf[k, 7:7 + n] @ qdd - pf[k, 2], pf[k, 7 + n:] @ qdd - pf[k, 3])
            slipping.append(self.pmode[k] == 1 and np.hypot(*pf[k, :2]) <= still
                            and np.hypot(*a) <= still)
        self.slip_offsets = [TOUCH_OFFSET * self.gap_tol if at_rest else 0.0
                             for at_rest in slipping]

    @property
    def planar(self):
        """The planar frictions' part of the mode: (pmode, anchor) as tuples."""
        return tuple(self.pmode), tuple(self.anchor)

    def mode(self):
        """{name: "open" | "contact" | "stick" | "slip"} (a friction whose contact is open:
        "open")."""
        return mode_names(self.system, self.contact, self.slip, self.pmode)

    def _record(self, t, k, kind):
        self.transitions.append((float(t), self.system.names[k], kind))

    def start(self, t, y):
        """The initial mode. A closed contact (g ≤ gap_tol) is at rest when abs(ġ) is at most
        the speed of a fall through gap_tol, √(2·gap_tol·abs(g̈)) (g̈ with every contact open):
        it is held if its force is then ≥ 0, and an inelastic impulse sets its ġ to 0 (a
        "contact" transition when ġ was not 0); one closing faster is struck first; any other
        is free. Frictions with v = 0 (abs(v) ≤ 1000·gap_tol) try sticking. Returns y (after
        the impulses at the start, if any). ContactError for a start inside a surface
        (g < −gap_tol) or coefficients out of range."""
        s = self.system
        imp, fr, pf = s.all_terms(t, y)[4:]
        check_coefficients(s, imp, fr, t, pf)
        check_outside(s, imp, self.gap_tol)
        for j in range(s.nf):
            v = fr[j, 0]
            self.slip[j] = 0 if abs(v) <= 1e3 * self.gap_tol else (1 if v > 0 else -1)
        closed = [i for i in range(s.ni) if imp[i, 0] <= self.gap_tol]
        if not closed:
            return self.settle(t, y, record=False)
        speed = s.rest_speeds(t, y, self.slip, self.gap_tol)
        for i in closed:
            self.contact[i] = bool(abs(imp[i, 1]) <= speed[i])
        self.settle(t, y, record=False)
        held = [i for i in closed if self.contact[i]]
        moving = [i for i in held if imp[i, 1] != 0]
        if moving:
            y = s.hold(t, y, held)
            for i in moving:
                self._record(t, i, CONTACT)
            imp = s.terms(t, y)[4]
        closing = [i for i in closed if not self.contact[i] and imp[i, 1] < -speed[i]]
        if closing:
            y = self._impacts(t, y, closing, imp)
        return self.settle(t, y, record=False)

    def switch(self, t, y, fired):
        """The state and mode after the segment ended at (t, y) on the events `fired`."""
        s = self.system
        closing = []
        self.sticking = {k for k in range(s.npf) if self.pmode[k] == 0}
        imp, fr, pf = s.all_terms(t, y)[4:]
        check_coefficients(s, imp, fr, t, pf)
        for i in range(s.ni):
            if not self.contact[i] and (i in fired or imp[i, 0] <= self.gap_tol) \
                    and imp[i, 1] < 0:
                closing.append(i)
        if closing:
            y = self._impacts(t, y, closing, imp)
        for i in fired:
            if i < s.ni and self.contact[i] and i not in closing:
                self.contact[i] = False
                self._record(t, i, "release")
        fr, pf = s.all_terms(t, y)[5:]
        fired = list(fired) + [s.ni + j for j in range(s.nf) if s.ni + j not in fired
                               and self.slip[j] != 0 and abs(fr[j, 0]) <= 1e3 * self.gap_tol]
        fired += [s.ni + s.nf + k for k in range(s.npf) if s.ni + s.nf + k not in fired
                  and self.pmode[k] == 1 and np.hypot(*pf[k, :2]) <= 1e3 * self.gap_tol]
        for k in fired:
            j = k - s.ni
            if j >= s.nf:
                self._planar_event(t, y, j - s.nf, pf[j - s.nf, :2])
            elif j >= 0 and not s.active(j, self.contact):
                continue
            elif j >= 0 and self.slip[j] == 0:
                lam = s.solve(t, y, self.contact, self.slip, planar=self.planar)[2][j]
                self.slip[j] = -1 if lam > 0 else 1
                self._record(t, k, SLIP)
            elif j >= 0:
                self._try_stick(t, y, j)
        return self.settle(t, y)

    def _planar_event(self, t, y, k, v):
        """Planar friction k's event: sticking, its force reached μ_s·|N| (it slips, away from
        the force); slipping, v reached 0 (it tries to stick) or turned across its anchor (a
        new anchor along v)."""
        if self.pmode[k] < 0:
            return
        if self.pmode[k] == 0:
            force = self.system.solve(t, y, self.contact, self.slip,
                                      planar=self.planar).planar_force[k]
            self.pmode[k], self.anchor[k] = 1, _unit(-force, self.anchor[k])
            self._record(t, self.system.ni + self.system.nf + k, SLIP)
        elif np.hypot(*v) <= 1e3 * self.gap_tol:
            self._try_stick_planar(t, y, k)
        else:
            self.anchor[k] = _unit(v, self.anchor[k])

    def _try_stick_planar(self, t, y, k, record=True):
        """Planar friction k at v = 0: stick if the holding force is within μ_s·|N| in norm,
        else slip away from it."""
        s = self.system
        self.pmode[k] = 0
        out = s.solve(t, y, self.contact, self.slip, planar=self.planar)
        force = out.planar_force[k]
        if np.hypot(*force) <= out.planar_rows[k, 5] * out.planar_normal[k]:
            kind = STICK
        else:
            self.pmode[k], self.anchor[k], kind = 1, _unit(-force, self.anchor[k]), SLIP
        if record:
            self._record(t, s.ni + s.nf + k, kind)

    def _impacts(self, t, y, closing, imp):
        """Apply the impact law to the closing contacts; those whose rebound e·|ġ⁻| is at most
        the rest velocity take e = 0 and are held when their force is then ≥ 0; held contacts
        the impulses lift off (ġ⁺ > 1000·gap_tol) are released."""
        s = self.system
        e, resting = {}, []
        for i in closing:
            speed = -imp[i, 1]
            self.fastest[i] = max(self.fastest[i], speed)
            rest = self.rest_velocity if self.rest_velocity is not None \
                else REST_FACTOR * self.fastest[i]
            e[i] = imp[i, 3]
            if e[i] * speed <= rest:
                e[i] = 0.0
                resting.append(i)
        y, _ = s.impact(t, y, self.contact, closing, e)
        after = s.terms(t, y)[4]
        for i in range(s.ni):               # held contacts the impulses lifted off their surface
            if self.contact[i] and i not in closing and after[i, 1] > 1e3 * self.gap_tol:
                self.contact[i] = False
                self._record(t, i, "release")
                self.bounced.append(i)
        held = []
        for i in closing:
            if i in resting:
                self.contact[i] = True
                self._classify_frictions(t, y, [i])
                if s.solve(t, y, self.contact, self.slip, planar=self.planar)[1][i] >= 0:
                    self._record(t, i, CONTACT)
                    held.append(i)
                    continue
                self.contact[i] = False
            self._record(t, i, "impact")
            self.bounced.append(i)
        for i in held:
            self._engage(t, y, i)
        return y

    def _on(self, contacts):
        """The frictions whose normal force is the multiplier of one of the impacts `contacts`."""
        return [j for j, ref in enumerate(self.system.normal)
                if ref is not None and ref[0] == "impact" and ref[1] in contacts]

    def _classify_frictions(self, t, y, contacts):
        """Slip direction sign(v), or 0 (v = 0 within 1000·gap_tol), for the frictions on the
        impacts `contacts` (inactive while those were open)."""
        fr = self.system.terms(t, y)[5]
        for j in self._on(contacts):
            v = fr[j, 0]
            self.slip[j] = 0 if abs(v) <= 1e3 * self.gap_tol else (1 if v > 0 else -1)

    def _engage(self, t, y, i):
        """The frictions on impact i, just held, start acting: those at v = 0 stick or slip by
        the holding force (`_try_stick`), the others slip (recorded)."""
        self._classify_frictions(t, y, [i])
        for j in self._on([i]):
            if self.slip[j] == 0:
                self._try_stick(t, y, j)
            else:
                self._record(t, self.system.ni + j, SLIP)

    def _try_stick(self, t, y, j):
        """Friction j reached v = 0: stick if the holding force is within μ_s·|N|, else slip on
        in the direction the force pushes."""
        s = self.system
        slip = list(self.slip)
        slip[j] = 0
        _, _, lam_f, normal, (_, _, _, fr) = s.solve(t, y, self.contact, slip,
                                                     planar=self.planar)
        if abs(lam_f[j]) <= fr[j, 3] * normal[j]:
            self.slip[j] = 0
            self._record(t, s.ni + j, STICK)
        else:
            self.slip[j] = -1 if lam_f[j] > 0 else 1
            self._record(t, s.ni + j, SLIP)

    def settle(self, t, y, record=True):
        """Make the mode consistent at (t, y): no negative contact force, no open contact at rest
        at its surface that the others press into it (`pressed`: it is held, its ġ set to 0),
        no sticking force beyond its limit, no sticking friction with v ≠ 0 (after an impact).
        Returns y."""
        s = self.system
        activated, tried, stuck, slid, rested = set(), set(), set(), set(), set()
        for _ in range(2 * (s.ni + s.nf + s.npf) + 2):
            out = s.solve(t, y, self.contact, self.slip, planar=self.planar)
            y, out = self._start_from_rest(t, y, out, rested, activated)
            qdd, lam_i, lam_f, normal, (_, _, imp, fr) = out
            changed = False
            for i in range(s.ni):
                if self.contact[i] and lam_i[i] < 0 and i not in slid:
                    slid.add(i)
                    if self._slide(t, out, i, activated, stuck, record):
                        changed = True
                        continue
                if self.contact[i] and lam_i[i] < 0:
                    self.contact[i] = False
                    changed = True
                    if record:
                        self._record(t, i, "release")
            pressed = self.pressed(imp, imp[:, 4:] @ qdd - imp[:, 2])
            if pressed:
                for i in pressed:
                    self.contact[i] = True
                    if record:
                        self._record(t, i, CONTACT)
                if any(imp[i, 1] != 0 for i in pressed):
                    y = s.hold(t, y, [i for i in range(s.ni) if self.contact[i]])
                changed = True
            for j in range(s.nf):
                if self.slip[j] != 0 or not s.active(j, self.contact):
                    continue
                v = fr[j, 0]
                if abs(v) > 1e3 * self.gap_tol or abs(lam_f[j]) > fr[j, 3] * normal[j]:
                    self.slip[j] = (1 if v > 0 else -1) if abs(v) > 1e3 * self.gap_tol else (
                        -1 if lam_f[j] > 0 else 1)
                    changed = True
                    if record:
                        self._record(t, s.ni + j, SLIP)
            slipped, planar_changed = self._settle_planar(out, activated, tried, stuck)
            if record:
                for k in slipped:
                    self._record(t, s.ni + s.nf + k, SLIP)
            changed = changed or planar_changed
            if not changed:
                break
        if record:                          # the planar frictions that began to act, as they end
            for k in sorted(activated):
                self._record(t, s.ni + s.nf + k, STICK if self.pmode[k] == 0 else SLIP)
            for k in sorted(stuck - activated):
                if self.pmode[k] == 0:
                    self._record(t, s.ni + s.nf + k, STICK)
        if len(self.transitions) > self.max_transitions:
            raise ChatteringError(t, self.max_transitions)
        self._touching(out if not changed else
                       s.solve(t, y, self.contact, self.slip, planar=self.planar))
        return y

    def _start_from_rest(self, t, y, out, rested, activated):
        """Planar frictions that begin to slip at this switch from sticking or from their
        contact's closing (`sticking`, or just `activated`), with 0 < ‖v‖ ≤ 1000·gap_tol (the
        drift of their sticking), start at v = 0 along their anchors: the impulse of
        `HybridSystem.hold` sets the velocities of every held row to 0 (held contacts, sticking
        planar frictions and these), so that their slip starts along the anchor, not along the
        drift. Each at most once per settle (`rested`: those in `sticking` or `activated`).
        Returns (y, the solution `out` of the mode at that y)."""
        s = self.system
        speeds = np.hypot(out.planar_slip[:, 0], out.planar_slip[:, 1])
        starting = [k for k in range(s.npf) if self.pmode[k] == 1 and k not in rested
                    and (k in self.sticking or k in activated)
                    and 0 < speeds[k] <= 1e3 * self.gap_tol]
        if not starting:
            return y, out
        rested.update(starting)
        held = [i for i in range(s.ni) if self.contact[i]]
        planars = sorted(starting + [k for k in range(s.npf) if self.pmode[k] == 0])
        y = s.hold(t, y, held, planars)
        return y, s.solve(t, y, self.contact, self.slip, planar=self.planar)

    def _slide(self, t, out, i, activated, stuck, record):
        """A held contact i whose force is negative with its frictions sticking: those frictions
        slip instead, away from their sticking forces (the contact may hold while slipping where
        sticking would pull on it). Returns whether one did."""
        s = self.system
        lam_f = out[2]
        slid = False
        for j in self._on([i]):
            if self.slip[j] == 0:
                self.slip[j] = -1 if lam_f[j] > 0 else 1
                slid = True
                if record:
                    self._record(t, s.ni + j, SLIP)
        for k in range(s.npf):
            ref = s.planar_normal[k]
            if ref is None or tuple(ref) != ("impact", i) or self.pmode[k] != 0:
                continue
            self.pmode[k], self.anchor[k] = 1, _unit(-out.planar_force[k], self.anchor[k])
            slid = True
            if k in stuck:
                stuck.discard(k)
            elif record and k not in activated:
                self._record(t, s.ni + s.nf + k, SLIP)
        return slid

    def pressed(self, imp, gdd):
        """The open contacts at rest at their surface (g ≤ gap_tol, ġ² ≤ 2·gap_tol·abs(g̈); not
        one that has just bounced) that the mode drives into it (g̈ < −1000·gap_tol): a contact
        released while another held kept it closed, or one found closed at the start beside
        others. A `rest_velocity` given holds only those whose rebound e·abs(ġ) is at most it
        (0: contacts never rest)."""
        return [i for i in range(self.system.ni) if not self.contact[i]
                and i not in self.bounced
                and imp[i, 0] <= self.gap_tol and gdd[i] < -1e3 * self.gap_tol
                and imp[i, 1] ** 2 <= 2 * self.gap_tol * abs(gdd[i])
                and (self.rest_velocity is None
                     or imp[i, 3] * abs(imp[i, 1]) <= self.rest_velocity)]

    def _settle_planar(self, out, activated, tried, stuck):
        """The planar frictions' part of `settle` on the solution `out` of the mode: inactive
        where their contact is open; where it has just closed (added to `activated`, all
        together), sticking when abs(v) ≤ 1000·gap_tol, else slipping along v; sticking ones
        slip when v ≠ 0 or their force leaves the disk; slipping ones take v's direction as
        their anchor, or, once per settle (`tried`), try sticking where v is 0 (stopped by the
        others: added to `stuck`). Returns the planar frictions that began to slip (to
        record), and whether a mode changed."""
        s = self.system
        slipped, changed = [], False
        for k in range(s.npf):
            v = out.planar_slip[k]
            moving = np.hypot(*v) > 1e3 * self.gap_tol
            if not s.planar_active(k, self.contact):
                changed |= self.pmode[k] != -1
                self.pmode[k] = -1
                activated.discard(k)
            elif self.pmode[k] == -1:
                changed = True
                activated.add(k)
                self.pmode[k], self.anchor[k] = (1, _unit(v, self.anchor[k])) if moving else \
                    (0, self.anchor[k])
            elif self.pmode[k] == 0 and (moving or np.hypot(*out.planar_force[k])
                                         > out.planar_rows[k, 5] * out.planar_normal[k]):
                changed = True
                self.pmode[k], self.anchor[k] = 1, _unit(v if moving else -out.planar_force[k],
                                                         self.anchor[k])
                if k in stuck:
                    stuck.discard(k)
                elif k not in activated:
                    slipped.append(k)
            elif self.pmode[k] == 1 and moving:
                self.anchor[k] = _unit(v, self.anchor[k])
            elif self.pmode[k] == 1 and k not in tried and k not in activated \
                    and np.dot(self.anchor[k], out.planar_acceleration[k]) <= 0:    # stopped
                tried.add(k)
                self.pmode[k], changed = 0, True
                stuck.add(k)
        return slipped, changed

    def lift_off(self, t, y):
        """How long the segment's first piece should be: half the predicted flight time of a
        contact that just bounced (g ≈ 0, ġ > 0, g̈ < 0), else inf, so that a flight shorter than a
        step is not stepped over."""
        s = self.system
        bounced, self.bounced = self.bounced, []
        if not bounced:
            return np.inf
        qdd, _, _, _, (_, _, imp, _) = s.solve(t, y, self.contact, self.slip, planar=self.planar)
        shortest = np.inf
        for i in bounced:
            if self.contact[i] or imp[i, 1] <= 0:
                continue
            gdd = imp[i, 4:] @ qdd - imp[i, 2]
            if gdd < 0:
                shortest = min(shortest, imp[i, 1] / -gdd)
        return shortest


def _unit(v, fallback):
    """v/‖v‖ as a tuple (the `fallback` where v is 0)."""
    norm = np.hypot(*v)
    return (float(v[0] / norm), float(v[1] / norm)) if norm > 0 else tuple(fallback)


def coefficient_problem(imp, fr):
    """(kind, index, value, μ) of the first coefficient out of range in the impact rows `imp`
    and friction rows `fr` of `HybridSystem.terms` — a restitution outside [0, 1] ("restitution"),
    μ < 0 ("mu"), μ_s < μ ("mu_static") — or None. NaN is out of every range."""
    for i, row in enumerate(imp):
        if not 0.0 <= row[3] <= 1.0:
            return "restitution", i, row[3], None
    for j, row in enumerate(fr):
        if not row[2] >= 0.0:
            return "mu", j, row[2], None
        if not row[3] >= row[2]:
            return "mu_static", j, row[3], row[2]
    return None


def coefficient_message(system, kind, k, value, mu, t):
    """The ContactError message of `coefficient_problem`'s finding at time t (the values as given:
    `{:g}` showed a restitution of 1.0000001 as 1)."""
    value, mu = float(value), None if mu is None else float(mu)
    if kind == "restitution":
        return (f"impact {system.impacts[k][0]!r} has restitution {value!r} at t = {t:.9g}: "
                "it must be between 0 and 1 (check the parameter values of the run)")
    name = (system.frictions + system.planars)[k][0]
    if kind == "mu":
        return (f"friction {name!r} has mu = {value!r} at t = {t:.9g}: a friction coefficient "
                "must be ≥ 0 (check the parameter values of the run)")
    return (f"friction {name!r} has mu_static = {value!r} below mu = {mu!r} at t = {t:.9g}: "
            "the static coefficient must be at least the kinetic one (check the parameter "
            "values of the run)")


def check_coefficients(system, imp, fr, t, pf=None):
    """ContactError when a restitution or friction coefficient is out of range (the planar
    frictions' rows `pf` counted after the frictions)."""
    if pf is not None and len(pf):
        fr = np.vstack([fr[:, :4], np.column_stack([pf[:, :2], pf[:, 4:6]])])
    problem = coefficient_problem(imp, fr)
    if problem is not None:
        raise ContactError(coefficient_message(system, *problem, t))


def check_outside(system, imp, gap_tol):
    """ContactError when a gap of the impact rows `imp` is below −gap_tol: a start inside a
    surface."""
    inside = [i for i in range(system.ni) if not imp[i, 0] >= -gap_tol]
    if inside:
        raise ContactError(start_inside_message(system, inside[0], imp[inside[0], 0], gap_tol))


def start_inside_message(system, i, gap, gap_tol):
    if i >= system.n_model_impacts:
        _, j, sign, bound, _ = system.stops[i - system.n_model_impacts]
        coordinate = system.mod.coordinates[j]
        return (f"the run starts with {coordinate} = {bound + gap / sign:.9g}, beyond its "
                f"{'lower' if sign > 0 else 'upper'} limit {bound:g} (enforced as a stop: "
                f"Model.limit(..., enforce=True), from_urdf(..., limits=True)): start within the "
                "limits, or build the model with the limits not enforced (limits=False)")
    return (f"the run starts inside the surface of impact {system.impacts[i][0]!r}: its gap is "
            f"{gap:g} (< -gap_tol = {-gap_tol:g}); start with the gap ≥ 0 (a state saved at a "
            "contact has gap 0)")


def check_start(mod, t0, y0, p, u, gap_tol=GAP_TOL, run=None):
    """ContactError (prefixed with the run index, if given) when the state (t0, y0) starts
    inside an impact's surface or a coefficient is out of range at the values p, u."""
    system = HybridSystem(mod, p, lambda t: u)
    imp, fr, pf = system.all_terms(t0, np.asarray(y0, dtype=float))[4:]
    try:
        check_coefficients(system, imp, fr, t0, pf)
        check_outside(system, imp, gap_tol)
    except ContactError as exc:
        if run is None:
            raise
        raise ContactError(f"run {run}: {exc}") from None


def duplicate_contacts(system, t, y, gap_tol):
    """ContactError naming two impacts closed at (t, y) whose gap gradients are parallel (two
    contacts on one surface make the contact equations singular), or None."""
    imp = system.terms(t, np.asarray(y, dtype=float))[4]
    closed = [i for i in range(system.ni) if abs(imp[i, 0]) <= max(gap_tol, 1e-9)]
    for a, i in enumerate(closed):
        for k in closed[a + 1:]:
            wi, wk = imp[i, 4:], imp[k, 4:]
            norm = np.linalg.norm(wi) * np.linalg.norm(wk)
            if norm > 0 and abs(abs(wi @ wk) - norm) <= 1e-9 * norm:
                return ContactError(
                    f"impacts {system.impacts[i][0]!r} and {system.impacts[k][0]!r} touch at "
                    f"t = {t:.9g} along parallel gap gradients: two contacts on one surface "
                    "(duplicate contacts) make the contact equations singular; declare each "
                    "contact once")
    return None


def singular_modes(system, t, y, gap_tol):
    """The ContactError for mode equations found singular at (t, y): duplicate contacts when two
    closed impacts have parallel gradients, else dependent contacts or constraints."""
    return duplicate_contacts(system, t, y, gap_tol) or ContactError(
        f"at t = {t:.9g} the mode equations of the impacts and frictions are singular: the "
        "held contacts, sticking frictions and constraints are dependent there")


class ChatteringError(RuntimeError):
    """More mode switches than `max_transitions`: the system chatters."""

    def __init__(self, t, limit):
        super().__init__(f"more than {limit} mode switches by t = {t:.9g}: the contacts or "
                         "frictions chatter (raise max_transitions, or check the model)")
        self.t = t


def simulate_hybrid(mod, t_span, y0, method, p, u_at, rtol, atol, t_eval=None,
                    rest_velocity=None, gap_tol=GAP_TOL, max_transitions=MAX_TRANSITIONS,
                    max_steps=None, max_wall_time=None, **options):
    """Integrate a model with impacts or frictions segment by segment with `solve_ivp`.

    Returns
    -------
    OdeResult-like dict fields: t, y, transitions, mode, nfev, status, message, n_segments
    """
    from scipy.integrate import solve_ivp
    from .solvers import SOLVERS
    system = HybridSystem(mod, p, u_at)
    sw = Switching(system, rest_velocity=rest_velocity, gap_tol=gap_tol,
                   max_transitions=max_transitions)
    t0, tf = map(float, t_span)
    y0 = np.asarray(y0, dtype=float)
    try:
        t, y = t0, sw.start(t0, y0)
    except np.linalg.LinAlgError:
        raise singular_modes(system, t0, y0, gap_tol) from None
    mode = (tuple(sw.contact), tuple(sw.slip), sw.planar)
    ts, ys, modes = [np.array([t0])], [y[:, None]], [mode]
    if sw.transitions:                      # struck at the start: saved before and after
        opened = ((False,) * system.ni, mode[1], None)
        ts, ys, modes = [np.array([t0]), np.array([t0])], [y0[:, None], y[:, None]], \
            [opened, mode]
    nfev, segments, status, message = 0, 0, 0, "The solver successfully reached the end."
    steps, started, stopped = 0, time.monotonic(), None
    no_progress, least = 0, stall_step(t0, tf)
    te_all = None if t_eval is None else np.asarray(t_eval, dtype=float)
    if te_all is not None:
        ts, ys = [te_all[te_all <= t0]], [np.repeat(y[:, None], np.sum(te_all <= t0), axis=1)]
        modes = [mode]
    while t < tf:
        t_start = t
        contact, slip, planar = tuple(sw.contact), tuple(sw.slip), sw.planar
        piece = sw.lift_off(t, y)
        t_end = min(tf, t + 0.5 * piece) if np.isfinite(piece) else tf
        if not t_end > t:
            t_end = tf

        def fun(tt, yy):
            return system.rhs(tt, yy, contact, slip, planar)
        values = _EventValues(system, contact, slip, planar, sw.offsets())
        events = [_event(values, k) for k in range(system.n_events)]
        guard = None
        if max_wall_time is not None or max_steps is not None:
            guard = _Guard(None if max_wall_time is None else started + max_wall_time,
                           None if max_steps is None else max_steps - steps)
            events.append(guard)
        sol = solve_ivp(fun, (t, t_end), y, method=SOLVERS.get(method, method), rtol=rtol,
                        atol=atol, dense_output=te_all is not None, events=events or None,
                        **options)
        nfev += sol.nfev
        segments += 1
        if guard is not None and guard.reason is not None:
            if te_all is None:
                ts.append(sol.t[1:-1])              # the last is the guard's root, ≈ t_cut
                ys.append(sol.y[:, 1:-1])
            else:
                te = te_all[(te_all > t) & (te_all <= guard.t_cut)]
                ts.append(te)
                ys.append(sol.sol(te) if len(te) else np.zeros((len(y), 0)))
            modes.append((contact, slip, planar))
            t, y = guard.t_cut, guard.y_cut
            steps += guard.steps_done
            status, message, stopped = -1, f"stopped at t = {t:.9g}", guard.reason
            break
        steps += len(sol.t) - 1
        if sol.status < 0:
            status, message = -1, sol.message
            break
        t_stop = sol.t[-1]
        if te_all is None:
            ts.append(sol.t[1:])
            ys.append(sol.y[:, 1:])
            modes.append((contact, slip, planar))
        else:
            te = te_all[(te_all > t) & (te_all <= t_stop)]
            ts.append(te)
            ys.append(sol.sol(te) if len(te) else np.zeros((len(y), 0)))
            modes.append((contact, slip, planar))
        if max_steps is not None and steps >= max_steps:
            stopped = "max_steps"
        elif max_wall_time is not None and time.monotonic() - started > max_wall_time:
            stopped = "max_wall_time"
        if stopped is not None:
            status, message, t = -1, f"stopped at t = {sol.t[-1]:.9g}", sol.t[-1]
            break
        if sol.status == 0:
            t, y = t_end, sol.y[:, -1]
        else:
            fired = [k for k in range(system.n_events) if len(sol.t_events[k])]
            t_hit = min(sol.t_events[k][0] for k in fired)
            fired = [k for k in fired if sol.t_events[k][0] == t_hit]
            y_hit = sol.y_events[fired[0]][0]
            try:
                y = sw.switch(t_hit, y_hit, fired)
            except ChatteringError as exc:
                status, message = -1, str(exc)
                break
            except np.linalg.LinAlgError:
                raise singular_modes(system, t_hit, y_hit, gap_tol) from None
            t = t_hit
            if te_all is None:
                ts.append(np.array([t]))
                ys.append(y[:, None])
                modes.append((tuple(sw.contact), tuple(sw.slip), sw.planar))
        no_progress = no_progress + 1 if t - t_start < least else 0
        if no_progress >= STALL_SEGMENTS:
            status, message = -1, stall_message(t, least, sw.transitions)
            break
    forces = [system.forces(ti, yi, *m) for times, states, m in zip(ts, ys, modes)
              for ti, yi in zip(times, states.T)]
    forces = np.array(forces).reshape(-1, system.m + system.ni + system.nf + 2 * system.npf).T
    return dict(t=np.concatenate(ts), y=np.concatenate(ys, axis=1), transitions=sw.transitions,
                forces=forces,
                mode=sw.mode(), nfev=nfev, status=status, message=message, n_segments=segments,
                success=status >= 0, stopped=stopped, t_reached=t, n_steps=steps,
                least_pivot=system.least_pivot)


def stall_step(t0, tf):
    """The least progress a segment must make: ten spacings of doubles at the far end of the
    span (as the native engine's stall test, lg_ode.h)."""
    far = max(abs(t0), abs(tf))
    return 10 * abs(np.nextafter(far, np.inf) - far)


def stall_message(t, least, transitions):
    """Why a hybrid solve stopped making progress at t."""
    recent = transitions[-3:]
    last = ", ".join(f"{kind} {name!r}" for _, name, kind in recent) or "none"
    head = (f"the hybrid solve made no progress: {STALL_SEGMENTS} segments in a row ended within "
            f"{least:.3g} s of their start, at t = {t:.9g} (last transitions: {last}). ")
    if recent and all(kind in (STICK, SLIP) for *_, kind in recent):
        return head + ("Frictions that toggle between stick and slip at one instant keep "
                       "switching without advancing: check their slip velocities and normal "
                       "forces (a normal force of 0 gives no friction)")
    if len({name for _, name, _ in recent}) == 1 and \
            {kind for *_, kind in recent} == {CONTACT, "release"}:
        return head + (f"Contact {recent[-1][1]!r} is held and released over and over at one "
                       "instant: held, its force comes out negative; released, it closes at "
                       "once. Where a friction slides at it this may be Painlevé's paradox (Coulomb "
                       "friction too large for the geometry pulls the contact in faster than a "
                       "normal force can push it out), which rigid contact cannot resolve: lower "
                       "its mu, or give the contact restitution")
    return head + ("Impacts that never come to rest (rest_velocity too small: the default is "
                   "1e-6 times the fastest impact) or contacts that hold a body from both sides "
                   "keep switching without advancing: raise rest_velocity or check the impacts")


class _EventValues:
    """All event values of a mode at (t, y), computed once for the solve_ivp event callables."""

    def __init__(self, system, contact, slip, planar=None, offsets=None):
        self.system, self.contact, self.slip, self.planar = system, contact, slip, planar
        self.offsets = offsets
        self.key, self.values = None, None

    def __call__(self, t, y):
        key = (t, y.tobytes())
        if key != self.key:
            self.key, self.values = key, self.system.events(t, y, self.contact, self.slip,
                                                            self.planar, self.offsets)
        return self.values


class _Guard:
    """A solve_ivp event for max_wall_time and max_steps inside a segment (None: no bound on
    either). SciPy evaluates the events at the segment's start and at the end of every accepted
    step. The guard is +1 until the monotonic clock passes `deadline` at a step's end, or that
    step is the (`steps` + 1)-th; it is then −1 after t_cut, the end of the step before (the
    last one no event had crossed: the step's own end may lie past an impact), +1 up to it. A
    terminal event, its root is found at t_cut to SciPy's tolerance, so that the segment ends
    there with every step before it and its dense output (the t_eval points up to t_cut);
    y_cut is the state at t_cut as the solver stored it."""

    terminal, direction = True, 0

    def __init__(self, deadline, steps):
        self.deadline, self.steps = deadline, steps
        self.steps_done, self.reason = -1, None
        self.t_cut, self.y_cut = None, None

    def __call__(self, t, y):
        if self.reason is not None:
            return 1.0 if t <= self.t_cut else -1.0
        reason = ("max_wall_time" if self.deadline is not None and
                  time.monotonic() > self.deadline else
                  "max_steps" if self.steps is not None and self.steps_done >= self.steps
                  else None)
        if reason and self.t_cut is not None:
            self.reason = reason
            return -1.0
        self.steps_done += 1
        self.t_cut, self.y_cut = t, np.array(y, dtype=float)
        return 1.0


def _event(values, k):
    def g(t, y):
        return values(t, y)[k]
    g.terminal, g.direction = True, -1
    return g


class _RunStop:
    """The stop of the ensemble chunk a thread is solving (`stopping`), which its native hybrid
    solves poll: Ctrl-C in `simulate_many` sets the chunks' shared flag, and a hybrid run read
    it only when it ended (a 14 s run held the interrupt for 12-19 s). A set flag ends the run
    with KeyboardInterrupt, as Ctrl-C ends a `simulate`, not with a stopped result whose
    transitions are then collected (0.5 s for a ball bouncing 1.5 s)."""

    def __init__(self):
        self.local = threading.local()

    def is_set(self):
        flag = getattr(self.local, "flag", None)
        if flag is not None and flag[0]:
            raise KeyboardInterrupt
        return False

    @contextmanager
    def stopping(self, flag):
        """Within the block, this thread's hybrid solves stop when flag[0] is set."""
        self.local.flag = flag
        try:
            yield
        finally:
            self.local.flag = None


RUN_STOP = _RunStop()


class UntrackedEventsWarning(UserWarning):
    """A model with impacts or frictions declares events (`model.event`) that its hybrid solve
    does not locate."""


def check_hybrid_run(mod, t_span, stacklevel=4):
    """A hybrid run goes forward in time (ValueError otherwise: backward, it returned the start
    state at every time, with success True), and warns UntrackedEventsWarning where the model
    declares events, which the hybrid solve does not locate (they were dropped without a
    word)."""
    t0, tf = map(float, t_span)
    if tf < t0:
        raise ValueError(f"a model with impacts or frictions runs forward in time only: "
                         f"t_span=({t0:g}, {tf:g}) goes backward (impacts lose energy and "
                         f"sticking is not reversible); give t0 < t1")
    if mod.event_definitions:
        names = ", ".join(e[0] for e in mod.event_definitions)
        warnings.warn(f"model {mod.name!r} has impacts or frictions: its hybrid solve does not "
                      f"locate the events declared with model.event ({names}), so the result "
                      f"has no t_events; a model without them locates them",
                      UntrackedEventsWarning, stacklevel=stacklevel)


def is_hybrid(mod):
    """True if `mod` runs as a hybrid solve: it has impacts, frictions or enforced limits."""
    return bool(mod.nonsmooth_definitions or mod.info.limit_stops)


def check_within_stops(mod, y, gap_tol=GAP_TOL):
    """ValueError when a state of `y` (2n × k) puts a coordinate beyond an enforced limit
    (a stop's gap below −gap_tol): a smooth run, such as one with sensitivities, is the hybrid
    one only while no stop is reached."""
    for name, j, sign, bound, _ in mod.info.limit_stops:
        gaps = sign * (np.asarray(y)[j] - bound)
        if gaps.size and gaps.min() < -gap_tol:
            raise ValueError(
                f"the run reached stop {name!r} ({mod.coordinates[j]} = "
                f"{np.asarray(y)[j][np.argmin(gaps)]:.6g}, limit {bound:g}): sensitivities are "
                "computed for smooth runs and do not cross switches; run within the limits, or "
                "build the model with its limits not enforced (from_urdf(..., limits=False))")


def force_names(mod):
    """The rows of a hybrid solve's contact forces: each impact's (the model's, then its stops'),
    each friction's, and the two components of each planar friction's (<name>_1, <name>_2)."""
    defs = mod.nonsmooth_definitions
    return tuple(d[0] for d in defs if d[1] == "impact") + \
        tuple(stop[0] for stop in mod.info.limit_stops) + \
        tuple(d[0] for d in defs if d[1] == "friction") + \
        tuple(f"{d[0]}_{c}" for d in defs if d[1] == "planar_friction" for c in (1, 2))


KIND_NAMES = ("impact", CONTACT, "release", STICK, SLIP)
#: lg_result_t.stopped codes of the guards (LG_STOP_STEPS, LG_STOP_WALL, LG_STOP_SAVED).
GUARDS = {1: "max_steps", 2: "max_wall_time", 4: "saved"}
#: lg_hybrid_result_t.failure codes (lg_hybrid.h).
FAILURES = {1: "model", 2: "inside", 3: "restitution", 4: "mu", 5: "mu_static", 6: "stalled"}
NORMAL_KINDS = {None: 0, "constraint": 1, "impact": 2}


def solve_hybrid_native(mod, t_span, y0, method, p, u_spec, rtol, atol, t_eval=None,
                        rest_velocity=None, gap_tol=GAP_TOL, max_transitions=MAX_TRANSITIONS,
                        max_step=np.inf, first_step=None, poll=None, max_steps=None,
                        max_wall_time=None):
    """The hybrid solve of `simulate_hybrid` in C (`native/lg_hybrid.c`): the same segments,
    events and switching rules with no Python per step or per switch.

    Returns
    -------
    dict as `simulate_hybrid`
    """
    from .native import _ode
    from .native.engine import _tolerances
    u_spec = list(u_spec)
    system = HybridSystem(mod, p, lambda t: np.array(
        [_ode.signal_values(tuple(spec), t)[0] for spec in u_spec]))
    n = mod.n_coordinates
    rtol, atol = _tolerances(rtol, atol, 2 * n)
    kinds = [NORMAL_KINDS[None if ref is None else ref[0]] for ref in system.normal]
    index = [0 if ref is None else int(ref[1]) for ref in system.normal]
    planar_kinds = [NORMAL_KINDS[None if ref is None else ref[0]] for ref in system.planar_normal]
    planar_index = [0 if ref is None else int(ref[1]) for ref in system.planar_normal]
    stops = [(j, sign, bound, e) for _, j, sign, bound, e in system.stops]
    t0, tf = map(float, t_span)
    first = 0.0 if first_step is None else float(first_step)
    out = _ode.solve_hybrid(
        method, mod.compiled_model.function_address("hybrid_terms"), n, system.m,
        system.n_model_impacts, system.nf, kinds, index, np.asarray(p, dtype=float),
        list(u_spec), t0, tf, np.asarray(y0, dtype=float), rtol, atol, float(max_step), first,
        t_eval, -1.0 if rest_velocity is None else float(rest_velocity), float(gap_tol),
        int(max_transitions), poll, int(max_steps or 0), float(max_wall_time or 0.0),
        stops=stops, planar_kind=planar_kinds, planar_index=planar_index,
        rhs=mod.compiled_model.function_address("rhs"))
    transitions = [(float(t), system.names[int(k)], KIND_NAMES[int(kind)])
                   for t, k, kind in out["transitions"]]
    message = native_failure_message(mod, system, out, transitions, float(gap_tol), t0, tf,
                                     np.asarray(y0, dtype=float))
    mode = mode_names(system, out["contact"], out["slip"], out["pmode"])
    return dict(t=out["t"], y=out["y"].T.copy(), forces=out["forces"].T.copy(),
                transitions=transitions, mode=mode,
                nfev=out["nfev"], status=out["status"], message=message,
                n_segments=out["n_segments"], success=out["status"] >= 0,
                stopped=GUARDS.get(out["stopped"]), t_reached=out["t_reached"],
                n_steps=out["n_steps"], least_pivot=out["least_pivot"])


def native_failure_message(mod, system, out, transitions, gap_tol, t0, tf, y0):
    """The message of a native hybrid solve, named as the SciPy engine names it; ContactError
    for what the SciPy engine raises (coefficients out of range, a start inside a surface,
    duplicate contacts)."""
    failure = FAILURES.get(out["failure"])
    t = out["t_reached"]
    k, value, other = out["failed_element"], out["failed_value"], out["failed_other"]
    if failure in ("restitution", "mu", "mu_static"):
        when = t if out["n_segments"] else t0
        raise ContactError(coefficient_message(system, failure, k, value, other, when))
    if failure == "inside":
        raise ContactError(start_inside_message(system, k, value, gap_tol))
    if failure == "stalled":
        return stall_message(t, stall_step(t0, tf), transitions)
    if failure == "model":
        at = (out["t"][-1], out["y"][-1]) if len(out["t"]) else (t0, y0)
        found = duplicate_contacts(system, *at, gap_tol)
        if found is not None:
            raise found
    return out["message"]


def simulate_nonsmooth(mod, t_span, y0, method, p, inputs, u_at, rtol, atol, t_eval, dense_output,
                       events, engine, progress, options, max_steps=None, max_wall_time=None):
    """`simulate` for a model with impacts or frictions: the hybrid solve in C (`engine` None or
    "native", when the native engine can run the model) or with `solve_ivp`. Returns an OdeResult
    with also `transitions`, `mode`, `n_segments`, `engine` and `guard` (None).

    max_steps and max_wall_time bound the whole solve (all segments), inside the segments too
    (on the SciPy engine at an accepted step); `max_transitions` bounds the switching, and
    Ctrl-C ends a native solve. A run whose factorizations of M met a relative pivot below
    `errors.near_singular_limit(rtol)` warns NearSingularMassMatrixWarning."""
    from .results import stopped_by_guard
    from scipy.integrate._ivp.ivp import OdeResult

    from .native.engine import _t_eval, guard_reason, native_reason
    from .runtime.arguments import input_specs
    if events is not None:
        raise ValueError("a model with impacts or frictions takes no Python events")
    check_hybrid_run(mod, t_span)
    if not isinstance(method, str) or method not in NATIVE_METHODS:
        raise ValueError(f"a model with impacts or frictions runs with "
                         f"{', '.join(NATIVE_METHODS[:-1])} or {NATIVE_METHODS[-1]}, not "
                         f"{getattr(method, '__name__', method)!r}")
    if dense_output:
        raise ValueError("dense_output is not available for a model with impacts or frictions: "
                         "give t_eval")
    options = dict(options)
    switching = {k: options.pop(k) for k in ("rest_velocity", "gap_tol", "max_transitions")
                 if k in options}
    why_not = None if engine == "scipy" else native_reason(mod, method, inputs, None, options,
                                                            rtol)
    if engine == "native" and why_not:
        raise ValueError(f"the native engine cannot run this solve: {why_not}")
    if t_eval is not None:
        t_eval = _t_eval(t_eval, *map(float, t_span))
    if engine != "scipy" and why_not is None:
        from .native._ode import Poll
        from .progress import ProgressBar
        bar = ProgressBar(*t_span, show=progress) if progress else None
        try:
            out = solve_hybrid_native(mod, t_span, y0, method, p, input_specs(mod, inputs), rtol,
                                      atol, t_eval, poll=Poll(bar, stop=RUN_STOP), max_steps=max_steps,
                                      max_wall_time=max_wall_time, **switching, **options)
            if bar is not None:                 # where it ended (the polls are 0.05 s apart)
                bar(out["t_reached"] if out["stopped"] is not None or out["status"] < 0
                    else t_span[1])
        finally:
            if bar is not None:
                bar.close()
        engine_name = "native"
    else:
        out = simulate_hybrid(mod, t_span, y0, method, p, u_at, rtol, atol, t_eval,
                              max_steps=max_steps, max_wall_time=max_wall_time, **switching,
                              **options)
        engine_name = "scipy"
    sol = OdeResult(t=out["t"], y=out["y"], sol=None, t_events=None, y_events=None,
                    nfev=out["nfev"], njev=0, nlu=0, status=out["status"],
                    message=out["message"], success=out["status"] >= 0)
    sol.engine = engine_name
    sol.transitions = out["transitions"]
    sol.mode = out["mode"]
    sol.n_segments = out["n_segments"]
    m = mod.n_constraints
    sol.hybrid_constraint_forces = out["forces"][:m]
    sol.contact_names = force_names(mod)
    sol.contact_forces = out["forces"][m:]
    sol.guard = None
    warn_near_singular(mod, min(out["least_pivot"], mod.pivot_record()), rtol)
    if out["stopped"] is not None:
        stopped_by_guard(sol, guard_reason(out["stopped"], max_steps, max_wall_time),
                         out["t_reached"], float(t_span[1]), out["n_steps"])
    return sol
