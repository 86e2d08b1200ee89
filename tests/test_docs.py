"""The manual runs as written and builds without a warning.

- Every ```python block of README.md and of docs/guide/*.md runs: each page's blocks in order in
  one namespace, in a temporary directory laid out like the repository's root (a copy of
  examples/ and of docs/data/), so a renamed argument breaks the suite, not the reader.
- The Sphinx site (guide, API reference, gallery) builds with `-W` into a temporary directory, from
  a copy of docs/ and examples/, so nothing is written into the checkout.
"""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT

DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted((DOCS / "guide").glob("*.md"))]
FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.M | re.S)
#: What a local build or run leaves in docs/ and examples/, not copied.
LEFT_BEHIND = shutil.ignore_patterns("generated", "__pycache__", "_build", "*.zarr",
                                     "sg_execution_times.rst")


def docs_sources(directory, names):
    """What a copy of docs/ leaves out: the outputs of a local build (and its gallery)."""
    return LEFT_BEHIND(directory, names) | ({"gallery"} if Path(directory) == DOCS else set())


def python_blocks(text):
    """[(line number, code)] of the fenced ```python blocks of a Markdown text."""
    return [(text.count("\n", 0, m.start()) + 2, m.group(1)) for m in FENCE.finditer(text)]


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


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_python_block_of_the_page_runs(page, repository_root, monkeypatch):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    blocks = python_blocks(page.read_text())
    assert blocks or page.name == "optimization.md", f"{page_id(page)} has no Python block"
    monkeypatch.chdir(repository_root)
    monkeypatch.syspath_prepend(str(repository_root))
    namespace = {"__name__": "__manual__"}
    try:
        for line, code in blocks:
            exec(compile(code, f"{page_id(page)}, block at line {line}", "exec"), namespace)
    finally:
        plt.close("all")
        for name in [n for n, m in sys.modules.items() if _loaded_from(repository_root, m)]:
            del sys.modules[name]           # the copies of examples/ the blocks imported


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
                 "lagrgen.simulate_many", "lagrgen.fit"):
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
