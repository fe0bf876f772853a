"""Static plots of instances, plans and solver comparisons (matplotlib).

* :func:`plot_instance` draws the map (grid cells or roadmap), obstacles, starts and
  goals (targets in team colours for TAPF);
* :func:`plot_plan` adds every robot's path (optionally cut to a time window, with the
  robots' positions at its end);
* :func:`plot_layers` draws a 3D grid one z-layer per panel (the other two functions
  show 3D grids projected onto the x-y plane, or one layer with ``layer=z``);
* :func:`format_table` and :func:`plot_runtime_table` turn rows of solver results into
  a text table and a runtime-vs-agents chart.

Nothing here selects a matplotlib backend: the functions work under ``Agg`` (scripts,
CI) as well as in Jupyter. When ``ax`` is None a new figure is made with
``matplotlib.pyplot``; close it with ``plt.close(ax.figure)`` when done.

Grids are drawn in cell coordinates with ``y`` growing downwards (the MovingAI
convention: x = column, y = row); roadmaps in their own coordinates, ``y`` up.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.io.files import atomic_path, check_output
from hierplan_opt.viz.gantt import FIGURE_SUFFIXES


# ---------------------------------------------------------------------------- helpers
def _pyplot():
    import matplotlib.pyplot as plt

    return plt


def _new_axes(ax: Any, figsize: tuple[float, float]) -> Any:
    if ax is not None:
        return ax
    # constrained layout keeps legends placed beside the axes inside the figure
    _, ax = _pyplot().subplots(figsize=figsize, layout="constrained")
    return ax


def _place_legend(ax: Any, handles: list[Any]) -> None:
    """Beside the axes when the figure's layout makes room for it (figures made here),
    else inside the axes where it covers least: never cut off at the figure's edge."""
    if ax.figure.get_layout_engine() is not None:
        ax.legend(
            handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False
        )
    else:
        ax.legend(handles=handles, loc="best", fontsize=8, framealpha=0.85)


def _palette(n: int) -> list[tuple[float, float, float, float]]:
    """``n`` distinguishable colours (tab10 up to 10, tab20 up to 20, then hsv)."""
    import matplotlib  # heavy module: matplotlib

    if n <= 10:
        cmap = matplotlib.colormaps["tab10"]
        return [cmap(i) for i in range(n)]
    if n <= 20:
        cmap = matplotlib.colormaps["tab20"]
        return [cmap(i) for i in range(n)]
    cmap = matplotlib.colormaps["hsv"]
    return [cmap(i / n) for i in range(n)]


def agent_colors(instance: Instance, by: str = "auto") -> list[tuple[float, float, float, float]]:
    """One colour per agent: by team (``by="team"``) or one per agent (``"agent"``).

    ``"auto"`` colours by team when the instance has two or more teams, else by agent
    (so that the robots of one anonymous team stay distinguishable).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.tapf(Graph.grid(3, 1), [([(0, 0), (2, 0)], [(1, 0), (0, 0)])])
    >>> c = agent_colors(inst)
    >>> len(c), c[0] == c[1], agent_colors(inst, "team")[0] == agent_colors(inst, "team")[1]
    (2, False, True)
    """
    if by not in ("auto", "team", "agent"):
        raise ValueError(f"colour by 'auto', 'team' or 'agent', not {by!r}")
    if instance.is_tapf and (by == "team" or (by == "auto" and len(instance.teams) > 1)):
        team_col = _palette(len(instance.teams))
        return [team_col[a.team if a.team is not None else 0] for a in instance.agents]
    return _palette(instance.num_agents)


def _extent(instance: Instance) -> float:
    """How many marker-sized items fit along the drawing (sets marker sizes).

    Grids: the longer side in cells. Roadmaps: vertices are points, not cells, so a
    vertex-count proxy (about 1.5 sqrt(n)) is used instead of coordinates.
    """
    g = instance.graph
    if g.kind == "grid" and g.shape is not None:
        return float(max(g.shape[0], g.shape[1]))
    return max(4.0, math.sqrt(g.n) * 1.5)


def _spacing(instance: Instance) -> float:
    """Distance between neighbouring vertices in drawing coordinates."""
    g = instance.graph
    if g.kind == "grid" or not len(g.lengths):
        return 1.0
    return float(np.median(g.lengths))


def _marker_size(instance: Instance) -> float:
    return float(np.clip(2400.0 / _extent(instance), 10.0, 160.0))


def _xy(instance: Instance, vertices: Sequence[int] | np.ndarray) -> np.ndarray:
    """Drawing coordinates (x, y) of vertex ids."""
    return instance.graph.coords[np.asarray(vertices, dtype=np.int64)][:, :2]


def _z(instance: Instance, vertices: Sequence[int] | np.ndarray) -> np.ndarray | None:
    g = instance.graph
    if g.dim < 3:
        return None
    return g.coords[np.asarray(vertices, dtype=np.int64)][:, 2]


def _in_layer(instance: Instance, vertices: Sequence[int], layer: int | None) -> np.ndarray:
    z = _z(instance, vertices)
    if layer is None or z is None:
        return np.ones(len(vertices), dtype=bool)
    return z == layer


def _check_layer(instance: Instance, layer: int | None) -> None:
    g = instance.graph
    if layer is None:
        return
    if g.kind != "grid" or g.shape is None or len(g.shape) != 3:
        raise ValueError("layer= applies only to 3D grids")
    if not 0 <= layer < g.shape[2]:
        raise ValueError(f"layer {layer} is outside the grid's z range 0..{g.shape[2] - 1}")


# ---------------------------------------------------------------------------- map
def _draw_grid(instance: Instance, ax: Any, layer: int | None) -> None:
    g = instance.graph
    assert g.shape is not None
    W, H = g.shape[0], g.shape[1]
    blocked = ~g.passable
    if len(g.shape) == 3:
        cube = blocked.reshape(g.shape[2], H, W)
        # Projection: the fraction of blocked layers above a cell (black = solid column).
        img = cube.mean(axis=0) if layer is None else cube[layer].astype(float)
    else:
        img = blocked.reshape(H, W).astype(float)
    ax.imshow(
        img,
        cmap="Greys",
        vmin=0.0,
        vmax=1.0,
        origin="upper",
        extent=(-0.5, W - 0.5, H - 0.5, -0.5),
        interpolation="nearest",
        zorder=0,
    )
    if W * H <= 1600:  # cell borders help on small maps and clutter big ones
        ax.set_xticks(np.arange(-0.5, W, 1.0), minor=True)
        ax.set_yticks(np.arange(-0.5, H, 1.0), minor=True)
        ax.grid(which="minor", color="0.85", linewidth=0.5, zorder=0.5)
        ax.tick_params(which="minor", length=0)
    ax.set_xlim(-0.5, W - 0.5)
    ax.set_ylim(H - 0.5, -0.5)


def _draw_roadmap(instance: Instance, ax: Any) -> None:
    from matplotlib.collections import LineCollection  # heavy module: matplotlib

    g = instance.graph
    xy = g.coords[:, :2]
    segs = []
    arrows = []
    for u in range(g.n):
        for v in g.adj[u]:
            if g.directed:
                arrows.append((u, v))
            elif u < v:
                segs.append((xy[u], xy[v]))
    if segs:
        ax.add_collection(LineCollection(segs, colors="0.7", linewidths=1.5, zorder=1))
    if len(arrows) > 400:  # arrow heads are slow to draw; plain lines beyond that
        ax.add_collection(
            LineCollection([(xy[u], xy[v]) for u, v in arrows], colors="0.7", zorder=1)
        )
    else:
        for u, v in arrows:
            ax.annotate(
                "",
                xy=xy[v],
                xytext=xy[u],
                arrowprops={"arrowstyle": "-|>", "color": "0.6", "shrinkA": 4, "shrinkB": 4},
                zorder=1,
            )
    ax.scatter(xy[:, 0], xy[:, 1], s=25, color="0.45", zorder=2)
    if g.names is not None and g.n <= 40:
        for v, name in enumerate(g.names):
            ax.annotate(
                name,
                xy[v],
                xytext=(4, 4),
                textcoords="offset points",
                fontsize=8,
                color="0.3",
                zorder=5,
            )
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = 0.08 * max(float(np.max(hi - lo)), 1.0)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)


def _draw_highways(instance: Instance, ax: Any, layer: int | None) -> None:
    if not instance.highways:
        return
    g = instance.graph
    arcs = [
        (u, v)
        for u, v in instance.highways
        if _in_layer(instance, [u], layer)[0] and _in_layer(instance, [v], layer)[0]
    ]
    if not arcs:
        return
    a = _xy(instance, [u for u, _ in arcs])
    b = _xy(instance, [v for _, v in arcs])
    d = b - a
    ax.quiver(
        a[:, 0] + 0.2 * d[:, 0],
        a[:, 1] + 0.2 * d[:, 1],
        0.6 * d[:, 0],
        0.6 * d[:, 1],
        angles="xy",
        scale_units="xy",
        scale=1.0,
        color="tab:olive",
        alpha=0.5,
        width=0.003 if g.kind == "grid" else 0.004,
        zorder=1.5,
    )


def _draw_agents(instance: Instance, ax: Any, layer: int | None, legend: bool) -> None:
    from matplotlib.lines import Line2D  # heavy module: matplotlib

    colors = agent_colors(instance, "team")
    size = _marker_size(instance)
    starts = instance.starts
    keep = _in_layer(instance, starts, layer)
    xy = _xy(instance, starts)
    idx = np.flatnonzero(keep)
    ax.scatter(
        xy[idx, 0],
        xy[idx, 1],
        s=size,
        c=[colors[i] for i in idx] if len(idx) else None,
        marker="o",
        edgecolors="black",
        linewidths=0.6,
        zorder=6,
    )
    if instance.is_tapf:
        team_col = _palette(len(instance.teams))
        for t, team in enumerate(instance.teams):
            tgt = list(team.targets)
            k = np.flatnonzero(_in_layer(instance, tgt, layer))
            if len(k):
                p = _xy(instance, tgt)[k]
                ax.scatter(
                    p[:, 0],
                    p[:, 1],
                    s=1.6 * size,
                    color=team_col[t],
                    marker="*",
                    edgecolors="black",
                    linewidths=0.5,
                    zorder=6,
                )
    else:
        goals = [a.goal for a in instance.agents]
        gl = [int(v) for v in goals if v is not None]
        gi = [i for i, v in enumerate(goals) if v is not None]
        k = [j for j, ok in enumerate(_in_layer(instance, gl, layer)) if ok] if gl else []
        if k:
            p = _xy(instance, gl)[k]
            ax.scatter(
                p[:, 0],
                p[:, 1],
                s=1.6 * size,
                c=[colors[gi[j]] for j in k],
                marker="*",
                edgecolors="black",
                linewidths=0.5,
                zorder=6,
            )
    if not legend:
        return
    handles = [
        Line2D([], [], marker="o", color="0.5", markeredgecolor="black", ls="", label="start"),
        Line2D([], [], marker="*", color="0.5", markeredgecolor="black", ls="", ms=10,
               label="goal" if not instance.is_tapf else "target"),
    ]  # fmt: skip
    if instance.is_tapf:
        team_col = _palette(len(instance.teams))
        handles += [
            Line2D([], [], color=team_col[t], lw=6, label=f"{team.name} ({len(team.agents)})")
            for t, team in enumerate(instance.teams)
        ]
    _place_legend(ax, handles)


def plot_instance(
    instance: Instance,
    ax: Any = None,
    *,
    layer: int | None = None,
    legend: bool = True,
    title: str | None = None,
) -> Any:
    """Draw the map, obstacles, starts (circles) and goals or team targets (stars).

    Parameters
    ----------
    instance : Instance
    ax : matplotlib Axes, optional
        Drawn into; a new figure is made when None.
    layer : int, optional
        3D grids only: draw this z-layer. By default a 3D grid is projected onto the
        x-y plane (grey level = fraction of blocked cells in the column).
    legend : bool
        Marker legend, and one entry per team for TAPF.
    title : str, optional
        Default: the instance name, kind and size.

    Returns
    -------
    matplotlib Axes

    Example
    -------
    >>> import matplotlib.pyplot as plt
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(4, 3, obstacles=[(1, 1)]), [(0, 0)], [(3, 2)])
    >>> ax = plot_instance(inst)
    >>> ax.get_title()
    'instance: MAPF, 1 agents, grid 4x3'
    >>> plt.close(ax.figure)
    """
    _check_layer(instance, layer)
    g = instance.graph
    ax = _new_axes(ax, (7.0, 5.5))
    if g.kind == "grid":
        _draw_grid(instance, ax, layer)
    else:
        _draw_roadmap(instance, ax)
    _draw_highways(instance, ax, layer)
    _draw_agents(instance, ax, layer, legend)
    ax.set_aspect("equal")
    if title is None:
        kind = f"TAPF ({len(instance.teams)} teams)" if instance.is_tapf else "MAPF"
        size = (
            "grid " + "x".join(map(str, g.shape))
            if g.kind == "grid" and g.shape is not None
            else f"roadmap {g.n} vertices"
        )
        title = f"{instance.name}: {kind}, {instance.num_agents} agents, {size}"
        if layer is not None:
            title += f", layer z={layer}"
        elif g.dim == 3:
            title += " (x-y projection)"
    ax.set_title(title, fontsize=10)
    return ax


# ---------------------------------------------------------------------------- plans
def _window(times: int | tuple[int, int] | None, horizon: int) -> tuple[int, int, bool]:
    """(t0, t1, show_positions) for the ``times`` argument of :func:`plot_plan`."""
    if times is None:
        return 0, horizon, False
    if isinstance(times, (int, np.integer)) and not isinstance(times, bool):
        t0, t1 = 0, int(times)
    elif (
        isinstance(times, tuple | list)
        and len(times) == 2
        and all(isinstance(t, (int, np.integer)) and not isinstance(t, bool) for t in times)
    ):
        t0, t1 = int(times[0]), int(times[1])
    else:
        raise ValueError(f"times must be None, a timestep or a (start, end) pair, got {times!r}")
    if t0 < 0 or t1 < t0:
        raise ValueError(f"times must satisfy 0 <= start <= end, got {times!r}")
    return t0, t1, True


def plot_plan(
    instance: Instance,
    plan: Plan,
    ax: Any = None,
    times: int | tuple[int, int] | None = None,
    *,
    layer: int | None = None,
    legend: bool = True,
    title: str | None = None,
    spread: float = 0.08,
    color_by: str = "auto",
    highlight: Sequence[int] | None = None,
    dense: bool | None = None,
) -> Any:
    """Draw the instance and every robot's path.

    Large fleets (``dense``, by default over 40 robots) stay readable: every path is a
    thin faint line (team colours for teams, else one colour), the ``highlight`` robots
    (default: the first five) are drawn in full with their names, and the title says so.

    Parameters
    ----------
    instance, plan
    ax : matplotlib Axes, optional
    times : int or (int, int), optional
        None draws whole paths. A timestep ``t`` draws the paths up to ``t`` and the
        robots' positions at ``t`` (large dots with the agent index); a pair
        ``(t0, t1)`` draws the paths between ``t0`` and ``t1`` and the positions at
        ``t1``. Robots stay at their last vertex after their path ends.
    layer : int, optional
        3D grids: draw only the moves inside this z-layer (default: x-y projection).
    legend : bool
    title : str, optional
        Default: the instance name with the plan's sum of costs and makespan.
    spread : float
        Paths of different robots are shifted by up to ``spread`` times the vertex
        spacing (cells, or the median roadmap edge length) so that shared corridors stay
        readable (0 disables).
    color_by : {"auto", "team", "agent"}
        Path colours, see :func:`agent_colors` (starts and targets always use the
        team colours on TAPF instances).
    highlight : sequence of int, optional
        Robots drawn in full on a dense plot (default: the first five).
    dense : bool, optional
        Faint paths with a highlighted subset; default: more than 40 robots.

    Returns
    -------
    matplotlib Axes

    Example
    -------
    >>> import os, tempfile
    >>> import matplotlib.pyplot as plt
    >>> import hierplan_opt as hp
    >>> g = hp.Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = hp.Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> plan = hp.solve(inst, "cbs").plan
    >>> ax = plot_plan(inst, plan, times=2)
    >>> ax.get_title()
    'instance: SoC 8, makespan 4, t = 2'
    >>> with tempfile.TemporaryDirectory() as d:
    ...     ax.figure.savefig(os.path.join(d, "plan.png"))
    ...     os.path.getsize(os.path.join(d, "plan.png")) > 1000
    True
    >>> plt.close(ax.figure)
    """
    if plan.num_agents != instance.num_agents:
        raise ValueError(
            f"the plan has {plan.num_agents} paths but the instance {instance.num_agents} agents"
        )
    _check_layer(instance, layer)
    horizon = max(plan.horizon, 1)
    t0, t1, show_pos = _window(times, horizon)
    ax = plot_instance(instance, ax, layer=layer, legend=False, title="")
    colors = agent_colors(instance, color_by)
    K = instance.num_agents
    scale = _spacing(instance)
    lw = float(np.clip(60.0 / _extent(instance), 0.8, 3.0))
    dense = K > 40 if dense is None else dense
    full_paths = range(K)
    if dense:
        hl = sorted({int(i) for i in (highlight if highlight is not None else range(min(5, K)))})
        if any(not 0 <= i < K for i in hl):
            raise ValueError(f"highlight lists robots outside 0..{K - 1}: {hl}")
        teams = instance.is_tapf and len(instance.teams) > 1
        faint_col = agent_colors(instance, "team") if teams else [(0.12, 0.47, 0.71, 1.0)] * K
        hl_col = _palette(max(len(hl), 1))
        segs, cols = [], []
        for i, path in enumerate(plan.paths):
            full = [path[min(t, len(path) - 1)] for t in range(t0, max(t1, t0) + 1)]
            xy = _xy(instance, full).astype(float)
            xy[~_in_layer(instance, full, layer)] = np.nan
            segs.append(xy)
            cols.append(faint_col[i])
        from matplotlib.collections import LineCollection  # heavy module: matplotlib

        ax.add_collection(LineCollection(segs, colors=cols, linewidths=0.6, alpha=0.3, zorder=3.5))
        colors = list(colors)
        for n, i in enumerate(hl):
            colors[i] = faint_col[i] if teams else hl_col[n]
        full_paths = hl
        lw = max(lw, 2.0)
    for i, path in ((i, plan.paths[i]) for i in full_paths):
        full = [path[min(t, len(path) - 1)] for t in range(t0, max(t1, t0) + 1)]
        shift = 0.0 if K == 1 else spread * scale * (2.0 * (i % 5) / 4.0 - 1.0)
        xy = _xy(instance, full) + shift
        inside = _in_layer(instance, full, layer)
        # Draw maximal runs of consecutive steps that lie in the shown layer.
        run: list[int] = []
        runs: list[list[int]] = []
        for k, ok in enumerate(inside):
            if ok:
                run.append(k)
            elif run:
                runs.append(run)
                run = []
        if run:
            runs.append(run)
        for r in runs:
            ax.plot(
                xy[r, 0],
                xy[r, 1],
                color=colors[i],
                lw=lw,
                alpha=0.85,
                solid_capstyle="round",
                zorder=4,
                label=instance.agents[i].name if r is runs[0] else None,
            )
        z = _z(instance, full)
        if layer is not None and z is not None:
            # Vertical moves out of the layer: a triangle pointing up or down.
            for k in range(len(full) - 1):
                if inside[k] and not inside[k + 1]:
                    up = z[k + 1] > z[k]
                    ax.scatter(
                        xy[k, 0], xy[k, 1], marker="^" if up else "v", color=colors[i], zorder=5
                    )
        if dense:
            ax.annotate(
                instance.agents[i].name,
                xy[-1],
                xytext=(4, 4),
                textcoords="offset points",
                fontsize=7,
                color="black",
                zorder=8,
            )
        if show_pos and inside[-1]:
            ax.scatter(
                xy[-1, 0],
                xy[-1, 1],
                s=2.2 * _marker_size(instance),
                color=colors[i],
                edgecolors="black",
                linewidths=1.0,
                zorder=7,
            )
            if K <= 30:
                ax.annotate(
                    str(i),
                    xy[-1],
                    ha="center",
                    va="center",
                    fontsize=7,
                    color="white",
                    fontweight="bold",
                    zorder=8,
                )
    if legend:
        from matplotlib.lines import Line2D  # heavy module: matplotlib

        if instance.is_tapf and colors == agent_colors(instance, "team"):
            team_col = _palette(len(instance.teams))
            handles = [
                Line2D([], [], color=team_col[t], lw=3, label=f"{tm.name} ({len(tm.agents)})")
                for t, tm in enumerate(instance.teams)
            ]
        elif K <= 12:
            handles = [
                Line2D([], [], color=colors[i], lw=3, label=a.name)
                for i, a in enumerate(instance.agents)
            ]
        else:
            handles = []
        if dense:
            handles = [
                Line2D([], [], color=(0.12, 0.47, 0.71), lw=0.8, alpha=0.5,
                       label=f"{K} paths (faint)")
            ] + handles + [
                Line2D([], [], color=colors[i], lw=3, label=instance.agents[i].name)
                for i in list(full_paths)[:12]
            ]  # fmt: skip
        handles += [
            Line2D([], [], marker="o", color="0.5", markeredgecolor="black", ls="", label="start"),
            Line2D([], [], marker="*", color="0.5", markeredgecolor="black", ls="", ms=10,
                   label="target" if instance.is_tapf else "goal"),
        ]  # fmt: skip
        if instance.highways:
            handles.append(
                Line2D([], [], marker=">", ls="", color="tab:olive", alpha=0.6, label="highway")
            )
        _place_legend(ax, handles)
    if title is None:
        title = f"{instance.name}: SoC {plan.sum_of_costs}, makespan {plan.makespan}"
        if dense:
            title += f"; {K} robots, {len(full_paths)} highlighted"
        if show_pos:
            title += f", t = {t1}" if t0 == 0 else f", t = {t0}..{t1}"
        if layer is not None:
            title += f", layer z={layer}"
        elif instance.graph.dim == 3:
            title += " (x-y projection)"
    ax.set_title(title, fontsize=10)
    return ax


def plot_layers(
    instance: Instance,
    plan: Plan | None = None,
    *,
    times: int | tuple[int, int] | None = None,
    ncols: int = 3,
    panel_size: float = 3.6,
    color_by: str = "auto",
) -> Any:
    """A 3D grid drawn one z-layer per panel (with the plan's moves inside each layer).

    Triangles mark where a robot leaves the layer upwards or downwards. 2D maps give
    a single panel.

    Returns
    -------
    matplotlib Figure

    Example
    -------
    >>> import matplotlib.pyplot as plt
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 3, 2), [(0, 0, 0)], [(2, 2, 1)])
    >>> fig = plot_layers(inst)
    >>> [ax.get_title() for ax in fig.axes]
    ['z = 0', 'z = 1']
    >>> plt.close(fig)
    """
    g = instance.graph
    layers = g.shape[2] if g.kind == "grid" and g.shape is not None and len(g.shape) == 3 else 1
    ncols = max(1, min(ncols, layers))
    nrows = math.ceil(layers / ncols)
    plt = _pyplot()
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(panel_size * ncols, panel_size * nrows * 0.8), squeeze=False
    )
    for z in range(nrows * ncols):
        ax = axes[z // ncols][z % ncols]
        if z >= layers:
            ax.remove()
            continue
        lay = z if layers > 1 else None
        title = f"z = {z}" if layers > 1 else None
        if plan is None:
            plot_instance(instance, ax, layer=lay, legend=False, title=title)
        else:
            plot_plan(
                instance, plan, ax, times, layer=lay, legend=False, title=title, color_by=color_by
            )
        ax.tick_params(labelsize=7)
    fig.suptitle(instance.name, fontsize=11)
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------------------- tables
def _cell(value: Any, floatfmt: str) -> str:
    value = getattr(value, "value", value)  # Status enum -> its name
    if value is None:
        return "-"
    if isinstance(value, float):
        if math.isnan(value):
            return "-"
        return format(value, floatfmt)
    return str(value)


def format_table(
    rows: Iterable[Mapping[str, Any]],
    columns: Sequence[str] | None = None,
    *,
    floatfmt: str = ".3g",
) -> str:
    """A fixed-width text table of result rows (dicts), numbers right-aligned.

    ``columns`` defaults to every key of the rows in first-seen order. Missing values
    and None print as ``-``; Status values print as their names.

    Example
    -------
    >>> rows = [{"solver": "cbs", "agents": 5, "cost": 101, "runtime": 0.0312},
    ...         {"solver": "mip", "agents": 5, "cost": None, "runtime": 12.5}]
    >>> print(format_table(rows))
    solver  agents  cost  runtime
    ------  ------  ----  -------
    cbs          5   101   0.0312
    mip          5     -     12.5
    """
    rows = list(rows)
    if columns is None:
        seen: list[str] = []
        for r in rows:
            seen += [k for k in r if k not in seen]
        columns = seen
    cells = [[_cell(r.get(c), floatfmt) for c in columns] for r in rows]
    numeric = [
        all(
            isinstance(getattr(r.get(c), "value", r.get(c)), (int, float)) or r.get(c) is None
            for r in rows
        )
        for c in columns
    ]
    widths = [max([len(c)] + [len(row[j]) for row in cells]) for j, c in enumerate(columns)]

    def line(values: Sequence[str]) -> str:
        out = [
            v.rjust(widths[j]) if numeric[j] else v.ljust(widths[j]) for j, v in enumerate(values)
        ]
        return "  ".join(out).rstrip()

    head = "  ".join(
        c.rjust(widths[j]) if numeric[j] else c.ljust(widths[j]) for j, c in enumerate(columns)
    ).rstrip()
    rule = "  ".join("-" * w for w in widths)
    return "\n".join([head, rule] + [line(r) for r in cells])


def plot_runtime_table(
    rows: Iterable[Mapping[str, Any]],
    ax: Any = None,
    *,
    x: str = "agents",
    y: str = "runtime",
    group: str = "solver",
    time_limit: float | None = None,
    logy: bool = True,
    title: str | None = None,
) -> Any:
    """Runtime (or another column) against the number of agents, one line per solver.

    Rows whose ``status`` is neither OPTIMAL nor FEASIBLE (time limit, error) are drawn
    as hollow markers; ``time_limit`` adds a dashed horizontal line.

    Returns
    -------
    matplotlib Axes

    Example
    -------
    >>> import matplotlib.pyplot as plt
    >>> rows = [{"solver": s, "agents": k, "runtime": t * k, "status": "OPTIMAL"}
    ...         for s, t in (("cbs", 0.01), ("mip", 1.0)) for k in (2, 4, 8)]
    >>> ax = plot_runtime_table(rows, time_limit=10)
    >>> [line.get_label() for line in ax.get_lines()][:2]
    ['cbs', 'mip']
    >>> plt.close(ax.figure)
    """
    rows = list(rows)
    ax = _new_axes(ax, (7.0, 4.5))
    groups: list[str] = []
    for r in rows:
        if str(r.get(group)) not in groups:
            groups.append(str(r.get(group)))
    colors = _palette(max(1, len(groups)))
    markers = "osD^v<>ph*"
    for k, name in enumerate(groups):
        pts = sorted(
            (r[x], r[y], str(getattr(r.get("status"), "value", r.get("status", "OPTIMAL"))))
            for r in rows
            if str(r.get(group)) == name and r.get(x) is not None and r.get(y) is not None
        )
        if not pts:
            continue
        xs = np.array([p[0] for p in pts], dtype=float)
        ys = np.array([p[1] for p in pts], dtype=float)
        ok = np.array([p[2] in ("OPTIMAL", "FEASIBLE") for p in pts])
        if logy:
            ys = np.maximum(ys, 1e-4)  # log axes cannot show 0 s
        m = markers[k % len(markers)]
        ax.plot(xs, ys, color=colors[k], marker=m, label=name, lw=1.5)
        if (~ok).any():
            ax.scatter(
                xs[~ok], ys[~ok], s=90, facecolors="white", edgecolors=colors[k], marker=m, zorder=5
            )
    if time_limit is not None:
        ax.axhline(time_limit, color="0.4", ls="--", lw=1, label="time limit")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(y + (" [s]" if y == "runtime" else ""))
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title if title is not None else f"{y} vs {x} (hollow: no result)", fontsize=10)
    return ax


def save_plan_figure(instance: Instance, plan: Plan, path: Any, **kwargs: Any) -> Any:
    """Draw :func:`plot_plan` into a stand-alone figure (not pyplot's) and save it
    atomically (type by extension); return the figure.

    Example
    -------
    >>> import os, tempfile
    >>> import hierplan_opt as hp
    >>> inst = hp.Instance.mapf(hp.Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "p.png")
    >>> fig = save_plan_figure(inst, hp.Plan.from_paths([[0, 1, 2]]), f)
    >>> os.path.getsize(f) > 1000
    True
    """
    from matplotlib.figure import Figure  # heavy module: matplotlib

    check_output(path, what="plan plot", suffixes=FIGURE_SUFFIXES)
    g = instance.graph
    if g.kind == "grid" and g.shape is not None:
        ratio = g.shape[1] / max(g.shape[0], 1)
    else:
        span = g.coords[:, :2].max(axis=0) - g.coords[:, :2].min(axis=0)
        ratio = float(span[1]) / max(float(span[0]), 1e-9)
    width = 11.0
    fig = Figure(figsize=(width, float(np.clip(width * 0.8 * ratio + 0.8, 3.0, 12.0))),
                 layout="constrained")  # fmt: skip
    ax = fig.add_subplot()
    plot_plan(instance, plan, ax, **kwargs)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    return fig


__all__ = [
    "agent_colors",
    "format_table",
    "plot_instance",
    "plot_layers",
    "plot_plan",
    "plot_runtime_table",
    "save_plan_figure",
]
