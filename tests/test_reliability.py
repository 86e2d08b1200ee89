"""Issue 8: never a wrong number, never a stuck cache. One test (or more) per defect found."""
import subprocess
import sys
import textwrap
import threading
import types

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import MassMatrixError, Model, ModelError
from lagrgen.cache import CACHE_DIR, EXT_SUFFIX

from conftest import example_model

DOUBLE = example_model("double_pendulum")
Y = np.array([0.4, -0.3, 0.2, 0.5])


@pytest.fixture(scope="module", params=["c", "python"])
def both(request, compile_once):
    return compile_once(DOUBLE) if request.param == "c" else lagrgen.build(DOUBLE, backend="python")


# -- 1. per-call argument buffers -----------------------------------------------------------
def test_a_reentrant_call_while_arguments_are_converted_gives_the_right_numbers(compile_once):
    mod = compile_once(DOUBLE)
    expected = mod.rhs(0.0, Y, [1.0, 1.0, 1.0, 1.0, 9.81], [0.7])

    class Sneaky:
        """A number whose conversion calls the same model with other arguments."""

        def __float__(self):
            mod.rhs(0.0, Y, {"m1": 7.0, "g": 1.0}, {"F": -3.0})
            mod.jacobian(0.0, Y, [2.0] * 5, [5.0])
            return 1.0

    for _ in range(50):
        assert_allclose(mod.rhs(0.0, Y, [Sneaky(), 1.0, 1.0, 1.0, 9.81], [0.7]), expected,
                        rtol=0, atol=0)
        assert_allclose(mod.rhs(0.0, Y, {"m1": 1.0}, {"F": Sneaky() and 0.7}), expected,
                        rtol=0, atol=0)
        assert_allclose(mod.rhs(0.0, Y, [1.0, 1.0, 1.0, 1.0, 9.81], [Sneaky()]),
                        mod.rhs(0.0, Y, None, [1.0]), rtol=0, atol=0)


def test_threads_with_dict_arguments_never_see_each_others_values(compile_once):
    mod = compile_once(DOUBLE)
    wrong = []

    def work(k):
        p, u = {"m1": 1.0 + k, "g": 9.0 + k}, {"F": 0.1 * k}
        expected = mod.rhs(0.0, Y, p, u)
        expected_j = mod.jacobian(0.0, Y, p, u)
        for _ in range(3000):
            if not (np.array_equal(mod.rhs(0.0, Y, p, u), expected)
                    and np.array_equal(mod.jacobian(0.0, Y, p, u), expected_j)):
                wrong.append(k)
        mod.time_in_c("rhs", 0.0, Y, p, u, repeat=2000)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(6)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert wrong == []


# -- 2. rates from internal symbols; float64 everywhere -------------------------------------
def test_a_damper_on_an_absolute_value_keeps_its_damping(compile_once):
    model = Model("abs_damper")
    x1, x2 = model.coordinates("x1 x2")
    m, c = model.parameters(m=1.0, c=0.7)
    model.particle(m, sp.Matrix([x1]))
    model.particle(m, sp.Matrix([x2]))
    model.damper(c, sp.Abs(x2 - x1))
    v1, v2 = x1.diff(model.t), x2.diff(model.t)
    F = model.forcing().replace(sp.sign, lambda arg: -1)   # away from x1 = x2
    assert sp.expand(F[0] - c * (v2 - v1)) == 0 and sp.expand(F[1] + c * (v2 - v1)) == 0
    for mod in (compile_once(model), lagrgen.build(model, backend="python")):
        assert_allclose(mod.forcing([0.0, 1.0], [0.5, -1.5]), [0.7 * -2.0, 0.7 * 2.0], rtol=1e-15)


def test_the_python_backend_returns_float64_for_integer_entries():
    model = Model("unit_masses")
    x, y = model.coordinates("x y")
    model.particle(1, sp.Matrix([x]))
    model.particle(2, sp.Matrix([y]))
    py = lagrgen.build(model, backend="python")
    F = py.forcing([0.0, 0.0], [0.0, 0.0])
    assert F.dtype == np.float64
    F += 0.5
    for name in ("mass_matrix", "rhs", "jacobian"):
        args = ([0, 0], 0.0) if name == "mass_matrix" else (0.0, [0, 0, 0, 0])
        assert getattr(py, name)(*args).dtype == np.float64
    lin = lagrgen.linearize(py, [0.0, 0.0])
    assert lin.M.dtype == lin.K.dtype == lin.C.dtype == np.float64


# -- 3. numbers printed exactly -------------------------------------------------------------
def test_integers_beyond_64_bits_and_huge_rationals_are_exact_doubles(compile_once):
    model = Model("stiff_numbers")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    model.potential_energy(10 ** 20 * x ** 2 / 2 + sp.Rational(10 ** 400 + 1, 10 ** 399) * x ** 2 / 2)
    for mod in (compile_once(model), lagrgen.build(model, backend="python")):
        assert mod.rhs(0.0, [1e-3, 0.0])[1] == pytest.approx(-(1e20 + 10.0) * 1e-3, rel=1e-15)
        assert mod.jacobian(0.0, [1e-3, 0.0])[1, 0] == pytest.approx(-(1e20 + 10.0), rel=1e-15)


@pytest.mark.parametrize("number", [sp.Float("1e400"), sp.Integer(10) ** 400,
                                    sp.Rational(1, 10 ** 400)])
def test_a_number_that_does_not_fit_a_double_is_a_model_error(number):
    model = Model("too_big")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    with pytest.raises(ModelError, match="potential energy: the number .* does not fit a double"):
        model.potential_energy(number * x ** 2)


# -- 4. byte order and alignment ------------------------------------------------------------
def test_byte_swapped_and_unaligned_arrays_are_converted(both):
    swapped = Y.astype(">f8")
    raw = np.zeros(Y.size * 8 + 1, dtype=np.uint8)
    unaligned = np.frombuffer(raw.data, dtype=np.float64, count=Y.size, offset=1)
    unaligned.flags.writeable or None
    np.copyto(np.ndarray(Y.size, np.float64, raw.data, 1), Y)
    p = np.asarray(both.defaults, dtype=">f8")
    for y in (swapped, unaligned):
        assert_allclose(both.rhs(0.0, y, p, np.array([0.3], ">f8")), both.rhs(0.0, Y, None, [0.3]),
                        rtol=0, atol=0)
        assert_allclose(both.jacobian(0.0, y), both.jacobian(0.0, Y), rtol=0, atol=0)
        assert_allclose(both.mass_matrix(y[:2]), both.mass_matrix(Y[:2]), rtol=0, atol=0)
        assert_allclose(both.forcing(y[:2], y[2:]), both.forcing(Y[:2], Y[2:]), rtol=0, atol=0)


# -- 5. module names ----------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["json", "os", "random", "numpy", "signal", "lagrgen", "x" * 101])
def test_names_of_needed_modules_and_overlong_names_are_refused(name):
    with pytest.raises(ModelError):
        Model(name)


def test_loading_a_model_leaves_sys_modules_alone(tmp_path):
    probe = types.ModuleType("lg_probe_module")
    sys.modules["lg_probe_module"] = probe
    try:
        model = Model("lg_probe_module")
        x, = model.coordinates("x")
        model.particle(1, sp.Matrix([x]))
        mod = lagrgen.build(model, out_dir=tmp_path)
        assert mod.rhs(0.0, [0.0, 0.0]).shape == (2,)
        assert sys.modules["lg_probe_module"] is probe
        assert lagrgen.load("lg_probe_module", out_dir=tmp_path).n_coordinates == 1
        assert sys.modules["lg_probe_module"] is probe
    finally:
        del sys.modules["lg_probe_module"]


# -- 6. a self-checking cache (each damage done between two fresh processes) ------------------
MODEL_FILE = """
import sympy as sp
from lagrgen import Model
model = Model("healing")
x, = model.coordinates("x")
k, = model.parameters(k=9.0)
model.particle(1, sp.Matrix([x]))
model.spring(k, x)
"""

BUILD_AND_RUN = textwrap.dedent("""
    import sys, runpy, lagrgen
    model = runpy.run_path(sys.argv[1])["model"]
    mod = lagrgen.build(model, out_dir=sys.argv[2], force=len(sys.argv) > 3)
    print(mod.build_info["cache_hit"], mod.rhs(0.0, [1.0, 0.0])[1])
""")


def build_in_fresh_process(tmp_path, force=False):
    cmd = [sys.executable, "-c", BUILD_AND_RUN, str(tmp_path / "healing.py"), str(tmp_path / "out")]
    out = subprocess.run(cmd + (["force"] if force else []), capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    hit, value = out.stdout.split()
    return hit == "True", float(value)


def cached_module(tmp_path):
    (entry,) = (tmp_path / "out" / CACHE_DIR).glob("healing-*/")
    return entry / f"healing{EXT_SUFFIX}"


@pytest.mark.parametrize("damage", ["truncate", "empty", "other_model"])
def test_a_damaged_cache_entry_is_compiled_again(tmp_path, damage):
    (tmp_path / "healing.py").write_text(MODEL_FILE)
    assert build_in_fresh_process(tmp_path) == (False, -9.0)
    assert build_in_fresh_process(tmp_path) == (True, -9.0)
    module = cached_module(tmp_path)
    data = module.read_bytes()
    if damage == "truncate":
        module.write_bytes(data[:len(data) // 2])
    elif damage == "empty":
        module.write_bytes(b"")
    else:
        other = Model("healing")
        x, = other.coordinates("x")
        other.particle(1, sp.Matrix([x]))
        other.spring(100.0, x)
        built = lagrgen.build(other, out_dir=tmp_path / "other")
        module.write_bytes((tmp_path / "other" / f"healing{EXT_SUFFIX}").read_bytes())
        assert built.rhs(0.0, [1.0, 0.0])[1] == -100.0
    assert build_in_fresh_process(tmp_path) == (False, -9.0)
    assert build_in_fresh_process(tmp_path) == (True, -9.0)


def test_force_republishes_a_damaged_published_module(tmp_path):
    (tmp_path / "healing.py").write_text(MODEL_FILE)
    build_in_fresh_process(tmp_path)
    published = tmp_path / "out" / f"healing{EXT_SUFFIX}"
    published.write_bytes(b"garbage")
    assert build_in_fresh_process(tmp_path, force=True) == (False, -9.0)
    code = f"import sys; sys.path.insert(0, {str(tmp_path / 'out')!r}); import healing; " \
           "print(healing.rhs(0.0, [1.0, 0.0])[1])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert float(out.stdout) == -9.0


def test_a_cached_model_in_a_read_only_directory_loads(tmp_path, monkeypatch):
    import importlib
    cache = importlib.import_module("lagrgen.cache")
    model = Model("read_only")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    model.spring(4.0, x)
    lagrgen.build(model, out_dir=tmp_path)

    def no_lock(path):
        raise PermissionError(13, "Read-only file system", str(path))
    monkeypatch.setattr(cache, "locked", no_lock)
    again = lagrgen.build(model, out_dir=tmp_path)
    assert again.build_info["cache_hit"] and again.rhs(0.0, [1.0, 0.0])[1] == -4.0
    model.spring(1.0, x)
    with pytest.raises(lagrgen.BuildError, match="cannot write the build of 'read_only'"):
        lagrgen.build(model, out_dir=tmp_path)


# -- 8. one rule for non-finite values ------------------------------------------------------
def test_domain_errors_follow_ieee_on_both_backends(compile_once):
    model = Model("domains")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    model.generalized_force(x, sp.sqrt(x) + sp.log(x + 1) + 1 / x)
    c, py = compile_once(model), lagrgen.build(model, backend="python")
    for q in (-4.0, 0.0, -1.0):
        a, b = c.forcing([q], [0.0]), py.forcing([q], [0.0])
        assert np.array_equal(np.isnan(a), np.isnan(b)) and np.array_equal(np.isinf(a), np.isinf(b))
        assert_allclose(a, b, rtol=1e-15)


def test_nan_in_the_state_is_a_mass_matrix_error_on_both_backends(both):
    for fn in (both.rhs, both.jacobian):
        with pytest.raises(MassMatrixError, match="NaN"):
            fn(0.0, [np.nan, 0.0, 0.0, 0.0])


def test_simulate_stops_where_the_derivative_becomes_non_finite(compile_once):
    model = Model("blow_up")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    model.generalized_force(x, sp.sqrt(1 - model.t))
    for mod in (compile_once(model), lagrgen.build(model, backend="python")):
        with pytest.raises(lagrgen.NonFiniteError, match=r"not finite at t=1\.0\d*"):
            lagrgen.simulate(mod, (0.0, 2.0), [0.0, 0.0], method="RK45")


# -- 9. clear errors ------------------------------------------------------------------------
def test_unclear_inputs_get_clear_model_errors(tmp_path):
    model = Model("clear")
    x, = model.coordinates("x")
    k, = model.parameters(k=1.0)
    v = sp.Matrix([x.diff(model.t)])
    model.kinetic_energy(v.T * v / 2)
    assert model.mass_matrix() == sp.Matrix([[1]])
    with pytest.raises(ModelError, match="relation"):
        model.potential_energy(sp.Eq(x, 1))
    with pytest.raises(ModelError, match="relation"):
        model.potential_energy(x > 0)
    with pytest.raises(ModelError, match="must be a scalar"):
        model.potential_energy(sp.Matrix([x, x]))
    with pytest.raises(ModelError, match="other assumptions"):
        model.potential_energy(sp.Symbol("k", positive=True) * x ** 2)
    model.spring(k, x)
    mod = lagrgen.build(model, out_dir=tmp_path, cflags="-ffast-math -O1")
    assert mod.rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-1.0)


def test_two_models_of_one_name_in_a_file_are_an_error(tmp_path, capsys):
    from lagrgen.cli import main
    (tmp_path / "twice.py").write_text(textwrap.dedent("""
        import sympy as sp
        from lagrgen import Model
        a = Model("same")
        b = Model("same")
        for m in (a, b):
            x, = m.coordinates("x")
            m.particle(1, sp.Matrix([x]))
    """))
    assert main(["build", str(tmp_path / "twice.py"), "--out", str(tmp_path / "out")]) == 1
    assert "more than one model named same" in capsys.readouterr().err
