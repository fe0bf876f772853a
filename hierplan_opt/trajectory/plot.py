"""Plots of refined trajectories: position, speed and acceleration against the limits.

Built on ``matplotlib.figure.Figure`` directly (no pyplot, no backend switch), so it
works in any process and leaves the caller's matplotlib state alone.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.trajectory.result import Trajectories


def plot_trajectories(
    traj: Trajectories,
    path: str | Path | None = None,
    *,
    max_agents: int = 12,
    dt: float = 0.05,
) -> Any:
    """Position, speed, acceleration (and turn rate for unicycles) of the first robots.

    Dashed lines mark each robot type's ``v_max``, ``a_max`` (``omega_max``). Returns the
    ``Figure``; saves it when ``path`` is given (format from the extension).

    Example
    -------
    >>> import tempfile, os
    >>> from hierplan_opt.trajectory.result import RobotTrajectory
    >>> r = RobotTrajectory("a", "double_integrator", np.array([0.0, 1.0, 2.0]),
    ...     np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]),
    ...     np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]]),
    ...     np.array([[1.0, 0.0], [-1.0, 0.0]]), np.zeros(3), np.zeros(3), np.zeros(2),
    ...     np.zeros(2), {"v_max": 1.0, "a_max": 1.0})
    >>> T = Trajectories((r,), "path", 0.0, 0.0, 0.0, 1.0, "")
    >>> with tempfile.TemporaryDirectory() as d:
    ...     fig = plot_trajectories(T, os.path.join(d, "t.png"))
    ...     os.path.getsize(os.path.join(d, "t.png")) > 0
    True
    """
    from matplotlib.figure import Figure  # heavy module: matplotlib
    from matplotlib.lines import Line2D  # heavy module: matplotlib

    s = traj.sample(dt)
    K = min(traj.num_agents, max_agents)
    heading = traj.has_heading
    rows = 4 if heading else 3
    fig = Figure(figsize=(10, 2.4 * rows), layout="constrained")
    axes = fig.subplots(rows, 1, sharex=True)
    t = s["t"]
    styles = ("-", "--", ":")
    names = ("x", "y", "z")
    # distinct colours for up to 20 robots (tab20), every robot named in the legend
    palette: list[Any] = [f"C{j}" for j in range(10)]
    if K > 10:
        import matplotlib  # heavy module: matplotlib

        cmap = matplotlib.colormaps["tab20"]
        palette = [cmap(j) for j in range(20)]
    for j in range(K):
        color = palette[j % len(palette)]
        for d in range(traj.dim):
            axes[0].plot(
                t,
                s["pos"][j, :, d],
                styles[d],
                color=color,
                lw=1,
            )
        axes[1].plot(t, np.linalg.norm(s["vel"][j], axis=1), color=color, lw=1)
        axes[2].plot(t, np.linalg.norm(s["acc"][j], axis=1), color=color, lw=1)
        if heading:
            axes[3].plot(t, np.abs(s["omega"][j]), color=color, lw=1)
    _limit_lines(axes[1], traj, "v_max", K)
    _limit_lines(axes[2], traj, "a_max", K)
    if heading:
        _limit_lines(axes[3], traj, "omega_max", K)
        axes[3].set_ylabel("|turn rate| (rad/s)")
    axes[0].set_ylabel("position (m)")
    axes[1].set_ylabel("speed (m/s)")
    axes[2].set_ylabel("|acceleration| (m/s²)")
    axes[-1].set_xlabel("time (s)")
    handles = [
        Line2D([], [], color=palette[j % len(palette)], lw=2, label=traj.robots[j].name)
        for j in range(K)
    ] + [
        Line2D([], [], color="0.3", ls=styles[d], lw=1, label=f"{names[d]} coordinate")
        for d in range(traj.dim)
    ]
    # beside the axes, inside the figure (constrained layout makes room)
    fig.legend(handles=handles, loc="outside right upper", fontsize=7)
    total = traj.num_agents
    shown = f"{K} of {total} robots" if total > K else f"{K} robots"
    fig.suptitle(
        f"refined trajectories ({traj.mode} mode, {shown}, stretch {traj.stretch:.3g}); "
        "dashed: limits"
    )
    if path is not None:
        fig.savefig(str(path), dpi=110)
    return fig


def _limit_lines(ax: Any, traj: Trajectories, key: str, K: int) -> None:
    seen = set()
    for r in traj.robots[:K]:
        v = float(r.limits.get(key, math.inf))
        if math.isfinite(v) and v not in seen:
            seen.add(v)
            ax.axhline(v, color="k", ls="--", lw=0.8)
