"""A slider-crank with a flywheel: crank angle th, connecting-rod angle phi and slider position x,
tied by two holonomic constraints; a gas force P pushes the piston.

The crank (radius r, with a flywheel of inertia J on its shaft) turns about the origin; the
connecting rod (length l, mass mr, uniform) joins the crank pin to the piston (mass mp) that
slides along the x axis. phi is the rod's angle below the axis, so

    crank pin = r·(cos th, sin th),   piston = (x, 0)
    Φ1 = r·cos th + l·cos phi − x = 0,   Φ2 = r·sin th − l·sin phi = 0

The input P is a force on the piston along −x (a gas force on the power stroke when positive), the
input Tl a load torque on the crank. No gravity (a horizontal engine). λ = (pin_x, pin_y) is the
force the rod receives from the piston pin: the piston presses on its guide with −pin_y.
"""
import sympy as sp

from lagrgen import Model

model = Model("slider_crank")
th, phi, x = model.coordinates("th phi x")
r, l, J, mr, mp, c = model.parameters(r=0.05, l=0.2, J=0.02, mr=0.3, mp=0.4, c=0.001)
P, Tl = model.inputs("P Tl")

pin = r * sp.Matrix([sp.cos(th), sp.sin(th)])
piston = sp.Matrix([x, 0])
rod_centre = (pin + piston) / 2
model.kinetic_energy(J * th.diff(model.t)**2 / 2)
model.rigid_body(mr, mr * l**2 / 12, rod_centre, -phi)
model.particle(mp, piston)
model.dissipation(c * th.diff(model.t)**2 / 2)
model.force(sp.Matrix([-P, 0]), at=piston)
model.torque(-Tl, th)
model.constraint(r * sp.cos(th) + l * sp.cos(phi) - x, name="pin_x")
model.constraint(r * sp.sin(th) - l * sp.sin(phi), name="pin_y")
model.line(sp.Matrix([0, 0]), pin, piston)
