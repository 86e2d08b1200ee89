"""A block on a spring with dry (Coulomb) friction, exactly and smoothed.

    wall ──k── m  on a floor with friction coefficient mu:   m·ẍ + k·x = −mu·m·g·sign(ẋ)

- "coulomb_friction": the friction force is discontinuous at ẋ = 0. Between two stops the motion is
  a harmonic half cycle about x = ±mu·m·g/k, so the amplitude falls by 2·mu·m·g/k every half cycle
  (linearly, not exponentially), and the block sticks for good once |k·x| ≤ mu·m·g at a stop.
  An explicit solver stepping across ẋ = 0 crawls; `turning_points` integrates one half cycle at a
  time with the switching surface ẋ = 0 as a terminal event (the output "slip_velocity"), so the
  solver steps onto the switch instead.
- "coulomb_smooth": the usual smooth alternative, sign(v) ≈ tanh(v/eps). It is one ordinary ODE
  (any solver, no events) and close to the exact motion while |v| ≫ eps; near a stop it creeps
  instead of sticking (the force vanishes at v = 0), and small eps makes it stiff (use Radau).

Run it: python examples/coulomb_friction.py   (writes coulomb_friction.png)
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
    else:
        friction = -mu * m * g * sp.sign(v)
    model.generalized_force(x, friction)
    model.output("friction_force", friction, units="N")
    model.output("slip_velocity", v, units="m/s")
    return model


model = _model("coulomb_friction", smooth=False)
smooth = _model("coulomb_smooth", smooth=True)


def turning_points(mod, x0, t_end, rtol=1e-10, atol=1e-12, params=None):
    """Positions where the block stops (ẋ = 0), from rest at x0, until it sticks or t_end.

    Each half cycle is integrated from rest until the slip velocity crosses zero again (a terminal
    event on the output "slip_velocity"); the block sticks when |k·x| ≤ mu·m·g there.
    """
    p = dict(zip(mod.parameters, mod.defaults), **(params or {}))
    band = p["mu"] * p["m"] * p["g"] / p["k"]
    stops, t, x = [x0], 0.0, x0
    while t < t_end and abs(x) > band:
        # moving towards −x when x > 0: ẋ returns to 0 from below (direction +1), and vice versa
        event = lagrgen.output_event(mod, "slip_velocity", params=params, terminal=True,
                                     direction=1 if x > 0 else -1)
        sol = lagrgen.simulate(mod, (t, t_end), [x, 0.0], method="DOP853", params=params,
                               events=[event], rtol=rtol, atol=atol)
        if sol.status != 1:
            break
        t, x = sol.t_events[0][0], sol.y_events[0][0][0]
        stops.append(x)
    return stops


if __name__ == "__main__":
    from lagrgen.outputs.plotting import plot_series
    exact = lagrgen.build(model, backend="python")
    approx = lagrgen.build(smooth, backend="python")
    stops = turning_points(exact, x0=0.2, t_end=5.0)
    print("turning points:", ", ".join(f"{s:.5f}" for s in stops))
    print("drop per half cycle:", np.round(-np.diff(np.abs(stops)), 6), "expected",
          2 * 0.3 * 9.81 / 100)
    t = np.linspace(0, 3, 1501)
    sol = lagrgen.simulate(approx, (0, 3), [0.2, 0.0], method="Radau", t_eval=t, max_steps=200_000)
    out = lagrgen.evaluate_outputs(approx, sol)
    plot_series(t, [sol.y[0], out["friction_force"], out["total_energy"]],
                ["x (tanh, eps = 1e-3)", "friction_force", "total_energy"],
                {"x (tanh, eps = 1e-3)": "m", "friction_force": "N", "total_energy": "J"},
                "coulomb_friction.png", title="block with dry friction")
    print("plot -> coulomb_friction.png")
