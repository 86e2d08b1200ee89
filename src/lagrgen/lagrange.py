"""Lagrange's equations, arranged as M(q, t)·q̈ = F(q, q̇, t, u), and the pieces of their Jacobian.

The derivation runs in SymEngine on internal symbols `q[i]`, `qd[i]`, `a[i]` (= q̈_i), `p[j]`, `u[k]`
and `t`; SymPy stays the language of model files and of what `Model.mass_matrix()` returns.
"""
from functools import cached_property

import symengine as se
import sympy as sp

from .errors import ModelError


def internal_symbols(prefix, count):
    """Return the SymEngine symbols prefix[0] .. prefix[count-1]."""
    return tuple(se.Symbol(f"{prefix}[{i}]") for i in range(count))


def diff(expr, var):
    """Return ∂expr/∂var, with |g|' = sign(g)·g' and sign' = 0 (SymEngine leaves both unevaluated)."""
    d = se.diff(expr, var)
    pending = d.atoms(se.Derivative, se.Subs)
    if not pending:
        return d
    fixes = {}
    for node in pending:
        inner = node.args[0]
        if isinstance(node, se.Subs):
            inner = inner.args[0]
            if isinstance(inner, se.sign):
                fixes[node] = se.Integer(0)
            elif isinstance(inner, se.Abs):
                fixes[node] = se.sign(node.args[2])
            else:
                raise ModelError(f"cannot differentiate {expr} with respect to {var}")
        elif isinstance(inner, se.Abs):
            fixes[node] = se.sign(inner.args[0]) * diff(inner.args[0], node.args[1])
        elif isinstance(inner, se.sign):
            fixes[node] = se.Integer(0)
        elif not any(isinstance(n, se.Subs) for n in pending):
            raise ModelError(f"cannot differentiate {inner} with respect to {node.args[1]}")
    return d.subs(fixes)


class Equations:
    """M(q,t)·q̈ = F(q,q̇,t,u) for one model, with the Jacobian pieces ∂F/∂q, ∂F/∂q̇, ∂(M·a)/∂q.

    Matrices are lists of lists of SymEngine expressions in the internal symbols.

    With constraints (n_holonomic Φ(q,t) = 0 first, then the velocity constraints, m in all) the
    equations are M·q̈ = F + Aᵀ·λ and A·q̈ = γ, where A = [Φ_q; A_v] (m×n), c = A·q̇ + b the
    velocity-level residuals (c_i = Φ̇_i for the holonomic rows) and, with Baumgarte's α, β,

        γ = −(∂c/∂q·q̇ + ∂c/∂t) − 2α·c − β²·[Φ; 0],

    i.e. ċ + 2α·c + β²·Φ = 0. λ lives in the kernel argument `a` after q̈: λ_k = a[n + k].
    """

    def __init__(self, spec, M, F, symbols, constraints=None, events=()):
        self.spec = spec
        self.events = list(events)
        self.n = len(F)
        self.M = M
        self.F = F
        self.q, self.qd, self.a, self.p, self.u, self.t = symbols
        phi, c = constraints or ([], [])
        self.n_holonomic = len(phi)
        self.m = len(c)
        self.Phi = phi
        self.c = c
        self.lam = internal_symbols("a", self.n + self.m)[self.n:]

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
    def dAl_dq(self):
        """∂(Aᵀλ)_i/∂q_j = Σ_k ∂A_ki/∂q_j·λ_k (n×n), λ held fixed."""
        n = self.n
        out = [[se.Integer(0)] * n for _ in range(n)]
        for k, row in enumerate(self.A):
            for i, Aki in enumerate(row):
                if Aki == 0:
                    continue
                for j, qj in enumerate(self.q):
                    d = diff(Aki, qj)
                    if d != 0:
                        out[i][j] += d * self.lam[k]
        return out

    @cached_property
    def G(self):
        """[∂γ/∂q − ∂(A·a)/∂q | ∂γ/∂q̇] (m×2n), a = q̈ held fixed."""
        out = []
        for k, g in enumerate(self.gamma):
            Aa = sum((Akj * aj for Akj, aj in zip(self.A[k], self.a) if Akj != 0), se.Integer(0))
            out.append([diff(g, qj) - diff(Aa, qj) for qj in self.q]
                       + [diff(g, qdj) for qdj in self.qd])
        return out

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
    def dMa_dq(self):
        """∂(M·a)_i/∂q_j = Σ_k ∂M_ik/∂q_j · a_k, with a = q̈ held fixed (each M_ik = M_ki once)."""
        n = self.n
        out = [[se.Integer(0)] * n for _ in range(n)]
        dM = {}
        for i in range(n):
            for k in range(n):
                if self.M[i][k] == 0:
                    continue
                key = (max(i, k), min(i, k))
                if key not in dM:
                    dM[key] = self._gradient(self.M[i][k], self._free[1][key], self.q)
                for j, d in enumerate(dM[key]):
                    if d != 0:
                        out[i][j] += d * self.a[k]
        return out

    @cached_property
    def outputs(self):
        """The output expressions, in `spec.output_names` order: the user's, then T, V, T + V,
        the input power Σ Q_j·q̇_j and the Rayleigh function R."""
        return output_expressions(self.spec, self.q, self.qd, self.t)

    @cached_property
    def explicit_time(self):
        """True if M or F depends on t explicitly (a rheonomic model: no static equilibrium in
        general, so a linearization holds only at one frozen time)."""
        return any(self.t in e.free_symbols for row in self.M for e in row) or \
            any(self.t in f.free_symbols for f in self.F)

    def differentiate(self):
        """Evaluate (and cache) every Jacobian piece now; return self."""
        _ = self.dF_dq, self.dF_dqd, self.dMa_dq, self.dF_du
        if self.m:
            _ = self.gamma, self.dAl_dq, self.G
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


def _add_particle(M, F, mass, position, q, qd, t):
    """Add a point mass: M += m·JᵀJ, F −= m·Jᵀ·b, with J = ∂r/∂q and b = r̈ at q̈ = 0.

    The kinematic products (Σ_c J_ci·J_cj, Σ_c J_ci·b_c) are expanded and added term by term into
    the `_Terms` accumulators M[i][j], F[i] with the mass as their weight, so that bodies sharing a
    kinematic product end up with one product times the sum of their masses (see `_Terms.expr`).
    """
    n = len(q)
    J = [[diff(rc, qi) if qi in free else se.Integer(0) for qi in q]
         for rc, free in ((rc, rc.free_symbols) for rc in position)]
    v = [sum((Jc[i] * qd[i] for i in range(n) if Jc[i] != 0), diff(rc, t))
         for Jc, rc in zip(J, position)]
    b = [rate(vc, q, qd, t) for vc in v]
    active = [i for i in range(n) if any(Jc[i] != 0 for Jc in J)]
    for i in active:
        for j in active:
            if j <= i:
                M[i][j].add(sum(Jc[i] * Jc[j] for Jc in J), mass)
        F[i].add(sum(Jc[i] * bc for Jc, bc in zip(J, b)), -mass)


class _Terms:
    """A sum Σ weight·expr kept as expanded terms, collected by structure when it is read.

    `expr()` returns the same sum regrouped: terms are split into a kinematic part (the factors
    that depend on q, q̇, a, t or u) and a parameter part; parameter parts of equal kinematic parts
    are added (Σ m_k once per product), kinematic parts with equal parameter sums are added next
    (sin²x·X + cos²x·X = X applied there), and common factors are taken out of both sums.
    """

    def __init__(self, kinematic):
        self.kinematic = kinematic
        self.terms = {}      # term without its numeric factor -> coefficient (number or expr)
        self.plain = []      # the weighted expressions as added, for comparison

    def add(self, expr, weight=1):
        self.plain.append(expr * weight)
        expr = se.expand(expr)
        if expr == 0:
            return
        for term in (expr.args if isinstance(expr, se.Add) else (expr,)):
            coeff, rest = _numeric_part(term)
            key = rest
            self.terms[key] = self.terms.get(key, 0) + coeff * weight

    def __iadd__(self, expr):
        self.add(expr)
        return self

    def __isub__(self, expr):
        self.add(expr, -1)
        return self

    def __eq__(self, other):
        return self.expr() == other

    def __ne__(self, other):
        return not self.__eq__(other)

    def expr(self):
        """The sum, regrouped; the plain sum instead if regrouping made it longer."""
        structured = _structured(self.terms, self.kinematic)
        plain = se.Add(*self.plain)
        return structured if se.count_ops(structured) <= se.count_ops(plain) else plain


def _numeric_part(term):
    """(number, rest) with term = number·rest."""
    if isinstance(term, se.Number):
        return term, se.Integer(1)
    if isinstance(term, se.Mul):
        args = term.args
        if isinstance(args[0], se.Number):
            return args[0], se.Mul(*args[1:])
    return se.Integer(1), term


def _split_kinematic(term, kinematic):
    """(kinematic part, parameter part) of a product."""
    kin, par = [], []
    for f in (term.args if isinstance(term, se.Mul) else (term,)):
        (kin if f.free_symbols & kinematic else par).append(f)
    return se.Mul(*kin), se.Mul(*par)


def _factor_out(terms):
    """(common, [term / common]) for a list of products: the factors every term shares, each at its
    lowest (positive integer) power."""
    def powers(term):
        out = {}
        for f in (term.args if isinstance(term, se.Mul) else (term,)):
            if isinstance(f, se.Number):
                continue
            base, exp = (f.args[0], f.args[1]) if isinstance(f, se.Pow) else (f, se.Integer(1))
            if isinstance(exp, se.Integer) and int(exp) > 0:
                out[base] = int(exp)
        return out
    if len(terms) == 1:
        return terms[0], [se.Integer(1)]
    common = powers(terms[0])
    for term in terms[1:]:
        if not common:
            break
        p = powers(term)
        common = {b: min(e, p[b]) for b, e in common.items() if b in p}
    if not common:
        return se.Integer(1), terms
    factor = se.Mul(*(b ** e for b, e in common.items()))
    return factor, [t / factor for t in terms]


def _pythagoras(kinsum):
    """{term: coeff} with every c·X·sin²x + c·X·cos²x replaced by c·X."""
    changed = True
    while changed:
        changed = False
        for term in list(kinsum):
            if term not in kinsum:
                continue
            for f in (term.args if isinstance(term, se.Mul) else (term,)):
                if isinstance(f, se.Pow) and f.args[1] == 2 and isinstance(f.args[0], se.sin):
                    x = f.args[0].args[0]
                    partner = term / f * se.cos(x) ** 2
                    if partner in kinsum and kinsum[partner] == kinsum[term]:
                        c = kinsum.pop(term)
                        kinsum.pop(partner)
                        rest = term / f
                        kinsum[rest] = kinsum.get(rest, 0) + c
                        if kinsum[rest] == 0:
                            del kinsum[rest]
                        changed = True
                        break
    return kinsum


def _add_terms(coeffs):
    """Σ coeff·term of a {term: coeff} dict."""
    return se.Add(*(c * t for t, c in coeffs.items()))


def _structured(terms, kinematic):
    """Σ coeff·term of `terms` ({term: coeff}), regrouped (see `_Terms`)."""
    by_kin = {}
    for term, coeff in terms.items():
        if coeff == 0:
            continue
        kin, par = _split_kinematic(term, kinematic)
        by_kin.setdefault(kin, []).append(coeff * par)
    by_par = {}
    for kin, pars in by_kin.items():
        psum = se.expand(se.Add(*pars))
        if psum == 0:
            continue
        c, rest = _numeric_part(psum)
        if isinstance(psum, se.Add):
            numeric = [_numeric_part(a) for a in psum.args]
            c = numeric[0][0]
            common, rests = _factor_out([r for _, r in numeric])
            rest = common * se.Add(*(cc / c * r for (cc, _), r in zip(numeric, rests)))
        kinsum = by_par.setdefault(rest, {})
        kinsum[kin] = kinsum.get(kin, 0) + c
    out = []
    for par, kinsum in by_par.items():
        kinsum = _pythagoras({k: v for k, v in kinsum.items() if v != 0})
        if not kinsum:
            continue
        items = list(kinsum.items())
        common, rests = _factor_out([k for k, _ in items])
        out.append(par * common * se.Add(*(c * r for (_, c), r in zip(items, rests))))
    return se.Add(*out)


def _add_rotation(M, F, inertia, omega, q, qd, t):
    """Add T = ½·ωᵀ·I·ω of a 3-D body, ω = W·q̇ + w₀ in body axes (I constant): M += Wᵀ·I·W,
    F −= Wᵀ·(I·b + ω × I·ω), with b = ω̇ at q̈ = 0 (Euler's equations projected on the q̇_j)."""
    from .bodies3d import add_rotation
    add_rotation(M, F, inertia, omega, q, qd, t, diff)


def _add_kinetic_energy(M, F, T, q, qd, t):
    """Add a general T: M += ∂²T/∂q̇∂q̇ᵀ, F += ∂T/∂q − (∂²T/∂q̇∂qᵀ)·q̇ − ∂²T/∂q̇∂t."""
    n = len(q)
    dT_dqd = [diff(T, s) for s in qd]
    for i in range(n):
        for j in range(i + 1):
            M[i][j] += diff(dT_dqd[i], qd[j])
        F[i] += diff(T, q[i]) - sum(diff(dT_dqd[i], q[j]) * qd[j] for j in range(n)) \
            - diff(dT_dqd[i], t)


def rate(expr, q, qd, t):
    """d expr/dt = Σ ∂expr/∂q_j·q̇_j + ∂expr/∂t for an expression of q and t (internal symbols)."""
    free = expr.free_symbols
    return sum((diff(expr, qj) * qdj for qj, qdj in zip(q, qd) if qj in free),
               diff(expr, t) if t in free else se.Integer(0))


def output_expressions(spec, q, qd, t):
    """[user outputs..., T, V, T + V, Σ Q_j·q̇_j, R] in the internal symbols (see `Model.output`);
    T includes ½·ωᵀ·I·ω of 3-D bodies. A model with external equations (from_sympy) has NaN for
    the five automatic outputs: its energies are not known to lagrgen."""
    convert = _Converter(spec)
    T = sum((convert(e) for e in spec.kinetic), se.Integer(0))
    for mass, position in spec.particles:
        v = [rate(convert(c), q, qd, t) for c in position]
        T += convert(mass) * sum(vc * vc for vc in v) / 2
    for inertia, omega in spec.bodies_3d:
        I = [[convert(e) for e in row] for row in inertia.tolist()]
        w = [convert(e) for e in omega]
        T += sum(w[i] * I[i][j] * w[j] for i in range(3) for j in range(3)) / 2
    V = sum((convert(e) for e in spec.potential), se.Integer(0))
    R = sum((convert(e) for e in spec.dissipation), se.Integer(0))
    for c, length in spec.dampers:
        R += convert(c) * rate(convert(length), q, qd, t) ** 2 / 2
    power = se.Integer(0)
    for vector, position in spec.virtual_work:
        f = [convert(c) for c in vector]
        r = [convert(c) for c in position]
        for i in range(len(q)):
            power += sum(fc * diff(rc, q[i]) for fc, rc in zip(f, r)) * qd[i]
    user = [convert(expr) for _, expr in spec.outputs]
    if spec.external is not None:
        # equations derived elsewhere (lagrgen.from_sympy) carry no energies: NaN, not a wrong 0
        return user + [se.nan] * 5
    return user + [T, V, T + V, power, R]


def derive(spec):
    """Return the `Equations` of the frozen description `spec` (a `ModelSpec`): Lagrange's
    equations arranged as M(q,t)·q̈ = F(q,q̇,t,u)."""
    n = len(spec.coordinates)
    if n == 0:
        raise ModelError(
            f"model {spec.name!r} has no generalized coordinates: declare them with "
            "model.coordinates('q1 q2 ...')")
    symbols = (internal_symbols("q", n), internal_symbols("qd", n), internal_symbols("a", n),
               internal_symbols("p", len(spec.parameters)),
               internal_symbols("u", len(spec.inputs)), se.Symbol("t"))
    q, qd, _, _, _, t = symbols
    convert = _Converter(spec)
    kinematic = set(q) | set(qd) | set(symbols[4]) | {t}
    M = [[_Terms(kinematic) for _ in range(n)] for _ in range(n)]
    F = [_Terms(kinematic) for _ in range(n)]

    general_T = [convert(e) for e in spec.kinetic]
    for mass, position in spec.particles:
        m = convert(mass)
        r = [convert(c) for c in position]
        if m.free_symbols & (set(q) | {t}):
            v = [rate(rc, q, qd, t) for rc in r]
            general_T.append(m * sum(vc * vc for vc in v) / 2)
        else:
            _add_particle(M, F, m, r, q, qd, t)
    for inertia, omega in spec.bodies_3d:
        _add_rotation(M, F, [[convert(e) for e in row] for row in inertia.tolist()],
                      [convert(e) for e in omega], q, qd, t)
    if general_T:
        _add_kinetic_energy(M, F, sum(general_T), q, qd, t)
    V = sum((convert(e) for e in spec.potential), se.Integer(0))
    R = sum((convert(e) for e in spec.dissipation), se.Integer(0))
    for c, length in spec.dampers:
        R += convert(c) * rate(convert(length), q, qd, t) ** 2 / 2
    for i in range(n):
        F[i] -= diff(V, q[i]) + diff(R, qd[i])
    for vector, position in spec.virtual_work:
        f = [convert(c) for c in vector]
        r = [convert(c) for c in position]
        for i in range(n):
            F[i] += sum(fc * diff(rc, q[i]) for fc, rc in zip(f, r))

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
    events = [convert(g) for _, g, _, _ in spec.events]
    return Equations(spec, M, F, symbols, _constraints(spec, convert, q, qd, t), events)


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
