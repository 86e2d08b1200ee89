"""Ensembles (issues 10, 22): the double pendulum (mass m1 varied), t = 0..10 s, RK45 at
rtol = atol = 1e-8, 101 output times; 10 000 and 100 000 runs on 1 and 2 threads (native engine,
one C batch per chunk) and on a 2-worker Dask LocalCluster (loopback), each without and with a
Zarr store. The configurations run interleaved, round by round, so that each sees the same share
of a shared machine; the load average is recorded per row. Threads run in a child process that
reports its peak memory (VmHWM); the Dask rows report the larger worker peak. Results of
every configuration are compared bit for bit (states and nfev) with the 1-thread run.

    python benchmarks/ensemble.py [--runs 10000 100000] [--repeats 3] [--no-dask]

Prints a table and writes it to benchmarks/results/ensemble.md (and .json).
"""
import argparse
import hashlib
import json
import os
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
import importlib.machinery, importlib.util, json, resource, shutil, statistics, sys, time
import numpy as np
import lagrgen
name, path, runs, workers, store, repeats = sys.argv[1:7]
loader = importlib.machinery.ExtensionFileLoader(name, path)
spec = importlib.util.spec_from_file_location(name, path, loader=loader)
mod = importlib.util.module_from_spec(spec)
loader.exec_module(mod)
runs, workers, repeats = int(runs), int(workers), int(repeats)
{HWM}
P = np.tile(mod.defaults, (runs, 1))
P[:, 0] = np.random.default_rng(1).uniform(0.5, 2.0, runs)
warm = lagrgen.simulate_many(mod, (0.0, 10.0), [0.5, 0.0, 0.0, 0.0], params=P[:4],
                             t_eval=[0.0, 10.0], workers=workers, progress=False,
                             store=None if store == "-" else store + ".warm")
times, cpu = [], []
for _ in range(repeats):
    cpu0 = time.process_time()
    start = time.perf_counter()
    ens = lagrgen.simulate_many(mod, (0.0, 10.0), [0.5, 0.0, 0.0, 0.0], params=P,
                                t_eval=np.linspace(0.0, 10.0, 101), method="RK45", rtol=1e-8,
                                atol=1e-8, workers=workers, progress=False,
                                store=None if store == "-" else store)
    times.append(time.perf_counter() - start)
    cpu.append(time.process_time() - cpu0)
    if store == "-":
        import hashlib
        h = hashlib.sha256(memoryview(np.ascontiguousarray(ens.y)).cast("B"))
        h.update(ens.nfev.astype("i8").tobytes())
        digest = h.hexdigest()
    del ens
peak = high_water_mark()
if store != "-":
    shutil.rmtree(store + ".warm", ignore_errors=True)
out = {"seconds": statistics.median(times), "cpu": statistics.median(cpu), "peak_bytes": peak}
if store == "-":
    out["digest"] = digest
print(json.dumps(out))
"""


#: Shared by this script, its children and the Dask workers (pasted into the child's script).
HWM_SOURCE = '''
def high_water_mark():
    """Peak resident memory of this process in bytes: VmHWM (Linux; reset by exec, unlike
    ru_maxrss, which a child inherits from the parent it was forked from), else ru_maxrss."""
    import resource
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
'''
exec(HWM_SOURCE)


def digest_of(y, nfev):
    """SHA-256 of the states and nfev (the states hashed in place, without a copy)."""
    h = hashlib.sha256(memoryview(np.ascontiguousarray(y)).cast("B"))
    h.update(np.asarray(nfev).astype("i8").tobytes())
    return h.hexdigest()


def store_digest(path):
    import lagrgen
    ds = lagrgen.open_ensemble(path)
    return digest_of(ds.y.values, ds.nfev.values)


def run_child(mod, runs, workers, store, repeats):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    script = CHILD.replace("{HWM}", HWM_SOURCE)
    proc = subprocess.run([sys.executable, "-c", script, mod.__name__, mod.__file__, str(runs),
                           str(workers), store or "-", str(repeats)], capture_output=True,
                          text=True, env=env, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def fresh_workers(client, mod, P):
    """Restart the workers (a fresh peak memory) and warm them up: the model uploaded and
    imported, lagrgen loaded (not timed, as the threads' child is warmed up)."""
    import lagrgen
    client.restart()
    warm = lagrgen.simulate_many(mod, T_SPAN, [0.5, 0.0, 0.0, 0.0], params=P[:10],
                                 t_eval=[0.0, 10.0], client=client, progress=False)
    assert warm.success.all()


def worker_peak(client):
    peaks = client.run(high_water_mark)
    return max(peaks.values())


CONFIGS = [("1 thread", 1, False), ("1 thread", 1, True), ("2 threads", 2, False),
           ("2 threads", 2, True), ("Dask LocalCluster, 2 workers", "dask", False),
           ("Dask LocalCluster, 2 workers", "dask", True)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, nargs="+", default=[10000, 100000])
    parser.add_argument("--repeats", type=int, default=3,
                        help="rounds for the runs below 50 000 (larger ones: one round)")
    parser.add_argument("--no-dask", action="store_true")
    args = parser.parse_args()

    import lagrgen
    from double_pendulum import model
    mod = lagrgen.build(model, out_dir=tempfile.mkdtemp(), quiet=True)
    scratch = Path(tempfile.mkdtemp(prefix="lagrgen-ens-bench-"))
    configs = [c for c in CONFIGS if not (args.no_dask and c[1] == "dask")]
    rows = []
    client = cluster = None
    if not args.no_dask:
        from distributed import Client, LocalCluster
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    try:
        for runs in args.runs:
            rounds = args.repeats if runs < 50000 else 1
            P = np.tile(mod.defaults, (runs, 1))
            P[:, 0] = np.random.default_rng(1).uniform(0.5, 2.0, runs)
            seen = {c: {"times": [], "cpu": [], "loads": [], "peak": 0, "digest": None}
                    for c in configs}
            for k in range(rounds):           # interleaved: every configuration sees the load
                for config in configs:
                    label, workers, store = config
                    path = scratch / f"{k}-{workers}-{runs}.zarr" if store else None
                    load = os.getloadavg()[0]
                    if workers == "dask":
                        fresh_workers(client, mod, P)
                        cpu0 = sum(client.run(time.process_time).values()) + time.process_time()
                        start = time.perf_counter()
                        ens = lagrgen.simulate_many(
                            mod, T_SPAN, [0.5, 0.0, 0.0, 0.0], params=P,
                            t_eval=np.linspace(0.0, 10.0, 101), method="RK45", rtol=TOL,
                            atol=TOL, client=client, progress=False, store=path)
                        seconds = time.perf_counter() - start
                        cpu = sum(client.run(time.process_time).values()) + \
                            time.process_time() - cpu0
                        digest = None if store else digest_of(ens.y, ens.nfev)
                        del ens
                        peak = worker_peak(client)
                    else:
                        r = run_child(mod, runs, workers, str(path) if store else None, 1)
                        seconds, peak, digest = r["seconds"], r["peak_bytes"], r.get("digest")
                        cpu = r["cpu"]
                    if store:
                        digest = store_digest(path)
                        shutil.rmtree(path, ignore_errors=True)
                    entry = seen[config]
                    entry["times"].append(seconds)
                    entry["cpu"].append(cpu)
                    entry["loads"].append((load + os.getloadavg()[0]) / 2)
                    entry["peak"] = max(entry["peak"], peak)
                    entry["digest"] = digest
                    print(f"{runs:>7} {label:<28} {'zarr' if store else '-':<5} {seconds:8.2f} s"
                          f"  peak {peak / 2 ** 20:6.0f} MiB  load {os.getloadavg()[0]:.2f}",
                          flush=True)
            reference = seen[configs[0]]["digest"]
            base = statistics.median(seen[configs[0]]["times"])
            for config in configs:
                entry = seen[config]
                seconds = statistics.median(entry["times"])
                rows.append({"runs": runs, "how": config[0], "store": config[2],
                             "seconds": seconds, "runs_per_s": runs / seconds,
                             "vs_1_thread": base / seconds, "peak_mib": entry["peak"] / 2 ** 20,
                             "cpu_ms_per_run": 1e3 * statistics.median(entry["cpu"]) / runs,
                             "identical": entry["digest"] == reference,
                             "load": statistics.mean(entry["loads"]), "rounds": rounds})
    finally:
        if client is not None:
            client.close()
            cluster.close()
        shutil.rmtree(scratch, ignore_errors=True)
    write_table(rows, args)


def write_table(rows, args):
    lines = [f"Ensembles of the double pendulum (m1 varied), t = 0..10 s, RK45 rtol = atol = 1e-8, "
             f"101 output times; native engine, one C batch per chunk of ≤ 500 runs. The "
             f"configurations run interleaved, round by round ({args.repeats} rounds below 50 000 "
             f"runs, one above; median seconds), so that each sees the same share of a machine "
             f"shared with other jobs ({os.cpu_count()} cores; the load average during its runs "
             f"is given). Threads run in a child process (its peak RSS, VmHWM); Dask rows: "
             f"the larger peak of the two worker processes, restarted before each measurement (without a store the client also "
             f"holds the whole result, as the threads do). \"identical\": states and nfev equal "
             f"bit for bit to the 1-thread run (with a store: as read back from it). \"CPU ms per "
             f"run\": the CPU time of the process(es) doing the work (child; for Dask the "
             f"workers and the client) per run, which the load does not change: equal figures "
             f"for 1 and 2 threads mean the parallel runs cost no extra work.", "",
             "| runs | how | Zarr store | seconds | runs/s | speed-up vs 1 thread | CPU ms per run "
             "| peak memory | identical | load |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['runs']} | {r['how']} | {'yes' if r['store'] else 'no'} | "
                     f"{r['seconds']:.2f} | {r['runs_per_s']:.0f} | {r['vs_1_thread']:.2f}× | "
                     f"{r['cpu_ms_per_run']:.3f} | {r['peak_mib']:.0f} MiB | {'yes' if r['identical'] else 'NO'} | "
                     f"{r['load']:.1f} |")
    targets = []
    for runs in args.runs:
        by = {(r["how"], r["store"]): r for r in rows if r["runs"] == runs}
        one, two = by.get(("1 thread", False)), by.get(("2 threads", False))
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
