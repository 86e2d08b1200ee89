"""A double pendulum in Cartesian coordinates: two point masses, two rods as constraints.

Mass m1 at (x1, y1) hangs from the origin on a rod of length L1, mass m2 at (x2, y2) from m1 on a
rod of length L2; gravity g acts in −y. The angle form is examples/double_pendulum.py (with equal
masses and lengths).

    Φ1 = x1² + y1² − L1² = 0,   Φ2 = (x2 − x1)² + (y2 − y1)² − L2² = 0
    T = ½·m1·|ṙ1|² + ½·m2·|ṙ2|²,   V = m1·g·y1 + m2·g·y2

The rod tensions are −2·L1·λ1 and −2·L2·λ2 (positive when pulling).
"""
import sympy as sp

from lagrgen import Model

model = Model("cartesian_double_pendulum")
x1, y1, x2, y2 = model.coordinates("x1 y1 x2 y2")
m1, m2, L1, L2, g = model.parameters(m1=1.0, m2=1.0, L1=1.0, L2=1.0, g=9.81)

r1, r2 = sp.Matrix([x1, y1]), sp.Matrix([x2, y2])
model.particle(m1, r1)
model.particle(m2, r2)
model.potential_energy(m1 * g * y1 + m2 * g * y2)
model.constraint(x1**2 + y1**2 - L1**2, name="rod1")
model.constraint((x2 - x1)**2 + (y2 - y1)**2 - L2**2, name="rod2")
model.line(sp.Matrix([0, 0]), r1, r2)
