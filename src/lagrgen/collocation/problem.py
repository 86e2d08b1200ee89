"""`lagrgen.Collocation`: an optimal-control or identification problem on a built model, declared
piece by piece (bounds, instance constraints, path constraints, an objective, data) and solved by
direct collocation with IPOPT (`solve`).
"""
import math
import numbers
import time

import numpy as np

from ..errors import LagrgenError
from ..numbers import finite_number
from ..runtime.arguments import key_name, parameter_vector, unknown_name
from .grid import Layout, scheme_name, variable_names
from .symbolic import internal_expression


#: The weight of the term that picks one motion among those of the least time
#: (`Collocation.minimize`): it moves the least time by far less than a solve's tolerance (the
#: seven-joint arm: no change in eight digits) and makes the optimum unique.
TIME_REGULARIZATION = 1e-6


class Collocation:
    """An optimal motion or an identification of the built model `mod`, by direct collocation.

    States q, q̇, the accelerations q̈ (and a constrained model's multipliers λ) and the inputs u
    are variables at every collocation point; the model's residual M·q̈ − F − Aᵀλ = 0 (and the
    constraints at acceleration level, A·q̈ = γ) holds at every point, and the scheme's defects tie
    neighbouring points (`lagrgen.collocation.grid`).

    Parameters
    ----------
    mod : built model
        A model built with the C backend (`lagrgen.build(model)`) in this session.
    nodes : int
        Number of nodes (≥ 2), equally spaced over the duration (default 101).
    duration : float or (float, float)
        The duration T (default 2.0 s); a pair (lo, hi), 0 < lo < hi, makes T a variable in
        those bounds (free final time).
    scheme : {"hermite-simpson", "trapezoidal", "backward-euler"}
    unknown_params : list of str, optional
        Parameters to estimate or optimize (variables of the problem); the others keep their
        values (`params`, else the defaults).
    params : dict, optional
        Values of known parameters (name -> value) replacing the defaults; also the starting values
        of unknown ones.
    t0 : float
        The time of the first node (for a model that depends on t).
    """

    def __init__(self, mod, nodes=101, duration=2.0, scheme="hermite-simpson",
                 unknown_params=None, *,
                 params=None, t0=0.0):
        self.mod = _compiled_model(mod)
        self.model = _source_model(self.mod)
        if isinstance(nodes, bool) or not isinstance(nodes, numbers.Integral) or nodes < 2:
            raise LagrgenError(f"nodes must be an integer of at least 2, got {nodes!r}")
        self.nodes = int(nodes)
        self.scheme = scheme_name(scheme)
        self.free_duration, self.duration_bounds = _duration(duration)
        self.t0 = _finite(t0, "t0")
        names = tuple(self.mod.parameters)
        unknown = [] if unknown_params is None else (
            [unknown_params] if isinstance(unknown_params, str) else list(unknown_params))
        unknown = [key_name(u) for u in unknown]
        for u in unknown:
            if u not in names:
                raise unknown_name("parameter", u, names)
        if len(set(unknown)) != len(unknown):
            raise LagrgenError(f"unknown_params names a parameter twice: {unknown}")
        self.unknown = tuple(unknown)
        values = parameter_vector(params, names, self.mod.defaults) if params is not None \
            else np.array(self.mod.defaults, dtype=float)
        missing = [name for name, v in zip(names, values)
                   if not np.isfinite(v) and name not in self.unknown]
        if missing:
            raise LagrgenError(f"parameter(s) {', '.join(missing)} have no default value: give "
                               "them in params={...} or list them in unknown_params")
        self.params = values
        n, m, nu = self.mod.n_coordinates, self.mod.n_constraints, len(self.mod.inputs)
        self.layout = Layout(n, m, nu, self.nodes, self.scheme,
                             tuple(names.index(u) for u in self.unknown), self.free_duration)
        if self.mod.explicit_time and self.free_duration:
            raise LagrgenError(
                f"model {self.mod.name!r} depends on t explicitly, which a free duration does not "
                "allow (the node times move with the duration): fix the duration")
        self._bounds = {}         # (kind, i) -> (lo, hi)
        self._fixed = {}          # (fraction of the duration: 0 or 1, kind, i) -> value
        self._interpolated = []   # (t − t0, kind, i, value) of instance constraints at(...)
        self._periodic = []       # (kind, i)
        self._path = []           # (label, internal expression, lo, hi)
        self._terminal = []       # (label, internal expression, lo, hi) at the last node
        self._integrand = None    # internal expression of ∫ L dt
        self._terminal_cost = None  # internal expression of the cost on the last node
        self._integrand_text = None
        self._minimize_time = False
        self._tracks = []         # (times, data (k, m), [(kind, i)], weights (k, m), names)
        self._given = {}          # input index -> a number, a callable of t or (times, values)
        self._transcriptions = {}  # (hessian, layout, controls) -> Transcription
        self._values_stamp = 0    # counts changes of instance values alone (resolve)
        self._bound_stops()

    def _bound_stops(self):
        """The enforced limits' stops (`from_urdf(..., limits=True)`, `Model.limit(...,
        enforce=True)`) as the coordinates' bounds: a simulation bounces off them, which smooth
        collocation cannot represent, so an optimal motion stays within them (else it went
        through them and said success)."""
        sides, info = {}, getattr(self.mod, "info", None)
        for _, j, sign, bound, _ in getattr(info, "limit_stops", ()):
            lo, hi = sides.get(j, (-math.inf, math.inf))
            sides[j] = (bound, hi) if sign > 0 else (lo, bound)
        for j, (lo, hi) in sides.items():
            self.bound(self.mod.coordinates[j], lo, hi)

    def __repr__(self):
        duration = self.duration_bounds if self.free_duration else self.duration_bounds[0]
        return (f"Collocation({self.mod.name!r}, nodes={self.nodes}, scheme={self.scheme!r}, "
                f"duration={duration!r}, unknown_params={list(self.unknown)})")

    # -- names -----------------------------------------------------------------------------
    def variable(self, name):
        """(kind, index) of a name: a coordinate ("q"), `<coordinate>_dot` ("qd"),
        `<coordinate>_ddot` ("qdd"), a constraint's multiplier ("lam"), an input ("u"), an
        unknown parameter ("p") or "duration" ("T")."""
        name = key_name(name)
        coords = list(self.mod.coordinates)
        for suffix, kind in (("_ddot", "qdd"), ("_dot", "qd")):
            if name.endswith(suffix) and name[:-len(suffix)] in coords:
                return kind, coords.index(name[:-len(suffix)])
        if name in coords:
            return "q", coords.index(name)
        if name in self.mod.inputs:
            return "u", list(self.mod.inputs).index(name)
        if name in self.mod.constraint_names:
            return "lam", list(self.mod.constraint_names).index(name)
        if name in self.unknown:
            return "p", self.unknown.index(name)
        if name == "duration":
            return "T", 0
        if name in self.mod.parameters:
            raise LagrgenError(f"parameter {name!r} is not an unknown of this problem: list it "
                               "in unknown_params to bound or estimate it")
        known = (coords + [f"{c}_dot" for c in coords] + [f"{c}_ddot" for c in coords]
                 + list(self.mod.inputs) + list(self.mod.constraint_names) + list(self.unknown))
        raise unknown_name("variable", name, tuple(known))

    def _point_variable(self, name, what):
        kind, i = self.variable(name)
        if kind in ("p", "T"):
            what_it_is = "an unknown parameter" if kind == "p" else "the duration"
            raise LagrgenError(f"{what} takes states, accelerations, multipliers and inputs; "
                               f"{name!r} is {what_it_is}")
        return kind, i

    # -- declarations ----------------------------------------------------------------------
    def bound(self, name, lo=-math.inf, hi=math.inf):
        """lo ≤ name ≤ hi at every point (a state, `<coordinate>_dot`, `<coordinate>_ddot`, input,
        constraint multiplier or unknown parameter); a free duration's bounds are given to the
        constructor."""
        kind, i = self.variable(name)
        if kind == "T":
            raise LagrgenError("the duration's bounds are the constructor's duration=(lo, hi)")
        lo, hi = _interval(lo, hi, f"bound({name!r}, lo, hi)")
        self._bounds[(kind, i)] = (lo, hi)
        self._changed()
        return self

    def bound_limits(self):
        """Bounds from the model's declared limits (`Model.limit`; a URDF's joint limits): each
        limited coordinate within [lower, upper], its rate `<coordinate>_dot` within ±velocity and
        the input `tau_<coordinate>` (when the model has one) within ±effort, replacing earlier
        bounds of those names; an absent limit leaves its side unbounded. Returns the problem."""
        limits = self.mod.limits
        if not any(v is not None for entry in limits.values() for v in entry):
            raise LagrgenError(f"model {self.mod.name!r} declares no limits: declare them with "
                               "model.limit(coordinate, lower, upper, velocity, effort) before "
                               "building it, or bound the variables with bound(name, lo, hi)")
        for name, (lower, upper, velocity, effort) in limits.items():
            if lower is not None or upper is not None:
                self.bound(name, -math.inf if lower is None else lower,
                           math.inf if upper is None else upper)
            if velocity is not None:
                self.bound(f"{name}_dot", -velocity, velocity)
            if effort is not None and f"tau_{name}" in self.mod.inputs:
                self.bound(f"tau_{name}", -effort, effort)
        return self

    def initial(self, q=None, qd=None, qdd=None, u=None):
        """Instance constraints at the first node: q, q̇, q̈ and u as dicts (name -> value) or
        arrays of all of them."""
        self._instance(0.0, q, qd, qdd, u, "initial")
        return self

    def final(self, q=None, qd=None, qdd=None, u=None):
        """Instance constraints at the last node (like `initial`)."""
        self._instance(1.0, q, qd, qdd, u, "final")
        return self

    def _instance(self, fraction, q, qd, qdd, u, what, structure=True):
        for kind, i, value in self._instance_items(q, qd, qdd, u, what):
            self._fix(fraction, kind, i, value, what)
        self._changed(structure)

    def _instance_items(self, q, qd, qdd, u, what):
        """[(kind, i, value)] of instance values given as dicts (name -> value) or arrays."""
        n, nu = self.layout.n, self.layout.nu
        out = []
        for kind, values, size, names in (
                ("q", q, n, self.mod.coordinates), ("qd", qd, n, self.mod.coordinates),
                ("qdd", qdd, n, self.mod.coordinates), ("u", u, nu, self.mod.inputs)):
            if values is None:
                continue
            if isinstance(values, dict):
                items = []
                for key, value in values.items():
                    name = key_name(key)
                    if name not in names:
                        raise unknown_name("coordinate" if kind != "u" else "input", name,
                                           tuple(names))
                    items.append((list(names).index(name), value))
            else:
                arr = np.atleast_1d(np.asarray(values, dtype=float))
                if arr.shape != (size,):
                    raise LagrgenError(f"{what}({kind}=...) takes a dict or {size} values, got "
                                       f"shape {arr.shape}")
                items = list(enumerate(arr))
            out += [(kind, i, _finite(value, f"{what} value of {kind}[{i}]"))
                    for i, value in items]
        return out

    def _fix(self, fraction, kind, i, value, what):
        """Fix variable i of `kind` at the node at `fraction` of the duration (0 or 1)."""
        if (fraction, kind, i) in self._fixed:
            raise LagrgenError(
                f"{what}(): the value of {variable_names(self.mod)[kind][i]} at t = "
                f"{'t0' if fraction == 0 else 't0 + T'} is already given "
                f"({self._fixed[(fraction, kind, i)]}); give each value once (a new Collocation "
                "starts over)")
        self._fixed[(fraction, kind, i)] = value

    def periodic(self, names=None):
        """x(T) = x(0) for the named states, accelerations or inputs (None: every q and q̇)."""
        if names is None:
            coords = self.mod.coordinates
            names = list(coords) + [f"{c}_dot" for c in coords]
        elif isinstance(names, str):
            names = [names]
        for name in names:
            self._periodic.append(self._point_variable(name, "periodic"))
        self._changed()
        return self

    def at(self, t, name, value):
        """An instance constraint name(t) = value (between nodes: on the interpolant)."""
        kind, i = self._point_variable(name, "at")
        t = _finite(t, "at(t, ...)") - self.t0
        value = _finite(value, f"at(..., {name!r}, value)")
        if self.free_duration:
            if abs(t) > 0:
                raise LagrgenError("at(t, ...) with a free duration takes t = t0 only (the other "
                                   "node times move); use final(...) for the end")
            self._fix(0.0, kind, i, value, "at")
            self._changed()
            return self
        T = self.duration_bounds[0]
        if not -1e-12 * T <= t <= T * (1 + 1e-12):
            raise LagrgenError(f"at(t={t + self.t0}, ...) lies outside the problem's time span "
                               f"[{self.t0}, {self.t0 + T}]")
        t = min(max(t, 0.0), T)
        step = T / (self.layout.nodes - 1)
        if abs(round(t / step) * step - t) <= 1e-9 * step:
            t = round(t / step) * step          # on a node of the grid: exactly there
        if any(abs(s - t) <= 1e-12 * T and (k, j) == (kind, i)
               for s, k, j, _ in self._interpolated):
            raise LagrgenError(f"at({t + self.t0}, {name!r}, ...) is already given; give each "
                               "value once")
        self._interpolated.append((t, kind, i, value))
        self._changed()
        return self

    def path(self, expr, lo=-math.inf, hi=math.inf):
        """lo ≤ expr ≤ hi at every collocation point; `expr` in the model's symbols (coordinates,
        their first and second derivatives, parameters, inputs, t)."""
        lo, hi = _interval(lo, hi, "path(expr, lo, hi)")
        if lo == -math.inf and hi == math.inf:
            raise LagrgenError("path(expr) needs a bound: path(expr, lo, hi)")
        label = f"path constraint {len(self._path) + 1}"
        internal = internal_expression(self.model, expr, label, allow_time=not self.free_duration)
        self._path.append((label, internal, lo, hi))
        self._changed()
        return self

    def terminal(self, expr, lo=-math.inf, hi=math.inf):
        """lo ≤ expr ≤ hi at the last node (e.g. a link's position, `Model.link_position`);
        `expr` in the model's symbols (coordinates, their rates, parameters; accelerations and
        inputs of the last node too)."""
        lo, hi = _interval(lo, hi, "terminal(expr, lo, hi)")
        if lo == -math.inf and hi == math.inf:
            raise LagrgenError("terminal(expr) needs a bound: terminal(expr, lo, hi)")
        label = f"terminal constraint {len(self._terminal) + 1}"
        internal = internal_expression(self.model, expr, label, allow_time=not self.free_duration)
        self._terminal.append((label, internal, lo, hi))
        self._changed()
        return self

    def minimize(self, integral=None, time=False, terminal=None):
        """The objective: ∫ integral dt over the motion (an expression in the model's symbols),
        plus T when `time` (minimum time; needs a free duration), plus `terminal` evaluated at
        the last node (e.g. a squared distance of a link from a target). Replaces an earlier
        objective; data terms (`track`) are added to it.

        The least time alone is often reached by many motions (a joint with slack can take any
        path that arrives in time): `solve` then picks the one of least
        ∫Σ(u_k/ū_k)² dt (ū_k the half range of input k's bounds, or 1) by adding that term
        weighted by TIME_REGULARIZATION, and says so in `res.notes`."""
        if integral is None and not time and terminal is None:
            raise LagrgenError("minimize() needs integral=expr, time=True and/or terminal=expr")
        if time and not self.free_duration:
            raise LagrgenError("minimize(time=True) needs a free duration: "
                               "Collocation(..., duration=(lo, hi))")
        self._integrand = None if integral is None else internal_expression(
            self.model, integral, "the objective's integrand", allow_time=not self.free_duration)
        self._terminal_cost = None if terminal is None else internal_expression(
            self.model, terminal, "the objective's terminal cost",
            allow_time=not self.free_duration)
        self._minimize_time = bool(time)
        self._changed()
        return self

    def track(self, t, data, names, weights=None):
        """A data term Σ weights·(value(t_i) − data_i)², the values interpolated between nodes.

        Parameters
        ----------
        t : (k,) sample times in the problem's span, in any order (gaps allowed)
        data : (len(names), k) samples (a 1-D array for one name); NaN marks a missing sample
        names : a name or list of names of states, accelerations or inputs
        weights : a scalar, one per name, or (len(names), k); default 1 (with the noise's standard
            deviation σ, 1/σ² weighs each sample by its precision)
        """
        if self.free_duration:
            raise LagrgenError("track() needs a fixed duration (the samples' places on the grid "
                               "would move with a free one)")
        names = [names] if isinstance(names, str) else list(names)
        rows = [self._point_variable(name, "track") for name in names]
        t = np.atleast_1d(np.asarray(t, dtype=float))
        data = np.asarray(data, dtype=float)
        if data.ndim == 1:
            data = data[None, :]
        if t.ndim != 1:
            raise LagrgenError(f"track: t must be a 1-D array of sample times, got shape "
                               f"{t.shape}")
        if data.shape != (len(names), t.size):
            raise LagrgenError(f"track: data must have shape (len(names), len(t)) = "
                               f"({len(names)}, {t.size}), got {data.shape}")
        if not np.all(np.isfinite(t)):
            raise LagrgenError("track: the sample times must be finite")
        if np.isinf(data).any():
            raise LagrgenError("track: a sample is infinite; give a missing sample as NaN")
        T = self.duration_bounds[0]
        s = t - self.t0
        if np.any(s < -1e-12 * T) or np.any(s > T * (1 + 1e-12)):
            raise LagrgenError(f"track: sample times must lie in [{self.t0}, {self.t0 + T}]")
        w = np.ones_like(data) if weights is None else _track_weights(weights, data.shape)
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise LagrgenError("track: weights must be finite and not negative")
        present = np.isfinite(data) & (w > 0)
        if not present.any():
            raise LagrgenError("track: no sample with a positive weight and a finite value")
        self._tracks.append((np.clip(s, 0.0, T), data, rows, w, present, tuple(names)))
        self._changed()
        return self

    def input(self, name, values):
        """Make input `name` known (not a variable): a number, a callable of t (e.g. a
        `lagrgen.Signal`), or one value per node (or per point) of the grid, linear between."""
        kind, k = self._point_variable(name, "input")
        if kind != "u":
            raise LagrgenError(f"input(): {name!r} is not an input of model {self.mod.name!r}")
        if self.free_duration and callable(values):
            raise LagrgenError("input(name, callable) needs a fixed duration")
        if not callable(values):
            values = self._input_table(name, values)
        self._given[k] = values
        self._changed()
        return self

    def _input_table(self, name, values):
        """(fractions of the duration, values) of an input given as numbers."""
        L = self.layout
        arr = np.asarray(values, dtype=float)
        if arr.ndim == 0:
            arr = np.full(2, float(arr))
            fractions = np.array([0.0, 1.0])
        elif arr.shape == (L.nodes,):
            fractions = L.node_fractions
        elif arr.shape == (L.points,):
            fractions = L.fractions
        else:
            raise LagrgenError(f"input({name!r}, values): give a number, a callable of t or one "
                               f"value per node ({L.nodes}), got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise LagrgenError(f"input({name!r}, ...): the values must be finite")
        return fractions, arr

    def given_values(self, k, times):
        """The values of the given input k at the absolute `times` (of one solve's points)."""
        values = self._given[k]
        if callable(values):
            out = np.array([float(values(t)) for t in times])
            if not np.all(np.isfinite(out)):
                raise LagrgenError(f"input({self.mod.inputs[k]!r}, ...): the callable gave a "
                                   "value that is not finite")
            return out
        fractions, table = values
        span = times[-1] - times[0]
        return np.interp((times - times[0]) / span if span > 0 else times * 0.0, fractions, table)

    def _changed(self, structure=True):
        """A declaration changed: the NLPs are made anew; or (structure False: instance values
        at the first node alone, `resolve`) their bounds are refreshed."""
        if structure or self.layout.m:
            self._transcriptions = {}
        self._values_stamp += 1

    # -- solving ---------------------------------------------------------------------------
    def solve(self, guess=None, hessian="exact", tol=1e-8, max_iter=3000, progress=True,
              options=None, mesh_tol=1e-6, max_meshes=10, solver="auto"):
        """Solve the problem, refining the mesh until the motion is accurate.

        Parameters
        ----------
        guess : None, CollocationResult, simulation result, dict or array
            The starting point. None: a smooth motion between the initial and final values
            (cubic in each coordinate) with the inputs it needs, or, when those exceed the
            inputs' bounds, the model's own motion from the initial state (see
            `lagrgen.collocation.guess.default_guess`); an earlier result warm-starts (any node
            count); a simulation (`lagrgen.simulate`) gives the states; a dict maps names (and
            "params", "duration") to values, arrays over the nodes or callables of t; an array
            is the decision vector.
        hessian : {"exact", "quasi-newton"}
            The exact Hessian of the Lagrangian (compiled second derivatives of the model), or
            IPOPT's limited-memory quasi-Newton approximation.
        tol, max_iter : IPOPT's convergence tolerance and iteration limit (per mesh)
        progress : print one line per iteration (throttled), one per mesh, and a summary
        options : dict of further IPOPT options (name -> value), replacing lagrgen's defaults
            (`lagrgen.collocation.solver`: with the exact Hessian mu_strategy="adaptive",
            mu_oracle="loqo", min_refinement_steps=0)
        mesh_tol : float or None
            The largest relative dynamics error allowed on any interval (`res.error`): the
            mesh is refined until it holds (`lagrgen.collocation.refine`), and `res.success` is
            False when it does not. None solves on the given grid alone (the error is still
            measured, and warned about when above 1e-6).
        max_meshes : int
            The most meshes (solves) the refinement may use, the given grid included.
        solver : {"auto", "ipopt", "sqp"}
            "auto": IPOPT on the first mesh, and the SQP on the problem's stage structure
            (`lagrgen.collocation.sqp`) for the refined meshes and a re-plan (`resolve`) it
            covers, IPOPT where it does not; "ipopt": IPOPT alone; "sqp": the SQP for every
            mesh, the first from its guess too (a cold start: on the Panda's least-effort move
            8 SQP iterations where IPOPT takes 27; on Talos's 16 joints it fails after 16
            iterations, ~7 s, and IPOPT solves the mesh), where the SQP applies (a
            fixed duration, no unknown parameters, path constraints, data, ties between nodes
            or constrained model; an error otherwise). Where one of the SQP's steps fails or it
            does not converge (under "auto" also where its stationarity residual stalls above
            tol), IPOPT solves that mesh from the same start, with a note (and under "auto" the
            meshes after it). The SQP profits from a warm start close to the answer, where IPOPT's
            interior point walks its barrier path again (benchmarks/robot_motions.py gives both
            on the Panda's re-plans and refined meshes). Where it stops on a flat optimum short of
            tol, "auto" has IPOPT finish the mesh from its motion and multipliers and "sqp"
            returns it with status 1 (a note says which).

        Returns
        -------
        CollocationResult
        """
        from .refine import solve_refined
        from .solver import settings
        chosen = settings(hessian, tol, max_iter, progress, options, solver)
        mesh_tol, max_meshes = _refinement(mesh_tol, max_meshes)
        self._require_objective()
        result = solve_refined(self, guess, chosen, mesh_tol, max_meshes)
        if progress:
            print(result.summary(), flush=True)
        return result

    def resolve(self, warm, initial=None, shift=0.0, **solve_options):
        """Solve the problem again from an earlier solution `warm`: re-planning (model-predictive
        control). The NLP of warm's mesh (its compiled units and sparsity) is reused and the
        solve starts from warm's motion: by the SQP on the problem's stage structure from warm's
        motion and multipliers where it covers the problem (solver="auto"), else by IPOPT (see
        `solve`; solver="ipopt" for IPOPT).

        Parameters
        ----------
        warm : CollocationResult
            An earlier solution of this problem: the start, and its (final) mesh the grid.
        initial : dict, optional
            A new initial state, {"q": ..., "qd": ...} as `initial` takes them (also "qdd",
            "u"), replacing the earlier initial values of those variables. A value outside its
            bounds by no more than a solver's tolerance (1e-6 relative) is clipped onto the
            bound, with a note in `res.notes`.
        shift : float
            Seconds dropped from the start of warm's motion, its end held: the start of the
            plan that continues it (0: warm as it is).
        **solve_options
            As `solve` (hessian, tol, max_iter, progress, options, solver, mesh_tol,
            max_meshes), with progress=False and mesh_tol=None by default: the solve keeps
            warm's grid (the dynamics error is measured when `res.error` is first read). A
            max_iter below the SQP's own limit (30) bounds the work: the SQP's iterate there is
            the result (status -1, as IPOPT's at its limit); max_iter=1 is one QP, a real-time
            iteration of model-predictive control.

        Returns
        -------
        CollocationResult
            With `solve_seconds`, the wall time of this re-plan (every mesh of it).
        """
        from .refine import solve_refined
        from .result import CollocationResult
        from .solver import settings
        if not isinstance(warm, CollocationResult) or warm._problem is not self:
            raise LagrgenError("resolve(warm=...) takes a result of this problem's solve or "
                               "resolve")
        shift = _finite(shift, "resolve(shift=...)")
        if not 0.0 <= shift < warm.duration:
            raise LagrgenError(f"resolve(shift={shift}) must lie in [0, the duration "
                               f"{warm.duration:g})")
        unknown = set(solve_options) - {"hessian", "tol", "max_iter", "progress", "options",
                                        "solver", "mesh_tol", "max_meshes"}
        if unknown:
            raise LagrgenError(f"resolve() got unexpected options {sorted(unknown)}: it takes "
                               "those of solve")
        opts = {"hessian": "exact", "tol": 1e-8, "max_iter": 3000, "progress": False,
                "options": None, "solver": "auto", "mesh_tol": None, "max_meshes": 10}
        opts.update(solve_options)
        chosen = settings(opts["hessian"], opts["tol"], opts["max_iter"], opts["progress"],
                          opts["options"], opts["solver"])
        mesh_tol, max_meshes = _refinement(opts["mesh_tol"], opts["max_meshes"])
        self._require_objective()
        earlier = dict(self._fixed)
        try:
            if initial is not None:
                self._replace_initial(initial)
            began = time.perf_counter()
            result = solve_refined(self, warm, chosen, mesh_tol, max_meshes,
                                   start=(warm._layout, warm._controls, shift))
            result.solve_seconds = time.perf_counter() - began
            return result
        except BaseException:
            if initial is not None:           # a re-plan that raises leaves the problem as it was
                self._fixed = earlier
                self._changed(structure=False)
            raise

    def _replace_initial(self, initial):
        """Set new initial values (resolve's `initial`): those given replace the earlier ones;
        the structure of the problem is kept (only its bounds are refreshed)."""
        if not isinstance(initial, dict):
            raise LagrgenError("resolve(initial=...) takes a dict {'q': ..., 'qd': ...}")
        extra = set(initial) - {"q", "qd", "qdd", "u"}
        if extra:
            raise LagrgenError(f"resolve(initial=...) takes the keys q, qd, qdd and u, got "
                               f"{sorted(extra)}")
        items = self._instance_items(*(initial.get(k) for k in ("q", "qd", "qdd", "u")),
                                     "resolve")
        for kind, i, value in items:
            self._fixed[(0.0, kind, i)] = value
        self._changed(structure=False)

    def _objective_integrand(self):
        """The integrand the NLP minimizes: the user's, or with the least time alone
        TIME_REGULARIZATION·Σ_k (u_k/ū_k)² over the free inputs (ū_k the half range of the input's
        bounds, or 1), which picks one motion among those of the least time."""
        if self._integrand is not None or not self._minimize_time:
            return self._integrand
        import symengine as se
        terms = []
        for k in range(self.layout.nu):
            if k in self._given:
                continue
            lo, hi = self._bounds.get(("u", k), (-math.inf, math.inf))
            scale = 0.5 * (hi - lo) if math.isfinite(hi - lo) and hi > lo else 1.0
            terms.append((se.Symbol(f"u[{k}]") / scale) ** 2)
        return TIME_REGULARIZATION * se.Add(*terms) if terms else None

    def regularization_note(self):
        """What `res.notes` says of the term that picks a motion of the least time."""
        return ("the least time may be reached by more than one motion (joints with slack): "
                "the one returned has the least ∫Σ(u/ū)² dt among them (ū: each input's half "
                f"range), chosen by a term of weight {TIME_REGULARIZATION:g} added to the "
                "objective (res.objective includes it; res.duration is the least time)")

    def _require_objective(self):
        if self._integrand is None and not self._minimize_time and not self._tracks \
                and self._terminal_cost is None:
            raise LagrgenError("no objective: call minimize(integral=..., time=...) or track(...)")

    def transcription(self, hessian="exact", layout=None, controls=None):
        """The NLP of this problem on its grid, or on the mesh `layout` with the inputs tied to
        `controls`: made once per declaration state, Hessian kind and mesh (instance values
        changed by `resolve` refresh its bounds alone)."""
        from .nlp import Transcription
        layout = self.layout if layout is None else layout
        key = (hessian, layout, controls)
        tr = self._transcriptions.get(key)
        if tr is None:
            if len(self._transcriptions) >= 8:
                self._transcriptions.clear()
            tr = self._transcriptions[key] = Transcription(self, hessian, layout, controls)
        elif tr.bounds_stamp != self._values_stamp:
            tr.refresh_bounds()
        return tr


def _refinement(mesh_tol, max_meshes):
    """The checked (mesh_tol, max_meshes) of `solve`."""
    if mesh_tol is not None:
        if isinstance(mesh_tol, bool) or not isinstance(mesh_tol, numbers.Real) \
                or not math.isfinite(mesh_tol) or mesh_tol <= 0:
            raise LagrgenError(f"mesh_tol must be a positive number (the largest relative "
                               f"dynamics error, e.g. 1e-6) or None, got {mesh_tol!r}")
        mesh_tol = float(mesh_tol)
    if isinstance(max_meshes, bool) or not isinstance(max_meshes, numbers.Integral) \
            or max_meshes < 1:
        raise LagrgenError(f"max_meshes must be an integer of at least 1, got {max_meshes!r}")
    return mesh_tol, int(max_meshes)


def _compiled_model(mod):
    if not hasattr(mod, "residual_terms") or not hasattr(mod, "n_coordinates"):
        raise TypeError(f"Collocation takes a built model (lagrgen.build(model)), got "
                        f"{type(mod).__name__}")
    if getattr(mod, "backend", None) != "c":
        raise LagrgenError("Collocation needs the C backend: lagrgen.build(model) (the Python "
                           "backend has no function table for the NLP's loops)")
    if mod.nonsmooth_definitions:
        names = [d[0] for d in mod.nonsmooth_definitions]
        raise LagrgenError(f"model {mod.name!r} has impacts or friction ({', '.join(names)}), "
                           "which direct collocation on smooth equations cannot represent"
                           + _joint_friction_hint(mod, names))
    return mod


def _joint_friction_hint(mod, names):
    """What to do where the non-smooth definitions include a robot's joint friction (from_urdf
    names the friction of joint j "friction_j")."""
    joints = {f"friction_{c}" for c in mod.coordinates}
    if not getattr(mod.info, "link_names", ()) or not joints.intersection(names):
        return ""
    return ("; the joints' Coulomb friction comes from the URDF's <dynamics friction>: "
            "from_urdf(..., joint_dynamics=False) builds the robot without it")


def _source_model(mod):
    model = getattr(mod, "_source_model", None)
    if model is None:
        raise LagrgenError(
            f"Collocation needs the lagrgen.Model that {mod.name!r} was built from (its "
            "expressions and second derivatives are compiled from it): build it in this session "
            "with lagrgen.build(model) rather than loading the module")
    if not built_from(model, mod):
        raise LagrgenError(f"model {mod.name!r} was changed after it was built: build it again "
                           "(lagrgen.build(model)) before setting up a Collocation")
    return model


def built_from(model, mod):
    """Whether `mod` was built from `model` as it stands, with any formulation asked for (the
    content hash of a build includes the formulation given to `lagrgen.build`, if any)."""
    from ..build import content_digest
    from ..lagrange import derived
    from ..tree import FORMULATIONS
    spec = model.spec()
    return any(content_digest(spec, asked, lambda: derived(spec)) == mod.content_hash
               for asked in (None,) + FORMULATIONS)


def _track_weights(weights, shape):
    """`weights` of track() as an array of the data's `shape` (names, samples): a scalar, one
    per name, one per sample of a single name, or that shape."""
    w = np.asarray(weights, dtype=float)
    if w.ndim == 1 and w.size == shape[0]:
        w = w.reshape(-1, 1)
    elif w.ndim == 1 and shape[0] == 1:
        w = w.reshape(1, -1)
    try:
        return np.broadcast_to(w, shape).copy()
    except ValueError:
        raise LagrgenError(f"track: weights must be a scalar, one per name ({shape[0]}), or of "
                           f"the data's shape {shape}, got shape {w.shape}") from None


def _finite(value, what):
    return finite_number(value, what, LagrgenError)


def _interval(lo, hi, what):
    """(lo, hi) of a bound: numbers or ±inf (no bound on that side) with lo ≤ hi."""
    lo, hi = _finite_or_inf(lo, f"{what}: lo"), _finite_or_inf(hi, f"{what}: hi")
    if lo == math.inf or hi == -math.inf:
        raise LagrgenError(f"{what} with lo = {lo}, hi = {hi}: a lower bound of +inf or an upper "
                           "bound of -inf leaves no value; use -inf for no lower bound and +inf "
                           "for no upper bound")
    if lo > hi:
        raise LagrgenError(f"{what} with lo = {lo}, hi = {hi}: the lower bound exceeds the upper")
    return lo, hi


def _finite_or_inf(value, what):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise LagrgenError(f"{what} must be a number, got {value!r}") from None
    if math.isnan(v):
        raise LagrgenError(f"{what} is NaN")
    return v


def _duration(duration):
    """(free, (lo, hi)) of the constructor's duration: a number (lo = hi) or a pair."""
    if isinstance(duration, (tuple, list)):
        if len(duration) != 2:
            raise LagrgenError(f"duration=(lo, hi) takes two numbers, got {duration!r}")
        lo, hi = (_finite(d, "duration bound") for d in duration)
        if not 0 < lo < hi:
            raise LagrgenError(f"duration=(lo, hi) needs 0 < lo < hi (a motion takes some time: "
                               f"give lo a small positive value), got {duration!r}")
        return True, (lo, hi)
    T = _finite(duration, "duration")
    if T <= 0:
        raise LagrgenError(f"duration must be positive, got {T}")
    return False, (T, T)

