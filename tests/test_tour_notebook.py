"""`examples/tour.ipynb` runs from start to end (nbclient, a fresh kernel, a tmp working directory)
and shows what it says: the equations as LaTeX, the simulation summaries with the coordinates,
four HTML/JavaScript animations (one a mode) with their frames, a mode-shape GIF written and displayed."""
import os
import re
import time

import pytest

from conftest import EXAMPLES

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    import lagrgen
    work = tmp_path_factory.mktemp("tour")
    nb = nbformat.read(EXAMPLES / "tour.ipynb", as_version=4)
    source = os.path.dirname(os.path.dirname(os.path.abspath(lagrgen.__file__)))
    env = dict(os.environ, LAGRGEN_EXAMPLES=str(EXAMPLES), MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(filter(None, [source, os.environ.get("PYTHONPATH")])))
    old = dict(os.environ)
    os.environ.update(env)      # the kernel inherits the environment
    try:
        start = time.perf_counter()
        client = nbclient.NotebookClient(nb, timeout=120, kernel_name="python3",
                                         resources={"metadata": {"path": str(work)}})
        client.execute()
        seconds = time.perf_counter() - start
    finally:
        os.environ.clear()
        os.environ.update(old)
    return nb, work, seconds


def outputs(nb, mime):
    found = []
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            data = out.get("data", {})
            if mime in data:
                found.append(data[mime])
    return found


def test_every_cell_ran_without_error(executed):
    nb, _, seconds = executed
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert all(c.execution_count for c in code)
    assert not [o for c in code for o in c.outputs if o.output_type == "error"]
    assert seconds < 90


def test_equations_and_summaries(executed):
    nb, _, _ = executed
    latex = outputs(nb, "text/latex")
    assert any(r"\ddot{\theta}" in text or r"\ddot" in text for text in latex)
    summaries = [h for h in outputs(nb, "text/html") if "lagrgen-simulation" in h]
    assert len(summaries) == 2
    assert "<td>theta1</td>" in summaries[0] and "<td>theta2</td>" in summaries[0]
    assert "<td>DOP853</td>" in summaries[0]
    assert "<td>x</td>" in summaries[1] and "<td>y</td>" in summaries[1]


def test_animations_have_their_frames(executed):
    nb, _, _ = executed
    animations = [h for h in outputs(nb, "text/html") if "<script" in h]
    counts = [len(re.findall(r'frames\[\d+\] = "data:image/png;base64,', h)) for h in animations]
    assert counts == [20, 12, 24, 20]  # fps × duration of each sol.animate(fps=...);
    # the inline mode animation has frames_per_period frames


def test_mode_gif_written_and_shown(executed):
    from PIL import Image
    nb, work, _ = executed
    with Image.open(work / "double_pendulum_mode2.gif") as im:
        assert im.n_frames == 16
    import base64
    import io
    shown, = outputs(nb, "image/gif")
    with Image.open(io.BytesIO(base64.b64decode(shown))) as im:
        assert im.n_frames == 16
    assert (work / "generated").is_dir()
