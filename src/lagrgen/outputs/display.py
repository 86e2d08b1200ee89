"""The equations of motion as a person writes them: Σ_j M_ij·q̈_j = F_i, one line per coordinate.

Coordinates, velocities and accelerations become plain symbols (`theta1`, `theta1'`, `theta1''` in
text; θ₁, θ̇₁, θ̈₁ as `\\theta_{1}`, `\\dot{\\theta}_{1}`, `\\ddot{\\theta}_{1}` in LaTeX), inputs u(t)
become u, and each entry gets a cheap simplification (trigsimp) if it is small enough.
"""
from dataclasses import dataclass

import sympy as sp
from sympy.printing.conventions import split_super_sub

from ..records import Impact

#: trigsimp only entries of at most this many operations, and at most SIMPLIFY_BUDGET in all:
#: trigsimp's time grows fast with size, and big models must still print quickly.
SIMPLIFY_MAX_OPS = 100
SIMPLIFY_BUDGET = 600


@dataclass
class DisplayedEquations:
    """M (n×n), F (n×1) and q̈ (n×1) in display symbols, with `names` mapping symbols to LaTeX."""

    name: str
    M: sp.Matrix
    F: sp.Matrix
    qdd: sp.Matrix
    latex_names: dict

    def rows(self):
        """[([(M_ij, q̈_j) for the nonzero M_ij], F_i)] for each coordinate i."""
        n = self.M.shape[0]
        return [([(self.M[i, j], self.qdd[j]) for j in range(n) if self.M[i, j] != 0], self.F[i])
                for i in range(n)]


def display_symbols(model):
    """{q_i(t): q_i, dq_i/dt: q_i', d²q_i/dt²: q_i'', u_k(t): u_k} and their LaTeX names."""
    rules, latex_names = {}, {}
    for q in model.q:
        name = q.func.__name__
        symbols = [sp.Symbol(name), sp.Symbol(name + "'"), sp.Symbol(name + "''")]
        exprs = [q, q.diff(model.t), q.diff(model.t, 2)]
        for expr, symbol, accent in zip(exprs, symbols, ("", r"\dot", r"\ddot")):
            rules[expr] = symbol
            latex_names[symbol] = accented(name, accent)
    for u in model.input_functions:
        symbol = sp.Symbol(u.func.__name__)
        rules[u] = symbol
        latex_names[symbol] = sp.latex(symbol)
    return rules, latex_names


def accented(name, accent):
    r"""LaTeX of the symbol `name` with `accent` (\dot, \ddot) over its base: \dot{\theta}_{1}."""
    full = sp.latex(sp.Symbol(name))
    if not accent:
        return full
    base = sp.latex(sp.Symbol(split_super_sub(name)[0]))
    if full.startswith(base):
        return f"{accent}{{{base}}}{full[len(base):]}"
    return f"{accent}{{{full}}}"


def tidy(expr, budget):
    """factor_terms(expr), then trigsimp if it has at most SIMPLIFY_MAX_OPS operations and the
    running `budget` (a one-element list of operations still allowed) covers it; never longer."""
    expr = sp.factor_terms(expr, sign=False)
    ops = sp.count_ops(expr)
    if ops > SIMPLIFY_MAX_OPS or ops > budget[0]:
        return expr
    budget[0] -= ops
    simpler = sp.factor_terms(sp.trigsimp(expr), sign=False)
    return simpler if sp.count_ops(simpler) <= ops else expr


def equations(model, simplify=True):
    """The model's M·q̈ = F in display symbols (see `DisplayedEquations`)."""
    rules, latex_names = display_symbols(model)
    M = model.mass_matrix().xreplace(rules)
    F = model.forcing().xreplace(rules)
    if simplify:
        budget = [SIMPLIFY_BUDGET]
        n = M.shape[0]
        for i in range(n):
            for j in range(i + 1):
                M[i, j] = M[j, i] = tidy(M[i, j], budget)
        F = F.applyfunc(lambda e: tidy(e, budget))
    qdd = sp.Matrix([rules[q.diff(model.t, 2)] for q in model.q])
    return DisplayedEquations(model.name, M, F, qdd, latex_names)


def to_text(expr):
    return sp.sstr(expr)


def to_latex(expr, names):
    return sp.latex(expr, symbol_names=names)


def weighted_sum(terms, coefficient, symbol, times):
    """Σ coefficient·symbol written out, parenthesizing sums and folding `+ -` into `-`."""
    parts = []
    for c, x in terms:
        if c == 1:
            parts.append(symbol(x))
            continue
        text = coefficient(c)
        if isinstance(c, sp.Add):
            text = f"({text})" if times == "*" else rf"\left({text}\right)"
        parts.append(f"{text}{times}{symbol(x)}")
    out = parts[0] if parts else "0"
    for part in parts[1:]:
        out += f" - {part[1:]}" if part.startswith("-") else f" + {part}"
    return out


def equation_lines(eqs, latex=False):
    """One string per coordinate: `Σ_j M_ij·q̈_j = F_i` (LaTeX: `... &= ... \\\\` rows)."""
    if latex:
        def tex(e):
            return to_latex(e, eqs.latex_names)
        rows = [f"{weighted_sum(lhs, tex, tex, ' ')} &= {tex(rhs)}" for lhs, rhs in eqs.rows()]
        return [row + (r" \\" if i < len(rows) - 1 else "") for i, row in enumerate(rows)]
    return [f"{weighted_sum(lhs, to_text, to_text, '*')} = {to_text(rhs)}" for lhs, rhs in eqs.rows()]


def matrix_lines(eqs, latex=False):
    """M and F, entry by entry (text) or as LaTeX matrices."""
    if latex:
        return [f"M = {to_latex(eqs.M, eqs.latex_names)}",
                f"F = {to_latex(eqs.F, eqs.latex_names)}"]
    n = eqs.M.shape[0]
    lines = [f"M[{i},{j}] = {to_text(eqs.M[i, j])}" for i in range(n) for j in range(n)]
    return lines + [f"F[{i}] = {to_text(eqs.F[i])}" for i in range(n)]


def render(model, latex=False, matrices=False, simplify=True):
    """The whole display of a model's equations as one string (what `lagrgen show` prints)."""
    eqs = equations(model, simplify=simplify)
    names = ", ".join(model.coordinate_names)
    if latex:
        out = [f"% {model.name}: M(q, t) q'' = F(q, q', t, u) for q = ({names})",
               r"\begin{aligned}", *equation_lines(eqs, latex=True), r"\end{aligned}"]
    else:
        out = [f"# {model.name}: M(q, t) q'' = F(q, q', t, u) for q = ({names})",
               *equation_lines(eqs)]
    out += constraint_lines(model, latex)
    out += nonsmooth_lines(model, latex)
    if matrices:
        out += matrix_lines(eqs, latex)
    units = unit_lines(model)
    if units:
        out.append(("% " if latex else "# ") + units)
    return "\n".join(out)


def unit_lines(model):
    """'units: x [m], theta [rad], m [kg], F [N]' for the names that carry a unit ('' if none)."""
    units = model.units
    names = (list(model.coordinate_names) + list(model.parameter_names) + list(model.input_names)
             + [n for n in model.output_names if n in units])
    labelled = [f"{n} [{units[n]}]" for n in names if units.get(n)]
    return "units: " + ", ".join(labelled) if labelled else ""
def constraint_lines(model, latex=False):
    """The constraints, one line each with its multiplier (nothing without constraints): the
    equations above then read M·q'' = F + Aᵀ·λ, with A·q'' = γ (Baumgarte-stabilized)."""
    holonomic, velocity = model.constraints, model.velocity_constraints
    if not holonomic and not velocity:
        return []
    rules, names = display_symbols(model)
    alpha, beta = model.spec().stabilization
    mark = "%" if latex else "#"
    lines = [f"{mark} constraints, with multipliers lambda: the equations above are M q'' = "
             f"F + A^T lambda, A = d(constraints)/dq' (Baumgarte alpha = {alpha:g}, "
             f"beta = {beta:g})"]
    if latex:
        lines.append(r"\begin{aligned}")
    for k, (expr, name) in enumerate(zip(holonomic + velocity, model.constraint_names)):
        kind = "holonomic" if k < len(holonomic) else "velocity"
        expr = expr.xreplace(rules)
        if latex:
            lines.append(f"&{to_latex(expr, names)} = 0 && \\text{{({kind}, }}\\lambda_{{{k + 1}}}"
                         f"\\text{{: {name.replace('_', ' ')})}} \\\\")
        else:
            lines.append(f"{to_text(expr)} = 0    ({kind}, multiplier {name})")
    if latex:
        lines.append(r"\end{aligned}")
    return lines


def nonsmooth_lines(model, latex=False):
    """The impacts and frictions, one line each (nothing without them): an impact's gap ≥ 0
    and restitution; a friction's slip velocity, normal force and coefficients."""
    records = model.nonsmooth
    if not records:
        return []
    rules, names = display_symbols(model)

    def shown(expr):
        expr = sp.sympify(expr).xreplace(rules)
        if expr.is_number and expr.is_real:
            return f"{float(expr):g}"
        return f"${to_latex(expr, names)}$" if latex else to_text(expr)
    mark = "%" if latex else "#"
    lines = [f"{mark} impacts and frictions (a hybrid solve: lagrgen.hybrid)"]
    for record in records:
        if isinstance(record, Impact):
            lines.append(f"{mark} impact {record.name}: {shown(record.gap)} >= 0, restitution "
                         f"{shown(record.restitution)}")
            continue
        normal = (f"the multiplier of {record.normal_force}"
                  if isinstance(record.normal_force, str) else shown(record.normal_force))
        static = "" if record.mu_static == record.mu else \
            f", mu_static = {shown(record.mu_static)}"
        lines.append(f"{mark} friction {record.name}: slip velocity {shown(record.slip_velocity)}, "
                     f"normal force {normal}, mu = {shown(record.mu)}{static}")
    return lines


def latex_block(model, simplify=True):
    """The equations of motion as one display-math LaTeX block, `$$\\begin{aligned} ... $$`, the
    rows of `render(model, latex=True)` (a notebook's rendering of a Model)."""
    rows = equation_lines(equations(model, simplify=simplify), latex=True)
    return "$$\\begin{aligned}\n" + "\n".join(rows) + "\n\\end{aligned}$$"
