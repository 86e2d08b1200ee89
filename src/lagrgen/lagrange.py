"""Lagrange's equations, arranged as M(q, t)·q̈ = F(q, q̇, t, u), and the pieces of their Jacobian.

The derivation runs in SymEngine on internal symbols `q[i]`, `qd[i]`, `a[i]` (= q̈_i), `p[j]`, `u[k]`
and `t`; SymPy stays the language of model files and of what `Model.mass_matrix()` returns.
"""
from functools import cached_property

import symengine as se
import sympy as sp

from .caching import once_per
from .calculus import diff, internal_symbols, rate  # noqa: F401  (rate: the derivation's d/dt)
from .contributions import CONTRIBUTIONS, Sums, add_kinetic_energy
from .errors import ModelError
from .records import ExternalEquations


class Equations:
    """M(q,t)·q̈ = F(q,q̇,t,u) for one model, with the Jacobian pieces ∂F/∂q, ∂F/∂q̇, ∂(M·a)/∂q.

    Matrices are lists of lists of SymEngine expressions in the internal symbols.

    With constraints (n_holonomic Φ(q,t) = 0 first, then the velocity constraints, m in all) the
    equations are M·q̈ = F + Aᵀ·λ and A·q̈ = γ, where A = [Φ_q; A_v] (m×n), c = A·q̇ + b the
    velocity-level residuals (c_i = Φ̇_i for the holonomic rows) and, with Baumgarte's α, β,

        γ = −(∂c/∂q·q̇ + ∂c/∂t) − 2α·c − β²·[Φ; 0],

    i.e. ċ + 2α·c + β²·Φ = 0. λ lives in the kernel argument `a` after q̈: λ_k = a[n + k].
    """

    def __init__(self, spec, collected, symbols, constraints=None, events=()):
        self.spec = spec
        self.collected = collected
        self.events = list(events)
        self.n = len(symbols[0])
        self.q, self.qd, self.a, self.p, self.u, self.t = symbols
        phi, c = constraints or ([], [])
        self.n_holonomic = len(phi)
        self.m = len(c)
        self.Phi = phi
        self.c = c
        self.lam = internal_symbols("a", self.n + self.m)[self.n:]

    @cached_property
    def _dense(self):
        """(M, F), formed on first use from the collected physics (`dense_equations`)."""
        return dense_equations(self.spec, self.collected)

    @property
    def M(self):
        """M(q, t) (n×n lists of SymEngine expressions, symmetric)."""
        return self._dense[0]

    @property
    def F(self):
        """F(q, q̇, t, u) (n SymEngine expressions), so that M·q̈ = F."""
        return self._dense[1]

    @cached_property
    def A(self):
        """A_kj = ∂c_k/∂q̇_j (m×n): the constraint Jacobian [Φ_q; A_v]."""
        return [[diff(ck, qdj) for qdj in self.qd] for ck in self.c]

    @cached_property
    def gamma(self):
        """γ (m) with A·q̈ = γ: −(∂c/∂q·q̇ + ∂c/∂t) − 2α·c − β²·Φ (Baumgarte, see the class)."""
        alpha, beta = (se.Float(v) for v in self.spec.stabilization)
        out = []
        for k, ck in enumerate(self.c):
            g = -rate(ck, self.q, self.qd, self.t)
            if alpha != 0:
                g -= 2 * alpha * ck
            if k < self.n_holonomic and beta != 0:
                g -= beta * beta * self.Phi[k]
            out.append(g)
        return out

    @cached_property
    def residuals(self):
        """Φ (n_holonomic), then c = A·q̇ + b (m)."""
        return list(self.Phi) + list(self.c)

    @cached_property
    def residual_jacobian(self):
        """∂r_k/∂[q, q̇] (n_holonomic + m rows, 2n columns) of the residuals r = [Φ; c]."""
        return [[diff(r, v) for v in list(self.q) + list(self.qd)] for r in self.residuals]

    @cached_property
    def dAl_dq(self):
        """∂(Aᵀλ)_i/∂q_j = Σ_k ∂A_ki/∂q_j·λ_k (n×n), λ held fixed."""
        return self._dAl(self.q)

    @cached_property
    def dAl_dp(self):
        """∂(Aᵀλ)_i/∂p_j (n×n_params), λ held fixed."""
        return self._dAl(self.p)

    def _dAl(self, variables):
        """∂(Aᵀλ)_i/∂v_j = Σ_k ∂A_ki/∂v_j·λ_k for v in `variables`, λ held fixed."""
        out = [[se.Integer(0)] * len(variables) for _ in range(self.n)]
        for k, row in enumerate(self.A):
            for i, Aki in enumerate(row):
                if Aki == 0:
                    continue
                for j, v in enumerate(variables):
                    d = diff(Aki, v)
                    if d != 0:
                        out[i][j] += d * self.lam[k]
        return out

    def _Aa(self, k):
        """(A·a)_k with a = q̈ held fixed."""
        return sum((Akj * aj for Akj, aj in zip(self.A[k], self.a) if Akj != 0), se.Integer(0))

    @cached_property
    def G(self):
        """[∂γ/∂q − ∂(A·a)/∂q | ∂γ/∂q̇] (m×2n), a = q̈ held fixed."""
        out = []
        for k, g in enumerate(self.gamma):
            Aa = self._Aa(k)
            out.append([diff(g, qj) - diff(Aa, qj) for qj in self.q]
                       + [diff(g, qdj) for qdj in self.qd])
        return out

    @cached_property
    def G_p(self):
        """∂γ/∂p − ∂(A·a)/∂p (m×n_params), a = q̈ held fixed."""
        return [[diff(g, pj) - diff(self._Aa(k), pj) for pj in self.p]
                for k, g in enumerate(self.gamma)]

    @cached_property
    def _free(self):
        """The free symbols of every F_i and M_ik (a derivative by anything else is 0)."""
        return ([f.free_symbols for f in self.F],
                {(i, k): self.M[i][k].free_symbols for i in range(self.n) for k in range(i + 1)})

    def _gradient(self, f, free, variables):
        """[∂f/∂v for v in variables]; a sum is differentiated by v only in its terms holding v
        (each term once per symbol it has, so a gradient costs about the size of f)."""
        wanted = [v for v in variables if v in free]
        if not wanted:
            return [se.Integer(0)] * len(variables)
        if not isinstance(f, se.Add) or len(wanted) == 1:
            return [diff(f, v) if v in free else se.Integer(0) for v in variables]
        by_symbol = {v: [] for v in wanted}
        for term in f.args:
            for v in term.free_symbols:
                if v in by_symbol:
                    by_symbol[v].append(term)
        return [diff(se.Add(*by_symbol[v]), v) if v in by_symbol else se.Integer(0)
                for v in variables]

    @cached_property
    def dF_dq(self):
        """∂F_i/∂q_j."""
        return [self._gradient(f, free, self.q) for f, free in zip(self.F, self._free[0])]

    @cached_property
    def dF_dqd(self):
        """∂F_i/∂q̇_j."""
        return [self._gradient(f, free, self.qd) for f, free in zip(self.F, self._free[0])]

    @cached_property
    def dF_du(self):
        """∂F_i/∂u_k."""
        return [self._gradient(f, free, self.u) for f, free in zip(self.F, self._free[0])]

    @cached_property
    def dF_dp(self):
        """∂F_i/∂p_j."""
        return [self._gradient(f, free, self.p) for f, free in zip(self.F, self._free[0])]

    @cached_property
    def dMa_dq(self):
        """∂(M·a)_i/∂q_j = Σ_k ∂M_ik/∂q_j · a_k, with a = q̈ held fixed (each M_ik = M_ki once)."""
        return self._dMa(self.q)

    @cached_property
    def dMa_dp(self):
        """∂(M·a)_i/∂p_j = Σ_k ∂M_ik/∂p_j · a_k, with a = q̈ held fixed."""
        return self._dMa(self.p)

    def _dMa(self, variables):
        """∂(M·a)_i/∂v_j for v in `variables`, a held fixed (each M_ik = M_ki differentiated once)."""
        n = self.n
        out = [[se.Integer(0)] * len(variables) for _ in range(n)]
        dM = {}
        for i in range(n):
            for k in range(n):
                if self.M[i][k] == 0:
                    continue
                key = (max(i, k), min(i, k))
                if key not in dM:
                    dM[key] = self._gradient(self.M[i][k], self._free[1][key], variables)
                for j, d in enumerate(dM[key]):
                    if d != 0:
                        out[i][j] += d * self.a[k]
        return out

    @property
    def energies(self):
        """(T, V, Σ Q_j·q̇_j, R) of the whole model (`Collected.energies`)."""
        return self.collected.energies

    @cached_property
    def outputs(self):
        """The output expressions, in `spec.output_names` order: the user's, then T, V, T + V,
        the input power Σ Q_j·q̇_j and the Rayleigh function R. A model with external equations
        (from_sympy) has NaN for those five: its energies are not known to lagrgen."""
        if self.spec.external is not None or self.energies is None:
            return self.outputs_of(None)
        return self.outputs_of(self.energies)

    def outputs_of(self, energies):
        """The user's outputs, then T, V, T + V, power and R of `energies` (None: NaN)."""
        convert = _Converter(self.spec)
        user = [convert(expr) for _, expr in self.spec.outputs]
        if self.spec.external is not None or energies is None:
            return user + [se.nan] * 5
        T, V, power, R = energies
        return user + [T, V, T + V, power, R]

    @cached_property
    def explicit_time(self):
        """True if M or F depends on t explicitly (a rheonomic model: no static equilibrium in
        general, so a linearization holds only at one frozen time)."""
        return any(self.t in e.free_symbols for row in self.M for e in row) or \
            any(self.t in f.free_symbols for f in self.F)

    def differentiate(self, parameters=True):
        """Evaluate (and cache) the Jacobian pieces now (by the parameters too, unless
        `parameters` is False: a model's own module needs none of those); return self."""
        _ = self.dF_dq, self.dF_dqd, self.dMa_dq, self.dF_du
        if self.m:
            _ = self.gamma, self.dAl_dq, self.G
        if parameters:
            _ = self.dF_dp, self.dMa_dp
            if self.m:
                _ = self.dAl_dp, self.G_p
        return self

    @cached_property
    def _to_user(self):
        return {internal: user for user, internal in user_to_internal(self.spec).items()}

    def to_user(self, expr):
        """Return a SymPy expression in the model's own symbols (q(t), q'(t), parameters, u(t))."""
        return sp.sympify(expr).xreplace(self._to_user)

    def user_matrix(self, which):
        """Return M or F (`which`) as a SymPy Matrix in the model's own symbols."""
        rows = self.M if which == "M" else [[f] for f in self.F]
        return sp.Matrix([[self.to_user(e) for e in row] for row in rows])


def user_to_internal(spec):
    """{q_i(t): q[i], dq_i/dt: qd[i], parameter j: p[j], u_k(t): u[k]} as SymPy symbols."""
    pairs = [(spec.qd, "qd"), (spec.coordinates, "q"), (spec.parameters, "p"),
             (spec.inputs, "u")]
    return {user: sp.Symbol(f"{prefix}[{i}]") for users, prefix in pairs
            for i, user in enumerate(users)}


def as_piecewise(expr):
    """`expr` with Heaviside, Min and Max rewritten as Piecewise (H(0) = ½ unless given), the one
    discontinuous form the derivation differentiates (branch by branch) and the printers print."""
    expr = sp.sympify(expr)
    if not expr.has(sp.Heaviside, sp.Min, sp.Max):
        return expr
    return expr.replace(lambda e: isinstance(e, (sp.Heaviside, sp.Min, sp.Max)),
                        lambda e: e.rewrite(sp.Piecewise))


class _Converter:
    """Turns a model's SymPy expressions into SymEngine ones in the internal symbols."""

    def __init__(self, spec):
        self.to_internal = user_to_internal(spec)

    def __call__(self, expr):
        internal = as_piecewise(expr).xreplace(self.to_internal)
        try:
            return se.sympify(internal)
        except Exception as exc:  # SymEngine raises several types for what it cannot read
            raise ModelError(f"cannot convert {expr} for differentiation: {exc}") from None


@once_per
def derived(spec):
    """The `Equations` of the frozen description `spec`, derived once per ModelSpec."""
    return derive(spec)


class Collected:
    """A model's physics after every record added its share (`contributions.Sums`), before the
    kinetic terms of its particles are formed into M and F: what both formulations start from.

    `sums` holds the particles (constant masses at positions, internal symbols), the general
    kinetic energies, V, R and Q; `convert` turns the model's SymPy expressions into internal
    symbols; `energies` are (T, V, Σ Q_j·q̇_j, R) for the outputs.
    """

    def __init__(self, sums, convert):
        self.sums = sums
        self.convert = convert
        self.particles = tuple(sums.particles)

    @cached_property
    def energies(self):
        """(T, V, Σ Q_j·q̇_j, R) for the outputs, the articulations' bodies included (formed on
        first use: `Sums.tree_energies`)."""
        T, V = self.sums.tree_energies()
        sums = self.sums
        return (sums.T + T, sums.V + V, sums.power, sums.R)

    @property
    def energies_beside_articulations(self):
        """(T, V, Σ Q_j·q̇_j, R) without the articulations' bodies (what the recursive
        formulation adds from each body's terms)."""
        sums = self.sums
        return (sums.T, sums.V, sums.power, sums.R)


def collect(spec, symbols):
    """The `Collected` physics of the frozen description `spec` in the internal `symbols`."""
    q, qd, _, _, u, t = symbols
    convert = _Converter(spec)
    sums = Sums(convert, q, qd, t, kinematic=set(q) | set(qd) | set(u) | {t})
    for record in spec.physics:
        if not isinstance(record, ExternalEquations):
            CONTRIBUTIONS[type(record)](record, sums)
    return Collected(sums, convert)


def derive(spec):
    """Return the `Equations` of the frozen description `spec` (a `ModelSpec`): Lagrange's
    equations arranged as M(q,t)·q̈ = F(q,q̇,t,u) (M and F formed on first use)."""
    n = len(spec.coordinates)
    if n == 0:
        raise ModelError(
            f"model {spec.name!r} has no generalized coordinates: declare them with "
            "model.coordinates('q1 q2 ...')")
    symbols = (internal_symbols("q", n), internal_symbols("qd", n), internal_symbols("a", n),
               internal_symbols("p", len(spec.parameters)),
               internal_symbols("u", len(spec.inputs)), se.Symbol("t"))
    q, qd, _, _, _, t = symbols
    collected = collect(spec, symbols)
    convert = collected.convert
    events = [convert(g) for _, g, _, _ in spec.events]
    equations = Equations(spec, collected, symbols, _constraints(spec, convert, q, qd, t), events)
    if spec.external is not None:
        _ = equations.M   # M and F given from outside are checked (symmetric) as they are read
    return equations


def dense_equations(spec, collected):
    """(M, F) of Lagrange's equations from the `Collected` physics: the particles' kinetic terms
    summed as composite bodies, the general kinetic energies differentiated, V, R and Q added."""
    sums, convert = collected.sums, collected.convert
    q, qd, t = sums.q, sums.qd, sums.t
    n = len(q)
    sums.particles = list(collected.particles)
    for deferred in sums.deferred:
        deferred()
    sums.add_particles()
    M, F = sums.M, sums.F
    if sums.general_T:
        add_kinetic_energy(M, F, sum(sums.general_T), q, qd, t)
    V = sums.V + sums.tree_energies()[1]
    for i in range(n):
        F[i] -= diff(V, q[i]) + diff(sums.R, qd[i])
        F[i] += sums.Q[i]

    M = [[M[i][j].expr() if j <= i else None for j in range(n)] for i in range(n)]
    F = [f.expr() for f in F]
    if spec.external is not None:
        M_external, F_external = _external_equations(spec, convert, q)
        M = [[M[i][j] + M_external[i][j] if j <= i else None for j in range(n)]
             for i in range(n)]
        F = [f + g for f, g in zip(F, F_external)]
    for i in range(n):
        for j in range(i + 1, n):
            M[i][j] = M[j][i]
    _check_mass_matrix(spec, M, qd)
    return M, F


def _constraints(spec, convert, q, qd, t):
    """(Φ, c): the holonomic constraints and the velocity-level residuals c = A·q̇ + b of all
    constraints (Φ̇ for the holonomic ones, then the velocity constraints as given)."""
    phi = [convert(e) for e in spec.constraints]
    c = [rate(f, q, qd, t) for f in phi] + [convert(e) for e in spec.velocity_constraints]
    for k, ck in enumerate(c):
        if all(diff(ck, v) == 0 for v in qd):
            label = (f"constraint {k + 1}" if k < len(phi)
                     else f"velocity constraint {k - len(phi) + 1}")
            raise ModelError(f"{label} of model {spec.name!r} does not restrict the velocities "
                             "(its Jacobian row is identically zero): it is not a constraint on "
                             "the motion")
    return phi, c


def _external_equations(spec, convert, q, points=3, seed=0):
    """M (lower triangle, the rest zero) and F of `spec.external` in the internal symbols, after
    checking M is symmetric: entries that differ in form are compared at random points."""
    import random
    M_user, F_user = spec.external
    n = len(q)
    M = [[convert(M_user[i, j]) for j in range(n)] for i in range(n)]
    F = [convert(F_user[i, 0]) for i in range(n)]
    rng = random.Random(seed)
    pairs = [(i, j) for i in range(n) for j in range(i) if M[i][j] != M[j][i]]
    if pairs:
        symbols = sorted(set().union(*(M[i][j].free_symbols | M[j][i].free_symbols
                                       for i, j in pairs)), key=str)
        for _ in range(points):
            values = {s: se.Float(rng.uniform(0.5, 1.5)) for s in symbols}
            for i, j in pairs:
                try:
                    a, b = (complex(M[i][j].subs(values).evalf()),
                            complex(M[j][i].subs(values).evalf()))
                except (TypeError, ValueError, RuntimeError):
                    continue  # not a number at this point (e.g. outside a function's domain)
                if abs(a - b) > 1e-9 * (1.0 + abs(a) + abs(b)):
                    raise ModelError(
                        f"the mass matrix given for model {spec.name!r} is not symmetric: "
                        f"M[{i}][{j}] = {M_user[i, j]} but M[{j}][{i}] = {M_user[j, i]}")
    lower = [[M[i][j] if j <= i else se.Integer(0) for j in range(n)] for i in range(n)]
    return lower, F


def _check_mass_matrix(model, M, qd):
    speeds = set(qd)
    for i, row in enumerate(M):
        if row[i] == 0:
            raise ModelError(
                f"coordinate {model.coordinate_names[i]!r} of model {model.name!r} has no inertia "
                "(its diagonal entry of the mass matrix is zero): give it a mass, an inertia or a "
                "kinetic energy term, or remove the coordinate")
        for e in row:
            if e.free_symbols & speeds:
                raise ModelError(
                    f"the kinetic energy of model {model.name!r} is not quadratic in the velocities "
                    "(the mass matrix ∂²T/∂q̇∂q̇ᵀ depends on them); lagrgen needs T = ½·q̇ᵀM(q,t)q̇ "
                    "+ linear + constant terms")
