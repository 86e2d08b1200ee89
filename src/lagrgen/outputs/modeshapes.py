"""Mode shapes that move: the k-th mode of a modal analysis drawn on the mechanism.

The motion is the linear one, q(t) = q0 + a·φ_k·sin(ω_k·t), over a whole number of periods, drawn
with the same scene as `simulate`'s animation (`plotting.mechanism_scene`). The amplitude a is
chosen so that the largest displacement of any drawn point is a given fraction of the mechanism's
size (measured at q0), found from the drawing itself: a coordinate may be an angle or a length.
"""
import numpy as np

from ..errors import LagrgenError
from .animation3d import is_3d, tracks_3d
from .figures import write_frames
from .plotting import drawable_tracks, mechanism_scene

#: The largest drawn displacement as a fraction of the mechanism's size at q0.
VISIBLE_FRACTION = 0.18
#: The length of a shapeless body's orientation tick (3-D: its axes) as a fraction of the size.
TICK = 0.09
#: The period assumed for a mode with ω = 0 (rigid body) or ω² < 0 (unstable): only for drawing.
NOMINAL_PERIOD = 1.0


def drawn_points(model, p, q, tick=0.0):
    """(frames, k, d) array of every point the animation draws (particles, body centres and the
    ends of their spokes or axes, line and spring ends) for q of shape (n, frames); a body drawn
    without a shape gets the end of a tick of length `tick` along its angle (as the scene's)."""
    times = np.zeros(q.shape[1])
    points = []
    if is_3d(model):
        for kind, data in tracks_3d(model, p, times, q):
            if kind == "body3d":
                x, R = data
                points.append(x)
                points.extend(x + tick * R[:, :, i] for i in range(3))
            else:
                points.extend(data)
        return np.stack(points, axis=1)
    for kind, data in drawable_tracks(model, p, times, q):
        if kind == "body":
            centre, angle, shape = data[0], data[1], data[2]
            reach = tick if shape is None else (shape[1] if shape[0] == "disk" else shape[1] / 2)
            points.append(centre)
            points.append(centre + reach * np.stack([np.cos(angle), np.sin(angle)], axis=-1))
        elif kind == "point":
            points.append(data[0])
        else:
            points.extend(data)
    if not points:
        raise LagrgenError(
            f"model {model.name!r} draws nothing (no particles, bodies, lines or springs with "
            "ends): add model.line(...) through the points to show, e.g. for a model from "
            "lagrgen.from_sympy")
    return np.stack(points, axis=1)


def mechanism_size(model, p, q0):
    """The largest extent (over the axes) of the drawn points at q0; 1 when they coincide."""
    pts = drawn_points(model, p, np.asarray(q0, dtype=float)[:, None])[0]
    size = float((pts.max(axis=0) - pts.min(axis=0)).max())
    return size if size > 1e-12 else 1.0


def largest_displacement(model, p, q0, shape, a, tick=0.0):
    """max over drawn points of |r(q0 + a·φ) − r(q0)| (`tick`: see `drawn_points`)."""
    q = np.stack([q0, q0 + a * shape], axis=1)
    pts = drawn_points(model, p, q, tick)
    return float(np.linalg.norm(pts[1] - pts[0], axis=-1).max())


def visible_amplitude(model, p, q0, shape, fraction=VISIBLE_FRACTION):
    """The amplitude a of φ whose largest drawn displacement is `fraction` of the mechanism's size
    (from the drawing's slope at q0, refined once at the amplitude found)."""
    size = mechanism_size(model, p, q0)
    target = fraction * size
    scale = np.abs(shape).max()
    if scale == 0:
        raise LagrgenError("the mode shape is zero: there is nothing to animate")
    a = 1e-4 * size / scale
    for _ in range(3):
        moved = largest_displacement(model, p, q0, shape, a, TICK * size)
        if moved <= 1e-14 * size:
            raise LagrgenError(
                f"mode shape moves nothing that model {model.name!r} draws: add particles, "
                "bodies or model.line(...) that depend on its coordinates")
        a *= target / moved
    return a


def mode_title(model_name, result, k):
    """'name: mode 2, 1.234 Hz, ζ = 0.01' (rigid-body or unstable modes say so)."""
    w = result.omega[k]
    if not np.isfinite(w):
        what = f"unstable (ω² = {np.real(result.omega_squared[k]):.3g} rad²/s²)"
    elif w == 0:
        what = "rigid-body mode (0 Hz)"
    else:
        what = f"{w / (2 * np.pi):.4g} Hz, ζ = {result.damping_ratios[k]:.3g}"
    return f"{model_name}: mode {k + 1}, {what}"


def mode_motion(result, k, amplitude, periods=1, frames_per_period=36):
    """(times, q of shape (n, frames)): q0 + amplitude·Im(φ_k·e^(iω_k·t)) over `periods` periods
    (φ_k·sin(ω_k·t) for a real shape; a complex one moves each coordinate with its own phase),
    the last frame left out so that a looping animation is seamless."""
    w = result.omega[k]
    period = 2 * np.pi / w if np.isfinite(w) and w > 0 else NOMINAL_PERIOD
    count = max(int(round(periods * frames_per_period)), 2)
    times = np.arange(count) * (periods * period / count)
    turn = np.exp(2j * np.pi * times / period)
    lin = result.linearization
    motion = np.imag(np.asarray(result.shapes[:, k], dtype=complex)[:, None] * turn[None, :])
    return times, lin.q0[:, None] + amplitude * motion


def check_mode_index(result, k):
    count = len(result.omega)
    if not (isinstance(k, (int, np.integer)) and -count <= k < count):
        raise IndexError(f"mode index {k!r} out of range: this analysis has {count} modes, "
                         f"k = 0 .. {count - 1} (mode k is result.omega[k], result.shapes[:, k])")
    return int(k) % count


def animate_mode(model, result, k, path, p, amplitude=None, periods=1, frames_per_period=36,
                 fps=20, dpi=80, title=None):
    """Write the k-th mode of `result` moving on `model`'s drawing to `path` (.gif or .mp4), or,
    with path None, return it as a `NotebookAnimation` (shows itself in a notebook).

    Returns
    -------
    (path or NotebookAnimation, amplitude): the amplitude a of the mass-normalized φ_k used.
    """
    k = check_mode_index(result, k)
    lin = result.linearization
    shape = np.abs(result.shapes[:, k]) if np.iscomplexobj(result.shapes) else result.shapes[:, k]
    if amplitude is None:
        amplitude = visible_amplitude(model, p, lin.q0, shape)
    times, q = mode_motion(result, k, amplitude, periods, frames_per_period)
    title = title or mode_title(model.name, result, k)
    if path is None:
        from .notebook import NotebookAnimation
        return NotebookAnimation(model, times, q, p, fps=fps, dpi=dpi, title=title), amplitude
    fig, scene, clock = mechanism_scene(model, times, q, p, title)
    return write_frames(fig, path, times, scene, clock, fps, dpi), amplitude
