"""What a robot's enforced joint limits cost in a simulation (`from_urdf(..., limits=True)`, the
default): every run of such a robot is a hybrid solve, even while no joint is at a stop.

examples/robots/arm7.urdf built twice, with its limits enforced and without, falls from
q = (0, 0.3, 0, −1, 0, 1.3, 0) at rest: for 0.3 s (before it reaches a stop: the same motion
both ways) and for 2 s (its shoulder strikes its upper stop and comes to rest on it; without the
stops it swings on). `lagrgen.simulate` on the native and SciPy engines, RK45 at lagrgen's
default tolerances, without and with 201 output times: the median wall time of ROUNDS runs
(SCIPY_ROUNDS on SciPy's engine), the builds interleaved so that the load of a shared machine
falls on both alike, and the ratio of the enforced limits' time to the free robot's. Prints the table and writes
benchmarks/results/robot_stops.{md,json}.

    python benchmarks/robot_stops.py
"""
import datetime
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OUT_DIR = HERE / "results" / "robot_stops_models"
URDF = ROOT / "examples" / "robots" / "arm7.urdf"
START = np.concatenate([[0.0, 0.3, 0.0, -1.0, 0.0, 1.3, 0.0], np.zeros(7)])
SPANS = (0.3, 2.0)
ROUNDS = 15
SCIPY_ROUNDS = 5


def builds():
    """{True: arm7 with its limits enforced, False: without}."""
    import lagrgen
    return {limits: lagrgen.build(lagrgen.from_urdf(URDF, limits=limits),
                                  out_dir=OUT_DIR, quiet=True) for limits in (True, False)}


def run(mod, engine, t_end, outputs):
    import lagrgen
    t_eval = np.linspace(0.0, t_end, 201) if outputs else None
    return lagrgen.simulate(mod, (0.0, t_end), START, engine=engine, t_eval=t_eval)


def timed(mod, engine, t_end, outputs):
    began = time.perf_counter()
    run(mod, engine, t_end, outputs)
    return time.perf_counter() - began


def measure():
    mods = builds()
    rows = []
    for t_end in SPANS:
        for engine in ("native", "scipy"):
            for outputs in (False, True):
                sols = {k: run(mod, engine, t_end, outputs) for k, mod in mods.items()}
                times = {k: [] for k in mods}
                for _ in range(ROUNDS if engine == "native" else SCIPY_ROUNDS):
                    for k, mod in mods.items():
                        times[k].append(timed(mod, engine, t_end, outputs))
                on, off = (statistics.median(times[k]) * 1e3 for k in (True, False))
                rows.append(dict(t_end=t_end, engine=engine, outputs=201 if outputs else None,
                                 enforced_ms=on, free_ms=off, ratio=on / off,
                                 transitions=len(sols[True].transitions),
                                 nfev_enforced=int(sols[True].nfev),
                                 nfev_free=int(sols[False].nfev)))
    return rows


def markdown(rows, when, load):
    lines = ["# A robot's enforced joint limits in a simulation", "",
             f"{when}, load average {load[0]:.1f} / {load[1]:.1f} on {os.cpu_count()} cores; "
             f"median of {ROUNDS} runs on the native engine, {SCIPY_ROUNDS} on SciPy's, "
             "the two builds interleaved.", "",
             "arm7 falling from rest, RK45 at the default tolerances. Over 0.3 s it reaches no "
             "stop: the motion is the same with and without its limits, and the ratio is what a "
             "hybrid solve costs between stops. Over 2 s its shoulder strikes its upper stop and "
             "rests on it (the free robot swings on: another motion).", "",
             "| span s | engine | output times | limits enforced ms | limits not enforced ms | "
             "ratio | switches | rhs calls, enforced / not |",
             "| --: | --- | --: | --: | --: | --: | --: | --- |"]
    for r in rows:
        lines.append(f"| {r['t_end']:g} | {r['engine']} | {r['outputs'] or 'steps'} | "
                     f"{r['enforced_ms']:.2f} | {r['free_ms']:.2f} | {r['ratio']:.2f} | "
                     f"{r['transitions']} | {r['nfev_enforced']} / {r['nfev_free']} |")
    return "\n".join(lines) + "\n"


def main():
    load = os.getloadavg()
    rows = measure()
    when = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
    text = markdown(rows, when, load)
    print(text)
    out = HERE / "results"
    (out / "robot_stops.md").write_text(text)
    (out / "robot_stops.json").write_text(json.dumps(dict(when=when, load=load, rounds=ROUNDS,
                                                          rows=rows), indent=1) + "\n")


if __name__ == "__main__":
    main()
