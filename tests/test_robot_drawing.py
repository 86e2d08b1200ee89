"""A robot drawn as a stick figure (issue 44 item 5): the 3-D animation of a URDF robot with a free
base draws lines through its links' frames — each moving link's origin joined to its parent's, and
to the frames of the links a fixed joint merged into it (a foot) — with its ground contacts'
points and the ground under it; a GIF has one frame per time."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import lagrgen

#: A trunk and one leg: a hip and a knee about y, a foot fixed 0.2 m below the knee's shank.
ONE_LEG = """<?xml version="1.0"?>
<robot name="one_leg">
  <link name="trunk"><inertial><mass value="1.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="thigh"><inertial><origin xyz="0 0 -0.1"/><mass value="0.2"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.0001"/></inertial></link>
  <link name="shank"><inertial><origin xyz="0 0 -0.1"/><mass value="0.1"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.0001"/></inertial></link>
  <link name="foot"><inertial><mass value="0.01"/>
    <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial></link>
  <joint name="hip" type="revolute"><parent link="trunk"/><child link="thigh"/>
    <origin xyz="0.1 0.05 0"/><axis xyz="0 1 0"/></joint>
  <joint name="knee" type="revolute"><parent link="thigh"/><child link="shank"/>
    <origin xyz="0 0 -0.2"/><axis xyz="0 1 0"/></joint>
  <joint name="ankle" type="fixed"><parent link="shank"/><child link="foot"/>
    <origin xyz="0 0 -0.2"/></joint>
</robot>
"""


@pytest.fixture(scope="module")
def one_leg(tmp_path_factory):
    """The one-legged robot with a free base and its foot against the ground, and three states
    of it (n × 3): tilted, turned and bent, the quaternion of a length other than 1."""
    path = tmp_path_factory.mktemp("one_leg") / "one_leg.urdf"
    path.write_text(ONE_LEG)
    model = lagrgen.from_urdf(path, base="free", joint_dynamics=False)
    model.ground_contact("foot", "foot", mu=0.5)
    rng = np.random.default_rng(4)
    q = np.empty((len(model.q), 3))
    q[:3] = rng.uniform(-0.5, 0.5, (3, 3))
    q[3:7] = 1.3 * rng.normal(size=(4, 3))
    q[7:] = rng.uniform(-1.5, 1.5, (2, 3))
    return model, q


def link_points(model, link, q, point=(0.0, 0.0, 0.0)):
    """The fixed-frame position of a point of `link` at the states q (n × frames): its
    `link_position` expression evaluated."""
    f = lagrgen.outputs.figures.numeric_function
    x = model.link_position(link, point)
    return np.stack([f(model, x[i], ())(np.zeros(q.shape[1]), q) for i in range(3)], axis=-1)


def test_a_robots_lines_join_its_links_frames_down_to_its_foot(one_leg):
    from lagrgen.outputs.animation3d import tracks_3d
    model, q = one_leg
    tracks = tracks_3d(model, np.zeros(0), np.zeros(q.shape[1]), q)
    lines = [data for kind, data in tracks if kind == "line"]
    frames = {link: link_points(model, link, q) for link in ("trunk", "thigh", "shank", "foot")}

    def drawn(a, b):
        return any(np.allclose(ends[0], frames[a], atol=1e-12) and
                   np.allclose(ends[1], frames[b], atol=1e-12) for ends in lines)
    assert drawn("trunk", "thigh") and drawn("thigh", "shank") and drawn("shank", "foot")
    # the foot's ground contact is drawn at the foot, the ground as a plane under it
    points = [data[0] for kind, data in tracks if kind == "point"]
    assert any(np.allclose(x, frames["foot"], atol=1e-12) for x in points)
    (normal, height), = [data for kind, data in model.drawables if kind == "ground"]
    assert normal == (0.0, 0.0, 1.0) and float(height) == 0.0


def test_a_robots_gif_has_a_frame_per_time_and_shows_the_ground(one_leg, tmp_path):
    from PIL import Image

    from lagrgen.outputs.animation3d import animate_3d
    model, q = one_leg
    times = np.linspace(0.0, 0.2, q.shape[1])
    path = animate_3d(model, times, q, tmp_path / "one_leg.gif", np.zeros(0), fps=5, dpi=40)
    with Image.open(path) as im:
        assert im.n_frames == q.shape[1]
        im.seek(im.n_frames - 1)
        pixels = np.asarray(im.convert("RGB"), dtype=int)
    sand = np.abs(pixels - [0xef, 0xe4, 0xd2]).max(axis=-1) <= 8
    assert sand.mean() > 0.02                     # the ground under the robot
