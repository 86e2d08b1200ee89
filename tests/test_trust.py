"""Trust on a fresh machine (issue 19): every finite number is a number, a native solve that can be
stopped (guards and Ctrl-C handled in C), and a cache hit that derives nothing."""
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model, ModelError


# -- zero and subnormals are numbers --------------------------------------------------------------
def switched_model(name="switched"):
    """Zeros written as floats on every path: a Piecewise force, Min/Max, an output, an event and
    a constraint; a subnormal force."""
    model = Model(name)
    x, y, z = model.coordinates("x y z")
    m, k = model.parameters(m=1.0, k=4.0)
    t = model.t
    xd = sp.diff(x, t)
    model.particle(m, sp.Matrix([x, y, z]))
    model.spring(k, x)
    model.generalized_force(x, sp.Piecewise((1.0, t > 1), (0.0, True)))
    model.generalized_force(y, sp.Max(0.0, sp.Min(0.0 * x + 1e-310, 2.0)))
    model.generalized_force(z, sp.Piecewise((0.0, x > 0.0), (5e-324, True)))
    model.constraint(z - 0.0 * x - y, name="tie")
    model.output("slipping", 0.0 * x + sp.Piecewise((0.0, xd > 0.0), (1.0, True)))
    model.event("crosses", x - 0.0)
    return model


@pytest.fixture(scope="module")
def switched(tmp_path_factory):
    model = switched_model()
    return [lagrgen.build(model, backend="python"),
            lagrgen.build(model, out_dir=tmp_path_factory.mktemp("trust"))]


def test_a_switched_force_written_with_zero_floats_builds_and_runs(switched):
    for mod in switched:
        y_after = np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.0])
        a_after = mod.rhs(2.0, y_after)[3:]
        a_before = mod.rhs(0.5, y_after)[3:]
        assert a_after[0] == pytest.approx(1.0 - 0.4)
        assert a_before[0] == pytest.approx(-0.4)
        assert mod.outputs(0.0, [0.1, 0, 0, 1.0, 0, 0])[0] == 0.0
        assert mod.outputs(0.0, [0.1, 0, 0, -1.0, 0, 0])[0] == 1.0
        assert mod.events(0.0, y_after)[0] == pytest.approx(0.1)
        assert_allclose(mod.constraint_residuals(0.0, [0.0, 0.2, 0.5, 0, 0, 0])[0], 0.3)


def test_subnormal_numbers_keep_their_value(switched):
    for mod in switched:
        lam = mod.constraint_forces(0.0, np.zeros(6))
        assert np.isfinite(lam).all()
        # y and z share the subnormal force through the tie: each moves with half of it
        assert 0.0 < mod.rhs(0.0, np.zeros(6))[4] < 1e-300


@pytest.mark.parametrize("number", [sp.Float("1e400"), sp.Integer(10) ** 400, sp.nan,
                                    sp.Rational(1, 10 ** 400)])
def test_only_overflow_nan_and_silent_underflow_are_refused(number):
    model = Model("refused")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    with pytest.raises(ModelError):
        model.potential_energy(number * x ** 2)


@pytest.mark.parametrize("zero", [0.0, sp.Float(0.0), sp.Float("0.0", 30), -0.0])
def test_every_kind_of_zero_is_accepted(zero):
    model = Model("zeros")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    model.generalized_force(x, sp.Piecewise((1.0, x > zero), (zero, True)))
    model.output("o", sp.Max(zero, x))
    assert lagrgen.build(model, backend="python").rhs(0.0, [-1.0, 0.0])[1] == 0.0


# -- a native solve that can be stopped -----------------------------------------------------------
CHATTER = """
import sympy as sp
from lagrgen import Model
model = Model("chatter")
x, = model.coordinates("x")
m, k, mu, g = model.parameters(m=1.0, k=1.0, mu=0.5, g=9.81)
model.particle(m, sp.Matrix([x]))
model.spring(k, x)
model.generalized_force(x, -mu * m * g * sp.sign(sp.diff(x, model.t)))
"""


@pytest.fixture(scope="module")
def chatter(tmp_path_factory):
    """A block held by dry friction written as sign(v) from rest with |k·x| < μ·m·g: the
    explicit solvers crawl for ever at v = 0."""
    out = tmp_path_factory.mktemp("chatter")
    namespace = {}
    exec(CHATTER, namespace)
    return lagrgen.build(namespace["model"], out_dir=out), out


def test_a_chattering_solve_stops_at_max_wall_time_on_the_native_engine(chatter):
    mod, _ = chatter
    started = time.monotonic()
    sol = lagrgen.simulate(mod, (0, 10), [1.0, 0.0], method="RK45", max_wall_time=1.0)
    elapsed = time.monotonic() - started
    assert sol.engine == "native" and sol.status == -1 and not sol.success
    assert "max_wall_time=1 s" in sol.guard and "stopped at t" in sol.message
    assert 1.0 <= elapsed < 5.0
    assert 0 < sol.t[-1] < 10 and sol.y.shape == (2, len(sol.t))


@pytest.mark.parametrize("engine", ["native", "scipy"])
def test_max_steps_keeps_the_solution_up_to_there_on_both_engines(chatter, engine):
    mod, _ = chatter
    sol = lagrgen.simulate(mod, (0, 10), [1.0, 0.0], method="RK45", max_steps=50, engine=engine)
    assert sol.engine == engine and sol.status == -1 and "max_steps=50" in sol.guard
    assert "after 50 steps" in sol.message
    assert len(sol.t) == 51
    assert_allclose(sol.y, np.array([[1.0], [0.0]]) + 0 * sol.y, atol=1e-6)   # held by friction


def test_guard_arguments_are_checked_once():
    with pytest.raises(ValueError, match="max_steps must be a positive integer"):
        lagrgen.simulate(None, (0, 1), [0, 0], max_steps=0)
    with pytest.raises(ValueError, match="max_wall_time must be a positive"):
        lagrgen.simulate(None, (0, 1), [0, 0], max_wall_time=-1)


def test_ctrl_c_ends_a_native_solve_within_half_a_second(chatter):
    """SIGINT sent to the process while the solve runs in C without the GIL: KeyboardInterrupt
    within 0.5 s, and the process goes on to run another solve."""
    mod, out = chatter
    code = textwrap.dedent(f"""
        import os, signal, threading, time
        import lagrgen
        signal.signal(signal.SIGINT, signal.default_int_handler)   # whatever was inherited
        mod = lagrgen.load("chatter", out_dir={str(out)!r})
        sent = []
        def interrupt():
            time.sleep(0.5)
            sent.append(time.monotonic())
            os.kill(os.getpid(), signal.SIGINT)
        threading.Thread(target=interrupt, daemon=True).start()
        try:
            lagrgen.simulate(mod, (0, 10), [1.0, 0.0], method="RK45")
            print("not interrupted")
        except KeyboardInterrupt:
            print("interrupted after", time.monotonic() - sent[0])
        sol = lagrgen.simulate(mod, (0, 0.1), [10.0, 0.0], method="RK45")   # sliding: no chatter
        print("usable", sol.engine, sol.success)
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    lines = proc.stdout.split("\n")
    assert lines[0].startswith("interrupted after"), proc.stdout + proc.stderr
    assert float(lines[0].split()[-1]) < 0.5
    assert lines[1] == "usable native True"


# -- a cache hit derives nothing ------------------------------------------------------------------
def oscillator(name="keyed_osc", k=4.0, unit=None, stiffening=1):
    model = Model(name)
    x, = model.coordinates("x", units=unit)
    m, kk = model.parameters(m=1.0, k=k)
    model.particle(m, sp.Matrix([x]))
    model.potential_energy(kk * x ** 2 / 2 + stiffening * x ** 4)
    return model


def test_a_cache_hit_of_an_equal_description_derives_nothing(tmp_path, monkeypatch):
    import lagrgen.lagrange as lagrange
    first = lagrgen.build(oscillator(), out_dir=tmp_path)
    assert not first.build_info["cache_hit"]

    def no_derivation(spec):
        raise AssertionError("a cache hit must not derive the equations")
    monkeypatch.setattr(lagrange, "derive", no_derivation)
    again = lagrgen.build(oscillator(), out_dir=tmp_path)    # a new, equal Model object
    assert again.build_info["cache_hit"] and again.content_hash == first.content_hash


def test_the_description_key_sees_every_part_of_the_description():
    from lagrgen.cache import description_digest
    base = description_digest(oscillator().spec())
    assert description_digest(oscillator().spec()) == base
    for changed in (oscillator(k=5.0), oscillator(unit="m"), oscillator(stiffening=2),
                    oscillator(name="other_osc")):
        assert description_digest(changed.spec()) != base
    held = oscillator()
    held.velocity_constraint(sp.diff(held.q[0], held.t))
    assert description_digest(held.spec()) != base


def test_a_fast_math_model_leaves_the_process_floating_point_mode_alone(tmp_path):
    """-ffast-math at link time would add GCC's crtfastmath.o, which makes the whole process
    flush subnormals to zero when the module loads; lagrgen compiles with the user's flags but
    links without them."""
    code = textwrap.dedent(f"""
        import numpy as np, sympy as sp, lagrgen
        model = lagrgen.Model("fast_osc")
        x, = model.coordinates("x")
        model.particle(1, sp.Matrix([x]))
        model.potential_energy(2 * x ** 2)
        mod = lagrgen.build(model, out_dir={str(tmp_path)!r}, cflags="-ffast-math -O2")
        print(mod.rhs(0.0, [1.0, 0.0])[1], float(np.array([1e-310])[0] / 2))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert float(out[0]) == -4.0 and float(out[1]) == 5e-311


@pytest.mark.parametrize("t_span, message", [((0, 1, 2), "two numbers"), ((0, np.inf), "finite"),
                                             ("ab", "two numbers"), ((0, "x"), "two numbers")])
def test_a_bad_time_span_says_what_a_time_span_is(chatter, t_span, message):
    mod, _ = chatter
    with pytest.raises(ValueError, match=message):
        lagrgen.simulate(mod, t_span, [1.0, 0.0])
