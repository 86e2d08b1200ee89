"""A restricted reader of numbers and expressions of t typed by users (the CLI's --inputs, --params).

User text is never evaluated as Python: it is parsed with `ast` and only numbers, the names `t`,
`pi` and `e`, the operators + − × ÷ ** and the functions of FUNCTIONS (each with its number of
arguments, ARITY) are accepted, in a text of at most MAX_LENGTH characters nested at most
MAX_DEPTH deep, every number a double; the tree is turned into a closure over NumPy functions.
Anything else is a one-line `ExpressionError`.
"""
import ast
import functools
import math
import operator

import numpy as np

from .errors import LagrgenError


class ExpressionError(LagrgenError, ValueError):
    """A number or an expression of t that the restricted reader does not accept."""


def _heaviside(x):
    return np.heaviside(x, 0.5)


#: The functions an expression may call (lower-case names; SymPy's capitalized ones too).
FUNCTIONS = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos,
    "atan": np.arctan, "atan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh,
    "exp": np.exp, "log": np.log, "sqrt": np.sqrt, "abs": np.abs, "sign": np.sign,
    "heaviside": _heaviside, "min": np.minimum, "max": np.maximum, "floor": np.floor,
}
FUNCTIONS.update({"Abs": np.abs, "Heaviside": _heaviside, "Min": np.minimum,
                  "Max": np.maximum})
#: (fewest, most) arguments of each function (None: any number); the others take one.
ARITY = {"atan2": (2, 2), "min": (2, None), "max": (2, None), "Min": (2, None),
         "Max": (2, None)}
#: The longest text and the deepest nesting (of operators and calls) the reader accepts.
MAX_LENGTH = 2000
MAX_DEPTH = 100
CONSTANTS = {"pi": math.pi, "e": math.e}
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow, ast.Mod: operator.mod}
_UNARY = {ast.UAdd: operator.pos, ast.USub: operator.neg}


def _shown(text, limit=60):
    """`text` quoted, cut to `limit` characters (a message stays one readable line)."""
    return repr(text) if len(text) <= limit else repr(text[:limit]) + f"... ({len(text)} chars)"


def _reject(text, what):
    names = ", ".join(sorted(n for n in FUNCTIONS if n.islower()))
    raise ExpressionError(f"cannot read {_shown(text)}: {what} (allowed: numbers, t, pi, e, "
                          f"+ - * / **, and the functions {names})")


def _compile(node, text, names):
    """A function of t for the syntax tree `node`, and whether it depends on t."""
    if isinstance(node, ast.Expression):
        return _compile(node.body, text, names)
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        try:
            value = np.float64(float(node.value))
        except OverflowError:
            value = np.float64(np.inf)
        if not np.isfinite(value):
            digits = ast.get_source_segment(text.strip(), node) or str(node.value)[:30]
            _reject(text, f"the number {digits[:30]}{'...' if len(digits) > 30 else ''} does "
                    "not fit a double (|x| up to 1.8e308)")
        return (lambda t: value), False
    if isinstance(node, ast.Name):
        if node.id == "t":
            return (lambda t: t), True
        if node.id in names or node.id in CONSTANTS:
            value = np.float64(names[node.id] if node.id in names else CONSTANTS[node.id])
            return (lambda t: value), False
        _reject(text, f"unknown name {node.id!r}")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        op = _BINARY[type(node.op)]
        (a, ta), (b, tb) = _compile(node.left, text, names), _compile(node.right, text, names)
        return (lambda t: op(a(t), b(t))), ta or tb
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        op = _UNARY[type(node.op)]
        a, ta = _compile(node.operand, text, names)
        return (lambda t: op(a(t))), ta
    if isinstance(node, ast.Call) and not isinstance(node.func, ast.Name):
        _reject(text, f"only the listed functions may be called, not {ast.unparse(node.func)}")
    if isinstance(node, ast.Call) and not node.keywords:
        if node.func.id not in FUNCTIONS:
            _reject(text, f"unknown function {node.func.id!r}")
        name = node.func.id
        fewest, most = ARITY.get(name, (1, 1))
        if len(node.args) < fewest or (most is not None and len(node.args) > most) \
                or any(isinstance(a, ast.Starred) for a in node.args):
            count = (f"{fewest}" if most == fewest else f"{fewest} or more" if most is None
                     else f"{fewest} to {most}")
            _reject(text, f"{name}() takes {count} argument{'s' if most != 1 else ''}, "
                    f"got {len(node.args)}")
        fn = FUNCTIONS[name]
        if len(node.args) > 2:
            fn = functools.partial(functools.reduce, fn)
            args = [_compile(a, text, names) for a in node.args]
            funcs = [f for f, _ in args]
            return (lambda t: fn(f(t) for f in funcs)), any(dep for _, dep in args)
        args = [_compile(a, text, names) for a in node.args]
        funcs = [f for f, _ in args]
        return (lambda t: fn(*(f(t) for f in funcs))), any(dep for _, dep in args)
    _reject(text, f"{type(node).__name__.lower()} is not allowed")


def _parse(text, names=None):
    if not isinstance(text, str) or not text.strip():
        raise ExpressionError(f"expected a number or an expression of t, got {text!r}")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression too long ({len(text)} characters, over "
                              f"{MAX_LENGTH})")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"cannot read {_shown(text)}: {exc.msg}") from None
    except (RecursionError, MemoryError):
        raise ExpressionError(f"expression nested too deeply (over {MAX_DEPTH} levels)") from None
    _check_depth(tree)
    return _compile(tree, text, dict(names or {}))


def _check_depth(tree):
    """ExpressionError if the syntax tree is nested deeper than MAX_DEPTH (each operand of a
    chain such as a + b + c + ... is one level deeper than the next)."""
    stack = [(tree, 0)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise ExpressionError(f"expression nested too deeply (over {MAX_DEPTH} levels: a "
                                  "sum or product of many terms counts one level per term)")
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))


def parse_time_function(text, names=None):
    """A float (when `text` does not depend on t) or a function t -> float for `text`.

    Parameters
    ----------
    text : str
        e.g. "0.5", "0.5*sin(2*pi*t)", "Max(0, t - 0.5)", "heaviside(t - 1)".
    names : dict, optional
        Further names the text may use, with their (constant) values, e.g. {"w": 2.0}.

    Returns
    -------
    float or callable
    """
    f, depends_on_t = _parse(text, names)
    if not depends_on_t:
        return _finite(_evaluate(f, 0.0), text)
    return lambda t: _evaluate(f, t)


def parse_number(text):
    """The float value of `text`, a number or an expression without t (e.g. "2*pi", "1e-3")."""
    f, depends_on_t = _parse(text)
    if depends_on_t:
        raise ExpressionError(f"{text!r} must be a number, not an expression of t")
    return _finite(_evaluate(f, 0.0), text)


def _evaluate(f, t):
    """f(t) as a float, in IEEE arithmetic (1/0 = inf, sqrt(-1) = nan), as NumPy computes it."""
    with np.errstate(all="ignore"):
        return float(f(np.float64(t)))


def _finite(value, text):
    if not math.isfinite(value):
        raise ExpressionError(f"{_shown(text)} is not a finite number ({value})")
    return value
