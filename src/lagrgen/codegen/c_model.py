"""The C files of a model: the standalone model (`<name>_model.h`, `<name>_model.c`: plain C, no
Python) and the thin Python module glue (`<name>_module.c`) that includes it."""
import re
from pathlib import Path
from string import Template

from ..functions import DIRECTIONS_SIGNATURE, EXPORTED
from ..kernels import KERNELS, kernel_names, link_chains, model_kernels
from .printer import c_function, in_lanes, kernel_statements
from .tree_code import APART, link_layout, template_name, tree_c

TEMPLATES = Path(__file__).resolve().parent / "templates"
SIGNATURE = "double t, const double *y, const double *p, const double *u, double *out"


def read_template(name):
    return (TEMPLATES / name).read_text()


#: The longest string literal every ISO C99 compiler must accept (5.2.4.1; -pedantic warns).
MAX_C_STRING = 4095
#: Bytes that stand for themselves in a C string: printable ASCII but the quote, the backslash
#: and the question mark (the first character of a trigraph such as ??/, a backslash in ISO C).
SAFE_C_BYTES = frozenset(b for b in range(0x20, 0x7F) if chr(b) not in '"\\?')
C_ESCAPES = {ord('"'): '\\"', ord("\\"): "\\\\"}


def c_string(text):
    """`text` (UTF-8) as an ISO C string literal: `"` and `\\` escaped, every other byte that is
    not printable ASCII, and `?`, as a three-digit octal escape, so that no user text can end
    the literal (trigraphs included) or reach the compiler as code."""
    return '"' + "".join(chr(b) if b in SAFE_C_BYTES else C_ESCAPES.get(b, f"\\{b:03o}")
                         for b in text.encode("utf-8")) + '"'


def c_char_array(text):
    """The initializer of a NUL-terminated `const char x[]` holding `text` (UTF-8): a string
    literal (`c_string`) up to MAX_C_STRING bytes, else the bytes as numbers (beyond ASCII as
    octal character constants), 20 a line."""
    data = text.encode("utf-8")
    if len(data) <= MAX_C_STRING:
        return c_string(text)
    codes = [str(b) if b < 0x80 else f"'\\{b:03o}'" for b in data] + ["0"]
    lines = [", ".join(codes[i:i + 20]) for i in range(0, len(codes), 20)]
    return "{\n    " + ",\n    ".join(lines) + "\n}"


def legend(info):
    """Comment lines saying which array slot holds which of the user's names."""
    n = len(info.coordinates)
    lines = [f" *   y[{i}] = q[{i}] = {c}, y[{n + i}] = qd[{i}] = its rate"
             for i, c in enumerate(info.coordinates)]
    lines += [f" *   p[{i}] = {name}" for i, name in enumerate(info.parameters)]
    lines += [f" *   u[{i}] = {name}" for i, name in enumerate(info.inputs)]
    return "\n".join(lines)


#: Statements per translation unit when a model's kernel parts are compiled separately.
STATEMENTS_PER_TU = 1200

TU_SETUP = """
/* The kernels' part functions may be compiled as separate translation units (lagrgen's own build
 * does, to use every core): define LG_TU to k to compile only unit k (0: everything else). Compiled
 * as it is, this file is one plain translation unit. */
#ifndef LG_TU
#  define LG_IN_TU(k) 1
#  define LG_PART_FN static
#else
#  define LG_IN_TU(k) ((k) == LG_TU)
#  define LG_PART_FN __attribute__((visibility("hidden")))
#endif
"""


#: A kernel with lanes is split into parts of at most this fraction of `max_statements`: each of
#: its statements holds LANES values, and the compiler's register allocation grows faster than
#: linearly with the values live in one function (measured at n = 20: half-size parts compile
#: the directions unit in 10 % less time; quarter-size ones no faster).
LANE_PART_FRACTION = 0.5


def part_limit(kernel, max_statements):
    """Statements per part of `kernel` (see c_function)."""
    return max(1, int(max_statements * LANE_PART_FRACTION)) if kernel.spec.lanes \
        else max_statements


def kernels_of(functions):
    """The names of the kernels the C bodies of `functions` call, in the order of KERNELS (with
    `constraints`, which the constraint solver of every unit calls)."""
    wanted = {"constraints"} | {k for f in functions for k in f.kernels}
    return [k.name for k in KERNELS if k.name in wanted]


def kernel_functions(equations, max_statements=400, units=None, names=None,
                     formulation="dense"):
    """The C functions lg_<kernel> of the `formulation`'s kernels that the model has (only those
    computing the dense kernels `names` when given, see `kernels.model_kernels`), split into parts
    when long.

    When the kernels have more than one part, the parts are assigned to translation units 1, 2, ...
    of about STATEMENTS_PER_TU statements each (see TU_SETUP); `units`, a list, receives the number
    of those units (0 when nothing was split)."""
    chunks = []
    kernels = [(k, kernel_statements(k)) for k in model_kernels(equations, formulation, names)]
    split = any(len(stmts) > part_limit(k, max_statements) for k, stmts in kernels)
    per_tu = max(1, STATEMENTS_PER_TU // max_statements)
    counter = [0]

    def tu_of_part(_k):
        counter[0] += 1
        return 1 + (counter[0] - 1) // per_tu

    for kernel, stmts in kernels:
        outputs = [o.name for o in kernel.spec.outputs]
        inputs = kernel.spec.arguments
        lanes = LANES if kernel.spec.lanes else None
        pointer = "*LG_RESTRICT " if lanes else "*"
        params = ", ".join("double t" if a == "t" else f"const double {pointer}{a}"
                           for a in inputs)
        params += "".join(f", double {pointer}{o}" for o in outputs)
        args = ", ".join(inputs) + "".join(f", {o}" for o in outputs)
        prologue = "    " + " ".join(f"(void){a};" for a in (*inputs, *outputs)) + "\n"
        if lanes:
            stmts = in_lanes(stmts, kernel.spec.lanes, lanes)
        limit = part_limit(kernel, max_statements)
        text = c_function(f"lg_{kernel.name}", params, args, stmts, kernel.spec.formula + ".",
                          limit, prologue, tu_of_part if split else None, lanes, status=True)
        if split and len(stmts) <= limit:
            text = f"#if LG_IN_TU(0)\n{text}#endif\n"
        chunks.append(tape_sizes(kernel) + text)
    if units is not None:
        units.append(1 + (counter[0] - 1) // per_tu if counter[0] else 0)
    return "\n".join(chunks)


#: Directions a kernel with lanes (kernels.KernelSpec.lanes) evaluates at once (LG_LANES in C).
LANES = 4

#: A function keeps its work arrays on its stack up to this many doubles (32 KiB), on the heap
#: above (LG_STACK_DOUBLES in model.c.in, LG_WORKSPACE in linalg.c.in): a model whose arrays fit
#: allocates nothing, and nested calls stay well within a thread's stack of 256 KiB. Measured on
#: a dense chain of 65 and of 100 masses (M on the heap), rhs and jacobian take the same time
#: with every workspace on the stack (-DLG_STACK_DOUBLES=1000000), within the timing noise.
STACK_DOUBLES = 4096


def tape_sizes(kernel):
    """`#define LG_<KERNEL>_<OUTPUT> <length>` for each tape output of `kernel`."""
    return "".join(f"#define LG_{kernel.name.upper()}_{o.name.upper()} "
                   f"{max(len(kernel.outputs[o.name]), 1)}\n"
                   for o in kernel.spec.outputs if o.shape == ("n_tape",))


#: The guard of a unit holding a function traced for the robot (`traced_units`).
TRACED_GUARD = "#if LG_IN_TU({}) /* traced */"


def traced_apart(functions):
    """The functions traced for a robot (`lagrgen.lean3d`) that a module with the registered
    `functions` compiles as units of their own: the node records, and q̈ where the module has
    the rhs (a unit that does not call it keeps it static in unit 0, where the compiler drops
    it)."""
    return {"lg_tree_nodes"} | ({"lg_lean_qdd"} if any(f.name == "rhs" for f in functions)
                                else set())


def traced_units(functions, after):
    """The C of the traced `functions` (`lagrgen.lean3d.Traced`), each guarded as a unit of its
    own numbered from after + 1 (after the kernels' parts): long straight-line functions whose
    compiler time is most of a robot's build, compiled side by side."""
    return "".join(f"\n{TRACED_GUARD.format(after + k)}\n{f.definition(APART)}#endif\n"
                   for k, f in enumerate(functions, 1))


#: A unit's guard in `<name>_model.c`: its number, and whether it holds a traced function.
UNIT_GUARD = re.compile(r"^#if LG_IN_TU\((\d+)\)( /\* traced \*/)?$", re.M)


def translation_units(model_c):
    """The number of separately compilable units in a `<name>_model.c` text besides unit 0 (the
    kernels' parts and the traced functions; 0: none)."""
    return max((int(k) for k, _ in UNIT_GUARD.findall(model_c)), default=0)


def traced_unit_numbers(model_c):
    """The units of a `<name>_model.c` text that hold a traced function (`traced_units`)."""
    return {int(k) for k, traced in UNIT_GUARD.findall(model_c) if traced}


def signature(function):
    """The C parameter list of a registered function."""
    return DIRECTIONS_SIGNATURE if function.call == "directions" else SIGNATURE


def model_functions(name, functions=EXPORTED):
    """The C definitions of the registered `functions`, `<name>_<function>`.

    A body that works in arrays defines `LG_<FUNCTION>_WORK`, their length in doubles, and uses
    the workspace `work`; it becomes `lg_<function>_body(..., work)`, which may return from
    anywhere, called by the function with its workspace (LG_RETURN_WITH_WORKSPACE: on the stack
    when short, else on the heap, released on every return)."""
    chunks = []
    for f in functions:
        outputs = ", ".join(o.name for o in f.outputs)
        body = read_template(f"functions/{f.name}.c").rstrip()
        head = f"/* {f.formula}; out = [{outputs}]. */\nLG_FN int {name}_{f.name}({signature(f)})"
        work = f"LG_{f.name.upper()}_WORK"
        if f"#define {work}" not in body:
            chunks.append(f"{head}\n{{\n{body}\n}}\n")
            continue
        inner = f"lg_{f.name}_body"
        chunks.append(f"LG_FN static int {inner}({signature(f)}, double *work)\n{{\n"
                      f"    (void)work;\n{body}\n}}\n\n{head}\n{{\n"
                      f"    LG_RETURN_WITH_WORKSPACE(double, work, {work},\n"
                      f"                             {inner}({argument_names(f)}, work));\n}}\n")
    return "\n".join(chunks)


def argument_names(function):
    """The names of the C parameters of a registered function, as a call's arguments."""
    return ", ".join(part.replace("*", " ").split()[-1] for part in signature(function).split(","))


def prototypes(name, functions=EXPORTED):
    return "\n".join(f"/* {f.formula} */\nLG_FN int {name}_{f.name}({signature(f)});"
                     for f in functions)


def _names(names):
    return ", ".join(c_string(s) for s in names) if names else "0"


def _double(value):
    return "NAN" if value is None else repr(float(value))


def substitutions(info):
    """Template values shared by the header, the model, the glue and the FMU: the name, version,
    hash, slot legend, and every size of `info.dimensions` (`2n` as n_states), each also as
    `<size>_or_1` (C arrays are never empty)."""
    sizes = {("n_states" if key == "2n" else key): value for key, value in info.dimensions.items()}
    return dict(name=info.name, version=info.lagrgen_version, content_hash=info.content_hash,
                legend=legend(info), **sizes,
                **{f"{key}_or_1": max(value, 1) for key, value in sizes.items()})


def model_header(info, functions=EXPORTED):
    """`<name>_model.h`: the standalone model's interface (its `functions`)."""
    return Template(read_template("model.h.in")).substitute(
        substitutions(info), guard=f"LAGRGEN_{info.name.upper()}_MODEL_H",
        prototypes=prototypes(info.name, functions))


def model_source(info, equations, max_statements=400, functions=EXPORTED):
    """`<name>_model.c`: the kernels the registered `functions` call, linear algebra, the
    functions and metadata in plain C."""
    defaults = info.defaults or [0.0]
    units = []
    formulation, names = info.formulation, kernels_of(functions)
    if "link_frames" in names and link_chains(equations):
        names.remove("link_frames")     # the links have functions of their own (link_functions)
    kernels = kernel_functions(equations, max_statements, units, names, formulation)
    recursive = formulation == "recursive"
    tree_kernels = kernel_names(names, formulation)
    traced, apart = [], traced_apart(functions)
    tree = tree_c(equations, read_template(template_name(equations)), tree_kernels, traced,
                  apart) if recursive and "tree_nodes" in tree_kernels else ""
    split = units[0] > 0 or bool(traced)
    return Template(read_template("model.c.in")).substitute(
        substitutions(info), linalg=read_template("linalg.c.in"), recursive=int(recursive),
        tree=tree, traced=traced_units([f for f in traced if f.name in apart], units[0]),
        kernels=kernels, tu_setup=TU_SETUP if split else "",
        tu0_begin="#if LG_IN_TU(0)\n" if split else "", tu0_end="\n#endif" if split else "",
        constraint_solver=read_template("constraints.c.in"), lanes=LANES,
        stack_doubles=STACK_DOUBLES,
        functions=model_functions(info.name, functions),
        inertial_index=", ".join(str(info.parameters.index(name))
                                 for name in info.inertial_parameters) or "0",
        link_tables=link_tables(equations) if info.link_names else "",
        coordinate_names=_names(info.coordinates),
        parameter_names=_names(info.parameters), input_names=_names(info.inputs),
        defaults=", ".join(_double(d) for d in defaults),
        metadata=c_char_array(info.to_json()))


def link_tables(equations):
    """The C tables of a tree's links (`tree_code.link_layout`): each link's node, each node's
    parent and coordinate."""
    layout = link_layout(equations)
    rows = ", ".join
    return (f"/* Link k is carried by node lg_link_node[k] (−1: fixed); node i's parent (−1: a root)"
            f" and coordinate. */\n#define N_LINK_NODES {len(layout['parent'])}\n"
            f"LG_MAYBE_UNUSED static const int lg_link_node[N_LINKS] = "
            f"{{{rows(map(str, layout['node']))}}};\n"
            f"LG_MAYBE_UNUSED static const int lg_link_parent[N_LINK_NODES] = "
            f"{{{rows(map(str, layout['parent']))}}};\n"
            f"LG_MAYBE_UNUSED static const int lg_link_coordinate[N_LINK_NODES] = "
            f"{{{rows(map(str, layout['coordinate']))}}};\n" + LINK_ARGUMENTS
            + link_functions(equations))


#: How link_pose and link_jacobian read their arguments y = [q, point (3), the link's index].
LINK_ARGUMENTS = """\
/* The link's index in y = [q, point (3), k]; -1 when it is out of range. */
LG_MAYBE_UNUSED static int lg_link_argument(const double *y)
{
    const double k = y[N + 3];
    return k >= 0.0 && k < N_LINKS ? (int)k : -1;
}

/* x = o + R·point, R row-major 3×3. */
LG_MAYBE_UNUSED static void lg_link_point(const double *R, const double *o, const double *point,
                                          double *x)
{
    for (int r = 0; r < 3; ++r)
        x[r] = o[r] + R[3 * r] * point[0] + R[3 * r + 1] * point[1] + R[3 * r + 2] * point[2];
}
"""


#: The arguments of a link's own functions (`link_functions`).
LINK_PARAMETERS = "const double *q, const double *p, const double *point, double *out"


def link_functions(equations):
    """Each link's own pose and Jacobian (`kernels.link_chains`: only the frames and twists of
    its chain), lg_link_pose_<k> and lg_link_jacobian_<k>, and their tables lg_link_poses and
    lg_link_jacobians, indexed by link (LG_LINK_CHAINS 1); LG_LINK_CHAINS 0 for a tree whose
    links walk the twists of all its nodes (lg_link_frames)."""
    chains = link_chains(equations)
    if not chains:
        return "#define LG_LINK_CHAINS 0\n"
    prologue = "    (void)q; (void)p; (void)point;\n"
    text = ["/* Each link's own pose and frame Jacobian, computing only the frames and twists of "
            "the nodes at and above it. */\n#define LG_LINK_CHAINS 1\n"
            f"typedef int (*lg_link_fn)({LINK_PARAMETERS});\n"]
    for k, pair in enumerate(chains):
        text += [c_function(f"lg_{kernel.name}_{k}", LINK_PARAMETERS, "q, p, point, out",
                            kernel_statements(kernel), f"{kernel.spec.formula}: link {k}",
                            prologue=prologue, status=True) for kernel in pair]
    for kernel in chains[0]:
        text.append(f"static const lg_link_fn lg_{kernel.name}s[N_LINKS] = {{"
                    + ", ".join(f"lg_{kernel.name}_{k}" for k in range(len(chains))) + "};\n")
    return "\n".join(text)


def module_source(info, units=0, functions=EXPORTED, template="module.c.in"):
    """`<name>_module.c`: the Python extension glue that includes `<name>_model.c` (as unit 0 of
    a model whose kernel parts are compiled as `units` separate units, see `unit_sources`) and
    lists its `functions`. The glue of a unit compiled on first use is `unit_module.c.in`: its
    table for the runtime to add to the model's, no model of its own."""
    table = ",\n".join(f'    {{"{f.name}", (lg_function){info.name}_{f.name}}}'
                       for f in functions)
    text = Template(read_template(template)).substitute(substitutions(info), table=table)
    if units:
        include = f'#include "{info.name}_model.c"'
        text = text.replace(include, "#define LG_TU 0\n" + include, 1)
    return text


def unit_file(name, k):
    """The file name of unit k of `<name>_model.c` (`unit_sources`)."""
    return f"{name}_unit{k}.c"


def unit_sources(name, units):
    """{file name: text} of the units 1 … `units` of `<name>_model.c` (internal to the build of
    the Python module: each compiles one group of kernel parts, or one traced function)."""
    return {unit_file(name, k): f'/* Unit {k} of {name}_model.c (lagrgen build file). */\n'
            f'#define LG_TU {k}\n#include "{name}_model.c"\n' for k in range(1, units + 1)}


def standalone_files(info, equations, functions=EXPORTED):
    """{file name: text} of the standalone C model with the registered `functions` (all of
    them: `export_c`; the model unit's: what `build` compiles and publishes)."""
    name = info.name
    return {f"{name}_model.h": model_header(info, functions),
            f"{name}_model.c": model_source(info, equations, functions=functions)}


