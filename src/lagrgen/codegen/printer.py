"""Code printers: SymEngine expressions and kernels to C99 and to Python source.

Printing goes through two small layers: an expression printer (precedence-aware, one method per node
type) and statements (`Declare` a CSE temporary, `Store` an output entry) that each language prints.
Symbols print by name: the internal names `q[i]`, `qd[i]`, `a[i]`, `p[j]`, `u[k]` and `t` are valid
array accesses in both languages, and no user-chosen name ever reaches the generated code.
"""
from dataclasses import dataclass
from fractions import Fraction

import symengine as se
from symengine.lib.symengine_wrapper import Constant

from ..errors import ModelError
from ..numbers import fits_a_double

ADD, MUL, ATOM = 1, 2, 3
#: Integers up to 2⁵³ are exact doubles and print as they are; larger ones as rounded doubles.
EXACT_INTEGER = 2 ** 53


def double(value, expr):
    """`value` (int, Fraction, Float) correctly rounded to a double; ModelError if it overflows."""
    if not fits_a_double(value):
        raise ModelError(f"the number {expr} in the equations does not fit a double "
                         f"(|x| up to 1.8e308): rescale the model's units or parameters")
    return float(value)


@dataclass
class Declare:
    """A CSE temporary: `const double name = expr;`."""
    name: str
    expr: object


@dataclass
class Comment:
    """A line for the reader of the generated code (no effect)."""
    text: str
    expr: object = se.Integer(0)


@dataclass
class Store:
    """An output entry: `array[index] = expr;`."""
    array: str
    index: int
    expr: object


@dataclass
class Zeros:
    """An output's first `count` entries set to zero (C: one memset; Python's output lists start
    as zeros), so that its zero entries need no statement each."""
    array: str
    count: int
    expr: object = se.Integer(0)


#: An output with at least this many zero entries is zeroed at once (`Zeros`) and only its other
#: entries stored: ∂Q/∂u of a robot, n × n_inputs with n nonzeros, would otherwise be n² stores.
ZEROS_AT_ONCE = 8


def kernel_statements(kernel):
    """The statements of a kernel: every output entry in order, each preceded by the CSE
    temporaries it needs that are not defined yet (so a temporary sits next to its first use, and a
    long kernel split into parts passes few of them between parts). A temporary no output needs
    is left out (a tangent whose uses cancelled, say): it would be dead code, and could name
    temporaries defined only after it."""
    temps = {str(sym): expr for sym, expr in kernel.temporaries}
    deps = {}

    def needs(expr):
        return [str(s) for s in expr.free_symbols if str(s) in temps]

    stmts, done = [], set()

    def require(names):
        stack = [(name, False) for name in names]
        while stack:
            name, ready = stack.pop()
            if name in done:
                continue
            if ready:
                done.add(name)
                stmts.append(Declare(name, temps[name]))
                continue
            if name not in deps:
                deps[name] = needs(temps[name])
            stack.append((name, True))
            stack.extend((d, False) for d in sorted(deps[name], key=_index, reverse=True)
                         if d not in done)

    require([name for name in temps if name not in done] if not kernel.outputs else [])
    notes = getattr(kernel, "notes", {})
    for name, exprs in kernel.outputs.items():
        zeroed = not getattr(kernel.spec, "lanes", ()) and \
            sum(1 for e in exprs if e == 0) >= ZEROS_AT_ONCE
        if zeroed:
            stmts.append(Zeros(name, len(exprs)))
        for i, e in enumerate(exprs):
            if (name, i) in notes:
                stmts.append(Comment(notes[name, i]))
            if zeroed and e == 0:
                continue
            require(sorted(needs(e), key=_index, reverse=True)[::-1])
            stmts.append(Store(name, i, e))
    return stmts


def _index(name):
    return int(name[1:])


def _is_negative(expr):
    if isinstance(expr, se.Number):
        return expr.is_negative
    if isinstance(expr, se.Mul):
        first = expr.args[0]
        return isinstance(first, se.Number) and first.is_negative
    return False


class ExpressionPrinter:
    """Shared precedence logic; subclasses name the functions and powers of their language."""

    functions = {}

    def doprint(self, expr):
        return self._print(expr)[0]

    def integer(self, v):
        return str(v)

    def real(self, v):
        """A floating-point literal (both languages: `2.0`, `0.25`)."""
        return f"{v}.0" if isinstance(v, int) else repr(float(v))

    def paren(self, expr, level):
        text, prec = self._print(expr)
        return f"({text})" if prec < level else text

    def _print(self, e):
        if isinstance(e, se.Symbol):
            return e.name, ATOM
        if isinstance(e, se.Integer):
            v = int(e)
            text = self.integer(v) if abs(v) <= EXACT_INTEGER else repr(double(v, e))
            return text, (ATOM if v >= 0 else MUL)
        if isinstance(e, se.Rational):
            num, den = (int(x) for x in e.get_num_den())
            if abs(num) <= EXACT_INTEGER and den <= EXACT_INTEGER:
                text = f"{self.real(abs(num))}/{self.real(den)}"
                return (f"-{text}" if num < 0 else text), MUL
            return repr(double(Fraction(num, den), e)), (ATOM if num >= 0 else MUL)
        if isinstance(e, se.Float):
            v = double(e, e)
            return repr(v), (ATOM if v >= 0 else MUL)
        if isinstance(e, Constant):
            return repr(float(e)), ATOM
        kind = type(e).__name__
        if kind == "NaN":
            return self.nan, ATOM
        if kind == "Piecewise":
            return self._print_piecewise(list(e.args)), ATOM
        if kind in RELATIONS:
            a, b = e.args
            return f"({self.doprint(a)} {RELATIONS[kind]} {self.doprint(b)})", ATOM
        if kind in ("And", "Or"):
            op = f" {self.logic[kind]} "
            return "(" + op.join(self.doprint(a) for a in e.args) + ")", ATOM
        if kind == "Not":
            return f"({self.logic['Not']}{self.doprint(e.args[0])})", ATOM
        if kind in ("BooleanTrue", "BooleanFalse"):
            return self.logic[kind], ATOM
        if isinstance(e, se.Add):
            return self._print_add(e), ADD
        if isinstance(e, se.Mul):
            return self._print_mul(e), MUL
        if isinstance(e, se.Pow):
            return self._print_pow(e)
        if isinstance(e, se.Function):
            name = self.functions.get(type(e).__name__)
            if name is None:
                raise NotImplementedError(f"no {self.language} equivalent for {type(e).__name__}")
            return f"{name}({', '.join(self.doprint(a) for a in e.args)})", ATOM
        raise NotImplementedError(f"cannot print {e!r} ({type(e).__name__}) as {self.language}")

    def _print_piecewise(self, args):
        """(e1, c1, e2, c2, ...): the first e_k whose c_k holds (NaN if none does)."""
        if not args:
            return self.nan
        value, cond = args[0], args[1]
        if type(cond).__name__ == "BooleanTrue":
            return self.doprint(value)
        return self.conditional(self.doprint(cond), self.doprint(value),
                                self._print_piecewise(args[2:]))

    def _print_add(self, e):
        terms = sorted(e.args, key=_is_negative)
        parts = [self.paren(terms[0], ADD)]
        for term in terms[1:]:
            if _is_negative(term):
                parts.append(f" - {self.paren(-term, MUL)}")
            else:
                parts.append(f" + {self.paren(term, ADD)}")
        return "".join(parts)

    def _print_mul(self, e):
        args = list(e.args)
        sign = ""
        if isinstance(args[0], se.Number):
            coeff = args.pop(0)
            if coeff.is_negative:
                sign, coeff = "-", -coeff
            if coeff != 1:
                args.insert(0, coeff)
        num, den = [], []
        for a in args:
            if isinstance(a, se.Pow) and isinstance(a.args[1], se.Number) and a.args[1].is_negative \
                    and not isinstance(a.args[0], Constant):
                den.append(se.Pow(a.args[0], -a.args[1]))
            else:
                num.append(a)
        text = "*".join(self.paren(a, MUL) for a in num) if num else self.real(1)
        if den:
            if len(den) == 1:
                text += "/" + self.paren(den[0], ATOM)
            else:
                text += "/(" + "*".join(self.paren(a, MUL) for a in den) + ")"
        return sign + text

    def _print_pow(self, e):
        base, exp = e.args
        if isinstance(base, Constant) and type(base).__name__ == "Exp1":
            return f"{self.functions['exp']}({self.doprint(exp)})", ATOM
        if isinstance(exp, se.Integer):
            k = int(exp)
            if k < 0:
                return f"{self.real(1)}/{self.paren(se.Pow(base, -exp), ATOM)}", MUL
            return self.integer_power(base, k)
        if exp == se.Rational(1, 2):
            return f"{self.functions['sqrt']}({self.doprint(base)})", ATOM
        if exp == se.Rational(-1, 2):
            return f"{self.real(1)}/{self.functions['sqrt']}({self.doprint(base)})", MUL
        return self.real_power(base, exp)


#: Relational node types and their operator (the same in C and Python).
RELATIONS = {"StrictLessThan": "<", "LessThan": "<=", "Equality": "==", "Unequality": "!="}


class CPrinter(ExpressionPrinter):
    """C99: libm functions, small integer powers as multiplications, doubles everywhere."""

    language = "C"
    nan = "NAN"
    logic = {"And": "&&", "Or": "||", "Not": "!", "BooleanTrue": "1", "BooleanFalse": "0"}

    def conditional(self, cond, yes, no):
        return f"({cond} ? {yes} : {no})"
    functions = {
        "sin": "sin", "cos": "cos", "tan": "tan", "asin": "asin", "acos": "acos", "atan": "atan",
        "atan2": "atan2", "sinh": "sinh", "cosh": "cosh", "tanh": "tanh", "asinh": "asinh",
        "acosh": "acosh", "atanh": "atanh", "exp": "exp", "log": "log", "sqrt": "sqrt",
        "Abs": "fabs", "sign": "lg_sign",
    }

    def integer_power(self, base, k):
        b = self.paren(base, ATOM)
        if k == 2:
            return (f"{b}*{b}", MUL) if isinstance(base, se.Symbol) else (f"lg_sq({b})", ATOM)
        if k == 3:
            return f"lg_cube({self.doprint(base)})", ATOM
        return f"pow({self.doprint(base)}, {k})", ATOM

    def real_power(self, base, exp):
        return f"pow({self.doprint(base)}, {self.doprint(exp)})", ATOM

    def statement(self, stmt):
        if isinstance(stmt, Comment):
            return "/* " + stmt.text.replace("*/", "* /") + " */"
        if isinstance(stmt, Zeros):
            return f"memset({stmt.array}, 0, {stmt.count} * sizeof(double));"
        if isinstance(stmt, Declare):
            return f"const double {stmt.name} = {self.doprint(stmt.expr)};"
        return f"{stmt.array}[{stmt.index}] = {self.doprint(stmt.expr)};"


class PythonPrinter(ExpressionPrinter):
    """Python: `math` functions bound as globals of the generated module, floats everywhere."""

    language = "Python"
    nan = "_nan"
    logic = {"And": "and", "Or": "or", "Not": "not ", "BooleanTrue": "True",
             "BooleanFalse": "False"}

    def conditional(self, cond, yes, no):
        return f"({yes} if {cond} else {no})"

    functions = {k: k for k in CPrinter.functions}
    functions.update({"Abs": "abs", "sign": "_sign"})

    def integer_power(self, base, k):
        return f"{self.paren(base, ATOM)}**{k}", ATOM

    def real_power(self, base, exp):
        return f"{self.paren(base, ATOM)}**{self.paren(exp, ATOM)}", ATOM

    def statement(self, stmt):
        if isinstance(stmt, Comment):
            return "# " + stmt.text.replace("\n", " ")
        if isinstance(stmt, Zeros):
            return f"# {stmt.array}: zeros but where set below"
        if isinstance(stmt, Declare):
            return f"{stmt.name} = {self.doprint(stmt.expr)}"
        return f"{stmt.array}[{stmt.index}] = {self.doprint(stmt.expr)}"


def print_statements(printer, statements, indent="    "):
    """The statements as source lines, one per statement, indented."""
    return "\n".join(indent + printer.statement(s) for s in statements)


def _symbol_names(stmt):
    return {str(s) for s in stmt.expr.free_symbols}


def in_lanes(statements, arrays, lanes):
    """`statements` for `lanes` directions at once: an access x[i] of one of `arrays` becomes
    x[lanes·i + b] (b the lane: see c_function's `lanes`)."""
    import re
    pattern = re.compile(rf"^({'|'.join(map(re.escape, arrays))})\[(\d+)\]$")

    def lane(symbol):
        match = pattern.match(symbol.name)
        return se.Symbol(f"{match[1]}[{lanes * int(match[2])} + b]") if match else symbol

    out = []
    for stmt in statements:
        expr = stmt.expr.xreplace({s: lane(s) for s in stmt.expr.free_symbols
                                   if isinstance(s, se.Symbol)})
        if isinstance(stmt, Store) and stmt.array in arrays:
            out.append(Store(stmt.array, f"{lanes * stmt.index} + b", expr))
        else:
            out.append(type(stmt)(*(expr if f == "expr" else getattr(stmt, f)
                                    for f in stmt.__dataclass_fields__)))
    return out


def c_function(name, params, args, statements, comment, max_statements=400, prologue="",
               tu_of_part=None, lanes=None, status=False):
    """C source of `static void name(params)` running `statements` (with `status`: `static int`,
    returning 0, or LG_NO_MEMORY when the workspace of its parts could not be allocated).

    A body longer than `max_statements` is split into parts `name_partK(params, w)` so the compiler
    never sees one huge function; a temporary used by a later part passes through the workspace w
    (with `status`, an LG_WORKSPACE of linalg.c.in: on the heap when long; else on the stack).
    `prologue` starts every function body (e.g. `(void)t;` for arguments a kernel may not use).
    With `tu_of_part` (part index -> translation unit number ≥ 1), each part is wrapped in
    `#if LG_IN_TU(k)` and the calling function in `#if LG_IN_TU(0)`, so that a build may compile
    the parts as separate translation units (see model.c.in); compiled as one file, nothing changes.
    With `lanes` (statements from `in_lanes`), every body runs in a loop over the lanes b, which
    the compiler vectorizes.
    """
    printer = CPrinter()
    head = f"/* {comment} */\nLG_FN static {'int' if status else 'void'} {name}({params})\n{{\n" \
        f"{prologue}"
    done = "\n    return 0;" if status else ""
    indent, open_loop, close_loop, slot_of = "    ", "", "", "{}".format
    if lanes:
        indent, open_loop, close_loop = "        ", f"    for (int b = 0; b < {lanes}; ++b) {{\n", \
            "\n    }"
        slot_of = f"{lanes} * {{}} + b".format
    if len(statements) <= max_statements:
        return head + open_loop + print_statements(printer, statements, indent) + close_loop \
            + done + "\n}\n"
    chunks = [statements[i:i + max_statements] for i in range(0, len(statements), max_statements)]
    defined = {s.name: k for k, chunk in enumerate(chunks) for s in chunk if isinstance(s, Declare)}
    imports = [sorted({v for s in chunk for v in _symbol_names(s)
                       if defined.get(v, k) < k}, key=lambda v: int(v[1:]))
               for k, chunk in enumerate(chunks)]
    slot = {v: i for i, v in enumerate(sorted({v for imp in imports for v in imp},
                                              key=lambda v: int(v[1:])))}
    linkage = "LG_PART_FN" if tu_of_part else "static"
    parts = []
    if tu_of_part:
        parts.append("".join(f"LG_FN LG_PART_FN void {name}_part{k}({params}, double *w);\n"
                             for k in range(len(chunks))))
    for k, chunk in enumerate(chunks):
        lines = [f"{indent}const double {v} = w[{slot_of(slot[v])}];" for v in imports[k]]
        lines.append(print_statements(printer, chunk, indent))
        lines += [f"{indent}w[{slot_of(slot[s.name])}] = {s.name};" for s in chunk
                  if isinstance(s, Declare) and s.name in slot]
        text = (f"LG_FN {linkage} void {name}_part{k}({params}, double *w)\n{{\n{prologue}"
                + "    (void)w;\n" + open_loop + "\n".join(lines) + close_loop + "\n}\n")
        if tu_of_part:
            text = f"#if LG_IN_TU({tu_of_part(k)})\n{text}#endif\n"
        parts.append(text)
    calls = "\n".join(f"    {name}_part{k}({args}, w);" for k in range(len(chunks)))
    size = max(len(slot), 1) * (lanes or 1)
    if status:
        main = (head + f"    LG_WORKSPACE(double, w, {size});\n    if (w == NULL)\n"
                "        return LG_NO_MEMORY;\n" + calls + "\n    LG_RELEASE(w);" + done + "\n}\n")
    else:
        main = head + f"    double w[{size}];\n" + calls + "\n}\n"
    if tu_of_part:
        main = f"#if LG_IN_TU(0)\n{main}#endif\n"
    return "\n".join(parts) + "\n" + main
