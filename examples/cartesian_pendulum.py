"""A simple pendulum described in Cartesian coordinates, with the rod as a holonomic constraint.

A point mass m at (x, y) is held at distance L from the pivot at the origin by a massless rod:
Φ = x² + y² − L² = 0. Gravity g acts in −y.

    T = ½·m·(ẋ² + ẏ²),   V = m·g·y,   M·q̈ = F + Φ_qᵀ·λ with Φ_q = [2x, 2y]

The generalized constraint force Φ_qᵀ·λ = 2λ·(x, y) is the rod's pull on the mass, so the rod
tension (positive when pulling) is −2·L·λ = m·(g·cos θ + L·θ̇²) for the angle θ from the
downward vertical. Start from a consistent state, e.g. (L sin θ0, −L cos θ0, 0, 0).
"""
import sympy as sp

from lagrgen import Model

model = Model("cartesian_pendulum")
x, y = model.coordinates("x y")
m, L, g = model.parameters(m=1.0, L=1.0, g=9.81)

bob = sp.Matrix([x, y])
model.particle(m, bob)
model.potential_energy(m * g * y)
model.constraint(x**2 + y**2 - L**2, name="rod")
model.line(sp.Matrix([0, 0]), bob)
