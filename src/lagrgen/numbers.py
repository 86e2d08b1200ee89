"""Numbers in model expressions: which ones a double holds, and which ones are zero.

Every number that rounds to a finite nonzero double is printed as that double (subnormals
included), and zero is zero; refused are numbers that overflow a double, NaN, and nonzero numbers
so small that they would silently become 0. Since SymPy 1.13 `Float(0.0) == 0` is False, so zero
is asked of the number itself (`is_zero`) rather than tested with `==`.
"""
import math


def finite_number(value, what, error):
    """`value` as a float; an `error` (an exception class) naming `what` when it is not a finite
    number."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise error(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise error(f"{what} must be finite, got {number}")
    return number


def fits_a_double(number):
    """True if `number` (int, Fraction, float, or a SymPy/SymEngine number) is zero or rounds to
    a finite nonzero double."""
    try:
        value = float(number)
    except (OverflowError, TypeError, ValueError):
        return False
    return math.isfinite(value) and (value != 0.0 or is_zero(number))


def is_zero(expr):
    """True for an exact or floating-point zero (Python, SymPy or SymEngine), False for anything
    else, including expressions that are not known to be zero."""
    known = getattr(expr, "is_zero", None)
    if isinstance(known, bool):
        return known
    try:
        return bool(expr == 0)
    except TypeError:
        return False
