"""Pictures of executions: an animation, distance over time, delay absorption per layer.

Every function returns a matplotlib ``Figure`` built without pyplot, so library code
never switches matplotlib's backend; a ``path`` saves it (PNG by extension). The
animation is written frame by frame (GIF with Pillow; MP4 needs ``ffmpeg``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.progress import Progress
from hierplan_opt.io.files import atomic_path, check_output
from hierplan_opt.viz.html import PALETTE
from hierplan_opt.viz.scene import LAYER_COLORS, Scene, scene_from_execution
from hierplan_opt.viz.scene import positions_at as scene_positions

if TYPE_CHECKING:
    from hierplan_opt.execution.simulate import Execution


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
    from matplotlib.figure import Figure  # heavy module: matplotlib

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
    from matplotlib.figure import Figure  # heavy module: matplotlib

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
    source: Any,
    instance: Instance | None,
    path: str | Path,
    *,
    fps: float = 10.0,
    size: tuple[int, int] | None = None,
    speed: float | None = None,
    max_frames: int | None = None,
    until: float | None = None,
    highlight: float = 3.0,
    names: bool | None = None,
    progress: bool | None = False,
) -> Path:
    """Write an animation (``.gif`` or ``.mp4``) of an execution, plan or any
    :class:`~hierplan_opt.viz.scene.Scene`.

    Robots are discs of their radius in their team's (or own) colour with their names
    where they fit, goals are crosses in the robot's colour, a clock runs in the corner,
    a robot that met a disturbance in the last ``highlight`` seconds gets a ring in the
    colour of the layer that handled it, and the pair of robots with the least
    clearance is joined by a dashed line (red when closer than ``r_i + r_j + margin``).
    The legend inside the picture says what each mark means and what is left out.

    ``fps`` frames per second of video, ``speed`` seconds of plan per second of video
    (default: 1, faster for plans over 60 s so that videos last at most 60 s; the clock
    shows the speed),
    ``size`` in pixels (default: 960 or 1280 wide, the map's aspect), ``until`` the last
    moment shown (default: the end); ``max_frames`` caps the frames (the video then runs faster, and
    the clock says so). MP4 uses the ffmpeg of the ``imageio-ffmpeg`` wheel (H.264);
    GIF uses Pillow with one fixed palette. The background is drawn once and every frame
    only redraws the robots (matplotlib blitting), so 200 robots for 60 s of plan take
    seconds. ``progress``: a bar (terminal) or status lines (see
    :class:`~hierplan_opt.core.progress.Progress`); ``None`` decides by the terminal.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt import Graph, Plan
    >>> from hierplan_opt.viz.scene import scene_from_plan
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0)], [(2, 1)])
    >>> f = os.path.join(tempfile.mkdtemp(), "a.gif")
    >>> p = animate(scene_from_plan(inst, Plan.from_paths([[0, 1, 2, 5]])), None, f, fps=2)
    >>> from PIL import Image
    >>> Image.open(p).n_frames
    7
    """

    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".gif", ".mp4"):
        raise InputError(f"{path}: animations are written as .gif or .mp4")
    check_output(path, what="animation", suffixes=(".gif", ".mp4"))
    if isinstance(source, Scene):
        scene = source
    else:
        if instance is None:
            raise InputError("animating an execution needs its instance")
        scene = scene_from_execution(instance, source)
    if speed is None:
        span = scene.end if until is None else min(float(until), scene.end)
        speed = max(1.0, span / 60.0)
    if not (math.isfinite(fps) and fps > 0 and math.isfinite(speed) and speed > 0):
        raise InputError(f"fps and speed must be positive numbers, got {fps} and {speed}")
    w, h = size if size is not None else _auto_size(scene)
    w, h = int(w), int(h)
    if not (64 <= w <= 7680 and 64 <= h <= 4320):
        raise InputError(f"animation size {w}x{h} is outside 64x64 .. 7680x4320 pixels")
    w, h = w - w % 2, h - h % 2  # H.264 wants even sizes
    end = max(scene.end if until is None else min(float(until), scene.end), 1e-9)
    frames = int(math.ceil(end / speed * fps)) + 1
    skip = 1.0
    if max_frames is not None and frames > max_frames:
        skip = (frames - 1) / max(max_frames - 1, 1)
        frames = max(2, int(max_frames))
    times = np.linspace(0.0, end, frames)
    drawer = _Drawer(scene, w, h, highlight, names, faster=skip * speed)
    with Progress(f"animate {path.name}", total=frames, unit="frames", enabled=progress) as bar:
        writer = _GifWriter(fps) if ext == ".gif" else _Mp4Writer(w, h, fps)
        with atomic_path(path) as tmp:
            writer.open(Path(tmp))
            try:
                for t in times:
                    writer.add(drawer.frame(float(t)))
                    bar.advance()
            finally:
                writer.close()
    return path


class _Drawer:
    """The figure of an animation: background drawn once, robots blitted per frame."""

    def __init__(
        self, scene: Any, w: int, h: int, highlight: float, names: bool | None, faster: float
    ) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # heavy module: matplotlib
        from matplotlib.collections import EllipseCollection  # heavy module: matplotlib
        from matplotlib.figure import Figure  # heavy module: matplotlib
        from matplotlib.lines import Line2D  # heavy module: matplotlib

        self.scene = scene
        self.highlight = highlight
        dpi = 100
        fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(fig)
        top, bottom = 58 / h, 48 / h  # title and clock above, legend below the map
        ax = fig.add_axes((0.01, bottom, 0.98, 1 - top - bottom))
        self.fig, self.ax = fig, ax
        g = scene.graph
        _draw_map(ax, g)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        K = scene.num_agents
        if scene.team_names:
            colors = [PALETTE[t % len(PALETTE)] for t in scene.team]
        else:
            colors = [PALETTE[k % len(PALETTE)] for k in range(K)]
        self.colors = np.array([_rgba(c) for c in colors]) if K else np.zeros((0, 4))
        spacing = 1.0 if g.kind == "grid" or not len(g.lengths) else float(np.median(g.lengths))
        point = scene.radius <= 0
        self.radius = np.where(point, 0.3 * spacing, scene.radius)
        # goals (own goals, or team targets) as crosses in the robot's or team's colour
        has = np.isfinite(scene.goals).all(axis=1)
        if has.any():
            gx = scene.goals[has]
            ax.scatter(gx[:, 0], gx[:, 1], marker="x", s=16, c=self.colors[has], lw=1.0, zorder=3)
        if scene.targets is not None and len(scene.targets):
            tc = [
                PALETTE[t % len(PALETTE)]
                for t in (scene.target_team if scene.team_names else [0] * len(scene.targets))
            ]
            ax.scatter(
                scene.targets[:, 0], scene.targets[:, 1], marker="x", s=16, c=tc, lw=1.0, zorder=3
            )
        # pixels per map unit decide whether names fit
        fig.canvas.draw()
        x0, x1 = ax.get_xlim()
        ppu = ax.bbox.width / max(abs(x1 - x0), 1e-9)
        fit = float(np.min(self.radius)) * ppu >= 5 if K else False
        self.names = (fit or K <= 30) if names is None else names
        self.coll = EllipseCollection(
            2 * self.radius,
            2 * self.radius,
            np.zeros(K),
            units="xy",
            offsets=np.zeros((K, 2)),
            offset_transform=ax.transData,
            facecolors=self.colors,
            edgecolors="none",
            zorder=5,
            animated=True,
        )
        ax.add_collection(self.coll)
        # names and the clock are drawn with Pillow on each frame (matplotlib's text
        # layout costs ~20 ms per string and frame)
        self.fontsize = int(np.clip(self.radius.min() * ppu * 1.2, 8, 13)) if K else 10
        self.ppu = ppu
        (self.pair,) = ax.plot([], [], ls="--", lw=1.2, color="0.15", animated=True, zorder=7)
        self.faster = faster
        # legend inside the axes: what each mark means, and what is left out
        handles = []
        if scene.team_names:
            handles += [
                Line2D([], [], marker="o", ls="", color=PALETTE[t % len(PALETTE)], label=n)
                for t, n in enumerate(scene.team_names)
            ]
        elif K <= 12:
            handles += [
                Line2D([], [], marker="o", ls="", color=colors[k], label=scene.names[k])
                for k in range(K)
            ]
        else:
            handles.append(
                Line2D(
                    [],
                    [],
                    marker="o",
                    ls="",
                    color="0.5",
                    label=f"{K} robots (colours repeat every {len(PALETTE)})",
                )
            )
        if has.any() or (scene.targets is not None and len(scene.targets)):
            word = "target" if scene.targets is not None else "goal"
            handles.append(Line2D([], [], marker="x", ls="", color="0.3", label=word))
        self.events = sorted(scene.events, key=lambda e: e["time"])
        if self.events:
            handles += [
                Line2D(
                    [],
                    [],
                    marker="o",
                    ls="",
                    mfc="none",
                    mec=c,
                    mew=2,
                    label=f"disturbance in last {highlight:g} s: {layer}",
                )
                for layer, c in LAYER_COLORS.items()
                if any(e["layer"] == layer for e in self.events)
            ]
        if K >= 2:
            handles.append(
                Line2D([], [], ls="--", color="0.15", label="closest pair (red: too close)")
            )
        if not self.names and K:
            handles.append(
                Line2D([], [], ls="", label="names hidden: too small here (--size, hierplan view)")
            )
        if point.any():
            handles.append(
                Line2D([], [], ls="", label=f"no footprint: drawn r = {0.3 * spacing:.2g}")
            )
        fig.legend(
            handles=handles,
            loc="lower center",
            fontsize=7,
            ncols=min(len(handles), 4),
            frameon=False,
            borderaxespad=0.2,
        )
        fig.text(0.01, 1 - 6 / h, scene.title, fontsize=10, va="top", ha="left")
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(fig.bbox)
        self.layer_rgba = {k: _rgba(v) for k, v in LAYER_COLORS.items()}
        self.event_t = np.array([e["time"] for e in self.events])
        index = {n: k for k, n in enumerate(scene.names)}
        self.event_a = [index.get(e["agent"], -1) for e in self.events]
        self.rad_m = scene.radius * scene.scale
        self.end = scene.end
        from matplotlib import font_manager  # heavy module: matplotlib
        from PIL import ImageFont  # heavy module: Pillow

        mono = font_manager.findfont("DejaVu Sans Mono")
        self.font = ImageFont.truetype(mono, 14)
        self.font_small = ImageFont.truetype(font_manager.findfont("DejaVu Sans"), self.fontsize)

    def frame(self, t: float) -> np.ndarray:
        from PIL import Image, ImageDraw  # heavy module: Pillow
        from scipy.spatial import cKDTree  # heavy module: scipy

        sc = self.scene
        p = scene_positions(sc, t)
        K = sc.num_agents
        self.canvas.restore_region(self.background)
        edges = np.zeros((K, 4))
        widths = np.zeros(K)
        if len(self.event_t):
            lo = int(np.searchsorted(self.event_t, t - self.highlight, side="right"))
            hi = int(np.searchsorted(self.event_t, t, side="right"))
            for i in range(lo, hi):
                k = self.event_a[i]
                if k >= 0:
                    edges[k] = self.layer_rgba.get(self.events[i]["layer"], (0.5, 0.5, 0.5, 1.0))
                    widths[k] = 2.5
        self.coll.set_offsets(p[:, :2])
        self.coll.set_edgecolor(edges)  # type: ignore[arg-type]
        self.coll.set_linewidth(widths)  # type: ignore[arg-type]
        self.ax.draw_artist(self.coll)
        if K >= 2:
            q = p * sc.scale
            dq, iq = cKDTree(q).query(q, k=min(K, 6))
            d, idx = np.asarray(dq), np.asarray(iq)
            req = self.rad_m[:, None] + self.rad_m[idx[:, 1:]] + sc.margin
            left = d[:, 1:] - req
            a = int(np.argmin(left.min(axis=1)))
            b = int(idx[a, 1 + int(np.argmin(left[a]))])
            self.pair.set_data([p[a, 0], p[b, 0]], [p[a, 1], p[b, 1]])
            self.pair.set_color("tab:red" if left.min() < -1e-9 else "0.15")
            self.ax.draw_artist(self.pair)
            dist = (
                f"  closest {sc.names[a]}-{sc.names[b]} {d[a, 1 + int(np.argmin(left[a]))]:.2f} m"
            )
        else:
            dist = ""
        fast = f" (speed x{self.faster:.3g})" if self.faster > 1.0001 else ""
        buf = np.asarray(self.canvas.buffer_rgba())
        img = Image.fromarray(buf[:, :, :3])
        draw = ImageDraw.Draw(img)
        if self.names:
            xy = self.ax.transData.transform(p[:, :2] + np.c_[self.radius * 1.1, 0 * self.radius])
            H = img.height
            for k in range(K):
                draw.text(
                    (xy[k, 0], H - xy[k, 1]),
                    sc.names[k],
                    fill=(20, 20, 20),
                    font=self.font_small,
                    anchor="lm",
                )
        text = f"t = {t:7.2f} s / {self.end:.2f} s{fast}{dist}"
        box = draw.textbbox((10, 28), text, font=self.font)
        draw.rectangle(
            (box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3),
            fill=(255, 255, 255),
            outline=(160, 160, 160),
        )
        draw.text((10, 28), text, fill=(0, 0, 0), font=self.font)
        return np.asarray(img)


def _auto_size(scene: Any) -> tuple[int, int]:
    """960 pixels wide (1280 for maps over 100 cells wide), tall enough for the map's
    aspect plus the title, clock and legend."""
    g = scene.graph
    if g.kind == "grid" and g.shape is not None:
        mw, mh = float(g.shape[0]), float(g.shape[1])
    else:
        span = g.coords[:, :2].max(axis=0) - g.coords[:, :2].min(axis=0)
        mw, mh = max(float(span[0]), 1.0), max(float(span[1]), 1.0)
    w = 1280 if mw > 100 else 960
    h = int(np.clip(w * 0.98 * mh / mw + 110, 320, 1080))
    return w, h


def _rgba(color: str) -> tuple[float, float, float, float]:
    from matplotlib.colors import to_rgba  # heavy module: matplotlib

    r, g, b, a = to_rgba(color)
    return (r, g, b, a)


def _draw_map(ax: Any, g: Any) -> None:
    """The map under an animation: grid cells (grey: blocked share of a 3D column) or
    the roadmap's edges and vertices."""
    if g.kind == "grid" and g.shape is not None:
        W, H = g.shape[0], g.shape[1]
        blocked = ~g.passable
        img = (
            blocked.reshape(g.shape[2], H, W).mean(axis=0)
            if len(g.shape) == 3
            else blocked.reshape(H, W)
        )
        ax.imshow(
            img.astype(float),
            cmap="Greys",
            vmin=0,
            vmax=1.25,
            origin="upper",
            extent=(-0.5, W - 0.5, H - 0.5, -0.5),
            interpolation="nearest",
            zorder=0,
        )
        ax.set_xlim(-0.5, W - 0.5)
        ax.set_ylim(H - 0.5, -0.5)
        return
    from matplotlib.collections import LineCollection  # heavy module: matplotlib

    xy = g.coords[:, :2]
    segs = [(xy[u], xy[int(v)]) for u in range(g.n) for v in g.adj[u] if g.directed or u < v]
    ax.add_collection(LineCollection(segs, colors="0.75", linewidths=1.2, zorder=1))
    ax.scatter(xy[:, 0], xy[:, 1], s=8, color="0.55", zorder=2)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = 0.08 * max(float(np.max(hi - lo)), 1.0)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)


class _GifWriter:
    """Frames quantized against one palette (from the first frame) in a worker thread
    while the next frames are drawn (Pillow releases the GIL there), written by Pillow."""

    def __init__(self, fps: float) -> None:
        self.fps = fps
        self.jobs: list[Any] = []
        self.palette: Any = None
        self.path: Path | None = None
        self.pool: Any = None

    def open(self, path: Path) -> None:
        self.path = path
        self.pool = ThreadPoolExecutor(max_workers=1)

    def _quantize(self, rgb: np.ndarray) -> Any:
        from PIL import Image  # heavy module: Pillow

        return Image.fromarray(rgb).quantize(palette=self.palette, dither=Image.Dither.NONE)

    def add(self, rgb: np.ndarray) -> None:
        from PIL import Image  # heavy module: Pillow

        if self.palette is None:
            self.palette = Image.fromarray(rgb).quantize(
                colors=255, method=Image.Quantize.MEDIANCUT
            )
        self.jobs.append(self.pool.submit(self._quantize, rgb))

    def close(self) -> None:
        frames = [j.result() for j in self.jobs]
        if self.pool is not None:
            self.pool.shutdown()
        if frames and self.path is not None:
            frames[0].save(
                self.path,
                format="GIF",
                save_all=True,
                append_images=frames[1:],
                duration=max(int(round(1000 / self.fps)), 20),
                optimize=True,
                loop=0,
            )
        self.jobs = []


class _Mp4Writer:
    """H.264 through the ffmpeg binary of the imageio-ffmpeg wheel (frames piped in)."""

    def __init__(self, w: int, h: int, fps: float) -> None:
        self.size = (w, h)
        self.fps = fps
        self.gen: Any = None

    def open(self, path: Path) -> None:
        import imageio_ffmpeg  # heavy module (finds its ffmpeg binary)

        self.gen = imageio_ffmpeg.write_frames(
            str(path),
            self.size,
            fps=self.fps,  # type: ignore[arg-type]  # ffmpeg takes fractional rates
            codec="libx264",
            pix_fmt_in="rgb24",
            output_params=["-f", "mp4", "-preset", "veryfast", "-tune", "animation"],
            macro_block_size=2,
            quality=6,
        )
        self.gen.send(None)

    def add(self, rgb: np.ndarray) -> None:
        self.gen.send(np.ascontiguousarray(rgb).tobytes())

    def close(self) -> None:
        if self.gen is not None:
            self.gen.close()
            self.gen = None
