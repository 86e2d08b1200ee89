"""A pendulum released from an angle swings into a wall beside its hanging position.

    bob at (L·sin θ, −L·cos θ); wall x >= d:   model.impact("wall", L·sin θ − d, restitution=e)

Every impact reverses the angular rate times e (θ̇⁺ = −e·θ̇⁻); as gravity pulls the bob into the
wall the bounces shorten geometrically and accumulate (a Zeno point), after which the bob rests
against the wall, held there by a contact force ≥ 0.

Run it: python examples/impact_pendulum.py   (writes docs/_static/impact_pendulum.png)
"""
import sympy as sp

from lagrgen import Model

model = Model("impact_pendulum")
theta, = model.coordinates("theta", units="rad")
m, L, g, e, d = model.parameters(m=(1.0, "kg"), L=(1.0, "m"), g=(9.81, "m/s^2"), e=(0.7, "-"),
                                 d=(0.2, "m"))
bob = sp.Matrix([L * sp.sin(theta), -L * sp.cos(theta)])
model.particle(m, bob)
model.potential_energy(m * g * bob[1])
model.impact("wall", bob[0] - d, restitution=e)
model.line([0, 0], bob)
model.line([d, -0.6], [d, -1.2])          # the wall

if __name__ == "__main__":
    import lagrgen
    mod = lagrgen.build(model)
    import numpy as np
    t = np.linspace(0, 8, 4001)
    sol = lagrgen.simulate(mod, (0, 8), {"theta": 0.8}, t_eval=t, rtol=1e-10, atol=1e-12)
    print(f"{len(sol.transitions)} switches; last: {sol.transitions[-1]}; mode {sol.mode}")
    fig = sol.plot(title="pendulum against a wall at x = 0.2 m, e = 0.7")
    fig.savefig("docs/_static/impact_pendulum.png", dpi=90)
    print("plot -> docs/_static/impact_pendulum.png")
