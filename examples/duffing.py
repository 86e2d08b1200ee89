"""A driven, lightly damped Duffing oscillator: a mass on a hardening spring, forced by F(t).

    m·ẍ + c·ẋ + k·x + k3·x³ = F(t)

Its steady-state amplitude against the forcing frequency bends to the right of the linear
resonance √(k/m) as the forcing grows:

    python -m lagrgen sweep examples/duffing.py --param w=0.5:2:60 --input "F=A*sin(w*t)" \
        --params A=0.3 --t-end 150 --linear 0.3 --plot duffing_sweep.png
"""
import sympy as sp

from lagrgen import Model

model = Model("duffing")
x, = model.coordinates("x")
m, c, k, k3, A = model.parameters(m=1.0, c=0.08, k=1.0, k3=0.5, A=0.3)
F, = model.inputs("F")

model.particle(m, sp.Matrix([x]))
model.spring(k, x)
model.potential_energy(k3 * x ** 4 / 4)
model.damper(c, x)
model.generalized_force(x, F)
