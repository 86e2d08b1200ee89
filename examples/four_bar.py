"""A four-bar linkage driven by a torque on its crank: a closed loop described by three link
angles and two loop-closure constraints.

Ground pivots O = (0, 0) and D = (d, 0). The crank OA (length a, angle th2 from +x), the coupler
AB (length b, angle th3) and the rocker DB (length c, angle th4) are uniform bars of masses
m2, m3, m4 (inertia m·l²/12 about the centre). Gravity g acts in −y; the input torque Tq drives the
crank.

    Φ1 = a·cos th2 + b·cos th3 − c·cos th4 − d = 0      (x of B reached two ways)
    Φ2 = a·sin th2 + b·sin th3 − c·sin th4 = 0          (y of B)

λ1 = B_x, λ2 = B_y (the constraints' names) are the x and y components of the force the rocker exerts on the coupler at the pin B
(Φ_qᵀ·λ is exactly the generalized force of (λ1, λ2) acting at B on the coupler and of
(−λ1, −λ2) acting at B on the rocker): the pin force to size the joint B for.
"""
import sympy as sp

from lagrgen import Model

model = Model("four_bar")
th2, th3, th4 = model.coordinates("th2 th3 th4")
a, b, c, d, m2, m3, m4, g = model.parameters(a=0.1, b=0.3, c=0.25, d=0.3, m2=0.5, m3=1.0,
                                             m4=0.8, g=9.81)
Tq, = model.inputs("Tq")

e = lambda th: sp.Matrix([sp.cos(th), sp.sin(th)])  # noqa: E731
O, D = sp.Matrix([0, 0]), sp.Matrix([d, 0])
A = a * e(th2)
B = A + b * e(th3)
for m, length, start, angle in ((m2, a, O, th2), (m3, b, A, th3), (m4, c, D, th4)):
    centre = start + length / 2 * e(angle)
    model.rigid_body(m, m * length**2 / 12, centre, angle)
    model.potential_energy(m * g * centre[1])
model.torque(Tq, th2)
model.constraint(a * sp.cos(th2) + b * sp.cos(th3) - c * sp.cos(th4) - d, name="B_x")
model.constraint(a * sp.sin(th2) + b * sp.sin(th3) - c * sp.sin(th4), name="B_y")
model.line(O, A, B, D)
