"""The compiled path: C against Python to round-off, the wrapper's forgiveness, the cache, the CLI."""
import json
import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import sympy as sp

import lagrgen
from lagrgen import Model
from lagrgen.cache import CACHE_DIR, EXT_SUFFIX

from conftest import EXAMPLE_MODELS, example_id, example_model, random_point


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("compiled")


@pytest.fixture(scope="module", params=EXAMPLE_MODELS, ids=example_id)
def both(request, out_dir):
    """(compiled, python) builds of one example model."""
    model = example_model(*request.param)
    return lagrgen.build(model, out_dir=out_dir), lagrgen.build(model, backend="python")


def close(a, b):
    """Agreement to round-off, relative to the size of the entries."""
    scale = 1 + (np.abs(b).max() if np.size(b) else 0.0)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * scale)


def test_c_and_python_agree_on_every_example(both):
    """M, F, rhs, jacobian and the linear terms agree to ~1e-12 at random states."""
    c, py = both
    rng = np.random.default_rng(7)
    for _ in range(5):
        q, qd, t, p, u = random_point(c, rng)
        y = np.concatenate([q, qd])
        close(c.mass_matrix(q, t, p, u), py.mass_matrix(q, t, p, u))
        close(c.forcing(q, qd, t, p, u), py.forcing(q, qd, t, p, u))
        close(c.rhs(t, y, p, u), py.rhs(t, y, p, u))
        close(c.jacobian(t, y, p, u), py.jacobian(t, y, p, u))
        for a, b in zip(c.linear_terms(q, qd, t, p, u), py.linear_terms(q, qd, t, p, u)):
            close(a, b)


def test_built_model_reports_its_interface(both):
    c, py = both
    for attr in ("name", "coordinates", "parameters", "inputs", "n_coordinates"):
        assert getattr(c, attr) == getattr(py, attr)
    assert isinstance(c.coordinates, tuple) and isinstance(c.parameters, tuple)
    assert c.defaults.dtype == np.float64
    np.testing.assert_array_equal(c.defaults, py.defaults)
    n = c.n_coordinates
    y = np.full(2 * n, 0.1)
    assert c.rhs(0.0, y).shape == (2 * n,)
    assert c.jacobian(0.0, y).shape == (2 * n, 2 * n)
    assert c.mass_matrix(y[:n]).shape == (n, n)
    assert c.forcing(y[:n], y[n:]).shape == (n,)


def test_simulate_takes_either_backend(both):
    c, py = both
    n = c.n_coordinates
    y0 = np.full(2 * n, 0.1)
    for method in ("RK45", "Radau"):
        a = lagrgen.simulate(c, (0, 1), y0, method=method, rtol=1e-10, atol=1e-10)
        b = lagrgen.simulate(py, (0, 1), y0, method=method, rtol=1e-10, atol=1e-10)
        assert a.success and b.success
        np.testing.assert_allclose(a.y[:, -1], b.y[:, -1], rtol=1e-7, atol=1e-9)


@pytest.fixture(scope="module")
def pendulum(out_dir):
    return lagrgen.build(example_model("double_pendulum"), out_dir=out_dir)


def test_strided_list_and_integer_inputs(pendulum):
    y = np.array([0.3, -0.2, 0.1, 0.4])
    expected = pendulum.rhs(0.0, y)
    wide = np.zeros(8)
    wide[::2] = y
    np.testing.assert_array_equal(pendulum.rhs(0.0, wide[::2]), expected)
    np.testing.assert_array_equal(pendulum.rhs(0.0, list(y)), expected)
    np.testing.assert_array_equal(pendulum.rhs(0, np.array([1, 2, 3, 4])),
                                  pendulum.rhs(0.0, np.array([1.0, 2.0, 3.0, 4.0])))
    np.testing.assert_array_equal(pendulum.rhs(0.0, y.astype(np.float32)),
                                  pendulum.rhs(0.0, y.astype(np.float32).astype(float)))
    np.testing.assert_array_equal(pendulum.jacobian(0.0, wide[::2]), pendulum.jacobian(0.0, y))
    p = np.array(pendulum.defaults)
    np.testing.assert_array_equal(pendulum.rhs(0.0, y, list(p), [0]), expected)
    np.testing.assert_array_equal(pendulum.mass_matrix([0.3, -0.2]), pendulum.mass_matrix(y[:2]))


def test_every_call_returns_a_new_array(pendulum):
    y = np.array([0.3, -0.2, 0.1, 0.4])
    a, b = pendulum.rhs(0.0, y), pendulum.rhs(0.0, y)
    assert a is not b and not np.shares_memory(a, b)
    first = a.copy()
    pendulum.rhs(0.0, y + 1.0)
    np.testing.assert_array_equal(a, first)
    assert pendulum.jacobian(0.0, y) is not pendulum.jacobian(0.0, y)


@pytest.mark.parametrize("call", [
    lambda m: m.rhs(0.0, np.zeros(3)),
    lambda m: m.rhs(0.0, np.zeros((2, 2))),
    lambda m: m.jacobian(0.0, np.zeros(5)),
    lambda m: m.mass_matrix(np.zeros(3)),
    lambda m: m.forcing(np.zeros(2), np.zeros(1)),
    lambda m: m.rhs(0.0, np.zeros(4), np.zeros(2)),
    lambda m: m.rhs(0.0, np.zeros(4), None, np.zeros(2)),
    lambda m: m.rhs(0.0, ["a", "b", "c", "d"]),
])
def test_wrong_lengths_raise_value_error(pendulum, call):
    with pytest.raises(ValueError, match="length|array"):
        call(pendulum)


def test_not_positive_definite_mass_matrix_is_an_error(pendulum):
    p = np.array(pendulum.defaults)
    p[list(pendulum.parameters).index("m1")] = -5.0
    with pytest.raises(lagrgen.MassMatrixError, match="not positive definite"):
        pendulum.rhs(0.0, [0.1, 0.2, 0.0, 0.0], p)
    with pytest.raises(np.linalg.LinAlgError):
        pendulum.jacobian(0.0, [0.1, 0.2, 0.0, 0.0], p)
    with pytest.raises(lagrgen.MassMatrixError, match="NaN"):
        pendulum.rhs(0.0, [np.nan, 0.2, 0.0, 0.0])


def test_parameters_by_dict_at_call_time(pendulum):
    y = [0.3, -0.2, 0.1, 0.4]
    p = np.array(pendulum.defaults)
    p[list(pendulum.parameters).index("g")] = 3.0
    np.testing.assert_array_equal(pendulum.rhs(0.0, y, {"g": 3.0}), pendulum.rhs(0.0, y, p))
    with pytest.raises(lagrgen.UnknownNameError, match="nope"):
        pendulum.rhs(0.0, y, {"nope": 1.0})


def keyword_model(name="c_names"):
    """A spring–mass whose names are C keywords, libm functions and lagrgen's own C identifiers."""
    model = Model(name)
    x, main = model.coordinates("int main")
    k, y, sin, double, N, q, p, u, a, x0, M = model.parameters(
        int_=None, y=2.0, sin=3.0, double=0.5, N=1.5, q=1.0, p=1.0, u=1.0, a=1.0, x0=1.0, M=1.0)
    F, = model.inputs("static")
    model.particle(y, sp.Matrix([x]))
    model.particle(sin, sp.Matrix([main]))
    model.spring(double, x, rest=x0)
    model.spring(N, main - x)
    model.potential_energy(q * p * u * a * M * x ** 2 / 2 + k * main ** 2 / 2)
    model.generalized_force(main, F)
    return model


def test_user_names_that_are_c_keywords(out_dir):
    model = keyword_model()
    c = lagrgen.build(model, out_dir=out_dir)
    py = lagrgen.build(model, backend="python")
    assert c.coordinates == ("int", "main")
    assert c.inputs == ("static",)
    assert np.isnan(c.defaults[0])
    p = np.array(c.defaults)
    p[0] = 4.0
    y = np.array([0.1, -0.3, 0.2, 0.5])
    close(c.rhs(0.0, y, p, [0.7]), py.rhs(0.0, y, p, [0.7]))
    close(c.jacobian(0.0, y, p, [0.7]), py.jacobian(0.0, y, p, [0.7]))
    with pytest.raises(ValueError, match="int_"):
        c.rhs(0.0, y)
    source = (out_dir / "c_names_model.c").read_text()
    assert "double int" not in source and " main =" not in source


def spring_mass(name, k):
    model = Model(name)
    x, = model.coordinates("x")
    m, = model.parameters(m=2.0)
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    return model


def test_second_build_is_a_cache_hit_and_a_changed_model_is_rebuilt(tmp_path):
    first = lagrgen.build(spring_mass("oscillator", 8.0), out_dir=tmp_path)
    assert not first.build_info["cache_hit"]
    again = lagrgen.build(spring_mass("oscillator", 8.0), out_dir=tmp_path)
    assert again.build_info["cache_hit"]
    assert again.rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-4.0)
    changed = lagrgen.build(spring_mass("oscillator", 18.0), out_dir=tmp_path)
    assert not changed.build_info["cache_hit"]
    assert changed.rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-9.0)
    assert lagrgen.load("oscillator", out_dir=tmp_path).rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-9.0)
    assert first.rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-4.0)


def test_load_of_a_model_never_built_says_how_to_build(tmp_path):
    with pytest.raises(lagrgen.BuildError, match="build it first"):
        lagrgen.load("nothing_here", out_dir=tmp_path)


def test_compile_error_shows_the_compilers_message(tmp_path):
    with pytest.raises(lagrgen.CompileError, match="no_such_header_for_lagrgen.h"):
        lagrgen.build(spring_mass("broken", 1.0), out_dir=tmp_path,
                      cflags=["-include", "no_such_header_for_lagrgen.h"])
    assert not list(tmp_path.glob(f"broken*{EXT_SUFFIX}"))
    assert not list((tmp_path / CACHE_DIR).glob(f"broken*{EXT_SUFFIX}"))
    assert not [p for p in (tmp_path / CACHE_DIR).iterdir() if p.name.startswith(".build")]
    with pytest.raises(lagrgen.BuildError):
        lagrgen.load("broken", out_dir=tmp_path)


def test_a_build_that_dies_halfway_leaves_nothing_to_load(tmp_path, monkeypatch):
    import importlib; compiler = importlib.import_module("lagrgen.build")

    def dies(source_path, output_path, flags):
        output_path.write_bytes(b"half a module")
        raise KeyboardInterrupt
    monkeypatch.setattr(compiler, "compile_module", dies)
    with pytest.raises(KeyboardInterrupt):
        lagrgen.build(spring_mass("interrupted", 1.0), out_dir=tmp_path)
    monkeypatch.undo()
    with pytest.raises(lagrgen.BuildError):
        lagrgen.load("interrupted", out_dir=tmp_path)
    mod = lagrgen.build(spring_mass("interrupted", 1.0), out_dir=tmp_path)
    assert not mod.build_info["cache_hit"]


MODEL_FILE = textwrap.dedent("""
    import sympy as sp
    from lagrgen import Model

    def oscillator(name, k):
        model = Model(name)
        x, = model.coordinates("x")
        m, = model.parameters(m=1.0)
        model.particle(m, sp.Matrix([x]))
        model.spring(k, x)
        return model

    soft = oscillator("soft", 4.0)
    stiff = oscillator("stiff", 9.0)
""")


def run(args, cwd, env_path=None):
    env = dict(os.environ)
    return subprocess.run([sys.executable, *args], cwd=cwd, capture_output=True, text=True,
                          env=env)


def test_cli_builds_and_another_process_imports(tmp_path):
    (tmp_path / "springs.py").write_text(MODEL_FILE)
    out = tmp_path / "built"
    result = run(["-m", "lagrgen", "build", "springs.py", "--out", str(out)], tmp_path)
    assert result.returncode == 0, result.stderr
    assert "soft: built in " in result.stdout and "stiff: built in " in result.stdout
    assert result.stdout.count(", dense formulation -> ") == 2
    check = ("import sys, json; sys.path.insert(0, sys.argv[1]); import soft, stiff; "
             "print(json.dumps([soft.rhs(0, [1.0, 0.0]).tolist(), stiff.name, stiff.coordinates]))")
    imported = run(["-c", check, str(out)], tmp_path)
    assert imported.returncode == 0, imported.stderr
    rhs, name, coordinates = json.loads(imported.stdout)
    assert rhs == [0.0, -4.0] and name == "stiff" and coordinates == ["x"]
    again = run(["-m", "lagrgen", "build", "springs.py", "--out", str(out)], tmp_path)
    assert again.returncode == 0 and again.stdout.count("cached") == 2
    assert again.stdout.count(", dense formulation -> ") == 2


def test_the_formulation_a_build_chose_is_shown(tmp_path, capsys):
    """In the verbose output of a build (derived or cached), in the built model's repr, and on the
    command line's line per model (a chain of RECURSIVE_FROM links: lagrgen chooses the
    recursion)."""
    from conftest import EXAMPLES, load_example
    from lagrgen.tree import RECURSIVE_FROM
    model = load_example("nlink_pendulum").make(RECURSIVE_FROM)
    for formulation in (None, "dense"):
        chosen = formulation or "recursive"
        mod = lagrgen.build(model, out_dir=tmp_path, formulation=formulation, verbose=True)
        assert f"{RECURSIVE_FROM} coordinates, {chosen} formulation" in capsys.readouterr().err
        assert mod.formulation == chosen and f"(c backend, {chosen} formulation)" in repr(mod)
        lagrgen.build(model, out_dir=tmp_path, formulation=formulation, verbose=True)
        assert f"({chosen} formulation)" in capsys.readouterr().err.split("cached build")[1]
    (tmp_path / "chain.py").write_text(f"import sys\nsys.path.insert(0, {str(EXAMPLES)!r})\n"
                                       f"from nlink_pendulum import make\n"
                                       f"chain = make({RECURSIVE_FROM})\n")
    result = run(["-m", "lagrgen", "build", "chain.py", "--out", str(tmp_path)], tmp_path)
    assert result.returncode == 0, result.stderr
    assert f"nlink{RECURSIVE_FROM}: cached in " in result.stdout
    assert ", recursive formulation -> " in result.stdout


def test_cli_reports_a_bad_model_file_without_a_traceback(tmp_path):
    (tmp_path / "empty.py").write_text("x = 1\n")
    result = run(["-m", "lagrgen", "build", "empty.py"], tmp_path)
    assert result.returncode != 0
    assert "defines no lagrgen.Model" in result.stderr and "Traceback" not in result.stderr


def test_two_processes_building_the_same_model_both_succeed(tmp_path):
    (tmp_path / "springs.py").write_text(MODEL_FILE)
    out = tmp_path / "shared_out"
    cmd = [sys.executable, "-m", "lagrgen", "build", "springs.py", "--out", str(out)]
    procs = [subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(3)]
    results = [p.communicate() + (p.returncode,) for p in procs]
    assert all(code == 0 for _, _, code in results), results
    assert sum(stdout.count("built") for stdout, _, _ in results) == 2
    assert lagrgen.load("soft", out_dir=out).rhs(0.0, [1.0, 0.0])[1] == pytest.approx(-4.0)


def test_generated_c_is_readable(out_dir, pendulum):
    source = (out_dir / "double_pendulum_model.c").read_text()
    assert source.startswith("/* double_pendulum:")
    assert f"lagrgen {lagrgen.__version__}" in source
    assert pendulum.content_hash in source
    assert "const double x0 = " in source
    for function in ("mass_matrix", "forcing", "rhs", "jacobian", "linear_terms"):
        assert f"LG_FN int double_pendulum_{function}(double t, const double *y" in source


def test_a_relative_out_dir_named_like_a_compiler_option_is_a_folder(tmp_path, monkeypatch):
    """The compiler is given absolute paths: a folder "-O3" is not an option to it."""
    monkeypatch.chdir(tmp_path)
    mod = lagrgen.build(spring_mass("dash_folder", 4.0), out_dir="-O3")
    assert (tmp_path / "-O3" / "dash_folder_model.c").is_file()
    assert mod.rhs(0.0, [0.1, 0.0])[1] == pytest.approx(-0.2)     # -k·x/m


# -- the compilers' runner (lagrgen.toolchain.run_compilers) ------------------------------------
SLEEPER = ("import os, sys, time\n"
           "open(sys.argv[1], 'w').write(str(os.getpid()))\n"
           "time.sleep(float(sys.argv[2]))\n"
           "sys.exit(int(sys.argv[3]))\n")


def _sleepers(tmp_path, seconds, codes=None):
    """(command, source) jobs of processes that write their pid, sleep, and exit with a code."""
    codes = codes or [0] * len(seconds)
    return [([sys.executable, "-c", SLEEPER, str(tmp_path / f"pid{k}"), str(s), str(c)],
             tmp_path / f"unit{k}.c") for k, (s, c) in enumerate(zip(seconds, codes))]


def _gone(tmp_path, count):
    """True when each started job's process no longer exists (killed and reaped)."""
    for k in range(count):
        path = tmp_path / f"pid{k}"
        if not path.exists() or not path.read_text():
            continue
        try:
            os.kill(int(path.read_text()), 0)
        except ProcessLookupError:
            continue
        return False
    return True


def test_a_ctrl_c_during_the_compilers_kills_them_at_once_and_leaves_no_thread(tmp_path):
    """An interrupt while compilers run reaches the caller at once (not when they finish), the
    compilers are killed and reaped, and no thread is left behind (the units ran on a thread
    pool, whose locks an interrupt could leave held and hang the build)."""
    import signal
    import threading
    from lagrgen.toolchain import run_compilers

    def interrupt(signum, frame):
        raise KeyboardInterrupt
    threads = threading.active_count()
    old = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, 1.0)
        began = time.perf_counter()
        with pytest.raises(KeyboardInterrupt):
            run_compilers(_sleepers(tmp_path, [30, 30, 30]), 2)
        waited = time.perf_counter() - began
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    assert waited < 10
    assert _gone(tmp_path, 3)
    assert not (tmp_path / "pid2").exists()           # the third never started
    assert threading.active_count() == threads


def test_a_failed_unit_stops_the_others_and_says_which(tmp_path):
    """The first compiler to fail raises CompileError naming its unit and showing its output;
    the ones still running are killed, the ones waiting never start."""
    from lagrgen.toolchain import run_compilers
    jobs = _sleepers(tmp_path, [30, 0.1, 30], codes=[0, 3, 0])
    began = time.perf_counter()
    with pytest.raises(lagrgen.CompileError, match=r"unit1\.c \(exit 3\)"):
        run_compilers(jobs, 2)
    assert time.perf_counter() - began < 10
    assert _gone(tmp_path, 3) and not (tmp_path / "pid2").exists()
    run_compilers(_sleepers(tmp_path, [0.05] * 5), 2)    # all succeed: no error
    assert all((tmp_path / f"pid{k}").exists() for k in range(5))


def test_a_missing_compiler_is_a_build_error_saying_what_to_do(tmp_path, monkeypatch):
    from pathlib import Path
    from lagrgen.toolchain import compiler_command, run_compiler
    monkeypatch.setenv("CC", str(tmp_path / "no_such_cc"))
    with pytest.raises(lagrgen.BuildError, match=r"no C compiler found .*\$CC.*backend='python'"):
        run_compiler([*compiler_command(), "--version"], Path("unit.c"))
