"""A pendulum that swings against a one-sided stop (a stiff contact spring).

The stop is a wall at x = d to the right of the pivot; while the bob presses into it (penetration
δ = L·sin θ − d > 0) a contact spring of stiffness kc pushes back: V_c = ½·kc·max(0, δ)².
Max makes the force switch on and off at δ = 0; the output "gap" = d − L·sin θ is the switching
surface, usable as an event (`lagrgen.output_event(mod, "gap")`) to land the solver on the contact.

Run it: python examples/contact_stop.py   (writes contact_stop.gif)
"""
import sympy as sp

from lagrgen import Model

model = Model("contact_stop")
theta, = model.coordinates("theta", units="rad")
m, L, g, kc, d = model.parameters(m=(1.0, "kg"), L=(1.0, "m"), g=(9.81, "m/s^2"),
                                  kc=(5e3, "N/m"), d=(0.3, "m"))
bob = sp.Matrix([L * sp.sin(theta), -L * sp.cos(theta)])
model.particle(m, bob)
model.potential_energy(m * g * bob[1])
model.potential_energy(kc * sp.Max(0, bob[0] - d) ** 2 / 2)
model.line([0, 0], bob)
model.line([d, 0.2], [d, -1.2])          # the wall
model.output("gap", d - bob[0], units="m")
model.output("contact_force", kc * sp.Max(0, bob[0] - d), units="N")

if __name__ == "__main__":
    import numpy as np

    import lagrgen
    from lagrgen.outputs.plotting import animate
    mod = lagrgen.build(model, backend="python")
    hit = lagrgen.output_event(mod, "gap", direction=-1)
    sol = lagrgen.simulate(mod, (0, 4), [-0.8, 0.0], events=[hit], rtol=1e-9, atol=1e-11,
                           dense_output=True)
    print("contacts begin at t =", np.round(sol.t_events[0], 4))
    animate(model, sol, "contact_stop.gif")
