"""Bring a double pendulum on a cart upright in the least time: opty's gallery problem "Upright a
Double Pendulum", solved by collocation.

A cart (mass m1) moves along x under a force F, |F| ≤ 50 N, within |x| ≤ 5 m; two rods of length
lx hinge on it in a chain, each a body of mass m at its far end with moment of inertia iZZ about
that end; q2 and q3 are the rods' absolute angles from the x axis, so −π/2 hangs and π/2 stands.
From hanging at rest to upright at rest — accelerations zero too — in the least time T. The
optimal force is bang-bang with a singular arc, on which a pure minimum-time objective lets the
force chatter from point to point; a tiny effort term (10⁻⁴·∫F² dt) keeps it smooth at a cost of
about 10⁻⁴ s.

`python -m lagrgen optimize examples/cart_double_pendulum_upright.py --animate upright.gif`
solves it; `python examples/cart_double_pendulum_upright.py` also draws
docs/_static/collocation_cart_upright.png and docs/_static/collocation_cart_upright.gif.
"""
import numpy as np
import sympy as sp

import lagrgen

model = lagrgen.Model("cart_double_pendulum")
q1, q2, q3 = model.coordinates("q1 q2 q3", units="m rad rad")
lx, m1, m2, m3, g, iZZ1, iZZ2 = model.parameters(lx=2.0, m1=1.0, m2=1.0, m3=1.0, g=9.81,
                                                 iZZ1=2.0, iZZ2=2.0)
F, = model.inputs("F", units="N")
cart = sp.Matrix([q1, 0])
elbow = cart + lx * sp.Matrix([sp.cos(q2), sp.sin(q2)])
tip = elbow + lx * sp.Matrix([sp.cos(q3), sp.sin(q3)])
model.particle(m1, cart)
model.rigid_body(m2, iZZ1, elbow, q2)
model.rigid_body(m3, iZZ2, tip, q3)
model.potential_energy(m2 * g * elbow[1] + m3 * g * tip[1])
model.force(sp.Matrix([F, 0]), at=cart)
model.line(cart, elbow, tip)

mod = lagrgen.build(model)
problem = lagrgen.Collocation(mod, nodes=151, duration=(1.0, 10.0), scheme="hermite-simpson")
problem.bound("F", -50.0, 50.0)
problem.bound("q1", -5.0, 5.0)
problem.initial(q=[0.0, -np.pi / 2, -np.pi / 2], qd=[0.0, 0.0, 0.0])
problem.final(q={"q2": np.pi / 2, "q3": np.pi / 2}, qd=[0.0, 0.0, 0.0], qdd=[0.0, 0.0, 0.0])
problem.minimize(time=True, integral=1e-4 * F ** 2)
guess = {"F": 50.0, "duration": 3.0}

if __name__ == "__main__":
    from pathlib import Path
    result = problem.solve(guess=guess)
    docs = Path(__file__).resolve().parent.parent / "docs"
    result.plot(docs / "_static" / "collocation_cart_upright.png",
                title=f"Upright in the least time: T = {result.duration:.4f} s")
    result.animate(docs / "_static" / "collocation_cart_upright.gif", fps=15, max_frames=60,
                   dpi=60)
