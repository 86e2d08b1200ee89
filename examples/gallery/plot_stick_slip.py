"""
Stick–slip on a moving belt
===========================

A block on a spring lies on a belt moving at v_b = 0.4 m/s (``examples/stick_slip.py``), with
static friction μ_s = 0.5 above kinetic friction μ_k = 0.3. It sticks to the belt until the spring
force reaches μ_s·m·g, at x_s = μ_s·m·g/k; it then slips, oscillating about c = μ_k·m·g/k, and
sticks again where its speed returns to v_b, at 2c − x_s. The phase portrait is a straight stick
segment and an elliptic slip arc, peaking at c + √((x_s − c)² + (v_b/ω)²).
"""
import matplotlib.pyplot as plt
import numpy as np

import lagrgen
from examples.stick_slip import model

mod = lagrgen.build(model)
t = np.linspace(0, 8, 4001)
sol = lagrgen.simulate(mod, (0, 8), {"x": 0.0, "x_dot": 0.4}, t_eval=t, rtol=1e-10, atol=1e-12)
xs, c, w = 0.5 * 9.81 / 20, 0.3 * 9.81 / 20, np.sqrt(20.0)
print(f"peak {sol.q[0].max():.6f} m, closed form {c + np.hypot(xs - c, 0.4 / w):.6f} m")

# %%
# Stick (green) and slip (blue) in the phase plane, and the switches along the time history.
fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
stuck = np.isclose(sol.qd[0], 0.4, atol=1e-9)
a.plot(sol.q[0], sol.qd[0], color="tab:blue", lw=1.2, label="slip")
a.plot(sol.q[0][stuck], sol.qd[0][stuck], ".", color="tab:green", ms=3, label="stick")
for x in (xs, 2 * c - xs):
    a.axvline(x, color="gray", ls=":", lw=0.8)
a.set(xlabel="x [m]", ylabel="x' [m/s]", title="phase portrait")
a.legend(fontsize="small")
b.plot(sol.t, sol.q[0])
for when, _, kind in sol.transitions:
    b.axvline(when, color="tab:green" if kind == "stick" else "tab:gray", ls=":", lw=0.7)
b.set(xlabel="t [s]", ylabel="x [m]", title="time history (dotted: stick / slip)")
fig.tight_layout()
