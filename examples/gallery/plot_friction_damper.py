"""
The hysteresis loop of a friction damper
========================================

A structure (mass M on a spring k, forced at 8 rad/s) is tied through a spring k_t to a light pad
pressed on a rough surface with normal force N (``examples/friction_damper.py``). While the pad
sticks, the force on the structure grows with slope k_t; once it reaches μ·N the pad slips and the
force stays at ±μ·N. The loop's area is the energy the damper takes out per cycle.
"""
import matplotlib.pyplot as plt
import numpy as np

import lagrgen
from examples.friction_damper import model

mod = lagrgen.build(model)
t = np.linspace(0, 12, 6001)
sol = lagrgen.simulate(mod, (0, 12), [0, 0, 0, 0], t_eval=t, rtol=1e-10, atol=1e-12)
force = lagrgen.evaluate_outputs(mod, sol)["damper_force"]
late = t > 6
cycles = 6 * 8 / (2 * np.pi)
print(f"{len(sol.transitions)} stick/slip switches; "
      f"{abs(np.trapezoid(force[late], sol.q[0][late])) / cycles:.4f} J dissipated per cycle")

# %%
fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
a.plot(sol.q[0][late], force[late], color="tab:red")
for level in (2.0, -2.0):
    a.axhline(level, color="gray", ls=":", lw=0.8)                 # ±μ·N
a.set(xlabel="structure displacement x [m]", ylabel="damper force [N]",
      title="hysteresis loop (steady state)")
b.plot(t, sol.q[0], label="x (structure)")
b.plot(t, sol.q[1], label="z (pad)")
b.set(xlabel="t [s]", ylabel="[m]", title="structure and pad")
b.legend(fontsize="small")
fig.tight_layout()
