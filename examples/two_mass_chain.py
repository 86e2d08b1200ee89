"""One physical system in two sets of coordinates: two masses in a chain fixed to a wall.

    wall ──k1,c1── m1 ──k2,c2── m2 ← f

Masses m1, m2 slide without friction on a line; spring k1 and damper c1 join the wall to m1, spring
k2 and damper c2 join m1 to m2; the input f is a force on m2 along the line. All springs are
unstretched when the displacements are zero.

- "two_mass_absolute": coordinates x1, x2, the absolute displacements of m1 and m2.
- "two_mass_relative": coordinates x1 and s = x2 − x1, the stretch of the second spring.

Both models have the same parameters (names, order and defaults) and the same input, so a motion
computed with one can be checked against the other.

For the pictures only, the masses are drawn at their rest positions 1 m and 2 m from the wall
(`particle(m1, [1 + x1])`: a constant added to a position changes no velocity and no equation),
with the springs above and the dampers below the line.
"""
import sympy as sp

from lagrgen import Model

DEFAULTS = dict(m1=1.0, m2=0.5, k1=40.0, k2=25.0, c1=0.4, c2=0.2)


def _draw(model, m1, m2, k1, k2, c1, c2, x1, x2):
    """The masses (drawn at rest 1 m and 2 m from the wall), springs and dampers of both models."""
    wall, p1, p2 = sp.Matrix([0, 0]), sp.Matrix([1 + x1, 0]), sp.Matrix([2 + x2, 0])
    up, down = sp.Matrix([0, 0.12]), sp.Matrix([0, -0.12])
    model.particle(m1, p1)
    model.particle(m2, p2)
    model.spring(k1, x1, ends=(wall + up, p1 + up))
    model.spring(k2, x2 - x1, ends=(p1 + up, p2 + up))
    model.damper(c1, x1, ends=(wall + down, p1 + down))
    model.damper(c2, x2 - x1, ends=(p1 + down, p2 + down))
    model.line(wall + 2 * up, wall + 2 * down)


def _absolute():
    model = Model("two_mass_absolute")
    x1, x2 = model.coordinates("x1 x2")
    m1, m2, k1, k2, c1, c2 = model.parameters(**DEFAULTS)
    f, = model.inputs("f")
    _draw(model, m1, m2, k1, k2, c1, c2, x1, x2)
    model.force(f, at=x2)
    return model


def _relative():
    model = Model("two_mass_relative")
    x1, s = model.coordinates(["x1", "s"])
    m1, m2, k1, k2, c1, c2 = model.parameters(**DEFAULTS)
    f, = model.inputs("f")
    x2 = x1 + s
    _draw(model, m1, m2, k1, k2, c1, c2, x1, x2)
    model.force(f, at=x2)
    return model


absolute = _absolute()
relative = _relative()
