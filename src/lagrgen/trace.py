"""Straight-line programs traced from numeric algorithms: a value type whose arithmetic records
itself, with constants folded, products with 0 and ±1 and sums with 0 removed, signs carried on
the references (x − y and y − x are one node) and every operation hash-consed (a common
subexpression is one node however often it is formed); printed as C, one `const double`
temporary per node that an output needs, with its flop count.

A value is a Python float (a constant) or an int reference 2·i + s to node i, negated when s = 1.
`Tape.leaf(text)` is an input (a C expression such as `q[3]`); the arithmetic is `add`, `sub`,
`mul`, `neg`, `inv`, `sin`, `cos`. `lagrgen.lean3d` runs the recursions of a robot on it.
"""
import math

#: Operations that cost one flop each (the others: leaves, sin and cos).
FLOPS = frozenset(("+", "-", "+c", "*", "*c", "1/"))


class Tape:
    """The nodes of one straight-line program, in the order they were formed (operands first)."""

    def __init__(self):
        self.nodes = []           # (op, a, b): a, b node indices or numbers
        self._index = {}

    def _node(self, key, sign=0):
        i = self._index.get(key)
        if i is None:
            i = self._index[key] = len(self.nodes)
            self.nodes.append(key)
        return 2 * i + sign

    def leaf(self, text):
        """The input `text` (a C expression, read where it is used)."""
        return self._node(("in", text, None))

    def add(self, x, y):
        """x + y."""
        fx, fy = isinstance(x, float), isinstance(y, float)
        if fx and fy:
            return x + y
        if fx or fy:
            c, r = (x, y) if fx else (y, x)
            if c == 0.0:
                return r
            i, s = r >> 1, r & 1          # ±v + c = ±(v ± c)
            return self._node(("+c", i, -c if s else c), s)
        i, si, j, sj = x >> 1, x & 1, y >> 1, y & 1
        if si == sj:
            if i == j:
                return self._node(("*c", i, 2.0), si)
            return self._node(("+", min(i, j), max(i, j)), si)
        if i == j:
            return 0.0
        if si:                           # −v_i + v_j = v_j − v_i
            i, j = j, i
        return self._node(("-", i, j)) if i < j else self._node(("-", j, i), 1)

    def neg(self, x):
        """−x."""
        return -x if isinstance(x, float) else x ^ 1

    def sub(self, x, y):
        """x − y."""
        return self.add(x, self.neg(y))

    def mul(self, x, y):
        """x·y."""
        fx, fy = isinstance(x, float), isinstance(y, float)
        if fx and fy:
            return x * y
        if fx or fy:
            c, r = (x, y) if fx else (y, x)
            if c == 0.0:
                return 0.0
            if c == 1.0:
                return r
            if c == -1.0:
                return r ^ 1
            s = (r & 1) ^ (c < 0.0)
            return self._node(("*c", r >> 1, abs(c)), s)
        i, j = x >> 1, y >> 1
        return self._node(("*", min(i, j), max(i, j)), (x & 1) ^ (y & 1))

    def inv(self, x):
        """1/x."""
        if isinstance(x, float):
            return 1.0 / x
        return self._node(("1/", x >> 1, None), x & 1)

    def sin(self, x):
        if isinstance(x, float):
            return math.sin(x)
        return self._node(("sin", x >> 1, None), x & 1)

    def cos(self, x):
        if isinstance(x, float):
            return math.cos(x)
        return self._node(("cos", x >> 1, None))

    def dot(self, xs, ys):
        """Σ x_i·y_i."""
        total = 0.0
        for x, y in zip(xs, ys):
            total = self.add(total, self.mul(x, y))
        return total

    # -- printing ---------------------------------------------------------------------------------
    def needed(self, values):
        """The indices of the nodes the `values` depend on, ascending."""
        seen, stack = set(), [v >> 1 for v in values if not isinstance(v, float)]
        while stack:
            i = stack.pop()
            if i in seen:
                continue
            seen.add(i)
            op, a, b = self.nodes[i]
            if op != "in":
                stack.append(a)
                if op in ("+", "-", "*"):
                    stack.append(b)
        return sorted(seen)

    def flops(self, nodes):
        """The flops of the nodes `nodes` (indices)."""
        return sum(1 for i in nodes if self.nodes[i][0] in FLOPS)


def number(c):
    """A C double literal of c (exact: repr)."""
    text = repr(float(c))
    return text if ("." in text or "e" in text or "n" in text) else text + ".0"


class Printer:
    """C statements of a tape's nodes: `const double <prefix>K = ...;` per needed node, leaves
    inline; `ref(v)` is the C expression of a value."""

    def __init__(self, tape, prefix="x"):
        self.tape, self.prefix = tape, prefix

    def name(self, i):
        op, a, _ = self.tape.nodes[i]
        return a if op == "in" else f"{self.prefix}{i}"

    def ref(self, v):
        if isinstance(v, float):
            return number(v) if v >= 0.0 else f"-{number(-v)}"
        text = self.name(v >> 1)
        return f"-{text}" if v & 1 else text

    def expression(self, i):
        op, a, b = self.tape.nodes[i]
        x = self.name(a) if op != "in" else a
        if op == "+":
            return f"{x} + {self.name(b)}"
        if op == "-":
            return f"{x} - {self.name(b)}"
        if op == "+c":
            return f"{x} + {number(b)}" if b >= 0.0 else f"{x} - {number(-b)}"
        if op == "*":
            return f"{x} * {self.name(b)}"
        if op == "*c":
            return f"{number(b)} * {x}"
        if op == "1/":
            return f"1.0 / {x}"
        return f"{op}({x})"

    def statements(self, nodes, indent="    "):
        """The declarations of `nodes` (indices, in order; leaves skipped)."""
        return [f"{indent}const double {self.prefix}{i} = {self.expression(i)};"
                for i in nodes if self.tape.nodes[i][0] != "in"]


class NotTraceable(Exception):
    """An expression with an operation the tape does not have (`from_symengine`)."""


def from_symengine(tape, expr, memo=None):
    """The tape's value of the SymEngine expression `expr` (internal symbols become leaves: their
    names are C array accesses); NotTraceable for a function other than sin and cos, or a power
    other than an integer one."""
    import symengine as se
    memo = {} if memo is None else memo
    stack = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if node in memo:
            continue
        if isinstance(node, se.Number):
            if not node.is_real:
                raise NotTraceable(str(node))
            memo[node] = float(node)
            continue
        if isinstance(node, se.Symbol):
            memo[node] = tape.leaf(node.name)
            continue
        if not ready:
            stack.append((node, True))
            stack.extend((a, False) for a in node.args)
            continue
        args = [memo[a] for a in node.args]
        if isinstance(node, se.Add):
            value = 0.0
            for a in args:
                value = tape.add(value, a)
        elif isinstance(node, se.Mul):
            value = 1.0
            for a in args:
                value = tape.mul(value, a)
        elif isinstance(node, se.Pow) and isinstance(node.args[1], se.Integer) \
                and 0 < abs(int(node.args[1])) <= 4:
            k, value = int(node.args[1]), 1.0
            for _ in range(abs(k)):
                value = tape.mul(value, args[0])
            if k < 0:
                value = tape.inv(value)
        elif isinstance(node, se.sin):
            value = tape.sin(args[0])
        elif isinstance(node, se.cos):
            value = tape.cos(args[0])
        else:
            raise NotTraceable(type(node).__name__)
        memo[node] = value
    return memo[expr]
