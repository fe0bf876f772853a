"""Decoupled time windows: refine every robot on its own without breaking a precedence.

The STN's ranges ``[earliest_v, latest_v]`` are not independent: for a Type-2 arc
``u -> v`` (robot k may pass ``v`` only ``lb`` after robot j passed ``u``) a late
``t_u`` and an early ``t_v`` can each lie in its range while ``t_v - t_u < lb``. A
*temporal decoupling* (Hunsberger, "Algorithms for a temporal decoupling problem in
multi-agent planning", AAAI 2002) tightens the ranges to windows ``[lo_v, hi_v]`` such
that **any** choice of times inside the windows satisfies every constraint between
robots; each robot can then be refined alone.

Construction. Let ``t*`` be the schedule's times (a consistent solution). For an arc
``u -> v`` with ``lb <= t_v - t_u <= ub`` between two robots, its slack is
``s = t*_v - t*_u - lb >= 0``; give the fraction ``beta`` of it to ``u`` and the rest
to ``v``::

    hi_u <= t*_u + beta s,        lo_v >= t*_v - (1 - beta) s

so ``lo_v - hi_u >= t*_v - t*_u - s = lb`` (and symmetrically with the slack
``ub - (t*_v - t*_u)`` of a finite upper bound). Every window is then intersected with
the STN range ``[earliest, latest]`` (latest against the schedule's makespan, so the
makespan is kept) and the node bounds (release, deadline). Events that no precedence
between robots touches need no window for the decoupling: they keep only their node
bounds (robots' final events keep ``latest``, which holds the makespan). Each window
contains ``t*_v``, so it is never empty and the schedule itself is one choice. The safety
markers are STN events like the vertices, so their precedences are decoupled too.

Events of one robot need no decoupling among themselves: the refinement enforces the
robot's own dynamics, which imply the order and the speed bounds of its pieces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.trajectory.events import EventNetwork

#: Tolerance (seconds) of :func:`violations`.
TOL = 1e-9


@dataclass(frozen=True, eq=False)
class Windows:
    """Per-event windows ``[lo, hi]`` (seconds) of an :class:`EventNetwork`."""

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    network: EventNetwork
    lo: np.ndarray
    hi: np.ndarray
    split: float
    stretch: float = 1.0

    def of(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Windows of robot ``j``'s events in path order."""
        r = self.network.events(j)
        return self.lo[r.start : r.stop], self.hi[r.start : r.stop]

    def stretched(self, factor: float) -> Windows:
        """The windows of the schedule slowed down by ``factor >= 1`` (all times scaled).

        Scaling keeps the decoupling (``factor (lo_v - hi_u) >= lb`` for ``lb >= 0``)
        but may pass a deadline; :func:`violations` with ``deadlines=True`` says so.
        """
        if not factor >= 1.0:
            raise InputError(f"a stretch factor must be >= 1, got {factor!r}")
        lo = self.lo * factor
        hi = self.hi * factor
        for a in (lo, hi):
            a.setflags(write=False)
        return Windows(self.network, lo, hi, self.split, self.stretch * factor)


def decouple(network: EventNetwork, split: float = 0.5) -> Windows:
    """Decoupled windows around the schedule's times (see the module docstring).

    Parameters
    ----------
    split : float in [0, 1]
        Share ``beta`` of each precedence's slack given to the earlier event.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> from hierplan_opt.trajectory.events import from_schedule
    >>> from hierplan_opt.core.instance import Kinematics
    >>> g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    >>> kin = [Kinematics("disc", radius=0.2), Kinematics("slow", v_max=0.15, radius=0.2)]
    >>> inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=kin)
    >>> plan = Plan.from_paths([[3, 4, 5], [1, 1, 4, 7]])  # agent0 crosses first
    >>> net = from_schedule(postprocess(inst, plan, acceleration=False))
    >>> w = decouple(net)
    >>> u, v = int(net.arc_src[0]), int(net.arc_dst[0])  # agent0 leaves, agent1 enters
    >>> [round(float(x), 6) for x in (net.times[u], net.times[v], w.hi[u], w.lo[v])]
    [1.7, 2.0, 1.85, 2.0]
    >>> violations(w)
    []
    """
    if not 0.0 <= split <= 1.0:
        raise InputError(f"split must lie in [0, 1], got {split!r}")
    net = network
    t = net.times
    src, dst = net.arc_src, net.arc_dst
    # Events without a precedence between robots need no window for decoupling; they
    # keep only their node bounds, and the robots' final events their latest time (the
    # makespan).
    tied = np.zeros(net.num_events, dtype=bool)
    tied[src] = tied[dst] = True
    tied[net.agent_ptr[1:] - 1] = True
    lo = np.where(tied, np.maximum(net.earliest, net.release), net.release)
    lo = np.maximum(lo, 0.0)
    hi = np.where(tied, np.minimum(net.latest, net.deadline), net.deadline)
    gap = t[dst] - t[src]
    s_lb = np.maximum(gap - net.arc_lb, 0.0)
    np.minimum.at(hi, src, t[src] + split * s_lb)
    np.maximum.at(lo, dst, t[dst] - (1.0 - split) * s_lb)
    fin = np.isfinite(net.arc_ub)
    if fin.any():
        s_ub = np.maximum(net.arc_ub[fin] - gap[fin], 0.0)
        np.maximum.at(lo, src[fin], t[src[fin]] - split * s_ub)
        np.minimum.at(hi, dst[fin], t[dst[fin]] + (1.0 - split) * s_ub)
    # The schedule's own time always stays inside (guards against rounding).
    lo = np.minimum(lo, t)
    hi = np.maximum(hi, t)
    for a in (lo, hi):
        a.setflags(write=False)
    return Windows(net, lo, hi, float(split))


def violations(windows: Windows, *, tol: float = TOL, deadlines: bool = False) -> list[str]:
    """Why ``windows`` do not decouple the network (empty when they do).

    Checks the worst case of every precedence between robots: the latest time of its
    first event against the earliest of its second (and the reverse for finite upper
    bounds), empty windows, and with ``deadlines`` the STN's node bounds.
    """
    net = windows.network
    lo, hi = windows.lo, windows.hi
    out = []
    for v in np.flatnonzero(lo > hi + tol).tolist():
        out.append(f"{net.where(v)}: empty window [{lo[v]:.6g}, {hi[v]:.6g}]")
    src, dst = net.arc_src, net.arc_dst
    bad = np.flatnonzero(lo[dst] - hi[src] < net.arc_lb - tol)
    for k in bad.tolist():
        u, v = int(src[k]), int(dst[k])
        out.append(
            f"{net.where(u)} may pass at {hi[u]:.6g} and {net.where(v)} at {lo[v]:.6g}, "
            f"closer than the precedence's {net.arc_lb[k]:.6g} s"
        )
    bad = np.flatnonzero(hi[dst] - lo[src] > net.arc_ub + tol)
    for k in bad.tolist():
        u, v = int(src[k]), int(dst[k])
        out.append(f"{net.where(u)} -> {net.where(v)}: upper bound {net.arc_ub[k]:.6g} s")
    if deadlines:
        for v in np.flatnonzero(hi > net.deadline + tol).tolist():
            out.append(f"{net.where(v)}: window ends at {hi[v]:.6g}, after its deadline")
    return out
