"""Independent checks of a schedule: continuous-time replay, and the STN's bounds.

The replay reads only the schedule's way-points and the robots' radii: it never looks
at the temporal plan graph or the markers that produced the schedule. Every robot moves
in a straight line at constant speed between consecutive way-points (and stays at its
last one). For two robots the relative position is piecewise linear in time, so the
closest approach on each piece has a closed form; the minimum over all pieces is the
exact minimum centre distance of the pair. The contract checked is
``distance >= r_i + r_j + margin`` for every pair.

**One definition of a violation** (:func:`collides`), used by the replay,
``hierplan post --check``, ``hierplan verify`` and the execution's collision count: a
pair violates a required separation ``D`` when its exact minimum centre distance is
below ``D`` (beyond a relative tolerance of 1e-9), **or when the two robots are ever on
one point** (distance ``<= 1e-9`` m), whatever ``D`` is, 0 included.
:func:`required_separation` gives ``D_ij = r_i + r_j + margin``;
:func:`pair_separations` computes every pair's exact minimum distance of
piecewise-linear trajectories (the replay's closed form and exact pruning).

Pairs are pruned exactly: time is cut into windows, every robot's positions in a window
lie in an axis-aligned box, and two robots whose boxes, widened by their radii, half
the margin and half of ``watch``, never overlap in the same window stay farther apart
than ``r_i + r_j + margin + watch`` all the time. They are counted in
``pairs_skipped``; ``all_pairs=True`` checks every pair.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.stn import STN

#: Tolerance of the distance check (metres, relative to the distance, at least 1 m).
TOL = 1e-9
#: Bound checks (seconds).
BOUND_TOL = 1e-6
#: When no pair checked came within the pruning bound, the minimum distance is completed
#: exactly over the skipped pairs if there are at most this many (else only bounded).
EXACT_SKIPPED = 4096


def required_separation(r_i: float, r_j: float, margin: float = 0.0) -> float:
    """The distance robots ``i`` and ``j`` must keep between their centres:
    ``r_i + r_j + margin`` (metres).

    Example
    -------
    >>> required_separation(0.2, 0.3, 0.1)
    0.6
    """
    return float(round(r_i + r_j + margin, 12))


def collides(distance: float | np.ndarray, required: float | np.ndarray) -> np.ndarray | bool:
    """Whether a pair whose smallest centre distance is ``distance`` violates its
    required separation ``required``: closer than ``required`` (beyond a relative
    tolerance :data:`TOL`), or on one point (``distance <= TOL`` metres), whatever
    ``required`` is. This is the one definition every check uses.

    Example
    -------
    >>> collides(0.0, 0.0), collides(0.05, 0.0), collides(0.55, 0.6), collides(0.6, 0.6)
    (True, False, True, False)
    """
    d = np.asarray(distance, dtype=float)
    need = np.asarray(required, dtype=float)
    out = (d < need - TOL * np.maximum(1.0, need)) | (d <= TOL)
    return bool(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class PairSeparations:
    """Exact minimum centre distances of the pairs of robots checked.

    ``pairs`` (P, 2) robot indices ``i < j``; ``distance`` and ``time`` (P,): the
    smallest distance and when it happens; ``required`` (P,): ``D_ij``; ``violated``
    (P,): :func:`collides`. Pairs not listed provably stay at least ``skipped_bound``
    apart (``pairs_skipped`` of them).
    """

    pairs: np.ndarray
    distance: np.ndarray
    time: np.ndarray
    required: np.ndarray
    pairs_skipped: int
    skipped_bound: float

    @property
    def violated(self) -> np.ndarray:
        out = collides(self.distance, self.required)
        return np.asarray(out, dtype=bool).reshape(len(self.distance))

    @property
    def violations(self) -> int:
        """Number of pairs that violate their required separation."""
        return int(np.count_nonzero(self.violated))


def pair_separations(
    times: list[np.ndarray],
    positions: list[np.ndarray],
    radius: np.ndarray,
    margin: float = 0.0,
    *,
    all_pairs: bool = False,
    watch: float = 1.0,
    slack: float = 0.0,
) -> PairSeparations:
    """Exact minimum distance of every pair of piecewise-linear trajectories.

    Robot ``j`` is at ``positions[j][k]`` (metres) at ``times[j][k]`` (increasing),
    moves in straight lines in between and stays at its last point. ``slack`` is
    subtracted from every distance (a sampling bound of the caller). Pairs whose boxes
    never come within ``D_ij + watch`` are skipped exactly (``all_pairs`` checks all).

    Example
    -------
    >>> t = [np.array([0.0, 1.0]), np.array([0.0, 1.0])]
    >>> p = [np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[1.0, 0.0], [0.0, 0.0]])]
    >>> sep = pair_separations(t, p, np.zeros(2))  # head-on: they meet at t = 0.5
    >>> sep.distance.tolist(), sep.time.tolist(), sep.violations
    ([0.0], [0.5], 1)
    """
    K = len(times)
    radius = np.asarray(radius, dtype=float)
    m = float(margin)
    if K < 2:
        z = np.zeros(0)
        return PairSeparations(np.zeros((0, 2), np.int64), z, z, z, 0, math.inf)
    if all_pairs:
        ii, jj = np.triu_indices(K, 1)
        pairs = np.stack([ii, jj], axis=1)
    else:
        horizon = max(float(max(t[-1] for t in times)), 1e-9)
        n_win = int(min(4096, max(1, sum(len(t) for t in times) // K)))
        lo, hi = _boxes(times, positions, n_win, horizon / n_win * (1 + 1e-12))
        pairs = _candidate_pairs(lo, hi, radius + m / 2 + watch / 2 + slack / 2)
    dist = np.empty(len(pairs))
    when = np.empty(len(pairs))
    for k, (a, b) in enumerate(pairs.tolist()):
        dist[k], when[k] = _pair_min(times[a], positions[a], times[b], positions[b])
    dist -= slack
    need = radius[pairs[:, 0]] + radius[pairs[:, 1]] + m if len(pairs) else np.zeros(0)
    skipped = K * (K - 1) // 2 - len(pairs)
    bound = math.inf
    if skipped:
        r = np.sort(radius)
        bound = float(r[0] + r[1] + m + watch)
    return PairSeparations(pairs.astype(np.int64).reshape(-1, 2), dist, when, need, skipped, bound)


def skipped_minimum(
    times: list[np.ndarray],
    positions: list[np.ndarray],
    checked: np.ndarray,
    limit: int = EXACT_SKIPPED,
) -> tuple[float, int, int, float] | None:
    """Exact ``(distance, i, j, time)`` of the closest pair among those not in
    ``checked`` (pairs ``i < j``); None when there is none or more than ``limit``.

    The pruning of :func:`pair_separations` skips pairs that stay far apart; when no
    pair checked came closer than the skipped ones' bound, this gives the true minimum.

    Example
    -------
    >>> t = [np.array([0.0, 1.0])] * 3
    >>> p = [np.array([[0.0, 0.0], [0.0, 0.0]]), np.array([[5.0, 0.0], [3.0, 0.0]]),
    ...      np.array([[9.0, 0.0], [9.0, 0.0]])]
    >>> skipped_minimum(t, p, np.array([[0, 1]]))  # (0, 2) and (1, 2): 1 and 2 at t = 0
    (4.0, 1, 2, 0.0)
    """
    K = len(times)
    ii, jj = np.triu_indices(K, 1)
    checked = np.asarray(checked, dtype=np.int64).reshape(-1, 2)
    keep = ~np.isin(ii * K + jj, checked[:, 0] * K + checked[:, 1])
    ii, jj = ii[keep], jj[keep]
    if not 0 < len(ii) <= limit:
        return None
    best = (math.inf, -1, -1, math.nan)
    for a, b in zip(ii.tolist(), jj.tolist(), strict=True):
        d, t = _pair_min(times[a], positions[a], times[b], positions[b])
        if d < best[0]:
            best = (d, a, b, t)
    return best


def closest_pair(
    sep: PairSeparations,
    times: list[np.ndarray],
    positions: list[np.ndarray],
    slack: float = 0.0,
) -> tuple[float, int, int, float] | None:
    """The closest pair of robots over all pairs: ``(distance, i, j, time)``, the
    distance less ``slack`` (as in ``sep``, made with that slack). The closest pair
    checked, unless pairs were skipped and none checked came within their bound: then
    the closest over all (:func:`skipped_minimum`). None without a pair, or when the
    skipped pairs are too many to measure (the minimum then exceeds
    ``sep.skipped_bound``).

    Example
    -------
    >>> t = [np.array([0.0, 1.0])] * 3
    >>> p = [np.array([[0.0, 0.0], [0.0, 0.0]]), np.array([[5.0, 0.0], [3.0, 0.0]]),
    ...      np.array([[9.0, 0.0], [9.0, 0.0]])]
    >>> closest_pair(pair_separations(t, p, np.zeros(3), watch=0.5), t, p)
    (3.0, 0, 1, 1.0)
    """
    best = (math.inf, -1, -1, math.nan)
    if len(sep.pairs):
        k = int(np.argmin(sep.distance))
        a, b = sep.pairs[k].tolist()
        best = (float(sep.distance[k]), a, b, float(sep.time[k]))
    if sep.pairs_skipped and best[0] + slack > sep.skipped_bound:
        # No pair checked came as close as a skipped one may: measure those too.
        extra = skipped_minimum(times, positions, sep.pairs)
        if extra is None:
            return None
        if extra[0] - slack < best[0]:
            best = (extra[0] - slack, extra[1], extra[2], extra[3])
    return best if best[1] >= 0 else None


@dataclass(frozen=True)
class ReplayReport:
    """Result of :func:`replay`.

    ``min_distance`` is the smallest centre distance over all pairs, reached by
    ``agents`` at ``time`` (``inf`` with fewer than two robots); ``min_distance_exact``
    False: more than ``EXACT_SKIPPED`` pairs were skipped and none checked came within
    ``skipped_bound``, so ``min_distance`` is the smallest over the pairs checked
    (``inf`` if none) and the true one exceeds ``skipped_bound``
    (:meth:`min_distance_text`). ``ok`` says whether every pair kept
    its required distance ``r_i + r_j + margin``; ``worst_gap`` is the smallest
    ``distance - required`` (for ``worst_pair``). ``by_type`` maps each pair of robot
    types to ``(smallest distance, required distance)`` over its pairs checked.
    ``violations`` counts the pairs that violate it (:func:`collides`: too close, or
    ever on one point).
    Skipped pairs stay at least ``skipped_bound`` apart (their required distance plus
    ``watch``).
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    min_distance: float
    agents: tuple[str, str] | None
    time: float | None
    pairs_checked: int
    pairs_skipped: int
    skipped_bound: float
    ok: bool = True
    worst_gap: float = math.inf
    worst_pair: tuple[str, str] | None = None
    by_type: dict[tuple[str, str], tuple[float, float]] = field(default_factory=dict)
    violations: int = 0
    min_distance_exact: bool = True

    def min_distance_text(self) -> str:
        """``"2 m"``, or ``"> 1.1 m"`` when only bounded (never ``inf`` for a real
        pair of robots)."""
        if self.min_distance_exact:
            return f"{self.min_distance:.4g} m"
        return f"> {self.skipped_bound:.4g} m"


def _pair_min(ta: np.ndarray, pa: np.ndarray, tb: np.ndarray, pb: np.ndarray):
    """Exact minimum distance of two piecewise-linear trajectories, and when."""
    tau = np.union1d(ta, tb)
    ra = np.stack([np.interp(tau, ta, pa[:, k]) for k in range(pa.shape[1])], axis=1)
    rb = np.stack([np.interp(tau, tb, pb[:, k]) for k in range(pb.shape[1])], axis=1)
    r = ra - rb
    if len(tau) == 1:
        return float(np.linalg.norm(r[0])), float(tau[0])
    r0 = r[:-1]
    dr = r[1:] - r[:-1]
    dd = np.einsum("ij,ij->i", dr, dr)
    s = np.where(dd > 0, np.clip(-np.einsum("ij,ij->i", r0, dr) / np.where(dd > 0, dd, 1), 0, 1), 0)
    closest = r0 + dr * s[:, None]
    dist = np.sqrt(np.einsum("ij,ij->i", closest, closest))
    k = int(np.argmin(dist))
    last = float(np.linalg.norm(r[-1]))
    if last < dist[k]:
        return last, float(tau[-1])
    return float(dist[k]), float(tau[k] + s[k] * (tau[k + 1] - tau[k]))


def _boxes(
    times: list[np.ndarray], pos: list[np.ndarray], n_win: int, width: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per robot and time window, the box holding all its positions: (K, n_win, dim)."""
    K = len(times)
    dim = pos[0].shape[1]
    edges = np.arange(n_win + 1) * width
    lo = np.empty((K, n_win, dim))
    hi = np.empty((K, n_win, dim))
    for j in range(K):
        t, p = times[j], pos[j]
        at = np.stack([np.interp(edges, t, p[:, k]) for k in range(dim)], axis=1)
        lo[j] = np.minimum(at[:-1], at[1:])
        hi[j] = np.maximum(at[:-1], at[1:])
        win = np.clip((t // width).astype(np.int64), 0, n_win - 1)
        np.minimum.at(lo[j], win, p)
        np.maximum.at(hi[j], win, p)
    return lo, hi


def _candidate_pairs(lo: np.ndarray, hi: np.ndarray, widen: np.ndarray) -> np.ndarray:
    """Unique robot pairs ``(i < j)`` whose widened boxes overlap in some window."""
    K, n_win, dim = lo.shape
    lo = lo - widen[:, None, None]
    hi = hi + widen[:, None, None]
    ext = (hi - lo).reshape(-1, dim)
    cell = max(float(ext.max()), 1e-9)  # every box meets at most 2**dim cells
    origin = lo.reshape(-1, dim).min(axis=0)
    clo = np.floor((lo.reshape(-1, dim) - origin) / cell).astype(np.int64)
    chi = np.floor((hi.reshape(-1, dim) - origin) / cell).astype(np.int64)
    span = chi - clo + 1
    count = np.prod(span, axis=1)
    box = np.repeat(np.arange(K * n_win), count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    dims = chi.max(axis=0) + 1
    key = (box % n_win).astype(np.int64)  # window index first, then the cell
    rem = local
    for k in range(dim):
        sp = span[box, k]
        key = key * int(dims[k]) + clo[box, k] + rem % sp
        rem = rem // sp
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    robot_s = box[order] // n_win
    win_s = box[order] % n_win
    start = np.flatnonzero(np.concatenate(([True], key_s[1:] != key_s[:-1])))
    size = np.diff(np.concatenate((start, [len(key_s)])))
    # All pairs inside each group of one window and cell.
    pos_in = np.arange(len(key_s)) - np.repeat(start, size)
    after = np.repeat(size, size) - pos_in - 1
    first = np.repeat(np.arange(len(key_s)), after)
    offs = np.arange(int(after.sum())) - np.repeat(np.cumsum(after) - after, after)
    second = first + 1 + offs
    a, b = robot_s[first], robot_s[second]
    w = win_s[first]
    keep = a != b
    a, b, w = a[keep], b[keep], w[keep]
    # Exact overlap of the two widened boxes in that window.
    ia, ib = a * n_win + w, b * n_win + w
    lo2, hi2 = lo.reshape(-1, dim), hi.reshape(-1, dim)
    overlap = np.all((lo2[ia] <= hi2[ib]) & (lo2[ib] <= hi2[ia]), axis=1)
    a, b = a[overlap], b[overlap]
    pairs = np.unique(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1), axis=0)
    return pairs.reshape(-1, 2)


def replay(
    schedule: Schedule,
    instance: Instance | None = None,
    *,
    all_pairs: bool | None = None,
    margin: float | None = None,
    watch: float | None = None,
) -> ReplayReport:
    """Exact minimum centre distances of a constant-velocity replay, against the
    required ``r_i + r_j + margin`` of every pair.

    Parameters
    ----------
    instance : Instance, optional
        Gives the robots' radii and types (without it every radius is 0).
    all_pairs : bool
        Check every pair (default: prune pairs that provably stay apart).
    margin : float, optional
        Extra clearance (default: the schedule's :attr:`Schedule.margin`).
    watch : float, optional
        Pairs that come within ``required + watch`` are always checked (default: the
        schedule's scale, i.e. one grid cell or 1 roadmap unit).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (0, 1)], [(2, 0), (2, 1)])
    >>> s = postprocess(inst, Plan.from_paths([[0, 1, 2], [3, 4, 5]]), margin=0.25)
    >>> rep = replay(s, inst)
    >>> rep.min_distance, rep.ok  # two robots side by side, one cell apart
    (1.0, True)
    """
    K = schedule.num_agents
    if instance is not None and instance.num_agents == K:
        radius = np.array([a.kinematics.radius for a in instance.agents], dtype=float)
        types = [a.kinematics.robot_type for a in instance.agents]
    else:
        radius = np.zeros(K)
        types = ["robot"] * K
    m = float(schedule.margin if margin is None else margin)
    watch = float(schedule.scale if watch is None else watch)
    times = [np.asarray(wp.arrival, dtype=float) for wp in schedule.waypoints]
    pos = [np.asarray(wp.coords, dtype=float) * schedule.scale for wp in schedule.waypoints]
    if K < 2:
        return ReplayReport(math.inf, None, None, 0, 0, math.inf)
    sep = pair_separations(times, pos, radius, m, all_pairs=bool(all_pairs), watch=watch)
    best = (math.inf, None, None)
    worst = (math.inf, None)
    by_type: dict[tuple[str, str], tuple[float, float]] = {}
    violated = sep.violated
    for k, (a, b) in enumerate(sep.pairs.tolist()):
        d, t, need = float(sep.distance[k]), float(sep.time[k]), float(sep.required[k])
        names = (schedule.agent_names[a], schedule.agent_names[b])
        if d < best[0]:
            best = (d, names, t)
        if d - need < worst[0]:
            worst = (d - need, names)
        key = (min(types[a], types[b]), max(types[a], types[b]))
        old = by_type.get(key, (math.inf, 0.0))
        by_type[key] = (min(old[0], d), max(old[1], need))
    ok = not bool(violated.any())
    closest = closest_pair(sep, times, pos)
    exact = closest is not None
    if closest is not None and closest[0] < best[0]:
        names = (schedule.agent_names[closest[1]], schedule.agent_names[closest[2]])
        best = (closest[0], names, closest[3])
    return ReplayReport(
        best[0],
        best[1],
        best[2],
        len(sep.pairs),
        sep.pairs_skipped,
        sep.skipped_bound,
        ok,
        worst[0],
        worst[1],
        by_type,
        int(np.count_nonzero(violated)),
        exact,
    )


def check_bounds(stn: STN, times: np.ndarray, tol: float = BOUND_TOL) -> list[str]:
    """Every STN bound the node ``times`` break (an empty list when all hold).

    Example
    -------
    >>> from hierplan_opt import Graph, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1]])))
    >>> check_bounds(stn, np.array([0.0, 1.0])), len(check_bounds(stn, np.array([0.0, 0.5])))
    ([], 1)
    """
    out = []
    tpg = stn.tpg
    diff = times[stn.arc_dst] - times[stn.arc_src]
    scale = np.maximum(1.0, np.abs(times[stn.arc_dst]))
    bad_lo = np.flatnonzero(diff < stn.lb - tol * scale)
    bad_hi = np.flatnonzero(diff > stn.ub + tol * scale)
    for k in bad_lo.tolist():
        u, v = int(stn.arc_src[k]), int(stn.arc_dst[k])
        out.append(
            f"{tpg.label(u)} -> {tpg.label(v)}: {diff[k]:.6g} s < lower bound {stn.lb[k]:.6g} s"
        )
    for k in bad_hi.tolist():
        u, v = int(stn.arc_src[k]), int(stn.arc_dst[k])
        out.append(
            f"{tpg.label(u)} -> {tpg.label(v)}: {diff[k]:.6g} s > upper bound {stn.ub[k]:.6g} s"
        )
    for v in np.flatnonzero(times < stn.release - tol).tolist():
        out.append(f"{tpg.label(v)}: time {times[v]:.6g} before its release {stn.release[v]:.6g}")
    for v in np.flatnonzero(times > stn.deadline + tol).tolist():
        out.append(f"{tpg.label(v)}: time {times[v]:.6g} after its deadline {stn.deadline[v]:.6g}")
    bad = np.flatnonzero(~np.isfinite(times))
    for v in bad.tolist():
        out.append(f"{tpg.label(v)}: time {times[v]} is not a finite number")
    return out
