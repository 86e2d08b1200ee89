"""A gantry crane moving a hanging load 4 m in 5 s with as little sway as it can.

A trolley (mass M) runs on a horizontal rail, driven by a force F (|F| ≤ 40 N); the load (mass
m) hangs from it on a rope of length L, at angle phi from the vertical. The trolley starts and
stops at rest with the load hanging still. The objective is the sway, the load's horizontal
offset from the trolley squared, integrated over the move, plus a small effort term:

    ∫ ((L·sin phi)² + 10⁻³·F²) dt

`python -m lagrgen optimize examples/crane.py --plot crane.png` solves it;
`python examples/crane.py` also draws docs/_static/collocation_crane.png and
docs/_static/collocation_crane.gif.
"""
import sympy as sp

import lagrgen

model = lagrgen.Model("crane")
x, phi = model.coordinates("x phi", units="m rad")
M, m, L, g = model.parameters(M=(10.0, "kg"), m=(5.0, "kg"), L=(2.0, "m"), g=(9.81, "m/s^2"))
F, = model.inputs("F", units="N")
trolley = sp.Matrix([x, 0])
load = trolley + L * sp.Matrix([sp.sin(phi), -sp.cos(phi)])
model.particle(M, trolley)
model.particle(m, load)
model.potential_energy(m * g * load[1])
model.force(sp.Matrix([F, 0]), at=trolley)
model.line(trolley, load)

mod = lagrgen.build(model)
problem = lagrgen.Collocation(mod, nodes=101, duration=5.0, scheme="hermite-simpson")
problem.bound("F", -40.0, 40.0)
problem.initial(q=[0.0, 0.0], qd=[0.0, 0.0])
problem.final(q=[4.0, 0.0], qd=[0.0, 0.0])
problem.minimize(integral=(L * sp.sin(phi)) ** 2 + 1e-3 * F ** 2)

if __name__ == "__main__":
    from pathlib import Path
    import numpy as np
    result = problem.solve()
    sway = 2.0 * np.abs(np.sin(result.y[1])).max()
    effort = lagrgen.Collocation(mod, nodes=101, duration=5.0, scheme="hermite-simpson")
    effort.bound("F", -40.0, 40.0).initial(q=[0.0, 0.0], qd=[0.0, 0.0])
    effort.final(q=[4.0, 0.0], qd=[0.0, 0.0]).minimize(integral=F ** 2)
    plain = 2.0 * np.abs(np.sin(effort.solve(progress=False).y[1])).max()
    print(f"largest sway of the load: {1000 * sway:.0f} mm (least-effort move: "
          f"{1000 * plain:.0f} mm)")
    docs = Path(__file__).resolve().parent.parent / "docs"
    result.plot(docs / "_static" / "collocation_crane.png",
                title=f"Crane, 4 m in 5 s: largest sway {1000 * sway:.0f} mm "
                      f"(least-effort move {1000 * plain:.0f} mm)")
    result.animate(docs / "_static" / "collocation_crane.gif", fps=12, max_frames=60, dpi=60)
