"""The pipeline of issue 9: the standalone C model, the function registry, the frozen description,
a light import, and arguments checked once at the boundary (names or Symbols, y0 dicts, NaN)."""
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model
from lagrgen.functions import DIRECTIONS_SIGNATURE, FUNCTIONS, MODEL_UNIT

from conftest import EXAMPLES, ROOT, example_model

DOUBLE = example_model("double_pendulum")


@pytest.fixture(scope="module")
def double(compile_once):
    return compile_once(DOUBLE)


@pytest.fixture(scope="module", params=["c", "python"])
def both(request, compile_once):
    if request.param == "c":
        return compile_once(DOUBLE)
    return lagrgen.build(DOUBLE, backend="python")


def run(cmd, **kwargs):
    return subprocess.run(cmd, capture_output=True, text=True, check=True, **kwargs)


# -- the standalone C model --------------------------------------------------------------------
def test_exported_c_needs_only_libm_and_runs_the_c_example(tmp_path):
    out = tmp_path / "c_model"
    run([sys.executable, "-m", "lagrgen", "export-c", str(EXAMPLES / "double_pendulum.py"),
         "--out", str(out)])
    assert sorted(p.name for p in out.iterdir()) == ["double_pendulum_model.c",
                                                      "double_pendulum_model.h"]
    source = (out / "double_pendulum_model.c").read_text()
    header = (out / "double_pendulum_model.h").read_text()
    includes = [line for line in (source + header).splitlines() if line.startswith("#include")]
    assert includes == ["#include <math.h>", "#include <stdlib.h>", "#include <string.h>",
                        '#include "double_pendulum_model.h"']
    assert "Python.h" not in source and "define LG_FN" in header
    exe = tmp_path / "rk4"
    run(["cc", "-O2", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-I", str(out),
         str(EXAMPLES / "c" / "rk4_double_pendulum.c"), str(out / "double_pendulum_model.c"),
         "-lm", "-o", str(exe)])
    final = np.array(run([str(exe), "2", "4000", "0.5", "-0.2", "0.3"]).stdout.split(), float)
    mod = lagrgen.build(DOUBLE, out_dir=tmp_path / "gen")
    sol = lagrgen.simulate(mod, (0.0, 2.0), [0.5, -0.2, 0.0, 0.0], method="DOP853", rtol=1e-12,
                           atol=1e-12, inputs={"F": 0.3})
    assert_allclose(final, sol.y[:, -1], rtol=1e-8, atol=1e-9)


def test_a_build_writes_the_standalone_model_beside_the_module(double, tmp_path):
    mod = lagrgen.build(DOUBLE, out_dir=tmp_path)
    header = (tmp_path / "double_pendulum_model.h").read_text()
    for f in FUNCTIONS:
        signature = (DIRECTIONS_SIGNATURE if f.call == "directions" else
                     "double t, const double *y, const double *p, const double *u, double *out")
        prototype = f"int double_pendulum_{f.name}({signature});"
        assert (prototype in header) == (f.unit == MODEL_UNIT), f.name   # the others: export_c
    assert mod.content_hash in header


# -- one registry --------------------------------------------------------------------------------
def test_every_registered_function_exists_on_both_backends_with_its_shapes(both):
    dims = both.dimensions
    n = both.n_coordinates
    q, qd, y = np.full(n, 0.3), np.full(n, -0.2), np.full(2 * n, 0.1)
    for f in FUNCTIONS:
        fn = getattr(both, f.name)
        if f.call == "link":               # a model without links (tests/test_links.py)
            with pytest.raises(lagrgen.UnknownNameError, match="has no links"):
                fn("base", q)
            continue
        a = np.full(n + both.n_constraints, 0.7)
        args = {"state": (0.0, y), "q": (q, 0.0), "q_qd": (q, qd, 0.0),
                "directions": (0.0, y, np.ones((3, 2 * n))), "implicit": (q, qd, a, 0.0),
                "weighted": (q, qd, a, np.full(n + both.n_constraints, -0.4), 0.0)}[f.call]
        out = fn(*args)
        outs = out if isinstance(out, tuple) else (out,)
        assert [o.shape for o in outs] == f.shapes({**dims, "k": 3}), f.name
        assert all(o.dtype == np.float64 for o in outs)


def test_backends_agree_on_every_registered_function(compile_once):
    c, py = compile_once(DOUBLE), lagrgen.build(DOUBLE, backend="python")
    rng = np.random.default_rng(3)
    for _ in range(5):
        y = rng.uniform(-1, 1, 4)
        p = np.array(c.defaults) * rng.uniform(0.5, 1.5, 5)
        u = rng.uniform(-1, 1, 1)
        for f in FUNCTIONS:
            if f.call == "link":           # the double pendulum has no links
                continue
            args = {"state": (0.4, y), "q": (y[:2], 0.4), "q_qd": (y[:2], y[2:], 0.4),
                    "directions": (0.4, y, rng.uniform(-1, 1, (2, 4)),
                                   rng.uniform(-1, 1, (2, 5))),
                    "implicit": (y[:2], y[2:], y[::-1][:2], 0.4),
                    "weighted": (y[:2], y[2:], y[::-1][:2], y[1:3], 0.4)}[f.call]
            a, b = getattr(c, f.name)(*args, p, u), getattr(py, f.name)(*args, p, u)
            for x, z in zip(a if isinstance(a, tuple) else (a,), b if isinstance(b, tuple) else (b,)):
                assert_allclose(x, z, rtol=1e-12, atol=1e-12)


# -- a frozen description --------------------------------------------------------------------
def test_the_description_is_frozen_and_changes_are_never_served_stale(tmp_path):
    model = Model("frozen_osc")
    x, = model.coordinates("x")
    m, = model.parameters(m=1.0)
    model.particle(m, sp.Matrix([x]))
    model.potential_energy(2 * x ** 2)
    for name in ("potential_terms", "particles", "kinetic_terms", "virtual_work"):
        assert not hasattr(model, name)
    with pytest.raises(AttributeError):
        model.name = "other"
    first = lagrgen.build(model, out_dir=tmp_path)
    assert first.rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-4.0)
    model.potential_energy(50 * x ** 2)
    second = lagrgen.build(model, out_dir=tmp_path)
    assert not second.build_info["cache_hit"]
    assert second.rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-104.0)
    assert second.content_hash != first.content_hash


def test_the_cache_key_covers_the_generator(monkeypatch, tmp_path):
    import importlib
    build = importlib.import_module("lagrgen.build")
    cache = importlib.import_module("lagrgen.cache")
    model = Model("keyed")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    first = lagrgen.build(model, out_dir=tmp_path)
    info = build.model_info(model.spec(), model.equations())
    cache.description_digest.cache_clear()
    monkeypatch.setattr(cache, "generator_digest", lambda: "a changed generator")
    assert build.model_info(model.spec(), model.equations()).content_hash != info.content_hash
    assert first.content_hash == info.content_hash


# -- a light import ------------------------------------------------------------------------------
def test_importing_a_compiled_model_imports_neither_sympy_nor_scipy(double):
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import double_pendulum as m; "
            "print(m.rhs(0.0, [0.5, 0, 0, 0])[2]); "
            "print(sorted(k for k in ('sympy', 'scipy', 'symengine', 'matplotlib') "
            "if k in sys.modules))")
    out_dir = _out_dir_of(double)
    lines = run([sys.executable, "-c", code, str(out_dir)]).stdout.splitlines()
    assert float(lines[0]) == pytest.approx(double.rhs(0.0, [0.5, 0, 0, 0])[2])
    assert lines[1] == "[]"


def test_load_imports_neither_sympy_nor_scipy(double):
    """`lagrgen.load` checks the name without SymPy and imports the module without SciPy."""
    code = ("import sys, lagrgen; m = lagrgen.load('double_pendulum', out_dir=sys.argv[1]); "
            "print(m.rhs(0.0, [0.5, 0, 0, 0])[2]); "
            "print(sorted(k for k in ('sympy', 'scipy', 'symengine', 'matplotlib') "
            "if k in sys.modules))")
    lines = run([sys.executable, "-c", code, str(_out_dir_of(double))]).stdout.splitlines()
    assert float(lines[0]) == pytest.approx(double.rhs(0.0, [0.5, 0, 0, 0])[2])
    assert lines[1] == "[]"
    code = ("import sys, lagrgen\ntry:\n    lagrgen.load('numpy', out_dir=sys.argv[1])\n"
            "except lagrgen.ModelError as exc:\n    print('refused', 'sympy' in sys.modules)")
    assert run([sys.executable, "-c", code, str(_out_dir_of(double))]).stdout.split() == \
        ["refused", "False"]


def test_a_built_model_has_exactly_the_names_its_protocol_lists(both):
    """Every public name of a built model is in its backend's Protocol and the other way round, and
    the Protocol lists one callable per registered model function."""
    from lagrgen.runtime.protocol import BuiltModel, CompiledBuiltModel, PythonBuiltModel

    def names(protocol):
        found = set()
        for cls in protocol.__mro__:
            if cls.__module__ == "lagrgen.runtime.protocol":
                found |= set(getattr(cls, "__annotations__", {}))
                found |= {k for k, v in vars(cls).items() if callable(v) and not k.startswith("_")}
        return found

    assert {f.name for f in FUNCTIONS} <= names(BuiltModel)
    protocol = CompiledBuiltModel if both.backend == "c" else PythonBuiltModel
    public = {k for k in dir(both) if not k.startswith("_")}
    assert public == names(protocol)
    for name in names(protocol):
        getattr(both, name)
    assert both.dimensions == both.info.dimensions
    assert both.n_coordinates == len(both.coordinates) == both.dimensions["n"]


def _out_dir_of(mod):
    """The out_dir a compiled model was published into (its cache entry's grandparent)."""
    from pathlib import Path
    return Path(mod.__file__).resolve().parent.parent.parent


def test_import_lagrgen_is_light():
    code = ("import sys, lagrgen; print(sorted(k for k in ('sympy', 'scipy', 'symengine', "
            "'matplotlib') if k in sys.modules)); lagrgen.Model; print('sympy' in sys.modules)")
    lines = run([sys.executable, "-c", code]).stdout.splitlines()
    assert lines == ["[]", "True"]


def test_the_modules_of_the_package_are_reachable_from_its_face():
    """`lagrgen.tree.RECURSIVE_FROM`, as the manual writes it, right after `import lagrgen` (the
    lazy face raised AttributeError until something imported lagrgen.tree); other names still
    raise AttributeError."""
    code = ("import sys, lagrgen; print('lagrgen.tree' in sys.modules, "
            "lagrgen.tree.RECURSIVE_FROM, lagrgen.options.__name__)\n"
            "for name in ('no_such_module', '_private'):\n"
            "    try:\n        getattr(lagrgen, name)\n"
            "    except AttributeError as exc:\n        print(exc)")
    lines = run([sys.executable, "-c", code]).stdout.splitlines()
    from lagrgen.tree import RECURSIVE_FROM
    assert lines == [f"False {RECURSIVE_FROM} lagrgen.options",
                     "module 'lagrgen' has no attribute 'no_such_module'",
                     "module 'lagrgen' has no attribute '_private'"]


# -- arguments checked once at the boundary -----------------------------------------------------
def test_params_and_inputs_may_be_keyed_by_symbols(both):
    m1 = next(s for s in DOUBLE.parameter_symbols if s.name == "m1")
    F = DOUBLE.input_functions[0]
    y = [0.4, -0.1, 0.2, 0.0]
    by_name = both.rhs(0.0, y, {"m1": 2.0}, {"F": 0.5})
    assert_allclose(both.rhs(0.0, y, {m1: 2.0}, {F: 0.5}), by_name, rtol=0, atol=0)
    sol_names = lagrgen.simulate(both, (0, 0.5), y, params={"m1": 2.0}, inputs={"F": 0.5})
    sol_symbols = lagrgen.simulate(both, (0, 0.5), y, params={m1: 2.0}, inputs={F: 0.5})
    assert_allclose(sol_names.y, sol_symbols.y, rtol=0, atol=0)
    with pytest.raises(lagrgen.UnknownNameError, match="unknown parameter name 'mass'"):
        both.rhs(0.0, y, {sp.Symbol("mass"): 1.0})


def test_y0_as_a_dict_and_the_result_carries_coordinates(both):
    sol = lagrgen.simulate(both, (0, 0.5), {"theta1": 0.5, "theta2_dot": 1.0}, method="DOP853")
    ref = lagrgen.simulate(both, (0, 0.5), [0.5, 0.0, 0.0, 1.0], method="DOP853")
    assert_allclose(sol.y, ref.y, rtol=0, atol=0)
    assert sol.coordinates == ("theta1", "theta2")
    assert sol.q.shape == sol.qd.shape == (2, len(sol.t))
    assert_allclose(sol.q, sol.y[:2]) and np.shares_memory(sol.q, sol.y)
    assert_allclose(sol.qd, sol.y[2:])
    with pytest.raises(lagrgen.UnknownNameError, match="theta3"):
        lagrgen.simulate(both, (0, 0.5), {"theta3": 0.5})


def test_simulate_with_args_says_to_use_params(both):
    with pytest.raises(TypeError, match="params"):
        lagrgen.simulate(both, (0, 1), [0.5, 0, 0, 0], args=(np.array(both.defaults),))


@pytest.mark.parametrize("where", ["p", "u"])
def test_nan_in_parameters_or_inputs_is_a_value_error_on_both_backends(both, where):
    y = [0.4, -0.1, 0.2, 0.0]
    p, u = np.array(both.defaults), np.zeros(1)
    (p if where == "p" else u)[0] = np.nan
    for fn in (lambda: both.rhs(0.0, y, p, u), lambda: both.jacobian(0.0, y, p, u),
               lambda: both.mass_matrix(y[:2], 0.0, p, u),
               lambda: both.rhs(0.0, y, list(p), list(u))):
        with pytest.raises(ValueError, match="finite"):
            fn()
    with pytest.raises(ValueError, match="finite"):
        lagrgen.simulate(both, (0, 1), y, params=p if where == "p" else None,
                         inputs={"F": np.nan} if where == "u" else None)
