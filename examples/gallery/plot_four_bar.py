"""
The pin force of a four-bar linkage
===================================

A crank–coupler–rocker linkage (``examples/four_bar.py``) in three angles closed by two loop
constraints, named ``B_x`` and ``B_y``: their multipliers are the force the rocker exerts on the
coupler at the pin B. A constant torque drives the crank; the reaction at B follows from the
simulation, and the loop stays closed to the solver's tolerance.
"""
import matplotlib.pyplot as plt
import numpy as np

import lagrgen
from examples.four_bar import model

mod = lagrgen.build(model)
y0 = lagrgen.consistent_state(mod, [1.0, 0.4, 1.6, 0.0, 0.0, 0.0])   # th2, th3, th4 and rates
sol = lagrgen.simulate(mod, (0.0, 2.0), y0, method="Radau", inputs={"Tq": 0.3},
                       t_eval=np.linspace(0.0, 2.0, 401), rtol=1e-9, atol=1e-11)
print("largest loop residual:", np.abs(sol.constraint_residuals).max())

# %%
fx, fy = sol.multipliers["B_x"], sol.multipliers["B_y"]
fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
ax1.plot(sol.t, np.unwrap(sol.q[0]), label="crank th2 [rad]")
ax1.legend(fontsize="small")
ax2.plot(sol.t, fx, label="B_x [N]")
ax2.plot(sol.t, fy, label="B_y [N]")
ax2.plot(sol.t, np.hypot(fx, fy), "k--", label="|B| [N]")
ax2.set_xlabel("t [s]")
ax2.legend(fontsize="small")
fig.tight_layout()
