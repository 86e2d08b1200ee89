"""The Chaplygin sleigh: a rigid body on a plane with a knife edge that cannot slide sideways,
a nonholonomic (velocity) constraint.

The body has mass m and inertia I about its centre of mass G = (x, y); its heading is theta. The
knife edge touches the plane at P = G − a·(cos θ, sin θ), behind the centre of mass, and P's
velocity has no component across the blade:

    −sin θ·ẋ_P + cos θ·ẏ_P = 0   ⇔   −sin θ·ẋ + cos θ·ẏ − a·θ̇ = 0

No forces act besides the constraint, which does no work, so T = ½·m·(ẋ² + ẏ²) + ½·I·θ̇² is
conserved. λ ("blade") is the sideways force of the blade on the body, along (−sin θ, cos θ).
"""
import sympy as sp

from lagrgen import Model

model = Model("chaplygin_sleigh")
x, y, theta = model.coordinates("x y theta")
m, I, a = model.parameters(m=1.0, I=0.2, a=0.5)
t = model.t

model.rigid_body(m, I, sp.Matrix([x, y]), theta)
model.velocity_constraint(-sp.sin(theta) * x.diff(t) + sp.cos(theta) * y.diff(t)
                          - a * theta.diff(t), name="blade")
heading = sp.Matrix([sp.cos(theta), sp.sin(theta)])
model.line(sp.Matrix([x, y]) - a * heading, sp.Matrix([x, y]) + a * heading)
