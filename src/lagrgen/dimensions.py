"""The unit of a model's energies, read from the unit labels of its coordinates, parameters and
inputs: the dimension of every term of T and V, with each label read as a product of powers of
the units of SymPy's SI unit system (`sympy.physics.units`: "kg", "N/m", "m/s^2", "rad"; "-" for
none). When every term that can be read is an energy and they agree, the energies are labelled
"J" (or "<factor> J" for labels such as g and mm); otherwise they carry no label. Labels stay
labels: no number changes.

A label is inert text: it is read by a grammar of its own (`read_unit`), never evaluated, and a
label that grammar cannot read is "no unit".
"""
import functools
import re

import sympy as sp

from .records import Articulation

#: The outputs labelled with the energy unit.
ENERGIES = ("kinetic_energy", "potential_energy", "total_energy")


@functools.lru_cache(maxsize=1)
def _unit_names():
    import sympy.physics.units as units
    return {name: value for name, value in vars(units).items()
            if isinstance(value, units.Quantity)}


@functools.lru_cache(maxsize=256)
def unit_quantity(label):
    """A unit label as a SymPy expression of SI quantities (1 for none), or None if unread."""
    if label is None or label.strip() in ("", "-", "1"):
        return sp.Integer(1)
    return read_unit(label)


#: The tokens of a unit label: a number, a name, ** or one of * / ^ ( ) + -.
_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)"
                    r"|([A-Za-z_][A-Za-z_0-9]*)|(\*\*|[*/^()+-]))")
#: Bounds on what a label may ask for: its length, its nesting and its exponents (a label such as
#: "10^(10^10)" would otherwise have SymPy compute a number of ten billion digits).
MAX_LABEL, MAX_DEPTH, MAX_EXPONENT = 200, 10, 12


class _Unread(Exception):
    """The label is not a unit `read_unit` can read."""


def read_unit(label):
    """The unit label `label` as a SymPy product of powers of SI quantities, or None when it is
    not one. The grammar, with the names of `sympy.physics.units` and decimal numbers:

        unit     := factor (("*" | "/") factor)*
        factor   := atom (("^" | "**") exponent)?
        atom     := NAME | NUMBER | "(" unit ")"
        exponent := ("+" | "-")? (NUMBER | "(" ("+" | "-")? unit ")")
                                                a rational of magnitude and denominator ≤ 12

    Nothing is evaluated: a label is tokenized and read by this grammar alone."""
    if not isinstance(label, str) or len(label) > MAX_LABEL:
        return None
    try:
        tokens = _tokens(label)
        value, rest = _product(tokens, 0)
    except (_Unread, ValueError, TypeError, ZeroDivisionError):
        return None
    if rest or value == 0 or not value.is_finite:
        return None
    return value


def _tokens(label):
    """The tokens of `label` (numbers as SymPy rationals, names as quantities); _Unread when a
    character starts no token or a name is no unit."""
    out, position, label = [], 0, label.rstrip()
    while position < len(label):
        match = _TOKEN.match(label, position)
        if match is None:
            raise _Unread(label)
        number, name, operator = match.groups()
        if number is not None:
            out.append(sp.Rational(number))
        elif name is not None:
            if name not in _unit_names():
                raise _Unread(name)
            out.append(_unit_names()[name])
        else:
            out.append(operator)
        position = match.end()
    return out


def _product(tokens, depth):
    """(the product of the factors at the start of `tokens`, the tokens left)."""
    value, tokens = _factor(tokens, depth)
    while tokens and tokens[0] in ("*", "/"):
        operator, (right, tokens) = tokens[0], _factor(tokens[1:], depth)
        value = value * right if operator == "*" else value / right
    return value, tokens


def _factor(tokens, depth):
    """(an atom raised to its exponent, if any, the tokens left)."""
    base, tokens = _atom(tokens, depth)
    if tokens and tokens[0] in ("^", "**"):
        exponent, tokens = _exponent(tokens[1:], depth)
        base = base ** exponent
    return base, tokens


def _exponent(tokens, depth):
    """(a signed rational exponent of magnitude at most MAX_EXPONENT, the tokens left)."""
    sign, tokens = _sign(tokens)
    if tokens and tokens[0] == "(":
        value, tokens = _parenthesized(tokens[1:], depth, signed=True)
    else:
        value, tokens = _atom(tokens, depth)
    if not (isinstance(value, sp.Rational) and abs(value) <= MAX_EXPONENT
            and value.q <= MAX_EXPONENT):
        raise _Unread(value)
    return sign * value, tokens


def _sign(tokens):
    """(−1 or 1, the tokens after a leading "-" or "+")."""
    if tokens and tokens[0] in ("+", "-"):
        return (-1 if tokens[0] == "-" else 1), tokens[1:]
    return 1, tokens


def _atom(tokens, depth):
    """(a number, a quantity or a parenthesized unit, the tokens left)."""
    if not tokens:
        raise _Unread("end of label")
    first, tokens = tokens[0], tokens[1:]
    if first == "(":
        return _parenthesized(tokens, depth, signed=False)
    if isinstance(first, str):
        raise _Unread(first)
    return first, tokens


def _parenthesized(tokens, depth, signed):
    """(the unit after an opening parenthesis, with a leading sign when `signed`, the tokens after
    its closing one)."""
    if depth >= MAX_DEPTH:
        raise _Unread("nesting")
    sign, tokens = _sign(tokens) if signed else (1, tokens)
    value, tokens = _product(tokens, depth + 1)
    if not tokens or tokens[0] != ")":
        raise _Unread("unbalanced parenthesis")
    return sign * value, tokens[1:]


def _dimension(expr, units):
    """The unit expression of `expr` (SymPy, internal symbols) given `units` {symbol: unit},
    or None where a factor has no readable unit. Functions (sin, exp, ...) are dimensionless."""
    if expr.is_Symbol:
        return units.get(expr)
    if expr.is_Number:
        return sp.Integer(1)
    if expr.is_Add:
        known = [d for d in (_dimension(a, units) for a in expr.args) if d is not None]
        return known[0] if known else None
    if expr.is_Mul:
        out = sp.Integer(1)
        for factor in expr.args:
            d = _dimension(factor, units)
            if d is None:
                return None
            out *= d
        return out
    if expr.is_Pow:
        base = _dimension(expr.base, units)
        return None if base is None or not expr.exp.is_Number else base ** expr.exp
    if isinstance(expr, (sp.Abs, sp.Piecewise)) and expr.args:
        first = expr.args[0][0] if isinstance(expr, sp.Piecewise) else expr.args[0]
        return _dimension(first, units)
    return sp.Integer(1)


@functools.lru_cache(maxsize=None)
def _si(unit):
    """(dimension dependencies, scale to SI) of a unit expression (once per expression: the terms
    of T and V share a few)."""
    import sympy.physics.units as u
    from sympy.physics.units.systems.si import SI, dimsys_SI
    dims = dimsys_SI.get_dimensional_dependencies(SI.get_dimensional_expr(unit))
    base = u.convert_to(unit, [u.kilogram, u.meter, u.second, u.ampere, u.kelvin, u.mole,
                               u.candela])
    scale = base.as_coeff_Mul()[0] if not base.is_Number else base
    return {str(k.name): v for k, v in dims.items()}, float(scale)


def energy_units(equations):
    """{energy output: its label} for `equations`, or {} when the labels give no energy unit."""
    unit = energy_unit(equations)
    return dict.fromkeys(ENERGIES, unit) if unit else {}


def energy_unit(equations):
    """The label of the energies of `equations` (`lagrgen.lagrange.Equations`), or None."""
    spec = equations.spec
    if spec.external is not None:
        return None
    if any(isinstance(r, Articulation) for r in spec.physics):
        return "J"      # a robot of a URDF file: SI by the format's definition
    if equations.energies is None:
        return None
    labels = dict(spec.units)
    names = spec.coordinate_names + spec.parameter_names + spec.input_names
    if all(unit_quantity(labels.get(name)) in (None, 1) for name in names):
        return None     # no label with a dimension (or none at all): no term is an energy
    import sympy.physics.units as u
    units = {sp.Symbol(str(equations.t)): u.second}
    for q, qd, name in zip(equations.q, equations.qd, spec.coordinate_names):
        unit = unit_quantity(labels.get(name))
        if unit is not None:
            units[sp.Symbol(str(q))], units[sp.Symbol(str(qd))] = unit, unit / u.second
    for symbols, names in ((equations.p, spec.parameter_names), (equations.u, spec.input_names)):
        for symbol, name in zip(symbols, names):
            unit = unit_quantity(labels.get(name))
            if unit is not None:
                units[sp.Symbol(str(symbol))] = unit
    labelled = {str(symbol) for symbol in units}
    found = set()
    for term in _terms(equations.energies[:2]):
        symbols = {str(symbol) for symbol in term.free_symbols}
        if symbols and symbols <= labelled:
            dims, scale = _si(_dimension(sp.sympify(term), units))
            found.add((tuple(sorted(dims.items())), scale))
    if len(found) != 1:
        return None
    dims, scale = found.pop()
    if dict(dims) != _si(u.joule)[0]:
        return None
    return "J" if scale == 1 else f"{scale:g} J"


def _terms(energies):
    """The terms of the expanded `energies`, expanded by SymEngine (SymPy's expand of a large
    model's T takes seconds to minutes)."""
    import symengine as se
    for energy in energies:
        expanded = se.expand(se.sympify(energy))
        yield from expanded.args if isinstance(expanded, se.Add) else (expanded,)
