"""Pictures of results: time histories, mode shapes, and an animated GIF of the mechanism.

Figures are drawn on matplotlib's Agg canvas (no window, no change to pyplot's global backend).
The data flow is one way: these functions take a Model (its geometry, `model.drawables`), parameter
values and a solution; they never build or derive anything.
"""
import numpy as np

from ..errors import LagrgenError
from ..runtime.arguments import defaults_array, parameter_vector
from .animation3d import animate_3d, is_3d
from .figures import finished, new_figure, numeric_function, span_of, write_frames  # noqa: F401

MAX_MODES_PLOTTED = 8


def label(name, units):
    """'x [m]' when `units` gives `name` a unit, else 'name'."""
    unit = (units or {}).get(name)
    return f"{name} [{unit}]" if unit else name


def unit_groups(names, units):
    """[(unit or None, [indices])]: the names grouped by unit, in order of first appearance."""
    groups = {}
    for i, name in enumerate(names):
        groups.setdefault((units or {}).get(name), []).append(i)
    return list(groups.items())


def rate_unit(unit):
    """The unit of a time derivative: 'm' -> 'm/s' (a label only)."""
    if not unit:
        return None
    return f"({unit})/s" if "/" in unit else f"{unit}/s"


#: Lines drawn in one panel at most: each its own colour (matplotlib's ten "tab" colours) and an
#: entry of the panel's legend, beside the panel; more lines of one unit take more panels.
LINES_PER_PANEL = 8


def panel_groups(groups):
    """[(label, [indices])] with each group of `groups` cut into panels of at most
    LINES_PER_PANEL lines, of nearly equal sizes, in order."""
    out = []
    for name, members in groups:
        count = -(-len(members) // LINES_PER_PANEL)
        out.extend((name, [int(i) for i in part]) for part in np.array_split(members, count))
    return out


def legend_beside(ax):
    """The axes' legend outside it, to the right of its top (covering no curve)."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize="small")


def plot_panels(t, rows, names, groups, path=None, title=None, xlabel="t", transitions=None):
    """Lines of `rows` against t in panels sharing the t axis: each group of `groups`
    ([(y label, [indices])]) in panels of at most LINES_PER_PANEL lines of distinct colours, each
    panel's legend beside it; the matplotlib Figure, saved to `path` if given."""
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    panels = panel_groups(groups)
    widest = max((len(names[i]) for _, members in panels for i in members), default=0)
    height = max(0.19 * max(len(members) for _, members in panels) + 0.8, 2.0)
    fig = new_figure(7.1 + 0.07 * widest, max(height * len(panels) + 0.8, 3.5))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (ylabel, members) in zip(axes, panels):
        for k, i in enumerate(members):
            ax.plot(t, rows[i], label=names[i], color=f"C{k}")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        legend_beside(ax)
    axes[-1].set_xlabel(xlabel)
    if title:
        axes[0].set_title(title)
    mark_transitions(axes, transitions)
    return finished(fig, path)


def plot_series(t, rows, names, units=None, path=None, title=None, time_unit="s",
                transitions=None):
    """One panel per unit group (a quantity with its unit on each y axis; a group of more than
    LINES_PER_PANEL lines in several panels), sharing the t axis, the legends beside the panels.

    Parameters
    ----------
    t : (m,) times; rows : (k, m) values; names : k names; units : {name: unit} (labels only)
    path : save the figure here if given; title : the figure title
    transitions : [(t, name, kind)] of a hybrid solve (`sol.transitions`): vertical markers

    Returns
    -------
    The matplotlib Figure.
    """
    groups = [(f"[{unit}]" if unit else "(no unit)", members)
              for unit, members in unit_groups(names, units)]
    return plot_panels(t, rows, names, groups, path, title,
                       f"t [{time_unit}]" if units else "t", transitions)


#: Marker styles (colour, dashes) of the transition kinds of a hybrid solve: black and grey, so
#: that no marker takes the colour of a curve.
TRANSITION_STYLES = {"impact": ("k", ":"), "contact": ("k", "--"), "release": ("k", "-."),
                     "stick": ("0.3", "--"), "slip": ("0.3", ":")}


def mark_transitions(axes, transitions, limit=200):
    """Thin vertical lines at the switching times (styled by kind, one legend entry per kind);
    the first `limit` only."""
    if not transitions:
        return
    seen = set()
    for t, _, kind in list(transitions)[:limit]:
        colour, dashes = TRANSITION_STYLES.get(kind, ("k", ":"))
        for k, ax in enumerate(axes):
            label = kind if k == 0 and kind not in seen else None
            ax.axvline(t, color=colour, ls=dashes, lw=0.6, alpha=0.8, label=label)
        seen.add(kind)
    legend_beside(axes[0])


def plot_fit(t, measured, fitted, names, path=None, title=None, units=None):
    """Measured samples (dots) and the fitted model's response (lines), one panel per name.

    Parameters
    ----------
    t : (m,) times; measured, fitted : (k, m) values; names : k names; units : {name: unit}
    path : save the figure here if given; title : the figure title

    Returns
    -------
    The matplotlib Figure.
    """
    measured, fitted = np.atleast_2d(measured), np.atleast_2d(fitted)
    fig = new_figure(7, max(2.0 * len(names) + 0.8, 3.5))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    for ax, name, data, model in zip(axes, names, measured, fitted):
        ax.plot(t, data, ".", ms=3, color="0.45", label=f"{name} measured")
        ax.plot(t, model, "-", color="tab:blue", lw=1.4, label=f"{name} fitted")
        ax.set_ylabel(label(name, units))
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("t [s]" if units else "t")
    if title:
        axes[0].set_title(title)
    return finished(fig, path)


def plot_time_history(sol, coordinates, path=None, velocities=True, title=None, units=None):
    """q_i(t) (and q̇_i(t)); with `units` ({name: unit}) one panel per unit group, each axis
    labelled with its unit; saved to `path` if given."""
    t, y = np.asarray(sol.t), np.asarray(sol.y)
    n = len(coordinates)
    if units and any(c in units for c in coordinates):
        names = list(coordinates)
        rate_units = {}
        rows = [y[i] for i in range(n)]
        if velocities:
            for i, c in enumerate(coordinates):
                names.append(f"{c}'")
                rows.append(y[n + i])
                if rate_unit(units.get(c)):
                    rate_units[f"{c}'"] = rate_unit(units.get(c))
        return plot_series(t, rows, names, {**units, **rate_units}, path, title,
                           transitions=getattr(sol, "transitions", None))
    rows = [y[i] for i in range(n)]
    groups = [("q", list(range(n)))]
    names = list(coordinates)
    if velocities:
        rows += [y[n + i] for i in range(n)]
        groups.append(("dq/dt", list(range(n, 2 * n))))
        names += [f"{c}'" for c in coordinates]
    return plot_panels(t, rows, names, groups, path, title,
                       transitions=getattr(sol, "transitions", None))


def plot_modes(result, coordinates, path=None, title=None):
    """Mode shapes as bars over the coordinates, one panel per mode (the first MAX_MODES_PLOTTED)."""
    count = min(len(result.omega), MAX_MODES_PLOTTED)
    fig = new_figure(7, 1.9 * count + 0.6)
    axes = fig.subplots(count, 1, sharex=True, squeeze=False)[:, 0]
    x = np.arange(len(coordinates))
    for i, ax in enumerate(axes):
        shape = np.real(result.shapes[:, i])
        ax.bar(x, shape, color="tab:red" if growing(result, i) else "tab:blue")
        ax.axhline(0.0, color="black", linewidth=0.8)
        ax.set_title(mode_label(result, i), fontsize="medium")
        ax.grid(True, axis="y", alpha=0.3)
    axes[-1].set_xticks(x)
    axes[-1].set_xticklabels(coordinates)
    if title:
        fig.suptitle(title)
    return finished(fig, path)


def growing(result, i):
    """Whether mode i grows: ω² < 0 (classical modes: ω is NaN) or ζ < 0."""
    return not np.isfinite(result.omega[i]) or result.damping_ratios[i] < 0


def mode_label(result, i):
    """'mode 1: 0.3815 Hz (2.397 rad/s), ζ = 0' (or 'unstable' for ω² < 0, ', unstable' for
    ζ < 0)."""
    w = result.omega[i]
    if not np.isfinite(w):
        return f"mode {i + 1}: unstable (ω² = {np.real(result.omega_squared[i]):.4g} rad²/s²)"
    return (f"mode {i + 1}: {w / (2 * np.pi):.4g} Hz ({w:.4g} rad/s), "
            f"ζ = {result.damping_ratios[i]:.3g}{', unstable' if growing(result, i) else ''}")


def model_parameters(model, params):
    """The parameter vector for `model` from None (defaults), a dict or a full array."""
    return parameter_vector(params, model.parameter_names,
                            defaults_array(model.parameter_defaults))


def solution_parameters(model, sol, params):
    """`model_parameters` of `params`, by default the values the simulation `sol` used (its
    `params`; the model's defaults where it has none)."""
    if params is None:
        params = sol.get("params") if hasattr(sol, "get") else getattr(sol, "params", None)
    return model_parameters(model, params)


def planar(model, position, p):
    """f(t, q) -> (frames, 2) array: a 1-D position lies on the x axis, a 3-D one is seen along z."""
    parts = [numeric_function(model, c, p) for c in list(position)[:2]]
    if len(parts) == 1:
        parts.append(lambda t, q: np.zeros(np.shape(t)))
    return lambda t, q: np.stack([f(t, q) for f in parts], axis=-1)


def drawable_tracks(model, p, t, q):
    """[(kind, data)] along the frames: data are (frames, 2) point arrays; a body adds its angles,
    its drawing shape (sizes as numbers) and its mass, a point its mass."""
    tracks = []
    for kind, points in model.drawables:
        if kind == "body":
            position, angle = points[:2]
            shape = points[2] if len(points) > 2 else None
            if shape is not None:
                shape = (shape[0],) + tuple(float(numeric_function(model, v, p)(np.zeros(1), q[:, :1])[0])
                                            for v in shape[1:])
            mass = _mass_value(model, points[3] if len(points) > 3 else None, p, q)
            tracks.append((kind, [planar(model, position, p)(t, q),
                                  numeric_function(model, angle, p)(t, q), shape, mass]))
        elif kind == "point":
            mass = _mass_value(model, points[1] if len(points) > 1 else None, p, q)
            tracks.append((kind, [planar(model, points[0], p)(t, q), mass]))
        else:
            tracks.append((kind, [planar(model, pt, p)(t, q) for pt in points]))
    return tracks


def _mass_value(model, mass, p, q):
    if mass is None:
        return None
    try:
        return abs(float(numeric_function(model, mass, p)(np.zeros(1), q[:, :1])[0]))
    except (TypeError, ValueError):
        return None


def marker_sizes(tracks, smallest=6.0, largest=16.0):
    """Marker size per point/body track: area proportional to mass, between the two sizes."""
    masses = [data[-1] for kind, data in tracks if kind in ("point", "body")]
    known = [m for m in masses if m]
    top = max(known) if known else 1.0
    sizes = iter([smallest + (largest - smallest) * np.sqrt(m / top) if m else 9.0
                  for m in masses] if known else [9.0] * len(masses))
    return [next(sizes) if kind in ("point", "body") else None for kind, _ in tracks]


def shape_outline(shape, centre, angle, points=40):
    """The outline of a body's drawing shape at `centre`, turned by `angle`: (k, 2) points."""
    kind = shape[0]
    if kind == "disk":
        a = np.linspace(0, 2 * np.pi, points)
        outline = shape[1] * np.stack([np.cos(a), np.sin(a)], axis=-1)
    elif kind == "bar":
        half = shape[1] / 2
        outline = np.array([[-half, 0.0], [half, 0.0]])
    else:
        w, h = shape[1] / 2, shape[2] / 2
        outline = np.array([[-w, -h], [w, -h], [w, h], [-w, h], [-w, -h]])
    c, s = np.cos(angle), np.sin(angle)
    return centre + outline @ np.array([[c, s], [-s, c]])


def dashpot(a, b, width=0.05):
    """A damper symbol from a to b: rod, open cylinder, piston plate, rod."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    d = b - a
    length = np.hypot(*d)
    if length == 0:
        return np.array([a, b])
    u, n = d / length, np.array([-d[1], d[0]]) / length
    p = lambda s, o: a + s * length * u + o * width * n  # noqa: E731
    nan = np.array([np.nan, np.nan])
    return np.array([a, p(0.3, 0), nan, p(0.7, 1), p(0.3, 1), p(0.3, -1), p(0.7, -1), nan,
                     p(0.55, 0.8), p(0.55, -0.8), nan, p(0.55, 0), b])


def frame_states(sol, n_frames):
    """(times, y at those times): n_frames equally spaced times, y from `sol`'s dense output, else
    interpolated between its saved points (`hermite_states`)."""
    t = np.asarray(sol.t, dtype=float)
    y = np.asarray(sol.y, dtype=float)
    times = np.linspace(t[0], t[-1], n_frames)
    if getattr(sol, "sol", None) is not None:
        return times, np.asarray(sol.sol(times))
    return times, hermite_states(t, y, times)


def hermite_states(t, y, times):
    """y = [q, q̇] at `times` between the saved points (t, y): q by the cubic Hermite interpolant
    of q and q̇ at the ends of each interval, q̇ linearly. An explicit solver's long steps drew a
    bouncing ball 0.18 m off its path by straight lines; an interval of zero length (an impact's
    states before and after) gives the later state."""
    if y.shape[0] % 2 or t.size < 2:
        return np.array([np.interp(times, t, row) for row in y])
    n = y.shape[0] // 2
    i = np.clip(np.searchsorted(t, times, side="right") - 1, 0, t.size - 2)
    h = t[i + 1] - t[i]
    s = np.where(h > 0, (times - t[i]) / np.where(h > 0, h, 1.0), 1.0)
    q0, q1, v0, v1 = y[:n, i], y[:n, i + 1], y[n:, i], y[n:, i + 1]
    q = ((2 * s ** 3 - 3 * s ** 2 + 1) * q0 + (s ** 3 - 2 * s ** 2 + s) * h * v0
         + (3 * s ** 2 - 2 * s ** 3) * q1 + (s ** 3 - s ** 2) * h * v1)
    return np.vstack([q, (1 - s) * v0 + s * v1])


def zigzag(a, b, coils=6, width=0.05):
    """Points of a zig-zag spring from a to b: straight ends, `coils` teeth of half-width `width`."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    d = b - a
    length = np.hypot(*d)
    if length == 0:
        return np.array([a, b])
    along, across = d / length, np.array([-d[1], d[0]]) / length
    s = np.concatenate([[0.0, 0.15], np.linspace(0.15, 0.85, 2 * coils + 1)[1:-1], [0.85, 1.0]])
    offset = np.zeros_like(s)
    offset[2:-2] = width * np.where(np.arange(len(s) - 4) % 2 == 0, 1.0, -1.0)
    return a + np.outer(s * length, along) + np.outer(offset, across)


def scene_limits(tracks):
    """(xmin, xmax, ymin, ymax) enclosing every drawn point (and body outline) over all frames,
    with a margin."""
    points = []
    for kind, data in tracks:
        if kind == "body":
            points.append(np.asarray(data[0]).reshape(-1, 2))
            if data[2] is not None:
                reach = max(abs(v) for v in data[2][1:])
                points.append(np.asarray(data[0]).reshape(-1, 2) + reach)
                points.append(np.asarray(data[0]).reshape(-1, 2) - reach)
        elif kind == "point":
            points.append(np.asarray(data[0]).reshape(-1, 2))
        else:
            points.extend(np.asarray(arr).reshape(-1, 2) for arr in data)
    allpts = np.concatenate(points)
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    size = span_of(lo, hi)
    centre = (lo + hi) / 2
    half = 0.5 * size * 1.2 + 0.05 * size
    return centre[0] - half, centre[0] + half, centre[1] - half, centre[1] + half


class Scene:
    """The artists of one animation frame, updated in place frame by frame."""

    def __init__(self, ax, tracks, size):
        self.tracks, self.size = tracks, size
        self.artists = []
        for (kind, data), ms in zip(tracks, marker_sizes(tracks)):
            if kind == "point":
                artist, = ax.plot([], [], "o", color="tab:blue", markersize=ms, zorder=3)
            elif kind == "body" and data[2] is not None:
                artist = (ax.plot([], [], "-", color="tab:orange", linewidth=2.5, zorder=3)[0],
                          ax.plot([], [], "-", color="tab:red", linewidth=1.5, zorder=4)[0])
            elif kind == "body":
                artist = (ax.plot([], [], "s", color="tab:orange", markersize=ms, zorder=3)[0],
                          ax.plot([], [], "-", color="tab:orange", linewidth=2, zorder=3)[0])
            elif kind == "spring":
                artist, = ax.plot([], [], "-", color="tab:green", linewidth=1.2)
            elif kind == "damper":
                artist, = ax.plot([], [], "-", color="tab:purple", linewidth=1.5)
            else:
                artist, = ax.plot([], [], "-", color="black", linewidth=1.5)
            self.artists.append(artist)

    def update(self, k):
        """Move every artist to frame k."""
        for (kind, data), artist in zip(self.tracks, self.artists):
            if kind == "point":
                artist.set_data([data[0][k, 0]], [data[0][k, 1]])
            elif kind == "body":
                centre, a, shape = data[0][k], data[1][k], data[2]
                if shape is not None:
                    outline = shape_outline(shape, centre, a)
                    artist[0].set_data(outline[:, 0], outline[:, 1])
                    reach = shape[1] if shape[0] == "disk" else shape[1] / 2
                    spoke = np.array([centre, centre + reach * np.array([np.cos(a), np.sin(a)])])
                    artist[1].set_data(spoke[:, 0], spoke[:, 1])
                else:
                    (x, y), tick = centre, 0.08 * self.size
                    artist[0].set_data([x], [y])
                    artist[1].set_data([x, x + tick * np.cos(a)], [y, y + tick * np.sin(a)])
            elif kind == "spring":
                pts = zigzag(data[0][k], data[1][k], width=0.025 * self.size)
                artist.set_data(pts[:, 0], pts[:, 1])
            elif kind == "damper":
                pts = dashpot(data[0][k], data[1][k], width=0.02 * self.size)
                artist.set_data(pts[:, 0], pts[:, 1])
            else:
                pts = np.array([d[k] for d in data])
                artist.set_data(pts[:, 0], pts[:, 1])


def frames_png(model, sol, prefix, count=4, params=None, dpi=80, title=None):
    """Save `count` equally spaced frames of the animation as `<prefix><k>.png`; return the paths
    (to look at a mechanism without a GIF viewer)."""
    p = solution_parameters(model, sol, params)
    times, y = frame_states(sol, count)
    tracks = drawable_tracks(model, p, times, y[:len(model.q)])
    xmin, xmax, ymin, ymax = scene_limits(tracks)
    paths = []
    for k, t in enumerate(times):
        fig = new_figure(5, 5)
        ax = fig.add_subplot(1, 1, 1)
        ax.set_xlim(xmin, xmax)
        ax.set_ylim(ymin, ymax)
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
        ax.set_title(f"{title or model.name}, t = {t:.2f}")
        Scene(ax, tracks, xmax - xmin).update(k)
        path = f"{prefix}{k}.png"
        fig.savefig(path, dpi=dpi)
        paths.append(path)
    return paths


def check_drawable(model):
    """LagrgenError unless `model` has something to draw."""
    if not model.drawables:
        raise LagrgenError(
            f"model {model.name!r} has nothing to draw: add particles, rigid bodies, "
            "model.line(...) or springs/dampers with ends=(a, b)")


def animation_frames(sol, fps, max_frames):
    """(times, y at those times): equally spaced, `fps` frames per simulated second, between 2
    and `max_frames` frames."""
    duration = float(sol.t[-1] - sol.t[0])
    return frame_states(sol, int(np.clip(round(duration * fps), 2, max_frames)))


def mechanism_scene(model, times, q, p, title=None):
    """(figure, scene, clock text) of the mechanism along q (n × frames): on 2-D axes, or on
    matplotlib's 3-D axes for a 3-D model; `scene.update(k)` moves it to frame k."""
    check_drawable(model)
    if is_3d(model):
        from .animation3d import scene_3d
        return scene_3d(model, times, q, p, title=title)
    tracks = drawable_tracks(model, p, times, q)
    xmin, xmax, ymin, ymax = scene_limits(tracks)
    fig = new_figure(5, 5)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_title(title or model.name)
    scene = Scene(ax, tracks, xmax - xmin)
    clock = ax.text(0.02, 0.96, "", transform=ax.transAxes, va="top")
    return fig, scene, clock


def animate(model, sol, path, params=None, fps=20, max_frames=120, dpi=80, title=None):
    """Write an animated GIF of `model.drawables` moving along the solution `sol` (y = [q, q̇]).

    `params` are the parameter values used in the simulation (None, a dict or a full array). The
    frames are equally spaced in time, at `fps` frames per simulated second up to `max_frames`.
    """
    check_drawable(model)
    p = solution_parameters(model, sol, params)
    times, y = animation_frames(sol, fps, max_frames)
    if is_3d(model):                      # 3-D bodies or 3-component points: matplotlib's 3-D axes
        return animate_3d(model, times, y[:len(model.q)], path, p, fps=fps, dpi=dpi, title=title)
    fig, scene, clock = mechanism_scene(model, times, y[:len(model.q)], p, title)
    return write_frames(fig, path, times, scene, clock, fps, dpi)


def plot_sweep(result, path=None, title=None, linear=None):
    """The sweep's measure of each coordinate against the swept value (markers: nonlinear runs;
    lines: `linear`, an optional (k, n) array such as A·|H(ω)| of the linearized model)."""
    fig = new_figure(7, 4)
    ax = fig.subplots()
    for i, name in enumerate(result.coordinates):
        line, = ax.plot(result.values, result.table[:, i], "o", ms=3.5,
                        label=f"{name} ({result.measure}, simulated)")
        if linear is not None:
            ax.plot(result.values, np.asarray(linear)[:, i], "-", color=line.get_color(),
                    alpha=0.7, label=f"{name} (linear model)")
    bad = ~np.asarray(result.success, dtype=bool)
    if bad.any():
        for x in result.values[bad]:
            ax.axvline(x, color="red", alpha=0.3)
    ax.set_xlabel(result.name)
    ax.set_ylabel(result.measure)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if title:
        ax.set_title(title)
    return finished(fig, path)
