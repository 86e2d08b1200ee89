"""Checking what a user declares: names, units, vectors, and every expression (its symbols,
functions, derivatives and numbers) against what the model declares. Beside the records
(`lagrgen.records`): a record holds only checked expressions."""
import cmath
import random

import sympy as sp
from sympy.core.function import AppliedUndef

from .errors import ModelError
from .names import check_name
from .numbers import fits_a_double

#: SymPy functions that have a C99 equivalent and that the symbolic core can differentiate.
SUPPORTED_FUNCTIONS = (
    sp.sin, sp.cos, sp.tan, sp.asin, sp.acos, sp.atan, sp.atan2,
    sp.sinh, sp.cosh, sp.tanh, sp.asinh, sp.acosh, sp.atanh,
    sp.exp, sp.log, sp.Abs, sp.sign,
    # discontinuous: rewritten as Piecewise before differentiation (lagrgen.lagrange)
    sp.Heaviside, sp.Min, sp.Max, sp.Piecewise,
)


def split_names(names, what):
    """Return a list of names from a space/comma-separated string or an iterable of strings."""
    if isinstance(names, str):
        names = names.replace(",", " ").split()
    else:
        names = list(names)
    if not names:
        raise ModelError(f"no {what} names given")
    return [check_name(n, what) for n in names]


def split_units(units, names, what):
    """{name: unit} from a space-separated string or an iterable of unit strings, one per name
    (None: no units). A unit is a label only; "-" or "" means dimensionless."""
    if units is None:
        return {}
    units = units.split() if isinstance(units, str) else list(units)
    if len(units) != len(names):
        raise ModelError(f"{len(names)} {what} name(s) {' '.join(names)} but {len(units)} unit(s) "
                         f"{units!r}: give one unit per name")
    out = {}
    for name, unit in zip(names, units):
        out[name] = check_unit(unit, f"{what} {name!r}")
    return out


def check_unit(unit, where):
    """`unit` if it is a string without whitespace or control characters, else ModelError."""
    if not isinstance(unit, str) or any(c.isspace() or not c.isprintable() for c in unit):
        raise ModelError(f"unit of {where} must be a string without spaces, got {unit!r}")
    return unit


def as_vector(value, what):
    """Return `value` (scalar, list, tuple, 1-D array or Matrix) as a SymPy column Matrix of 1 to
    3 entries."""
    if isinstance(value, sp.MatrixBase):
        vec = sp.Matrix(value).reshape(len(value), 1)
    elif isinstance(value, (list, tuple)) or getattr(value, "ndim", None) == 1:
        vec = sp.Matrix([sp.sympify(v) for v in value])
    else:
        vec = sp.Matrix([sp.sympify(value)])
    if not 1 <= len(vec) <= 3:
        raise ModelError(f"{what} must have 1 to 3 components, got {len(vec)}")
    return vec



#: The kinds of atoms `check_expression` inspects, gathered in one traversal of an expression.
_CHECKED_ATOMS = (sp.Derivative, AppliedUndef, sp.Function, sp.Number, sp.Piecewise,
                  sp.core.numbers.ComplexInfinity, sp.core.numbers.ImaginaryUnit)


def _checked(scope, velocities, inputs):
    """The subexpressions `scope` has already found valid under these flags (declarations only
    grow, so what was valid stays valid): a chain's positions share their parents' terms, and a
    drawn line repeats the particles' positions."""
    cache = scope.__dict__.setdefault("_checked_subtrees", {})
    return cache.setdefault((velocities, inputs), set())


def _declared(scope):
    """(parameters, coordinates, inputs) of `scope` as sets, kept while their counts hold."""
    key = (len(scope.parameter_symbols), len(scope.q), len(scope.input_functions))
    cached = scope.__dict__.get("_declared_sets")
    if cached is None or cached[0] != key:
        cached = (key, (frozenset(scope.parameter_symbols), frozenset(scope.q),
                        frozenset(scope.input_functions)))
        scope.__dict__["_declared_sets"] = cached
    return cached[1]


def _scan(expr, checked):
    """(free symbols, {kind: atoms of it}, and "subtrees": every subexpression visited) of
    `expr`, in one traversal that skips the subtrees in `checked`."""
    symbols, kinds, seen = set(), {kind: [] for kind in _CHECKED_ATOMS}, set()
    stack = [expr]
    while stack:
        e = stack.pop()
        if e in seen or e in checked:
            continue
        seen.add(e)
        if e.is_Symbol:
            symbols.add(e)
            continue
        for kind in _CHECKED_ATOMS:
            if isinstance(e, kind):
                kinds[kind].append(e)
        stack.extend(e.args)
    kinds["subtrees"] = seen
    return symbols, kinds


def check_expression(scope, expr, where, velocities=True, inputs=True, vector=False):
    """Return `expr` sympified, after checking every symbol and function in it is one `scope` (a
    `Description`: its name, t, parameters, coordinates and inputs) declares.

    A scalar is expected unless `vector`; a 1×1 matrix counts as its entry."""
    try:
        expr = sp.sympify(expr)
    except (sp.SympifyError, TypeError) as exc:
        raise ModelError(f"{where}: cannot read {expr!r} as a SymPy expression ({exc})") from None
    if isinstance(expr, sp.MatrixBase):
        if vector:
            for e in expr:
                check_expression(scope, e, where, velocities, inputs)
            return expr
        if expr.shape != (1, 1):
            raise ModelError(f"{where} must be a scalar expression, got a {expr.shape[0]}×"
                             f"{expr.shape[1]} matrix")
        expr = expr[0, 0]
    if not isinstance(expr, sp.Expr):
        kind = "a relation (an equation or inequality)" if isinstance(
            expr, (sp.Rel, sp.logic.boolalg.Boolean)) else f"a {type(expr).__name__}"
        raise ModelError(f"{where}: {expr} is {kind}, not an expression; write the quantity "
                         "itself (for a switch use Piecewise, Heaviside or sign)")
    checked = _checked(scope, velocities, inputs)
    if expr in checked:
        return expr
    symbols, kinds = _scan(expr, checked)
    parameters, coordinates, inputs_ = _declared(scope)
    for s in symbols - parameters - {scope.t}:
        twin = next((p for p in scope.parameter_symbols if p.name == s.name), None)
        if twin is not None or s.name == "t":
            raise ModelError(
                f"{where}: symbol {s} is not the {'parameter' if twin else 'time'} {s.name} of "
                f"model {scope.name!r}, only a symbol of the same name with other assumptions "
                f"({s.assumptions0 or 'none'}); use the symbol "
                f"{'model.parameters' if twin else 'model.t'} returned")
        raise ModelError(
            f"{where}: symbol {s} is neither a coordinate, a parameter, an input nor t; "
            f"declare it with model.parameters({s}=...) or model.inputs('{s}')")
    for d in kinds[sp.Derivative]:
        if d.expr not in coordinates or d.variables != (scope.t,):
            raise ModelError(
                f"{where}: {d} is not allowed; only first time derivatives of coordinates "
                "(velocities) may appear")
        if not velocities:
            raise ModelError(f"{where}: must not depend on velocities, but contains {d}")
    for f in kinds[AppliedUndef]:
        if f in coordinates:
            continue
        if f in inputs_:
            if not inputs:
                raise ModelError(
                    f"{where}: must not depend on input {f.func.__name__} (its time derivative "
                    "is not known); use t for a prescribed motion")
            continue
        raise ModelError(
            f"{where}: {f} is neither a coordinate nor an input of model {scope.name!r}; "
            "coordinates and inputs must be functions of model.t declared on this model")
    for f in kinds[sp.Function]:
        if not isinstance(f, AppliedUndef) and not isinstance(f, SUPPORTED_FUNCTIONS):
            names = ", ".join(fn.__name__ for fn in SUPPORTED_FUNCTIONS)
            raise ModelError(f"{where}: function {f.func.__name__} is not supported (use {names})")
    if kinds[sp.core.numbers.ComplexInfinity] or any(
            n in (sp.oo, -sp.oo) or n is sp.nan for n in kinds[sp.Number]):
        raise ModelError(f"{where}: expression {expr} contains an infinity or NaN")
    if kinds[sp.core.numbers.ImaginaryUnit]:
        raise ModelError(f"{where}: expression {expr} is complex (it contains I): every quantity "
                         "of a model is a real number")
    for piecewise in kinds[sp.Piecewise]:
        if piecewise.args[-1].cond is not sp.true:
            raise ModelError(
                f"{where}: {piecewise} has no branch for when no condition holds (it would be "
                "NaN there); end it with an otherwise branch (value, True), e.g. "
                "Piecewise((f, x > 0), (0, True))")
    for number in kinds[sp.Number]:
        if not fits_a_double(number):
            raise ModelError(
                f"{where}: the number {sp.N(number, 6)} does not fit a double (|x| up to "
                "1.8e308): rescale the model's units or parameters")
    checked.update(kinds.pop("subtrees"))
    return expr


# -- impacts and friction (Model.impact, Model.friction) ---------------------------------------
def check_restitution(e, name):
    """`e`, a number in [0, 1] or an expression of parameters."""
    if e.is_number and not 0.0 <= float(e) <= 1.0:
        raise ModelError(f"impact {name!r}: restitution must be between 0 and 1, got {float(e)}")
    return e


def ratio_varies(a, b, t, samples=2):
    """True when a/b takes two values at random states (numbers put for its coordinates and t,
    the parameters held at one set of numbers): it depends on the state, as the gaps of a
    robot's feet on different surfaces do; False when it does not or cannot be told
    numerically."""
    rng = random.Random(20261206)
    key = dict(key=str)
    moving = sorted(a.atoms(AppliedUndef) | b.atoms(AppliedUndef) | {t}, **key)
    fixed = {s: sp.Float(rng.uniform(0.3, 1.3))
             for s in sorted((a.free_symbols | b.free_symbols) - {t}, **key)}
    values = []
    for _ in range(samples):
        at = {**fixed, **{u: sp.Float(rng.uniform(0.3, 1.3)) for u in moving}}
        try:
            ratio = complex(sp.N(a.xreplace(at))) / complex(sp.N(b.xreplace(at)))
        except (TypeError, ValueError, ZeroDivisionError):
            return False
        if not cmath.isfinite(ratio):
            return False
        values.append(ratio)
    return any(abs(v - values[0]) > 1e-9 * (1 + abs(values[0])) for v in values[1:])


def check_distinct_gap(name, gap, impacts, coordinates, t):
    """ModelError when `gap` is a constant multiple of another impact's gap: two contacts on one
    surface (a positive multiple) or on its two sides (a negative one) make the contact
    equations singular once both are closed."""
    for other in impacts:
        if ratio_varies(gap, other.gap, t):
            continue
        try:
            ratio = sp.cancel(gap / other.gap)
        except (TypeError, ValueError, ZeroDivisionError):
            continue
        if ratio.has(t, sp.zoo, sp.nan) or any(ratio.has(c) for c in coordinates):
            continue
        side = "the same surface" if ratio.is_positive else (
            "the two sides of one surface" if ratio.is_negative else "one surface")
        raise ModelError(f"impact {name!r}: its gap {gap} is {ratio} times the gap of impact "
                         f"{other.name!r}, so both contacts lie on {side} (duplicate contacts "
                         "make the contact equations singular): declare the contact once, or "
                         "use model.constraint for a body held on both sides")


def check_affine_in_velocities(expr, qd, where):
    """`expr`, which must be w(q, t)·q̇ + b(q, t) with w not identically zero."""
    present = expr.atoms(sp.Derivative)
    coefficients = [sp.diff(expr, v) if v in present else sp.Integer(0) for v in qd]
    for v, c in zip(qd, coefficients):
        if any(c.has(w) for w in qd):
            raise ModelError(f"{where}: the slip velocity {expr} is not linear in the velocities "
                             f"(its coefficient of {v} is {c}); write it as w(q, t)·q̇ + b(q, t)")
    if all(c == 0 for c in coefficients):
        raise ModelError(f"{where}: the slip velocity {expr} involves no velocity of a coordinate")
    return expr


def check_static_coefficient(mu, mu_s, where):
    """`mu_s`, which must be at least `mu` when both are numbers."""
    if mu.is_number and mu_s.is_number and not float(mu_s) >= float(mu):
        raise ModelError(f"{where}: mu_static ({float(mu_s):g}) must be at least mu "
                         f"({float(mu):g}): the static friction coefficient is never below the "
                         "kinetic one")
    return mu_s


def check_coefficient(value, where, what):
    """`value`, a friction coefficient: a number ≥ 0 or an expression of parameters."""
    if value.is_number and not float(value) >= 0:
        raise ModelError(f"{where}: {what} must be ≥ 0, got {value}")
    return value
