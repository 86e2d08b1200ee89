"""Issues 28.10, 28.14 and 32.5: what users type and hand to the command line is read within
limits, with one-line errors. The expression reader limits depth, arity and numbers to a double;
sweeps limit their count (and run in chunks of bounded memory); `fit` refuses a record that
lacks a coordinate unless --y0 gives it and takes --weights, --inputs and --bounds; the CSV
reader accepts a byte-order mark and reports an over-long field or non-UTF-8 bytes in one line."""
import csv

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen import Model
from lagrgen.cli import main
from lagrgen.expressions import ExpressionError, parse_number, parse_time_function

from conftest import EXAMPLES, example_model

CHAIN = str(EXAMPLES / "two_mass_chain.py")


# -- 28.10: the expression reader and sweeps --------------------------------------------------
@pytest.mark.parametrize("text, message", [
    ("-" * 1999 + "1", "nested too deeply"),
    ("+".join(["t"] * 500), "nested too deeply"),
    ("min(t)", r"min\(\) takes 2 or more arguments, got 1"),
    ("atan2(t)", r"atan2\(\) takes 2 arguments, got 1"),
    ("sin(t, t)", r"sin\(\) takes 1 argument, got 2"),
    ("1" + "0" * 400, r"the number 1000000000\d*\.\.\. does not fit a double"),
    ("1e400 * t", "does not fit a double"),
    ("t" * 2001, "expression too long"),
])
def test_the_expression_reader_refuses_in_one_line(text, message):
    with pytest.raises(ExpressionError, match=message) as error:
        parse_time_function(text)
    assert "\n" not in str(error.value) and len(str(error.value)) < 400


def test_functions_of_several_arguments_still_read():
    assert parse_time_function("max(t, 1, 3*t)")(0.5) == 1.5
    assert parse_number("atan2(1, 1)") == pytest.approx(np.pi / 4)
    assert parse_time_function("+".join(["t"] * 40))(0.5) == 20.0


def test_a_sweep_has_a_documented_count_limit_and_chunks_its_runs(monkeypatch):
    import importlib
    sweeps = importlib.import_module("lagrgen.sweep")
    model = Model("swept_spring")
    x, = model.coordinates("x")
    k, = model.parameters(k=4.0)
    model.particle(1, sp.Matrix([x]))
    model.spring(k, x)
    model.initial_state(q=[1.0])
    mod = lagrgen.build(model, backend="python")
    with pytest.raises(ValueError, match=r"1 to 1000000 values, got 1000001"):
        sweeps.sweep(mod, "k", np.ones(1_000_001), (0.0, 1.0))
    with pytest.raises(ValueError, match="samples must be a whole number from 2 to 100000"):
        sweeps.sweep(mod, "k", [1.0], (0.0, 1.0), samples=10**9)
    calls = []
    real = sweeps.simulate_many
    monkeypatch.setattr(sweeps, "CHUNK_BYTES", 16 * 5 * 1 * 3)      # three runs a chunk
    monkeypatch.setattr(sweeps, "simulate_many",
                        lambda *a, **k: calls.append(len(k["params"])) or real(*a, **k))
    ks = np.linspace(1.0, 8.0, 7)
    result = sweeps.sweep(mod, "k", ks, (0.0, 1.0), measure="final", settle=0.0, samples=5,
                          rtol=1e-9, atol=1e-12)
    assert calls == [3, 3, 1] and result.success.all()
    assert_allclose(result.table[:, 0], np.cos(np.sqrt(ks)), rtol=1e-6)


def test_the_sweep_command_refuses_a_billion_points(capsys):
    status = main(["sweep", CHAIN, "--model", "two_mass_absolute", "--param",
                   "k1=1:2:1000000000", "--t-end", "1"])
    assert status == 1
    assert "N must be a whole number from 1 to 1000000, got '1000000000'" in \
        capsys.readouterr().err


# -- 28.14: fit on the command line ------------------------------------------------------------
@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """A record of x1 alone (no x2 column) of the chain pushed by f = 0.5 from x2 = -0.05."""
    out = tmp_path_factory.mktemp("cli_fit")
    model = example_model("two_mass_chain", "absolute")
    mod = lagrgen.build(model, out_dir=out)
    t = np.linspace(0, 4, 81)
    sol = lagrgen.simulate(mod, (0, 4), [0.1, -0.05, 0, 0], inputs={"f": 0.5}, t_eval=t,
                           method="DOP853", rtol=1e-11, atol=1e-13)
    path = out / "x1_only.csv"
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(["t [s]", "x1 [m]"])
        writer.writerows(zip(t, sol.y[0]))
    return out, path


def fit_args(out, path, *extra):
    return ["fit", CHAIN, "--model", "two_mass_absolute", "--data", str(path), "--params", "k1",
            "--out", str(out), *extra]


def test_fit_refuses_a_coordinate_the_record_lacks(record, capsys):
    out, path = record
    assert main(fit_args(out, path, "--inputs", "f=0.5")) == 1
    err = capsys.readouterr().err
    assert "has no column 'x2' and --y0 does not give its start: give --y0 x2=VALUE" in err


def test_fit_takes_y0_inputs_bounds_and_weights(record, capsys):
    out, path = record
    status = main(fit_args(out, path, "--y0", "x2=-0.05", "--inputs", "f=0.5", "--bounds",
                           "k1=1:100", "--weights", "x1=2", "--initial", "k1=30"))
    printed = capsys.readouterr().out
    assert status == 0, printed
    estimate = float(printed.splitlines()[1].split("=")[1].split("±")[0])
    assert estimate == pytest.approx(40.0, rel=1e-5)
    assert main(fit_args(out, path, "--y0", "x2=-0.05", "--inputs", "f=0.5", "--bounds",
                         "k1=1:30", "--initial", "k1=20")) == 0
    captured = capsys.readouterr()
    assert "(on its bound)" in captured.out and "warning: estimates on their bounds" in \
        captured.err
    assert main(fit_args(out, path, "--y0", "x2=-0.05", "--weights", "x2=1")) == 1
    assert "--weights x2: not one of the measured names (x1)" in capsys.readouterr().err
    assert main(fit_args(out, path, "--y0", "x2=-0.05", "--bounds", "k1=5")) == 1
    assert "expected LOW:HIGH" in capsys.readouterr().err


# -- 32.5: the CSV reader ----------------------------------------------------------------------
def test_the_csv_reader_accepts_a_byte_order_mark(record, tmp_path, capsys):
    out, path = record
    marked = tmp_path / "bom.csv"
    marked.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert main(fit_args(out, marked, "--y0", "x2=-0.05", "--inputs", "f=0.5")) == 0


@pytest.mark.parametrize("content, message", [
    (b"t,x1\n0," + b"1" * 140_000 + b"\n1,2\n", "line 2: not a CSV record of numbers (field "
                                                 "larger than field limit"),
    (b"t,x1\n0,\xff\xfe\n1,2\n", "not a UTF-8 text file"),
])
def test_the_csv_reader_reports_bad_records_in_one_line(record, tmp_path, capsys, content,
                                                         message):
    out, _ = record
    bad = tmp_path / "bad.csv"
    bad.write_bytes(content)
    assert main(fit_args(out, bad, "--y0", "x2=-0.05")) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and len(err) < 400
