"""A block on a spring with dry (Coulomb) friction, exactly and smoothed.

    wall ──k── m  on a floor with friction coefficient mu:   m·ẍ + k·x = −mu·m·g·sign(ẋ)

- "coulomb_friction": `model.friction("floor", ẋ, m·g, mu)`. Between two stops the motion is a
  harmonic half cycle about x = ±mu·m·g/k, so the amplitude falls by 2·mu·m·g/k every half cycle
  (linearly, not exponentially), and the block sticks for good once |k·x| ≤ mu·m·g at a stop.
  lagrgen locates each stop (ẋ = 0) as an event and decides there: stick when the spring force is
  within the friction limit, else slip back.
- "coulomb_smooth": the usual smooth alternative, sign(v) ≈ tanh(v/eps). It is one ordinary ODE
  (any solver, no events) and close to the exact motion while |v| ≫ eps; near a stop it creeps
  instead of sticking (the force vanishes at v = 0), and small eps makes it stiff (use Radau).

Run it: python examples/coulomb_friction.py   (writes docs/_static/coulomb_friction.png)
"""
import numpy as np
import sympy as sp

import lagrgen
from lagrgen import Model


def _model(name, smooth):
    model = Model(name)
    x, = model.coordinates("x", units="m")
    m, k, mu, g = model.parameters(m=(1.0, "kg"), k=(100.0, "N/m"), mu=(0.3, "-"),
                                   g=(9.81, "m/s^2"))
    v = x.diff(model.t)
    model.particle(m, [x])
    model.spring(k, x, ends=([0], [x]))
    if smooth:
        eps, = model.parameters(eps=(1e-3, "m/s"))
        friction = -mu * m * g * sp.tanh(v / eps)
        model.generalized_force(x, friction)
        model.output("friction_force", friction, units="N")
    else:
        model.friction("floor", v, m * g, mu)
    model.output("slip_velocity", v, units="m/s")
    return model


model = _model("coulomb_friction", smooth=False)
smooth = _model("coulomb_smooth", smooth=True)


def turning_points(mod, x0, t_end, rtol=1e-10, atol=1e-12, params=None):
    """Positions where the block stops (ẋ = 0), from rest at x0, until it sticks or t_end: the
    start, then the position at every switch of the hybrid solve (slip reversals, the stick)."""
    sol = lagrgen.simulate(mod, (0, t_end), [x0, 0.0], params=params, rtol=rtol, atol=atol)
    stops = [x0]
    for t, _, _ in sol.transitions:
        k = np.flatnonzero(sol.t == t)[0]
        stops.append(sol.y[0, k])
    return stops


if __name__ == "__main__":
    from lagrgen.outputs.plotting import plot_series
    exact = lagrgen.build(model)
    approx = lagrgen.build(smooth)
    stops = turning_points(exact, x0=0.2, t_end=5.0)
    print("turning points:", ", ".join(f"{s:.5f}" for s in stops))
    print("drop per half cycle:", np.round(-np.diff(np.abs(stops)), 6), "expected",
          2 * 0.3 * 9.81 / 100)
    t = np.linspace(0, 1.5, 1501)
    sol = lagrgen.simulate(exact, (0, 1.5), [0.2, 0.0], t_eval=t, rtol=1e-10, atol=1e-12)
    ref = lagrgen.simulate(approx, (0, 1.5), [0.2, 0.0], method="Radau", t_eval=t,
                           rtol=1e-8, atol=1e-10)
    plot_series(t, [sol.y[0], ref.y[0], sol.y[1], ref.y[1]],
                ["x (Coulomb, sticks)", "x (tanh, eps = 1e-3)", "x' (Coulomb)", "x' (tanh)"],
                {"x (Coulomb, sticks)": "m", "x (tanh, eps = 1e-3)": "m", "x' (Coulomb)": "m/s",
                 "x' (tanh)": "m/s"},
                "docs/_static/coulomb_friction.png", title="block with dry friction",
                transitions=sol.transitions)
    print("plot -> docs/_static/coulomb_friction.png")
