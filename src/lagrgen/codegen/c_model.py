"""The C files of a model: the standalone model (`<name>_model.h`, `<name>_model.c`: plain C, no
Python) and the thin Python module glue (`<name>_module.c`) that includes it."""
import json
from pathlib import Path
from string import Template

from .._version import __version__
from ..functions import FUNCTIONS
from ..kernels import KERNEL_ARGUMENTS, all_kernels
from .printer import c_function, kernel_statements

TEMPLATES = Path(__file__).resolve().parent / "templates"
SIGNATURE = "double t, const double *y, const double *p, const double *u, double *out"


def read_template(name):
    return (TEMPLATES / name).read_text()


def c_string(text):
    """`text` as a C string literal (ASCII only: everything else as \\u escapes of JSON)."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def legend(info):
    """Comment lines saying which array slot holds which of the user's names."""
    n = len(info["coordinates"])
    lines = [f" *   y[{i}] = q[{i}] = {c}, y[{n + i}] = qd[{i}] = its rate"
             for i, c in enumerate(info["coordinates"])]
    lines += [f" *   p[{i}] = {name}" for i, name in enumerate(info["parameters"])]
    lines += [f" *   u[{i}] = {name}" for i, name in enumerate(info["inputs"])]
    return "\n".join(lines)


def kernel_functions(equations, max_statements=400):
    """The C functions lg_<kernel> of every registered kernel (split into parts when long)."""
    chunks = []
    arguments = ", ".join(KERNEL_ARGUMENTS)
    prologue = "    " + " ".join(f"(void){a};" for a in KERNEL_ARGUMENTS) + "\n"
    for kernel in all_kernels(equations):
        outputs = [o.name for o in kernel.spec.outputs]
        params = ("double t, " + ", ".join(f"const double *{a}" for a in KERNEL_ARGUMENTS[1:])
                  + "".join(f", double *{o}" for o in outputs))
        args = arguments + "".join(f", {o}" for o in outputs)
        chunks.append(c_function(f"lg_{kernel.name}", params, args, kernel_statements(kernel),
                                 kernel.spec.formula + ".", max_statements, prologue))
    return "\n".join(chunks)


def model_functions(name):
    """The C definitions of every function of the registry, `<name>_<function>`."""
    chunks = []
    for f in FUNCTIONS:
        outputs = ", ".join(o.name for o in f.outputs)
        body = read_template(f"functions/{f.name}.c").rstrip()
        chunks.append(f"/* {f.formula}; out = [{outputs}]. */\n"
                      f"LG_FN int {name}_{f.name}({SIGNATURE})\n{{\n{body}\n}}\n")
    return "\n".join(chunks)


def prototypes(name):
    return "\n".join(f"/* {f.formula} */\nLG_FN int {name}_{f.name}({SIGNATURE});"
                     for f in FUNCTIONS)


def _names(names):
    return ", ".join(c_string(s) for s in names) if names else "0"


def _double(value):
    return "NAN" if value is None else repr(float(value))


def substitutions(info, n):
    """Template values shared by the header, the model and the glue."""
    return dict(
        name=info["name"], version=__version__, content_hash=info["content_hash"],
        legend=legend(info), n=n, n_states=2 * n, n_params=len(info["parameters"]),
        n_inputs=len(info["inputs"]), n_or_1=max(n, 1),
        n_constraints=info["dimensions"]["n_constraints"],
        n_events=info["dimensions"]["n_events"],
        n_residuals=info["dimensions"]["n_residuals"],
        n_params_or_1=max(len(info["parameters"]), 1),
        n_inputs_or_1=max(len(info["inputs"]), 1))


def model_header(info, n):
    """`<name>_model.h`: the standalone model's interface."""
    return Template(read_template("model.h.in")).substitute(
        substitutions(info, n), guard=f"LAGRGEN_{info['name'].upper()}_MODEL_H",
        prototypes=prototypes(info["name"]))


def model_source(info, equations, max_statements=400):
    """`<name>_model.c`: kernels, linear algebra, model functions and metadata in plain C."""
    defaults = info["defaults"] or [0.0]
    return Template(read_template("model.c.in")).substitute(
        substitutions(info, equations.n), linalg=read_template("linalg.c.in"),
        kernels=kernel_functions(equations, max_statements),
        constraint_solver=read_template("constraints.c.in"),
        functions=model_functions(info["name"]),
        coordinate_names=_names(info["coordinates"]),
        parameter_names=_names(info["parameters"]), input_names=_names(info["inputs"]),
        defaults=", ".join(_double(d) for d in defaults),
        metadata=c_string(json.dumps(info, sort_keys=True)))


def module_source(info, n):
    """`<name>_module.c`: the Python extension glue that includes `<name>_model.c`."""
    table = ",\n".join(f'    {{"{f.name}", {info["name"]}_{f.name}}}' for f in FUNCTIONS)
    return Template(read_template("module.c.in")).substitute(substitutions(info, n), table=table)


def standalone_files(info, equations):
    """{file name: text} of the standalone C model."""
    name = info["name"]
    return {f"{name}_model.h": model_header(info, equations.n),
            f"{name}_model.c": model_source(info, equations)}


