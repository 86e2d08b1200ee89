"""Results that show themselves in a notebook, on both backends.

- `sol._repr_html_()` is a summary whose tables (parsed) name the model, engine, method, span and
  hold one row per coordinate with its final q and q̇;
- `sol.animate()._repr_html_()` is matplotlib's JS animation: a script and one embedded PNG per
  frame (fps × duration), each a picture of the mechanism; `.save(path)` writes the same frames;
- a result whose drawing is unknown says to pass the model.
"""
import base64
import io
import re
from html.parser import HTMLParser

import numpy as np
import pytest
from numpy.testing import assert_allclose
from PIL import Image, ImageChops

import lagrgen
from conftest import example_model
from lagrgen.errors import LagrgenError


class Tables(HTMLParser):
    """The text of every table cell, table by table, row by row."""

    def __init__(self):
        super().__init__()
        self.tables, self._cell = [], None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.tables[-1][-1].append(self._cell)
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data


def tables(text):
    parser = Tables()
    parser.feed(text)
    return parser.tables


def js_frames(text):
    """The PNG frames embedded by matplotlib's to_jshtml, as PIL images."""
    found = re.findall(r'frames\[(\d+)\] = "data:image/png;base64,(.*?)"', text, re.S)
    assert [int(i) for i, _ in found] == list(range(len(found)))
    return [Image.open(io.BytesIO(base64.b64decode(data.replace("\\\n", ""))))
            for _, data in found]


@pytest.fixture(scope="module")
def pendulum(build):
    model = example_model("double_pendulum")
    return model, build(model)


@pytest.mark.parametrize("method", ["RK45", "Radau"])
def test_summary_table(pendulum, method):
    model, mod = pendulum
    sol = lagrgen.simulate(mod, (0.0, 0.5), [0.3, -0.2, 0.0, 0.0], method=method)
    run, coords = tables(sol._repr_html_())
    fields = {row[0]: row[1] for row in run}
    assert fields["model"] == "double_pendulum"
    assert fields["engine"] == sol.engine
    assert fields["method"] == method
    assert fields["t"] == "0 … 0.5"
    assert f"nfev {sol.nfev}" in fields["evaluations"]
    assert fields["result"] == "success"
    assert coords[0][:3] == ["coordinate", "final q", "final q\u0307"]
    assert [row[0] for row in coords[1:]] == ["theta1", "theta2"]
    values = np.array([[float(v) for v in row[1:3]] for row in coords[1:]])
    assert_allclose(values, np.stack([sol.q[:, -1], sol.qd[:, -1]], axis=1), rtol=1e-5)


def test_summary_of_a_failed_run_and_escaping(build):
    model = lagrgen.Model("escape_me")
    x, = model.coordinates("x")
    k, = model.parameters(k=1.0)
    model.particle(1, [x])
    model.spring(k, x)
    mod = build(model)
    sol = lagrgen.simulate(mod, (0, 10), [1.0, 0.0], max_steps=2, engine="scipy")
    run, _ = tables(sol._repr_html_())
    fields = {row[0]: row[1] for row in run}
    assert fields["result"].startswith("failed")
    assert "max_steps" in fields["message"]
    assert "<script" not in sol._repr_html_()


def test_animation_html_has_one_png_per_frame(pendulum):
    model, mod = pendulum
    sol = lagrgen.simulate(mod, (0.0, 1.0), [1.0, 0.0, 0.0, 0.0])
    anim = sol.animate(fps=10)
    text = anim._repr_html_()
    assert "<script" in text and "anim" in text
    shots = js_frames(text)
    assert len(shots) == len(anim) == 10
    assert shots[0].size == shots[-1].size
    assert ImageChops.difference(shots[0].convert("RGB"), shots[-1].convert("RGB")).getbbox()
    assert_allclose(anim.times[[0, -1]], [0.0, 1.0])
    assert_allclose(anim.q[:, [0, -1]], sol.q[:, [0, -1]], rtol=1e-12)


def test_animation_saves_a_gif(pendulum, tmp_path):
    model, mod = pendulum
    sol = lagrgen.simulate(mod, (0.0, 0.6), [1.0, 0.0, 0.0, 0.0])
    path = sol.animate(fps=10).save(tmp_path / "a.gif")
    with Image.open(path) as im:
        assert im.n_frames == 6
    with pytest.raises(ValueError, match=r"\.gif or \.mp4"):
        sol.animate(fps=10).save(tmp_path / "a.webm")


def test_animation_uses_the_simulated_parameters(pendulum):
    model, mod = pendulum
    sol = lagrgen.simulate(mod, (0.0, 0.2), [0.0, 0.0, 0.0, 0.0], params={"L1": 2.0})
    anim = sol.animate(fps=10)
    assert anim.p[list(mod.parameters).index("L1")] == 2.0


def test_unknown_drawing_says_to_pass_the_model(pendulum):
    model, mod = pendulum
    sol = lagrgen.simulate(mod, (0.0, 0.2), [0.2, 0.0, 0.0, 0.0])
    del sol.__dict__["_built"]
    with pytest.raises(LagrgenError, match=r"sol\.animate\(model=model\)"):
        sol.animate()
    assert len(sol.animate(model=model, fps=10)) == 2


def test_constrained_summary_and_a_3d_animation(build):
    cart = build(example_model("cartesian_pendulum"))
    sol = lagrgen.simulate(cart, (0, 0.5), lagrgen.consistent_state(cart, [0.8, -0.5, 0, 0]))
    run, coords = tables(sol._repr_html_())
    fields = {row[0]: row[1] for row in run}
    assert_allclose(float(fields["λ rod (final)"]), sol.multipliers["rod"][-1], rtol=1e-5)
    assert [row[0] for row in coords[1:]] == ["x", "y"]
    top = build(example_model("pendulum3d"))
    y0 = np.zeros(2 * top.n_coordinates)
    y0[0], y0[top.n_coordinates + 1] = 0.6, 1.5
    sol = lagrgen.simulate(top, (0, 0.5), y0)
    shots = js_frames(sol.animate(fps=8)._repr_html_())
    assert len(shots) == 4
    assert ImageChops.difference(shots[0].convert("RGB"), shots[-1].convert("RGB")).getbbox()
