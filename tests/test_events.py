"""Compiled events (API.md §8): model.event expressions located natively and by solve_ivp alike."""
import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model, ModelError

from conftest import counts_close


def falling_ball():
    model = Model("falling_ball")
    x, y = model.coordinates("x y")
    m, g = model.parameters(m=1.0, g=9.81)
    model.particle(m, sp.Matrix([x, y]))
    model.potential_energy(m * g * y)
    model.event("hits_floor", y, terminal=True, direction=-1)
    model.event("crosses_x1", x - 1, terminal=False, direction=0)
    return model


@pytest.fixture(scope="module")
def ball(compile_once):
    return compile_once(falling_ball())


def test_compiled_events_on_both_engines_and_backends(ball):
    py = lagrgen.build(falling_ball(), backend="python")
    y0 = {"y": 2.0, "x_dot": 2.0}
    t_hit = np.sqrt(2 * 2.0 / 9.81)
    results = [lagrgen.simulate(ball, (0, 5), y0, method="DOP853", rtol=1e-10, atol=1e-12),
               lagrgen.simulate(ball, (0, 5), y0, method="DOP853", rtol=1e-10, atol=1e-12,
                                engine="scipy"),
               lagrgen.simulate(py, (0, 5), y0, method="DOP853", rtol=1e-10, atol=1e-12)]
    assert [r.engine for r in results] == ["native", "scipy", "scipy"]
    for sol in results:
        assert sol.status == 1 and sol.event_names == ("hits_floor", "crosses_x1")
        assert_allclose(sol.t_events[0], [t_hit], rtol=1e-9)
        assert_allclose(sol.t_events[1], [0.5], rtol=1e-9)
        assert sol.t[-1] == pytest.approx(t_hit, rel=1e-9)
        assert_allclose(sol.y_events[0][0][1], 0.0, atol=1e-9)
    assert counts_close(results[0].nfev, results[1].nfev)
    assert_allclose(ball.events(0.0, [0.3, 2.0, 0, 0]), [2.0, -0.7])
    assert_allclose(py.events(0.0, [0.3, 2.0, 0, 0]), [2.0, -0.7])


def test_a_model_without_events_has_none(compile_once):
    model = Model("no_events")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    mod = compile_once(model)
    assert mod.events(0.0, [0.0, 0.0]).shape == (0,) and mod.event_definitions == ()
    assert not hasattr(lagrgen.simulate(mod, (0, 1), [0, 1]), "event_names")


def test_bad_events_are_refused():
    model = Model("bad_events")
    x, = model.coordinates("x")
    model.event("e", x)
    for args, message in [(("e", x), "already declared"), (("f", x, False, 2), "direction"),
                          (("g", x, -1), "terminal"), (("h", sp.Matrix([x, x])), "scalar"),
                          (("1x", x), "invalid event")]:
        with pytest.raises(ModelError, match=message):
            model.event(*args)
