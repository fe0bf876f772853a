"""Gantt-style plot of a schedule: per robot, the arrival window of every way-point.

Each robot is one row. For every vertex way-point a bar spans its arrival window
``[earliest, latest]`` (its slack, latest against the makespan); a tick marks the
scheduled arrival. Markers are drawn as thin ticks, and the critical path is red.

Nothing here selects a matplotlib backend or changes pyplot's state.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

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
    max_agents: int = 60,
):
    """Draw the Gantt chart of ``schedule``; return the matplotlib ``Figure``.

    Like other matplotlib-based libraries it never selects a backend or changes
    matplotlib's global state: with ``ax`` it draws into that Axes; with ``path`` only
    (a file to save, type by extension, see :data:`FIGURE_SUFFIXES`) it builds a
    stand-alone ``Figure`` that pyplot does not track, saves it atomically and returns
    it; with neither it makes a new pyplot figure, which Jupyter shows. Only the first
    ``max_agents`` robots are drawn.

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
    from hierplan_opt.io.files import atomic_path, check_output

    if path is not None:
        check_output(path, what="Gantt chart", suffixes=FIGURE_SUFFIXES)
    K = min(schedule.num_agents, max_agents)
    size = (10.0, 1.0 + 0.35 * K)
    if ax is not None:
        fig = ax.figure
    elif path is not None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=size)
        ax = fig.subplots()
    else:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=size)
    _draw(schedule, ax, K)
    fig.tight_layout()
    if path is not None:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=100)
    return fig


def _draw(schedule: Schedule, ax: Any, K: int) -> None:
    crit = set(schedule.critical_path)
    for j in range(K):
        wp = schedule.waypoints[j]
        y = K - 1 - j
        vert = np.array([k == "vertex" for k in wp.kind])
        if vert.any():
            e, lat = wp.earliest[vert], wp.latest[vert]
            ax.barh(
                np.full(int(vert.sum()), y),
                np.maximum(lat - e, 1e-3 * max(schedule.makespan, 1.0)),
                left=e,
                height=0.6,
                color="tab:blue",
                alpha=0.35,
                edgecolor="tab:blue",
            )
        colors = ["red" if n in crit else "black" for n in wp.node.tolist()]
        sizes = [60 if k == "vertex" else 20 for k in wp.kind]
        ax.scatter(wp.arrival, np.full(len(wp), y), marker="|", c=colors, s=sizes)
    ax.set_yticks(range(K))
    ax.set_yticklabels(list(reversed(schedule.agent_names[:K])), fontsize=8)
    ax.set_xlabel("time [s]")
    ax.axvline(schedule.makespan, color="gray", linestyle="--", linewidth=0.8)
    ax.set_title(
        f"{schedule.objective} schedule ({schedule.method}): makespan "
        f"{schedule.makespan:.3g} s; bars = arrival windows (slack), red = critical path"
    )
