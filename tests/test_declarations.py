"""Issue 28.12: what a model declares is refused at declaration when it can only fail later —
an event count beyond a C int, a name that clashes with a velocity name `<coordinate>_dot`, a
Piecewise without an otherwise branch — and an overflowing mass matrix is reported as an
overflow, not as a mass matrix that is not positive definite."""
import numpy as np
import pytest
import sympy as sp

import lagrgen
from lagrgen import Model, ModelError, NonFiniteError


def spring_mass(name, mass=1.0):
    model = Model(name)
    x, = model.coordinates("x")
    m, k = model.parameters(m=mass, k=4.0)
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    return model, x, m


def test_an_event_count_beyond_a_c_int_is_refused():
    model, x, _ = spring_mass("event_count")
    with pytest.raises(ModelError, match=r"terminal must be .* from 0 to 2147483647, got "
                                         r"9223372036854775808"):
        model.event("cross", x, terminal=2**63)
    model.event("cross", x, terminal=2**31 - 1)


@pytest.mark.parametrize("kind", ["parameters", "inputs", "output", "constraint"])
def test_a_name_beside_a_coordinate_that_reads_as_its_velocity_is_refused(kind):
    model, x, _ = spring_mass(f"dot_clash_{kind}")
    declare = {"parameters": lambda: model.parameters(x_dot=1.0),
               "inputs": lambda: model.inputs("x_dot"),
               "output": lambda: model.output("x_dot", x),
               "constraint": lambda: model.constraint(x - 1, name="x_dot")}[kind]
    with pytest.raises(ModelError, match=r"'x_dot' clashes with the velocity name 'x_dot' of "
                                         r"coordinate 'x'"):
        declare()


def test_a_coordinate_declared_after_its_velocity_name_is_refused():
    model = Model("dot_clash_later")
    model.parameters(y_dot=2.0)
    with pytest.raises(ModelError, match=r"coordinate name 'y' clashes with the velocity name "
                                         r"'y_dot' of coordinate 'y'.*rename the parameter"):
        model.coordinates("y")
    model.coordinates("x")
    with pytest.raises(ModelError, match="rename the coordinate"):
        model.coordinates("x_dot")


def test_a_piecewise_without_an_otherwise_branch_is_refused():
    model, x, _ = spring_mass("piecewise_open")
    with pytest.raises(ModelError, match=r"no branch for when no condition holds .*"
                                         r"\(value, True\)"):
        model.generalized_force(x, sp.Piecewise((1.0, x > 0)))
    model.generalized_force(x, sp.Piecewise((1.0, x > 0), (0.0, True)))


@pytest.mark.parametrize("backend", ["python", "c"])
def test_an_overflowing_mass_matrix_is_reported_as_an_overflow(backend, tmp_path):
    model, x, m = spring_mass(f"overflow_{backend}", mass=1e300)
    model.particle(m * m, sp.Matrix([x]))
    mod = lagrgen.build(model, backend=backend, out_dir=tmp_path)
    with pytest.raises(NonFiniteError, match="mass matrix .* not finite .* overflows"):
        mod.rhs(0.0, [1.0, 0.0])
    with pytest.raises(NonFiniteError, match="overflows"):
        lagrgen.simulate(mod, (0, 1), [1.0, 0.0])
    with pytest.raises(NonFiniteError, match="overflows"):
        lagrgen.modes(mod, [0.0])
    with pytest.raises(NonFiniteError, match="overflows"):
        lagrgen.linearize(mod, [0.0]).state_space()
    assert np.isfinite(mod.rhs(0.0, [1.0, 0.0], p=[1.0, 4.0])).all()
