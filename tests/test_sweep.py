"""Sweeps (issue 10 item 5): steady-state amplitudes of a driven oscillator against the forcing
frequency agree with the linear frequency response for a linear model; the CLI writes the table."""
import csv

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model
from lagrgen.sweep import sweep

from conftest import EXAMPLES


def linear_oscillator():
    model = Model("sweep_linear")
    x, = model.coordinates("x")
    m, c, k = model.parameters(m=1.0, c=0.4, k=4.0)
    F, = model.inputs("F")
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    model.damper(c, x)
    model.generalized_force(x, F)
    return model


@pytest.fixture(scope="module")
def linear(compile_once):
    return compile_once(linear_oscillator())


def test_a_linear_sweep_is_the_frequency_response(linear):
    omegas = np.linspace(0.5, 4.0, 8)
    amplitude = 0.2
    result = sweep(linear, "w", omegas, (0.0, 80.0),
                   inputs=lambda w: {"F": lambda t, w=w: amplitude * np.sin(w * t)},
                   settle=0.6, samples=3000, method="DOP853", rtol=1e-9, atol=1e-12)
    H = lagrgen.frequency_response(linear, [0.0], omegas / (2 * np.pi), input="F")
    assert result.success.all()
    assert_allclose(result.column("x"), amplitude * np.abs(H[:, 0]), rtol=2e-3)


def test_sweeping_a_parameter(linear):
    result = sweep(linear, "k", [1.0, 4.0, 9.0], (0.0, 5.0), y0=[1.0, 0.0], measure="final",
                   params={"c": 0.0}, method="DOP853", rtol=1e-10, atol=1e-12)
    assert_allclose(result.table[:, 0], np.cos(np.sqrt([1.0, 4.0, 9.0]) * 5.0), atol=1e-6)
    with pytest.raises(ValueError, match="not a parameter"):
        sweep(linear, "w", [1.0], (0.0, 1.0))
    with pytest.raises(ValueError, match="unknown measure"):
        sweep(linear, "k", [1.0], (0.0, 1.0), measure="rms")


def test_the_sweep_command_writes_the_table_and_a_plot(tmp_path, capsys, monkeypatch):
    from lagrgen.cli import main
    monkeypatch.chdir(tmp_path)
    status = main(["sweep", str(EXAMPLES / "duffing.py"), "--param", "w=0.8:1.2:3",
                   "--input", "F=A*sin(w*t)", "--params", "A=0.05", "--t-end", "60",
                   "--linear", "0.05", "--csv", "out.csv", "--plot", "out.png", "--out", "gen"])
    assert status == 0
    rows = list(csv.reader(open(tmp_path / "out.csv")))
    assert rows[0] == ["w", "x_amplitude"] and len(rows) == 4
    amplitudes = [float(r[1]) for r in rows[1:]]
    assert amplitudes[1] > amplitudes[0] and amplitudes[1] > amplitudes[2]
    assert (tmp_path / "out.png").stat().st_size > 1000
    assert main(["sweep", str(EXAMPLES / "duffing.py"), "--param", "q=0:1:3", "--t-end", "1",
                 "--out", "gen"]) == 1
    assert "not a parameter" in capsys.readouterr().err
