"""Ensembles (issue 10): a 1000-run ensemble of the double pendulum (masses varied), t = 0..10 s,
RK45 at rtol = atol = 1e-8, on 1 and on 2 threads (native engine), and on a 2-worker Dask
LocalCluster; medians of a few repeats, load average recorded.

    python benchmarks/ensemble.py [--runs 1000] [--repeats 3] [--no-dask]

Prints a table and writes it to benchmarks/results/ensemble.md.
"""
import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples"))
RESULTS = ROOT / "benchmarks" / "results" / "ensemble.md"


def median_seconds(fn, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-dask", action="store_true")
    args = parser.parse_args()

    import lagrgen
    from double_pendulum import model
    mod = lagrgen.build(model, out_dir=tempfile.mkdtemp(), quiet=True)
    P = np.tile(mod.defaults, (args.runs, 1))
    P[:, 0] = np.random.default_rng(1).uniform(0.5, 2.0, args.runs)
    t_eval = np.linspace(0.0, 10.0, 101)

    def run(**kw):
        return lagrgen.simulate_many(mod, (0.0, 10.0), [0.5, 0.0, 0.0, 0.0], params=P,
                                     t_eval=t_eval, method="RK45", rtol=1e-8, atol=1e-8,
                                     progress=False, **kw)

    check = run(workers=1)
    rows = []
    one = median_seconds(lambda: run(workers=1), args.repeats)
    rows.append(("1 thread (native engine)", one, "1.00×"))
    two = median_seconds(lambda: run(workers=2), args.repeats)
    rows.append(("2 threads (native engine)", two, f"{one / two:.2f}× (target ≥ 1.8×)"))
    scipy_one = median_seconds(lambda: lagrgen.simulate_many(
        mod, (0.0, 10.0), [0.5, 0.0, 0.0, 0.0], params=P[:100], t_eval=t_eval, method="RK45",
        rtol=1e-8, atol=1e-8, workers=1, progress=False, engine="scipy"), 1) * args.runs / 100
    rows.append(("1 thread, scipy engine (from 100 runs)", scipy_one, f"{scipy_one / one:.1f}× slower"))
    if not args.no_dask:
        from distributed import Client, LocalCluster
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None, silence_logs=40) as cluster, \
                Client(cluster) as client:
            same = run(client=client)
            assert np.array_equal(same.y, check.y), "Dask result differs from the local one"
            dask_s = median_seconds(lambda: run(client=client), args.repeats)
        rows.append(("Dask LocalCluster, 2 worker processes", dask_s, f"{one / dask_s:.2f}×"))
    load = os.getloadavg()[0]
    lines = [f"{args.runs}-run ensemble of the double pendulum, t = 0..10 s, RK45 rtol = atol = "
             f"1e-8, 101 output times; median of {args.repeats}; load average {load:.2f} on "
             f"{os.cpu_count()} cores", "",
             "| how | seconds | vs 1 thread |", "|---|---|---|"]
    lines += [f"| {name} | {s:.3f} | {ratio} |" for name, s, ratio in rows]
    table = "\n".join(lines) + "\n"
    print(table)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(table)


if __name__ == "__main__":
    main()
