"""Results that show themselves in Jupyter: a simulation's HTML summary and its animation as
HTML/JavaScript frames (matplotlib's `FuncAnimation.to_jshtml`: no ffmpeg needed).

`SimulationResult._repr_html_` and `SimulationResult.animate` delegate here.
"""
import html

import numpy as np

from ..errors import LagrgenError


def drawing_model(sol, model=None):
    """The `lagrgen.Model` whose drawing animates `sol`: `model` if given, else the description the
    simulated built model was built from."""
    if model is not None:
        return model
    built = sol.__dict__.get("_built")
    source = getattr(built, "_source_model", None)
    if source is None:
        name = sol.__dict__.get("_model_name") or "this model"
        raise LagrgenError(
            f"the drawing of {name!r} is unknown (a result not made by lagrgen.simulate, or a "
            "model loaded rather than built in this session): pass the lagrgen.Model, "
            "sol.animate(model=model)")
    return source


class NotebookAnimation:
    """The mechanism moving along a simulation: shows itself in a notebook as an HTML/JavaScript
    animation (`_repr_html_`), or is written to a GIF or MP4 file with `save(path)`.

    Attributes
    ----------
    times : (frames,) the simulated times of the frames
    q : (n, frames) the coordinates at those times
    """

    def __init__(self, model, times, q, p, fps=20, dpi=72, title=None):
        self.model, self.times, self.q, self.p = model, np.asarray(times), np.asarray(q), p
        self.fps, self.dpi, self.title = fps, dpi, title
        self._html = None

    def __len__(self):
        return len(self.times)

    def _scene(self):
        from .plotting import mechanism_scene
        return mechanism_scene(self.model, self.times, self.q, self.p, self.title)

    def to_jshtml(self):
        """The animation as an HTML fragment: every frame an embedded PNG, with play controls."""
        if self._html is None:
            from matplotlib.animation import FuncAnimation
            fig, scene, clock = self._scene()

            def show(k):
                scene.update(k)
                clock.set_text(f"t = {self.times[k]:.2f}")
            anim = FuncAnimation(fig, show, frames=len(self.times), interval=1000 / self.fps,
                                 blit=False, repeat=True)
            fig.set_dpi(self.dpi)
            self._html = anim.to_jshtml(fps=self.fps, default_mode="loop")
        return self._html

    def _repr_html_(self):
        return self.to_jshtml()

    def save(self, path):
        """Write the animation to `path` (.gif with Pillow, .mp4 with ffmpeg); return the path."""
        from .figures import write_frames
        fig, scene, clock = self._scene()
        return write_frames(fig, path, self.times, scene, clock, self.fps, self.dpi)


def animation(sol, model=None, params=None, fps=20, max_frames=120, dpi=72, title=None):
    """A NotebookAnimation of `sol`: frames equally spaced in time, `fps` per simulated second, at
    most `max_frames`; `params` default to the values the simulation used."""
    from .plotting import animation_frames, check_drawable, solution_parameters
    model = drawing_model(sol, model)
    check_drawable(model)
    p = solution_parameters(model, sol, params)
    times, y = animation_frames(sol, fps, max_frames)
    return NotebookAnimation(model, times, y[:len(model.q)], p, fps=fps, dpi=dpi, title=title)


def _cell(value):
    return f"<td>{html.escape(str(value))}</td>"


def _row(label, value):
    return f"<tr><th style='text-align:left'>{html.escape(label)}</th>{_cell(value)}</tr>"


def summary_html(sol):
    """A compact HTML summary of a simulation: model, engine, method, time span, steps, function
    evaluations, success and message, then a table of the coordinates' final values."""
    t = np.asarray(sol.t)
    name = sol.__dict__.get("_model_name") or ""
    steps = sol.get("n_steps")
    steps = len(t) - 1 if steps is None else steps
    counts = ", ".join(f"{key} {sol[key]}" for key in ("nfev", "njev", "nlu") if key in sol)
    span = f"{t[0]:.6g} … {t[-1]:.6g}" if len(t) else "(no points)"
    status = "success" if sol.get("success") else f"failed (status {sol.get('status')})"
    rows = [_row("model", name), _row("engine", sol.get("engine", "")),
            _row("method", sol.__dict__.get("_method") or ""), _row("t", span),
            _row("output points", len(t)), _row("steps", steps), _row("evaluations", counts),
            _row("result", status), _row("message", sol.get("message", ""))]
    for name, lam in (sol.get("multipliers") or {}).items():
        rows.append(_row(f"λ {name} (final)", f"{np.asarray(lam)[-1]:.6g}" if len(lam) else ""))
    units = sol.__dict__.get("_units") or {}
    coordinates = list(sol.get("coordinates", ()))
    n = len(coordinates)
    y = np.asarray(sol.y)
    final = y[:, -1] if y.ndim == 2 and y.shape[1] else np.full(2 * n, np.nan)
    table = ["<tr><th>coordinate</th><th>final q</th><th>final q&#775;</th><th>unit</th></tr>"]
    for i, c in enumerate(coordinates):
        table.append(f"<tr>{_cell(c)}{_cell(f'{final[i]:.6g}')}{_cell(f'{final[n + i]:.6g}')}"
                     f"{_cell(units.get(c, ''))}</tr>")
    return ("<div class='lagrgen-simulation'>"
            f"<b>lagrgen simulation of {html.escape(name)}</b>"
            f"<table class='lagrgen-run'>{''.join(rows)}</table>"
            f"<table class='lagrgen-coordinates'>{''.join(table)}</table></div>")
