"""Differentiation in the internal symbols of the derivation (SymEngine): the derivative with the
rules SymEngine lacks, and the total time derivative of an expression of q and t."""
import symengine as se

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


def rate(expr, q, qd, t):
    """d expr/dt = Σ ∂expr/∂q_j·q̇_j + ∂expr/∂t for an expression of q and t (internal symbols);
    a sum is differentiated by each variable in its terms holding it only (a chain's positions are
    long sums, each term of one coordinate)."""
    free = expr.free_symbols
    rates = {qj: qdj for qj, qdj in zip(q, qd) if qj in free}
    if t in free:
        rates[t] = se.Integer(1)
    if not rates:
        return se.Integer(0)
    terms = expr.args if isinstance(expr, se.Add) and len(rates) > 1 else (expr,)
    holding = {v: [] for v in rates}
    for term in terms:
        for v in term.free_symbols & rates.keys():
            holding[v].append(term)
    return sum((diff(se.Add(*holding[v]), v) * r for v, r in rates.items()), se.Integer(0))
