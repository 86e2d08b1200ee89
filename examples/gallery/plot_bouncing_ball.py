"""
A bouncing ball that comes to rest
==================================

A ball dropped from 1 m onto a floor with restitution e = 0.8 (``examples/bouncing_ball.py``):
each impact reverses its speed times e, the impacts accumulate, and from the Zeno time
t₁ + 2·e·v₁/(g·(1 − e)) on the ball rests on the floor (a held contact).
"""
import numpy as np

import lagrgen
from examples.bouncing_ball import model

mod = lagrgen.build(model)
t = np.linspace(0, 5, 2001)
sol = lagrgen.simulate(mod, (0, 5), {"y": 1.0}, t_eval=t, rtol=1e-10, atol=1e-12)
print(sol.transitions[:2], sol.transitions[-1], sol.mode)

# %%
# The result plots itself; the dotted lines mark the impacts and the final contact.
fig = sol.plot(title="bouncing ball, e = 0.8")
