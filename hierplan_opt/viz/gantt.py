"""Gantt-style plot of a schedule: per robot, the arrival window of every way-point.

Each robot is one row. For every vertex way-point a bar spans its arrival window
``[earliest, latest]`` (its slack, latest against the makespan); a tick marks the
scheduled arrival. Markers are drawn as thin ticks, and the critical path is red.
Charts of any size: beyond ``rows`` robots, consecutive robots share a row (every
robot is still drawn), and ``agents=(first, stop)`` draws a range; the figure says
which robots it shows and how they are grouped. The legend is inside the figure.

Nothing here selects a matplotlib backend or changes pyplot's state.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.io.files import atomic_path, check_output
from hierplan_opt.schedule.output import Schedule

#: File types :func:`plot_gantt` can save (matplotlib's own writers, no LaTeX needed).
FIGURE_SUFFIXES = (
    ".png",
    ".pdf",
    ".svg",
    ".svgz",
    ".jpg",
    ".jpeg",
    ".eps",
    ".ps",
    ".tif",
    ".tiff",
    ".webp",
)


def plot_gantt(
    schedule: Schedule,
    path: str | Path | None = None,
    *,
    ax: Any = None,
    rows: int = 60,
    agents: tuple[int, int] | None = None,
    max_agents: int | None = None,
):
    """Draw the Gantt chart of ``schedule``; return the matplotlib ``Figure``.

    Like other matplotlib-based libraries it never selects a backend or changes
    matplotlib's global state: with ``ax`` it draws into that Axes; with ``path`` only
    (a file to save, type by extension, see :data:`FIGURE_SUFFIXES`) it builds a
    stand-alone ``Figure`` that pyplot does not track, saves it atomically and returns
    it; with neither it makes a new pyplot figure, which Jupyter shows.

    At most ``rows`` rows: with more robots, ``ceil(K / rows)`` consecutive robots share
    a row (their bars overlap, darker where they do). ``agents=(first, stop)`` draws
    robots ``first .. stop - 1`` only. Both are written in the figure's title, so
    nothing is left out silently. ``max_agents`` is the old name of ``rows``.

    Example
    -------
    >>> import tempfile, os
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> g = Graph.grid(3, 1)
    >>> s = postprocess(Instance.mapf(g, [(0, 0)], [(2, 0)]), Plan.from_paths([[0, 1, 2]]))
    >>> with tempfile.TemporaryDirectory() as d:
    ...     fig = plot_gantt(s, os.path.join(d, "g.png"))
    ...     os.path.getsize(os.path.join(d, "g.png")) > 0
    True
    """

    if path is not None:
        check_output(path, what="Gantt chart", suffixes=FIGURE_SUFFIXES)
    if max_agents is not None:
        rows = max_agents
    if rows < 1:
        raise InputError(f"a Gantt chart needs at least one row, got rows={rows}")
    K = schedule.num_agents
    first, stop = agents if agents is not None else (0, K)
    if not (0 <= first < stop <= K):
        raise InputError(f"robots {first}..{stop - 1} are not a range of the {K} robots")
    n = stop - first
    per = math.ceil(n / rows)
    R = math.ceil(n / per)
    size = (10.0, 1.9 + 0.3 * R)
    if ax is not None:
        fig = ax.figure
    elif path is not None:
        from matplotlib.figure import Figure  # heavy module: matplotlib

        fig = Figure(figsize=size, layout="constrained")
        ax = fig.subplots()
    else:
        import matplotlib.pyplot as plt  # heavy module: matplotlib

        fig, ax = plt.subplots(figsize=size, layout="constrained")
    _draw(schedule, ax, first, stop, per)
    if path is not None:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=100)
    return fig


def _draw(schedule: Schedule, ax: Any, first: int, stop: int, per: int) -> None:
    from matplotlib.collections import PolyCollection  # heavy module: matplotlib
    from matplotlib.lines import Line2D  # heavy module: matplotlib
    from matplotlib.patches import Patch  # heavy module: matplotlib

    K = schedule.num_agents
    R = math.ceil((stop - first) / per)
    crit = set(schedule.critical_path)
    floor = 1e-3 * max(schedule.makespan, 1.0)
    boxes, xs, ys, colors, sizes = [], [], [], [], []
    for j in range(first, stop):
        wp = schedule.waypoints[j]
        y = R - 1 - (j - first) // per
        vert = np.array([k == "vertex" for k in wp.kind], dtype=bool)
        e, lat = wp.earliest[vert], wp.latest[vert]
        right = np.maximum(lat, e + floor)
        for a, b in zip(e.tolist(), right.tolist(), strict=True):
            boxes.append([(a, y - 0.3), (b, y - 0.3), (b, y + 0.3), (a, y + 0.3)])
        xs.append(wp.arrival)
        ys.append(np.full(len(wp), y))
        colors += ["red" if nd in crit else "black" for nd in wp.node.tolist()]
        sizes.append(np.where(vert, 60, 20))
    alpha = 0.35 if per == 1 else max(0.08, 0.35 / per)
    ax.add_collection(
        PolyCollection(boxes, facecolors="tab:blue", edgecolors="tab:blue", alpha=alpha, lw=0.5)
    )
    if xs:
        ax.scatter(np.concatenate(xs), np.concatenate(ys), marker="|", c=colors,
                   s=np.concatenate(sizes), linewidths=1.0)  # fmt: skip
    names = schedule.agent_names
    labels = []
    for r in range(R):
        a = first + r * per
        b = min(a + per, stop) - 1
        labels.append(names[a] if a == b else f"{names[a]}..{names[b]}")
    ax.set_yticks(range(R))
    ax.set_yticklabels(list(reversed(labels)), fontsize=8 if R <= 40 else 6)
    ax.set_ylim(-0.8, R - 0.2)
    ax.set_xlim(0, schedule.makespan * 1.02 + floor)
    ax.set_xlabel("time [s]")
    ax.axvline(schedule.makespan, color="gray", linestyle="--", linewidth=0.8)
    shown = []
    if (first, stop) != (0, K):
        shown.append(f"robots {first}..{stop - 1} of {K} shown")
    else:
        shown.append(f"all {K} robots")
    if per > 1:
        shown.append(f"{per} robots per row (bars overlap)")
    ax.set_title(
        f"{schedule.objective} schedule ({schedule.method}): makespan {schedule.makespan:.3g} s;"
        f" {', '.join(shown)}",
        fontsize=10,
    )
    handles = [
        Patch(facecolor="tab:blue", alpha=0.35, edgecolor="tab:blue",
              label="arrival window at a vertex (slack)"),
        Line2D([], [], marker="|", ls="", color="black", ms=9, mew=1.5,
               label="scheduled arrival (vertex)"),
        Line2D([], [], marker="|", ls="", color="black", ms=5, mew=1,
               label="safety marker / turn"),
        Line2D([], [], marker="|", ls="", color="red", ms=9, mew=1.5, label="critical path"),
        Line2D([], [], ls="--", color="gray", lw=0.8, label="makespan"),
    ]  # fmt: skip
    fig = ax.figure
    if fig.get_layout_engine() is not None and len(fig.axes) == 1:
        fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8)
    else:
        ax.legend(handles=handles, loc="best", fontsize=7, framealpha=0.9)
