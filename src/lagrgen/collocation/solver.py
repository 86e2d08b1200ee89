"""IPOPT on a collocation NLP: loading it (through cyipopt, without its SciPy interface), the options
collocation problems start from, one line of progress per iteration, and the solve.

cyipopt's package imports `scipy.optimize` for its `minimize_ipopt` (about 0.3 s of a process);
its compiled wrapper `ipopt_wrapper`, which holds `Problem`, needs only `cyipopt.exceptions`. That
module is loaded from its file under its own name (so a later `import cyipopt` finds it and shares
its exception class with the wrapper), then the wrapper alone; when anything fails on that path,
or cyipopt is already imported, the package is imported as usual. A package imported after the
wrapper alone lacks only the attribute `cyipopt.exceptions` (`from cyipopt.exceptions import …`
works).
"""
import importlib.util
import math
import numbers
import os
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import LagrgenError

#: IPOPT's return codes that mean a solution (Solve_Succeeded, Solved_To_Acceptable_Level).
STATUS_SUCCESS = (0, 1)
#: IPOPT's return code for an option value it refuses.
INVALID_OPTION = -12
#: The options every solve starts from (the caller's `options` replace them).
BASE_OPTIONS = {"print_level": 0, "sb": "yes"}
#: With the exact Hessian: the barrier parameter set at every iteration from the complementarity
#: (LOQO's rule) rather than decreased only once each barrier problem is solved, and a step refined
#: only when its residual asks for it (IPOPT checks the residual of every solve). On the problems of
#: benchmarks/collocation.py they reach the same optima as IPOPT's defaults, in a third to a half of
#: the iterations on the swing-ups and a few more on the cart (its results list both); with the
#: quasi-Newton Hessian IPOPT's defaults do better.
EXACT_OPTIONS = {"mu_strategy": "adaptive", "mu_oracle": "loqo", "min_refinement_steps": 0}
QUASI_NEWTON_OPTIONS = {"hessian_approximation": "limited-memory"}
#: IPOPT's start on a refined mesh, from the last mesh's solution: that point kept as it is (not
#: pushed off its bounds, which breaks the dynamics of a motion riding a velocity limit) and a
#: small barrier parameter decreased monotonically, which takes ~25 iterations per mesh on a
#: robot's least-effort move (benchmarks: the seven-joint arm) instead of 70–100. "far": a mesh
#: whose last mesh's error exceeded `refine.NEAR`·mesh_tol (the first refined mesh, from the
#: problem's grid, off by 1e-3 on robots) begins with a larger barrier parameter (the Panda: 25
#: iterations where 1e-6 took 45; Talos: 30 where it took 51); "near": a start within that,
#: where the small one is quicker (Talos: 24 and 22 iterations against 30 and 34).
WARM_STARTS = {"near": {"bound_push": 1e-8, "bound_frac": 1e-8, "mu_init": 1e-6,
                        "mu_strategy": "monotone"},
               "far": {"bound_push": 1e-8, "bound_frac": 1e-8, "mu_init": 1e-4,
                       "mu_strategy": "monotone"}}
#: A "near" start also takes the last mesh's multipliers, interpolated
#: (`refined_multipliers` of `lagrgen.collocation.guess`), with the point and them kept as they
#: are: the Panda's last mesh in 16 iterations instead of 25, Talos's last two in 17 and 16
#: instead of 24 and 22. From a "far" start they do not help (27 against 25 on the Panda), and
#: an identification (examples/chain_identification.py, its last mesh's error 1.05) stalled on
#: them.
DUAL_OPTIONS = {"warm_start_init_point": "yes", "warm_start_bound_push": 1e-9,
                "warm_start_bound_frac": 1e-9, "warm_start_mult_bound_push": 1e-9,
                "warm_start_slack_bound_push": 1e-9, "warm_start_slack_bound_frac": 1e-9}


#: IPOPT counts iterations in a C int.
MAX_ITERATIONS = 2**31 - 1


#: The solvers `Collocation.solve` may use: "auto" (IPOPT on the first mesh; the structured SQP
#: on the refined meshes and a re-plan it covers, from the warm start's motion and multipliers,
#: IPOPT from the same start where it fails or its stationarity residual stalls (and on the
#: refinement's meshes after it), from its last iterate where that is near a solution, finishing
#: from its answer where it stops on a flat optimum short of tol: benchmarks/robot_motions.py),
#: "ipopt", or "sqp" (the structured SQP on every warm-started mesh, IPOPT on one started from a
#: guess, an error where the SQP does not apply, IPOPT with a note where one of its steps fails
#: or it does not converge).
SOLVERS = ("auto", "ipopt", "sqp")


@dataclass(frozen=True)
class Settings:
    """How each mesh of a solve runs (checked by `settings`)."""
    hessian: str
    tol: float
    max_iter: int
    progress: bool
    options: dict
    solver: str = "auto"


def settings(hessian, tol, max_iter, progress, options, solver="auto"):
    """The checked `Settings` of `Collocation.solve`'s arguments; a LagrgenError saying what is
    wrong otherwise (before IPOPT, which would print its documentation and fail)."""
    if hessian not in ("exact", "quasi-newton"):
        raise LagrgenError(f"hessian must be 'exact' or 'quasi-newton', got {hessian!r}")
    if solver not in SOLVERS:
        raise LagrgenError(f"solver must be one of {', '.join(map(repr, SOLVERS))}, got "
                           f"{solver!r}")
    if solver == "sqp" and hessian != "exact":
        raise LagrgenError("solver='sqp' needs the exact Hessian (hessian='exact')")
    if isinstance(tol, bool) or not isinstance(tol, numbers.Real) or not math.isfinite(tol) \
            or tol <= 0:
        raise LagrgenError(f"tol must be a positive finite number (IPOPT's convergence "
                           f"tolerance, e.g. 1e-8), got {tol!r}")
    if isinstance(max_iter, bool) or not isinstance(max_iter, numbers.Integral) \
            or not 0 <= max_iter <= MAX_ITERATIONS:
        raise LagrgenError(f"max_iter must be an integer from 0 to {MAX_ITERATIONS} (IPOPT's "
                           f"iteration limit), got {max_iter!r}")
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise LagrgenError(f"options must be a dict of IPOPT option names and values, got "
                           f"{type(options).__name__}")
    for name, value in options.items():
        if not isinstance(name, str):
            raise LagrgenError(f"options: IPOPT option names are strings, got {name!r}")
        number = isinstance(value, numbers.Real) and not isinstance(value, bool)
        if not (isinstance(value, str) or number) or (number and not math.isfinite(value)):
            raise LagrgenError(f"options[{name!r}] must be a string or a finite number (IPOPT "
                               f"takes no other values), got {value!r}")
    return Settings(hessian, float(tol), int(max_iter), bool(progress), dict(options), solver)


def solver_options(hessian, tol, max_iter, options, start=None, duals=False):
    """The IPOPT options of a solve: the base, those of the Hessian's kind (and of a refined
    mesh's `start`, a key of WARM_STARTS, and DUAL_OPTIONS when it starts from multipliers),
    tol and max_iter, and then the caller's."""
    kind = EXACT_OPTIONS if hessian == "exact" else QUASI_NEWTON_OPTIONS
    return {**BASE_OPTIONS, **kind, **(WARM_STARTS[start] if start else {}),
            **(DUAL_OPTIONS if duals else {}), "tol": float(tol), "max_iter": int(max_iter),
            **options}


def ipopt():
    """A module with cyipopt's `Problem` class, or a LagrgenError saying how to install it."""
    for name in ("cyipopt", "ipopt_wrapper"):
        module = sys.modules.get(name)
        if module is not None and hasattr(module, "Problem"):
            return module
    try:
        return _wrapper_alone()
    except Exception:      # another layout of cyipopt: its package, as usual
        pass
    try:
        import cyipopt
    except ImportError:
        raise LagrgenError(
            "Collocation.solve needs IPOPT through the cyipopt module: pip install "
            "'lagrgen[optimize]' (the binary wheels of cyipopt-wheels carry IPOPT; no system "
            "library is needed)") from None
    return cyipopt


def _wrapper_alone():
    """cyipopt's compiled `ipopt_wrapper` with `cyipopt.exceptions`, without the package."""
    package = importlib.util.find_spec("cyipopt")
    if package is None or importlib.util.find_spec("ipopt_wrapper") is None:
        raise ImportError("no cyipopt")
    if "cyipopt.exceptions" not in sys.modules:
        path = Path(list(package.submodule_search_locations)[0]) / "exceptions.py"
        spec = importlib.util.spec_from_file_location("cyipopt.exceptions", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[spec.name]
            raise
    import ipopt_wrapper
    if not hasattr(ipopt_wrapper, "Problem"):
        raise ImportError("ipopt_wrapper has no Problem")
    return ipopt_wrapper


class _Progress:
    """One line per IPOPT iteration, at most `rate` lines a second (and always the last)."""

    def __init__(self, enabled, rate=4.0):
        self.enabled, self.interval = enabled, 1.0 / rate
        self.last_print = -np.inf
        self.pending = None
        self.iterations = 0
        self.interrupted = False

    def __call__(self, alg_mod, iter_count, obj_value, inf_pr, inf_du, mu, d_norm,
                 regularization_size, alpha_du, alpha_pr, ls_trials):
        self.iterations = iter_count
        if not self.enabled:
            return not self.interrupted
        now = time.perf_counter()
        line = (f"{iter_count:5d}  {obj_value: .8e}  {inf_pr:.2e}  {inf_du:.2e}  "
                f"{np.log10(max(mu, 1e-300)):6.2f}  {alpha_pr:.2e}")
        if iter_count == 0:
            print(" iter   objective        inf_pr    inf_du    lg(mu)  alpha_pr", flush=True)
        if now - self.last_print >= self.interval or iter_count < 3:
            print(line, flush=True)
            self.last_print, self.pending = now, None
        else:
            self.pending = line
        return not self.interrupted

    def finish(self):
        if self.enabled and self.pending:
            print(self.pending, flush=True)


def add_option(nlp, key, value):
    """Set one IPOPT option (an integer given for a real option as a real); a LagrgenError with
    IPOPT's own words when it refuses the name or the value (which IPOPT prints, with its
    documentation of the option, to the C stdout)."""
    tries = [value, float(value)] if isinstance(value, numbers.Integral) else [value]
    with _c_stdout() as printed:
        for attempt in tries:
            try:
                nlp.add_option(key, attempt)
                refused = False
                break
            except TypeError:
                refused = True
    if refused:
        said = " ".join(line.strip() for line in printed[0].splitlines()[:2] if line.strip())
        raise LagrgenError(f"IPOPT refuses the option {key}={value!r}: {said or 'unknown name'} "
                           "(IPOPT's options: https://coin-or.github.io/Ipopt/OPTIONS.html)")


@contextmanager
def _c_stdout():
    """Catch what C code writes to the process's stdout (file descriptor 1): yields a list
    that holds the text once the block ends."""
    sys.stdout.flush()
    saved, printed = os.dup(1), [""]
    with tempfile.TemporaryFile() as caught:
        os.dup2(caught.fileno(), 1)
        try:
            yield printed
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            caught.seek(0)
            printed[0] = caught.read().decode(errors="replace")


def solve_mesh(problem, layout, controls, guess, settings, start=None, shift=0.0,
               replan=False):
    """The CollocationResult of one solve of `problem` on the mesh `layout` (inputs tied to
    `controls`, a ControlMesh, or free) from `guess` (see `Collocation.solve`; `shift` seconds
    of an earlier result dropped, its end held); `start`: a refined mesh's start from the last
    mesh's solution, which IPOPT takes with those options of WARM_STARTS, or None: IPOPT's usual
    barrier, also for a re-plan (a new initial state or a shift puts its start off the central
    path, where the warm options took 215-221 iterations on the Panda against a cold solve's
    26-28); from a "near" start IPOPT also starts from the guess's multipliers
    (`guess.refined_multipliers`, with DUAL_OPTIONS); the structured SQP (with the guess's
    multipliers) solves a warm-started mesh (a refined one, a `replan`, or one started from an
    earlier result; under "sqp" also one from any other guess, a cold start) instead when
    `settings.solver` is "sqp", or "auto" on a `replan` or a refined mesh the SQP covers
    (IPOPT from the same start, with a note and the result's `sqp_failed`, where one of its
    steps fails, it does not converge or, under "auto", its stationarity residual stalls or its
    KKT error crawls; from the SQP's last iterate and multipliers instead where that is within
    `sqp.NEAR_SOLUTION` of a solution; under "auto" IPOPT from the SQP's answer where it stops
    short of tol on a flat optimum: `finished_by_ipopt`; a max_iter the SQP reaches ends the
    solve there, as IPOPT's would)."""
    from .guess import initial_guess, refined_multipliers, warm_multipliers
    from .result import CollocationResult
    tr = problem.transcription(settings.hessian, layout, controls)
    x0 = initial_guess(problem, tr, guess, shift)
    T0 = layout.duration(x0) if layout.free else problem.duration_bounds[0]
    bound = tr.bound(T0)
    multipliers = refined_multipliers(bound, guess) if start == "near" else None
    if settings.solver == "ipopt" or (settings.solver == "auto" and not replan
                                      and start is None):
        return solve_nlp(problem, bound, x0, settings, start, multipliers)
    from .sqp import StepFailed, unsupported
    reason = unsupported(bound)
    if reason and settings.solver == "sqp":
        raise LagrgenError(f"solver='sqp' cannot solve this problem: the SQP does not handle "
                           f"{reason}; solve it with solver='auto' or 'ipopt'")
    cold = start is None and not isinstance(guess, CollocationResult)
    if reason or (cold and settings.solver != "sqp"):
        result = solve_nlp(problem, bound, x0, settings, start, multipliers)
        if reason and replan:
            result.notes.append(f"the structured SQP does not handle {reason}: IPOPT solved "
                                "this re-plan")
        return result
    lam0, z0 = warm_multipliers(bound, guess, shift)
    if lam0 is None and multipliers is not None:
        lam0, z0 = multipliers
    began = time.perf_counter()
    try:
        result = solve_structured(problem, bound, x0, lam0, z0, settings,
                                  purify=not getattr(guess, "_sqp_as_left", False))
    except StepFailed as exc:
        last = exc.outcome
        if last is not None and last.near:
            result = finished_by_ipopt(problem, bound, last.x, last.lam, last.z, settings,
                                       f"the structured SQP failed ({exc})")
        else:
            result = solve_nlp(problem, bound, x0, settings, start, multipliers)
            result.notes.append(f"the structured SQP failed ({exc}): IPOPT solved this mesh "
                                f"from the same start (result.solver says which solved it)")
        result.sqp_failed = str(exc)
        return timed_from(result, began)
    if result.status in (0, -1) or settings.solver == "sqp":     # -1: stopped at max_iter
        return result
    return timed_from(finished_by_ipopt(problem, bound, result.x, result._lam, result._z,
                                        settings, f"the structured SQP stopped short of tol "
                                                  f"({result.message})"), began)


def timed_from(result, began):
    """`result` of a mesh that IPOPT solved after the SQP, its seconds (and solve_seconds)
    counted from `began`, the SQP's start: both solvers' time."""
    result.seconds = result.solve_seconds = time.perf_counter() - began
    return result


def finished_by_ipopt(problem, tr, x, lam, z, settings, why):
    """IPOPT's solve of `tr` from the SQP's last point x and its multipliers lam and z, kept
    as a near start, with a note that says `why`: after a stop on a flat optimum (above tol;
    solver="sqp" returns the SQP's answer instead), and after a stall or a crawl within
    `sqp.NEAR_SOLUTION` (a re-plan from a disturbed state: 3 iterations where IPOPT from the
    re-plan's start took 1549)."""
    result = solve_nlp(problem, tr, x, settings, "near", (lam, z))
    result.notes.append(f"{why}: IPOPT finished this mesh from its motion and multipliers")
    return result


def solve_structured(problem, tr, x0, lam0, z0, settings, purify=True):
    """The CollocationResult of the structured SQP (`lagrgen.collocation.sqp`) on the
    transcription `tr` from (x0, lam0, z0); sqp.Unsupported where it does not apply, StepFailed
    where a step fails or it does not converge within its iterations. purify=False where the
    warm start's SQP took its QPs as the interior point left them (`sqp.solve`): a refined
    mesh of Talos then skips the active set's vain passes and solves its first QP as tightly as
    the later ones. A caller's max_iter below the SQP's own SQP_ITERATIONS is a bound on the
    work (a real-time iteration of model-predictive control: max_iter=1, one QP): the SQP's
    iterate where it ends is the result, status -1 as IPOPT's at its limit."""
    from .result import CollocationResult
    from .sqp import SQP_ITERATIONS, StepFailed, solve
    start = time.perf_counter()
    monitor, timed = _SQPProgress(settings.progress), _Timed(tr)
    outcome = solve(timed, x0, lam0, z0, settings.tol, min(settings.max_iter, SQP_ITERATIONS),
                    monitor, hand_over=settings.solver == "auto", purify=purify)
    seconds = time.perf_counter() - start
    stopped = not outcome.converged and settings.max_iter < SQP_ITERATIONS
    if not outcome.converged and not stopped:
        raise StepFailed(f"it stopped: {outcome.message}", outcome)
    flat = outcome.dual > settings.tol and not stopped
    if stopped:
        status, message = -1, (f"SQP stopped at max_iter={settings.max_iter} (the "
                               f"constraints' violation {outcome.primal:.1e}, the stationarity "
                               f"residual {outcome.dual:.1e}; tol {settings.tol:g})")
    elif flat:      # a success looser than tol, as IPOPT's acceptable level (status 1)
        status, message = 1, (f"SQP stopped on a flat optimum (stationarity residual "
                              f"{outcome.dual:.1e} above tol {settings.tol:g})")
    else:
        status, message = 0, "SQP converged to the tolerance"
    info = {"status": status, "status_msg": message, "obj_val": tr.objective(outcome.x),
            "mult_g": outcome.lam, "mult_z": outcome.z,
            "notes": [flat_optimum_note(outcome.dual, settings.tol)] if flat else []}
    result = CollocationResult.from_solution(problem, tr, outcome.x, info, outcome.iterations,
                                             seconds, settings.hessian)
    result.callback_seconds = timed.seconds
    result.solver, result._sqp_as_left = "sqp", outcome.as_left
    return result


def flat_optimum_note(dual, tol):
    """The note of an SQP solve that ended on a flat optimum, its stationarity residual `dual`
    above `tol`."""
    return (f"the SQP stopped where its steps no longer lower the objective, its stationarity "
            f"residual {dual:.1e} above tol {tol:g}: the optimum is flat there (a motion not "
            f"unique to the last digits) and found less precisely than tol; solver='ipopt' "
            f"solves to tol")


class _Timed:
    """The transcription `tr` with the time spent in its evaluations counted (`seconds`): the
    structured SQP's callbacks, as `_Callbacks` counts IPOPT's (the rest is the SQP's own)."""

    EVALUATIONS = frozenset({"objective", "constraints", "gradient", "jacobian",
                             "point_hessians", "point_gradients", "point_residuals"})

    def __init__(self, tr):
        self._tr, self.seconds = tr, 0.0

    def __getattr__(self, name):
        value = getattr(self._tr, name)
        if name not in self.EVALUATIONS:
            return value

        def timed(*args):
            start = time.perf_counter()
            try:
                return value(*args)
            finally:
                self.seconds += time.perf_counter() - start
        return timed


class _SQPProgress:
    """One line per SQP iteration when enabled."""

    def __init__(self, enabled):
        self.enabled = enabled

    def __call__(self, iteration, objective, primal, dual, alpha):
        if not self.enabled:
            return
        if iteration == 1:
            print(" iter   objective        inf_pr    inf_du    alpha (SQP)", flush=True)
        print(f"{iteration:5d}  {objective: .8e}  {primal:.2e}  {dual:.2e}  {alpha:.2e}",
              flush=True)


def solve_nlp(problem, tr, x0, settings, start=None, multipliers=None):
    """Run IPOPT on the transcription from x0 (a refined mesh's `start`: see `solve_mesh`; and
    the constraints' and bounds' `multipliers` (λ, z) when given); the CollocationResult."""
    from .result import CollocationResult
    cyipopt = ipopt()
    began = time.perf_counter()
    monitor = _Progress(settings.progress)
    adapter = _Callbacks(tr, monitor)
    nlp = cyipopt.Problem(n=tr.layout.size, m=tr.n_constraints, problem_obj=adapter,
                          lb=tr.lo, ub=tr.hi, cl=tr.g_lo, cu=tr.g_hi)
    hessian = settings.hessian
    for key, value in solver_options(hessian, settings.tol, settings.max_iter, settings.options,
                                     start, duals=multipliers is not None).items():
        add_option(nlp, key, value)
    duals = {}
    if multipliers is not None:
        lam, z = multipliers
        duals = {"lagrange": lam, "zl": np.maximum(-z, 0.0), "zu": np.maximum(z, 0.0)}
    x0 = np.clip(np.asarray(x0, dtype=float), tr.lo, tr.hi)
    try:
        x, info = nlp.solve(x0, **duals)
    finally:
        if hasattr(nlp, "close"):
            nlp.close()
    if adapter.interrupt is not None:
        raise KeyboardInterrupt
    if int(info["status"]) == INVALID_OPTION:
        raise LagrgenError(f"IPOPT refused an option's value (Invalid_Option): check options="
                           f"{settings.options!r} against IPOPT's list of options "
                           "(https://coin-or.github.io/Ipopt/OPTIONS.html)")
    monitor.finish()
    seconds = time.perf_counter() - began
    info["mult_z"] = np.asarray(info["mult_x_U"]) - np.asarray(info["mult_x_L"])
    result = CollocationResult.from_solution(problem, tr, np.asarray(x), info,
                                             monitor.iterations, seconds, hessian)
    result.callback_seconds = adapter.seconds
    result.solver = "ipopt"
    return result


class _Callbacks:
    """The object cyipopt calls: the transcription's callbacks, with Ctrl-C ending the solve and
    the time spent in them counted (`seconds`; the rest of a solve is IPOPT's own)."""

    def __init__(self, tr, monitor):
        self.tr, self.monitor, self.interrupt = tr, monitor, None
        self.seconds = 0.0
        self.jacobianstructure = tr.jacobianstructure
        if tr.exact:
            self.hessianstructure = tr.hessianstructure

    def _guard(self, f, *args):
        start = time.perf_counter()
        try:
            return f(*args)
        except KeyboardInterrupt as exc:
            self.interrupt = exc
            self.monitor.interrupted = True
            raise
        finally:
            self.seconds += time.perf_counter() - start

    def objective(self, x):
        return self._guard(self.tr.objective, x)

    def gradient(self, x):
        return self._guard(self.tr.gradient, x)

    def constraints(self, x):
        return self._guard(self.tr.constraints, x)

    def jacobian(self, x):
        return self._guard(self.tr.jacobian, x)

    def hessian(self, x, lagrange, obj_factor):
        return self._guard(self.tr.hessian, x, lagrange, obj_factor)

    def intermediate(self, *args):
        try:
            return self.monitor(*args)
        except KeyboardInterrupt as exc:
            self.interrupt = exc
            return False
