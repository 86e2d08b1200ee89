"""Plots of time histories stay readable at any number of lines (issue 45 item 9): every legend
lies inside the figure and over no panel, and no two lines of one panel share a colour; at 6, 18
and 101 joints as a robot's --plot draws them."""
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from lagrgen.outputs.plotting import LINES_PER_PANEL, plot_series, plot_time_history


def joint_run(n, seed=0):
    """A run of n joints (names as long as a vendor's) whose curves differ."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, 50)
    y = np.sin(np.outer(rng.uniform(0.5, 5.0, 2 * n), t) + rng.uniform(0, 6, (2 * n, 1)))
    names = [f"hand_right_index_virtual_{k}_joint" for k in range(n)]
    return SimpleNamespace(t=t, y=y), names


def check_readable(fig, lines):
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    page = fig.bbox
    axes = fig.axes
    drawn = 0
    for ax in axes:
        colours = [to_rgba(line.get_color()) for line in ax.get_lines() if
                   not line.get_label().startswith("_")]
        assert 0 < len(colours) <= LINES_PER_PANEL + 1
        assert len(set(colours)) == len(colours), "two lines of one panel share a colour"
        drawn += len([line for line in ax.get_lines() if line.get_linestyle() == "-"])
        legend = ax.get_legend().get_window_extent(renderer)
        assert page.x0 <= legend.x0 and legend.x1 <= page.x1 + 0.5
        assert page.y0 <= legend.y0 and legend.y1 <= page.y1 + 0.5
        for other in axes:
            assert not legend.overlaps(other.get_window_extent(renderer)), \
                "a legend covers a panel"
            if other is not ax:
                assert not legend.overlaps(other.get_legend().get_window_extent(renderer))
        labels = [text.get_text() for text in ax.get_legend().get_texts()]
        assert labels == [line.get_label() for line in ax.get_lines()
                          if not line.get_label().startswith("_")]
    assert drawn == lines


@pytest.mark.parametrize("n", [6, 18, 101])
def test_every_legend_lies_beside_its_panel_and_no_colour_repeats_in_one(n):
    run, names = joint_run(n)
    units = {name: "rad" for name in names[:-2]} | {name: "m" for name in names[-2:]}
    rates = {f"{name}'": f"{unit}/s" for name, unit in units.items()}
    check_readable(plot_time_history(run, names, units=units), 2 * n)
    if n > 20:
        return                       # the other figures of many panels: as fast as the robot's
    check_readable(plot_time_history(run, names), 2 * n)
    series = plot_series(run.t, run.y[:n], names[:n], {**units, **rates})
    check_readable(series, n)
    assert len(series.axes) == 1 + -(-(n - 2) // LINES_PER_PANEL)


def test_a_hybrid_runs_switches_join_the_first_legend():
    run, names = joint_run(3)
    run.transitions = [(0.2, "contact", "impact"), (0.5, "contact", "stick")]
    fig = plot_time_history(run, names)
    labels = [text.get_text() for text in fig.axes[0].get_legend().get_texts()]
    assert labels == names + ["impact", "stick"]
    check_readable(fig, 2 * 3)
