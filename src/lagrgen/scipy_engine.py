"""The SciPy engine: a solve through `scipy.integrate.solve_ivp` with the model's rhs and analytic
Jacobian (Radau and BDF as `lagrgen.solvers` classes), its compiled events as event callables, and
the step and wall-time guards as a terminal event."""
import math
import time

from scipy.integrate import solve_ivp

from .errors import NonFiniteError
from .methods import STIFF_METHODS
from .results import stopped_by_guard
from .solvers import SOLVERS


class Guard:
    """A terminal solve_ivp event that ends the integration after `max_steps` steps or
    `max_wall_time` seconds: solve_ivp evaluates it once per accepted step, so it counts steps; once
    tripped it changes sign just after the last step taken, where the solver then stops (keeping
    the result up to there)."""

    terminal = True
    direction = 0

    def __init__(self, max_steps, max_wall_time):
        self.max_steps, self.max_wall_time = max_steps, max_wall_time
        self.steps, self.start = -1, time.monotonic()
        self.last_t, self.tripped_at, self.reason = None, None, None

    def __call__(self, t, y):
        if self.tripped_at is not None:
            return -1.0 if t > self.tripped_at else 1.0
        self.steps += 1
        if self.max_steps is not None and self.steps > self.max_steps:
            self.reason = f"the step limit max_steps={self.max_steps} was reached"
        elif self.max_wall_time is not None and \
                time.monotonic() - self.start > self.max_wall_time:
            self.reason = f"the wall-time limit max_wall_time={self.max_wall_time:g} s was reached"
        if self.reason is None or self.last_t is None:
            self.last_t = t
            return 1.0
        self.tripped_at = self.last_t
        return -1.0


def event_functions(mod, p, u_at):
    """The model's compiled events as solve_ivp event callables (one per event)."""
    functions = []
    for k, (name, terminal, direction) in enumerate(mod.event_definitions):
        def g(t, y, k=k):
            return mod.events(t, y, p, u_at(t))[k]
        g.__name__, g.terminal, g.direction = name, terminal, direction
        functions.append(g)
    return functions


def solve_scipy(mod, t_span, y0, method, p, u_at, rtol, atol, t_eval=None, dense_output=False,
                events=None, max_steps=None, max_wall_time=None, progress=None, **options):
    """solve_ivp on ẏ = mod.rhs(t, y, p, u_at(t)), raising NonFiniteError at a non-finite
    derivative; events None means the model's compiled events. Returns SciPy's OdeResult with
    `engine` "scipy" and `guard` (None, or why a guard stopped it)."""
    rhs, jacobian = mod.rhs, mod.jacobian

    def fun(t, y):
        ydot = rhs(t, y, p, u_at(t))
        if not math.isfinite(ydot.sum()):
            raise NonFiniteError.at(mod.name, t, y)
        return ydot

    def watched(t, y):
        progress(t)
        return fun(t, y)

    def jac(t, y):
        return jacobian(t, y, p, u_at(t))

    if events is None:
        events = event_functions(mod, p, u_at) if mod.event_definitions else None
    elif not isinstance(events, (list, tuple)):
        events = [events]
    guard = None
    if max_steps is not None or max_wall_time is not None:
        guard = Guard(max_steps, max_wall_time)
        events = list(events or []) + [guard]
    if getattr(method, "__name__", method) in STIFF_METHODS:
        options.setdefault("jac", jac)
    sol = solve_ivp(watched if progress else fun, t_span, y0, method=SOLVERS.get(method, method),
                    rtol=rtol, atol=atol, t_eval=t_eval, dense_output=dense_output,
                    events=events, **options)
    sol.engine, sol.guard = "scipy", None
    if guard is not None:
        drop_guard_event(sol, guard, t_span)
    return sol


def drop_guard_event(sol, guard, t_span):
    """Drop the guard's event from `sol` and, if it stopped the run, say so (status −1)."""
    sol.t_events, sol.y_events = sol.t_events[:-1], sol.y_events[:-1]
    if not sol.t_events:        # the guard was the only event: as solve_ivp without events
        sol.t_events = sol.y_events = None
    if guard.reason is not None and len(sol.t) and sol.status == 1 and \
            guard.tripped_at is not None:
        if len(sol.t) > 1 and sol.t[-2] == guard.tripped_at:   # the guard's root, just after
            sol.t, sol.y = sol.t[:-1], sol.y[:, :-1]
        stopped_by_guard(sol, guard.reason, guard.tripped_at, t_span[1], guard.steps - 1)
