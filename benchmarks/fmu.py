"""Co-simulation FMUs against `lagrgen.simulate` (issue 24, item 4).

The n-link pendulum (n = 2, 5), t = 0..10 s, all angles 0.5 rad, DOP853 at rtol = 1e-8,
atol = 1e-10, sampled every `h` (0.1 s and 0.01 s). Timed, as medians after one warm-up:

* `simulate`: `lagrgen.simulate(..., t_eval=grid)` on the native engine (one solve);
* FMU loop: the FMI 2.0 co-simulation FMU driven directly (FMPy's FMU2Slave: one `fmi2DoStep`
  per communication step and a `fmi2GetReal` of the states), i.e. one native solve per step;
* FMPy CS: `fmpy.simulate_fmu` of the same FMU (FMPy's recorder and input handling included);
* FMPy ME: `fmpy.simulate_fmu` of the FMI 2.0 Model Exchange FMU with FMPy's CVode (rtol 1e-8).

Each row gives the times as ratios to `simulate` and the largest state difference from it.
Prints the table and writes benchmarks/results/fmu.{md,json}.

    python benchmarks/fmu.py
"""
import datetime
import json
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
T_END = 10.0
RTOL, ATOL = 1e-8, 1e-10


def timed(fn, runs=3):
    """(median wall time in ms over `runs` runs after one warm-up, the last result)."""
    result = fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), result


def fmu_loop(path, work, start, grid, names):
    """(the instantiated FMU, a function that drives it step by step from `start` and returns
    the states at the grid points, (len(grid), 2n))."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    md = fmpy.read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=work, modelIdentifier=md.coSimulation.
                    modelIdentifier, instanceName="bench")
    refs = [vr[k] for k in names]
    fmu.instantiate()          # once: FMPy's freeInstance also unloads the library

    def run():
        fmu.reset()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal(refs, list(start))
        fmu.exitInitializationMode()
        out = [fmu.getReal(refs)]
        for t0, t1 in zip(grid[:-1], grid[1:]):
            fmu.doStep(currentCommunicationPoint=t0, communicationStepSize=t1 - t0)
            out.append(fmu.getReal(refs))
        return np.array(out)
    return fmu, run


def rows_for(n, out):
    import fmpy
    import lagrgen
    sys.path.insert(0, str(ROOT))
    from examples.nlink_pendulum import make
    model = make(n)
    mod = lagrgen.build(model, out_dir=out / "gen")
    cs = lagrgen.export_fmu(model, out / "cs", kind="cs", method="DOP853", rtol=RTOL, atol=ATOL)
    me = lagrgen.export_fmu(model, out / "me")
    work = fmpy.extract(str(cs), out / f"unzipped{n}")
    names = [*mod.coordinates, *(f"{c}_dot" for c in mod.coordinates)]
    y0 = np.r_[np.full(n, 0.5), np.zeros(n)]
    start = dict(zip(names, y0))
    rows = []
    for h in (0.1, 0.01):
        grid = np.linspace(0.0, T_END, int(round(T_END / h)) + 1)
        t_sim, sol = timed(lambda: lagrgen.simulate(mod, (0.0, T_END), y0, method="DOP853",
                                                    rtol=RTOL, atol=ATOL, t_eval=grid))
        fmu, run = fmu_loop(cs, work, y0, grid, names)
        t_loop, loop = timed(run)
        fmu.terminate()
        fmu.freeInstance()
        t_cs, res_cs = timed(lambda: fmpy.simulate_fmu(str(cs), start_values=start,
                                                       stop_time=T_END, output_interval=h,
                                                       output=names), runs=1)
        t_me, res_me = timed(lambda: fmpy.simulate_fmu(str(me), start_values=start,
                                                       stop_time=T_END, output_interval=h,
                                                       relative_tolerance=RTOL, output=names),
                             runs=1)

        def deviation(res):
            y = np.array([np.interp(grid, res["time"], res[k]) for k in names])
            return float(np.abs(y - sol.y).max())
        rows.append({
            "n": n, "h": h, "steps": len(grid) - 1, "simulate_ms": t_sim,
            "loop_ratio": t_loop / t_sim, "fmpy_cs_ratio": t_cs / t_sim,
            "fmpy_me_ratio": t_me / t_sim,
            "loop_dev": float(np.abs(loop.T - sol.y).max()), "fmpy_cs_dev": deviation(res_cs),
            "fmpy_me_dev": deviation(res_me)})
    return rows


def markdown(rows):
    lines = [
        "# Co-simulation FMUs against `lagrgen.simulate`",
        "",
        f"n-link pendulum, t = 0..{T_END:g} s, DOP853 rtol {RTOL:g} atol {ATOL:g}, communication "
        "step h. Times as ratios to `simulate` (one native solve with t_eval = the grid); "
        "deviation = largest state difference from it. FMU loop: the FMI 2.0 co-simulation FMU "
        "driven directly (one fmi2DoStep, i.e. one native solve, per step); FMPy CS / ME: "
        "`fmpy.simulate_fmu` of the co-simulation FMU / of the Model Exchange FMU with CVode.",
        "",
        f"{platform.machine()}, Python {platform.python_version()}, "
        f"{datetime.date.today().isoformat()}.",
        "",
        "| n | h | steps | simulate (ms) | FMU loop ×| FMPy CS × | FMPy ME × | loop dev | "
        "FMPy CS dev | FMPy ME dev |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['n']} | {r['h']:g} | {r['steps']} | {r['simulate_ms']:.2f} | "
            f"{r['loop_ratio']:.1f} | {r['fmpy_cs_ratio']:.1f} | {r['fmpy_me_ratio']:.1f} | "
            f"{r['loop_dev']:.1e} | {r['fmpy_cs_dev']:.1e} | {r['fmpy_me_dev']:.1e} |")
    return "\n".join(lines) + "\n"


def main():
    with tempfile.TemporaryDirectory(prefix="lagrgen-bench-fmu-") as tmp:
        rows = [r for n in (2, 5) for r in rows_for(n, Path(tmp) / f"n{n}")]
    md = markdown(rows)
    print(md)
    results = HERE / "results"
    (results / "fmu.md").write_text(md)
    (results / "fmu.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
