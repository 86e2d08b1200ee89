"""What every picture shares: a figure on matplotlib's Agg canvas, its finishing step, the GIF
frame loop, and the numeric function of a drawing expression (for the 2-D and 3-D animations)."""
import numpy as np
import sympy as sp
from matplotlib.animation import PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..errors import LagrgenError


def finished(fig, path):
    """`fig` laid out, and saved to `path` when one is given."""
    fig.tight_layout()
    if path is not None:
        fig.savefig(path)
    return fig


MOVIE_SUFFIXES = (".gif", ".mp4")


def movie_writer(path, fps):
    """matplotlib's writer for `path` by its suffix: Pillow for .gif, ffmpeg for .mp4."""
    from pathlib import Path
    suffix = Path(path).suffix.lower()
    if suffix == ".gif":
        return PillowWriter(fps=fps)
    if suffix == ".mp4":
        from matplotlib.animation import FFMpegWriter
        if not FFMpegWriter.isAvailable():
            raise LagrgenError(
                f"cannot write {str(path)!r}: an MP4 needs the ffmpeg program, which was not "
                "found on PATH (install ffmpeg, or write a .gif instead)")
        return FFMpegWriter(fps=fps)
    raise ValueError(f"cannot write an animation to {str(path)!r}: the file name must end in "
                     f"{' or '.join(MOVIE_SUFFIXES)}")


def write_frames(fig, path, times, scene, clock, fps, dpi):
    """An animation at `path` (GIF or MP4, by its suffix): for each time, `scene.update(k)`, the
    clock text, one frame."""
    writer = movie_writer(path, fps)
    with writer.saving(fig, str(path), dpi):
        for k, t in enumerate(times):
            scene.update(k)
            clock.set_text(f"t = {t:.2f}")
            writer.grab_frame()
    return path


def new_figure(width, height):
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig


def numeric_function(model, expr, p):
    """f(t, q) for q of shape (n, frames): `expr` with the parameter values p substituted."""
    n = len(model.q)
    Q = sp.symbols(f"_q0:{n}") if n else ()
    T = sp.Symbol("_t")
    values = {s: sp.Float(v) for s, v in zip(model.parameter_symbols, p)}
    plain = sp.sympify(expr).xreplace(values).xreplace({**dict(zip(model.q, Q)), model.t: T})
    f = sp.lambdify([T, Q], plain, "numpy")
    return lambda t, q: np.broadcast_to(np.asarray(f(t, tuple(q)), dtype=float), np.shape(t))


def span_of(lo, hi):
    """The size of a scene from its extent: the largest side, or where nothing moves (a
    mechanism at rest) the distance of its centre from the origin, at least 1."""
    size = float((hi - lo).max())
    centre = 0.5 * (lo + hi)
    if size <= 1e-9 * (1.0 + np.abs(centre).max()):
        size = max(float(np.abs(centre).max()), 1.0)
    return size
