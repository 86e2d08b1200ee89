"""The command line reads every URDF a user may have (issue 45 item 8): the from_urdf options as
flags of every command that takes a model file, and errors that name the flag, not the Python
keyword."""
import importlib.metadata
import warnings
from pathlib import Path

import pytest

from lagrgen.cli import COMMANDS, main, parser
from lagrgen.urdf import URDFError, from_urdf

INERTIA = '<inertia ixx="0.01" iyy="0.02" izz="0.015"/>'


def link(name, mass=1.0, inertia=INERTIA):
    if mass is None:
        return f'<link name="{name}"/>'
    return (f'<link name="{name}"><inertial><origin xyz="0 0 -0.1"/><mass value="{mass}"/>'
            f'{inertia}</inertial></link>')


def joint(name, parent, child, kind="revolute", extra=""):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0 0 -0.2"/><axis xyz="0 1 0"/>{extra}</joint>')


def robot(*elements):
    return f'<?xml version="1.0"?><robot name="bot">{"".join(elements)}</robot>'


#: name: (file, its error without the flag, the flag that reads it, coordinates with the flag)
CASES = {
    "an unphysical inertia": (
        robot(link("a"), link("b", inertia='<inertia ixx="0.1" iyy="0.1" izz="0.5"/>'),
              joint("j", "a", "b")),
        "triangle inequality", ["--no-check-inertias"], 1),
    "a massless joint": (
        robot(link("a"), link("b"), link("c", None), joint("j", "a", "b"), joint("k", "b", "c")),
        "joint 'k' of 'bot' moves no mass", ["--massless", "fixed"], 1),
    "a mimic of a fixed joint": (
        robot(link("a"), link("b"), link("c"), joint("j", "a", "b", "fixed"),
              joint("k", "b", "c", extra='<mimic joint="j"/>')),
        "mimics 'j', which is not a moving joint", ["--no-mimic"], 1),
    "no moving joint": (
        robot(link("a"), link("b"), joint("j", "a", "b", "fixed")),
        "robot 'bot' has no moving joint", ["--base", "floating"], 6),
}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("urdf_flags")
    paths = {}
    for k, (case, (text, *_)) in enumerate(sorted(CASES.items())):
        paths[case] = folder / f"case{k}.urdf"
        paths[case].write_text(text)
    return paths


@pytest.mark.parametrize("case", sorted(CASES))
def test_an_error_names_the_flag_that_reads_the_file(case, files, capsys):
    _, error, flag, _ = CASES[case]
    with pytest.raises(URDFError, match="from_urdf\\(\\.\\.\\., "):
        from_urdf(files[case])
    assert main(["build", str(files[case]), "--out", "unused"]) == 1
    message = capsys.readouterr().err
    assert message.startswith("lagrgen: error:") and error in message
    assert " ".join(flag) in message and "from_urdf" not in message
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["show", str(files[case]), "--raw", *flag]) == 0
    assert capsys.readouterr().out.startswith("robot bot: ")


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_flag_reaches_from_urdf_through_a_command(case, files, capsys):
    _, _, flag, n = CASES[case]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["simulate", str(files[case]), "--backend", "python", "--t-end", "0.01",
                     "--csv", "-", "--quiet", *flag]) == 0
    header = capsys.readouterr().out.splitlines()[0].split(",")
    assert len([c for c in header if c.endswith("[rad]") or c.endswith("[m]")]) == n


def test_every_command_that_reads_a_model_file_takes_the_flags():
    sub = next(a for a in parser()._actions if a.dest == "command")
    for name, command in sub.choices.items():
        options = {s for a in command._actions for s in a.option_strings}
        if "--base" in options:
            assert {"--no-check-inertias", "--no-mimic", "--massless",
                    "--no-joint-dynamics"} <= options, name
    takers = [n for n, c in sub.choices.items()
              if any(a.dest == "model_file" for a in c._actions)]
    assert len(takers) >= len(COMMANDS) - 2


def test_the_show_command_reads_a_vendor_file_with_an_unphysical_antenna(capsys):
    root = None
    try:
        for f in importlib.metadata.files("example-robot-data") or ():
            if str(f).endswith("tiago_description/robots/tiago_dual.urdf"):
                root = Path(f.locate())
    except importlib.metadata.PackageNotFoundError:
        pass
    if root is None:
        pytest.skip("example-robot-data is not installed")
    assert main(["show", str(root)]) == 1
    assert "--no-check-inertias" in capsys.readouterr().err
    with pytest.warns(UserWarning, match="taken as it is"):
        assert main(["show", str(root), "--no-check-inertias"]) == 0
    assert "robot tiago_dual: 101 coordinates" in capsys.readouterr().out


def test_a_free_base_with_mimic_joints_names_the_flag(tmp_path, capsys):
    """The command line's error for a free base with a mimic joint names --no-mimic (it named
    the Python option), and the flag reads the file."""
    path = tmp_path / "mimicking.urdf"
    path.write_text(robot(link("a"), link("b"), link("c"), joint("j", "a", "b"),
                          joint("k", "b", "c", extra='<mimic joint="j"/>')))
    assert main(["build", str(path), "--base", "free", "--out", str(tmp_path / "gen")]) == 1
    message = capsys.readouterr().err
    assert "mimics 'j'" in message and "--no-mimic" in message and "from_urdf" not in message
    assert main(["show", str(path), "--raw", "--base", "free", "--no-mimic"]) == 0


@pytest.mark.parametrize("code, said", [
    ('raise RuntimeError("no such part")', "line 3: the model file raised RuntimeError: no such "
                                           "part"),
    ("undefined_helper(1)", "line 3: the model file raised NameError: name 'undefined_helper'")])
def test_an_error_inside_a_model_file_is_one_line_naming_its_line(tmp_path, capsys, code, said):
    """An exception a model file raises (not a SyntaxError nor lagrgen's own) printed a whole
    traceback; it is one line, `lagrgen: error: FILE, line N: ...`, exit status 1."""
    path = tmp_path / "broken.py"
    path.write_text(f'import lagrgen\nmodel = lagrgen.Model("broken")\n{code}\n')
    assert main(["build", str(path), "--out", str(tmp_path / "gen")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lagrgen: error: ") and said in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
