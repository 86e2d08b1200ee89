"""Planar double pendulum driven by a horizontal force at its tip.

Two point masses m1, m2 hang on massless rigid links of lengths L1, L2 from a fixed pivot, under
gravity g (acting in −y). The coordinates theta1, theta2 are the absolute angles of the links from
the downward vertical. The input F is a horizontal force (along +x) applied at the tip mass.

    pA = L1·(sin θ1, −cos θ1),   pB = pA + L2·(sin θ2, −cos θ2)
    T  = ½·m1·|ṗA|² + ½·m2·|ṗB|²,   V = g·(m1·yA + m2·yB),   δW = F·δxB
"""
import sympy as sp

from lagrgen import Model

model = Model("double_pendulum")
theta1, theta2 = model.coordinates("theta1 theta2")
m1, m2, L1, L2, g = model.parameters(m1=1.0, m2=1.0, L1=1.0, L2=1.0, g=9.81)
F, = model.inputs("F")

origin = sp.Matrix([0, 0])
pA = origin + sp.Matrix([L1 * sp.sin(theta1), -L1 * sp.cos(theta1)])
pB = pA + sp.Matrix([L2 * sp.sin(theta2), -L2 * sp.cos(theta2)])

model.particle(m1, pA)
model.particle(m2, pB)
model.potential_energy(g * (m1 * pA[1] + m2 * pB[1]))
model.force(sp.Matrix([F, 0]), at=pB)
model.line(origin, pA, pB)
