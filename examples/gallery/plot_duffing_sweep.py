"""
A frequency sweep of the Duffing oscillator
===========================================

A lightly damped mass on a hardening spring, m·ẍ + c·ẋ + k·x + k3·x³ = F(t)
(``examples/duffing.py``), forced with F = A·sin(w·t). Its steady-state amplitude against the
forcing frequency leans to the right of the linear resonance √(k/m) and jumps down where the
upper branch ends; the linearized model has a plain peak. Each run is one native solve: the
forcing is a sampled ``lagrgen.Signal``, which the C engine interpolates.
"""
import matplotlib.pyplot as plt
import numpy as np

import lagrgen
from examples.duffing import model

mod = lagrgen.build(model)
A = 0.3
t_samples = np.linspace(0, 150, 15001)


def forcing(w):
    """The input F = A·sin(w·t) of one run, sampled finely enough for the cubic interpolant."""
    return {"F": lagrgen.Signal(t_samples, A * np.sin(w * t_samples), kind="cubic")}


omegas = np.linspace(0.5, 2.0, 31)
result = lagrgen.sweep(mod, "w", omegas, (0, 150), inputs=forcing, method="DOP853")
H = lagrgen.frequency_response(mod, [0.0], omegas / (2 * np.pi), input="F")

# %%
fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(result.values, result.column("x"), "o-", ms=3, label="steady amplitude (simulated)")
ax.plot(omegas, A * abs(H[:, 0]), "--", label="linearized: A·|H(w)|")
ax.set(xlabel="w [rad/s]", ylabel="amplitude of x", title="Duffing oscillator, A = 0.3")
ax.legend(fontsize="small")
