"""Ensembles: many runs of one built model (parameter sweeps, Monte Carlo), on threads or on a Dask
cluster, collected into arrays (runs × states × times).

Each run is one `lagrgen.simulate`; on the native engine a run holds no GIL, so threads use every
core. A run that fails (a singular mass matrix, a non-finite derivative, a step-size collapse) is
reported in its row (`success`, `status`, `message`; its states are NaN) and does not lose the
others. Arguments are converted once, here, for all runs.
"""
import math
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .errors import LagrgenError
from .runtime.arguments import as_vector, state_vector
from .runtime.arguments import parameters_from
from .simulate import simulate


@dataclass
class EnsembleResult:
    """The runs of `simulate_many`: shared output times, states per run, and per-run status.

    Attributes
    ----------
    t : (len(t_eval),) the output times, shared by every run
    y : (runs, 2n, len(t_eval)) the states; NaN after a run failed
    success, status, nfev : (runs,) arrays, as `solve_ivp` reports them for each run
    message : list of str, one per run
    coordinates : the coordinate names
    engines : list of str, the engine each run used ("native" or "scipy")
    """

    t: np.ndarray
    y: np.ndarray
    success: np.ndarray
    status: np.ndarray
    nfev: np.ndarray
    message: list
    coordinates: tuple = ()
    engines: list = field(default_factory=list)

    @property
    def runs(self):
        return self.y.shape[0]

    @property
    def q(self):
        """(runs, n, len(t)) coordinates."""
        return self.y[:, :len(self.coordinates)]

    @property
    def qd(self):
        """(runs, n, len(t)) velocities."""
        return self.y[:, len(self.coordinates):]


def _count(values, single_ndim):
    """The number of runs a per-run argument asks for (1 for a shared one)."""
    if values is None or isinstance(values, dict):
        return 1
    if isinstance(values, (list, tuple)) and values and isinstance(values[0], (dict, list, tuple,
                                                                               np.ndarray)):
        return len(values)
    arr = np.asarray(values, dtype=float)
    return arr.shape[0] if arr.ndim == single_ndim + 1 else 1


def _per_run(values, runs, single_ndim, what):
    """`values` as a list of `runs` entries (a shared one repeated)."""
    count = _count(values, single_ndim)
    if count not in (1, runs):
        raise ValueError(f"{what} gives {count} runs but another argument gives {runs}: give one "
                         f"{what} for all runs or one per run")
    if count == 1:
        return [values] * runs
    return list(values)


def ensemble_arguments(mod, y0, params, inputs):
    """(Y0 (runs, 2n), P (runs, n_params), inputs list): the runs' arguments, converted once."""
    runs = max(_count(y0, 1), _count(params, 1), _count(inputs, 0) if not isinstance(
        inputs, dict) else 1)
    coordinates = tuple(mod.coordinates)
    Y0 = np.array([state_vector(v, coordinates) for v in _per_run(y0, runs, 1, "y0")])
    P = np.array([parameters_from(mod, v) for v in _per_run(params, runs, 1, "params")])
    if inputs is None or isinstance(inputs, dict):
        run_inputs = [inputs] * runs
    else:
        run_inputs = _per_run(list(inputs), runs, 0, "inputs")
    return Y0, P, run_inputs


def _one_run(mod, t_span, y0, p, inputs, t_eval, method, rtol, atol, options):
    """(y (2n, len(t_eval)), success, status, nfev, message, engine) of one run; never raises for a
    failure of the run itself."""
    n2, k = 2 * mod.n_coordinates, len(t_eval)
    y = np.full((n2, k), np.nan)
    try:
        sol = simulate(mod, t_span, y0, method=method, params=p, inputs=inputs, rtol=rtol,
                       atol=atol, t_eval=t_eval, **options)
    except (LagrgenError, np.linalg.LinAlgError, FloatingPointError, ArithmeticError) as exc:
        return y, False, -1, 0, str(exc), "scipy"
    y[:, :sol.y.shape[1]] = sol.y
    return (y, bool(sol.success), int(sol.status), int(sol.nfev), str(sol.message),
            getattr(sol, "engine", "scipy"))


def _run_chunk(mod, indices, t_span, Y0, P, run_inputs, t_eval, method, rtol, atol, options):
    return [_one_run(mod, t_span, Y0[i], P[i], run_inputs[i], t_eval, method, rtol, atol, options)
            for i in indices]


class _Progress:
    """A one-line progress report of finished runs on stderr (only on a terminal)."""

    def __init__(self, total, show):
        self.total, self.done, self.show = total, 0, show
        self.start = self.last = time.perf_counter()

    def add(self, k):
        self.done += k
        now = time.perf_counter()
        if self.show and (now - self.last > 0.2 or self.done == self.total):
            self.last = now
            print(f"\r[lagrgen] runs {self.done}/{self.total} ({now - self.start:.1f} s)",
                  end="\n" if self.done == self.total else "", file=sys.stderr, flush=True)


def chunks(runs, parts):
    """`runs` indices split into at most `parts` contiguous chunks of nearly equal size."""
    parts = max(1, min(parts, runs))
    bounds = np.linspace(0, runs, parts + 1).round().astype(int)
    return [list(range(a, b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def simulate_many(mod, t_span, y0, params=None, inputs=None, t_eval=None, method="RK45",
                  rtol=1e-6, atol=1e-9, workers=None, client=None, progress=None, **options):
    """Integrate many runs of `mod` that share `t_span` and `t_eval`.

    Parameters
    ----------
    mod : a built model (either backend)
    y0 : one state (2n,) or a dict, or one per run: (runs, 2n) or a list
    params : None, one vector or dict, an (runs, n_params) array, or a list of dicts/vectors
    inputs : None or one dict shared by all runs, or a list of dicts (one per run)
    t_eval : the output times (required: every run is sampled on them)
    method, rtol, atol, **options : as for `lagrgen.simulate`
    workers : threads on this machine (default: every core for a compiled model, 1 otherwise)
    client : a `dask.distributed.Client`: the runs go to its workers in a few chunks per worker
    progress : show a progress line on stderr (default: when stderr is a terminal)

    Returns
    -------
    EnsembleResult with t (len(t_eval),), y (runs, 2n, len(t_eval)), success, status, nfev,
    message (one per run). The number of runs is the largest of the per-run arguments.
    """
    if t_eval is None:
        raise ValueError("simulate_many needs t_eval: every run is sampled at the same times")
    t_eval = as_vector(t_eval, np.size(t_eval), "t_eval")
    Y0, P, run_inputs = ensemble_arguments(mod, y0, params, inputs)
    runs = len(Y0)
    show = sys.stderr.isatty() if progress is None else progress
    args = (t_span, Y0, P, run_inputs, t_eval, method, rtol, atol, options)
    if client is not None:
        rows = _on_dask(client, mod, runs, args)
    else:
        if workers is None:
            workers = (os.cpu_count() or 1) if getattr(mod, "backend", "") == "c" else 1
        rows = _on_threads(mod, runs, int(workers), args, _Progress(runs, show))
    y, success, status, nfev, message, engines = zip(*rows)
    return EnsembleResult(t=t_eval, y=np.array(y), success=np.array(success, dtype=bool),
                          status=np.array(status, dtype=int), nfev=np.array(nfev, dtype=int),
                          message=list(message), coordinates=tuple(mod.coordinates),
                          engines=list(engines))


def _on_threads(mod, runs, workers, args, progress):
    if workers <= 1:
        rows = []
        for i in range(runs):
            rows.extend(_run_chunk(mod, [i], *args))
            progress.add(1)
        return rows
    parts = chunks(runs, max(workers * 4, math.ceil(runs / 50)))
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(_run_chunk, mod, part, *args) for part in parts]
        rows = []
        for future in futures:
            result = future.result()
            progress.add(len(result))
            rows.extend(result)
    return rows


def _on_dask(client, mod, runs, args):
    """Run the chunks on a Dask cluster; a compiled model's module file is uploaded to every
    worker and imported there by name."""
    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    parts = chunks(runs, 3 * n_workers)
    if getattr(mod, "backend", "") == "c":
        client.upload_file(mod.__file__, load=False)
        target = ("module", mod.__name__)
    else:
        target = ("object", mod)
    futures = client.map(_dask_chunk, [target] * len(parts), parts, [args] * len(parts),
                         pure=False)
    rows = []
    for result in client.gather(futures):
        rows.extend(result)
    return rows


def _dask_chunk(target, indices, args):
    """One chunk on a Dask worker: import the uploaded compiled model (or use the object)."""
    kind, value = target
    if kind == "module":
        import importlib
        mod = importlib.import_module(value)
    else:
        mod = value
    return _run_chunk(mod, indices, *args)
