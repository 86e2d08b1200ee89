"""Mesh refinement: solve on the problem's grid, measure every interval's discretization error
(`accuracy`), and, while it exceeds the tolerance, split the intervals where it does and solve
again from the last solution, until the error is within the tolerance or the meshes run out.

After the first mesh (the problem's grid and scheme as given) the states are collocated with
Hermite–Simpson on the refined mesh. An input that has chattered or switched at its bounds (on any
mesh so far: `inputs_switching`) stays one polynomial per interval of the problem's grid (quadratic
for Hermite–Simpson, linear for the other schemes: `grid.ControlMesh`): the refinement makes the
motion that the inputs produce exact, without giving the optimizer finer inputs to chatter with. A
discretization coarser than the inputs is what a chattering optimum exploits (a brachistochrone by
minimum time beats the cycloid with an input flipping between its bounds from point to point); with
the states resolved inside each input's interval that gain is gone. Where such an input switches
between its bounds (a bang-bang optimum), the control intervals of the switch get knots around the
switching time, narrowed each mesh until the switch spans at most √mesh_tol of the duration, so the
switching time is located rather than smeared over an interval of the grid. The other inputs, those
that ride a bound once or never reach one, are refined with the states (a quadratic per interval of
the mesh): tied to a coarse grid, a smooth optimum (a robot's least-effort move riding its velocity
limits) is a harder problem than it is, and IPOPT crawls on it; and an arc at a bound shorter than
an interval of the grid (the Panda's least-time move starts and ends with a burst of ~5 ms at the
first joint's torque limit, on intervals of 15 ms) is held to a quadratic that cannot follow it:
tied, its least time came out 0.27 % longer.

An interval with error e > mesh_tol/MARGIN is split into ⌈(MARGIN·e/mesh_tol)^(1/(p+1))⌉ pieces,
at least 2 and at most MAX_PIECES per mesh, where p is the order of the local error e ∝ h^(p+1):
Hermite–Simpson's 4 on smooth motions; from the third mesh on, each interval takes the order its
interval of the mesh before showed when the last refinement split it (`observed_orders`), lower
where the motion is not smooth (an input at its bound, a velocity riding its limit: on the Panda's
least-effort move most intervals show 1.5 to 3.5, and splitting them all for 4 left three above
the tolerance and took a fourth mesh). After the first mesh of a trapezoidal or backward-Euler
problem, whose errors say little of Hermite–Simpson's, intervals are split in halves. The margin
keeps the intervals just below the tolerance from crossing it on the next solve one at a time (a
mesh each).
"""
import time
import warnings
from dataclasses import replace

import numpy as np

from .accuracy import DEFAULT_MESH_TOL, DiscretizationWarning, interval_errors, \
    warn_if_coarse  # noqa: F401
from .grid import ControlMesh
from .result import MeshRecord

#: The most pieces one interval is split into per mesh.
MAX_PIECES = 8
#: A mesh has at most MAX_GROWTH times the nodes of the last, and never more than MAX_NODES.
MAX_GROWTH, MAX_NODES = 4, 20_000
#: The order of the local error of Hermite–Simpson's states (e ∝ h^(ORDER + 1)).
ORDER = 4
#: Intervals within this factor of the tolerance are split too, and pieces aim that far below it.
MARGIN = 4.0
#: The least order `observed_orders` gives an interval.
LEAST_ORDER = 1.0
#: A refined mesh's start is "near" its optimum (`solver.WARM_STARTS`) when the last mesh's
#: error is within this factor of mesh_tol, else "far".
NEAR = 1000.0
#: An input within this share of its range from a bound counts as on the bound.
ON_BOUND = 1e-3
#: A mesh whose new ties raise the objective by more than this many times the error is solved
#: again without them (`tying_cost`).
TIE_SLACK = 100.0
#: A switch is looked for between intervals saturated at opposite bounds at most this many
#: control intervals apart.
SWITCH_SPAN = 3


def solve_refined(problem, guess, settings, mesh_tol, max_meshes, start=None):
    """The CollocationResult of `problem` refined until its error is within `mesh_tol` (None:
    the problem's grid alone), with `errors`, `error` and `meshes`; from `start` = (the mesh, its
    ControlMesh or None, a shift in seconds) of the result `guess` when given (`resolve`: a warm
    start; with mesh_tol None the error is measured when first read)."""
    from .solver import solve_mesh
    if start is None:
        layout, controls, shift = problem.layout, None, 0.0
    else:
        layout, controls, shift = start
    knots = tuple(controls.knots if controls is not None else layout.node_fractions)
    degree = 2 if problem.scheme == "hermite-simpson" else 1
    meshes, spent, callbacks, limit, gave_up = [], 0.0, 0.0, None, None
    tied = frozenset() if controls is None else frozenset(controls.tied or ())
    result = solve_mesh(problem, layout, controls, guess, settings, shift=shift,
                        replan=start is not None)
    if start is not None and mesh_tol is None:
        if result.success:
            result.estimate_errors(stacklevel=3)
        return result
    while True:
        began = time.perf_counter()
        errors = interval_errors(result, mesh_tol or DEFAULT_MESH_TOL)
        spent += result.seconds + time.perf_counter() - began
        callbacks += result.callback_seconds
        meshes.append(MeshRecord(layout.nodes, result.iterations, float(errors.max()),
                                 result.objective, result.status, result.seconds,
                                 result.t.copy(), errors, result.solver))
        if settings.progress and mesh_tol is not None:
            print(f"mesh {len(meshes)}: {layout.nodes} nodes, {result.iterations} iterations, "
                  f"dynamics error {errors.max():.2e}", flush=True)
        if mesh_tol is None or not result.success or len(meshes) >= max_meshes:
            break
        switches, limit = next_knots(result, errors, knots, problem, mesh_tol)
        if switches is None:
            break
        knots = tuple(sorted(set(knots) | set(switches)))
        order = observed_orders(meshes, mesh_tol) if len(meshes) > (
            1 if problem.scheme == "hermite-simpson" else 2) else ORDER
        layout = refined_layout(layout, errors, mesh_tol, knots, order)
        new_ties = inputs_switching(result, problem, knots) - tied
        tied = tied | new_ties
        controls = ControlMesh(knots, degree, tied)
        if settings.solver == "auto" and result.sqp_failed:
            settings = replace(settings, solver="ipopt")
            gave_up = (len(meshes), result.sqp_failed)
        start = "near" if errors.max() <= NEAR * mesh_tol else "far"
        last, result = result, solve_mesh(problem, layout, controls, result, settings,
                                          start=start)
        if new_ties and tying_cost(last, result, errors.max(), mesh_tol) > 0:
            untied = ControlMesh(knots, degree, tied - new_ties)
            retry = solve_mesh(problem, layout, untied, last, settings, start=start)
            spent += result.seconds
            if retry.success and retry.objective < result.objective:
                result, tied, controls = retry, tied - new_ties, untied
    result.callback_seconds = callbacks
    if gave_up and not result.sqp_failed:
        mesh, result.sqp_failed = gave_up
        result.notes.append(f"the structured SQP failed on mesh {mesh} ({result.sqp_failed}): "
                            f"IPOPT solved it, and the meshes after it")
    result = finished(result, errors, meshes, mesh_tol, spent, limit)
    if result.success:
        result.estimate_errors(stacklevel=3)
    return result


def tying_cost(last, tied, error, mesh_tol):
    """How much a mesh whose inputs were newly tied to polynomials between the control knots
    (`inputs_switching`) lost against the mesh before it, beyond what the discretization can
    account for (TIE_SLACK times the larger of the last error and mesh_tol, relative): > 0 means
    the ties cost the optimum (a least-time pendulum's torque tied between 21 user knots rose
    from 1.004836 s to 1.006341 s), and the mesh is solved again with those inputs free."""
    if not (last.success and tied.success):
        return 0.0
    slack = TIE_SLACK * max(error, mesh_tol) * max(1.0, abs(last.objective))
    return tied.objective - last.objective - slack


def next_knots(result, errors, knots, problem, mesh_tol):
    """(the control knots a next mesh adds, None) when the refinement goes on; else (None, why
    it stops short of the tolerance, or None when it is within it)."""
    if not np.all(np.isfinite(errors)):
        return None, (f"as the model's dynamics cannot be integrated from the solution on "
                      f"{int(np.sum(~np.isfinite(errors)))} of its intervals (its rhs fails "
                      "there: a mass matrix that is not positive definite at these states or "
                      "parameters?)")
    switches = switch_knots(result, knots, problem, mesh_tol)
    if errors.max() <= mesh_tol and not switches:
        return None, None
    if result._layout.nodes >= MAX_NODES:
        return None, f"as the refinement reached its limit of {MAX_NODES} nodes"
    return switches, None


def finished(result, errors, meshes, mesh_tol, seconds, limit=None):
    """`result` with its errors, mesh history, totals and the verdict on its error."""
    result.errors, result.error, result.meshes = errors, float(errors.max()), tuple(meshes)
    result.iterations = sum(m.iterations for m in meshes)
    result.seconds = seconds
    result.mesh_tol = mesh_tol
    for name, (excess, when) in result.bound_excursions().items():
        result.notes.append(f"between the points the interpolated {name} leaves its bound by "
                            f"{excess:.2g} (largest near t = {when:.4g} s): collocation bounds "
                            "the states at its points only; a finer mesh shrinks it")
    if mesh_tol is None:
        warn_if_coarse(result.error, errors.size, stacklevel=5)
    elif result.success and result.error > mesh_tol:
        result.success = False
        stop = limit or f"after {len(meshes)} meshes ({meshes[-1].nodes} nodes)"
        solvers = " and ".join(sorted({m.solver.upper() if m.solver == "ipopt" else
                                       "the structured SQP" for m in meshes}))
        result.message = (f"{solvers} solved each mesh, but the dynamics error {result.error:.2e} "
                          f"still exceeds mesh_tol={mesh_tol:g} {stop}: raise max_meshes, give "
                          "more nodes or a larger mesh_tol (a motion that needs ever more nodes "
                          "may be stiff or undetermined: look at res.errors)")
    return result


def observed_orders(meshes, mesh_tol):
    """Per interval of the last mesh, the order p of the local error (e ∝ h^(p+1)) that its
    interval on the mesh before showed when split: p = log(e / e_c)/log(c) − 1 (e that
    interval's error, above mesh_tol, c its pieces, e_c their largest error), within
    [LEAST_ORDER, ORDER]; ORDER where its interval was not split or within mesh_tol."""
    before, after = meshes[-2], meshes[-1]
    f0, f1 = _fractions(before.times), _fractions(after.times)
    owner = np.clip(np.searchsorted(f0, 0.5 * (f1[:-1] + f1[1:])) - 1, 0, f0.size - 2)
    pieces = np.bincount(owner, minlength=f0.size - 1)
    worst = np.zeros(f0.size - 1)
    np.maximum.at(worst, owner, after.errors)
    orders = np.full(f0.size - 1, float(ORDER))
    split = (pieces >= 2) & (before.errors > mesh_tol) & (worst > 0)
    orders[split] = np.log(before.errors[split] / worst[split]) / np.log(pieces[split]) - 1
    return np.clip(orders, LEAST_ORDER, ORDER)[owner]


def _fractions(times):
    """Node times as fractions of the duration."""
    times = np.asarray(times, dtype=float)
    return (times - times[0]) / (times[-1] - times[0])


def refined_layout(layout, errors, mesh_tol, knots, order=ORDER):
    """The next mesh: each interval with error e > mesh_tol/MARGIN split into equal pieces for
    a local error of `order` (one for all intervals or one each; see the module; in halves
    after a mesh of another scheme), the control knots added as nodes; Hermite–Simpson."""
    nodes = layout.node_fractions
    target = mesh_tol / MARGIN
    ratio = np.maximum(errors, target) / target
    with np.errstate(over="ignore"):
        wanted = np.ceil(ratio ** (1.0 / (order + 1))) if layout.scheme == "hermite-simpson" \
            else 2          # another scheme's error says little of Hermite–Simpson's
        pieces = np.where(errors > target, np.clip(wanted, 2, MAX_PIECES), 1)
    pieces = within_budget(pieces, errors, min(MAX_GROWTH * layout.nodes, MAX_NODES))
    points = [nodes[:1]]
    for k, count in enumerate(pieces.astype(int)):
        inner = nodes[k] + (nodes[k + 1] - nodes[k]) * np.arange(1, count) / count
        points += [inner, nodes[k + 1:k + 2]]
    merged = np.concatenate(points)
    extra = [k for k in knots if np.min(np.abs(merged - k)) > 1e-12]
    merged = np.sort(np.concatenate([merged, extra]))
    return replace(layout, nodes=merged.size, scheme="hermite-simpson", mesh=tuple(merged))


def within_budget(pieces, errors, budget):
    """`pieces` cut so that the mesh has at most `budget` nodes: the added nodes of each interval
    scaled down alike, the worst intervals first when even one each is too many."""
    pieces = pieces.astype(int)
    added = pieces - 1
    room = budget - 1 - pieces.size
    if added.sum() <= room:
        return pieces
    scaled = np.floor(added * room / added.sum()).astype(int)
    scaled[(added > 0) & (scaled == 0)] = 1
    if scaled.sum() > room:
        order = np.argsort(-np.where(added > 0, errors, -np.inf))
        scaled = np.zeros_like(added)
        scaled[order[:max(room, 0)]] = 1
        scaled[added == 0] = 0
    return 1 + scaled


def inputs_switching(result, problem, knots):
    """The inputs (indices) that chatter or switch at their bounds: those that come back to a
    bound after leaving it (two runs of points on it or more), or go from one bound to the other
    within SWITCH_SPAN + 1 control intervals (`knots`): a bang-bang switch."""
    knots = np.asarray(knots)
    interval = np.clip(np.searchsorted(knots, result._layout.fractions, side="right") - 1, 0,
                       knots.size - 2)
    switching = set()
    for k, _, _, _, low, high in _inputs_at_bounds(result, problem):
        if max(_runs(low), _runs(high)) >= 2 or (low.any() and high.any() and np.abs(
                np.subtract.outer(interval[low], interval[high])).min() <= SWITCH_SPAN + 1):
            switching.add(k)
    return frozenset(switching)


def _inputs_at_bounds(result, problem):
    """(k, point values, lo, hi, on lo, on hi) of each free input k with a finite bound, "on" a
    bound within ON_BOUND of its range (of its largest magnitude when the range is infinite)."""
    for k in range(result._layout.nu):
        lo, hi = problem._bounds.get(("u", k), (-np.inf, np.inf))
        if k in problem._given or not (np.isfinite(lo) or np.isfinite(hi)) or hi <= lo:
            continue
        values = result._point_values("u", k)
        band = ON_BOUND * (hi - lo) if np.isfinite(hi - lo) else ON_BOUND * max(
            1.0, float(np.abs(values).max()))
        yield k, values, lo, hi, values <= lo + band, values >= hi - band


def _runs(flags):
    """How many runs of consecutive True there are in `flags`."""
    return int(flags[0]) + int(np.count_nonzero(flags[1:] & ~flags[:-1]))


def switch_knots(result, knots, problem, mesh_tol):
    """New control knots that narrow each input's switches between its bounds: where control
    intervals saturated at opposite bounds are at most SWITCH_SPAN apart and the intervals
    between them (the switch) span more than √mesh_tol of the duration, two knots around the
    switching time (where the input crosses the middle of its range), a sixteenth of that span
    (at least a quarter of √mesh_tol) on either side."""
    knots = np.asarray(knots)
    fractions = result._layout.fractions
    shortest = np.sqrt(mesh_tol)
    found = []
    for k, values, lo, hi, low, high in _inputs_at_bounds(result, problem):
        if not np.isfinite(hi - lo):
            continue
        side = _saturation(low, high, fractions, knots)
        for first, last in _switches(side):
            a, b = knots[first + 1], knots[last]
            if b - a <= shortest:
                continue
            s = _crossing(values, fractions, a, b, 0.5 * (lo + hi))
            half = max((b - a) / 16, shortest / 4)
            found += [k for k in (s - half, s + half) if a < k < b]
    return [k for k in found if np.min(np.abs(knots - k)) > 1e-12]


def _saturation(low, high, fractions, knots):
    """Per control interval: −1 (every point on the lower bound: `low`), +1 (on the upper:
    `high`) or 0."""
    side = []
    for a, b in zip(knots[:-1], knots[1:]):
        inside = (fractions >= a - 1e-12) & (fractions <= b + 1e-12)
        side.append(-1 if np.all(low[inside]) else 1 if np.all(high[inside]) else 0)
    return side


def _switches(side):
    """(first, last) control intervals saturated at opposite bounds with 1 to SWITCH_SPAN
    unsaturated intervals between them."""
    out = []
    saturated = [c for c, s in enumerate(side) if s]
    for first, last in zip(saturated[:-1], saturated[1:]):
        if side[first] == -side[last] and 1 <= last - first - 1 <= SWITCH_SPAN:
            out.append((first, last))
    return out


def _crossing(values, fractions, a, b, level):
    """Where the point values between the fractions a and b first cross `level` (linear
    between points); the middle of [a, b] if they do not."""
    inside = (fractions >= a - 1e-12) & (fractions <= b + 1e-12)
    f, v = fractions[inside], values[inside] - level
    change = np.flatnonzero(np.sign(v[:-1]) * np.sign(v[1:]) <= 0)
    if not change.size:
        return 0.5 * (a + b)
    j = change[0]
    if v[j] == v[j + 1]:
        return f[j]
    return f[j] + (f[j + 1] - f[j]) * v[j] / (v[j] - v[j + 1])
