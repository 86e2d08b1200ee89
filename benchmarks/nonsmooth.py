"""Impacts and dry friction (issue 20): the hybrid solve on both engines, and the smoothed
alternative (tanh friction + Radau) at the same accuracy.

For each example of examples/ (bouncing_ball, coulomb_friction, stick_slip, impact_pendulum,
impact_damper, friction_damper) `lagrgen.simulate` runs with rtol = 1e-8, atol = 1e-10 on the
native (C) and SciPy engines: median wall time of 3 runs after a warm-up, the number of switches
and rhs calls. The error is max |x(t) − x_ref(t)| of the first coordinate on a 2001-point grid
against the same hybrid solve at rtol = 1e-12 (for the Coulomb block also the rest position
against the closed form). For the friction examples the smoothed model replaces sign(v) by
tanh(v/eps) (the stick–slip oscillator: a tanh with a static peak,
μ_k + (μ_s − μ_k)·exp(−(v/2eps)²))
and runs with Radau at rtol = 1e-8; eps is lowered 1e-2, 1e-3, 1e-4 until its error is at most the
hybrid solve's (or the last is shown). Prints the table and writes
benchmarks/results/nonsmooth.{md,json}.

    python benchmarks/nonsmooth.py
"""
import datetime
import importlib.util
import json
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OUT_DIR = HERE / "results" / "nonsmooth_models"
TOL = dict(rtol=1e-8, atol=1e-10)
REF = dict(rtol=1e-12, atol=1e-14)
EPS = (1e-2, 1e-3, 1e-4)
CASES = {   # example: (model attribute, t_end, y0)
    "bouncing_ball": ("model", 5.0, {"y": 1.0}),
    "coulomb_friction": ("model", 2.0, {"x": 0.2}),
    "stick_slip": ("model", 8.0, {"x": 0.0, "x_dot": 0.4}),
    "impact_pendulum": ("model", 6.0, {"theta": 0.8}),
    "impact_damper": ("model", 20.0, {}),
    "friction_damper": ("model", 8.0, {}),
}


def example(stem):
    spec = importlib.util.spec_from_file_location(f"bench_{stem}", ROOT / "examples" / f"{stem}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def smoothed(stem, eps):
    """The example's model with its friction smoothed (tanh), or None for the impact examples."""
    from lagrgen import Model
    model = Model(f"{stem}_smooth_{str(eps).replace('.', '_').replace('-', 'm')}")
    if stem == "coulomb_friction":
        x, = model.coordinates("x")
        m, k, mu, g = model.parameters(m=1.0, k=100.0, mu=0.3, g=9.81)
        model.particle(m, [x])
        model.potential_energy(k * x ** 2 / 2)
        model.generalized_force(x, -mu * m * g * sp.tanh(x.diff(model.t) / eps))
    elif stem == "stick_slip":
        x, = model.coordinates("x")
        m, k, mu_s, mu_k, g, vb = model.parameters(m=1.0, k=20.0, mu_s=0.5, mu_k=0.3, g=9.81,
                                                   v_b=0.4)
        v = x.diff(model.t) - vb
        mu = mu_k + (mu_s - mu_k) * sp.exp(-(v / (2 * eps)) ** 2)
        model.particle(m, [x])
        model.potential_energy(k * x ** 2 / 2)
        model.generalized_force(x, -mu * m * g * sp.tanh(v / eps))
    elif stem == "friction_damper":
        x, z = model.coordinates("x z")
        M, m_s, k, k_t, c_t, F0, w, N, mu = model.parameters(
            M=1.0, m_s=0.01, k=100.0, k_t=200.0, c_t=2.0, F0=5.0, w=8.0, N=10.0, mu=0.2)
        model.particle(M, [x])
        model.particle(m_s, [z])
        model.potential_energy(k * x ** 2 / 2 + k_t * (x - z) ** 2 / 2)
        model.damper(c_t, x - z)
        model.generalized_force(x, F0 * sp.sin(w * model.t))
        model.generalized_force(z, -mu * N * sp.tanh(z.diff(model.t) / eps))
    else:
        return None
    return model


def timed(fn, runs=3):
    result = fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


def run_case(stem):
    import lagrgen
    attr, t_end, y0 = CASES[stem]
    mod = lagrgen.build(getattr(example(stem), attr), out_dir=OUT_DIR)
    grid = np.linspace(0, t_end, 2001)
    ref = lagrgen.simulate(mod, (0, t_end), y0, t_eval=grid, **REF)
    row = {"example": stem}
    for engine in ("native", "scipy"):
        seconds, sol = timed(lambda: lagrgen.simulate(mod, (0, t_end), y0, t_eval=grid,
                                                      engine=engine, **TOL))
        row[engine] = {"ms": seconds * 1e3, "switches": len(sol.transitions), "nfev": sol.nfev,
                       "error": float(np.abs(sol.y[0] - ref.y[0]).max())}
    if stem == "coulomb_friction":
        band = 0.3 * 9.81 / 100
        x0 = 0.2
        while abs(x0) > band:
            x0 = -x0 + 2 * band * np.sign(x0)
        row["rest_error"] = float(abs(ref.y[0, -1] - x0))
    target = row["native"]["error"]
    smooth = None
    for eps in EPS:
        model = smoothed(stem, eps)
        if model is None:
            break
        smod = lagrgen.build(model, out_dir=OUT_DIR)
        try:
            seconds, sol = timed(lambda: lagrgen.simulate(smod, (0, t_end), y0, method="Radau",
                                                          t_eval=grid, **TOL), runs=1)
        except lagrgen.LagrgenError as exc:
            smooth = {"eps": eps, "ms": float("nan"), "nfev": 0, "success": False,
                      "error": None, "failure": str(exc)[:120]}
            continue
        smooth = {"eps": eps, "ms": seconds * 1e3, "nfev": sol.nfev, "success": bool(sol.success),
                  "error": float(np.abs(sol.y[0] - ref.y[0]).max()) if sol.success else None}
        if sol.success and smooth["error"] <= target:
            break
    row["smoothed"] = smooth
    return row


def markdown(rows, when):
    lines = [f"# Impacts and dry friction: hybrid solve vs smoothed friction ({when})", "",
             f"rtol = {TOL['rtol']:g}, atol = {TOL['atol']:g}; error: max |x − x_ref| of the "
             "first coordinate on 2001 points against the hybrid solve at rtol = 1e-12. "
             "Smoothed: tanh(v/eps) friction with Radau at the same tolerances, eps lowered "
             "until its error is at most the native hybrid solve's.", "",
             "| example | switches | native ms | native nfev | SciPy ms | SciPy/native | error "
             "| smoothed eps | smoothed ms | smoothed error | smoothed/native |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        n, s, sm = r["native"], r["scipy"], r["smoothed"]
        if sm is None:
            tail = "— | — | — | —"
        else:
            err = "failed" if sm["error"] is None else f"{sm['error']:.1e}"
            tail = f"{sm['eps']:g} | {sm['ms']:.1f} | {err} | {sm['ms'] / n['ms']:.0f}×"
        lines.append(f"| {r['example']} | {n['switches']} | {n['ms']:.1f} | {n['nfev']} | "
                     f"{s['ms']:.0f} | {s['ms'] / n['ms']:.0f}× | {n['error']:.1e} | {tail} |")
    coulomb = next((r for r in rows if "rest_error" in r), None)
    if coulomb:
        lines += ["", f"Coulomb block: the rest position of the reference solve differs from the "
                  f"closed form by {coulomb['rest_error']:.1e} m."]
    lines += ["", "The impact damper's ball rattles near grazing contacts: its motion depends "
              "sensitively on the impact times, so any two tolerances part after some seconds "
              "(rtol 1e-6, 1e-8, 1e-10, 1e-12 leave the 1e-13 solve by 1e-6 at t = 3.7, 10.1, "
              "12.0, 13.4 s); its error column measures that, not a bias.",
              "", f"Machine: {platform.machine()}, Python {platform.python_version()}, "
              f"{platform.system()}."]
    return "\n".join(lines) + "\n"


def main():
    sys.path.insert(0, str(ROOT / "src"))
    when = datetime.date.today().isoformat()
    rows = []
    for stem in CASES:
        rows.append(run_case(stem))
        print(stem, "done", flush=True)
    text = markdown(rows, when)
    print(text)
    out = HERE / "results"
    (out / "nonsmooth.md").write_text(text)
    (out / "nonsmooth.json").write_text(json.dumps({"date": when, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
