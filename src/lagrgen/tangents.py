"""Forward-mode directional derivatives of CSE'd kernels: the derivatives along k directions of
everything a kernel computes, at about the cost of the kernel per direction.

For a kernel's program (temporaries x_i = e_i(…) in dependency order, then outputs), the tangent
of each temporary along a direction δ is the chain rule on its own expression,

    δx_i = Σ_s ∂e_i/∂s · δs     (s: the inputs and earlier temporaries e_i uses),

so the tangent program mirrors the kernel edge by edge. The coefficients ∂e_i/∂s depend on the point
only, not on the direction: they are computed once (with the kernel itself, CSE'd, into a *tape*
`c`), and each direction then costs one multiply-add per edge (`v` temporaries, linear in the
seeds). This is how `directional_derivatives` forms the k products J·S + ∂f/∂p·P of the forward
sensitivities without forming J.
"""
from dataclasses import dataclass

import symengine as se

from .calculus import diff


@dataclass
class Linearized:
    """A kernel's program split for k directions.

    tape_temporaries : [(symbol, expression)] the kernel's temporaries, then those of the tape
    tape : [expression] the coefficients ∂e_i/∂s, in the tape's order (`c[j]` in `tangents`)
    temporaries : [(symbol v_i, expression)] the tangents, linear in the seeds and `c[j]`
    tangents : {output name: [expression]} the tangents of the kernel's outputs
    """
    tape_temporaries: list
    tape: list
    temporaries: list
    tangents: dict


def tape_symbol(j):
    return se.Symbol(f"c[{j}]")


def linearize(temporaries, outputs, seeds):
    """The forward-mode program of the kernel (`temporaries`, `outputs` {name: [expression]})
    along the seeds {input symbol: its direction symbol} (inputs without a seed are held fixed).

    Returns a `Linearized`; a tangent temporary is named v<i>, a tape temporary x<i> after the
    kernel's own."""
    tangent = dict(seeds)
    slots = {}
    tape = []
    temps = []

    def coefficient(c):
        if isinstance(c, se.Number):
            return c
        j = slots.get(c)
        if j is None:
            j = slots[c] = len(tape)
            tape.append(c)
        return tape_symbol(j)

    def differential(expr):
        terms = []
        for s in sorted(expr.free_symbols, key=str):
            ds = tangent.get(s)
            if ds is not None:
                d = diff(expr, s)
                if d != 0:
                    terms.append(coefficient(d) * ds)
        return se.Add(*terms) if terms else se.Integer(0)

    def named(dx):
        """A tangent as a symbol: itself if it is one (or zero), else a new temporary v<i>."""
        if dx == 0 or isinstance(dx, se.Symbol):
            return dx
        known = named_of.get(dx)
        if known is None:
            known = named_of[dx] = se.Symbol(f"v{len(temps)}")
            temps.append((known, dx))
        return known

    named_of = {}
    for x, e in temporaries:
        dx = differential(e)
        if dx != 0:
            tangent[x] = named(dx)
    tangents = {key: [named(differential(e)) for e in exprs] for key, exprs in outputs.items()}
    return Linearized(list(temporaries) + _tape_temporaries(temporaries, tape),
                      tape, temps, tangents)


def _tape_temporaries(temporaries, tape):
    """CSE over the tape's coefficients (in place), with temporaries named after the kernel's."""
    if not tape:
        return []
    start = 1 + max((int(str(x)[1:]) for x, _ in temporaries), default=-1)
    replacements, reduced = se.cse(tape)
    rename = {old: se.Symbol(f"x{start + i}") for i, (old, _) in enumerate(replacements)}
    tape[:] = [e.xreplace(rename) for e in reduced]
    return [(rename[old], e.xreplace(rename)) for old, e in replacements]
