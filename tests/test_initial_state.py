"""Issue 28.15: a model carries its own initial state (`model.initial_state(q=..., qd=...)`),
kept in its ModelInfo (so a loaded model has it), used by `simulate`, `simulate_many` and `sweep`
when y0 is omitted (y0 stays the third positional argument), by the command line and as the
FMU's start values; the slider-crank example starts turning."""
import csv

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model, ModelError

from conftest import EXAMPLES

START = [0.4, -0.2, 0.0, 1.5]


def two_springs(name="with_start"):
    model = Model(name)
    x, y = model.coordinates("x y")
    k, = model.parameters(k=4.0)
    model.particle(1, sp.Matrix([x, y]))
    model.spring(k, x)
    model.spring(k, y)
    model.initial_state(q={"x": 0.4, y: -0.2}, qd=[0.0, 1.5])
    return model


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("initial_state")
    model = two_springs()
    return model, out, [lagrgen.build(model, backend="python"), lagrgen.build(model, out_dir=out)]


def test_the_declared_state_is_kept_by_both_backends_and_a_loaded_model(built):
    model, out, mods = built
    assert model.initial_values == tuple(START)
    for mod in [*mods, lagrgen.load("with_start", out_dir=out)]:
        assert_allclose(mod.initial_state, START, rtol=0)
        assert not mod.initial_state.flags.writeable


def test_simulate_starts_from_it_when_y0_is_omitted(built):
    _, _, mods = built
    for mod in mods:
        omitted = lagrgen.simulate(mod, (0.0, 1.0), rtol=1e-9, atol=1e-12)
        given = lagrgen.simulate(mod, (0.0, 1.0), START, "RK45", rtol=1e-9, atol=1e-12)
        assert_allclose(omitted.y[:, 0], START, rtol=0)
        assert_allclose(omitted.y[:, -1], given.y[:, -1], rtol=0, atol=0)
        assert_allclose(omitted.y[0, -1], 0.4 * np.cos(2.0), rtol=1e-7)
    ens = lagrgen.simulate_many(mods[1], (0.0, 1.0), params=[{"k": 4.0}, {"k": 9.0}],
                                t_eval=[0.0, 1.0], rtol=1e-9, atol=1e-12)
    assert_allclose(ens.y[:, :, 0], [START, START], rtol=0)
    assert_allclose(ens.y[0, 0, -1], 0.4 * np.cos(2.0), rtol=1e-7)
    swept = lagrgen.sweep(mods[1], "k", [4.0], (0.0, 1.0), measure="final", settle=0.0,
                          samples=5, rtol=1e-9, atol=1e-12)
    assert_allclose(swept.table[0, 0], 0.4 * np.cos(2.0), rtol=1e-7)


def test_a_model_without_one_starts_at_rest_at_zero():
    model = Model("no_start")
    x, = model.coordinates("x")
    model.particle(1, sp.Matrix([x]))
    mod = lagrgen.build(model, backend="python")
    assert model.initial_values == () and list(mod.initial_state) == [0.0, 0.0]
    assert lagrgen.simulate(mod, (0.0, 1.0)).y[:, -1].tolist() == [0.0, 0.0]


def test_a_bad_initial_state_is_a_model_error():
    model = two_springs("bad_start")
    with pytest.raises(ModelError, match="'z' is not a coordinate of model 'bad_start'"):
        model.initial_state(q={"z": 1.0})
    with pytest.raises(ModelError, match="give a dict of coordinate names or 2 numbers"):
        model.initial_state(qd=[1.0])
    with pytest.raises(ModelError, match=r"initial_state q\['x'\] must be finite"):
        model.initial_state(q={"x": float("nan")})
    with pytest.raises(ModelError, match=r"must be a number, got .*theta"):
        model.initial_state(q={"x": sp.Symbol("theta")})


def test_fmu_start_values_are_the_initial_state(built, tmp_path):
    fmpy = pytest.importorskip("fmpy")
    model = built[0]
    path = lagrgen.export_fmu(model, tmp_path)
    md = fmpy.read_model_description(str(path))
    start = {v.name: float(v.start) for v in md.modelVariables
             if v.name in ("x", "y", "x_dot", "y_dot")}
    assert start == dict(zip(("x", "y", "x_dot", "y_dot"), START))
    run = fmpy.simulate_fmu(str(path), stop_time=0.1, output_interval=0.05, output=["x", "y"],
                            apply_default_start_values=False)
    assert (run["x"][0], run["y"][0]) == (0.4, -0.2)


def test_the_slider_crank_example_turns_on_the_command_line(tmp_path):
    from lagrgen.cli import main
    out = tmp_path / "run.csv"
    assert main(["simulate", str(EXAMPLES / "slider_crank.py"), "--t-end", "0.5",
                 "--backend", "python", "--samples", "11", "--csv", str(out), "--quiet"]) == 0
    rows = list(csv.reader(out.open()))
    th = [float(row[1]) for row in rows[1:]]
    assert rows[0][1].startswith("th") and th[0] == pytest.approx(np.pi / 3)
    assert th[-1] - th[0] == pytest.approx(np.pi, rel=0.05)        # half a turn in 0.5 s
