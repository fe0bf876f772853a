"""The ``reorder`` layer: switch passing orders at shared locations (switchable ADG).

After Berndt et al. (IEEE T-RO 2023/2024): when a robot is late, the robots behind it
at a shared location may pass first. Every Type-2 arc joins two *adjacent claims* of
one lock in the TPG's order (robot A leaves, then robot B enters). Switching the pair
swaps the two claims in the lock's order: ``Z -> A -> B -> C`` becomes
``Z -> B -> A -> C`` (arcs ``Z.leave -> B.enter``, ``B.leave -> A.enter``,
``A.leave -> C.enter``). The claims of every lock stay totally ordered, so the
soundness theorem of MAPF-POST still holds and the clearance is kept.

A CP-SAT model over a receding horizon (events planned within ``HORIZON`` seconds, and
the ends of the candidate claims) picks the switches (``formulations/reorder.md``):
integer event times in milliseconds, one Boolean per candidate pair, each arc enforced
only in the orientation chosen, at most one switch per lock, and the objective the sum
over robots of the time of their last event in the horizon. Every cycle of the TPG
contains a robot's own move (positive lower bound), so a feasible assignment is
acyclic: no deadlock. Switches are applied only if they lower the objective.

Candidates: both claims not entered yet, neither a start nor a goal claim; the
missing marker of a claim is replaced by the vertex before (enter) or after (leave),
which lies outside the claimed disc (tight regime) — a conservative choice. Point
robots (plain TPG): a claim is the visit node itself. Not in the general regime.
A pair is switched only when the lock's arcs touching the two claims are exactly the
arc between them and the arcs to their neighbours, and a claim without a neighbour
really is the first (last) of its robot at the lock (:func:`_simple`): a robot that
passes a lock twice in a row has no arc between its passages, and treating its first
passage as the last one left the second unordered with the robot switched behind it
(two point robots on one vertex, issue 30). In the plain TPG a robot already on its way
into the vertex is not switched either (it has no place to wait).
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from hierplan_opt.execution.state import ExecState
from hierplan_opt.schedule.solve_graph import InconsistentSTNError, earliest_times
from hierplan_opt.schedule.stn import PRECEDENCE, STN
from hierplan_opt.schedule.tpg import ENTER, LEAVE, TYPE2

log = logging.getLogger(__name__)

#: Receding horizon (seconds after now) of the model.
HORIZON = 20.0
#: CP-SAT work limit per decision, in CP-SAT's deterministic seconds: a run's switches
#: do not depend on the machine's load (a wall-clock limit made them differ run to run).
WORK_LIMIT = 0.2
#: Wall-clock limit per solve (seconds): the decision is made while robots drive, so a
#: starved machine cuts it here (then switches can differ from run to run).
TIME_LIMIT = 1.0
#: Smallest improvement of the objective worth a switch (seconds).
GAIN = 1e-3


@dataclasses.dataclass(frozen=True)
class _Pair:
    arc: int  # A.leave -> B.enter
    a_enter: int
    a_leave: int
    b_enter: int
    b_leave: int
    lock: int
    before: int  # arc Z.leave -> A.enter (-1 if none)
    after: int  # arc B.leave -> C.enter (-1 if none)


def _claim_ends(stn: STN, sim: ExecState, arc: int) -> _Pair | None:
    """The two adjacent claims joined by precedence ``arc`` (A leaves, B enters) and
    the arcs to their neighbours in the lock's order, from the arcs of that lock."""
    tpg = stn.tpg
    S = sim.S
    u, w = int(stn.arc_src[arc]), int(stn.arc_dst[arc])
    lock = int(sim.locks[arc])
    ja, jb = int(tpg.node_agent[u]), int(tpg.node_agent[w])
    same = np.flatnonzero(sim.locks == lock)
    src, dst = stn.arc_src[same], stn.arc_dst[same]
    a0 = int(tpg.agent_ptr[ja])
    b1 = int(tpg.agent_ptr[jb + 1])
    plain = tpg.regime == "none"
    # A's claim: entered at the last arc of this lock into A's nodes up to u.
    into_a = (dst >= a0) & (dst <= u) & (tpg.node_agent[src] != ja)
    before = int(same[into_a][np.argmax(dst[into_a])]) if into_a.any() else -1
    # B's claim: left at the first arc of this lock out of B's nodes from w on.
    out_b = (src >= w) & (src < b1) & (tpg.node_agent[dst] != jb)
    after = int(same[out_b][np.argmin(src[out_b])]) if out_b.any() else -1
    if plain:
        # Plain TPG: the arc runs from A's arrival at its next vertex (u: it has left
        # the shared vertex) to B's arrival at the shared vertex (w). Switched, B must
        # have reached its next vertex before A reaches the shared one.
        a_enter = int(S.last_vertex[u - 1]) if u - 1 >= a0 else -1
        b_leave = int(S.next_vertex[w + 1]) if w + 1 < b1 else -1
        if a_enter < a0 or b_leave < 0 or b_leave >= b1:
            return None
    elif int(tpg.node_kind[u]) != LEAVE or int(tpg.node_kind[w]) != ENTER:
        return None  # an arc of an earlier switch (vertex to vertex): not a claim's ends
    else:
        a_enter = int(stn.arc_dst[before]) if before >= 0 else int(S.last_vertex[u])
        if before < 0:
            # A is first at the lock: it waits at the vertex before the one it claims.
            va = int(S.last_vertex[u])
            a_enter = int(S.last_vertex[va - 1]) if va > a0 else -1
        b_leave = int(stn.arc_src[after]) if after >= 0 else -1
        if after < 0:
            vb = int(S.next_vertex[w])
            b_leave = int(S.next_vertex[vb + 1]) if vb + 1 < b1 else -1
        if a_enter < a0 or b_leave < 0 or b_leave >= b1:
            return None
    va, vb = int(S.last_vertex[u]), int(S.next_vertex[w]) if not plain else w
    if plain:
        va = a_enter
    if S.first[va] or S.final[vb] or S.first[vb] or S.final[va] or a_enter == a0:
        return None  # start and goal claims stay where they are
    if not (np.isnan(sim.t[a_enter]) and np.isnan(sim.t[w])):
        return None  # a claim already entered
    if plain and not (np.isnan(sim.phys[a_enter]) and np.isnan(sim.phys[w])):
        return None  # a robot already on its way into the vertex (no place to wait)
    if not _simple(stn, sim, same, arc, (a_enter, u), (w, b_leave), before, after):
        return None
    return _Pair(arc, a_enter, u, w, b_leave, lock, before, after)


def _simple(
    stn: STN,
    sim: ExecState,
    same: np.ndarray,
    arc: int,
    a: tuple[int, int],
    b: tuple[int, int],
    before: int,
    after: int,
) -> bool:
    """Whether the switch of claims ``a`` and ``b`` (node ranges enter..leave of the
    two robots) keeps every claim of the lock ordered: the lock's arcs that touch the
    two claims are exactly ``before`` (into A's enter), ``arc`` (A -> B) and ``after``
    (out of B's leave), and A (B) has no other claim of the lock before (after) it
    when it has no neighbour there. Anything else (rotation markers, several
    predecessors, a robot's own earlier or later visit of the lock) is not switched:
    dropping ``before`` or ``after`` there would leave two claims unordered."""
    tpg = stn.tpg
    src, dst = stn.arc_src[same], stn.arc_dst[same]
    allowed = {arc, before, after} - {-1}
    for lo, hi in (a, b):
        touch = ((src >= lo) & (src <= hi)) | ((dst >= lo) & (dst <= hi))
        if not set(same[touch].tolist()) <= allowed:
            return False
    if before >= 0 and int(stn.arc_dst[before]) != a[0]:
        return False  # the predecessor of an earlier claim (or of a marker inside)
    if after >= 0 and int(stn.arc_src[after]) != b[1]:
        return False
    lock = int(sim.locks[arc])
    ja, jb = int(tpg.node_agent[a[0]]), int(tpg.node_agent[b[0]])
    a0, b1 = int(tpg.agent_ptr[ja]), int(tpg.agent_ptr[jb + 1])
    if before < 0:
        # A first at the lock: no earlier claim of A there (an arc or a visit).
        earlier = ((dst >= a0) & (dst < a[0])) | ((src >= a0) & (src < a[0]))
        if earlier.any() or np.any(tpg.node_vertex[a0 : a[0]] == lock):
            return False
    if after < 0:
        later = ((dst > b[1]) & (dst < b1)) | ((src > b[1]) & (src < b1))
        if later.any() or np.any(tpg.node_vertex[b[1] + 1 : b1] == lock):
            return False
    return True


def try_reorder(sim: ExecState, now: float) -> tuple[STN, np.ndarray, np.ndarray, int] | None:
    """Choose switches of passing orders: ``(stn, locks, targets, switches)`` to install
    (the event loop does), or None when none helps. The state is not changed."""
    stn = sim.stn
    tpg = stn.tpg
    if tpg.regime == "general":
        return None
    happened = ~np.isnan(sim.t)
    T = np.where(happened, sim.t, sim.T)
    horizon = (~happened) & (now + HORIZON >= T)
    prec = np.flatnonzero((sim.locks >= 0) & horizon[stn.arc_dst] & ~happened[stn.arc_src])
    pairs = [p for k in prec.tolist() if (p := _claim_ends(stn, sim, k)) is not None]
    if not pairs:
        return None
    nodes = set(np.flatnonzero(horizon).tolist())
    for p in pairs:
        nodes |= {p.a_enter, p.a_leave, p.b_enter, p.b_leave}
        for k in (p.before, p.after):
            if k >= 0:
                nodes |= {int(stn.arc_src[k]), int(stn.arc_dst[k])}
    chosen = _solve(sim, stn, T, happened, sorted(nodes), pairs, now)
    if not chosen:
        return None
    new, locks = _switched(stn, sim.locks, pairs, chosen)
    if not new.topo.is_dag:
        # A cycle through events outside the horizon: keep the switches that stay
        # acyclic, one at a time.
        kept: list[int] = []
        for i in chosen:
            trial, _ = _switched(stn, sim.locks, pairs, [*kept, i])
            if trial.topo.is_dag:
                kept.append(i)
        if not kept:
            return None
        chosen = kept
        new, locks = _switched(stn, sim.locks, pairs, chosen)
    release = np.array(new.release, dtype=float)
    release = np.where(happened, sim.t, np.maximum(release, sim.T0))
    unh = np.flatnonzero(~happened & ~np.isnan(sim.phys))
    release[unh] = np.maximum(release[unh], sim.phys[unh])
    try:
        times = earliest_times(new.with_bounds(release=release))
    except InconsistentSTNError:
        return None  # deadlines: leave it to the STN layer (and re-planning)
    return new, locks, np.where(happened, sim.t, times), len(chosen)


def _solve(
    sim: ExecState,
    stn: STN,
    T: np.ndarray,
    happened: np.ndarray,
    nodes: list[int],
    pairs: list[_Pair],
    now: float,
) -> list[int]:
    from ortools.sat.python import cp_model  # heavy module: OR-Tools

    idx = {v: i for i, v in enumerate(nodes)}
    ms = 1000.0
    big = int(ms * (float(np.nanmax(T)) + 10 * HORIZON + 1e4))
    m = cp_model.CpModel()
    t = [m.new_int_var(0, big, f"t{v}") for v in nodes]
    lo_ms = np.zeros(stn.num_nodes, dtype=np.int64)
    for v in nodes:
        lo = now if not happened[v] else float(sim.t[v])
        if not happened[v] and not np.isnan(sim.phys[v]):
            lo = max(lo, float(sim.phys[v]))
        if happened[v]:
            lo_ms[v] = int(round(lo * ms))
            m.add(t[idx[v]] == int(lo_ms[v]))
        else:
            lo_ms[v] = int(np.ceil(lo * ms - 1e-6))
            m.add(t[idx[v]] >= int(lo_ms[v]))
    x = [m.new_bool_var(f"x{i}") for i in range(len(pairs))]
    owners: dict[int, list[int]] = {}
    for i, p in enumerate(pairs):
        for k in (p.arc, p.before, p.after):
            if k >= 0:
                owners.setdefault(k, []).append(i)
    by_lock: dict[int, list[int]] = {}
    for i, p in enumerate(pairs):
        by_lock.setdefault(p.lock, []).append(i)
    for group in by_lock.values():
        if len(group) > 1:
            m.add(sum(x[i] for i in group) <= 1)
    inside = np.zeros(stn.num_nodes, dtype=bool)
    inside[nodes] = True
    arcs = np.flatnonzero(inside[stn.arc_src] & inside[stn.arc_dst])

    lb = np.ceil(np.asarray(stn.lb, dtype=float) * ms - 1e-6).astype(np.int64)

    def arc(u: int, v: int, lb: int, cond: list) -> None:
        c = m.add(t[idx[v]] >= t[idx[u]] + lb)
        if cond:
            c.only_enforce_if(cond)

    for k in arcs.tolist():
        u, v = int(stn.arc_src[k]), int(stn.arc_dst[k])
        arc(u, v, int(lb[k]), [~x[i] for i in owners.get(k, [])])
    for i, p in enumerate(pairs):
        arc(p.b_leave, p.a_enter, int(lb[p.arc]), [x[i]])
        if p.before >= 0:
            arc(int(stn.arc_src[p.before]), p.b_enter, int(lb[p.before]), [x[i]])
        if p.after >= 0:
            arc(p.a_leave, int(stn.arc_dst[p.after]), int(lb[p.after]), [x[i]])
    tpg = stn.tpg
    lasts = []
    node_set = np.array(nodes)
    agents = tpg.node_agent[node_set]
    for j in np.unique(agents).tolist():
        lasts.append(int(node_set[agents == j].max()))
    m.minimize(sum(t[idx[v]] for v in lasts))
    solver = cp_model.CpSolver()
    solver.parameters.max_deterministic_time = WORK_LIMIT
    solver.parameters.max_time_in_seconds = TIME_LIMIT
    solver.parameters.num_workers = 1
    solver.parameters.random_seed = 0
    current = _current_orders_ms(stn, arcs, lo_ms, lb, happened)
    if current is None:
        return []  # the current orders cannot keep the robots' recorded times
    base = float(current[lasts].sum())
    for xi in x:  # start from the current orders
        m.add_hint(xi, False)
    for v in nodes:
        m.add_hint(t[idx[v]], int(current[v]))
    status = solver.solve(m)
    if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return []
    if solver.objective_value > base - GAIN * ms:
        return []
    return [i for i in range(len(pairs)) if solver.value(x[i])]


def _current_orders_ms(
    stn: STN, arcs: np.ndarray, lo_ms: np.ndarray, lb: np.ndarray, happened: np.ndarray
) -> np.ndarray | None:
    """Earliest times (integer ms) of the model's nodes under the current passing orders:
    the longest path over ``arcs`` (lower bounds ``lb``, ms) from the node bounds
    ``lo_ms``, happened nodes fixed.
    This is the optimum of the model with no switch, computed exactly by the STN's
    topological waves instead of a first CP-SAT solve (it was half of reorder's time).
    None when a happened node's recorded time is earlier than its arcs allow (the model
    is infeasible then)."""
    t = lo_ms.copy()
    use = np.zeros(stn.num_arcs, dtype=bool)
    use[arcs] = True
    topo = stn.topo
    if not topo.is_dag:
        return None
    for k in range(len(topo.waves)):
        a = topo.arcs[topo.arc_ptr[k] : topo.arc_ptr[k + 1]]
        a = a[use[a]]
        if not len(a):
            continue
        src, dst = stn.arc_src[a], stn.arc_dst[a]
        cand = t[src] + lb[a]
        fixed = happened[dst]
        if np.any(cand[fixed] > t[dst[fixed]]):
            return None
        np.maximum.at(t, dst[~fixed], cand[~fixed])
    return t


def arc_locks(stn: STN) -> np.ndarray:
    """The lock (vertex) of every precedence arc of a freshly built STN, -1 elsewhere
    (the STN lists the TPG's Type-2 arcs in order, after its Type-1 arcs)."""
    tpg = stn.tpg
    locks = np.full(stn.num_arcs, -1, dtype=np.int64)
    prec = np.flatnonzero(stn.arc_kind == PRECEDENCE)
    t2 = np.flatnonzero(tpg.arc_type == TYPE2)
    if len(prec) == len(t2):
        locks[prec] = tpg.arc_lock[t2]
    return locks


def _switched(
    stn: STN, locks: np.ndarray, pairs: list[_Pair], chosen: list[int]
) -> tuple[STN, np.ndarray]:
    """The STN with the chosen claims swapped (arcs removed and added), and its locks."""
    drop: set[int] = set()
    add: list[tuple[int, int, float, int]] = []
    for i in chosen:
        p = pairs[i]
        drop.add(p.arc)
        add.append((p.b_leave, p.a_enter, float(stn.lb[p.arc]), p.lock))
        if p.before >= 0:
            drop.add(p.before)
            add.append((int(stn.arc_src[p.before]), p.b_enter, float(stn.lb[p.before]), p.lock))
        if p.after >= 0:
            drop.add(p.after)
            add.append((p.a_leave, int(stn.arc_dst[p.after]), float(stn.lb[p.after]), p.lock))
    keep = np.ones(stn.num_arcs, dtype=bool)
    keep[list(drop)] = False
    n_add = len(add)
    new = dataclasses.replace(
        stn,
        arc_src=np.concatenate([stn.arc_src[keep], np.array([a[0] for a in add], dtype=np.int64)]),
        arc_dst=np.concatenate([stn.arc_dst[keep], np.array([a[1] for a in add], dtype=np.int64)]),
        lb=np.concatenate([stn.lb[keep], np.array([a[2] for a in add])]),
        ub=np.concatenate([stn.ub[keep], np.full(n_add, np.inf)]),
        arc_kind=np.concatenate([stn.arc_kind[keep], np.full(n_add, PRECEDENCE)]),
        arc_length=np.concatenate([stn.arc_length[keep], np.zeros(n_add)]),
        arc_turn=np.concatenate([stn.arc_turn[keep], np.zeros(n_add)]),
    )
    new_locks = np.concatenate([locks[keep], np.array([a[3] for a in add], dtype=np.int64)])
    return new, new_locks
