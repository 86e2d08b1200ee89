"""The structured derivation (masses collected per kinematic product, parameter sums factored,
sin² + cos² folded) against a plain expanded Lagrange derivation in SymPy, on random multi-body
models at random states; and the build that compiles long kernels as several translation units."""
import subprocess

import numpy as np
import pytest
import symengine as se
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen.build import model_info
from lagrgen.toolchain import compiler_command
from lagrgen.codegen.c_model import standalone_files, translation_units
from conftest import ROOT, load_example

t = sp.Symbol("t")


def random_model(seed):
    """A random planar model (tree of point masses on pin and slider joints, shared masses, a rigid
    body, a moving support, springs, gravity, an input force) and its plain SymPy T, V and Q."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 6))
    model = lagrgen.Model(f"random{seed}")
    q = model.coordinates([f"q{i}" for i in range(n)])
    masses = model.parameters(**{f"m{i}": float(rng.uniform(0.5, 2)) for i in range(3)})
    lengths = model.parameters(**{f"l{i}": float(rng.uniform(0.5, 2)) for i in range(n)})
    g, k, w = model.parameters(g=9.81, k=float(rng.uniform(1, 5)), w=1.3)
    force, = model.inputs(["f"])
    support = sp.Matrix([sp.sin(w * t) / 4, 0])
    points = [support]
    T, V = sp.Integer(0), sp.Integer(0)
    for b in range(int(rng.integers(n + 1, n + 4))):
        parent = points[int(rng.integers(0, len(points)))]
        a, c = (int(i) for i in rng.integers(0, n, 2))
        kind = int(rng.integers(0, 3))
        if kind == 0:
            angle = q[a]
        elif kind == 1:
            angle = q[a] + q[c] if a != c else 2 * q[a]
        else:
            angle = q[a] - q[c] / 2
        if kind == 2 and b % 2:
            r = parent + sp.Matrix([q[a], sp.Rational(1, 2) * q[c]])
        else:
            r = parent + lengths[a] * sp.Matrix([sp.sin(angle), -sp.cos(angle)])
        m = masses[int(rng.integers(0, 3))] * (1 if b % 3 else sp.Rational(3, 2))
        model.particle(m, r)
        v = r.diff(t)
        T += m * (v.T * v)[0] / 2
        V += m * g * r[1]
        points.append(r)
    for i in range(n):  # every coordinate gets inertia of its own (the tree may miss one)
        model.particle(masses[0] / 4, sp.Matrix([lengths[i] * sp.cos(q[i]), q[i] / 3]))
        r = sp.Matrix([lengths[i] * sp.cos(q[i]), q[i] / 3])
        v = r.diff(t)
        T += masses[0] / 4 * (v.T * v)[0] / 2
    model.rigid_body(masses[1], masses[2] * lengths[0] ** 2, points[-1], q[0] + q[n - 1])
    vb = points[-1].diff(t)
    T += masses[1] * (vb.T * vb)[0] / 2 + masses[2] * lengths[0] ** 2 * (q[0] + q[n - 1]).diff(t) ** 2 / 2
    model.potential_energy(V)
    model.potential_energy(k * (q[0] - q[1]) ** 2 / 2)
    V += k * (q[0] - q[1]) ** 2 / 2
    model.generalized_force(q[n - 1], force * sp.cos(q[0]))
    Q = [sp.Integer(0)] * n
    Q[n - 1] = force * sp.cos(q[0])
    return model, q, T, V, Q


def plain_lagrange(q, T, V, Q):
    """M = ∂²T/∂q̇∂q̇ᵀ and F = ∂L/∂q − (∂²L/∂q̇∂qᵀ)·q̇ − ∂²L/∂q̇∂t + Q, expanded, in SymPy."""
    qd = [c.diff(t) for c in q]
    L = sp.expand(T - V)
    dL_dqd = [L.diff(s) for s in qd]
    M = sp.Matrix([[d.diff(s) for s in qd] for d in dL_dqd])
    # d/dt ∂L/∂q̇ = M q̈ + (the rest): take the total derivative and drop the q̈ terms
    F = []
    for i, c in enumerate(q):
        total = dL_dqd[i].diff(t)
        rest = total.subs({s.diff(t): 0 for s in qd})
        F.append(L.diff(c) - rest + Q[i])
    return M, sp.Matrix(F)


@pytest.mark.parametrize("seed", range(6))
def test_structured_derivation_matches_plain_lagrange(seed):
    model, q, T, V, Q = random_model(seed)
    M_ref, F_ref = plain_lagrange(q, T, V, Q)
    mod = lagrgen.build(model, backend="python")
    params = [sp.Symbol(name) for name in mod.parameters]
    qs, qds = sp.symbols(f"x0:{len(q)}"), sp.symbols(f"v0:{len(q)}")
    fsym = sp.Symbol("fin")
    to_plain = {**{c.diff(t): s for c, s in zip(q, qds)}, **{c: s for c, s in zip(q, qs)}}
    spec = model.spec()
    to_plain.update({user: sym for user, sym in zip(spec.parameters, params)})
    to_plain.update({spec.inputs[0]: fsym})
    args = (t, qs, qds, params, fsym)
    M = sp.lambdify(args, M_ref.xreplace(to_plain), "numpy")
    F = sp.lambdify(args, F_ref.xreplace(to_plain), "numpy")
    rng = np.random.default_rng(100 + seed)
    for _ in range(4):
        tv = float(rng.uniform(0, 3))
        qv, qdv = rng.uniform(-2, 2, len(q)), rng.uniform(-2, 2, len(q))
        p = np.asarray(mod.defaults, dtype=float) * rng.uniform(0.7, 1.3, len(mod.defaults))
        u = rng.uniform(-1, 1, 1)
        assert_allclose(mod.mass_matrix(qv, tv, p, u), np.asarray(M(tv, qv, qdv, p, u[0]), float),
                        rtol=1e-11, atol=1e-11)
        assert_allclose(mod.forcing(qv, qdv, tv, p, u), np.asarray(F(tv, qv, qdv, p, u[0]),
                        float).ravel(), rtol=1e-10, atol=1e-10)


def test_chain_mass_sums_are_collected():
    """The n-link pendulum's M_ij is one product with one mass sum: L_i L_j cos(θ_i − θ_j)·Σ m_k
    (as sin·sin + cos·cos), and M_ii = L_i²·Σ m_k with sin² + cos² folded."""
    eq = load_example("nlink_pendulum").make(5).equations()
    p = eq.p
    assert eq.M[4][4] - p[9] ** 2 * p[4] == 0
    assert sp.expand(sp.sympify(eq.M[0][0]) - sp.sympify(p[5] ** 2 * sum(p[:5]))) == 0
    assert se.count_ops(eq.M[0][0]) <= 6
    m13 = sp.sympify(eq.M[1][3])
    q = sp.sympify(eq.q)
    expected = sp.sympify(p[6] * p[8] * (p[3] + p[4])) * (sp.sin(q[1]) * sp.sin(q[3])
                                                          + sp.cos(q[1]) * sp.cos(q[3]))
    assert sp.expand(m13 - expected) == 0
    assert se.count_ops(eq.M[1][3]) <= 11  # 4 trig calls, 6 products, 1 sum (+1 in Σm)


@pytest.fixture(scope="module")
def split_model(tmp_path_factory):
    """The 9-link pendulum, whose kernels are long enough to be compiled as several units."""
    model = load_example("nlink_pendulum").make(9, name="split9")
    return model, lagrgen.build(model, out_dir=tmp_path_factory.mktemp("split"), quiet=True)


def test_split_build_matches_python_backend(split_model):
    model, mod = split_model
    source = standalone_files(model_info(model.spec(), model.equations()),
                              model.equations())["split9_model.c"]
    assert translation_units(source) >= 1
    py = lagrgen.build(model, backend="python")
    rng = np.random.default_rng(5)
    p = np.asarray(mod.defaults, dtype=float)
    for _ in range(3):
        y = rng.uniform(-1, 1, 18)
        assert_allclose(mod.rhs(0.0, y, p), py.rhs(0.0, y, p), rtol=1e-11, atol=1e-11)
        assert_allclose(mod.jacobian(0.0, y, p), py.jacobian(0.0, y, p), rtol=1e-10, atol=1e-10)


def test_split_standalone_file_is_one_plain_c_unit(split_model, tmp_path):
    """The standalone model.c of a split model still compiles alone as strict C99, no warnings."""
    model, _ = split_model
    for name, text in standalone_files(model_info(model.spec(), model.equations()),
                                       model.equations()).items():
        (tmp_path / name).write_text(text)
    result = subprocess.run([*compiler_command(), "-std=c99", "-pedantic", "-Wall", "-Werror",
                             "-O0", "-c", str(tmp_path / "split9_model.c"), "-o",
                             str(tmp_path / "m.o")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    symbols = subprocess.run(["nm", str(tmp_path / "m.o")], capture_output=True, text=True).stdout
    assert " T split9_rhs" in symbols and "part0" in symbols
    assert " T lg_" not in symbols  # the parts stay internal (static) in the one-file build


# -- the import graph: one way, no cycles -----------------------------------------------------------
#: The package's modules by stage, in data-flow order (ARCHITECTURE.md): a module may import one of
#: its own stage or an earlier one, never a later one. An entry names a module or a whole package.
STAGES = [
    ("base", ["_version", "errors", "numbers", "names", "caching", "functions", "methods",
              "options", "signals", "toolchain"]),
    ("description", ["rotation", "bodies3d", "records", "links", "checks", "description"]),
    ("derivation", ["calculus", "terms", "frames", "contributions", "lagrange", "nonsmooth", "tree", "tree3d",
                    "free_base", "dimensions"]),
    ("kernels", ["tangents", "hessians", "kernels", "trace", "lean3d"]),
    ("code", ["codegen"]),
    ("runtime", ["runtime"]),
    ("build", ["cache", "build", "units"]),
    ("display", ["outputs"]),
    ("running", ["progress", "results", "solvers", "scipy_engine", "native", "sensitivity",
                 "simulate", "constraints", "ensemble", "ensemble_store",
                 "hybrid"]),
    ("analysis", ["linearization", "vibration", "stability", "sweep", "bench", "identifiability",
                  "fit", "inertial", "collocation"]),
    ("face", ["model", "sympy_interop", "urdf", "base_state", "expressions", "cli", "__main__", ""]),
]
#: The package's sources in this checkout (the installed package has no .pyx files).
PACKAGE = ROOT / "src" / "lagrgen"


def package_modules():
    """{module name relative to lagrgen ('' for the package): its file} for .py and .pyx files."""
    from pathlib import Path
    root = Path(PACKAGE)
    out = {}
    for path in sorted(root.rglob("*.py")) + sorted(root.rglob("*.pyx")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imported_modules(name, path, modules):
    """The package modules `name` imports anywhere in its file (top level or inside functions)."""
    import ast
    import re
    text = path.read_text()
    if path.suffix == ".pyx":
        found = set(re.findall(r"^\s*from lagrgen\.([\w.]+) c?import", text, re.M))
        return {m for m in found if m in modules}
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    package = [p for p in package if p]
    found = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1]
            elif node.module == "lagrgen" or (node.module or "").startswith("lagrgen."):
                base = []
                node_module = node.module[len("lagrgen"):].lstrip(".")
                target = node_module
                found |= {c for c in [target] + [f"{target}.{a.name}".strip(".") for a in node.names]
                          if c in modules}
                continue
            else:
                continue
            target = ".".join(base + ([node.module] if node.module else []))
            found |= {c for c in [target] + [f"{target}.{a.name}".strip(".") for a in node.names]
                      if c in modules}
        elif isinstance(node, ast.Import):
            found |= {a.name[len("lagrgen."):] for a in node.names
                      if a.name.startswith("lagrgen.") and a.name[len("lagrgen."):] in modules}
    return found - {name, ""} if name else found - {""}


def import_graph():
    modules = package_modules()
    return {name: imported_modules(name, path, modules) for name, path in modules.items()}


def stage_of(name):
    """The index in STAGES of the module `name` (the longest entry naming it or its package)."""
    best = None
    for index, (_, entries) in enumerate(STAGES):
        for entry in entries:
            if name == entry or (entry and name.startswith(entry + ".")):
                if best is None or len(entry) > best[1]:
                    best = (index, len(entry))
    assert best is not None, f"module lagrgen.{name} has no stage: add it to STAGES (and ARCHITECTURE.md)"
    return best[0]


def test_every_module_has_a_stage_and_imports_none_of_a_later_one():
    graph = import_graph()
    assert {"model", "lagrange", "kernels", "codegen.c_model", "runtime.pymodel", "build",
            "simulate", "outputs.plotting", "runtime._compiled"} <= set(graph)
    late = [f"lagrgen.{a or '__init__'} ({STAGES[stage_of(a)][0]}) imports lagrgen.{b} "
            f"({STAGES[stage_of(b)][0]})"
            for a, targets in graph.items() for b in targets if stage_of(b) > stage_of(a)]
    assert late == []


def test_the_runtime_imports_only_the_base_and_itself():
    graph = import_graph()
    allowed = {i for i, (stage, _) in enumerate(STAGES) if stage in ("base", "runtime")}
    for name, targets in graph.items():
        if name.startswith("runtime."):
            assert {b for b in targets if stage_of(b) not in allowed} == set(), name


def import_cycles(graph):
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index, low, on_stack, stack, cycles = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(component)

    for v in graph:
        if v not in index:
            visit(v)
    return cycles


def test_the_package_has_no_import_cycle():
    assert import_cycles(import_graph()) == []
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]


def test_the_benchmark_modules_have_no_import_cycle():
    """benchmarks/ imports its sibling modules one way (_peers and _pinocchio share _built)."""
    import ast
    folder = ROOT / "benchmarks"
    names = {path.stem for path in folder.glob("*.py")}
    graph = {}
    for path in folder.glob("*.py"):
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found |= {a.name for a in node.names if a.name in names}
            elif isinstance(node, ast.ImportFrom) and node.module in names:
                found.add(node.module)
        graph[path.stem] = found - {path.stem}
    assert {"_peers", "_pinocchio", "_built"} <= set(graph)
    assert import_cycles(graph) == []


def test_the_import_graph_sees_an_import_inside_a_function(tmp_path):
    """The checker itself: a lazy import is an import (a later module reached from a function)."""
    modules = {"model": None, "outputs.display": None, "outputs": None}
    path = tmp_path / "model.py"
    path.write_text("def f():\n    from .outputs.display import latex_block\n")
    assert imported_modules("model", path, modules) == {"outputs.display"}
    path.write_text("from lagrgen.outputs import display\n")
    assert imported_modules("model", path, modules) == {"outputs", "outputs.display"}


#: The stages of inertial identification (ARCHITECTURE.md), each importing only those before it.
INERTIAL_STAGES = ["regressor", "limits", "base", "records", "consistency", "estimation",
                   "trajectories"]


def test_the_inertial_package_imports_its_stages_one_way():
    """lagrgen.inertial is its stages, each importing only earlier ones, and its face keeps
    every public name of the module it was (from lagrgen.inertial import ... as before)."""
    import lagrgen.inertial as inertial
    graph = import_graph()
    inside = sorted(name for name in graph if name.startswith("inertial."))
    assert inside == sorted(f"inertial.{stage}" for stage in INERTIAL_STAGES)
    for i, stage in enumerate(INERTIAL_STAGES):
        within = {b.partition(".")[2] for b in graph[f"inertial.{stage}"]
                  if b.startswith("inertial.")}
        assert within <= set(INERTIAL_STAGES[:i]), stage
    for name in ("identify_inertial", "base_parameters", "exciting_trajectory",
                 "InertialEstimate", "BaseParameters", "ExcitingTrajectory", "filtered_records",
                 "motion_bandwidth", "pseudo_inertia", "regressor_of", "stacked_regressor",
                 "links_of", "inertial_parameters_of", "FIELDS"):
        assert name in inertial.__all__ and getattr(inertial, name) is not None


def test_user_facing_text_cites_no_section_of_the_contract():
    """Messages, docstrings and examples never cite "API §..." (a document users do not have)."""
    roots = [PACKAGE, ROOT / "examples", ROOT / "docs" / "guide"]
    cited = [str(path.relative_to(ROOT)) for root in roots for path in sorted(root.rglob("*"))
             if path.suffix in (".py", ".pyx", ".in", ".md", ".h") and path.is_file()
             and any(mark in path.read_text() for mark in ("API §", "API.md §"))]
    assert cited == []


def test_architecture_md_lists_the_stages_of_the_import_check():
    """ARCHITECTURE.md's table of rooms names the same stages, in order, with the same modules."""
    from pathlib import Path
    text = (Path(__file__).resolve().parent.parent / "ARCHITECTURE.md").read_text()
    rows = [line for line in text.splitlines() if line.startswith("| ") and "`" in line]
    assert [row.split("|")[1].strip() for row in rows] == [stage for stage, _ in STAGES]
    for row, (stage, entries) in zip(rows, STAGES):
        named = row.split("|")[2]
        assert all(f"`{entry or '__init__'}" in named for entry in entries), stage


def test_every_physics_record_has_one_contribution_function():
    """A physics kind is a record of lagrgen.records with its contribution in CONTRIBUTIONS."""
    import dataclasses
    from lagrgen import contributions, records
    kinds = {cls for cls in vars(records).values()
             if isinstance(cls, type) and dataclasses.is_dataclass(cls)}
    not_physics = {records.ModelSpec, records.Constraint, records.VelocityConstraint,
                   records.ExternalEquations, records.Impact, records.Friction,
                   records.Segment, records.LinkFrame}
    assert kinds - not_physics == set(contributions.CONTRIBUTIONS)
    assert len(set(contributions.CONTRIBUTIONS.values())) == len(contributions.CONTRIBUTIONS)


def test_the_method_names_are_listed_only_in_the_method_table():
    """No module but `methods.py` spells a collection of two or more method names: they are read
    from `methods.TABLE` (with what FMUs say of each and the benchmarks' choice)."""
    import ast
    from lagrgen.methods import BENCH_METHODS, METHODS, TABLE
    names = set(METHODS)
    listing = []
    for name, path in package_modules().items():
        if path.suffix != ".py" or name == "methods":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Dict) and all(isinstance(v, ast.Name) for v in node.values):
                continue        # a method's implementation by its name (lagrgen.solvers.SOLVERS)
            items = node.keys if isinstance(node, ast.Dict) else \
                getattr(node, "elts", []) if isinstance(node, (ast.Tuple, ast.List, ast.Set)) else []
            spelled = [i.value for i in items if isinstance(i, ast.Constant) and i.value in names]
            if len(spelled) >= 2:
                listing.append(f"lagrgen.{name}, line {node.lineno}: {spelled}")
    assert listing == []
    assert all(m.description for m in TABLE) and set(BENCH_METHODS) <= names
