"""Task assignment: revealed tasks to free robots, greedily or by min-cost matching.

A task's cost for a robot is the travel distance to its first errand plus the length
of the errand chain (exact distances where the tables are affordable, Manhattan
otherwise). ``greedy`` gives each free robot, in turn, the cheapest task left (like the
Start-Kit's default scheduler); ``hungarian`` solves the min-cost assignment of the
free robots to the unassigned tasks at once (scipy's ``linear_sum_assignment``).
Tasks a robot has started (an errand done) stay with it, as the LoRR rules require.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from hierplan_opt.core.errors import InputError
from hierplan_opt.lifelong.model import Distances

SCHEDULERS = ("greedy", "hungarian")
#: Most free robots matched at once (a larger call falls back to greedy).
HUNGARIAN_MAX = 1000
#: Robots per block of the greedy cost matrix.
BLOCK = 512


def chain_length(dist: Distances, errands: Sequence[int]) -> int:
    """Travel from the first errand through the others (estimated where no table).

    Example
    -------
    >>> import numpy as np
    >>> from hierplan_opt.lifelong.model import Grid
    >>> chain_length(Distances(Grid(1, 5, np.zeros(5, dtype=bool))), [0, 4, 2])
    6
    """
    return sum(dist.estimate(a, b) for a, b in zip(errands, errands[1:], strict=False))


def assign(
    kind: str,
    dist: Distances,
    robots: Sequence[int],
    robot_locs: Sequence[int],
    tasks: Sequence[int],
    task_errands: Sequence[Sequence[int]],
    chain: Sequence[int],
) -> dict[int, int]:
    """Robot -> task for the free ``robots`` (at ``robot_locs``) and unassigned ``tasks``.

    ``chain[k]`` is :func:`chain_length` of task ``tasks[k]``.

    Example
    -------
    >>> import numpy as np
    >>> from hierplan_opt.lifelong.model import Grid
    >>> d = Distances(Grid(1, 6, np.zeros(6, dtype=bool)))
    >>> assign("greedy", d, [0, 1], [0, 5], [7, 8], [[4], [1]], [0, 0])
    {0: 8, 1: 7}
    """
    if not robots or not tasks:
        return {}
    if kind not in SCHEDULERS:
        raise InputError(f"unknown scheduler {kind!r} (use: {', '.join(SCHEDULERS)})")
    firsts = np.asarray([e[0] for e in task_errands], dtype=np.int64)
    dist.prefetch(firsts.tolist())
    chain_a = np.asarray(chain, dtype=np.int64)
    if kind == "hungarian" and len(robots) <= HUNGARIAN_MAX:
        cost = _costs(dist, np.asarray(robot_locs, dtype=np.int64), firsts, chain_a)
        ri, ci = linear_sum_assignment(cost)
        return {robots[a]: tasks[b] for a, b in zip(ri.tolist(), ci.tolist(), strict=True)}
    # greedy (also for more free robots than a matching can take in a planning call)
    out: dict[int, int] = {}
    taken = np.zeros(len(tasks), dtype=bool)
    big = np.iinfo(np.int64).max // 2
    locs = np.asarray(robot_locs, dtype=np.int64)
    for s in range(0, len(robots), BLOCK):
        cost = _costs(dist, locs[s : s + BLOCK], firsts, chain_a)
        for row in range(cost.shape[0]):
            if taken.all():
                return out
            k = int(np.argmin(np.where(taken, big, cost[row])))
            taken[k] = True
            out[robots[s + row]] = tasks[k]
    return out


def _costs(dist: Distances, locs: np.ndarray, firsts: np.ndarray, chain: np.ndarray) -> np.ndarray:
    cols = dist.grid.cols
    cost = np.abs(locs[:, None] // cols - firsts[None, :] // cols) + np.abs(
        locs[:, None] % cols - firsts[None, :] % cols
    )
    cids = dist.cid_np[locs]
    for k, g in enumerate(firsts.tolist()):
        t = dist.cache.get(g)
        if t is not None:
            cost[:, k] = np.frombuffer(t, dtype=np.uint16)[cids]
    return cost + chain[None, :]


__all__ = ["SCHEDULERS", "assign", "chain_length"]
