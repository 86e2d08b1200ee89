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
import math

import sympy as sp

from lagrgen import Model

DEFAULTS = dict(r=0.05, l=0.2, J=0.02, mr=0.3, mp=0.4, c=0.001)

model = Model("slider_crank")
th, phi, x = model.coordinates("th phi x")
r, l, J, mr, mp, c = model.parameters(**DEFAULTS)
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


def turning_start(th0=math.pi / 3, th_dot0=2 * math.pi, r=DEFAULTS["r"], l=DEFAULTS["l"]):
    """(q, qd) of the crank at angle th0 turning at th_dot0 (one turn a second), with phi, x and
    their rates from the two constraints and their time derivatives."""
    phi0 = math.asin(r * math.sin(th0) / l)
    phi_dot0 = r * math.cos(th0) * th_dot0 / (l * math.cos(phi0))
    q = {"th": th0, "phi": phi0, "x": r * math.cos(th0) + l * math.cos(phi0)}
    qd = {"th": th_dot0, "phi": phi_dot0,
          "x": -r * math.sin(th0) * th_dot0 - l * math.sin(phi0) * phi_dot0}
    return q, qd


model.initial_state(*turning_start())       # the flywheel turning: `simulate --animate` shows it
