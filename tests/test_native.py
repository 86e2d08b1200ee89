"""The native engine (lagrgen.native.engine, lagrgen/native/lg_ode.c) against SciPy's solve_ivp.

Acceptance: the same steps as the SciPy engine, states equal to 1e-10 relative, dense output and
events as SciPy's. "The same steps" is asserted where it is a property of the port and not of the
machine: on SciPy's ported release series (`conftest.SCIPY_PORTED`) with the same arithmetic the
counts are equal; a last-bit difference in OpenBLAS's sums (another CPU, another OpenBLAS) may
flip one accept/reject decision, so the counts are compared within `conftest.counts_close` and,
where the step times differ, the solutions at the end within the tolerance of the solve.
"""
import ctypes
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

import lagrgen
from lagrgen import Model, Signal
from lagrgen.native._ode import signal_values
from lagrgen.native.engine import solve_native

from conftest import counts_close, example_model

METHODS = ["RK23", "RK45", "DOP853", "Radau", "BDF"]


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("native_models")


@pytest.fixture(scope="module")
def pendulum(out_dir):
    return lagrgen.build(example_model("double_pendulum"), out_dir=out_dir)


@pytest.fixture(scope="module")
def chain(out_dir):
    return lagrgen.build(example_model("two_mass_chain", "absolute"), out_dir=out_dir)


@pytest.fixture(scope="module")
def fading_mass(out_dir):
    """x with kinetic energy (1 - t) xdot^2 / 2: M = 1 - t stops being positive at t = 1."""
    model = Model("fading_mass")
    x, = model.coordinates("x")
    k, = model.parameters(k=1.0)
    xd = sp.diff(x, model.t)
    model.kinetic_energy(sp.Rational(1, 2) * (1 - model.t) * xd**2)
    model.potential_energy(k * x**2 / 2)
    return lagrgen.build(model, out_dir=out_dir)


def scipy_reference(mod, t_span, y0, method, p=None, u_of_t=None, **kw):
    """solve_ivp on the model's Python-callable rhs (and jacobian for the stiff methods)."""
    p = np.asarray(mod.defaults if p is None else p, dtype=float)
    u0 = np.zeros(len(mod.inputs))
    uf = (lambda t: u0) if u_of_t is None else u_of_t
    if method in ("Radau", "BDF"):
        kw["jac"] = lambda t, y: mod.jacobian(t, y, p, uf(t))
    return solve_ivp(lambda t, y: mod.rhs(t, y, p, uf(t)), t_span, y0, method=method, **kw)


def assert_same_solve(ours, ref, mod, p=None, u_of_t=None, rel=1e-10, t_rel=1e-7):
    """Same steps (counts, and step times to `t_rel`) and the same states to `rel` relative.

    Step sizes come from error estimates that cancel about eight digits, so a last-bit difference
    in a sum (SciPy's sums run in OpenBLAS, ours in plain C) moves a step time by ~1e-9
    relative: SciPy itself does the same when only its LU routine is swapped. The states are
    therefore compared at the same times: ours moved to SciPy's step times to first order,
    y + f(t, y) (t_ref - t), which is exact to O(dt^2) ~ 1e-20.
    """
    assert ours.engine == "native"
    assert ours.status == ref.status, ours.message
    assert counts_close((ours.nfev, ours.njev, ours.nlu), (ref.nfev, ref.njev, ref.nlu))
    if ours.t.shape != ref.t.shape or not np.allclose(ours.t, ref.t, rtol=t_rel, atol=0):
        scale = float(np.max(np.abs(ref.y))) if ref.y.size else 1.0
        assert ours.t[-1] == pytest.approx(ref.t[-1], rel=t_rel)
        assert_allclose(ours.y[:, -1], ref.y[:, -1], rtol=1e-5, atol=1e-5 * scale)
        return
    y = ours.y.copy()
    p = np.asarray(mod.defaults if p is None else p, dtype=float)
    u0 = np.zeros(len(mod.inputs))
    for k in np.nonzero(ours.t != ref.t)[0]:
        u = u0 if u_of_t is None else u_of_t(ours.t[k])
        y[:, k] += mod.rhs(ours.t[k], ours.y[:, k], p, u) * (ref.t[k] - ours.t[k])
    scale = float(np.max(np.abs(ref.y))) if ref.y.size else 1.0
    assert_allclose(y, ref.y, rtol=rel, atol=rel * scale)


@pytest.mark.parametrize("method", METHODS)
def test_double_pendulum_same_steps_as_scipy(pendulum, method):
    y0 = [0.5, -0.3, 0.0, 0.4]
    ours = lagrgen.simulate(pendulum, (0, 3), y0, method=method, rtol=1e-8, atol=1e-8)
    ref = scipy_reference(pendulum, (0, 3), y0, method, rtol=1e-8, atol=1e-8)
    assert ours.t.size > 20
    assert_same_solve(ours, ref, pendulum)


@pytest.mark.parametrize("method", METHODS)
def test_damped_chain_with_constant_force(chain, method):
    y0 = [0.1, -0.05, 0.0, 0.2]
    ours = lagrgen.simulate(chain, (0, 5), y0, method=method, inputs={"f": 0.7},
                            rtol=1e-7, atol=1e-9)
    u = np.array([0.7])
    ref = scipy_reference(chain, (0, 5), y0, method, u_of_t=lambda t: u, rtol=1e-7, atol=1e-9)
    assert_same_solve(ours, ref, chain, u_of_t=lambda t: u)


@pytest.mark.parametrize("method", ["Radau", "BDF"])
def test_stiff_chain(chain, method):
    p = dict(zip(chain.parameters, chain.defaults))
    p.update(k1=1e6, c1=1e4)
    pv = np.array([p[k] for k in chain.parameters])
    y0 = [0.01, 0.0, 0.0, 0.0]
    ours = lagrgen.simulate(chain, (0, 2), y0, method=method, params=pv, inputs={"f": 1.0},
                            rtol=1e-6, atol=1e-9)
    u = np.array([1.0])
    ref = scipy_reference(chain, (0, 2), y0, method, p=pv, u_of_t=lambda t: u,
                          rtol=1e-6, atol=1e-9)
    assert ref.njev >= 1 and ref.nlu > 1
    assert_same_solve(ours, ref, chain, p=pv, u_of_t=lambda t: u, t_rel=1e-5)


@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "BDF"])
def test_cubic_signal_input_same_steps(pendulum, method):
    ts = np.linspace(0, 3, 13)
    sig = Signal(ts, 2.0 * np.sin(2 * ts), kind="cubic")
    y0 = [0.2, 0.1, 0.0, 0.0]
    ours = lagrgen.simulate(pendulum, (0, 3), y0, method=method, inputs={"F": sig},
                            rtol=1e-8, atol=1e-8)
    assert ours.engine == "native"
    ref = scipy_reference(pendulum, (0, 3), y0, method, u_of_t=lambda t: np.array([sig(t)]),
                          rtol=1e-8, atol=1e-8)
    assert_same_solve(ours, ref, pendulum, u_of_t=lambda t: np.array([sig(t)]))
    on_scipy = lagrgen.simulate(pendulum, (0, 3), y0, method=method, inputs={"F": sig},
                                rtol=1e-8, atol=1e-8, engine="scipy")
    assert on_scipy.engine == "scipy" and counts_close(on_scipy.nfev, ours.nfev)


@pytest.mark.parametrize("kind", ["linear", "previous"])
@pytest.mark.parametrize("method", ["RK45", "Radau"])
def test_kinked_signal_input(pendulum, kind, method):
    """Linear and previous signals have kinks/jumps at the samples, where accepting or rejecting
    a step is decided by error estimates as ill-conditioned as the data: a last-bit difference
    can flip one decision, so the step counts may differ slightly; the solutions agree."""
    ts = np.linspace(0, 3, 13)
    sig = Signal(ts, 2.0 * np.sin(2 * ts), kind=kind)
    y0 = [0.2, 0.1, 0.0, 0.0]
    t_eval = np.linspace(0, 3, 31)
    ours = lagrgen.simulate(pendulum, (0, 3), y0, method=method, inputs={"F": sig},
                            rtol=1e-9, atol=1e-9, t_eval=t_eval)
    ref = scipy_reference(pendulum, (0, 3), y0, method, u_of_t=lambda t: np.array([sig(t)]),
                          rtol=1e-9, atol=1e-9, t_eval=t_eval)
    assert ours.engine == "native" and ours.success
    assert abs(ours.nfev - ref.nfev) <= 0.1 * ref.nfev
    assert_allclose(ours.y, ref.y, rtol=1e-6, atol=1e-6)
    free = lagrgen.simulate(pendulum, (0, 3), y0, method=method, rtol=1e-9, atol=1e-9,
                            t_eval=t_eval)
    assert np.max(np.abs(free.y - ours.y)) > 1e-3    # the input acted


def test_signal_interpolation_in_c_matches_numpy_and_scipy():
    rng = np.random.default_rng(3)
    ts = np.cumsum(rng.uniform(0.1, 1.0, 9))
    vs = rng.normal(size=9)
    t = np.concatenate((np.linspace(ts[0] - 1, ts[-1] + 1, 301), ts))
    lin = Signal(ts, vs, "linear")
    assert_allclose(signal_values(lin.native_spec(), t), np.interp(t, ts, vs), rtol=1e-14,
                    atol=1e-14)
    assert_allclose(lin(t), np.interp(t, ts, vs))
    cub = Signal(ts, vs, "cubic")
    assert_allclose(signal_values(cub.native_spec(), t), CubicSpline(ts, vs)(t), rtol=1e-12,
                    atol=1e-12)
    prev = Signal(ts, vs, "previous")
    k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 1)
    assert_allclose(signal_values(prev.native_spec(), t), vs[k], rtol=0, atol=0)
    assert prev(ts[3]) == vs[3] and prev(ts[3] - 1e-9) == vs[2]


@pytest.mark.parametrize("args, match", [
    (([0, 1, 1], [1, 2, 3]), "strictly increasing"),
    (([0, 1], [1, 2, 3]), "has 2 values but values has 3"),
    (([0, np.nan], [1, 2]), "finite"),
    (([0], [1]), "at least 2"),
    (([[0, 1]], [[1, 2]]), "1-D"),
])
def test_signal_validation(args, match):
    with pytest.raises(ValueError, match=match):
        Signal(*args)
    with pytest.raises(ValueError, match="unknown Signal kind"):
        Signal([0, 1], [0, 1], kind="quadratic")


@pytest.mark.parametrize("method", METHODS)
def test_t_eval_and_dense_output(pendulum, method):
    y0 = [0.5, -0.3, 0.0, 0.4]
    t_eval = np.linspace(0, 3, 37)
    ours = lagrgen.simulate(pendulum, (0, 3), y0, method=method, rtol=1e-8, atol=1e-8,
                            t_eval=t_eval, dense_output=True)
    ref = scipy_reference(pendulum, (0, 3), y0, method, rtol=1e-8, atol=1e-8, t_eval=t_eval,
                          dense_output=True)
    assert_same_solve(ours, ref, pendulum)   # DOP853's dense stages are counted in nfev here
    tt = np.linspace(0, 3, 501)
    assert_allclose(ours.sol(tt), ref.sol(tt), rtol=1e-10, atol=1e-10)
    assert type(ours.sol.interpolants[0]) is type(ref.sol.interpolants[0])


@pytest.mark.parametrize("method", ["RK45", "BDF"])
def test_backwards_in_time_with_t_eval(chain, method):
    y0 = [0.1, -0.05, 0.0, 0.2]
    t_eval = np.linspace(4, 0, 9)
    ours = lagrgen.simulate(chain, (4, 0), y0, method=method, rtol=1e-7, atol=1e-9,
                            t_eval=t_eval, dense_output=True)
    ref = scipy_reference(chain, (4, 0), y0, method, rtol=1e-7, atol=1e-9, t_eval=t_eval,
                          dense_output=True)
    assert_same_solve(ours, ref, chain)
    assert_allclose(ours.sol([3.3, 1.1]), ref.sol([3.3, 1.1]), rtol=1e-10, atol=1e-12)


EVENTS_C = r"""
/* g0 = theta1 (zero crossings), g1 = theta2 - 0.1 */
int pendulum_events(double t, const double *y, const double *p, const double *u, double *g)
{
    (void)t; (void)p; (void)u;
    g[0] = y[0];
    g[1] = y[1] - 0.1;
    return 0;
}
"""


@pytest.fixture(scope="module")
def events_address(tmp_path_factory):
    """The address of a C events function compiled into a small shared library."""
    d = tmp_path_factory.mktemp("events")
    (d / "ev.c").write_text(EVENTS_C)
    lib_path = d / ("ev.dylib" if sys.platform == "darwin" else "ev.so")
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-o", str(lib_path), str(d / "ev.c")],
                   check=True)
    lib = ctypes.CDLL(str(lib_path))
    return lib, ctypes.cast(lib.pendulum_events, ctypes.c_void_p).value


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("terminal, direction", [((False, False), (0, 0)),
                                                  ((False, True), (1, -1)),
                                                  ((2, False), (-1, 0))])
def test_events_against_solve_ivp(pendulum, events_address, method, terminal, direction):
    _, address = events_address
    y0 = np.array([0.5, -0.3, 0.0, 0.4])

    def g0(t, y):
        return y[0]

    def g1(t, y):
        return y[1] - 0.1
    for g, term, d in zip((g0, g1), terminal, direction):
        g.terminal, g.direction = term, d
    ref = scipy_reference(pendulum, (0, 6), y0, method, rtol=1e-8, atol=1e-8, events=[g0, g1])
    ours = solve_native(pendulum, (0, 6), y0, method, rtol=1e-8, atol=1e-8,
                        events=(address, terminal, direction))
    assert_same_solve(ours, ref, pendulum)
    assert sum(len(te) for te in ref.t_events) >= 1
    for te, ye, rte, rye in zip(ours.t_events, ours.y_events, ref.t_events, ref.y_events):
        assert te.shape == rte.shape
        if rte.size:
            assert_allclose(te, rte, rtol=1e-10, atol=1e-12)
            assert_allclose(ye, rye, rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("method", ["RK45", "Radau", "BDF"])
def test_singular_mass_matrix_stops_with_a_message(fading_mass, method):
    # the first step (1.2) puts a stage past t = 1, where M = 1 - t < 0
    res = solve_native(fading_mass, (0, 2), [1.0, 0.0], method, first_step=1.2)
    assert res.status == -1 and not res.success
    assert "not positive definite at t = " in res.message
    t_fail = float(res.message.rsplit("=", 1)[1])
    assert 1.0 < t_fail <= 1.2
    assert res.mass_matrix_failure[0] == t_fail and res.mass_matrix_failure[1].shape == (2,)
    assert res.t[-1] == 0.0
    # simulate raises the same error on both engines
    for engine in ("native", "scipy"):
        with pytest.raises(lagrgen.MassMatrixError, match="not positive definite at t=1"):
            lagrgen.simulate(fading_mass, (0, 2), [1.0, 0.0], method=method, first_step=1.2,
                             engine=engine)


def test_engine_choice(pendulum):
    y0 = [0.1, 0.0, 0.0, 0.0]
    assert lagrgen.simulate(pendulum, (0, 1), y0).engine == "native"
    assert lagrgen.simulate(pendulum, (0, 1), y0, engine="scipy").engine == "scipy"
    lsoda = lagrgen.simulate(pendulum, (0, 1), y0, method="LSODA")
    assert lsoda.engine == "scipy"
    with pytest.raises(ValueError, match="LSODA"):
        lagrgen.simulate(pendulum, (0, 1), y0, method="LSODA", engine="native")
    forced = lagrgen.simulate(pendulum, (0, 1), y0, inputs={"F": lambda t: 0.1 * t})
    assert forced.engine == "scipy" and "Python callable" in forced.message
    with pytest.raises(ValueError, match="Python callable"):
        lagrgen.simulate(pendulum, (0, 1), y0, inputs={"F": np.cos}, engine="native")
    with pytest.raises(ValueError, match="events"):
        lagrgen.simulate(pendulum, (0, 1), y0, events=lambda t, y: y[0], engine="native")
    with pytest.raises(ValueError, match="engine must be"):
        lagrgen.simulate(pendulum, (0, 1), y0, engine="fortran")
    py = lagrgen.build(example_model("double_pendulum"), backend="python")
    assert lagrgen.simulate(py, (0, 1), y0).engine == "scipy"


def test_bad_arguments_raise(pendulum):
    y0 = [0.1, 0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="y0 must have 4"):
        solve_native(pendulum, (0, 1), [0.1, 0.0], "RK45")
    with pytest.raises(ValueError, match="no native implementation"):
        solve_native(pendulum, (0, 1), y0, "LSODA")
    with pytest.raises(ValueError, match="max_step"):
        lagrgen.simulate(pendulum, (0, 1), y0, max_step=0.0)
    with pytest.raises(ValueError, match="first_step"):
        lagrgen.simulate(pendulum, (0, 1), y0, first_step=2.0)
    with pytest.raises(ValueError, match="not within"):
        lagrgen.simulate(pendulum, (0, 1), y0, t_eval=[0.5, 1.5])
    with pytest.raises(ValueError, match="sorted"):
        lagrgen.simulate(pendulum, (0, 1), y0, t_eval=[0.5, 0.2])
    with pytest.raises(ValueError, match="atol"):
        lagrgen.simulate(pendulum, (0, 1), y0, atol=-1.0)
    with pytest.raises(ValueError, match="NaN"):
        solve_native(pendulum, (0, 1), y0, "RK45", p=[np.nan] * len(pendulum.defaults))
    with pytest.raises(lagrgen.UnknownNameError, match="unknown input name 'G'"):
        lagrgen.simulate(pendulum, (0, 1), y0, inputs={"G": 1.0})
    with pytest.raises(ValueError, match="finite"):
        solve_native(pendulum, (0, np.inf), y0, "RK45")
    assert lagrgen.simulate(pendulum, (0, 1), y0, rtol=[1e-6] * 4).engine == "scipy"
    with pytest.raises(ValueError, match="terminal"):
        solve_native(pendulum, (0, 1), y0, "RK45", events=(1, [0.5], [0]))


def test_options_match_scipy(pendulum):
    y0 = [0.5, -0.3, 0.0, 0.4]
    ours = lagrgen.simulate(pendulum, (0, 2), y0, method="RK45", max_step=0.05,
                            first_step=1e-3, atol=[1e-8, 1e-8, 1e-6, 1e-6])
    ref = scipy_reference(pendulum, (0, 2), y0, "RK45", max_step=0.05, first_step=1e-3,
                          atol=[1e-8, 1e-8, 1e-6, 1e-6], rtol=1e-6)
    assert_same_solve(ours, ref, pendulum)
    empty = lagrgen.simulate(pendulum, (1, 1), y0, method="DOP853", dense_output=True)
    ref0 = scipy_reference(pendulum, (1, 1), y0, "DOP853", dense_output=True, rtol=1e-6,
                           atol=1e-9)
    assert_same_solve(empty, ref0, pendulum)


def test_solves_in_threads_are_independent(pendulum, chain):
    """The C core is reentrant and runs without the GIL: concurrent solves give the sequential
    results exactly."""
    from concurrent.futures import ThreadPoolExecutor
    jobs = [(pendulum, [0.1 * k, -0.2, 0.0, 0.1], m) for k in range(1, 4)
            for m in ("DOP853", "Radau", "BDF")]
    jobs += [(chain, [0.1, 0.0, 0.0, 0.0], "RK45")]

    def run(job):
        mod, y0, method = job
        return solve_native(mod, (0, 2), y0, method, rtol=1e-8, atol=1e-8)
    sequential = [run(j) for j in jobs]
    with ThreadPoolExecutor(4) as pool:
        parallel = list(pool.map(run, jobs))
    for a, b in zip(sequential, parallel):
        assert a.nfev == b.nfev and np.array_equal(a.y, b.y)


@pytest.mark.parametrize("method", ["Radau", "BDF"])
def test_tiny_rtol_is_clipped_like_scipy(pendulum, method):
    """rtol below 100 EPS is clipped with SciPy's warning; the Newton tolerance uses it as given.

    At rtol = 100 EPS the error estimates are rounding noise, so step times are only compared
    through the counts (equal decisions) and the states at the end."""
    y0 = [0.5, -0.3, 0.0, 0.4]
    with pytest.warns(UserWarning, match="rtol"):
        ref = scipy_reference(pendulum, (0, 0.3), y0, method, rtol=1e-16, atol=1e-12)
    with pytest.warns(UserWarning, match="rtol") as caught:
        ours = lagrgen.simulate(pendulum, (0, 0.3), y0, method=method, rtol=1e-16, atol=1e-12)
    assert not [w for w in caught if w.category is lagrgen.NearSingularMassMatrixWarning]
    assert counts_close((ours.nfev, ours.njev, ours.nlu, ours.t.size),
                        (ref.nfev, ref.njev, ref.nlu, ref.t.size))
    assert_allclose(ours.y[:, -1], ref.y[:, -1], rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("method", ["DOP853", "Radau", "BDF"])
def test_terminal_event_with_t_eval_and_dense_output(pendulum, events_address, method):
    _, address = events_address
    y0 = np.array([0.5, -0.3, 0.0, 0.4])

    def g0(t, y):
        return y[0]

    def g1(t, y):
        return y[1] - 0.1
    g0.terminal, g0.direction = 1, -1
    g1.terminal, g1.direction = False, 0
    t_eval = np.linspace(0, 6, 61)
    ref = scipy_reference(pendulum, (0, 6), y0, method, rtol=1e-8, atol=1e-8, events=[g0, g1],
                          t_eval=t_eval, dense_output=True)
    ours = solve_native(pendulum, (0, 6), y0, method, rtol=1e-8, atol=1e-8, t_eval=t_eval,
                        dense_output=True, events=(address, (1, False), (-1, 0)))
    assert ref.status == 1 and ref.t[-1] < ref.t_events[0][0] < 6
    assert_same_solve(ours, ref, pendulum)
    assert_allclose(ours.t_events[0], ref.t_events[0], rtol=1e-10)
    tt = np.linspace(0, ref.t_events[0][0], 50)
    assert_allclose(ours.sol(tt), ref.sol(tt), rtol=1e-9, atol=1e-10)


def test_stop_on_nonfinite(fading_mass):
    """p = k = inf makes every derivative non-finite: with stop_on_nonfinite the solve ends at the
    first one, naming t and the state; without it the method reacts as SciPy's would."""
    y0 = [1.0, 0.0]
    res = solve_native(fading_mass, (0, 0.5), y0, "RK45", p=[np.inf], stop_on_nonfinite=True)
    assert res.status == -1 and "not finite at t = 0" in res.message
    assert res.nfev == 1 and res.nonfinite_failure[0] == 0.0
    assert_allclose(res.nonfinite_failure[1], y0)
    with pytest.raises(ValueError, match="finite"):
        lagrgen.simulate(fading_mass, (0, 0.5), y0, params=[np.inf])
