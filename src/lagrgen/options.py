"""The numeric options of a run, each checked once where it enters (`simulate`,
`simulate_many`, the hybrid solve, the command line, an FMU's solver settings): one rule and one
message per option, the same for every engine. Plain Python and NumPy, so that every stage may
use it; the FMU's C setters apply the same rules (codegen/templates/fmu_core.c.in).

The rules: rtol in (0, 1); atol ≥ 0; max_step > 0 (inf: none); first_step > 0 and within the
span; max_wall_time > 0 seconds; max_steps, max_transitions whole numbers from 1 to 2³¹ − 1 (a C long everywhere);
gap_tol, rest_velocity ≥ 0; t_eval finite, within t_span, in the direction of integration.
Every number finite unless said otherwise (NaN never).
"""
import math
import numbers

import numpy as np

#: The largest count a guard takes: the C engine holds it in a long (32 bits on Windows).
MAX_COUNT = 2 ** 31 - 1
#: The options of a model with impacts or frictions (`lagrgen.hybrid`).
SWITCHING_OPTIONS = ("rest_velocity", "gap_tol", "max_transitions")


def _shown(value):
    """A value as a message shows it: NumPy scalars as plain numbers."""
    return repr(value.item() if isinstance(value, np.generic) else value)


def _number(value, name, what):
    """`value` as a float; ValueError naming the option when it is no real number."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.ndarray)):
        raise ValueError(f"{name} must be {what}, got {_shown(value)}")
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be {what}, got {_shown(value)}") from None


def _tolerance(value, name, what, ok, array_what):
    """`value` as a float, or a 1-D float array, whose every entry satisfies `ok`; ValueError
    naming the option (and the first bad entry of an array) otherwise."""
    if np.ndim(value):
        values = np.asarray(value)
        if values.dtype.kind not in "fiu" or values.ndim != 1:
            raise ValueError(f"{name} must be {array_what}, got {_shown(value)}")
        values = values.astype(float)
        bad = ~ok(values)
        if bad.any():
            raise ValueError(f"{name} must be {what}: entry {int(np.argmax(bad))} is "
                             f"{_shown(values[bad][0])}")
        return values
    number = _number(value, name, what)
    if not ok(np.float64(number)):
        raise ValueError(f"{name} must be {what}, got {_shown(number)}")
    return number


def relative_tolerance(rtol, name="rtol"):
    """rtol as a float (or a float array, for the SciPy engine): every entry finite in (0, 1)."""
    what = "positive and less than 1, e.g. 1e-6"
    return _tolerance(rtol, name, what, lambda v: (v > 0) & (v < 1),
                      f"a number or a 1-D array of numbers {what}")


def absolute_tolerance(atol, name="atol"):
    """atol as a float or a 1-D float array: every entry finite and ≥ 0."""
    what = "a finite number ≥ 0, e.g. 1e-9"
    return _tolerance(atol, name, what, lambda v: np.isfinite(v) & (v >= 0),
                      f"{what} or a 1-D array of them (one per state)")


def count(value, name, none="no limit"):
    """A guard's count (None: `none`): a whole number from 1 to MAX_COUNT, as an int."""
    if value is None:
        return None
    what = f"a positive integer up to {MAX_COUNT} (a C long; None for {none})"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be {what}, got {_shown(value)}")
    if isinstance(value, numbers.Integral):
        whole = int(value)
    else:
        number = float(value)
        if not (math.isfinite(number) and number == int(number)):
            raise ValueError(f"{name} must be {what}, got {_shown(value)}")
        whole = int(number)
    if not 1 <= whole <= MAX_COUNT:
        raise ValueError(f"{name} must be {what}, got {_shown(value)}")
    return whole


def seconds(value, name="max_wall_time"):
    """A wall-time limit (None: none): a finite number of seconds > 0."""
    if value is None:
        return None
    what = "a positive number of seconds (None for no limit)"
    number = _number(value, name, what)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be {what}, got {_shown(value)}")
    return number


def nonnegative(value, name, default=None):
    """A switching tolerance (None: `default`): a finite number ≥ 0."""
    if value is None:
        return default
    what = "a finite number ≥ 0"
    number = _number(value, name, what)
    if not (math.isfinite(number) and number >= 0):
        raise ValueError(f"{name} must be {what}, got {_shown(value)}")
    return number


def max_step(value):
    """solve_ivp's max_step: a number > 0 (inf, the default: no limit)."""
    number = _number(value, "max_step", "a positive number (inf for no limit)")
    if not number > 0:
        raise ValueError(f"max_step must be a positive number (inf for no limit), got {_shown(value)}")
    return number


def first_step(value, t_span):
    """solve_ivp's first_step (None: chosen by the solver): finite, > 0, at most |tf − t0|."""
    if value is None:
        return None
    what = "a positive number no larger than the time span (None: chosen by the solver)"
    number = _number(value, "first_step", what)
    if not (math.isfinite(number) and 0 < number <= abs(t_span[1] - t_span[0])):
        raise ValueError(f"first_step must be {what}, got {_shown(value)}")
    return number


def output_times(t_eval, t0, tf):
    """t_eval as a float array (None stays None): 1-D, finite, within [t0, tf], strictly in the
    direction of integration."""
    if t_eval is None:
        return None
    try:
        times = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"t_eval must be a 1-D array of times, got {_shown(t_eval)}") from None
    if times.ndim != 1:
        raise ValueError(f"t_eval must be a 1-D array of times, got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        k = int(np.argmax(~np.isfinite(times)))
        raise ValueError(f"t_eval must hold finite times: entry {k} is {_shown(times[k])}")
    if np.any(times < min(t0, tf)) or np.any(times > max(t0, tf)):
        raise ValueError(f"t_eval has times not within `t_span` ({_shown(t0)}, {_shown(tf)})")
    d = np.diff(times)
    if (tf > t0 and np.any(d <= 0)) or (tf < t0 and np.any(d >= 0)):
        raise ValueError("t_eval must be sorted strictly in the direction of integration "
                         "(increasing when t_span[1] > t_span[0])")
    return np.ascontiguousarray(times)


def check_run_options(rtol, atol, t_span, t_eval=None, max_steps=None, max_wall_time=None,
                      options=None):
    """Check every numeric option of one run (ValueError naming the first bad one) and return
    (rtol, atol, t_eval, max_steps, max_wall_time, options): numbers as floats, counts as ints,
    t_eval as an array.

    `options` are simulate's remaining keyword options (max_step, first_step and, for a model
    with impacts or frictions, rest_velocity, gap_tol, max_transitions).
    """
    options = dict(options or {})
    rtol = relative_tolerance(rtol)
    atol = absolute_tolerance(atol)
    t0, tf = t_span
    t_eval = output_times(t_eval, t0, tf)
    max_steps = count(max_steps, "max_steps")
    max_wall_time = seconds(max_wall_time)
    if "max_step" in options:
        options["max_step"] = max_step(options["max_step"])
    if "first_step" in options:
        options["first_step"] = first_step(options["first_step"], t_span)
    if "rest_velocity" in options:
        options["rest_velocity"] = nonnegative(options["rest_velocity"], "rest_velocity")
    for name, check in (("gap_tol", nonnegative),
                        ("max_transitions", lambda v, n: count(v, n, "the default"))):
        if name in options:
            options[name] = check(options[name], name)
            if options[name] is None:
                del options[name]
    return rtol, atol, t_eval, max_steps, max_wall_time, options
