"""A thin disk rolling without slipping on a horizontal plane, built with SymPy's KanesMethod.

Coordinates: the heading (yaw) and the lean of the disk's plane; speeds: the disk's angular
velocity in the lean frame L (w_lean about the lean axis, spin about the axle, w_up about the
disk's diameter through the contact point). The spin angle and the contact point's position are
ignorable and left out, as SymPy's own rolling-disc example does: the spin is then a speed that
is no coordinate's rate, and `lagrgen.from_sympy` gives it the ignorable coordinate `int_spin`.
Kane's equations follow from the contact point's velocity being zero (rolling).

Rolling upright at speed v = r·spin, the disk is stable for v² > g·r/3 (thin uniform disk) and
falls over below: try

    python -m lagrgen stability examples/rolling_disk.py --sweep v=0.2:3:57 \\
        --qd0 int_spin=v/r --plot rolling_disk_root_locus.png
"""
import sympy as sp
import sympy.physics.mechanics as me

import lagrgen


def rolling_disk_kane():
    """The KanesMethod of the rolling disk (equations formed)."""
    yaw, lean = me.dynamicsymbols("yaw lean")
    w_lean, spin, w_up = me.dynamicsymbols("w_lean spin w_up")
    r, m, g = sp.symbols("r m g", positive=True)
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [yaw, N.z])
    L = Y.orientnew("L", "Axis", [lean, Y.x])
    disk = L.orientnew("D", "Axis", [0, L.y])   # the spin angle is ignorable: not a coordinate
    disk.set_ang_vel(N, w_lean * L.x + spin * L.y + w_up * L.z)
    contact = me.Point("C")
    contact.set_vel(N, 0)
    centre = contact.locatenew("G", r * L.z)
    centre.v2pt_theory(contact, N, disk)
    # the angular velocity of the lean frame, in the coordinates' rates, is that of the disk
    # about L.x and L.z: the two kinematic differential equations
    rates = L.ang_vel_in(N)
    kd = [w_lean - me.dot(rates, L.x), w_up - me.dot(rates, L.z)]
    body = me.RigidBody("disk", centre, disk, m,
                        (me.inertia(L, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4), centre))
    km = me.KanesMethod(N, q_ind=[yaw, lean], u_ind=[w_lean, spin, w_up], kd_eqs=kd)
    km.kanes_equations([body], [(centre, -m * g * Y.z)])
    return km


model = lagrgen.from_sympy(rolling_disk_kane(), "rolling_disk",
                           defaults={"r": 0.3, "m": 2.0, "g": 9.81})

# what animations draw: the rim (the contact point, whose position is ignorable, at the origin)
# and a spoke turning with the spin angle int_spin
_yaw, _lean, _spin = model.q
_r = model.parameter_symbols[0]
_x = sp.Matrix([sp.cos(_yaw), sp.sin(_yaw), 0])                       # the lean axis L.x
_z = sp.Matrix([sp.sin(_lean) * sp.sin(_yaw), -sp.sin(_lean) * sp.cos(_yaw), sp.cos(_lean)])
_centre = _r * _z
model.line(*[_centre + _r * (sp.cos(a) * _x + sp.sin(a) * _z)
             for a in [2 * sp.pi * k / 24 for k in range(25)]])
model.line(_centre, _centre + _r * (sp.cos(_spin) * _x - sp.sin(_spin) * _z))
