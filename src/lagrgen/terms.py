"""The term-collection pass of the derivation: sums of M and F kept as expanded terms and regrouped
by structure when read (masses summed once per kinematic product, parameter sums factored,
sin² + cos² folded). See `Terms`."""
import symengine as se


class Terms:
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

    def add(self, expr, weight=1, plain=True):
        """Add weight·expr (to the plain sum too unless `plain` is False: see `record`)."""
        if plain:
            self.plain.append(expr * weight)
        expr = se.expand(expr)
        if expr == 0:
            return
        for term in (expr.args if isinstance(expr, se.Add) else (expr,)):
            coeff, rest = _numeric_part(term)
            key = rest
            self.terms[key] = self.terms.get(key, 0) + coeff * weight

    def record(self, expr):
        """Add expr to the plain sum only: the form of terms added with plain=False."""
        self.plain.append(expr)

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


def expanded_terms(expr):
    """[(number, rest)] of the terms of expr expanded."""
    expr = se.expand(expr)
    if expr == 0:
        return []
    return [_numeric_part(term) for term in (expr.args if isinstance(expr, se.Add) else (expr,))]


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
    """Σ coeff·term of `terms` ({term: coeff}), regrouped (see `Terms`)."""
    by_kin = {}
    for term, coeff in terms.items():
        if coeff == 0:
            continue
        kin, par = _split_kinematic(term, kinematic)
        by_kin.setdefault(kin, []).append(coeff * par)
    by_par = {}
    for kin, pars in by_kin.items():
        if len(pars) == 1 and isinstance(pars[0], se.Mul) and any(
                isinstance(f, se.Add) for f in pars[0].args):
            # one product of a composite body's summed masses and parameters: already grouped
            # (its sums expanded, short, so that cancelling weights give 0)
            par = se.Mul(*(se.expand(f) if isinstance(f, se.Add) else f for f in pars[0].args))
            if par == 0:
                continue
            c, rest = _numeric_part(par)
            kinsum = by_par.setdefault(rest, {})
            kinsum[kin] = kinsum.get(kin, 0) + c
            continue
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
