"""Pictures of executions: an animation, distance over time, delay absorption per layer.

Every function returns a matplotlib ``Figure`` built without pyplot, so library code
never switches matplotlib's backend; a ``path`` saves it (PNG by extension). The
animation is written frame by frame (GIF with Pillow; MP4 needs ``ffmpeg``).
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.io.files import atomic_path

if TYPE_CHECKING:
    from hierplan_opt.execution.simulate import Execution

LAYER_COLORS = {"slack": "tab:green", "stn": "tab:orange", "replan": "tab:red", "none": "grey"}


def positions_at(ex: Execution, t: float) -> np.ndarray:
    """Positions ``(K, dim)`` of every robot at time ``t`` (instance coordinates).

    Example
    -------
    >>> from hierplan_opt import Graph, Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> from hierplan_opt.execution import simulate
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> ex = simulate(inst, postprocess(inst, Plan.from_paths([[0, 1, 2]])))
    >>> positions_at(ex, 1.5).tolist()
    [[1.5, 0.0]]
    """
    out = []
    for tr in ex.trajectories:
        out.append([np.interp(t, tr[:, 0], tr[:, k]) for k in range(1, tr.shape[1])])
    return np.array(out, dtype=float)


def distance_over_time(ex: Execution, samples: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Sampled times and the smallest centre distance (metres) over all pairs then.

    The exact minimum over continuous time is ``ex.statistics["min_distance"]``.
    """
    end = max(float(tr[-1, 0]) for tr in ex.trajectories)
    times = np.linspace(0.0, max(end, 1e-9), samples)
    scale = ex.schedule.scale
    d = np.full(samples, np.inf)
    for k, t in enumerate(times):
        p = positions_at(ex, float(t)) * scale
        if len(p) > 1:
            diff = p[:, None, :] - p[None, :, :]
            dist = np.sqrt((diff**2).sum(-1))
            dist[np.diag_indices(len(p))] = np.inf
            d[k] = dist.min()
    return times, d


def plot_distance(ex: Execution, instance: Instance, path: str | Path | None = None) -> Any:
    """Smallest distance between any two robots over time against the guaranteed one.

    Example
    -------
    >>> from hierplan_opt import Graph, Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> from hierplan_opt.execution import simulate
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (0, 1)], [(2, 0), (2, 1)])
    >>> ex = simulate(inst, postprocess(inst, Plan.from_paths([[0, 1, 2], [3, 4, 5]])))
    >>> plot_distance(ex, inst).axes[0].get_ylabel()
    'min distance (m)'
    """
    from matplotlib.figure import Figure

    times, d = distance_over_time(ex)
    st = ex.statistics
    fig = Figure(figsize=(8, 3.5))
    ax = fig.add_subplot()
    ax.plot(times, d, color="tab:blue", label="closest pair (sampled)")
    g = float(st["guaranteed_distance"])
    ax.axhline(g, color="tab:red", ls="--", label=f"guaranteed {g:.3g} m")
    if math.isfinite(st["min_distance"]):
        ax.axhline(
            st["min_distance"],
            color="tab:green",
            ls=":",
            label=f"exact min {st['min_distance']:.3g} m",
        )
    for e in ex.log:
        if e.kind != "random":
            ax.axvline(e.time, color=LAYER_COLORS.get(e.layer, "grey"), alpha=0.4, lw=1)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("min distance (m)")
    ax.set_title(f"{ex.policy}: {st['collisions']} collisions")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    if path is not None:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110)
    return fig


def plot_layers(runs: Sequence[tuple[str, dict[str, int]]], path: str | Path | None = None) -> Any:
    """Share of disturbances handled by each layer, one bar per ``(label, handled)``.

    ``handled`` is ``Execution.statistics["handled"]`` (or a Monte Carlo sum).

    Example
    -------
    >>> fig = plot_layers([("low", {"slack": 9, "stn": 1}), ("high", {"slack": 5, "stn": 5})])
    >>> fig.axes[0].get_ylabel()
    'share of disturbances'
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.5))
    ax = fig.add_subplot()
    bottom = np.zeros(len(runs))
    for layer, color in LAYER_COLORS.items():
        share = np.array([h.get(layer, 0) / max(1, sum(h.values())) for _, h in runs], dtype=float)
        ax.bar([r[0] for r in runs], share, bottom=bottom, color=color, label=layer)
        bottom += share
    ax.set_ylabel("share of disturbances")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    if path is not None:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110)
    return fig


def animate(
    ex: Execution,
    instance: Instance,
    path: str | Path,
    *,
    fps: int = 8,
    max_frames: int = 240,
    highlight: float = 3.0,
) -> Path:
    """Write an animation of the run: robots as discs of their radius with a dashed
    circle of half their safety distance; a robot delayed in the last ``highlight``
    seconds is red and the layer that reacted is shown.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Rectangle

    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".gif", ".mp4"):
        raise InputError(f"{path}: animations are written as .gif or .mp4")
    if ext == ".mp4" and shutil.which("ffmpeg") is None:
        raise InputError(f"{path}: MP4 needs ffmpeg on the PATH; write a .gif instead")
    g = instance.graph
    scale = ex.schedule.scale
    margin = ex.schedule.margin
    end = max(float(tr[-1, 0]) for tr in ex.trajectories)
    frames = int(min(max_frames, max(2, math.ceil(end * fps) + 1)))
    times = np.linspace(0.0, end, frames)
    fig = Figure(figsize=(8, 5))
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    coords = g.coords[:, :2]
    for v in np.flatnonzero(~g.passable).tolist():
        x, y = coords[v]
        ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, color="0.3"))
    lo = coords.min(axis=0) - 1
    hi = coords.max(axis=0) + 1
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])
    ax.set_aspect("equal")
    radius = [a.kinematics.radius / scale for a in instance.agents]
    discs, rings = [], []
    for k in range(len(ex.agent_names)):
        r = max(radius[k], 0.08)
        discs.append(ax.add_patch(Circle((0, 0), r, color="tab:blue", alpha=0.8)))
        rings.append(
            ax.add_patch(
                Circle((0, 0), r + margin / 2 / scale, fill=False, ls="--", color="tab:blue")
            )
        )
    label = ax.text(0.01, 0.99, "", transform=ax.transAxes, va="top", fontsize=9)
    images = []
    writer: Any = None
    ctx: Any = None
    if ext == ".mp4":
        from matplotlib.animation import FFMpegWriter

        writer = FFMpegWriter(fps=fps)
        ctx = writer.saving(fig, str(path), 100)
        ctx.__enter__()
    try:
        for t in times:
            p = positions_at(ex, float(t))
            recent = [e for e in ex.log if t - highlight <= e.time <= t and e.agent != "-"]
            late = {e.agent for e in recent}
            for k, name in enumerate(ex.agent_names):
                color = "tab:red" if name in late else "tab:blue"
                discs[k].center = (p[k, 0], p[k, 1])
                discs[k].set_color(color)
                rings[k].center = (p[k, 0], p[k, 1])
                rings[k].set_edgecolor(color)
            layers = ", ".join(f"{e.agent} {e.kind} -> {e.layer}" for e in recent[-3:])
            label.set_text(f"t = {t:6.2f} s  {layers}")
            if writer is not None:
                writer.grab_frame()
            else:
                canvas.draw()
                from PIL import Image

                rgba = np.asarray(canvas.buffer_rgba())
                images.append(Image.fromarray(rgba).convert("P"))
    finally:
        if ctx is not None:
            ctx.__exit__(None, None, None)
    if images:
        with atomic_path(path) as tmp:
            images[0].save(
                tmp, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0
            )
    return path
