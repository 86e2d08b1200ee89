"""Model declarations, and every bad input refused with the documented exception and a message that
says what is wrong.

ModelError (a ValueError) for bad model descriptions, UnknownNameError (ValueError and KeyError) for
unknown run-time names, ValueError for arrays of the wrong length or missing parameter values, and
MassMatrixError (a numpy.linalg.LinAlgError) for a mass matrix that is not positive definite.
"""
import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import MassMatrixError, Model, ModelError, UnknownNameError
from conftest import example_model


def oscillator(name="oscillator"):
    """x with T = ½mẋ², V = ½kx², input force f: mẍ = −kx + f."""
    model = Model(name)
    x, = model.coordinates("x")
    m, k = model.parameters(m=1.0, k=4.0)
    f, = model.inputs("f")
    model.particle(m, x)
    model.spring(k, x)
    model.generalized_force(x, f)
    return model


OSCILLATOR = oscillator()


@pytest.fixture(scope="module")
def double_pendulum(build):
    return build(example_model("double_pendulum"))


@pytest.fixture(scope="module")
def osc(build):
    return build(OSCILLATOR)


# -- declarations ------------------------------------------------------------------------------

def test_coordinates_and_inputs_accept_a_list_or_a_string_and_return_tuples():
    model = Model("declarations")
    pair = model.coordinates(["a", "b"])
    single = model.coordinates("c")
    inputs = model.inputs(["u1", "u2"])
    assert all(isinstance(r, tuple) for r in (pair, single, inputs))
    assert (len(pair), len(single), len(inputs)) == (2, 1, 2)
    assert pair[0] == sp.Function("a")(model.t) and single[0] == sp.Function("c")(model.t)
    assert inputs[1] == sp.Function("u2")(model.t)


def test_parameters_called_several_times_append_in_order(build):
    model = Model("several_calls")
    x, = model.coordinates("x")
    first = model.parameters(a=1.0)
    second = model.parameters(b=2.0, c=3.0)
    third = model.parameters("d")
    assert first == (sp.Symbol("a"),) and second == (sp.Symbol("b"), sp.Symbol("c"))
    assert third == (sp.Symbol("d"),)
    model.particle(first[0] + second[0] + second[1] + third[0], x)
    mod = build(model)
    assert mod.parameters == ("a", "b", "c", "d")
    assert_allclose(mod.defaults[:3], [1.0, 2.0, 3.0])
    assert mod.mass_matrix([0.0], p=[1.0, 2.0, 3.0, 4.0])[0, 0] == pytest.approx(10.0)


def test_parameters_without_defaults_take_names_as_coordinates_do():
    model = Model("positional_names")
    assert model.parameters("m k") == (sp.Symbol("m"), sp.Symbol("k"))
    assert model.parameters("c", "d, e", g=9.81) == tuple(sp.symbols("c d e g"))
    assert model.parameter_names == ("m", "k", "c", "d", "e", "g")
    with pytest.raises(ModelError, match="parameter"):
        model.parameters(3)
    with pytest.raises(ModelError, match="already"):
        model.parameters("m")


@pytest.fixture(scope="module")
def no_default(build):
    """mẍ = −kx with k declared without a default."""
    model = Model("no_default")
    x, = model.coordinates("x")
    m, = model.parameters(m=1.0)
    k, = model.parameters("k")
    model.particle(m, x)
    model.spring(k, x)
    return build(model)


def test_parameter_without_default_must_be_given(no_default):
    with pytest.raises(ValueError, match="k"):
        no_default.rhs(0.0, [1.0, 0.0])
    with pytest.raises(ValueError, match="default"):
        lagrgen.simulate(no_default, (0.0, 1.0), [1.0, 0.0])


def test_parameter_without_default_given_at_run_time(no_default):
    """With k = 4, m = 1: x(t) = cos 2t, by dict and by full array."""
    t = np.linspace(0.0, 3.0, 7)
    for params in ({"k": 4.0}, np.array([1.0, 4.0])):
        sol = lagrgen.simulate(no_default, (0.0, 3.0), [1.0, 0.0], method="DOP853", params=params,
                               rtol=1e-11, atol=1e-12, t_eval=t)
        assert_allclose(sol.y[0], np.cos(2 * t), atol=1e-8)


# -- invalid and duplicate names ---------------------------------------------------------------

@pytest.mark.parametrize("declare", [
    lambda m: Model("1x"),
    lambda m: m.coordinates("1x"),
    lambda m: m.coordinates(["ok", "a b"]),
    lambda m: m.coordinates("lambda"),
    lambda m: m.parameters(**{"lambda": 1.0}),
    lambda m: m.parameters(**{"a-b": 1.0}),
    lambda m: m.inputs(["for"]),
], ids=["model 1x", "coordinate 1x", "coordinate 'a b'", "coordinate lambda", "parameter lambda",
        "parameter a-b", "input for"])
def test_invalid_names_are_refused(declare):
    with pytest.raises(ModelError, match="invalid"):
        declare(Model("names"))


def test_invalid_name_error_is_a_value_error():
    with pytest.raises(ValueError, match="identifier"):
        Model("names").coordinates("1x")


@pytest.mark.parametrize("declare", [
    lambda m: (m.coordinates("x"), m.parameters(x=1.0)),
    lambda m: (m.parameters(x=1.0), m.coordinates("x")),
    lambda m: m.coordinates("x x"),
    lambda m: (m.coordinates("x"), m.coordinates(["x"])),
    lambda m: (m.parameters(k=1.0), m.inputs("k")),
    lambda m: (m.parameters(k=1.0), m.parameters(k=2.0)),
    lambda m: m.coordinates("t"),
], ids=["coordinate then parameter", "parameter then coordinate", "repeated coordinate",
        "coordinate twice", "parameter then input", "parameter twice", "time"])
def test_duplicate_names_are_refused(declare):
    with pytest.raises(ModelError, match="already used"):
        declare(Model("duplicates"))


# -- models that cannot be derived -------------------------------------------------------------

def coordinate_free_model():
    model = Model("empty")
    m, g = model.parameters(m=1.0, g=9.81)
    model.potential_energy(m * g)
    return model


def test_no_coordinates_at_mass_matrix():
    with pytest.raises(ModelError, match="no generalized coordinates"):
        coordinate_free_model().mass_matrix()


def test_no_coordinates_at_build(backend, tmp_path):
    with pytest.raises(ModelError, match="no generalized coordinates"):
        lagrgen.build(coordinate_free_model(), backend=backend, out_dir=tmp_path)


k = sp.Symbol("k")


@pytest.mark.parametrize("add", [
    lambda m, x: m.particle(k, x),
    lambda m, x: m.particle(1, sp.Matrix([x, k])),
    lambda m, x: m.rigid_body(1, k, x, x),
    lambda m, x: m.kinetic_energy(k * x.diff(m.t)**2),
    lambda m, x: m.potential_energy(k * x**2),
    lambda m, x: m.spring(k, x),
    lambda m, x: m.spring(1, x, rest=k),
    lambda m, x: m.damper(k, x),
    lambda m, x: m.dissipation(k * x.diff(m.t)**2),
    lambda m, x: m.force(sp.Matrix([k, 0]), at=sp.Matrix([x, 0])),
    lambda m, x: m.force(sp.Matrix([1, 0]), at=sp.Matrix([x, k])),
    lambda m, x: m.torque(k, x),
    lambda m, x: m.generalized_force(x, k),
], ids=["particle mass", "particle position", "inertia", "kinetic energy", "potential energy",
        "spring", "spring rest", "damper", "dissipation", "force vector", "force point", "torque",
        "generalized force"])
def test_undeclared_symbol_is_refused(add):
    model = Model("undeclared")
    x, = model.coordinates("x")
    with pytest.raises(ModelError, match="symbol k is neither"):
        add(model, x)


@pytest.mark.parametrize("add, message", [
    (lambda m, x: m.particle(1, sp.Function("y")(m.t)), "neither a coordinate nor an input"),
    (lambda m, x: m.potential_energy(sp.gamma(x)), "not supported"),
    (lambda m, x: m.particle(1, x + sp.Function("u")(m.t)), "must not depend on input"),
    (lambda m, x: m.force(x.diff(m.t, 2), at=x), "not allowed"),
    (lambda m, x: m.potential_energy(x.diff(m.t)**2), "must not depend on velocities"),
    (lambda m, x: m.generalized_force("nope", 1), "not a generalized coordinate"),
], ids=["unknown function", "unsupported function", "input in position", "acceleration",
        "velocity in V", "unknown coordinate"])
def test_other_bad_expressions_are_refused(add, message):
    model = Model("bad_expressions")
    x, = model.coordinates("x")
    model.inputs("u")
    with pytest.raises(ModelError, match=message):
        add(model, x)


# -- run-time names and array lengths ----------------------------------------------------------

@pytest.mark.parametrize("kwargs", [{"params": {"nope": 1.0}}, {"inputs": {"nope": 0.0}}],
                         ids=["parameter", "input"])
def test_unknown_run_time_names(double_pendulum, kwargs):
    with pytest.raises(UnknownNameError, match="nope") as info:
        lagrgen.simulate(double_pendulum, (0.0, 0.1), [0.1, 0.0, 0.0, 0.0], **kwargs)
    assert isinstance(info.value, KeyError) and isinstance(info.value, ValueError)
    known = "m1" if "params" in kwargs else "F"
    assert known in str(info.value)


@pytest.mark.parametrize("call", [
    lambda mod: mod.rhs(0.0, [0.1, 0.2, 0.3]),
    lambda mod: mod.rhs(0.0, np.zeros(5)),
    lambda mod: mod.rhs(0.0, np.zeros(4), p=np.ones(4)),
    lambda mod: mod.rhs(0.0, np.zeros(4), u=np.ones(2)),
    lambda mod: mod.rhs(0.0, np.zeros((2, 2))),
    lambda mod: mod.mass_matrix([0.1]),
    lambda mod: mod.mass_matrix([0.1, 0.2], p=[1.0]),
    lambda mod: mod.forcing([0.1, 0.2], [0.0]),
    lambda mod: mod.forcing([0.1, 0.2, 0.3], [0.0, 0.0]),
    lambda mod: mod.jacobian(0.0, np.zeros(3)),
    lambda mod: mod.jacobian(0.0, np.zeros(4), u=[]),
    lambda mod: lagrgen.simulate(mod, (0.0, 1.0), [0.1, 0.2]),
    lambda mod: lagrgen.simulate(mod, (0.0, 1.0), np.zeros(4), params=np.ones(6)),
], ids=["rhs y short", "rhs y long", "rhs p", "rhs u", "rhs y 2-D", "mass_matrix q", "mass_matrix p",
        "forcing qd", "forcing q", "jacobian y", "jacobian u", "simulate y0", "simulate p"])
def test_wrong_array_lengths(double_pendulum, call):
    with pytest.raises(ValueError, match="length|shape"):
        call(double_pendulum)


def test_unknown_method(osc):
    with pytest.raises(ValueError, match="RK45"):
        lagrgen.simulate(osc, (0.0, 1.0), [1.0, 0.0], method="Euler")


# -- mass matrices that are not positive definite ----------------------------------------------

@pytest.mark.parametrize("call", [
    lambda mod: mod.rhs(0.0, [0.5, 0.0], p=[-1.0, 4.0]),
    lambda mod: mod.jacobian(0.0, [0.5, 0.0], p=[-1.0, 4.0]),
    lambda mod: lagrgen.simulate(mod, (0.0, 1.0), [0.5, 0.0], params={"m": -1.0}),
    lambda mod: lagrgen.simulate(mod, (0.0, 1.0), [0.5, 0.0], method="Radau",
                                 params=[0.0, 4.0]),
], ids=["rhs", "jacobian", "simulate", "simulate zero mass"])
def test_mass_matrix_not_positive_definite(osc, call):
    with pytest.raises(MassMatrixError, match="not positive definite") as info:
        call(osc)
    assert isinstance(info.value, np.linalg.LinAlgError)


def test_negative_mass_still_evaluates_the_mass_matrix(osc):
    """mass_matrix itself just evaluates M; only solving with it needs positive definiteness."""
    assert_allclose(osc.mass_matrix([0.5], p=[-1.0, 4.0]), [[-1.0]])


def test_dependent_coordinates_give_a_singular_mass_matrix(build):
    """One particle at x + y: M = m·[[1, 1], [1, 1]] is singular for every state."""
    model = Model("dependent")
    x, y = model.coordinates("x y")
    m, = model.parameters(m=1.0)
    model.particle(m, x + y)
    mod = build(model)
    assert_allclose(mod.mass_matrix([0.0, 0.0]), [[1.0, 1.0], [1.0, 1.0]])
    with pytest.raises(MassMatrixError, match="not positive definite"):
        mod.rhs(0.0, [0.1, 0.2, 0.0, 0.0])


@pytest.mark.parametrize("name", ["pendule_é", "lagrgen"])
def test_model_names_must_make_importable_modules(name):
    with pytest.raises(ModelError, match="model"):
        Model(name)
    with pytest.raises(ModelError, match="model"):
        lagrgen.load(name)
