"""Python source of a model's kernels: one function per registered kernel, run by the Python
backend (`lagrgen.runtime.pymodel`); for the recursive formulation also the tree's tables
(`TREE`, read by `lagrgen.runtime.tree`)."""
from ..kernels import model_kernels
from .printer import PythonPrinter, kernel_statements, print_statements


def python_source(equations, formulation="dense"):
    """Python source of `name(t, q, qd, a, p, u)` -> its outputs (lists), for every kernel of the
    `formulation`."""
    printer = PythonPrinter()
    chunks = []
    for kernel in model_kernels(equations, formulation, python=True):
        lines = [f"def {kernel.name}({', '.join(kernel.spec.arguments)}):"]
        lines += [f"    {name} = [0.0] * {len(exprs)}" for name, exprs in kernel.outputs.items()]
        body = print_statements(printer, kernel_statements(kernel))
        if body:
            lines.append(body)
        lines.append(f"    return {', '.join(kernel.outputs)},")
        chunks.append("\n".join(lines))
    if formulation == "recursive":
        from .tree_code import layout
        chunks.append(f"TREE = {layout(equations)!r}")
    from ..kernels import has_links
    if has_links(equations):
        from .tree_code import link_layout
        chunks.append(f"LINKS = {link_layout(equations)!r}")
    return "\n\n\n".join(chunks) + "\n"
