"""A friction damper: a structure tied through a spring to a slider pressed on a rough surface.

    structure x (mass M, spring k, force F0·sin(Ω·t)); slider z (small mass m_s) joined to it by
    a spring k_t (with a little damping c_t against the pad's ringing) and pressed by N:
    model.friction("pad", ż, N, mu)

The force the damper puts on the structure, k_t·(x − z) + c_t·(ẋ − ż), follows a hysteresis loop: while the
pad sticks it grows with slope k_t, once it reaches mu·N the pad slips and it stays at ±mu·N. The
loop's area is the energy dissipated per cycle (≈ 4·mu·N·(X − mu·N/k_t) for amplitude X).

Run it: python examples/friction_damper.py   (writes docs/_static/friction_damper.png)
"""
import sympy as sp

from lagrgen import Model

model = Model("friction_damper")
x, z = model.coordinates("x z", units="m m")
M, m_s, k, k_t, c_t, F0, w, N, mu = model.parameters(
    M=(1.0, "kg"), m_s=(0.01, "kg"), k=(100.0, "N/m"), k_t=(200.0, "N/m"), c_t=(2.0, "N*s/m"),
    F0=(5.0, "N"), w=(8.0, "rad/s"), N=(10.0, "N"), mu=(0.2, "-"))
model.particle(M, [x])
model.particle(m_s, [z])
model.spring(k, x, ends=([0], [x]))
model.spring(k_t, x - z)
model.damper(c_t, x - z)
model.generalized_force(x, F0 * sp.sin(w * model.t))
model.friction("pad", z.diff(model.t), N, mu)
model.output("damper_force", k_t * (x - z) + c_t * (x - z).diff(model.t), units="N")

if __name__ == "__main__":
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import lagrgen
    mod = lagrgen.build(model)
    t = np.linspace(0, 12, 12001)
    sol = lagrgen.simulate(mod, (0, 12), [0, 0, 0, 0], t_eval=t, rtol=1e-10, atol=1e-12)
    force = lagrgen.evaluate_outputs(mod, sol)["damper_force"]
    late = t > 6
    area = -np.trapezoid(force[late], sol.y[0][late]) / (6 * 8 / (2 * np.pi))
    print(f"{len(sol.transitions)} stick/slip switches; energy dissipated per cycle "
          f"{abs(area):.4f} J; largest damper force {np.abs(force).max():.4f} N (mu·N = 2 N)")
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    a.plot(sol.y[0][late], force[late], color="tab:red")
    a.axhline(2.0, color="gray", ls=":", lw=0.8)
    a.axhline(-2.0, color="gray", ls=":", lw=0.8)
    a.set_xlabel("structure displacement x [m]")
    a.set_ylabel("damper force on the structure [N]")
    a.set_title("hysteresis loop (steady state)")
    a.grid(True, alpha=0.3)
    b.plot(t, sol.y[0], label="x")
    b.plot(t, sol.y[1], label="z (pad)")
    b.set_xlabel("t [s]")
    b.set_ylabel("[m]")
    b.set_title("structure and pad")
    b.legend(fontsize="small")
    b.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig("docs/_static/friction_damper.png", dpi=90)
    print("plot -> docs/_static/friction_damper.png")
