"""`lagrgen.simulate`: every solve_ivp method, parameters and inputs in every accepted form, the
options it passes through to SciPy, and the analytic Jacobian handed to the stiff methods.

References are DOP853 at rtol = atol = 1e-12 or SciPy's `solve_ivp` called directly on `mod.rhs`.
"""
import numpy as np
import scipy.integrate
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

import lagrgen
from conftest import example_model

METHODS = ["RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA"]
Y0 = [0.5, -0.3, 0.0, 0.4]
SPAN = (0.0, 2.0)
T_EVAL = np.linspace(0.0, 2.0, 21)


@pytest.fixture(scope="module")
def pendulum(build):
    return build(example_model("double_pendulum"))


@pytest.fixture(scope="module")
def reference(pendulum):
    """The double pendulum from Y0 under DOP853 at rtol = atol = 1e-12, on T_EVAL."""
    return lagrgen.simulate(pendulum, SPAN, Y0, method="DOP853", rtol=1e-12, atol=1e-12,
                            t_eval=T_EVAL)


class CountingJacobian:
    """A built model whose `jacobian` calls are counted (everything else is the model's own)."""

    def __init__(self, mod):
        self._mod = mod
        self.calls = 0

    def __getattr__(self, name):
        return getattr(self._mod, name)

    def jacobian(self, *args):
        self.calls += 1
        return self._mod.jacobian(*args)


@pytest.mark.parametrize("method", METHODS)
def test_every_method_agrees_with_dop853(pendulum, reference, method):
    sol = lagrgen.simulate(pendulum, SPAN, Y0, method=method, rtol=1e-10, atol=1e-12,
                           t_eval=T_EVAL)
    assert sol.success, sol.message
    assert_allclose(sol.t, T_EVAL)
    assert_allclose(sol.y, reference.y, rtol=0, atol=1e-6)
    assert np.ptp(reference.y[0]) > 0.5


@pytest.mark.parametrize("method", ["Radau", "BDF"])
def test_stiff_methods_use_the_analytic_jacobian(pendulum, method):
    counted = CountingJacobian(pendulum)
    sol = lagrgen.simulate(counted, SPAN, Y0, method=method, rtol=1e-8, atol=1e-10)
    assert sol.success
    assert sol.njev > 0
    assert counted.calls == sol.njev


@pytest.mark.parametrize("method", [scipy.integrate.Radau, scipy.integrate.BDF])
def test_a_stiff_solver_class_also_gets_the_analytic_jacobian(pendulum, method):
    counted = CountingJacobian(pendulum)
    sol = lagrgen.simulate(counted, SPAN, Y0, method=method, rtol=1e-8, atol=1e-10)
    assert sol.success and sol.njev > 0
    assert counted.calls == sol.njev


def test_radau_and_bdf_take_the_same_steps_as_scipys(pendulum):
    """lagrgen.solvers only replaces SciPy's checked LU wrappers: identical steps and results."""
    p = np.asarray(pendulum.defaults)
    u = np.zeros(len(pendulum.inputs))
    for name in ("Radau", "BDF"):
        ours = lagrgen.simulate(pendulum, SPAN, Y0, method=name, rtol=1e-8, atol=1e-10,
                                engine="scipy")
        scipys = scipy.integrate.solve_ivp(
            lambda t, y: pendulum.rhs(t, y, p, u), SPAN, Y0, method=name, rtol=1e-8, atol=1e-10,
            jac=lambda t, y: pendulum.jacobian(t, y, p, u))
        assert (ours.nfev, ours.njev, ours.nlu) == (scipys.nfev, scipys.njev, scipys.nlu)
        assert_allclose(ours.y, scipys.y, rtol=1e-13, atol=1e-13)


STIFF = dict(params={"k1": 1e6, "c1": 1e4}, inputs={"f": 1.0})


@pytest.fixture(scope="module")
def stiff_chain(build):
    """two_mass_absolute with k1 = 1e6, c1 = 1e4: modes at −1e4 and −1e2 1/s beside a 7 rad/s
    oscillation, stiff (RK45 needs ~6e4 evaluations where BDF needs ~1e3)."""
    return build(example_model("two_mass_chain", "absolute"))


@pytest.fixture(scope="module")
def stiff_reference(stiff_chain):
    return lagrgen.simulate(stiff_chain, (0.0, 3.0), [0.0, 0.1, 0.0, 0.0], method="Radau",
                            rtol=1e-11, atol=1e-13, **STIFF)


@pytest.mark.parametrize("method", ["Radau", "BDF", "LSODA"])
def test_stiff_problem_uses_the_analytic_jacobian(stiff_chain, stiff_reference, method):
    """Even LSODA switches to its stiff solver here and calls the Jacobian; every stiff method
    takes far fewer steps than an explicit one would and matches the tight Radau solution."""
    counted = CountingJacobian(stiff_chain)
    sol = lagrgen.simulate(counted, (0.0, 3.0), [0.0, 0.1, 0.0, 0.0], method=method, rtol=1e-8,
                           atol=1e-10, **STIFF)
    assert sol.success and counted.calls > 0 and sol.njev > 0
    assert sol.nfev < 10000
    assert_allclose(sol.y[:, -1], stiff_reference.y[:, -1], atol=1e-6)


@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_explicit_methods_do_not_need_the_jacobian(pendulum, method):
    counted = CountingJacobian(pendulum)
    lagrgen.simulate(counted, (0.0, 0.5), Y0, method=method)
    assert counted.calls == 0


def test_params_by_dict_and_by_full_array(pendulum):
    """{"m2": 2, "L1": 0.8} (the rest default) and the full array give one solution, unlike the
    defaults."""
    p = np.array(pendulum.defaults, dtype=float)
    p[list(pendulum.parameters).index("m2")] = 2.0
    p[list(pendulum.parameters).index("L1")] = 0.8
    run = dict(method="DOP853", rtol=1e-10, atol=1e-12, t_eval=T_EVAL)
    by_dict = lagrgen.simulate(pendulum, SPAN, Y0, params={"m2": 2.0, "L1": 0.8}, **run)
    by_array = lagrgen.simulate(pendulum, SPAN, Y0, params=p, **run)
    by_list = lagrgen.simulate(pendulum, SPAN, Y0, params=list(p), **run)
    default = lagrgen.simulate(pendulum, SPAN, Y0, **run)
    assert_allclose(by_dict.y, by_array.y, rtol=1e-13, atol=1e-13)
    assert_allclose(by_list.y, by_array.y, rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(by_dict.y - default.y)) > 1e-2


def test_default_params_are_the_defaults(pendulum):
    run = dict(method="RK45", t_eval=T_EVAL)
    none = lagrgen.simulate(pendulum, SPAN, Y0, **run)
    empty = lagrgen.simulate(pendulum, SPAN, Y0, params={}, **run)
    array = lagrgen.simulate(pendulum, SPAN, Y0, params=pendulum.defaults, **run)
    assert_allclose(none.y, empty.y, rtol=1e-14, atol=0)
    assert_allclose(none.y, array.y, rtol=1e-14, atol=0)


def test_constant_input_as_value_or_as_callable(pendulum):
    run = dict(method="DOP853", rtol=1e-10, atol=1e-12, t_eval=T_EVAL)
    value = lagrgen.simulate(pendulum, SPAN, Y0, inputs={"F": 0.5}, **run)
    function = lagrgen.simulate(pendulum, SPAN, Y0, inputs={"F": lambda t: 0.5}, **run)
    free = lagrgen.simulate(pendulum, SPAN, Y0, **run)
    assert_allclose(value.y, function.y, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(value.y - free.y)) > 1e-2


def test_time_varying_input_matches_solve_ivp(pendulum):
    """inputs={"F": sin 3t} is the same as solve_ivp on rhs(t, y, p, [sin 3t])."""
    run = dict(method="DOP853", rtol=1e-10, atol=1e-12, t_eval=T_EVAL)
    sol = lagrgen.simulate(pendulum, SPAN, Y0, inputs={"F": lambda t: np.sin(3 * t)}, **run)
    ref = solve_ivp(lambda t, y: pendulum.rhs(t, y, None, [np.sin(3 * t)]), SPAN, Y0, **run)
    assert_allclose(sol.y, ref.y, rtol=1e-12, atol=1e-12)


def test_mixed_constant_and_callable_inputs(build):
    """cart_pendulum with P constant and Fc(t) = t: the same as solve_ivp with u = [P, t]."""
    mod = build(example_model("cart_pendulum"))
    y0 = [0.0, 0.3, 0.0, 0.0]
    run = dict(method="RK45", rtol=1e-9, atol=1e-11, t_eval=np.linspace(0.0, 1.5, 16))
    sol = lagrgen.simulate(mod, (0.0, 1.5), y0, inputs={"Fc": lambda t: t, "P": 2.0}, **run)
    ref = solve_ivp(lambda t, y: mod.rhs(t, y, None, [2.0, t]), (0.0, 1.5), y0, **run)
    assert_allclose(sol.y, ref.y, rtol=1e-12, atol=1e-12)
    assert sol.y[0, -1] > 0.1


def test_t_eval_is_passed_through(pendulum):
    t_eval = np.array([0.0, 0.1, 0.7, 1.3, 2.0])
    sol = lagrgen.simulate(pendulum, SPAN, Y0, t_eval=t_eval)
    np.testing.assert_array_equal(sol.t, t_eval)
    assert sol.y.shape == (4, 5)


def test_dense_output_is_passed_through(pendulum, reference):
    sol = lagrgen.simulate(pendulum, SPAN, Y0, method="DOP853", rtol=1e-12, atol=1e-12,
                           dense_output=True)
    assert sol.sol is not None
    assert_allclose(sol.sol(T_EVAL), reference.y, atol=1e-9)


def test_events_are_passed_through(pendulum):
    """θ1 = 0 is crossed; as a terminal event the integration stops there."""
    def upright(t, y):
        return y[0]
    upright.terminal = True
    sol = lagrgen.simulate(pendulum, SPAN, Y0, method="DOP853", rtol=1e-10, atol=1e-12,
                           events=upright)
    assert sol.status == 1
    assert len(sol.t_events[0]) == 1
    assert sol.t[-1] == pytest.approx(sol.t_events[0][0])
    assert abs(sol.y_events[0][0][0]) < 1e-8
    assert 0.0 < sol.t_events[0][0] < SPAN[1]


def test_other_options_go_to_solve_ivp(pendulum):
    sol = lagrgen.simulate(pendulum, (0.0, 1.0), Y0, method="RK45", max_step=0.01)
    assert len(sol.t) > 100
    assert np.all(np.diff(sol.t) <= 0.01 + 1e-12)
