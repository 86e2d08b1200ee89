"""The belt-driven stick–slip oscillator: a block on a spring, lying on a belt moving at v_b.

    m·ẍ + k·x = friction(ẋ − v_b),   static coefficient mu_s > kinetic mu_k

The block sticks to the belt (ẋ = v_b) until the spring force reaches mu_s·m·g, at
x_s = mu_s·m·g/k; it then slips, oscillating about c = mu_k·m·g/k with amplitude
√((x_s − c)² + (v_b/ω)²) (ω = √(k/m)), and sticks again where ẋ = v_b returns, at x = 2c − x_s.
The limit cycle — a straight stick segment and an elliptic slip arc in the phase plane — is the
squeal of brakes and the creak of doors.

Run it: python examples/stick_slip.py   (writes docs/_static/stick_slip.png)
"""
import sympy as sp

from lagrgen import Model

model = Model("stick_slip")
x, = model.coordinates("x", units="m")
m, k, mu_s, mu_k, g, v_b = model.parameters(m=(1.0, "kg"), k=(20.0, "N/m"), mu_s=(0.5, "-"),
                                            mu_k=(0.3, "-"), g=(9.81, "m/s^2"),
                                            v_b=(0.4, "m/s"))
model.particle(m, [x])
model.spring(k, x, ends=([0], [x]))
model.friction("belt", x.diff(model.t) - v_b, m * g, mu_k, mu_static=mu_s)

if __name__ == "__main__":
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import lagrgen
    mod = lagrgen.build(model)
    t = np.linspace(0, 8, 8001)
    sol = lagrgen.simulate(mod, (0, 8), {"x": 0.0, "x_dot": 0.4}, t_eval=t, rtol=1e-10,
                           atol=1e-12)
    xs, c, w = 0.5 * 9.81 / 20, 0.3 * 9.81 / 20, np.sqrt(20.0)
    print("switches:", [(round(tt, 4), kind) for tt, _, kind in sol.transitions[:6]])
    print(f"peak {sol.y[0].max():.6f}, closed form {c + np.hypot(xs - c, 0.4 / w):.6f}")
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    stuck = np.isclose(sol.y[1], 0.4, atol=1e-9)
    a.plot(sol.y[0], sol.y[1], color="tab:blue", lw=1.2, label="slip")
    a.plot(sol.y[0][stuck], sol.y[1][stuck], ".", color="tab:green", ms=3, label="stick")
    a.axvline(xs, color="gray", ls=":", lw=0.8)
    a.axvline(2 * c - xs, color="gray", ls=":", lw=0.8)
    a.set_xlabel("x [m]")
    a.set_ylabel("x' [m/s]")
    a.set_title("phase portrait: stick segment, slip arc")
    a.legend(fontsize="small")
    a.grid(True, alpha=0.3)
    b.plot(sol.t, sol.y[0], label="x")
    for tt, _, kind in sol.transitions:
        b.axvline(tt, color="tab:green" if kind == "stick" else "tab:gray", ls=":", lw=0.7)
    b.set_xlabel("t [s]")
    b.set_ylabel("x [m]")
    b.set_title("time history (dotted: stick / slip)")
    b.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig("docs/_static/stick_slip.png", dpi=90)
    print("plot -> docs/_static/stick_slip.png")
