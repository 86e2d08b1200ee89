"""Mode shapes that move (`Modes.animate`, `python -m lagrgen modes --animate DIR`).

- the GIF has periods × frames_per_period frames that change, the title names the mode;
- the amplitude makes the largest drawn displacement ~18 % of the mechanism's size;
- the double pendulum's first mode swings both masses to the same side (in phase), the second to
  opposite sides (anti-phase), at ω = √((g/L)(2 ∓ √2));
- `modes(lin)` and a loaded model say how to get a drawing; bad k, suffixes and MP4 without
  ffmpeg are clear errors; the command writes one GIF per mode.
"""
import shutil

import numpy as np
import pytest
from numpy.testing import assert_allclose
from PIL import Image, ImageChops

import lagrgen
from conftest import EXAMPLES, example_model
from lagrgen.errors import LagrgenError
from test_cli_tools import run


@pytest.fixture(scope="module")
def pendulum_modes(build):
    model = example_model("double_pendulum")
    mod = build(model)
    return model, mod, lagrgen.modes(mod, [0.0, 0.0])


def frames(path):
    with Image.open(path) as im:
        out = []
        for i in range(im.n_frames):
            im.seek(i)
            out.append(im.convert("RGB"))
        return out


def test_gif_has_the_requested_frames_and_they_move(pendulum_modes, tmp_path):
    model, mod, res = pendulum_modes
    path = res.animate(1, tmp_path / "m2.gif", periods=2, frames_per_period=12)
    shots = frames(path)
    assert len(shots) == 24
    assert ImageChops.difference(shots[0], shots[3]).getbbox() is not None   # a quarter period
    assert ImageChops.difference(shots[3], shots[9]).getbbox() is not None   # + and − swing


def test_frequencies_and_phases_of_the_double_pendulum(pendulum_modes):
    from lagrgen.outputs.modeshapes import drawn_points, mode_motion, mode_title
    model, mod, res = pendulum_modes
    assert_allclose(res.omega, np.sqrt(9.81 * (2 - np.array([1, -1]) * np.sqrt(2))), rtol=1e-10)
    for k, same_side in ((0, True), (1, False)):
        times, q = mode_motion(res, k, 0.2, periods=1, frames_per_period=8)
        pA, pB = drawn_points(model, res.linearization.p, q[:, 2:3])[0][:2]   # the particles
        assert_allclose(pA, [np.sin(q[0, 2]), -np.cos(q[0, 2])], atol=1e-12)
        upper, lower = pA[0], pB[0] - pA[0]       # each link's sideways swing at a quarter period
        assert abs(upper) > 0.01 and abs(lower) > 0.01
        assert (np.sign(upper) == np.sign(lower)) == same_side
        assert f"{res.frequencies_hz[k]:.4g} Hz" in mode_title(model.name, res, k)


def test_amplitude_makes_the_motion_visible(pendulum_modes, tmp_path):
    from lagrgen.outputs.modeshapes import (VISIBLE_FRACTION, largest_displacement,
                                            mechanism_size)
    model, mod, res = pendulum_modes
    for k in range(2):
        res.animate(k, tmp_path / f"m{k}.gif", frames_per_period=4)
        a = res.last_amplitude
        size = mechanism_size(model, res.linearization.p, res.linearization.q0)
        assert_allclose(size, 2.0)                          # two links of 1 m hanging down
        moved = largest_displacement(model, res.linearization.p, res.linearization.q0,
                                     res.shapes[:, k], a)
        assert_allclose(moved, VISIBLE_FRACTION * size, rtol=1e-3)


def test_explicit_amplitude_and_model(pendulum_modes, tmp_path):
    model, mod, res = pendulum_modes
    res.animate(0, tmp_path / "a.gif", model=model, amplitude=0.01, frames_per_period=4)
    assert res.last_amplitude == 0.01


def test_modes_of_a_linearization_cannot_draw(pendulum_modes, tmp_path):
    model, mod, _ = pendulum_modes
    res = lagrgen.modes(lagrgen.linearize(mod, [0.0, 0.0]))
    assert len(res.omega) == 2
    with pytest.raises(LagrgenError, match=r"modes\(mod, q0\)"):
        res.animate(0, tmp_path / "x.gif")
    res.animate(0, tmp_path / "x.gif", model=model, frames_per_period=4)   # given: fine
    assert (tmp_path / "x.gif").exists()


def test_bad_index_and_suffix(pendulum_modes, tmp_path):
    model, mod, res = pendulum_modes
    with pytest.raises(IndexError, match="2 modes"):
        res.animate(2, tmp_path / "x.gif")
    with pytest.raises(ValueError, match=r"\.gif or \.mp4"):
        res.animate(0, tmp_path / "x.avi")
    assert not (tmp_path / "x.avi").exists()


@pytest.mark.skipif(shutil.which("ffmpeg") is not None, reason="ffmpeg is installed")
def test_mp4_without_ffmpeg_says_so(pendulum_modes, tmp_path):
    model, mod, res = pendulum_modes
    with pytest.raises(LagrgenError, match="ffmpeg"):
        res.animate(0, tmp_path / "x.mp4")


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="needs ffmpeg")
def test_mp4_with_ffmpeg(pendulum_modes, tmp_path):
    model, mod, res = pendulum_modes
    path = res.animate(0, tmp_path / "x.mp4", frames_per_period=6)
    assert path.stat().st_size > 0


def test_a_3d_model_animates(build, tmp_path):
    model = lagrgen.Model("spherical_for_modes")
    import sympy as sp
    from lagrgen import rotation
    a, b = model.coordinates("a b")
    m, L, g = model.parameters(m=1.0, L=1.0, g=9.81)
    R = rotation.z(a) * rotation.x(b)
    tip = R * sp.Matrix([0, -L, 0])
    model.rigid_body_3d(m, [0.1, 0.1, 0.1], tip, R)
    model.potential_energy(m * g * tip[1])
    model.line([0, 0, 0], tip)
    mod = build(model)
    res = lagrgen.modes(mod, [0.0, 0.0])
    shots = frames(res.animate(0, tmp_path / "s.gif", frames_per_period=8))
    assert len(shots) == 8
    assert ImageChops.difference(shots[0], shots[2]).getbbox() is not None


def test_command_writes_one_gif_per_mode(tmp_path):
    run("modes", EXAMPLES / "double_pendulum.py", "--animate", tmp_path / "anim", "--quiet")
    written = sorted(p.name for p in (tmp_path / "anim").iterdir())
    assert written == ["double_pendulum_mode1.gif", "double_pendulum_mode2.gif"]
    assert all(len(frames(tmp_path / "anim" / w)) == 36 for w in written)


def test_a_loaded_model_asks_for_the_description(pendulum_modes, tmp_path):
    import types
    model, mod, _ = pendulum_modes
    res = lagrgen.modes(mod, [0.0, 0.0])
    assert res.model is mod
    res.model = types.SimpleNamespace(name="double_pendulum")   # as `load` gives: no drawing
    with pytest.raises(LagrgenError, match=r"loaded.*model=model"):
        res.animate(0, tmp_path / "x.gif")


def test_without_a_path_the_mode_shows_itself_in_a_notebook(pendulum_modes, tmp_path):
    from test_notebook_display import js_frames
    model, mod, res = pendulum_modes
    anim = res.animate(1, frames_per_period=6)
    text = anim._repr_html_()
    assert "mode 2" in anim.title and len(js_frames(text)) == 6
    with Image.open(anim.save(tmp_path / "m.gif")) as im:
        assert im.n_frames == 6
