"""A 3-D double pendulum: two rigid links on ball joints, each joint as z-y-x angles.

Link 1 hangs from a ball joint at the origin; link 2 from a ball joint at link 1's lower end.
Each joint's rotation relative to its parent is z(a)·y(b)·x(c) (yaw, pitch, roll), so the links'
orientations are R1 = z(a1)·y(b1)·x(c1) and R2 = R1·z(a2)·y(b2)·x(c2). The links are slender
boxes (principal moments J1, J2 about their centres, body z along the link); gravity g acts in −z.
The sequence is singular where a pitch angle b is ±π/2 (a link's relative swing of 90° about its
body y axis); the hanging motions stay clear of it.

    r1 = R1·(0, 0, −l1/2),   joint = R1·(0, 0, −l1),   r2 = joint + R2·(0, 0, −l2/2)
"""
import sympy as sp

from lagrgen import Model, rotation

model = Model("pendulum3d")
a1, b1, c1, a2, b2, c2 = model.coordinates("a1 b1 c1 a2 b2 c2")
m1, m2, l1, l2, g = model.parameters(m1=1.0, m2=0.8, l1=1.0, l2=0.8, g=9.81)
J1 = (m1 * l1 ** 2 / 12, m1 * l1 ** 2 / 12 * 0.9, m1 * 0.01)      # about the centre, body axes
J2 = (m2 * l2 ** 2 / 12, m2 * l2 ** 2 / 12 * 0.9, m2 * 0.01)

R1 = rotation.sequence("zyx", (a1, b1, c1))
R2 = R1 * rotation.sequence("zyx", (a2, b2, c2))
r1 = R1 * sp.Matrix([0, 0, -l1 / 2])
joint = R1 * sp.Matrix([0, 0, -l1])
r2 = joint + R2 * sp.Matrix([0, 0, -l2 / 2])
model.rigid_body_3d(m1, J1, r1, R1)
model.rigid_body_3d(m2, J2, r2, R2)
model.potential_energy(g * (m1 * r1[2] + m2 * r2[2]))
model.line([0, 0, 0], joint, joint + R2 * sp.Matrix([0, 0, -l2]))
