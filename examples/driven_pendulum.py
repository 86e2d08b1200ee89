"""A pendulum hanging from the tip of a crank that turns at a prescribed constant rate (rheonomic).

A crank of length r turns about a fixed pivot at the constant rate Omega: its angle Omega·t from the
+x axis is prescribed, so it is not a coordinate and the equations depend explicitly on t. A point
mass m hangs from the crank tip on a massless link of length L; theta (the coordinate) is the
link's angle from the downward vertical. Gravity g acts in −y.

    tip = r·(cos Ωt, sin Ωt),   bob = tip + L·(sin θ, −cos θ)
    T = ½·m·|d bob/dt|²,   V = m·g·y_bob
"""
import sympy as sp

from lagrgen import Model

model = Model("driven_pendulum")
t = model.t
theta, = model.coordinates("theta")
m, L, r, Omega, g = model.parameters(m=1.0, L=1.0, r=0.2, Omega=3.0, g=9.81)

pivot = sp.Matrix([0, 0])
tip = sp.Matrix([r * sp.cos(Omega * t), r * sp.sin(Omega * t)])
bob = tip + sp.Matrix([L * sp.sin(theta), -L * sp.cos(theta)])

model.particle(m, bob)
model.potential_energy(m * g * bob[1])
model.line(pivot, tip, bob)
