"""A pendulum on a cart, with a torsional spring at the hinge and a force along the link.

A cart of mass M moves on a horizontal line (coordinate x). A point mass m hangs from a hinge on
the cart on a massless link of length L; theta is the link's angle from the downward vertical and
a torsional spring of stiffness kt at the hinge pulls it back to theta = 0. Gravity g acts in −y.

Inputs: P, a force at the bob directed along the link, away from the hinge (a tension when
positive: it follows the link as it turns), and Fc, a horizontal force on the cart.

    bob = (x + L·sin θ, −L·cos θ),   e = (sin θ, −cos θ) the unit vector from hinge to bob
    T = ½·M·ẋ² + ½·m·|d bob/dt|²,   V = m·g·y_bob + ½·kt·θ²,   δW = P·e·δbob + Fc·δx
"""
import sympy as sp

from lagrgen import Model

model = Model("cart_pendulum")
x, theta = model.coordinates("x theta")
M, m, L, kt, g = model.parameters(M=2.0, m=0.5, L=0.8, kt=3.0, g=9.81)
P, Fc = model.inputs("P Fc")

hinge = sp.Matrix([x, 0])
link = sp.Matrix([sp.sin(theta), -sp.cos(theta)])
bob = hinge + L * link

model.particle(M, hinge)
model.particle(m, bob)
model.potential_energy(m * g * bob[1])
model.spring(kt, theta)
model.force(P * link, at=bob)
model.force(sp.Matrix([Fc, 0]), at=hinge)
model.line(hinge, bob)
