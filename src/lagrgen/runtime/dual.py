"""Forward-mode derivatives on the Python backend: `Dual` numbers (a value and its gradient with
respect to chosen variables) and the namespace that runs a kernel's Python source on them.

A kernel of first derivatives run on duals seeded with the variables z gives their exact
second derivatives (no step, no truncation): the Python backend's residual Hessian of a model
whose second derivatives are not a kernel of its own.
"""
import math

import numpy as np


class Dual:
    """x + ε·g with ε² = 0: the value x (float) and its gradient g (1-D float64 array)."""

    __slots__ = ("x", "g")

    def __init__(self, x, g):
        self.x, self.g = float(x), g

    # -- arithmetic ----------------------------------------------------------------------------
    def __add__(self, other):
        if isinstance(other, Dual):
            return Dual(self.x + other.x, self.g + other.g)
        return Dual(self.x + other, self.g)

    __radd__ = __add__

    def __sub__(self, other):
        if isinstance(other, Dual):
            return Dual(self.x - other.x, self.g - other.g)
        return Dual(self.x - other, self.g)

    def __rsub__(self, other):
        return Dual(other - self.x, -self.g)

    def __neg__(self):
        return Dual(-self.x, -self.g)

    def __pos__(self):
        return self

    def __mul__(self, other):
        if isinstance(other, Dual):
            return Dual(self.x * other.x, self.g * other.x + other.g * self.x)
        return Dual(self.x * other, self.g * other)

    __rmul__ = __mul__

    def __truediv__(self, other):
        if isinstance(other, Dual):
            return Dual(self.x / other.x, (self.g * other.x - other.g * self.x) / other.x ** 2)
        return Dual(self.x / other, self.g / other)

    def __rtruediv__(self, other):
        return Dual(other / self.x, -other * self.g / self.x ** 2)

    def __pow__(self, k):
        if isinstance(k, Dual):
            return exp(k * log(self))
        if k == 0:
            return Dual(1.0, self.g * 0.0)
        return Dual(self.x ** k, k * self.x ** (k - 1) * self.g)

    def __rpow__(self, base):
        return exp(self * math.log(base))

    def __abs__(self):
        return self if self.x >= 0 else -self

    # -- comparisons (of the values: the branch taken at the point) ----------------------------
    def _value(other):
        return other.x if isinstance(other, Dual) else other

    def __lt__(self, other):
        return self.x < Dual._value(other)

    def __le__(self, other):
        return self.x <= Dual._value(other)

    def __gt__(self, other):
        return self.x > Dual._value(other)

    def __ge__(self, other):
        return self.x >= Dual._value(other)

    def __float__(self):
        return self.x


def seeded(values):
    """The duals of `values` as the variables: value i with the unit gradient e_i."""
    eye = np.eye(len(values))
    return [Dual(v, eye[i]) for i, v in enumerate(values)]


def value(x):
    """The value of a dual or a number."""
    return x.x if isinstance(x, Dual) else float(x)


def gradient(x, size):
    """The gradient of a dual (zeros for a number)."""
    return x.g if isinstance(x, Dual) else np.zeros(size)


def _lift(f, df):
    """f on numbers and duals, df its derivative (of the value)."""
    def apply(x):
        if isinstance(x, Dual):
            return Dual(f(x.x), df(x.x) * x.g)
        return f(x)
    apply.__name__ = f.__name__
    return apply


sin = _lift(math.sin, math.cos)
cos = _lift(math.cos, lambda x: -math.sin(x))
tan = _lift(math.tan, lambda x: 1.0 + math.tan(x) ** 2)
asin = _lift(math.asin, lambda x: 1.0 / math.sqrt(1.0 - x * x))
acos = _lift(math.acos, lambda x: -1.0 / math.sqrt(1.0 - x * x))
atan = _lift(math.atan, lambda x: 1.0 / (1.0 + x * x))
sinh = _lift(math.sinh, math.cosh)
cosh = _lift(math.cosh, math.sinh)
tanh = _lift(math.tanh, lambda x: 1.0 - math.tanh(x) ** 2)
asinh = _lift(math.asinh, lambda x: 1.0 / math.sqrt(x * x + 1.0))
acosh = _lift(math.acosh, lambda x: 1.0 / math.sqrt(x * x - 1.0))
atanh = _lift(math.atanh, lambda x: 1.0 / (1.0 - x * x))
exp = _lift(math.exp, math.exp)
log = _lift(math.log, lambda x: 1.0 / x)
sqrt = _lift(math.sqrt, lambda x: 0.5 / math.sqrt(x))


def atan2(y, x):
    """atan2 on numbers and duals: d = (x·dy − y·dx)/(x² + y²)."""
    if not isinstance(y, Dual) and not isinstance(x, Dual):
        return math.atan2(y, x)
    xv, yv = value(x), value(y)
    size = (y if isinstance(y, Dual) else x).g.size
    g = (xv * gradient(y, size) - yv * gradient(x, size)) / (xv * xv + yv * yv)
    return Dual(math.atan2(yv, xv), g)


def _sign(x):
    v = value(x)
    return float(v > 0) - float(v < 0)


#: The namespace a kernel's Python source runs in on duals (the names of pymodel's namespace).
NAMESPACE = {"sin": sin, "cos": cos, "tan": tan, "asin": asin, "acos": acos, "atan": atan,
             "atan2": atan2, "sinh": sinh, "cosh": cosh, "tanh": tanh, "asinh": asinh,
             "acosh": acosh, "atanh": atanh, "exp": exp, "log": log, "sqrt": sqrt,
             "_sign": _sign, "_nan": math.nan}
