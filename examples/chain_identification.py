"""Identify the springs and dampers of a chain from a gapped, noisy record, by collocation.

Three masses in a row, joined to a wall and to each other by springs k1, k2, k3 and dampers c1,
c2, c3; a known force F shakes the last mass. Two sensors record the first and the last mass's
position, 2 mm noise, at irregular times over 8 s, with a 1.5 s dropout in the middle. The
initial state is unknown too: collocation estimates it with the parameters, the record's gaps
are simply times without samples, and the standard errors come with the estimates.

`python -m lagrgen optimize examples/chain_identification.py` solves it;
`python examples/chain_identification.py` also draws
docs/_static/collocation_identification.png: the record and the identified motion, and each
estimate's error in units of its standard error.
"""
import numpy as np
import sympy as sp

import lagrgen

model = lagrgen.Model("damped_chain")
x1, x2, x3 = model.coordinates("x1 x2 x3", units="m m m")
m, = model.parameters(m=(1.0, "kg"))
k1, k2, k3 = model.parameters(k1=(40.0, "N/m"), k2=(25.0, "N/m"), k3=(30.0, "N/m"))
c1, c2, c3 = model.parameters(c1=(0.4, "N*s/m"), c2=(0.2, "N*s/m"), c3=(0.3, "N*s/m"))
F, = model.inputs("F", units="N")
for x in (x1, x2, x3):
    model.particle(m, sp.Matrix([x]))
for k, c, stretch in ((k1, c1, x1), (k2, c2, x2 - x1), (k3, c3, x3 - x2)):
    model.spring(k, stretch)
    model.damper(c, stretch)
model.generalized_force(x3, F)
mod = lagrgen.build(model)

# -- the record: a simulation of the true chain, sampled irregularly, with noise and a gap --
truth = {"k1": 40.0, "k2": 25.0, "k3": 30.0, "c1": 0.4, "c2": 0.2, "c3": 0.3}
rng = np.random.default_rng(2026)
shaker = lagrgen.Signal(np.linspace(0, 8, 161), np.sin(2.1 * np.linspace(0, 8, 161))
                        + 0.5 * np.sin(5.3 * np.linspace(0, 8, 161)))
t = np.sort(rng.uniform(0, 8, 400))
t = t[(t < 3.0) | (t > 4.5)]                                   # the dropout
motion = lagrgen.simulate(mod, (0, 8), [0.01, 0.0, -0.01, 0, 0, 0], params=truth,
                          inputs={"F": shaker}, t_eval=t, rtol=1e-11, atol=1e-13)
noise = 2e-3
record = motion.y[[0, 2]] + noise * rng.standard_normal((2, t.size))

# -- the problem: k1 … c3 unknown (starting 30 % off), F known, the initial state free --
estimated = list(truth)
problem = lagrgen.Collocation(mod, nodes=161, duration=8.0, scheme="hermite-simpson",
                              unknown_params=estimated,
                              params={name: 0.7 * value for name, value in truth.items()})
problem.input("F", shaker)
problem.track(t, record, ["x1", "x3"], weights=1 / noise ** 2)
for name in estimated:
    problem.bound(name, 0.0, 1e3)

if __name__ == "__main__":
    from pathlib import Path
    result = problem.solve()
    for name in estimated:
        err = result.params[name] - truth[name]
        print(f"{name}: {result.params[name]:.5f} ± {result.stderr[name]:.5f} "
              f"(true {truth[name]}, off by {err / result.stderr[name]:+.2f} standard errors)")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), height_ratios=(2, 1))
    dense = np.linspace(0, 8, 801)
    motion = result.state_at(dense)
    for row, (name, i) in enumerate((("x1", 0), ("x3", 2))):
        dots, = top.plot(t, 1000 * record[row], ".", ms=2.5, alpha=0.5, label=f"{name} record")
        top.plot(dense, 1000 * motion[i], color=dots.get_color(), lw=1.2,
                 label=f"{name} identified")
    top.axvspan(3.0, 4.5, color="0.9", label="dropout")
    top.set_ylabel("position [mm]")
    top.set_xlabel("t [s]")
    top.legend(fontsize="x-small", ncol=3, loc="upper left")
    top.set_title("Damped chain identified from a gapped, noisy record (collocation)")
    z = [(result.params[n] - truth[n]) / result.stderr[n] for n in estimated]
    bottom.axhspan(-2, 2, color="0.92")
    bottom.errorbar(range(len(estimated)), z, yerr=1.0, fmt="o", capsize=4)
    bottom.axhline(0, color="k", lw=0.8)
    bottom.set_xticks(range(len(estimated)),
                      [f"{n}\n{result.params[n]:.4g}±{result.stderr[n]:.2g}" for n in estimated],
                      fontsize="x-small")
    bottom.set_ylabel("(estimate − truth)\n/ standard error")
    fig.tight_layout()
    static = Path(__file__).resolve().parent.parent / "docs" / "_static"
    fig.savefig(static / "collocation_identification.png")
