"""The `show`, `modes` and `simulate` commands, run as `python -m lagrgen ...` in a subprocess.

- `--help` lists the commands and each command's help its options;
- `show` prints one line per coordinate, and `--latex` LaTeX with dotted symbols;
- `modes` prints the double pendulum's ω = √((g/L)(2 ∓ √2)) (compiled backend) and plots shapes;
- `simulate` writes a CSV with a header t, q, q' and one row per sample that matches
  `lagrgen.simulate`, a PNG plot and an animated GIF whose frames change;
- errors come out as one `lagrgen: error: ...` line, without a traceback; progress only on request.
"""
import csv
import io
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from PIL import Image, ImageChops

import lagrgen
from conftest import EXAMPLES, ROOT, example_model

SOURCE = str(Path(lagrgen.__file__).resolve().parent.parent)
DOUBLE = str(EXAMPLES / "double_pendulum.py")
CHAIN = str(EXAMPLES / "two_mass_chain.py")


def run(*args, cwd=None, check=True):
    """Run `python -m lagrgen ARGS` with this lagrgen first on the path; return the process."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [SOURCE, env.get("PYTHONPATH")]))
    env["MPLBACKEND"] = "Agg"
    proc = subprocess.run([sys.executable, "-m", "lagrgen", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def in_process(capsys, *args):
    """Run `lagrgen.cli.main(ARGS)` here; return (exit status, stdout, stderr)."""
    from lagrgen.cli import main
    try:
        status = main([str(a) for a in args])
    except SystemExit as exc:
        status = exc.code
    out = capsys.readouterr()
    return status, out.out, out.err


def test_help_describes_every_command(capsys):
    top = run("--help").stdout
    for command in ("build", "show", "modes", "simulate", "bench"):
        assert command in top
    expected = {"show": ("--latex", "--model"), "modes": ("--at", "--params", "--plot", "--backend"),
                "simulate": ("--t-end", "--method", "--y0", "--inputs", "--csv", "--plot",
                             "--animate", "--backend", "--out", "--quiet"),
                "bench": ("--methods", "--t-end", "--rtol", "--atol", "--repeats", "--output")}
    for command, options in expected.items():
        status, out, _ = in_process(capsys, command, "--help")
        assert status == 0
        for option in options:
            assert option in out


def test_every_command_shows_an_example_that_parses(capsys):
    """Each command module's `--help` ends with an example: a command line of that command, on a
    model file of the repository, that the parser accepts."""
    from lagrgen.cli import COMMANDS, parser
    top = parser()
    for name in COMMANDS:
        command = name.replace("_", "-")
        status, out, _ = in_process(capsys, command, "--help")
        assert status == 0 and "\nexample" in out, command
        lines = out.split("\nexample", 1)[1].split(":\n", 1)[1].replace("\\\n", " ").splitlines()
        assert lines, command
        for line in lines:
            argv = shlex.split(line)
            assert argv[:4] == ["python", "-m", "lagrgen", command], line
            assert (ROOT / argv[4]).is_file(), line
            assert top.parse_args(argv[3:]).run.__module__ == f"lagrgen.cli.{name}"


def test_show_prints_one_line_per_coordinate():
    lines = run("show", DOUBLE).stdout.strip().splitlines()
    equations = [line for line in lines if not line.startswith("#")]
    assert len(equations) == 2
    for line in equations:
        assert line.count(" = ") == 1 and "theta1''" in line and "theta2''" in line
    assert "theta2'**2" in equations[0]
    chain = run("show", CHAIN, "--model", "two_mass_relative").stdout.strip().splitlines()
    assert [line for line in chain if not line.startswith("#")] == [
        "(m1 + m2)*x1'' + m2*s'' = -c1*x1' + f - k1*x1",
        "m2*x1'' + m2*s'' = -c2*s' + f - k2*s"]


def test_show_latex():
    out = run("show", DOUBLE, "--latex", "--matrices").stdout
    body = out[out.index(r"\begin{aligned}"):out.index(r"\end{aligned}")].splitlines()[1:]
    assert len(body) == 2 and all("&=" in line for line in body)
    assert body[0].endswith(r"\\") and not body[1].endswith(r"\\")
    for piece in (r"\ddot{\theta}_{1}", r"\ddot{\theta}_{2}", r"\dot{\theta}_{2}^{2}",
                  r"\cos{\left(\theta_{1} - \theta_{2} \right)}"):
        assert piece in out
    assert "M = " in out and r"\left[\begin{matrix}" in out


def table_rows(text):
    """{mode: (omega, f_hz, zeta)} from the table `modes` prints."""
    rows = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[0].isdigit():
            rows[int(parts[0])] = tuple(map(float, parts[1:]))
    return rows


def test_modes_of_the_double_pendulum(tmp_path):
    g, L = 9.81, 0.8
    png = tmp_path / "shapes.png"
    out = run("modes", DOUBLE, "--at", "theta1=0.2,theta2=-0.1", "--params", f"L1={L},L2={L}",
              "--plot", png, "--out", tmp_path / "gen", cwd=tmp_path).stdout
    assert "theta1 = " in out
    rows = table_rows(out)
    omega = np.sqrt((g / L) * np.array([2 - np.sqrt(2), 2 + np.sqrt(2)]))
    assert_allclose([rows[1][0], rows[2][0]], omega, rtol=1e-5)
    assert_allclose([rows[1][1], rows[2][1]], omega / (2 * np.pi), rtol=1e-5)
    assert rows[1][2] == 0 and rows[2][2] == 0
    with Image.open(png) as image:
        assert image.format == "PNG" and image.size[0] > 0 and image.size[1] > 0


def test_modes_damping_of_the_chain():
    out = run("modes", CHAIN, "--model", "two_mass_absolute", "--backend", "python").stdout
    mod = lagrgen.build(example_model("two_mass_chain", "absolute"), backend="python")
    res = lagrgen.modes(mod, [0.0, 0.0])
    rows = table_rows(out)
    assert_allclose([rows[i + 1][2] for i in range(2)], res.damping_ratios, rtol=1e-5)
    assert all(z > 0 for z in res.damping_ratios)


def read_csv(path):
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    return rows[0], np.array(rows[1:], dtype=float)


def test_simulate_writes_csv_plot_and_animation(tmp_path):
    paths = {ext: tmp_path / f"run.{ext}" for ext in ("csv", "png", "gif")}
    proc = run("simulate", DOUBLE, "--backend", "python", "--t-end", 2.0, "--samples", 41,
               "--y0", "theta1=0.9,theta2'=-0.5", "--params", "m2=2.0", "--inputs", "F=0.3",
               "--method", "DOP853", "--rtol", 1e-10, "--atol", 1e-12,
               "--csv", paths["csv"], "--plot", paths["png"], "--animate", paths["gif"],
               "--frames", 6, cwd=tmp_path)
    header, data = read_csv(paths["csv"])
    assert header == ["t", "theta1", "theta2", "theta1_dot", "theta2_dot", "kinetic_energy", "potential_energy", "total_energy", "input_power", "rayleigh_dissipation"]
    assert data.shape == (41, 10)
    assert_allclose(data[[0, -1], 0], [0.0, 2.0])
    assert_allclose(data[0, 1:5], [0.9, 0.0, 0.0, -0.5])
    mod = lagrgen.build(example_model("double_pendulum"), backend="python")
    sol = lagrgen.simulate(mod, (0.0, 2.0), [0.9, 0.0, 0.0, -0.5], method="DOP853",
                           params={"m2": 2.0}, inputs={"F": 0.3}, t_eval=np.linspace(0, 2, 41),
                           rtol=1e-10, atol=1e-12)
    assert_allclose(data[:, 1:5], sol.y.T, rtol=1e-12, atol=1e-14)
    assert_allclose(data[:, 5:], lagrgen.evaluate_outputs(mod, sol).T, rtol=1e-12, atol=1e-12)
    assert proc.stdout == ""
    with Image.open(paths["png"]) as image:
        assert image.format == "PNG" and min(image.size) > 100
    with Image.open(paths["gif"]) as gif:
        assert gif.format == "GIF" and min(gif.size) > 0 and gif.n_frames >= 3
        frames = []
        for k in range(gif.n_frames):
            gif.seek(k)
            frames.append(gif.convert("RGB"))
    assert any(ImageChops.difference(frames[0], f).getbbox() is not None for f in frames[1:])


def test_simulate_csv_to_stdout_with_a_time_varying_input(tmp_path):
    proc = run("simulate", CHAIN, "--model", "two_mass_relative", "--backend", "python",
               "--t-end", 1.0, "--samples", 11, "--inputs", "f=2*sin(3*t)", "--quiet",
               "--rtol", 1e-10, "--atol", 1e-12, cwd=tmp_path)
    rows = list(csv.reader(io.StringIO(proc.stdout)))
    assert rows[0] == ["t", "x1", "s", "x1_dot", "s_dot", "kinetic_energy", "potential_energy", "total_energy", "input_power", "rayleigh_dissipation"] and len(rows) == 12
    mod = lagrgen.build(example_model("two_mass_chain", "relative"), backend="python")
    sol = lagrgen.simulate(mod, (0.0, 1.0), [0, 0, 0, 0], inputs={"f": lambda t: 2 * np.sin(3 * t)},
                           t_eval=np.linspace(0, 1, 11), rtol=1e-10, atol=1e-12)
    assert_allclose(np.array(rows[1:], dtype=float)[:, 1:5], sol.y.T, rtol=1e-9, atol=1e-13)
    assert proc.stderr == ""


def test_errors_are_one_clean_line(tmp_path):
    proc = run("simulate", CHAIN, "--t-end", "1", cwd=tmp_path, check=False)
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr.startswith("lagrgen: error: ") and "choose one with --model" in proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.splitlines()) == 1


@pytest.mark.parametrize("args, message", [
    (["show", "no_such_file.py"], "no model file"),
    (["simulate", DOUBLE, "--t-end", "1", "--backend", "python", "--params", "mass=2"],
     "unknown parameter name 'mass'"),
    (["simulate", DOUBLE, "--t-end", "1", "--backend", "python", "--y0", "1,2,3"],
     "expected 2 positions or 4 values"),
    (["simulate", DOUBLE, "--t-end", "1", "--backend", "python", "--inputs", "G=1"],
     "unknown input name 'G'"),
    (["simulate", DOUBLE, "--t-end", "1", "--backend", "python", "--inputs", "F=2*x"],
     "unknown name 'x'"),
    (["simulate", DOUBLE, "--t-end", "1", "--backend", "python", "--inputs",
      "F=__import__('os').system('touch INJECTED')"], "only the listed functions may be called"),
    (["simulate", DOUBLE, "--t-end", "1", "--backend", "python", "--inputs",
      "F=().__class__"], "attribute is not allowed"),
    (["simulate", DOUBLE, "--t-end", "1", "--backend", "python", "--params", "m1=t"],
     "must be a number, not an expression of t"),
    (["modes", DOUBLE, "--backend", "python", "--at", "phi=1"], "unknown coordinate name 'phi'"),
    (["modes", DOUBLE, "--backend", "python", "--params", "m1=-3"], "mass matrix of model"),
    (["modes", str(EXAMPLES / "cart_pendulum.py"), "--backend", "python", "--at", "theta=3"],
     "no equilibrium"),
])
def test_error_messages(args, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = in_process(capsys, *args)
    assert status == 1 and out == ""
    assert err.startswith("lagrgen: error: ") and message in err
    assert not (tmp_path / "INJECTED").exists()


def test_progress_only_on_request(tmp_path):
    from lagrgen.progress import ProgressBar
    quiet = run("simulate", DOUBLE, "--t-end", 1, "--samples", 3, cwd=tmp_path)
    assert "simulate:" not in quiet.stderr and "native engine" in quiet.stderr
    asked = run("simulate", DOUBLE, "--t-end", 1, "--samples", 3, "--progress", cwd=tmp_path)
    assert "simulate:" in asked.stderr and "100%" in asked.stderr
    stream = io.StringIO()
    progress = ProgressBar(0.0, 10.0, show=True, stream=stream, mininterval=0)
    progress(2.5)
    progress.close(10.0)
    text = stream.getvalue()
    assert " 25%" in text and "100%" in text and "t = 10 of 10" in text
    silent = io.StringIO()
    auto = ProgressBar(0.0, 10.0, show="auto", stream=silent)    # not a terminal: nothing
    auto(5.0)
    auto.close(10.0)
    assert silent.getvalue() == ""


def test_bench_prints_and_writes_a_table_of_both_paths(tmp_path):
    """`bench` on a one-coordinate model: build, per-call and solve_ivp rows with speed-ups."""
    (tmp_path / "osc.py").write_text(
        "import sympy as sp\nfrom lagrgen import Model\n"
        "model = Model('bench_osc')\nx, = model.coordinates('x')\n"
        "m, k = model.parameters(m=1.0, k=4.0)\n"
        "model.particle(m, sp.Matrix([x]))\nmodel.spring(k, x)\n")
    out = tmp_path / "bench.md"
    proc = run("bench", "osc.py", "--methods", "RK45", "Radau", "--repeats", "1", "--t-end", "1",
               "--output", out, cwd=tmp_path)
    table = out.read_text()
    assert table.strip() == proc.stdout.strip()
    assert "### bench_osc (n = 1)" in table
    for row in ("| C path |", "| rhs |", "| jacobian |", "| RK45 |", "| Radau |"):
        assert row in table
    speedups = [float(v) for v in re.findall(r"\| (\d+)× \|", table)]
    assert len(speedups) == 4
    bad = run("bench", "osc.py", "--methods", "Euler", cwd=tmp_path, check=False)
    assert bad.returncode == 1 and "unknown method 'Euler'" in bad.stderr
