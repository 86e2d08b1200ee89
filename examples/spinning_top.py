"""A heavy symmetric top spinning on a fixed tip (3-D rigid body, z-x-z Euler angles).

The tip is the fixed origin; the body's symmetry axis is its body z axis, the centre of mass at
distance l along it. The orientation is the classical z-x-z sequence: precession psi about the
vertical, nutation theta (the tilt of the axis), spin phi about the symmetry axis. Gravity g acts
in −z.

    R = z(psi)·x(theta)·z(phi),   r_G = R·(0, 0, l)
    T = ½·m·|ṙ_G|² + ½·ωᵀ·diag(A, A, C)·ω   (ω from ω̃ = Rᵀ·Ṙ, body axes),   V = m·g·z_G

z-x-z is singular at theta = 0 (the axis upright: psi and phi turn about the same line), so start
the top tilted; for a top that stands upright use z(psi)·y(theta)·x(...)-type sequences with the
singular configuration away from the motion.
Try: python -m lagrgen simulate examples/spinning_top.py --t-end 3 --method DOP853 \
         --y0 theta=0.5,psi_dot=0.8,phi_dot=40 --animate top.gif
"""
import sympy as sp

from lagrgen import Model, rotation

model = Model("spinning_top")
psi, theta, phi = model.coordinates("psi theta phi")
m, A, C, l, r, g = model.parameters(m=0.5, A=0.002, C=0.003, l=0.05, r=0.04, g=9.81)

R = rotation.z(psi) * rotation.x(theta) * rotation.z(phi)
com = R * sp.Matrix([0, 0, l])
model.rigid_body_3d(m, [A, A, C], com, R)
model.potential_energy(m * g * com[2])

# what an animation draws: the axis from the tip through the disc, and the disc's rim
model.line([0, 0, 0], R * sp.Matrix([0, 0, 1.6 * l]))
rim = [R * sp.Matrix([r * sp.cos(2 * sp.pi * k / 16), r * sp.sin(2 * sp.pi * k / 16), l])
       for k in range(17)]
model.line(*rim)
model.line(rim[0], com, rim[8])
