"""What `Collocation.solve` returns: the motion at the nodes, the estimates, the solver's report,
and the ways to look at it (plot, animation, xarray) and to check it (a re-simulation)."""
import math
from dataclasses import dataclass, field

import numpy as np

from .grid import interpolate_rows

#: IPOPT's return codes, by value.
IPOPT_STATUS = {
    0: "Solve_Succeeded", 1: "Solved_To_Acceptable_Level", 2: "Infeasible_Problem_Detected",
    3: "Search_Direction_Becomes_Too_Small", 4: "Diverging_Iterates",
    5: "User_Requested_Stop", 6: "Feasible_Point_Found", -1: "Maximum_Iterations_Exceeded",
    -2: "Restoration_Failed", -3: "Error_In_Step_Computation", -4: "Maximum_CpuTime_Exceeded",
    -5: "Maximum_WallTime_Exceeded", -10: "Not_Enough_Degrees_Of_Freedom",
    -11: "Invalid_Problem_Definition", -12: "Invalid_Option", -13: "Invalid_Number_Detected",
    -100: "Unrecoverable_Exception", -101: "NonIpopt_Exception_Thrown", -102: "Insufficient_Memory",
    -199: "Internal_Error"}


@dataclass(frozen=True)
class MeshRecord:
    """One mesh of a solve: its nodes, the solver's iterations, status and objective there, the
    largest relative dynamics error of its intervals, (for pictures) the node times and each
    interval's error, and which solver gave its answer ("ipopt" or "sqp")."""
    nodes: int
    iterations: int
    error: float
    objective: float
    status: int
    seconds: float
    times: np.ndarray = field(default=None, repr=False, compare=False)
    errors: np.ndarray = field(default=None, repr=False, compare=False)
    solver: str = "ipopt"


class Deviation(float):
    """The largest deviation abs(y_simulated − y_collocated) over the nodes and states (a float;
    inf when the re-simulation stopped early), with `by_state` (name -> its largest deviation),
    the `simulation` it came from and its `message` ("" when it reached the end)."""

    def __new__(cls, value, by_state, simulation, message=""):
        obj = super().__new__(cls, value)
        obj.by_state, obj.simulation, obj.message = by_state, simulation, message
        return obj

    def __repr__(self):
        worst = max(self.by_state, key=self.by_state.get)
        return f"Deviation({float(self):.3g}, worst {worst!r})"


class CollocationResult:
    """The solution of a `Collocation` problem.

    Attributes
    ----------
    success, status, message : whether the solver converged, its return code and message (IPOPT's;
        the SQP's 0 to tol, 1 on a flat optimum looser than tol as IPOPT's acceptable level, −1)
    iterations, objective : IPOPT's iterations and the objective at the solution
    t : (nodes,) node times; y : (2n, nodes) [q; q̇]; u : (n_inputs, nodes); qdd : (n, nodes)
    multipliers : (n_constraints, nodes) the constraints' λ (constrained models)
    params, stderr : {name: value} of the unknown parameters and their standard errors (from the
        data term; NaN without data or success, inf for those the data do not determine)
    cov : covariance of the unknown parameters (k, k), or None
    unidentified, unseen : the parameters the data do not determine, and the combinations
        (dicts name -> component) along which the fit does not change (an IdentifiabilityWarning
        names them)
    at_bounds : the parameters whose estimate sits on a bound (flagged by a FitWarning)
    duration : T
    coordinates, inputs : names
    constraint_violation : the largest violation of any constraint (bounds included)
    error : the largest relative dynamics error of an interval (`lagrgen.collocation.accuracy`)
    errors : (intervals,) each interval's, on the final mesh
    meshes : the refinement's history, one `MeshRecord` (nodes, iterations, error, objective,
        status, seconds, solver) per mesh
    mesh_tol : the tolerance of the error the refinement worked to (None: the grid as given)
    seconds : wall time of the solve over every mesh (after the problem's units were made)
    callback_seconds : the part of it spent evaluating the NLP (the rest is the solver's own)
    solve_seconds : wall time of the last mesh's solve (of `Collocation.resolve`: the whole
        re-plan, every mesh of it)
    solver : "ipopt" or "sqp", the solver of the last mesh (`Collocation.solve`'s solver=)
    sqp_failed : why the structured SQP gave up on a mesh of the solve, which IPOPT then solved
        from the same start (under solver="auto" the later meshes too; a note says so), or ""
    notes : what the solve adjusted and says so (an initial value on a bound clipped, a state
        whose interpolant leaves its bound between the points: `bound_excursions`, ...)
    x : the decision vector (a warm start for another solve)
    """

    sqp_failed = ""

    def __init__(self, **fields):
        self.__dict__.update(fields)

    def __getattr__(self, name):
        """`errors`, `error`, `meshes` and `mesh_tol` of a re-plan (`Collocation.resolve`
        without mesh_tol), measured when first read (a re-plan in a loop need not pay for it),
        with the DiscretizationWarning of a solve on its grid as given when the error is large."""
        if name in ("errors", "error", "meshes", "mesh_tol") and "x" in self.__dict__:
            from .accuracy import interval_errors, warn_if_coarse
            errors = interval_errors(self)
            self.errors, self.error, self.mesh_tol = errors, float(errors.max()), None
            warn_if_coarse(self.error, errors.size, stacklevel=3)
            self.meshes = (MeshRecord(self._layout.nodes, self.iterations, self.error,
                                      self.objective, self.status, self.seconds,
                                      self.t.copy(), errors, self.solver),)
            return self.__dict__[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @classmethod
    def from_solution(cls, problem, tr, x, info, iterations, seconds, hessian):
        L, mod = tr.layout, problem.mod
        Z = L.point_block(x)
        nodes = L.node_points
        T = float(L.duration(x)) if L.free else problem.duration_bounds[0]
        t_points = tr.point_times(T)
        status = int(info["status"])
        params = {mod.parameters[j]: float(x[L.p_start + k]) for k, j in enumerate(L.unknown)}
        g = tr.constraints(x)
        violation = max(float(np.max(np.maximum(tr.g_lo - g, g - tr.g_hi), initial=0.0)),
                        float(np.max(np.maximum(tr.lo - x, x - tr.hi), initial=0.0)))
        full = np.array(problem.params)
        full[list(L.unknown)] = x[L.p_start:L.p_start + len(L.unknown)]
        message = info["status_msg"]
        message = message.decode() if isinstance(message, bytes) else str(message)
        return cls(
            success=status in (0, 1), status=status, message=message,
            iterations=int(iterations), objective=objective_at(tr, x, info, status),
            t=t_points[nodes], y=Z[nodes, :2 * L.n].T.copy(),
            u=Z[nodes, L.offset("u"):].T.copy(), qdd=Z[nodes, 2 * L.n:3 * L.n].T.copy(),
            multipliers=Z[nodes, 3 * L.n:3 * L.n + L.m].T.copy(),
            params=params, stderr=dict.fromkeys(params, np.nan), cov=None, unidentified=(),
            unseen=[], at_bounds=(), duration=T,
            coordinates=tuple(mod.coordinates), inputs=tuple(mod.inputs),
            constraint_violation=violation, seconds=seconds, x=np.array(x),
            hessian=hessian, scheme=L.scheme, t_points=t_points, _layout=L,
            _problem=problem, _full_params=full, _evaluations=dict(tr.evaluations),
            _transcription=tr, _controls=tr.controls,
            _lam=np.asarray(info.get("mult_g", np.zeros(0)), dtype=float),
            _z=np.asarray(info.get("mult_z", np.zeros(0)), dtype=float),
            notes=list(getattr(tr, "notes", ())) + info.get(
                "notes", acceptable_note(status, problem._minimize_time)),
            solve_seconds=seconds, solver="ipopt")

    def estimate_errors(self, stacklevel=2):
        """Fill `stderr`, `cov`, `unidentified`, `unseen` and `at_bounds` from the data term at
        the solution (`lagrgen.collocation.statistics`; `solve` calls it for a successful
        result of a problem with data and unknown parameters: NaN otherwise)."""
        tr = self._transcription
        if self.status not in (0, 1) or not tr.n_data or not self.params:
            return
        from .statistics import parameter_errors
        stderr, self.cov, self.unidentified, self.unseen, self.at_bounds = parameter_errors(
            tr, self.x, stacklevel + 1)
        self.stderr = {name: stderr.get(name, np.nan) for name in self.params}

    def __repr__(self):
        return (f"CollocationResult(success={self.success}, objective={self.objective:.10g}, "
                f"iterations={self.iterations}, duration={self.duration:.6g}, "
                f"nodes={self.t.size})")

    def summary(self):
        """A few lines: the outcome, the objective, the duration and the estimates."""
        lines = [f"{'solved' if self.success else 'NOT solved'}: {self.message} "
                 f"({IPOPT_STATUS.get(self.status, self.status)})",
                 f"objective {self.objective:.10g} after {self.iterations} iterations "
                 f"({self.seconds:.3g} s, {self.hessian} Hessian, {self.scheme})",
                 f"duration {self.duration:.6g}, largest constraint violation "
                 f"{self.constraint_violation:.2e}"]
        meshes = getattr(self, "meshes", ())
        if meshes:
            tolerance = "the grid as given" if self.mesh_tol is None else \
                f"mesh_tol {self.mesh_tol:g}"
            nodes = " → ".join(str(m.nodes) for m in meshes)
            lines.append(f"dynamics error {self.error:.2e} (relative, largest of "
                         f"{self.errors.size} intervals; {tolerance}); "
                         f"{len(meshes)} mesh{'es' if len(meshes) > 1 else ''}: {nodes} nodes")
        for name, value in self.params.items():
            err = self.stderr.get(name, np.nan)
            note = f" ± {err:.3g}" if np.isfinite(err) else \
                " (the data do not determine it)" if err == np.inf else ""
            lines.append(f"  {name} = {value:.8g}{note}" +
                         (" (on a bound)" if name in self.at_bounds else ""))
        return "\n".join(lines)

    # -- values between the nodes ------------------------------------------------------------
    def _point_values(self, kind, i):
        L = self._layout
        return L.point_block(self.x)[:, L.offset(kind) + i]

    def bound_excursions(self, samples=16):
        """{state name: (excursion, t)}: how far each state's interpolant (`state_at`) leaves
        its bounds between the points, where collocation does not bound it, largest over
        `samples` instants per interval, for the states that leave them by more than 1e-6 of
        max(1, abs(bound)) (names: the coordinates and <coordinate>_dot). An interval's bound is
        the loosest of its points' (instance values do not bound the states between)."""
        L, tr = self._layout, self._transcription
        lo, hi = (L.point_block(b)[:, :2 * L.n] for b in (tr.lo, tr.hi))
        if not (np.isfinite(lo).any() or np.isfinite(hi).any()):
            return {}
        names = list(self.coordinates) + [f"{c}_dot" for c in self.coordinates]
        starts = np.asarray(L.node_points)
        low = np.minimum(np.minimum.reduceat(lo, starts[:-1], axis=0), lo[starts[1:]]).T
        high = np.maximum(np.maximum.reduceat(hi, starts[:-1], axis=0), hi[starts[1:]]).T
        fractions = (np.arange(samples) + 0.5) / samples
        times = self.t[:-1, None] + fractions * np.diff(self.t)[:, None]      # (K, samples)
        values = self.state_at(times.ravel()).reshape(2 * L.n, *times.shape)
        excess = np.maximum(low[:, :, None] - values, values - high[:, :, None])
        out = {}
        for i in np.flatnonzero(excess.max(axis=(1, 2)) > 0):
            k, j = np.unravel_index(np.argmax(excess[i]), times.shape)
            bound = low[i, k] if values[i, k, j] < low[i, k] else high[i, k]
            if excess[i, k, j] > 1e-6 * max(1.0, abs(bound)):
                out[names[i]] = (float(excess[i, k, j]), float(times[k, j]))
        return out

    def state_at(self, times):
        """[q; q̇] at `times` (a number or an array), on the collocation's interpolant: (2n,) or
        (2n, len(times))."""
        L = self._layout
        scalar = np.ndim(times) == 0
        s = np.clip(np.atleast_1d(np.asarray(times, dtype=float)) - self.t_points[0], 0.0,
                    self.duration)
        rows = []
        for kind, rate in (("q", "qd"), ("qd", "qdd")):
            for i in range(L.n):
                rows.append(interpolate_rows(self._point_values(kind, i), L, kind, s,
                                             self.duration, self._point_values(rate, i)))
        out = np.array(rows)
        return out[:, 0] if scalar else out

    def input_signals(self):
        """{input name: lagrgen.Signal} of the found inputs, as the scheme implies them: linear
        between nodes (trapezoidal), the quadratic through node, midpoint and node on each
        interval (Hermite–Simpson), the next node's value held over each interval (backward
        Euler)."""
        from ..signals import Signal
        L = self._layout
        out = {}
        for k, name in enumerate(self.inputs):
            values = self._point_values("u", k)
            if L.scheme == "hermite-simpson":
                out[name] = Signal.piecewise(self.t, simpson_quadratics(self.t, values))
            elif L.scheme == "trapezoidal":
                out[name] = Signal(self.t, values, kind="linear")
            else:
                held = np.append(values[1:], values[-1])
                out[name] = Signal(self.t, held, kind="previous")
        return out

    def check(self, method="DOP853", rtol=1e-10, atol=1e-12, max_wall_time=10.0, max_steps=None):
        """Re-simulate the model from the first node's state with the found inputs and parameters
        on the native engine; the largest deviation from the collocated states at the nodes
        (a `Deviation`: a float with `by_state` and `simulation`). An unstable motion (a pendulum
        held upright) departs even from an exact answer; a deviation that shrinks as the nodes
        grow says the grid resolves the motion.

        The re-simulation stops after `max_wall_time` seconds or `max_steps` steps (None: no
        limit), as a stiff or diverging motion can keep an explicit method busy for hours; the
        deviation is then infinite and its `message` the simulation's (try method="Radau")."""
        from ..simulate import simulate
        mod = self._problem.mod
        sol = simulate(mod, (self.t[0], self.t[-1]), self.y[:, 0], method=method,
                       params=self._full_params, inputs=self.input_signals(), t_eval=self.t,
                       rtol=rtol, atol=atol, max_wall_time=max_wall_time, max_steps=max_steps)
        names = list(self.coordinates) + [f"{c}_dot" for c in self.coordinates]
        if sol.y.shape[1] != self.t.size or not sol.success:
            return Deviation(np.inf, {name: np.inf for name in names}, sol,
                             f"check(): the re-simulation stopped early: {sol.message}")
        error = np.abs(sol.y - self.y).max(axis=1)
        return Deviation(float(error.max()), dict(zip(names, map(float, error))), sol)

    # -- looking at it ---------------------------------------------------------------------------
    def plot(self, path=None, title=None):
        """Coordinates, rates and inputs against time (the data of `track` as dots); returns the
        matplotlib Figure (saved to `path` if given)."""
        from .plots import plot_result
        return plot_result(self, path, title)

    def plot_errors(self, path=None, title=None):
        """Each mesh's relative dynamics error per interval against time, with mesh_tol (log
        scale); returns the matplotlib Figure (saved to `path` if given)."""
        from .plots import plot_errors
        return plot_errors(self, path, title)

    def animate(self, path=None, fps=20, max_frames=120, dpi=72, title=None):
        """The mechanism moving along the solution: a notebook animation, saved to `path` (GIF or
        MP4) if given."""
        from ..outputs.notebook import animation
        from ..results import SimulationResult
        times = np.linspace(self.t[0], self.t[-1], max(2 * max_frames, self.t.size))
        sol = SimulationResult(t=times, y=self.state_at(times))
        sol.sol = self.state_at
        sol.__dict__["_built"] = self._problem.mod
        sol["params"] = self._full_params
        anim = animation(sol, None, self._full_params, fps, max_frames, dpi,
                         title or f"{self._problem.mod.name} (collocation)")
        if path is not None:
            anim.save(path)
        return anim

    def to_xarray(self):
        """An xarray.Dataset: y (state, time), u (input, time), qdd (coordinate, time) and the
        multipliers; the estimates, the objective and the solver's status in attrs."""
        import xarray as xr
        states = list(self.coordinates) + [f"{c}_dot" for c in self.coordinates]
        data = {"y": (("state", "time"), self.y), "qdd": (("coordinate", "time"), self.qdd)}
        coords = {"time": self.t, "state": states, "coordinate": list(self.coordinates)}
        if self.inputs:
            data["u"] = (("input", "time"), self.u)
            coords["input"] = list(self.inputs)
        names = self._problem.mod.constraint_names
        if names:
            data["multipliers"] = (("constraint", "time"), self.multipliers)
            coords["constraint"] = list(names)
        attrs = {"objective": self.objective, "status": self.status, "message": self.message,
                 "iterations": self.iterations, "duration": self.duration,
                 "scheme": self.scheme, "model": self._problem.mod.name,
                 "error": getattr(self, "error", np.nan)}
        for name, value in self.params.items():
            attrs[f"param_{name}"] = value
            attrs[f"stderr_{name}"] = self.stderr[name]
        return xr.Dataset(data, coords=coords, attrs=attrs)


def simpson_quadratics(t_nodes, values):
    """(intervals, 4) piecewise coefficients (powers 3..0 of t − t_k) of the quadratic through
    (t_k, u_k), (t_k + h/2, u_k+½), (t_k+1, u_k+1) on each interval, `values` at the points
    node, midpoint, node, ...: u_k + a1·x + a2·x² with a1 = (−3u_k + 4u_k+½ − u_k+1)/h,
    a2 = 2(u_k − 2u_k+½ + u_k+1)/h²."""
    u0, um, u1 = values[0:-1:2], values[1::2], values[2::2]
    h = np.diff(t_nodes)
    return np.column_stack([np.zeros_like(h), 2 * (u0 - 2 * um + u1) / h**2,
                            (-3 * u0 + 4 * um - u1) / h, u0])


def objective_at(tr, x, info, status):
    """The objective at the solver's answer x: IPOPT's value where it solved (0, 1) or stopped
    at its limit (-1), else evaluated at x (IPOPT reports 0 after an error), NaN where the
    problem cannot be evaluated there."""
    if status in (0, 1, -1):
        return float(info["obj_val"])
    try:
        with np.errstate(all="ignore"):
            value = float(tr.objective(x))
    except Exception:
        return math.nan
    return value if math.isfinite(value) else math.nan


def acceptable_note(status, least_time=False):
    """[a note] when IPOPT ended at its acceptable level (status 1: success, but looser than
    `tol`), else []; of a `least_time` problem, that its duration may still be above the least
    by far more than that level."""
    if status != 1:
        return []
    start = ("IPOPT stopped at its acceptable level (several iterations within acceptable_tol, "
             "1e-6 by default), not at the requested tol: ")
    if least_time:
        return [start + "a least-time optimum is flat (many motions take nearly the least time) "
                "and IPOPT's steps crawl on it, so the duration may still be above the least by "
                "~1e-3 (the robots guide's seven-joint arm refined to mesh_tol 1e-4: 0.3 % above "
                "where 3000 more iterations took it); options={'acceptable_iter': 0} makes it "
                "go on to tol, slowly"]
    return [start + "the answer is optimal to about 1e-6; options={'acceptable_iter': 0} makes "
            "it go on to tol"]

