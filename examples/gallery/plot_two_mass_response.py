"""
Modes and frequency response of a two-mass chain
================================================

Two masses in a chain fixed to a wall, wall ─k1,c1─ m1 ─k2,c2─ m2 ← f
(``examples/two_mass_chain.py``). The linearization about the equilibrium gives the natural
frequencies and damping ratios, and the frequency response δq/δf peaks at each of them; a force
switched on at t = 0 rings at the same frequencies and settles at the static deflection.
"""
import matplotlib.pyplot as plt
import numpy as np

import lagrgen
from examples.two_mass_chain import absolute

mod = lagrgen.build(absolute)
q0 = lagrgen.equilibrium(mod, [0.0, 0.0])
res = lagrgen.modes(mod, q0)
print("f [Hz]:", res.frequencies_hz, "damping ratios:", res.damping_ratios)
freqs = np.linspace(0.05, 2.5, 500)
H = lagrgen.frequency_response(mod, q0, freqs, input="f")

# %%
# The magnitude of δq/δf with the natural frequencies marked, and the step response.
t = np.linspace(0, 15, 1501)
sol = lagrgen.simulate(mod, (0, 15), [0, 0, 0, 0], inputs={"f": 1.0}, t_eval=t, rtol=1e-9,
                       atol=1e-12)
fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
a.semilogy(freqs, abs(H[:, 0]), label="x1")
a.semilogy(freqs, abs(H[:, 1]), label="x2")
for f in res.frequencies_hz:
    a.axvline(f, color="gray", ls=":", lw=0.8)
a.set(xlabel="f [Hz]", ylabel="|δq/δf| [m/N]", title="frequency response")
a.legend(fontsize="small")
b.plot(sol.t, sol.q[0], label="x1")
b.plot(sol.t, sol.q[1], label="x2")
b.set(xlabel="t [s]", ylabel="[m]", title="response to a unit force on m2")
b.legend(fontsize="small")
fig.tight_layout()
