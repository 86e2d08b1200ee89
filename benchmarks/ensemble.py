"""Ensembles (issues 10, 22): the double pendulum (mass m1 varied), t = 0..10 s, RK45 at
rtol = atol = 1e-8, 101 output times; 10 000 and 100 000 runs on 1 and 2 threads (native engine,
one C batch per chunk) and on a 2-worker Dask LocalCluster (loopback), each without and with a
Zarr store. Threads run in a child process that reports its peak memory (ru_maxrss); the Dask rows
report the client's and the largest worker's peak. Results of every configuration are compared
bit for bit (states and nfev) with the 1-thread run. Load average recorded per row (the machine is
shared).

    python benchmarks/ensemble.py [--runs 10000 100000] [--repeats 3] [--no-dask]

Prints a table and writes it to benchmarks/results/ensemble.md (and .json).
"""
import argparse
import hashlib
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples"))
RESULTS = ROOT / "benchmarks" / "results" / "ensemble.md"
T_SPAN, TOL = (0.0, 10.0), 1e-8

CHILD = """
import importlib.machinery, importlib.util, json, resource, statistics, sys, time
import numpy as np
import lagrgen
name, path, runs, workers, store, repeats = sys.argv[1:7]
loader = importlib.machinery.ExtensionFileLoader(name, path)
spec = importlib.util.spec_from_file_location(name, path, loader=loader)
mod = importlib.util.module_from_spec(spec)
loader.exec_module(mod)
runs, workers, repeats = int(runs), int(workers), int(repeats)
P = np.tile(mod.defaults, (runs, 1))
P[:, 0] = np.random.default_rng(1).uniform(0.5, 2.0, runs)
times = []
for _ in range(repeats):
    start = time.perf_counter()
    ens = lagrgen.simulate_many(mod, (0.0, 10.0), [0.5, 0.0, 0.0, 0.0], params=P,
                                t_eval=np.linspace(0.0, 10.0, 101), method="RK45", rtol=1e-8,
                                atol=1e-8, workers=workers, progress=False,
                                store=None if store == "-" else store)
    times.append(time.perf_counter() - start)
    if store == "-":
        digest = [ens.y.tobytes(), ens.nfev.astype("i8").tobytes()]
    del ens
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
out = {"seconds": statistics.median(times), "peak_bytes": peak}
if store == "-":
    import hashlib
    out["digest"] = hashlib.sha256(digest[0] + digest[1]).hexdigest()
print(json.dumps(out))
"""


def digest_of(y, nfev):
    return hashlib.sha256(np.ascontiguousarray(y).tobytes() +
                          np.asarray(nfev).astype("i8").tobytes()).hexdigest()


def store_digest(path):
    import lagrgen
    ds = lagrgen.open_ensemble(path)
    return digest_of(ds.y.values, ds.nfev.values)


def run_child(mod, runs, workers, store, repeats):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", CHILD, mod.__name__, mod.__file__, str(runs),
                           str(workers), store or "-", str(repeats)], capture_output=True,
                          text=True, env=env, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def worker_peak(client):
    peaks = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
    return max(peaks.values())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, nargs="+", default=[10000, 100000])
    parser.add_argument("--repeats", type=int, default=3,
                        help="repeats of the runs below 50 000 (larger ones run once)")
    parser.add_argument("--no-dask", action="store_true")
    args = parser.parse_args()

    import lagrgen
    from double_pendulum import model
    mod = lagrgen.build(model, out_dir=tempfile.mkdtemp(), quiet=True)
    scratch = Path(tempfile.mkdtemp(prefix="lagrgen-ens-bench-"))
    rows = []

    def add(runs, how, store, seconds, peak, same, base):
        rows.append({"runs": runs, "how": how, "store": store, "seconds": seconds,
                     "runs_per_s": runs / seconds, "vs_1_thread": base / seconds,
                     "peak_mib": peak / 2 ** 20 if peak else None, "identical": same,
                     "load": os.getloadavg()[0]})
        print(f"{runs:>7} {how:<28} {'zarr' if store else '-':<5} {seconds:8.2f} s  "
              f"{base / seconds:5.2f}x  peak {peak / 2 ** 20 if peak else float('nan'):7.0f} MiB  "
              f"identical {same}  load {os.getloadavg()[0]:.2f}", flush=True)

    client = cluster = None
    if not args.no_dask:
        from distributed import Client, LocalCluster
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    try:
        for runs in args.runs:
            repeats = args.repeats if runs < 50000 else 1
            P = np.tile(mod.defaults, (runs, 1))
            P[:, 0] = np.random.default_rng(1).uniform(0.5, 2.0, runs)
            one = run_child(mod, runs, 1, None, repeats)
            reference = one["digest"]
            add(runs, "1 thread", False, one["seconds"], one["peak_bytes"], True, one["seconds"])
            base = one["seconds"]
            for workers in (1, 2):
                if workers == 2:
                    r = run_child(mod, runs, 2, None, repeats)
                    add(runs, "2 threads", False, r["seconds"], r["peak_bytes"],
                        r["digest"] == reference, base)
                path = scratch / f"threads{workers}-{runs}.zarr"
                r = run_child(mod, runs, workers, str(path), repeats)
                add(runs, f"{workers} thread{'s' if workers > 1 else ''}", True, r["seconds"],
                    r["peak_bytes"], store_digest(path) == reference, base)
                shutil.rmtree(path, ignore_errors=True)
            if client is None:
                continue

            def on_dask(store=None):
                return lagrgen.simulate_many(mod, T_SPAN, [0.5, 0.0, 0.0, 0.0], params=P,
                                             t_eval=np.linspace(0.0, 10.0, 101), method="RK45",
                                             rtol=TOL, atol=TOL, client=client, progress=False,
                                             store=store)
            on_dask_warm = lagrgen.simulate_many(mod, T_SPAN, [0.5, 0.0, 0.0, 0.0],
                                                 params=P[:10], t_eval=[0.0, 10.0],
                                                 client=client, progress=False)
            assert on_dask_warm.success.all()
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                ens = on_dask()
                times.append(time.perf_counter() - start)
            same = digest_of(ens.y, ens.nfev) == reference
            del ens
            add(runs, "Dask LocalCluster, 2 workers", False, statistics.median(times),
                worker_peak(client), same, base)
            times = []
            for k in range(repeats):
                path = scratch / f"dask-{runs}-{k}.zarr"
                start = time.perf_counter()
                on_dask(store=path)
                times.append(time.perf_counter() - start)
            same = store_digest(path) == reference
            add(runs, "Dask LocalCluster, 2 workers", True, statistics.median(times),
                worker_peak(client), same, base)
            client.restart()       # a fresh peak for the next size
    finally:
        if client is not None:
            client.close()
            cluster.close()
        shutil.rmtree(scratch, ignore_errors=True)

    lines = [f"Ensembles of the double pendulum (m1 varied), t = 0..10 s, RK45 rtol = atol = 1e-8, "
             f"101 output times; native engine, one C batch per chunk of ≤ 500 runs. Seconds are "
             f"the median of {args.repeats} below 50 000 runs, one run above. Threads ran in a "
             f"child process (its peak RSS); Dask rows: the largest peak of the two workers (the "
             f"client holds the whole result without a store). \"identical\": "
             f"states and nfev equal bit for bit to the 1-thread run. {os.cpu_count()} cores "
             f"shared with other jobs: the load average (1 min) is given per row.", "",
             "| runs | how | Zarr store | seconds | runs/s | speed-up vs 1 thread | peak memory "
             "| identical | load |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        peak = f"{r['peak_mib']:.0f} MiB" if r["peak_mib"] else "–"
        lines.append(f"| {r['runs']} | {r['how']} | {'yes' if r['store'] else 'no'} | "
                     f"{r['seconds']:.2f} | {r['runs_per_s']:.0f} | {r['vs_1_thread']:.2f}× | "
                     f"{peak} | {'yes' if r['identical'] else 'NO'} | {r['load']:.1f} |")
    targets = []
    for runs in args.runs:
        by = {(r["how"], r["store"]): r for r in rows if r["runs"] == runs}
        two = by.get(("2 threads", False))
        one = by.get(("1 thread", False))
        dask = by.get(("Dask LocalCluster, 2 workers", False))
        if one and two:
            targets.append(f"{runs} runs: 2 threads {one['seconds'] / two['seconds']:.2f}× one "
                           "thread (target ≥ 1.9×)")
        if dask and two:
            targets.append(f"{runs} runs: LocalCluster {dask['seconds'] / two['seconds']:.2f}× "
                           "the 2-thread time (target ≤ 1.25×)")
        store = by.get(("2 threads", True))
        if store:
            targets.append(f"{runs} runs to a store on 2 threads: peak {store['peak_mib']:.0f} "
                           "MiB (target < 1024 MiB at 100 000 runs)")
    lines += [""] + [f"- {t}" for t in targets]
    table = "\n".join(lines) + "\n"
    print(table)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(table)
    RESULTS.with_suffix(".json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
