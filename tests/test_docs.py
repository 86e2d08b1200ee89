"""The manual runs as written, shows the program's own numbers, and builds without a warning.

- Every ```python block of README.md and of docs/guide/*.md runs: each page's blocks in order in
  one namespace, in a temporary directory laid out like the repository's root (a copy of
  examples/ and of docs/data/), so a renamed argument breaks the suite, not the reader.
- A statement ending in a comment `# -> VALUE` shows its result: what it prints (or, when it
  prints nothing, the repr of its value) must read as VALUE, each number of VALUE to the digits
  it shows (half a unit of its last digit; a whole unit when it ends in `...`, digits cut off;
  an integer exactly), whitespace aside; a bare `...` stands for any text.
- A fenced block after `<!-- output: python -m lagrgen ARGS -->` is what that command prints, read
  the same way (the command runs in-process, after the page's Python blocks).
- The Sphinx site (guide, API reference, gallery) builds with `-W` into a temporary directory, from
  a copy of docs/ and examples/, so nothing is written into the checkout.
"""
import ast
import contextlib
import io
import re
import shlex
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path

import pytest

from conftest import ROOT

DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted((DOCS / "guide").glob("*.md"))]
FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.M | re.S)
#: What a local build or run leaves in docs/ and examples/, not copied.
LEFT_BEHIND = shutil.ignore_patterns("generated", "__pycache__", "_build", "*.zarr",
                                     "sg_execution_times.rst")


#: A number as a page shows it (not a digit of a name such as theta1), maybe cut off by `...`;
#: or a bare `...`, any text.
SHOWN = re.compile(r"(?<![\w.])([-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?)(\.\.\.)?|\.\.\.")
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
RESULT_COMMENT = re.compile(r"#\s*->\s*(.*?)\s*$")
OUTPUT_BLOCK = re.compile(r"^<!-- output: python -m lagrgen (.*?) -->\n```[^\n]*\n(.*?)^```",
                          re.M | re.S)


def docs_sources(directory, names):
    """What a copy of docs/ leaves out: the outputs of a local build (and its gallery)."""
    return LEFT_BEHIND(directory, names) | ({"gallery"} if Path(directory) == DOCS else set())


def python_blocks(text):
    """[(line number, code)] of the fenced ```python blocks of a Markdown text."""
    return [(text.count("\n", 0, m.start()) + 2, m.group(1)) for m in FENCE.finditer(text)]


def shown_tolerance(text, cut_off):
    """How far a number shown as `text` may be from the value: half a unit of its last digit
    (a whole one when digits were cut off), 0 for an integer (no point, no exponent)."""
    mantissa, _, exponent = text.lower().partition("e")
    if "." not in mantissa and not exponent:
        return 0.0
    unit = 10.0 ** (int(exponent or 0) - len(mantissa.partition(".")[2]))
    return unit if cut_off else unit / 2


def shown_mismatch(shown, actual):
    """Why the text `actual` does not read as `shown` (see the module's docstring), or ""."""
    pieces, numbers, start = [], [], 0
    for m in SHOWN.finditer(shown):
        pieces += [re.escape(w) for w in shown[start:m.start()].split()]
        if m.group(1) is None:
            pieces.append(".*?")
        else:
            pieces.append(f"({NUMBER})")
            numbers.append((m.group(1), shown_tolerance(m.group(1), bool(m.group(2)))))
        start = m.end()
    pieces += [re.escape(w) for w in shown[start:].split()]
    match = re.fullmatch(r"\s*" + r"\s*".join(pieces) + r"\s*", actual, re.S)
    if match is None:
        return "the text differs"
    for (text, tol), got in zip(numbers, match.groups()):
        if abs(float(got) - float(text)) > tol * (1 + 1e-9):
            return f"{got} is not {text} to the digits shown"
    return ""


def result_comments(code):
    """{line: shown value} of the block's `# -> value` comments."""
    shown = {}
    for token in tokenize.generate_tokens(io.StringIO(code).readline):
        if token.type == tokenize.COMMENT and (m := RESULT_COMMENT.search(token.string)):
            shown[token.start[0]] = m.group(1)
    return shown


def checking_results(code, where):
    """The block compiled so that each statement ending in `# -> value` is checked: it becomes
    __check_result__(place, value, lambda: statement)."""
    shown = result_comments(code)
    tree = ast.parse(code, where)
    checked = set()

    class Checked(ast.NodeTransformer):
        def visit_Expr(self, node):
            if node.end_lineno not in shown:
                return node
            checked.add(node.end_lineno)
            thunk = ast.Lambda(ast.arguments(posonlyargs=[], args=[], kwonlyargs=[],
                                             kw_defaults=[], defaults=[]), node.value)
            call = ast.Call(ast.Name("__check_result__", ast.Load()),
                            [ast.Constant(f"{where}, line {node.end_lineno}"),
                             ast.Constant(shown[node.end_lineno]), thunk], [])
            return ast.copy_location(ast.Expr(call), node)
    tree = ast.fix_missing_locations(Checked().visit(tree))
    unchecked = sorted(set(shown) - checked)
    assert not unchecked, (f"{where}, line {unchecked[0]}: a `# ->` comment must end an "
                           "expression statement (a print(...) or a bare expression)")
    return compile(tree, where, "exec")


def check_result(place, shown, evaluate):
    """Run `evaluate` (a checked statement); what it prints, or the repr of its value when it
    prints nothing, must read as `shown`."""
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        value = evaluate()
    sys.stdout.write(printed.getvalue())
    actual = printed.getvalue() or repr(value)
    why = shown_mismatch(shown, actual)
    assert not why, f"{place}: the page shows {shown!r}, the block gives {actual!r} ({why})"


def page_id(path):
    return path.relative_to(ROOT).as_posix()


@pytest.fixture(scope="module")
def repository_root(tmp_path_factory):
    """A directory laid out like the repository's root for the blocks: examples/, docs/data/.
    One for all pages, so a model two pages build is compiled once (generated/ is shared)."""
    root = tmp_path_factory.mktemp("manual")
    shutil.copytree(ROOT / "examples", root / "examples", ignore=LEFT_BEHIND)
    if (DOCS / "data").is_dir():
        shutil.copytree(DOCS / "data", root / "docs" / "data")
    return root


def test_the_block_reader_finds_each_python_block():
    text = "x\n```python\na = 1\n```\n```sh\nno\n```\n```python\nb = a\n\n```\n"
    assert python_blocks(text) == [(3, "a = 1\n"), (9, "b = a\n\n")]


def test_shown_results_are_read_to_the_digits_shown():
    assert not shown_mismatch("array([4.6215, 9.6769])", "array([4.62146289, 9.67688383])")
    assert shown_mismatch("array([4.6214, 9.6769])", "array([4.62146289, 9.67688383])")
    assert not shown_mismatch("0.99045444115...", "0.990454441159")         # cut off
    assert shown_mismatch("0.99045444115...", "0.990454441171")
    assert not shown_mismatch("[(0.9905, 0, 'unstable->stable')]",
                              "[(0.990454441159, 0,\n  'unstable->stable')]")
    assert shown_mismatch("[(0.9905, 5, 'unstable->stable')]", "[(0.99045, 0, 'unstable->stable')]")
    assert shown_mismatch("0", "0.3") and not shown_mismatch("0.", "0.3")  # an integer exactly
    assert not shown_mismatch("1.19e-5", "1.1915e-05") and shown_mismatch("1.19e-5", "1.2e-05")
    assert not shown_mismatch("theta1 = 0.38 ...", "theta1 = 0.3827 more text\n")
    assert shown_mismatch("theta2 = 0.38", "theta1 = 0.38")
    assert not shown_mismatch("(-0.7753+4.4649j)", "(-0.775341882195845+4.46486771378823j)")
    assert shown_mismatch("True", "False") and not shown_mismatch("nan inf", "nan  inf")


def test_result_comments_are_checked(capsys):
    namespace = {"__check_result__": check_result}
    code = "x = 2\nprint(x / 3)          # shown: -> 0.667\nx * 1.5   # -> 3.0\n"
    exec(checking_results(code, "good"), namespace)
    assert capsys.readouterr().out == "0.6666666666666666\n"
    with pytest.raises(AssertionError, match=r"bad, line 1: the page shows '0.5'.*\(0.6666"):
        exec(checking_results("print(2 / 3)  # -> 0.5\n", "bad"), namespace)
    with pytest.raises(AssertionError, match="must end an expression statement"):
        checking_results("y = 1  # -> 1\n", "assignment")
    exec(checking_results("for k in (1, 2):\n    k * 0  # -> 0\n", "loop"), namespace)


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_python_block_of_the_page_runs(page, repository_root, monkeypatch):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    blocks = python_blocks(page.read_text())
    assert blocks or page.name == "optimization.md", f"{page_id(page)} has no Python block"
    monkeypatch.chdir(repository_root)
    monkeypatch.syspath_prepend(str(repository_root))
    namespace = {"__name__": "__manual__", "__check_result__": check_result}
    try:
        for line, code in blocks:
            exec(checking_results(code, f"{page_id(page)}, block at line {line}"), namespace)
        for command, shown in OUTPUT_BLOCK.findall(page.read_text()):
            check_command_output(command, shown, page_id(page))
    finally:
        plt.close("all")
        for name in [n for n, m in sys.modules.items() if _loaded_from(repository_root, m)]:
            del sys.modules[name]           # the copies of examples/ the blocks imported


def check_command_output(command, shown, where):
    """`python -m lagrgen COMMAND` run in-process prints what the page shows after it."""
    from lagrgen.cli import main
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        status = main(shlex.split(command))
    assert status == 0, f"{where}: `{command}` ended with status {status}"
    why = shown_mismatch(shown, printed.getvalue())
    assert not why, (f"{where}: `{command}` printed {printed.getvalue()!r}, the page shows "
                     f"{shown!r} ({why})")


def _loaded_from(root, module):
    """Whether `module` (or a namespace package) was imported from a file under `root`."""
    places = [getattr(module, "__file__", None), *(getattr(module, "__path__", None) or [])]
    return any(str(place or "").startswith(str(root)) for place in places)


def test_the_manual_builds_without_a_warning(tmp_path):
    """`sphinx-build -W`: the guide, the API reference of every public name and the gallery."""
    shutil.copytree(DOCS, tmp_path / "docs", ignore=docs_sources)
    shutil.copytree(ROOT / "examples", tmp_path / "examples", ignore=LEFT_BEHIND)
    out = tmp_path / "html"
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           "-j", "1", str(tmp_path / "docs"), str(out)], capture_output=True,
                          text=True, timeout=600, cwd=tmp_path, env=_environment())
    assert proc.returncode == 0, proc.stderr[-4000:]
    api = (out / "api.html").read_text()
    for name in ("lagrgen.simulate", "lagrgen.Model", "lagrgen.build", "lagrgen.modes",
                 "lagrgen.simulate_many", "lagrgen.fit", "lagrgen.stability.EigenvalueSweep",
                 "lagrgen.stability.Crossing", "lagrgen.NotAnEquilibriumWarning"):
        assert f'id="{name}"' in api, name
    index = (out / "index.html").read_text()
    for page in PAGES[1:]:
        assert f'href="guide/{page.stem}.html"' in index, page.stem
    pictures = list((out / "_images").glob("sphx_glr_plot_*_001.png"))
    assert len(pictures) == len(list((ROOT / "examples" / "gallery").glob("plot_*.py")))


def _environment():
    import os
    env = dict(os.environ)
    env["MPLBACKEND"] = "Agg"
    return env
