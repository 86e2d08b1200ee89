"""Write docs/data/two_mass_run.csv: the record the identification page fits.

The two-mass chain of examples/two_mass_chain.py ("two_mass_absolute", true values k1 = 40,
k2 = 25, c1 = 0.4, c2 = 0.2) released from x1 = 0.1, x2 = -0.05 at rest, sampled every 0.05 s
for 10 s, with 1 mm of Gaussian noise (seed 7) on x1 and x2; columns t, x1, x2 as
`python -m lagrgen simulate --csv` writes them. Run from the repository's root:

    python docs/data/make_two_mass_run.py
"""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import lagrgen  # noqa: E402
from examples.two_mass_chain import absolute  # noqa: E402

mod = lagrgen.build(absolute, out_dir=ROOT / "generated")
t = np.linspace(0, 10, 201)
sol = lagrgen.simulate(mod, (0, 10), [0.1, -0.05, 0, 0], t_eval=t, method="DOP853", rtol=1e-10,
                       atol=1e-12)
noisy = sol.q + np.random.default_rng(7).normal(0, 1e-3, sol.q.shape)
rows = "\n".join(",".join(f"{v:.6g}" for v in row) for row in np.column_stack([t, noisy.T]))
(Path(__file__).parent / "two_mass_run.csv").write_text("t,x1,x2\n" + rows + "\n")
