"""The figure of a collocation result: coordinates, rates and inputs against time, each with its
unit; the samples of the data terms as dots on their curves' panels."""
import numpy as np

from ..outputs.figures import finished, new_figure
from ..outputs.plotting import label, rate_unit


def plot_result(result, path=None, title=None):
    """Panels q(t), q̇(t) and u(t) (when the model has inputs) of `result`; the Figure."""
    mod = result._problem.mod
    units = dict(getattr(mod, "units", {}) or {})
    units.update({f"{c}_dot": rate_unit(units.get(c)) for c in result.coordinates
                  if units.get(c)})
    panels = [("coordinates", list(result.coordinates), result.y[:len(result.coordinates)]),
              ("rates", [f"{c}_dot" for c in result.coordinates],
               result.y[len(result.coordinates):])]
    if result.inputs:
        L = result._layout
        points = L.point_block(result.x)[:, L.offset("u"):L.offset("u") + L.nu].T
        panels.append(("inputs", list(result.inputs), points))
    fig = new_figure(7, 2.3 * len(panels) + 0.8)
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    dense = np.linspace(result.t[0], result.t[-1], max(400, 4 * result.t.size))
    states = result.state_at(dense)
    colours = {}
    for ax, (what, names, rows) in zip(axes, panels):
        for i, (name, row) in enumerate(zip(names, rows)):
            if what == "inputs":
                line, = ax.plot(result.t_points, row, label=label(name, units))
            else:
                offset = 0 if what == "coordinates" else len(result.coordinates)
                line, = ax.plot(dense, states[offset + i], label=label(name, units))
            colours[name] = line.get_color()
        ax.set_ylabel(what)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="small")
    for times, data, _, _, present, names in result._problem._tracks:
        for r, name in enumerate(names):
            ax = _panel_of(name, result, axes)
            if ax is None:
                continue
            keep = present[r]
            ax.plot(times[keep] + result.t[0], data[r, keep], ".", ms=3, alpha=0.6,
                    color=colours.get(name, "k"), label=f"{name} (data)")
            ax.legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("t [s]" if units else "t")
    axes[0].set_title(title or f"{mod.name}: {result.scheme}, objective {result.objective:.6g}")
    return finished(fig, path)


def _panel_of(name, result, axes):
    if name in result.coordinates:
        return axes[0]
    if name.endswith("_dot") and name[:-4] in result.coordinates:
        return axes[1]
    if name in result.inputs:
        return axes[2]
    return None


def plot_errors(result, path=None, title=None):
    """Each mesh's relative dynamics error per interval against time (a step at the interval's
    place, log scale), with the tolerance; returns the matplotlib Figure (saved to `path`)."""
    fig = new_figure(7, 3.4)
    ax = fig.subplots()
    floor = 1e-16
    for number, mesh in enumerate(result.meshes, start=1):
        errors = np.maximum(np.nan_to_num(mesh.errors, posinf=1e300), floor)
        ax.stairs(errors, mesh.times, baseline=None,
                  label=f"mesh {number}: {mesh.nodes} nodes, largest {mesh.error:.1e}")
    if result.mesh_tol is not None:
        ax.axhline(result.mesh_tol, color="k", ls="--", lw=1, label=f"mesh_tol {result.mesh_tol:g}")
    ax.set_yscale("log")
    ax.set_xlabel("t")
    ax.set_ylabel("relative dynamics error")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    ax.set_title(title or f"{result._problem.mod.name}: the dynamics error of each interval")
    return finished(fig, path)
