"""The tools the n-link benchmark compares, as builders `(n, work, cfg, make) -> _peers.Built`:
lagrgen's C and Python paths (their build times measured here) and the peers of `_peers.py`
(PyDy, CasADi) under a build time cap.
"""
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import _peers
from nlink_measure import median, timed

TOOLS = ("lagrgen-C", "lagrgen-Python", "PyDy", "CasADi")


def cached_in_fresh_process(model_file, n, out_dir):
    """Seconds of lagrgen.build for an already built model, in a new Python process."""
    code = ("import importlib.util, json, sys, time\n"
            f"spec = importlib.util.spec_from_file_location('nlink_pendulum', {str(model_file)!r})\n"
            "m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)\n"
            "import lagrgen\n"
            f"model = m.make({n})\n"
            "start = time.perf_counter()\n"
            f"mod = lagrgen.build(model, out_dir={str(out_dir)!r})\n"
            "print(json.dumps([time.perf_counter() - start, mod.build_info.get('cache_hit')]))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seconds, hit = json.loads(out.stdout.strip().splitlines()[-1])
    if not hit:
        raise RuntimeError("the build in a fresh process was not a cache hit")
    return seconds


def solver_notes():
    """What lagrgen.simulate runs that plain solve_ivp (the peers) does not."""
    try:
        from lagrgen.solvers import SOLVERS
    except ImportError:
        return []
    return [f"lagrgen.simulate runs {' and '.join(SOLVERS)} as lagrgen.solvers classes (SciPy's, "
            "with LAPACK LU called directly); the peers run SciPy's own classes via solve_ivp"]


def build_lagrgen_c(n, work, cfg, make):
    """lagrgen's C path: cold builds into fresh out_dirs (force=True), then cached builds."""
    import lagrgen

    colds, mod, out_dir = [], None, None
    for k in range(max(1, cfg["cold_runs"])):
        out_dir = Path(work) / f"cold{k}"
        seconds, mod = timed(lagrgen.build, make(n), out_dir=out_dir, force=True)
        colds.append({**mod.build_info, "wall": seconds})
        if sum(c["wall"] for c in colds) > cfg["cold_budget"]:
            break
    cached = []
    for _ in range(cfg["cached_runs"]):
        model = make(n)
        seconds, again = timed(lagrgen.build, model, out_dir=out_dir)
        if not again.build_info.get("cache_hit"):
            raise RuntimeError("second build of an identical model was not a cache hit")
        cached.append(seconds)
    fresh = [cached_in_fresh_process(cfg["model_file"], n, out_dir)
             for _ in range(cfg["fresh_process_runs"])]
    build = {key: median([c[key] for c in colds if key in c]) for key in ("derive", "cse+emit", "compile")}
    build.update(cold=median([c["wall"] for c in colds]), cold_runs=len(colds), cached=median(cached),
                 cached_fresh_process=median(fresh), cold_all=[c["wall"] for c in colds])
    p = np.asarray(mod.defaults, dtype=float)

    def simulate(method, t_span, y0, rtol, atol):
        return lagrgen.simulate(mod, t_span, y0, method=method, rtol=rtol, atol=atol)

    return _peers.Built(
        "lagrgen-C", mod.rhs, mod.jacobian, args=(p,), notes=solver_notes(),
        rhs_in_c=lambda t, y, r: mod.time_in_c("rhs", t, y, p, repeat=r),
        jac_in_c=lambda t, y, r: mod.time_in_c("jacobian", t, y, p, repeat=r),
        simulate=simulate, build=build)


def build_lagrgen_python(n, work, cfg, make):
    """lagrgen's pure-Python (NumPy) path."""
    import lagrgen

    walls, mod = [], None
    for _ in range(max(1, cfg["cold_runs"])):
        seconds, mod = timed(lagrgen.build, make(n), backend="python")
        walls.append(seconds)
        if sum(walls) > cfg["cold_budget"]:
            break
    info = getattr(mod, "build_info", None) or {}
    build = {key: info.get(key) for key in ("derive", "cse+emit", "compile")}
    build.update(cold=median(walls), cold_runs=len(walls))
    p = np.asarray(mod.defaults, dtype=float)

    def simulate(method, t_span, y0, rtol, atol):
        return lagrgen.simulate(mod, t_span, y0, method=method, rtol=rtol, atol=atol)

    return _peers.Built("lagrgen-Python", mod.rhs, mod.jacobian, args=(p,), simulate=simulate,
                        build=build, notes=solver_notes())


def build_peer(tool):
    """A builder for the peer `tool` with the time cap of cfg peer_timeout."""
    def build(n, work, cfg, make):
        deadline = time.perf_counter() + cfg["peer_timeout"]
        return _peers.BUILDERS[tool](n, work, deadline)
    return build


BUILDERS = {"lagrgen-C": build_lagrgen_c, "lagrgen-Python": build_lagrgen_python,
            "PyDy": build_peer("PyDy"), "CasADi": build_peer("CasADi")}
