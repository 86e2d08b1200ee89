"""The model from the user's side: plain C compiled against `export-c`'s files, the notebook views
(`Model._repr_latex_`, `result.plot()`), and the portable build lock."""
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose

import lagrgen
from lagrgen.cli import main

from conftest import EXAMPLES, example_model

#: The README's C program: classical RK4 over the exported double pendulum, printing y(T).
RK4_PROGRAM = r"""
#include <stdio.h>
#include "double_pendulum_model.h"

#define NS double_pendulum_N_STATES

/* one classical Runge-Kutta step of y' = rhs(t, y, p, u); nonzero if M is not positive definite */
static int rk4_step(double t, double h, double *y, const double *p, const double *u)
{
    static const double c[4] = {0.0, 0.5, 0.5, 1.0};
    double k[4][NS], stage[NS];
    for (int s = 0; s < 4; ++s) {
        for (int i = 0; i < NS; ++i)
            stage[i] = y[i] + (s ? c[s] * h * k[s - 1][i] : 0.0);
        if (double_pendulum_rhs(t + c[s] * h, stage, p, u, k[s]))
            return 1;
    }
    for (int i = 0; i < NS; ++i)
        y[i] += h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
    return 0;
}

int main(void)
{
    double y[NS] = {0.5, -0.3, 0.0, 0.0};       /* theta1, theta2, theta1_dot, theta2_dot */
    double u[double_pendulum_N_INPUTS] = {0.2};  /* F */
    const double *p = double_pendulum_defaults;  /* m1, m2, L1, L2, g */
    const double h = 1e-3;
    for (int k = 0; k < 2000; ++k)
        if (rk4_step(k * h, h, y, p, u))
            return 1;
    for (int i = 0; i < NS; ++i)
        printf("%s%s = %.17g\n", double_pendulum_coordinate_names[i % double_pendulum_N_COORDINATES],
               i < double_pendulum_N_COORDINATES ? "" : "_dot", y[i]);
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_a_c_program_using_an_exported_model(tmp_path, capsys):
    assert main(["export-c", str(EXAMPLES / "double_pendulum.py"), "--out", str(tmp_path)]) == 0
    assert "double_pendulum_model.c" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["double_pendulum_model.c",
                                                          "double_pendulum_model.h"]
    (tmp_path / "pendulum_rk4.c").write_text(RK4_PROGRAM)
    exe = tmp_path / "pendulum_rk4"
    subprocess.run(["gcc", "-O2", "-std=c99", "-Wall", "-Werror=implicit-function-declaration",
                    "-o", str(exe), str(tmp_path / "pendulum_rk4.c"),
                    str(tmp_path / "double_pendulum_model.c"), "-lm"], check=True)
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    names = [line.split(" = ")[0] for line in out.splitlines()]
    assert names == ["theta1", "theta2", "theta1_dot", "theta2_dot"]
    y_c = np.array([float(line.split(" = ")[1]) for line in out.splitlines()])
    mod = lagrgen.build(example_model("double_pendulum"), backend="python")
    sol = lagrgen.simulate(mod, (0.0, 2.0), [0.5, -0.3, 0.0, 0.0], inputs={"F": 0.2},
                           method="DOP853", rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(y_c - sol.y[:, 0])) > 0.1          # it moved
    assert_allclose(y_c, sol.y[:, -1], atol=1e-10, rtol=0)   # RK4 at h = 1 ms: error ~1e-12


def test_repr_latex_shows_the_equations():
    model = example_model("double_pendulum")
    text = model._repr_latex_()
    assert text.startswith("$$\\begin{aligned}") and text.endswith("\\end{aligned}$$")
    rows = text.split("\n")[1:-1]
    assert len(rows) == 2 and all("&=" in r for r in rows)
    assert r"\ddot{\theta}_{1}" in text and r"\dot{\theta}_{2}^{2}" in text and "F" in text
    assert lagrgen.Model("empty")._repr_latex_() is None   # nothing to derive: plain repr


def test_a_built_models_repr_names_its_interface(tmp_path):
    model = example_model("double_pendulum")
    for mod in (lagrgen.build(model, out_dir=tmp_path), lagrgen.build(model, backend="python")):
        assert repr(mod) == (f"<lagrgen model 'double_pendulum' ({mod.backend} backend, dense "
                             "formulation): coordinates theta1, theta2; parameters m1=1, m2=1, "
                             "L1=1, L2=1, g=9.81; inputs F>")
    recursive = lagrgen.build(model, backend="python", formulation="recursive")
    assert repr(recursive).startswith("<lagrgen model 'double_pendulum' (python backend, "
                                      "recursive formulation): coordinates theta1, theta2;")
    bare = lagrgen.Model("bare")
    x, = bare.coordinates("x")
    k, = bare.parameters("k")
    bare.particle(1, x)
    bare.spring(k, x)
    assert repr(lagrgen.build(bare, backend="python")).endswith("parameters k=?; no inputs>")


def test_simulation_result_plots_itself():
    model = example_model("two_mass_chain", "absolute")
    mod = lagrgen.build(model, backend="python")
    sol = lagrgen.simulate(mod, (0.0, 1.0), {"x1": 0.1}, t_eval=np.linspace(0, 1, 11))
    fields = set(sol.keys())
    fig = sol.plot()
    assert set(sol.keys()) == fields and "plot" not in fields     # no new field
    assert fig.axes[0].get_title() == "two_mass_absolute"
    assert fig.axes[0].get_legend_handles_labels()[1] == ["x1", "x2"]
    assert fig.axes[1].get_legend_handles_labels()[1] == ["x1'", "x2'"]
    assert_allclose(fig.axes[0].lines[1].get_ydata(), sol.q[1])
    assert len(sol.plot(velocities=False, title="T").axes) == 1
    assert isinstance(sol, __import__("scipy").integrate._ivp.ivp.OdeResult)


def test_lock_is_exclusive_and_imported_lazily(tmp_path):
    from lagrgen.cache import locked
    spans = []

    def hold():
        with locked(tmp_path / "x.lock"):
            start = time.monotonic()
            time.sleep(0.05)
            spans.append((start, time.monotonic()))
    threads = [threading.Thread(target=hold) for _ in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    spans.sort()
    assert len(spans) == 4
    assert all(a[1] <= b[0] for a, b in zip(spans, spans[1:]))
    code = ("import sys, lagrgen.cache as b; "
            "assert 'filelock' not in sys.modules and not hasattr(b, 'fcntl')")
    subprocess.run([sys.executable, "-c", code], check=True)
