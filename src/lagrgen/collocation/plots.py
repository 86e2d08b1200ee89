"""The figure of a collocation result: coordinates, rates and inputs against time, each with its
unit; the samples of the data terms as dots on their curves' panels."""
import numpy as np

from ..outputs.figures import finished, new_figure
from ..outputs.plotting import label, legend_beside, panel_groups, rate_unit


def plot_result(result, path=None, title=None):
    """Panels q(t), q̇(t) and u(t) (when the model has inputs) of `result`, each of at most
    LINES_PER_PANEL curves of distinct colours with its legend beside it; the Figure."""
    mod = result._problem.mod
    units = dict(getattr(mod, "units", {}) or {})
    units.update({f"{c}_dot": rate_unit(units.get(c)) for c in result.coordinates
                  if units.get(c)})
    n = len(result.coordinates)
    dense = np.linspace(result.t[0], result.t[-1], max(400, 4 * result.t.size))
    states = result.state_at(dense)
    names = list(result.coordinates) + [f"{c}_dot" for c in result.coordinates]
    curves = [(dense, states[i]) for i in range(2 * n)]
    groups = [("coordinates", list(range(n))), ("rates", list(range(n, 2 * n)))]
    if result.inputs:
        L = result._layout
        points = L.point_block(result.x)[:, L.offset("u"):L.offset("u") + L.nu].T
        groups.append(("inputs", list(range(2 * n, 2 * n + len(result.inputs)))))
        names += list(result.inputs)
        curves += [(result.t_points, row) for row in points]
    panels = panel_groups(groups)
    fig = new_figure(7.5 + 0.07 * max(len(label(name, units)) for name in names),
                     2.3 * len(panels) + 0.8)
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    placed = {}
    for ax, (what, members) in zip(axes, panels):
        for k, i in enumerate(members):
            ax.plot(*curves[i], label=label(names[i], units), color=f"C{k}")
            placed[names[i]] = (ax, f"C{k}")
        ax.set_ylabel(what)
        ax.grid(True, alpha=0.3)
    for times, data, _, _, present, tracked in result._problem._tracks:
        for r, name in enumerate(tracked):
            if name not in placed:
                continue
            ax, colour = placed[name]
            keep = present[r]
            ax.plot(times[keep] + result.t[0], data[r, keep], ".", ms=3, alpha=0.6,
                    color=colour, label=f"{name} (data)")
    for ax in axes:
        legend_beside(ax)
    axes[-1].set_xlabel("t [s]" if units else "t")
    axes[0].set_title(title or f"{mod.name}: {result.scheme}, objective {result.objective:.6g}")
    return finished(fig, path)


def plot_errors(result, path=None, title=None):
    """Each mesh's relative dynamics error per interval against time (a step at the interval's
    place, log scale), with the tolerance; returns the matplotlib Figure (saved to `path`)."""
    fig = new_figure(9.6, 3.4)
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
    legend_beside(ax)
    ax.set_title(title or f"{result._problem.mod.name}: the dynamics error of each interval")
    return finished(fig, path)
