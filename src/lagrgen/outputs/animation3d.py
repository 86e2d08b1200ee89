"""Animated GIFs of three-dimensional models on matplotlib's 3-D axes.

A model is drawn in 3-D when it has a `rigid_body_3d` or any drawable point with 3 components;
`lagrgen.plotting.animate` hands such models here. Each 3-D body is drawn as its centre of mass and
its body frame (three short lines along the body axes R·e_x, R·e_y, R·e_z, red/green/blue); the
model's `line(...)` polylines, particles, planar bodies (in the z = 0 plane) and springs/dampers
(straight lines) are drawn as well. A robot (`from_urdf`) is a stick figure through its links'
frames (`robot_tracks`), its ground contacts' points at their places and the planes of the ground
under it (`draw_ground`).
"""
import numpy as np

from ..errors import LagrgenError
from .figures import new_figure, numeric_function, span_of, write_frames

AXIS_COLOURS = ("tab:red", "tab:green", "tab:blue")


def is_3d(model):
    """True if the model has a 3-D body, a robot, a ground or a drawable point with 3
    components."""
    for kind, points in model.drawables:
        if kind in ("body3d", "robot", "ground"):
            return True
        if kind == "point":
            points = points[:1]          # (position, mass): the mass only sizes the marker
        if kind != "body" and any(len(pt) == 3 for pt in points):
            return True
    return False


def spatial(model, position, p):
    """f(t, q) -> (frames, 3) array; 1- and 2-component positions get zeros for y, z."""
    parts = [numeric_function(model, c, p) for c in list(position)[:3]]
    while len(parts) < 3:
        parts.append(lambda t, q: np.zeros(np.shape(t)))
    return lambda t, q: np.stack([f(t, q) for f in parts], axis=-1)


def robot_frames(model, record, p, t, q):
    """(origins, rotations) of a robot's segment frames along the frames ((frames, 3) and
    (frames, 3, 3) per segment), by its forward kinematics in NumPy."""
    from ..frames import rodrigues
    origins, rotations = [], []
    frames = np.shape(t)[0]
    for segment in record.segments:
        if segment.kind == "free":        # the origin and the direction of the quaternion
            x = np.stack([numeric_function(model, e, p)(t, q) for e in segment.motion], axis=-1)
            origins.append(x[:, :3])
            rotations.append(quaternion_rotations(x[:, 3:]))
            continue
        theta = numeric_function(model, segment.motion, p)(t, q)
        P = np.array(segment.rotation.tolist(), dtype=float)
        o = np.array(segment.offset, dtype=float).reshape(3)
        axis = np.array(segment.axis, dtype=float)
        if segment.parent >= 0:
            R0, p0 = rotations[segment.parent], origins[segment.parent]
        else:
            R0, p0 = np.broadcast_to(np.eye(3), (frames, 3, 3)), np.zeros((frames, 3))
        RP = R0 @ P
        if segment.kind == "revolute":
            origins.append(p0 + R0 @ o)
            rotations.append(RP @ rodrigues(axis, theta))
        else:
            origins.append(p0 + R0 @ o + (RP @ axis) * theta[:, None])
            rotations.append(RP)
    return origins, rotations


def quaternion_rotations(z):
    """The rotation matrices (frames, 3, 3) of the directions of the quaternions z (frames, 4:
    x, y, z, w)."""
    x, y, w_, w = (z / np.linalg.norm(z, axis=-1, keepdims=True)).T
    return np.stack([np.stack([1 - 2 * (y * y + w_ * w_), 2 * (x * y - w * w_),
                               2 * (x * w_ + w * y)], axis=-1),
                     np.stack([2 * (x * y + w * w_), 1 - 2 * (x * x + w_ * w_),
                               2 * (y * w_ - w * x)], axis=-1),
                     np.stack([2 * (x * w_ - w * y), 2 * (y * w_ + w * x),
                               1 - 2 * (x * x + y * y)], axis=-1)], axis=-2)


def robot_tracks(model, record, p, t, q):
    """Line tracks from each link-carrying segment's origin to its parent link's (or to the
    fixed origin for a root of a fixed base) and on to its body's centre of mass, a point there;
    and from a segment's origin to the frame of each link a fixed joint merged into its body (a
    foot, a hand's tool), so that a leg reaches its foot."""
    origins, rotations = robot_frames(model, record, p, t, q)
    tracks = []
    for frame in record.links:
        offset = np.array(frame.offset, dtype=float).reshape(3)
        if frame.segment < 0 or not offset.any() or \
                frame.name == record.segments[frame.segment].link:
            continue
        origin = origins[frame.segment]
        tracks.append(("line", [origin, origin + rotations[frame.segment] @ offset]))
    for k, segment in enumerate(record.segments):
        if not segment.link:
            continue
        parent = segment.parent
        while parent >= 0 and not record.segments[parent].link:
            parent = record.segments[parent].parent
        if parent >= 0:
            tracks.append(("line", [origins[parent], origins[k]]))
        elif segment.parent < 0 and segment.kind != "free":
            tracks.append(("line", [np.zeros_like(origins[k]), origins[k]]))
        mass = float(numeric_function(model, segment.inertia[0], p)(t[:1], q[:, :1])[0])
        if mass <= 0.0:
            continue
        centre = np.array([float(numeric_function(model, h, p)(t[:1], q[:, :1])[0])
                           for h in segment.inertia[1:4]]) / mass
        point = origins[k] + rotations[k] @ centre
        tracks.append(("line", [origins[k], point]))
        tracks.append(("point", [point]))
    return tracks


def tracks_3d(model, p, t, q):
    """[(kind, data)] along the frames: (frames, 3) point arrays; (frames, 3, 3) R for bodies."""
    tracks = []
    for kind, points in model.drawables:
        if kind == "robot":
            tracks += robot_tracks(model, points[0], p, t, q)
            continue
        if kind == "ground":                 # drawn once, under the scene (`draw_ground`)
            continue
        if kind == "body3d":
            position, R = points
            Rn = np.stack([np.stack([numeric_function(model, R[i, j], p)(t, q) for j in range(3)],
                                    axis=-1) for i in range(3)], axis=-2)
            tracks.append((kind, [spatial(model, position, p)(t, q), Rn]))
        elif kind == "body":
            position, angle = points[:2]     # then the drawing shape and the mass (2-D only)
            a = numeric_function(model, angle, p)(t, q)
            c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
            Rn = np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1),
                           np.stack([z, z, o], -1)], axis=-2)
            tracks.append(("body3d", [spatial(model, position, p)(t, q), Rn]))
        elif kind == "point":
            tracks.append((kind, [spatial(model, points[0], p)(t, q)]))
        else:
            tracks.append((kind, [spatial(model, pt, p)(t, q) for pt in points]))
    return tracks


def box(tracks):
    """(centre, half width) of a cube enclosing every drawn point over all frames."""
    pts = np.concatenate([np.asarray(arr).reshape(-1, 3) for kind, data in tracks
                          for arr in (data[:1] if kind == "body3d" else data)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    size = span_of(lo, hi)
    return (lo + hi) / 2, 0.5 * size * 1.15 + 0.05 * size


class Scene3D:
    """The artists of one 3-D frame, updated in place frame by frame."""

    def __init__(self, ax, tracks, size):
        self.tracks, self.tick = tracks, 0.09 * size
        self.artists = []
        for kind, _ in tracks:
            if kind == "point":
                artist, = ax.plot([], [], [], "o", color="tab:blue", markersize=7)
            elif kind == "body3d":
                artist = [ax.plot([], [], [], "o", color="tab:orange", markersize=6)[0]] + \
                         [ax.plot([], [], [], "-", color=col, linewidth=2.5)[0]
                          for col in AXIS_COLOURS]
            elif kind == "spring":
                artist, = ax.plot([], [], [], "-", color="tab:green", linewidth=1.2)
            elif kind == "damper":
                artist, = ax.plot([], [], [], "-", color="tab:purple", linewidth=3, alpha=0.7)
            else:
                artist, = ax.plot([], [], [], "-", color="black", linewidth=2)
            self.artists.append(artist)

    def update(self, k):
        """Move every artist to frame k."""
        for (kind, data), artist in zip(self.tracks, self.artists):
            if kind == "body3d":
                x, R = data[0][k], data[1][k]
                _set(artist[0], x[None, :])
                for axis in range(3):
                    _set(artist[axis + 1], np.array([x, x + self.tick * R[:, axis]]))
            elif kind == "point":
                _set(artist, data[0][k][None, :])
            else:
                _set(artist, np.array([d[k] for d in data]))


def _set(artist, pts):
    artist.set_data(pts[:, 0], pts[:, 1])
    artist.set_3d_properties(pts[:, 2])


def setup_axes(fig, tracks, title):
    """A 3-D axes with equal scales on a cube around the scene, z up."""
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    centre, half = box(tracks)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.view_init(elev=20, azim=-60)
    ax.set_title(title)
    return ax, 2 * half


def draw_ground(ax, model, p, centre, half):
    """The planes of the model's ground contacts (normal·x = height) as sand-coloured squares,
    ruled by grey grids, across the scene's cube (`model.ground_contact`), under the rest."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    for kind, (normal, height) in (d for d in model.drawables if d[0] == "ground"):
        n = np.array(normal, dtype=float)
        h = float(numeric_function(model, height, p)(np.zeros(1), np.zeros((len(model.q), 1)))[0])
        t1 = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        middle = centre + (h - n @ centre) * n
        corners = [middle + a * half * t1 + b * half * t2
                   for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        ax.computed_zorder = False       # the ground under the scene, whatever the depths say
        ax.add_collection3d(Poly3DCollection([corners], facecolor="#efe4d2",
                                             edgecolor="none", zorder=0))
        for s in np.linspace(-half, half, 9):
            for a, b in ((t1, t2), (t2, t1)):
                ends = np.array([middle + s * a - half * b, middle + s * a + half * b])
                ax.plot(ends[:, 0], ends[:, 1], ends[:, 2], "-", color="0.6", linewidth=0.8,
                        zorder=0.5)


def scene_3d(model, times, q, p, title=None):
    """(figure, scene, clock text) of the 3-D model along q (n × frames) at `times`."""
    from .figures import new_figure
    if not model.drawables:
        raise LagrgenError(f"model {model.name!r} has nothing to draw")
    tracks = tracks_3d(model, p, times, q)
    fig = new_figure(5, 5)
    ax, size = setup_axes(fig, tracks, title or model.name)
    draw_ground(ax, model, p, *box(tracks))
    scene = Scene3D(ax, tracks, size)
    clock = ax.text2D(0.02, 0.96, "", transform=ax.transAxes, va="top")
    return fig, scene, clock


def animate_3d(model, times, q, path, p, fps=20, dpi=80, title=None):
    """Write an animated GIF of the 3-D model along q (n × frames) at `times`; return `path`."""
    from .figures import write_frames
    fig, scene, clock = scene_3d(model, times, q, p, title)
    return write_frames(fig, path, times, scene, clock, fps, dpi)
