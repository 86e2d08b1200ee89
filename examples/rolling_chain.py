"""Three masses in a chain on a line; the last one is a disk that rolls without slipping.

    wall ──k1,c1── m1 ──k2,c2── m2 ──k3,c3── (disk m3, radius R)
          f →

Coordinates x1, x2, x3 are the absolute displacements of the two sliding masses and of the disk's
centre; the springs are unstretched at zero. The disk is uniform (moment of inertia ½·m3·R² about
its centre) and rolls on the line without slip, so it turns by the angle −x3/R (clockwise when it
moves to +x) and its kinetic energy is ½·m3·ẋ3² + ½·(½·m3·R²)·(ẋ3/R)² = ¾·m3·ẋ3². The input f is
a force on m1 along the line.

For the pictures only, the bodies are drawn at rest positions 1, 2 and 3 m from the wall (a constant
added to a position changes neither the velocities nor the equations), the disk as a disk that
turns as it rolls, and the springs and dampers between the points they join.
"""
import sympy as sp

from lagrgen import Model

model = Model("rolling_chain")
x1, x2, x3 = model.coordinates("x1 x2 x3")
m1, m2, m3, R = model.parameters(m1=1.0, m2=1.5, m3=2.0, R=0.3)
k1, k2, k3 = model.parameters(k1=100.0, k2=60.0, k3=40.0)
c1, c2, c3 = model.parameters(c1=0.5, c2=0.3, c3=0.2)
f, = model.inputs("f")

# drawing positions: wall at 0, masses at rest 1 and 2 m out, the disk's centre 3 m out at height R
wall, p1, p2, p3 = sp.Matrix([0, 0.1]), sp.Matrix([1 + x1, 0.1]), sp.Matrix([2 + x2, 0.1]), \
    sp.Matrix([3 + x3, R])
low = sp.Matrix([0, -0.1])        # dampers run below the springs
model.particle(m1, p1)
model.particle(m2, p2)
model.rigid_body(m3, m3 * R**2 / 2, p3, angle=-x3 / R, shape=("disk", R))
model.spring(k1, x1, ends=(wall, p1))
model.spring(k2, x2 - x1, ends=(p1, p2))
model.spring(k3, x3 - x2, ends=(p2, p3))
model.damper(c1, x1, ends=(wall + 2 * low, p1 + 2 * low))
model.damper(c2, x2 - x1, ends=(p1 + 2 * low, p2 + 2 * low))
model.damper(c3, x3 - x2, ends=(p2 + 2 * low, p3 - sp.Matrix([0, R + 0.1])))
model.line([0, 0.4], [0, -0.4])               # the wall
model.line([0, 0], [4, 0])                    # the floor the disk rolls on
model.generalized_force(x1, f)
