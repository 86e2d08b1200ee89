"""The unit of a model's energies, read from the unit labels of its coordinates, parameters and
inputs: the dimension of every term of T and V, with each label read by SymPy's SI unit system
(`sympy.physics.units`: "kg", "N/m", "m/s^2", "rad"; "-" for none). When every term that can be
read is an energy and they agree, the energies are labelled "J" (or "<factor> J" for labels such
as g and mm); otherwise they carry no label. Labels stay labels: no number changes.
"""
import functools

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
    try:
        value = sp.parse_expr(label.replace("^", "**"), local_dict=_unit_names())
    except (SyntaxError, TypeError, ValueError, sp.SympifyError, AttributeError):
        return None
    if value.free_symbols - set(_unit_names().values()):
        return None
    return value


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
    if equations.energies is None or spec.external is not None:
        return None
    if any(isinstance(r, Articulation) for r in spec.physics):
        return "J"      # a robot of a URDF file: SI by the format's definition
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
