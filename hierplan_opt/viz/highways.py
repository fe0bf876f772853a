"""A map with its highway arrows and, optionally, the planned paths.

Nothing here selects a matplotlib backend; the function returns the Axes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from typing import Any

from hierplan_opt.core.highways import highway_share
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan


def plot_highways(
    instance: Instance,
    plan: Plan | None = None,
    highways: Iterable[tuple[int, int]] | None = None,
    ax: Any = None,
    *,
    title: str | None = None,
) -> Any:
    """Draw the map, its highways as arrows (the paper's Fig. 2) and the planned paths.

    Parameters
    ----------
    instance
        The instance (its own highways are drawn unless ``highways`` is given).
    plan
        Paths to draw on top (:func:`hierplan_opt.viz.plots.plot_plan`).
    highways
        The directed edges to draw (default: ``instance.highways``).
    title
        Default: the instance name, and with a plan its sum of costs and the share of
        moves on highway edges.

    Example
    -------
    >>> import matplotlib.pyplot as plt
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.highways import corridors
    >>> g = Graph.grid(5, 3, obstacles=[(1, 1), (2, 1), (3, 1)])
    >>> inst = Instance.mapf(g, [(0, 0)], [(4, 2)])
    >>> ax = plot_highways(inst, highways=corridors(g))
    >>> sum(len(c.get_offsets()) for c in ax.collections if hasattr(c, "U"))  # arrows
    12
    >>> plt.close(ax.figure)
    """
    from hierplan_opt.viz.plots import plot_instance, plot_plan

    hw = frozenset(highways) if highways is not None else (instance.highways or frozenset())
    shown = replace(instance, highways=hw)  # plots draws the instance's highways as arrows
    if plan is not None:
        ax = plot_plan(shown, plan, ax, legend=False, title="")
    else:
        ax = plot_instance(shown, ax, legend=False, title="")
    for arrows in ax.collections:  # the highway arrows on top of the paths, in red
        if hasattr(arrows, "U"):
            arrows.set_zorder(4)
            arrows.set_color("tab:red")
            arrows.set_alpha(0.8)
    if title is None:
        title = instance.name
        if plan is not None:
            share = highway_share(plan, hw)
            title += f": SoC {plan.sum_of_costs}, {100 * share:.0f} % of moves on highways"
    ax.set_title(title)
    return ax


__all__ = ["plot_highways"]
