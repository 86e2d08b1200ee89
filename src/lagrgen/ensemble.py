"""Ensembles: many runs of one built model (parameter sweeps, Monte Carlo), on threads or on a Dask
cluster, collected into arrays (runs × states × times), labelled data (`to_xarray`) or a Zarr store.

The runs are split into contiguous chunks. On the native engine a chunk is one call into C
(`lagrgen.native._ode.solve_batch`) that loops over its runs without the GIL and without Python
between runs, writing states, multipliers and outputs into preallocated arrays; threads and Dask
tasks each run whole chunks. Runs that need the SciPy engine (callable inputs, LSODA, a model of
the Python backend, options only `solve_ivp` has) take the per-run path, one `lagrgen.simulate`
each. A run that fails (a singular mass matrix, a non-finite derivative, a step-size collapse) is
reported in its row (`success`, `status`, `message`) and does not lose the others; its row is
recomputed on the per-run path so that it reads exactly as a single `simulate` would.
"""
import hashlib
import math
import os
import sys
import threading
import _thread
import queue
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from .errors import LagrgenError, near_singular_limit, warn_near_singular
from .hybrid import RUN_STOP, check_hybrid_run, force_names, is_hybrid
from .methods import BY_NAME
from .native.engine import _event_arrays, _tolerances, native_events, native_reason
from .options import check_run_options as checked_options
from .runtime.arguments import input_specs, parameters_from, state_vector
from .runtime.free_base import check_quaternion
from .signals import Signal, constant_spec
from .simulate import (check_run_options, evaluate_outputs, refuse_switching_options, simulate,
                       time_span)

#: The messages of the native engine for status 0 and 1 (those of solve_ivp).
MESSAGES = {0: "The solver successfully reached the end of the integration interval.",
            1: "A termination event occurred."}
#: Runs per chunk at most: one Zarr chunk along `run`, one task, one step of the progress bar.
MAX_CHUNK = 500

#: simulate_many's keyword options that are not the solvers' (read by it, not passed on).
ENSEMBLE_OPTIONS = ("engine", "max_steps", "max_wall_time")


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
    multipliers : (runs, len(constraint_names), len(t)) constraint forces λ (M·q̈ = F + Aᵀλ) of
        a constrained model, then the contact and friction forces of a model with impacts or
        frictions (as `simulate`'s `contact_forces`), else None
    outputs : (runs, len(output_names), len(t)) the model's outputs when `outputs=True`, else None
    params : (runs, n_params) the parameters of every run
    parameter_names, output_names, constraint_names : names, in model order
    units : {name: unit} of the model (labels only)
    settings : {"method", "rtol", "atol"} of the runs
    transitions : None, or per run the list of (t, name, kind) of a non-smooth model's run
    sensitivities : (runs, len(sensitivity_names), 2n, len(t)) the forward sensitivities
        ∂y(t)/∂p_j of each run when `simulate_many(..., sensitivities=names)`, else None
    sensitivity_names : the names given (parameters, `y0:<state>`), in that order
    """

    t: np.ndarray
    y: np.ndarray
    success: np.ndarray
    status: np.ndarray
    nfev: np.ndarray
    message: list
    coordinates: tuple = ()
    engines: list = field(default_factory=list)
    multipliers: Optional[np.ndarray] = None
    outputs: Optional[np.ndarray] = None
    params: Optional[np.ndarray] = None
    parameter_names: tuple = ()
    output_names: tuple = ()
    constraint_names: tuple = ()
    units: dict = field(default_factory=dict)
    model_name: str = ""
    transitions: Optional[list] = None
    settings: dict = field(default_factory=dict)
    sensitivities: Optional[np.ndarray] = None
    sensitivity_names: tuple = ()

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

    def to_xarray(self):
        """The ensemble as an `xarray.Dataset` (needs the `ensembles` extra).

        Returns
        -------
        xarray.Dataset with `y` (run, state, time), the states named like the coordinates then
        `<coordinate>_dot`; one variable (run) per parameter; `success`, `status`, `nfev` (run);
        `multipliers` (run, constraint, time) and `outputs` (run, output, time) when present;
        units in each variable's attrs (`units`, or `state_units` / `output_units` by name).
        """
        from .ensemble_store import to_dataset
        return to_dataset(self)


# ---------------------------------------------------------------- arguments, converted once


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


def _rows(values, runs, width, what, convert):
    """(runs, width) float array of per-run vectors: a 2-D array is checked as a whole, anything
    else converted entry by entry with `convert`."""
    if isinstance(values, np.ndarray) and values.ndim == 2 and values.dtype.kind in "fiu":
        if values.shape[1] != width:
            raise ValueError(f"{what} has {values.shape[1]} columns, expected {width}")
        if values.shape[0] not in (1, runs):
            raise ValueError(f"{what} gives {values.shape[0]} runs but another argument gives "
                             f"{runs}: give one {what} for all runs or one per run")
        out = np.ascontiguousarray(np.broadcast_to(values, (runs, width)), dtype=float)
        if not np.all(np.isfinite(out)):
            bad = np.argwhere(~np.isfinite(out))[0]
            raise ValueError(f"{what} of run {bad[0]} has a NaN or infinite entry (column "
                             f"{bad[1]})")
        return out
    shared = _count(values, 1) == 1
    if shared and isinstance(values, (list, tuple)) and values and \
            isinstance(values[0], (dict, list, tuple, np.ndarray)):
        values = values[0]                       # one run given as a list of one entry
    if shared:
        return np.tile(convert(values), (runs, 1)) if runs else np.empty((0, width))
    return np.array([convert(v) for v in _per_run(values, runs, 1, what)], dtype=float)


def ensemble_arguments(mod, y0, params, inputs):
    """(Y0 (runs, 2n), P (runs, n_params), inputs list): the runs' arguments, converted once."""
    runs = max(_count(y0, 1), _count(params, 1), _input_count(inputs))
    coordinates = tuple(mod.coordinates)
    Y0 = _rows(y0, runs, 2 * len(coordinates), "y0", lambda v: state_vector(v, coordinates))
    P = _rows(params, runs, len(mod.parameters), "params", lambda v: parameters_from(mod, v))
    if _input_count(inputs) == 1 and not isinstance(inputs, (list, tuple)):
        run_inputs = [inputs] * runs
    else:
        run_inputs = list(inputs)
        if len(run_inputs) not in (1, runs):
            raise ValueError(f"inputs gives {len(run_inputs)} runs but another argument gives "
                             f"{runs}: give one inputs for all runs or one per run")
        run_inputs = run_inputs * runs if len(run_inputs) == 1 else run_inputs
    return Y0, P, run_inputs


def _input_count(inputs):
    """The number of runs `inputs` asks for: None, a dict or one input vector are shared; a list
    (of dicts or vectors) or a 2-D array give one entry per run."""
    if inputs is None or isinstance(inputs, dict):
        return 1
    if isinstance(inputs, (list, tuple)):
        return len(inputs)
    return np.shape(inputs)[0] if np.ndim(inputs) == 2 else 1


def batch_inputs(mod, inputs, run_inputs):
    """(shared input specs, U (runs, max(n_inputs, 1))) for the C batch, or None when some run's
    inputs need the SciPy engine or differ between runs in a way the batch does not carry (a
    callable, different Signals for one input). U holds each constant input's value per run."""
    names = tuple(mod.inputs)
    runs = len(run_inputs)
    U = np.zeros((runs, max(len(names), 1)))
    if inputs is None or isinstance(inputs, dict) or (isinstance(inputs, np.ndarray)
                                                      and inputs.ndim == 1):
        if native_reason(mod, "RK45", inputs, None, {}) is not None:
            return None
        specs = input_specs(mod, inputs)
        for i, spec in enumerate(specs):
            U[:, i] = spec[1]
        return specs, U
    if isinstance(inputs, np.ndarray) and inputs.ndim == 2:
        if inputs.shape[1] != len(names):
            raise ValueError(f"inputs has {inputs.shape[1]} columns, expected {len(names)}")
        U[:, :len(names)] = inputs
        return [constant_spec(0.0) for _ in names], U
    per_name = [[] for _ in names]
    for u in run_inputs:
        if native_reason(mod, "RK45", u, None, {}) is not None:
            return None
        for i, spec_or_signal in enumerate(_input_entries(mod, u)):
            per_name[i].append(spec_or_signal)
    specs = []
    for i, entries in enumerate(per_name):
        signals = [e for e in entries if isinstance(e, Signal)]
        if not signals:
            U[:, i] = entries
            specs.append(constant_spec(0.0))
        elif len(signals) == runs and all(s is signals[0] for s in signals):
            specs.append(signals[0].native_spec())
        else:
            return None
    return specs, U


def _input_entries(mod, u):
    """Per input of one run: its Signal, or its constant value."""
    specs = input_specs(mod, u)
    if isinstance(u, dict):
        from .runtime.arguments import key_name
        by_name = {key_name(k): v for k, v in u.items()}
        return [by_name[name] if isinstance(by_name.get(name), Signal) else spec[1]
                for name, spec in zip(mod.inputs, specs)]
    return [spec[1] for spec in specs]


# ---------------------------------------------------------------- the plan and one chunk


@dataclass
class Plan:
    """What every chunk shares: the times, the method and tolerances, what to compute, and (for
    the C batch) the shared input specs. Small and picklable: it travels with each Dask task."""

    t_span: tuple
    t_eval: np.ndarray
    method: str
    rtol: float
    atol: object
    options: dict
    outputs: bool
    batch: bool
    specs: Optional[list] = None
    dim: int = 0
    n_outputs: int = 0
    n_constraints: int = 0
    sensitivities: tuple = ()


@dataclass
class Part:
    """One chunk of runs [start, start + len(Y0)): their initial states, parameters and inputs
    (U for the C batch, else the list of per-run inputs)."""

    start: int
    Y0: np.ndarray
    P: np.ndarray
    inputs: object

    def __len__(self):
        return len(self.Y0)


def empty_part_result(plan, m):
    """The arrays of one chunk's results, to be filled (states NaN until written)."""
    k = len(plan.t_eval)
    out = {"y": np.full((m, plan.dim, k), np.nan), "status": np.zeros(m, dtype=np.intc),
           "nfev": np.zeros(m, dtype=np.dtype("l")), "success": np.zeros(m, dtype=bool)}
    if plan.n_constraints:
        out["multipliers"] = np.full((m, plan.n_constraints, k), np.nan)
    if plan.outputs:
        out["outputs"] = np.full((m, plan.n_outputs, k), np.nan)
    if plan.sensitivities:
        out["sensitivities"] = np.full((m, len(plan.sensitivities), plan.dim, k), np.nan)
    return out


def solve_part(mod, plan, part, out=None, stop=None):
    """Solve one chunk; fill `out` (arrays of `empty_part_result`, or new ones) and return it
    with also `message` and `engines` (lists) and `transitions` (None or a list per run)."""
    m = len(part)
    if out is None:
        out = empty_part_result(plan, m)
    stop = np.zeros(1, dtype=np.intc) if stop is None else stop
    out["message"] = [""] * m
    out["engines"] = ["native"] * m
    out["transitions"] = None
    if plan.batch:
        rerun = _solve_batch(mod, plan, part, out, stop)
    else:
        rerun = range(m)
    for i in rerun:
        if stop[0]:
            break
        with RUN_STOP.stopping(stop):
            _one_run(mod, plan, part, i, out)
    done = out["status"] != -2
    out["success"][:] = (out["status"] >= 0) & done
    for i in np.flatnonzero(done & (out["status"] >= 0)):
        if not out["message"][i]:
            out["message"][i] = MESSAGES[int(out["status"][i])]
    return out


def _solve_batch(mod, plan, part, out, stop):
    """The chunk in one call into C; returns the indices of the runs to redo on the per-run
    path (failures, whose error message and partial states come from `simulate`)."""
    from .native import _ode as _native
    cm = mod.compiled_model
    rtol, atol = _tolerances(plan.rtol, plan.atol, plan.dim)
    jac = cm.function_address("jacobian") if BY_NAME[plan.method].stiff else 0
    events = native_events(mod) if mod.event_definitions else None
    ev_addr, ev_max, ev_dir = _event_arrays(events)
    extras = []
    if plan.n_constraints:
        extras.append((cm.function_address("constraint_forces"), plan.n_constraints,
                       out["multipliers"]))
    if plan.outputs:
        extras.append((cm.function_address("outputs"), plan.n_outputs, out["outputs"]))
    P = part.P if part.P.shape[1] else np.zeros((len(part), 1))
    redo = _inconsistent_starts(mod, plan, part)
    pivots = np.ones(len(part))
    _native.solve_batch(plan.method, cm.function_address("rhs"), jac, plan.dim,
                        np.ascontiguousarray(part.Y0), np.ascontiguousarray(P), plan.specs,
                        np.ascontiguousarray(part.inputs), float(plan.t_span[0]),
                        float(plan.t_span[1]), rtol, atol,
                        float(plan.options.get("max_step", np.inf)),
                        float(plan.options.get("first_step") or 0.0), plan.t_eval, ev_addr,
                        ev_max, ev_dir, True, extras, out["y"], out["status"], out["nfev"], stop,
                        int(plan.options.get("max_steps") or 0),
                        float(plan.options.get("max_wall_time") or 0.0),
                        cm.function_address("pivot_record"), pivots)
    warn_near_singular_runs(mod, part, pivots, plan.rtol)
    return sorted(set(redo) | set(np.flatnonzero(out["status"] == -1).tolist()))


def warn_near_singular_runs(mod, part, pivots, rtol):
    """One NearSingularMassMatrixWarning naming the runs of the chunk `part` whose least relative
    pivot of M (`pivots`, per run) is below `near_singular_limit(rtol)`."""
    low = np.flatnonzero(pivots < near_singular_limit(rtol))
    if len(low):
        warn_near_singular(mod, float(pivots[low].min()), rtol,
                           runs=[part.start + int(i) for i in low])


def _inconsistent_starts(mod, plan, part):
    """Runs of a constrained model whose initial state `simulate` rejects (redundant
    constraints): they go to the per-run path, which reports the error."""
    if not plan.n_constraints:
        return []
    from .constraints import check_state
    bad = []
    t0 = float(plan.t_span[0])
    for i in range(len(part)):
        try:
            check_state(mod, t0, part.Y0[i], part.P[i], _run_u(mod, plan, part, i, t0))
        except (LagrgenError, np.linalg.LinAlgError, ArithmeticError):
            bad.append(i)
    return bad


def _run_u(mod, plan, part, i, t):
    from .native import _ode as _native
    return np.array([part.inputs[i, j] if spec[0] == "constant" else
                     _native.signal_values(tuple(spec), t)[0]
                     for j, spec in enumerate(plan.specs or ())])


def _run_inputs_for_simulate(mod, plan, part, i):
    """The `inputs` argument of run i for `simulate` (from U and the shared specs, or as given)."""
    if not plan.batch:
        return part.inputs[i]
    values = {}
    for j, (name, spec) in enumerate(zip(mod.inputs, plan.specs)):
        values[name] = float(part.inputs[i, j]) if spec[0] == "constant" else _signal_of(spec)
    return values


def _signal_of(spec):
    kind, _, ts, values, _ = spec
    return Signal(ts, values, kind=kind)


def _one_run(mod, plan, part, i, out):
    """Run i of the chunk through `lagrgen.simulate`, into row i of `out`; a failure of the run
    itself (not of the arguments) is kept in its row."""
    k = len(plan.t_eval)
    for key in ("y", "multipliers", "outputs", "sensitivities"):
        if key in out:
            out[key][i] = np.nan
    try:
        sol = simulate(mod, plan.t_span, part.Y0[i], method=plan.method, params=part.P[i],
                       inputs=_run_inputs_for_simulate(mod, plan, part, i), rtol=plan.rtol,
                       atol=plan.atol, t_eval=plan.t_eval,
                       sensitivities=list(plan.sensitivities) or None, **plan.options)
    except (LagrgenError, np.linalg.LinAlgError, FloatingPointError, ArithmeticError) as exc:
        out["status"][i], out["nfev"][i], out["message"][i] = -1, 0, str(exc)
        out["engines"][i] = "scipy" if not plan.batch else "native"
        return
    saved = min(sol.y.shape[1], k)
    out["y"][i, :, :saved] = sol.y[:, :saved]
    out["status"][i], out["nfev"][i] = int(sol.status), int(sol.nfev)
    out["message"][i] = str(sol.message)
    out["engines"][i] = getattr(sol, "engine", "scipy")
    if "multipliers" in out:
        out["multipliers"][i, :, :saved] = run_multipliers(mod, sol)[:, :saved]
    if "outputs" in out:
        out["outputs"][i, :, :saved] = evaluate_outputs(mod, sol)[:plan.n_outputs, :saved]
    if "sensitivities" in out:
        out["sensitivities"][i, :, :, :saved] = sol.sensitivities[:, :, :saved]
    transitions = getattr(sol, "transitions", None)
    if transitions is not None:             # non-smooth models (impacts, friction): one list per run
        if out["transitions"] is None:
            out["transitions"] = [None] * len(part)
        out["transitions"][i] = list(transitions)


# ---------------------------------------------------------------- the driver


def batch_reason(mod, method, options, sensitivities=()):
    """Why the runs cannot go through the C batch (a str), or None when they can. The hook for
    non-smooth models: a model with impacts or frictions (`nonsmooth_definitions`)
    runs per run, where `simulate` gives each run's transitions, until the batch collects them;
    so do runs with sensitivities (each on the native engine when it can run them)."""
    if options.get("engine") == "scipy":
        return "engine='scipy'"
    if sensitivities:
        return "the sensitivities are integrated per run"
    rest = {k: v for k, v in options.items() if k not in ENSEMBLE_OPTIONS}
    why = native_reason(mod, method, None, None, rest)
    if why:
        return why
    if is_hybrid(mod):
        return "the transitions of a non-smooth model are collected per run"
    return None


def simulate_many(mod, t_span, y0=None, params=None, inputs=None, t_eval=None, method="RK45",
                  rtol=1e-6, atol=1e-9, workers=None, client=None, progress=None, outputs=False,
                  store=None, sensitivities=None, **options):
    """Integrate many runs of `mod` that share `t_span` and `t_eval`.

    Parameters
    ----------
    mod : a built model (either backend)
    y0 : one state (2n,) or a dict, or one per run: (runs, 2n) or a list (None: the model's
        `initial_state`)
    params : None, one vector or dict, an (runs, n_params) array, or a list of dicts/vectors
    inputs : None or one dict shared by all runs, a list of dicts (one per run), or an
        (runs, n_inputs) array of constant inputs
    t_eval : the output times (required: every run is sampled on them)
    method, rtol, atol, **options : as for `lagrgen.simulate`
    workers : threads on this machine (default: every core for a compiled model, 1 otherwise)
    client : a `dask.distributed.Client`: the runs go to its workers in chunks (the compiled
        model's module is uploaded to the workers once per client)
    progress : True or False: a progress bar of the finished runs (tqdm) on stderr; None or
        "auto" (default): only on a terminal, once the ensemble has taken a second
    outputs : also evaluate the model's outputs (`mod.output_names`) at every output time
    store : None, or the path of a Zarr store (needs the `ensembles` extra): each chunk is
        written there as it finishes (by the Dask workers themselves with a client), and the
        whole result is never held in memory
    sensitivities : parameter names (and `y0:<state>` names), as for `simulate`: each run
        integrates its forward sensitivities ∂y(t)/∂p_j with its state (one `simulate` per run,
        natively when it can; with a client the model's compiled derivatives go to the workers
        with its module). Its states are then those of `simulate(..., sensitivities=...)`: the
        error control covers the sensitivities too.

    Returns
    -------
    Without `store`: an EnsembleResult with t (len(t_eval),), y (runs, 2n, len(t_eval)),
    success, status, nfev, message (one per run), multipliers (constrained models), outputs
    (with outputs=True), sensitivities (runs, k, 2n, len(t_eval)) and sensitivity_names (with
    sensitivities); `to_xarray()` labels it. With `store`: the store opened lazily as an
    `xarray.Dataset` (`lagrgen.open_ensemble(store)`): the same variables as `to_xarray()`,
    read from disk when used, with `attrs["messages"]` = {run: message} for the runs that did
    not end normally.
    The number of runs is the largest of the per-run arguments. Ctrl-C stops every chunk that
    is running (within a run's time) and raises KeyboardInterrupt.
    """
    if t_eval is None:
        raise ValueError("simulate_many needs t_eval: every run is sampled at the same times")
    check_run_options(method, options.get("engine"), options, "simulate_many",
                      ENSEMBLE_OPTIONS + ("events",))
    if workers is not None and (int(workers) != workers or workers < 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    if client is not None and workers is not None:
        raise ValueError("give either workers (threads here) or client (Dask workers), not both")
    if client is not None and not callable(getattr(client, "scheduler_info", None)):
        raise TypeError(f"client must be a dask.distributed.Client, got {type(client).__name__}")
    t0, tf = time_span(t_span)
    rest = {k: v for k, v in options.items() if k not in ENSEMBLE_OPTIONS}
    rtol, atol, t_eval, max_steps, max_wall_time, rest = checked_options(
        rtol, atol, (t0, tf), t_eval, options.get("max_steps"), options.get("max_wall_time"),
        rest)
    refuse_switching_options(mod, rest)
    options = dict(rest, **{k: v for k, v in (("engine", options.get("engine")),
                                              ("max_steps", max_steps),
                                              ("max_wall_time", max_wall_time))
                            if k in options})
    if len(t_eval) == 0:
        raise ValueError("t_eval must hold at least one time")
    Y0, P, run_inputs = ensemble_arguments(mod, mod.initial_state if y0 is None else y0,
                                           params, inputs)
    runs = len(Y0)
    if runs == 0:
        raise ValueError("simulate_many needs at least one run")
    check_quaternion(mod.coordinates, np.transpose(Y0))
    if is_hybrid(mod):
        check_hybrid_run(mod, (t0, tf), stacklevel=3)
        check_starts(mod, t0, Y0, P, run_inputs, options.get("gap_tol"))
    sensitivities = sensitivity_names(mod, sensitivities, options)
    why_not = batch_reason(mod, method, options, sensitivities) if mod.backend == "c" else \
        "the model is not compiled"
    packed = None if why_not else batch_inputs(mod, inputs, run_inputs)
    if packed is not None and np.ndim(rtol) == 0:
        specs, U = packed
        _tolerances(rtol, atol, 2 * mod.n_coordinates)   # argument errors before any run
        for j, name in enumerate(mod.inputs):
            if np.any(np.isnan(U[:, j])):
                raise ValueError(f"input {name!r} is NaN in some run")
    else:
        specs, U = None, None
    plan = Plan(t_span=(t0, tf), t_eval=t_eval, method=method, rtol=rtol, atol=atol,
                options=dict(options), outputs=bool(outputs), batch=specs is not None,
                specs=specs, dim=2 * mod.n_coordinates,
                n_outputs=len(mod.output_names) if outputs else 0,
                n_constraints=len(multiplier_names(mod)), sensitivities=sensitivities)
    if outputs and not hasattr(mod, "outputs"):
        raise ValueError(f"model {mod.name!r} has no outputs function")
    parallel = len(client.scheduler_info().get("workers", {})) if client is not None else \
        int(workers) if workers is not None else \
        (os.cpu_count() or 1) if mod.backend == "c" else 1
    size = max(1, min(MAX_CHUNK, math.ceil(runs / (4 * max(parallel, 1)))))
    parts = [Part(a, Y0[a:a + size], P[a:a + size],
                  U[a:a + size] if plan.batch else run_inputs[a:a + size])
             for a in range(0, runs, size)]
    meta = ensemble_meta(mod, plan, P)
    if store is not None:
        from .ensemble_store import create_store, finish_store, open_ensemble, store_path
        store = store_path(store)
        create_store(store, meta, runs, size)
        sink = StoreSink(store)
    else:
        sink = MemorySink(plan, runs)
    with RunsBar(runs, "auto" if progress is None else progress, mod.name) as bar:
        if client is not None:
            _on_dask(client, mod, plan, parts, sink, bar)
        else:
            _on_threads(mod, plan, parts, max(1, parallel), sink, bar)
    if store is not None:
        finish_store(store, sink.messages)
        return open_ensemble(store)
    return sink.result(mod, plan, meta)


def sensitivity_names(mod, names, options):
    """The `sensitivities` names of `simulate_many` as a tuple (empty for None), checked once
    for all runs as `simulate` checks them."""
    if names is None:
        return ()
    from .sensitivity import checked_names
    return checked_names(mod, names, options.get("events"))


def check_starts(mod, t0, Y0, P, run_inputs, gap_tol=None):
    """ContactError naming the first run of a model with impacts or frictions that starts
    inside a surface or whose restitution or friction coefficients are out of range."""
    from .hybrid import GAP_TOL, check_start
    from .runtime.arguments import input_function
    for i in range(len(Y0)):
        u = input_function(mod, run_inputs[i])(t0)
        check_start(mod, t0, Y0[i], P[i], u, GAP_TOL if gap_tol is None else gap_tol, run=i)


def multiplier_names(mod):
    """The rows of an ensemble's `multipliers`: the model's constraints, then (a model with
    impacts or frictions) each impact's contact force and each friction's force."""
    return tuple(mod.constraint_names) + (force_names(mod) if is_hybrid(mod) else ())


def run_multipliers(mod, sol):
    """The `multiplier_names(mod)` rows of one run's result."""
    rows = [sol.constraint_forces] if mod.n_constraints else []
    if is_hybrid(mod):
        rows.append(sol.contact_forces)
    return np.concatenate(rows)


def ensemble_meta(mod, plan, P):
    """What labels the results: names, units, parameters per run, times."""
    coordinates = tuple(mod.coordinates)
    return {"model": mod.name, "coordinates": coordinates,
            "states": coordinates + tuple(f"{c}_dot" for c in coordinates),
            "parameters": tuple(mod.parameters), "params": P, "t": plan.t_eval,
            "output_names": tuple(mod.output_names) if plan.outputs else (),
            "constraint_names": multiplier_names(mod),
            "elements": tuple(d[0] for d in mod.nonsmooth_definitions) + tuple(
                stop[0] for stop in mod.info.limit_stops),
            "units": dict(mod.units), "sensitivity_names": plan.sensitivities,
            "method": getattr(plan.method, "__name__", str(plan.method)),
            "rtol": float(np.max(plan.rtol)), "atol": float(np.max(plan.atol))}


class MemorySink:
    """Collects the chunks into whole arrays (runs first)."""

    def __init__(self, plan, runs):
        self.arrays = empty_part_result(plan, runs)
        self.message = [""] * runs
        self.engines = [""] * runs
        self.transitions = None

    def views(self, part):
        """Row slices of the whole arrays for a chunk solved here (written in place)."""
        return {k: v[part.start:part.start + len(part)] for k, v in self.arrays.items()}

    def take(self, part, result, in_place=False):
        a, b = part.start, part.start + len(part)
        if not in_place:
            for key, value in self.arrays.items():
                value[a:b] = result[key]
        self.message[a:b] = result["message"]
        self.engines[a:b] = result["engines"]
        if result.get("transitions") is not None:
            if self.transitions is None:
                self.transitions = [None] * len(self.message)
            self.transitions[a:b] = result["transitions"]

    def result(self, mod, plan, meta):
        arr = self.arrays
        return EnsembleResult(
            t=plan.t_eval, y=arr["y"], success=arr["success"],
            status=arr["status"].astype(int), nfev=arr["nfev"].astype(int),
            message=self.message, coordinates=meta["coordinates"], engines=self.engines,
            multipliers=arr.get("multipliers"), outputs=arr.get("outputs"), params=meta["params"],
            parameter_names=meta["parameters"], output_names=meta["output_names"],
            constraint_names=meta["constraint_names"], units=meta["units"],
            model_name=meta["model"], transitions=self.transitions,
            settings={k: meta[k] for k in ("method", "rtol", "atol")},
            sensitivities=arr.get("sensitivities"), sensitivity_names=meta["sensitivity_names"])


class StoreSink:
    """Chunks go to a Zarr store (written by whoever solved them); only the messages of the
    runs that did not end normally are kept here, for the store's `messages` attribute."""

    def __init__(self, path):
        self.path = str(path)
        self.messages = {}

    def views(self, part):
        return None

    def take(self, part, result, in_place=False):
        for i, (status, message) in enumerate(zip(result["status"], result["message"])):
            if int(status) not in (0, 1):        # the end, or a terminal event: normal ends
                self.messages[str(part.start + i)] = message


def _solve_into(mod, plan, part, sink, stop):
    """Solve one chunk where it runs (thread or Dask worker) and write it to its place: the
    in-memory arrays (here), or the store."""
    if isinstance(sink, StoreSink):
        from .ensemble_store import write_part
        result = solve_part(mod, plan, part, stop=stop)
        if not stop[0]:
            write_part(sink.path, part.start, result)
        return {"message": result["message"], "status": result["status"],
                "engines": result["engines"], "transitions": result["transitions"],
                "stopped": bool(stop[0])}
    views = sink.views(part)
    result = solve_part(mod, plan, part, out=views, stop=stop)
    result["stopped"] = bool(stop[0])
    return result


class RunsBar:
    """A tqdm bar of the finished runs on stderr. `show`: True, False, or "auto" (only on a
    terminal, and only once the ensemble has taken a second, like `simulate`'s bar)."""

    def __init__(self, total, show, name):
        self.total, self.name, self.bar = total, name, None
        self.auto = show == "auto"
        self.show = bool(show) and (not self.auto or sys.stderr.isatty())

    def __enter__(self):
        if self.show:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, unit="run", desc=self.name or "runs",
                            file=sys.stderr, leave=True, dynamic_ncols=True,
                            delay=1.0 if self.auto else 0.0)
        return self

    def update(self, k):
        if self.bar is not None:
            self.bar.update(k)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()


def _on_threads(mod, plan, parts, workers, sink, bar):
    """The chunks on `workers` threads (even for one: the main thread only waits, so Ctrl-C
    reaches it at once; it then sets the shared stop flag that every running batch reads).

    The main thread takes no lock that a worker needs, so that a KeyboardInterrupt at any moment
    of it leaves none held: the chunks to solve and the chunks solved pass through
    `queue.SimpleQueue`s (written in C), and the threads are started by `_thread` (a
    `threading.Thread` waits on a Python-level Condition to start). `concurrent.futures`
    deadlocked here: waiting, it took every pending future's lock in a Python loop, and
    submitting, its idle Semaphore's; an interrupt inside either left a lock held that a worker
    then waited on for ever."""
    stop = np.zeros(1, dtype=np.intc)
    todo, finished = queue.SimpleQueue(), queue.SimpleQueue()
    for part in parts:
        todo.put(part)
    running = 0
    try:
        for _ in range(min(workers, len(parts))):
            _thread.start_new_thread(_chunk_worker, (mod, plan, sink, stop, todo, finished))
            running += 1
        left = len(parts)
        while left:
            item = _next_finished(finished)
            if item is None:                            # a thread found no chunk left
                running -= 1
                if not running:
                    raise RuntimeError("the ensemble's threads ended with chunks unsolved")
                continue
            part, result, error = item
            left -= 1
            if error is not None:
                raise error
            sink.take(part, result, in_place=isinstance(sink, MemorySink))
            bar.update(len(part))
    except BaseException:
        stop[0] = 1
        raise
    finally:
        while running:                                  # each thread's end: no chunk under way
            if _next_finished(finished) is None:
                running -= 1


def _chunk_worker(mod, plan, sink, stop, todo, finished):
    """One ensemble thread: solves chunks from `todo` until it is empty or `stop` is set, each
    put on `finished` as (part, result, None) or (part, None, the exception); then None."""
    try:
        while not stop[0]:
            try:
                part = todo.get_nowait()
            except queue.Empty:
                break
            try:
                finished.put((part, _solve_into(mod, plan, part, sink, stop), None))
            except BaseException as exc:        # noqa: B036 — the main thread raises it
                finished.put((part, None, exc))
    finally:
        finished.put(None)


def _next_finished(finished):
    """The next item put on `finished`, waiting in short slices so that Ctrl-C is seen."""
    while True:
        try:
            return finished.get(timeout=0.1)
        except queue.Empty:
            pass


_SCATTERED = {}
_SCATTER_LOCK = threading.Lock()


def _worker_target(client, mod, labels=()):
    """What a Dask task needs to find the model: a compiled model's module by content — its
    name, the SHA-256 of its file and the file's bytes (scattered to the workers once per client
    and content) — with the units compiled on first use that the runs call (`labels`, compiled
    here first, shipped the same way), or the model object itself. A model rebuilt under the
    same name is another content, so another file on the workers: never the module a worker
    loaded before."""
    if mod.backend != "c":
        return ("object", mod, ())
    from .runtime import units as runtime_units
    shipped_units = []
    for label in labels:
        with runtime_units.LOCK:
            unit = runtime_units.unit_module(mod.__file__, mod.compiled_model.info, label)
        shipped_units.append((label, unit.__name__, *_shipped_file(client, unit.__file__)))
    return ("module", (mod.__name__, *_shipped_file(client, mod.__file__)),
            tuple(shipped_units))


def _shipped_file(client, path):
    """(file name, SHA-256, the file's bytes scattered to every worker) of the file `path`,
    scattered once per client and content. Bytes the cluster no longer holds
    (`client.restart()`, lost workers), or held for another client that had this one's id and
    scheduler, are shipped again."""
    with open(path, "rb") as f:
        data = f.read()
    digest = hashlib.sha256(data).hexdigest()
    key = (id(client), client.scheduler.address, digest)
    with _SCATTER_LOCK:
        cached = _SCATTERED.get(key)
        if cached is None or cached.client is not client or cached.status != "finished":
            for stale in [k for k, f in _SCATTERED.items() if f.client.status == "closed"]:
                del _SCATTERED[stale]       # keeps no closed client (and its bytes) alive
            _SCATTERED[key] = client.scatter(data, broadcast=True, hash=False)
        shipped = _SCATTERED[key]
    return os.path.basename(path), digest, shipped


def run_units(plan):
    """The labels of the units compiled on first use that the runs of `plan` call: that of the
    directional derivatives when they integrate sensitivities."""
    from .functions import BY_NAME as FUNCTIONS_BY_NAME
    return (FUNCTIONS_BY_NAME["directional_derivatives"].unit,) if plan.sensitivities else ()


def _on_dask(client, mod, plan, parts, sink, bar):
    """The chunks as Dask tasks: each returns compact arrays (or, with a store, writes its chunk
    itself and returns only the messages). A chunk's result is released on the worker as soon as
    it has been taken here, so the workers never hold more than the chunks under way."""
    from distributed import as_completed
    target = _worker_target(client, mod, run_units(plan))
    path = sink.path if isinstance(sink, StoreSink) else None
    futures = client.map(_dask_part, parts, target=target, plan=plan, store=path, pure=False)
    by_key = {f.key: part for f, part in zip(futures, parts)}
    try:
        for future in as_completed(futures):
            part = by_key.pop(future.key)
            sink.take(part, future.result())
            bar.update(len(part))
            future.release()
    except BaseException:
        client.cancel(futures)
        raise


def _dask_part(part, target, plan, store):
    """One chunk on a Dask worker: import the uploaded compiled model and offer it its uploaded
    units (or use the object)."""
    kind, value, shipped_units = target
    mod = _uploaded_module(*value) if kind == "module" else value
    for unit in shipped_units:
        _offer_unit(mod, *unit)
    stop = np.zeros(1, dtype=np.intc)
    if store is None:
        return solve_part(mod, plan, part, stop=stop)
    return _solve_into(mod, plan, part, StoreSink(store), stop)


_WORKER_MODULES = {}
_WORKER_LOCK = threading.Lock()


def _uploaded_module(name, filename, digest, data):
    """The compiled model of content `digest` in this Dask worker's process: its bytes written
    once under a content-addressed name in the worker's directory (`_worker_file`) and imported
    by that path once per process (not by name: a module of the same name elsewhere on
    sys.path, such as the model's description or an earlier build of it, must not shadow it)."""
    from .cache import import_extension
    with _WORKER_LOCK:
        if digest not in _WORKER_MODULES:
            path = _worker_file(name, filename, digest, data)
            _WORKER_MODULES[digest] = import_extension(name, path)
        return _WORKER_MODULES[digest]


def _offer_unit(mod, label, name, filename, digest, data):
    """Make the uploaded unit `label` (module `name`) the one the uploaded model `mod` finds
    when it first calls a function of that unit (`lagrgen.units.provide`)."""
    from .units import provide
    with _WORKER_LOCK:
        provide(mod.__file__, label, name, _worker_file(name, filename, digest, data))


def _worker_file(name, filename, digest, data):
    """The path of the uploaded file of content `digest` in this worker's directory: written
    once (atomically, never over a file a process may have loaded), checked against the
    digest."""
    from distributed import get_worker

    from .cache import file_digest
    from .toolchain import write_atomic
    if hashlib.sha256(data).hexdigest() != digest:
        raise LagrgenError(f"the compiled module {name!r} arrived damaged on this Dask worker "
                           "(its SHA-256 differs from the client's)")
    path = Path(get_worker().local_directory) / f"lagrgen-{digest[:32]}-{filename}"
    if not (path.is_file() and file_digest(path) == digest):
        write_atomic(path, data, 0o755)
    return path
