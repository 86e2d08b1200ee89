"""A ball dropped on the floor, bouncing with restitution e until it comes to rest.

    height y, floor contact y >= 0:   model.impact("floor", y, restitution=e)

Each impact reverses the velocity times e (ẏ⁺ = −e·ẏ⁻): the k-th flight lasts 2·eᵏ·v₁/g, a
geometric series, so infinitely many bounces fit before the Zeno time t₁ + 2·e·v₁/(g·(1 − e)),
t₁ = √(2h/g), v₁ = g·t₁. lagrgen switches to resting contact (y = 0 held, its force ≥ 0) when the
bounces become negligible, and the ball stays on the floor.

Run it: python examples/bouncing_ball.py   (writes docs/_static/bouncing_ball.png)
"""
import sympy as sp

from lagrgen import Model

model = Model("bouncing_ball")
y, = model.coordinates("y", units="m")
m, g, e = model.parameters(m=(0.1, "kg"), g=(9.81, "m/s^2"), e=(0.8, "-"))
model.particle(m, sp.Matrix([0, y]))
model.potential_energy(m * g * y)
model.impact("floor", y, restitution=e)

if __name__ == "__main__":
    import numpy as np

    import lagrgen
    mod = lagrgen.build(model)
    h = 1.0
    sol = lagrgen.simulate(mod, (0, 5), {"y": h}, rtol=1e-10, atol=1e-12)
    t1 = np.sqrt(2 * h / 9.81)
    zeno = t1 + 2 * 0.8 * 9.81 * t1 / (9.81 * 0.2)
    print(f"{len(sol.transitions)} switches on the {sol.engine} engine; the first impacts at",
          np.round([t for t, *_ in sol.transitions[:4]], 6), "(t1 =", round(t1, 6), ")")
    print(f"at rest from t = {sol.transitions[-1][0]:.6f} (Zeno time {zeno:.6f}),",
          "mode", sol.mode)
    t = np.linspace(0, 5, 5001)
    fine = lagrgen.simulate(mod, (0, 5), {"y": h}, t_eval=t, rtol=1e-10, atol=1e-12)
    fig = fine.plot(title="bouncing ball, e = 0.8 (dotted: impacts, then resting contact)")
    fig.savefig("docs/_static/bouncing_ball.png", dpi=90)
    print("plot -> docs/_static/bouncing_ball.png")
