"""Linear programs over an STN (Pyomo + HiGHS, or the same LP straight to HiGHS).

Variables: one time ``t_v >= 0`` per STN node (``release_v <= t_v <= deadline_v``).

Constraints (the STN): ``lb_e <= t_v - t_u <= ub_e`` for every arc ``e = (u, v)``.

Objectives:

* ``makespan``: minimise ``M`` s.t. ``M >= t_f`` for every robot's final node ``f``.
  Equal to the graph method's makespan (the earliest schedule is optimal).
* ``flowtime``: minimise ``sum_f t_f``. Also attained by the earliest schedule (the
  STN's solutions form a lattice whose least element is the earliest schedule), so it
  is a cross-check of the graph method, not a different schedule.
* ``safety``: stage 1 minimises ``R`` s.t. the STN and ``t_v - t_u <= len_e * R`` on
  every piece (every robot moves at least ``1 / R`` on every piece: robots keep
  moving and the markers keep their meaning); stage 2 minimises ``M`` with ``R`` fixed
  at its optimum (times ``1 + 1e-9``).

Before either back end writes the LP, the STN is reduced exactly (see
:func:`_eliminate`, :func:`_compress`, :func:`_eliminate_markers`;
``reduction="chains"`` / ``"none"`` for
comparison) and the eliminated nodes' times are recovered afterwards.

Back ends: ``"pyomo"`` builds a Pyomo ``ConcreteModel`` and solves it with
``SolverFactory("appsi_highs")``; ``"highs"`` assembles the identical LP as a sparse
CSR matrix and hands it to ``highspy`` in one ``passModel`` call. Pyomo's model
construction and the appsi translation cost ~50-100 us per constraint, so ``"auto"``
uses Pyomo up to :data:`PYOMO_MAX_ARCS` STN arcs and the direct path above.

HiGHS never receives the graph method's schedule as a start or basis: the LP is an
independent check of the graph answer.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hierplan_opt.core.errors import HierplanError, OptionError
from hierplan_opt.core.progress import watching_highs
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.schedule.stn import PIECE, STN

log = logging.getLogger(__name__)

OBJECTIVES = ("makespan", "safety", "flowtime")
BACKENDS = ("auto", "pyomo", "highs")
REDUCTIONS = ("auto", "chains", "none")
PYOMO_MAX_ARCS = 20_000
#: Relative slack on R* in stage 2 of the safety LP.
R_SLACK = 1e-9


class LPError(HierplanError):
    """The LP solver did not reach an optimum (infeasible STN, time limit, failure)."""


@dataclass(frozen=True, eq=False)
class LPSolution:
    """Node times and objective values of an LP schedule."""

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    times: np.ndarray
    makespan: float
    objective_value: float
    R: float | None = None
    backend: str = ""
    stats: dict[str, Any] = field(default_factory=dict)


def solve_lp(
    stn: STN,
    objective: str = "makespan",
    *,
    backend: str = "auto",
    time_limit: float | None = None,
    highs_options: dict[str, Any] | None = None,
    reduction: str = "auto",
) -> LPSolution:
    """Solve the LP for ``objective`` over ``stn``.

    The LP is written on an exactly reduced network (``reduction="auto"``): for
    makespan and flowtime every plain node with a single arc in or out is eliminated
    (Fourier-Motzkin projection), for safety chains of plain nodes are merged and
    (HiGHS back end) single-precedence markers are eliminated with ``R`` as a
    parameter; ``"chains"`` merges chains only, ``"none"`` writes one variable per
    STN node.
    Eliminated nodes get their times back afterwards. HiGHS solves the LP from
    scratch: the graph method's schedule is never passed as a start or basis, so
    the LP is an independent check of it.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import build_stn, build_tpg
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]])))
    >>> round(solve_lp(stn, "makespan", backend="pyomo").makespan, 6)
    2.0
    >>> round(solve_lp(stn, "safety", backend="highs").R, 6)  # 1 / slowest speed
    1.0
    """
    if objective not in OBJECTIVES:
        raise OptionError(f"unknown LP objective {objective!r} (use {', '.join(OBJECTIVES)})")
    if backend not in BACKENDS:
        raise OptionError(f"unknown LP backend {backend!r} (use {', '.join(BACKENDS)})")
    if reduction not in REDUCTIONS:
        raise OptionError(f"unknown reduction {reduction!r} (use {', '.join(REDUCTIONS)})")
    if backend == "auto":
        backend = "pyomo" if stn.num_arcs <= PYOMO_MAX_ARCS else "highs"
    t0 = time.perf_counter()
    if backend == "pyomo":
        sol = _solve_pyomo(stn, objective, time_limit, reduction)
    else:
        sol = _solve_highs(stn, objective, time_limit, highs_options or {}, reduction)
    sol.stats["lp_time"] = time.perf_counter() - t0
    return sol


# ---------------------------------------------------------------------- Pyomo
def _solve_pyomo(
    stn: STN, objective: str, time_limit: float | None, reduction: str = "auto"
) -> LPSolution:
    import pyomo.environ as pyo  # heavy module: Pyomo

    t_build = time.perf_counter()
    net = _reduce(stn, objective, reduction)
    n = net.n
    src = net.src.tolist()
    dst = net.dst.tolist()
    lb = net.lb.tolist()
    ub = net.ub.tolist()
    finals = net.finals.tolist()
    release = net.release.tolist()
    deadline = net.deadline.tolist()

    # Pyomo builds components dynamically; its classes do not declare them for a checker.
    m: Any = pyo.ConcreteModel(name="mapf_post")
    m.N = pyo.RangeSet(0, n - 1)
    m.t = pyo.Var(
        m.N,
        bounds=lambda _m, v: (release[v], deadline[v] if math.isfinite(deadline[v]) else None),
    )
    # Reference every time variable once up front: appsi adds the variables of each
    # new constraint in a separate HiGHS call otherwise (quadratic-looking slow-down).
    m.all_vars = pyo.Constraint(expr=pyo.quicksum(m.t[v] for v in range(n)) >= 0)

    # ---- STN arcs: lb <= t_dst - t_src <= ub
    def arc_rule(_m: Any, k: int) -> Any:
        hi = ub[k] if math.isfinite(ub[k]) else None
        return (lb[k], _m.t[dst[k]] - _m.t[src[k]], hi)

    m.A = pyo.RangeSet(0, len(src) - 1) if src else pyo.Set(initialize=[])
    m.arc = pyo.Constraint(m.A, rule=arc_rule)

    # ---- makespan variable
    m.M = pyo.Var(bounds=(0, None))
    m.finish = pyo.Constraint(range(len(finals)), rule=lambda _m, j: _m.t[finals[j]] <= _m.M)

    stats: dict[str, Any] = {}
    R_val: float | None = None
    if objective == "safety":
        assert isinstance(net, _Reduced)
        pieces = np.flatnonzero((net.kind == PIECE) & (net.length > 0)).tolist()
        length = net.length.tolist()
        m.R = pyo.Var(bounds=(net.R_lb, None))
        m.speed = pyo.Constraint(
            range(len(pieces)),
            rule=lambda _m, i: (
                _m.t[dst[pieces[i]]] - _m.t[src[pieces[i]]] <= length[pieces[i]] * _m.R
            ),
        )
        m.obj_R = pyo.Objective(expr=m.R)
        m.obj_M = pyo.Objective(expr=m.M)
        m.obj_M.deactivate()
    elif objective == "makespan":
        m.obj = pyo.Objective(expr=m.M)
    else:
        m.obj = pyo.Objective(expr=pyo.quicksum(m.t[f] for f in finals))
    stats["lp_build_time"] = time.perf_counter() - t_build

    t_solve = time.perf_counter()
    opt: Any = pyo.SolverFactory("appsi_highs")
    if not opt.available():
        raise LPError("the HiGHS solver is not available to Pyomo (appsi_highs)")
    if time_limit is not None:
        opt.config.time_limit = float(time_limit)
    opt.config.stream_solver = False
    # appsi copies HiGHS's log to its logger at INFO; keep it for -v (DEBUG) only.
    opt.config.log_level = logging.DEBUG
    opt.set_instance(m)  # builds the highspy model now, for the progress callbacks

    def run() -> None:
        with watching_highs(opt._solver_model):  # Pyomo keeps it private
            res = opt.solve(m, load_solutions=False)
        if not pyo.check_optimal_termination(res):
            tc = res.solver.termination_condition
            raise LPError(f"the LP was not solved to optimality (HiGHS via Pyomo: {tc})")
        m.solutions.load_from(res)

    run()
    if objective == "safety":
        R_val = _value(pyo, m.R)
        m.R.setub(R_val * (1 + R_SLACK) + 1e-12)
        m.obj_R.deactivate()
        m.obj_M.activate()
        run()
        obj_val = _value(pyo, m.M)
    elif objective == "makespan":
        obj_val = _value(pyo, m.M)
    else:
        obj_val = float(sum(_value(pyo, m.t[f]) for f in finals))
    stats["lp_solve_time"] = time.perf_counter() - t_solve
    x = np.array([_value(pyo, m.t[v]) for v in range(n)], dtype=float)
    times = _clean(net.expand(x, R_val), stn)
    stats["lp_nodes"] = n
    stats["lp_arcs"] = len(src)
    return LPSolution(
        times,
        float(times[stn.tpg.final_nodes()].max()),
        obj_val,
        R_val,
        "pyomo",
        stats,
    )


def _value(pyo: Any, component: Any) -> float:
    """A solved Pyomo variable's value as a float (LPError if the solver left none)."""
    v = pyo.value(component)
    if v is None:
        raise LPError(f"the LP solver gave no value for {component}")
    return float(v)


# ---------------------------------------------------------------------- HiGHS direct
def _solve_highs(
    stn: STN,
    objective: str,
    time_limit: float | None,
    options: dict[str, Any],
    reduction: str = "auto",
) -> LPSolution:
    import highspy  # heavy module: highspy
    import scipy.sparse as sp  # heavy module: scipy

    inf = highspy.kHighsInf
    t_build = time.perf_counter()
    net = _reduce(stn, objective, reduction, markers=True)
    n = net.n
    finals = net.finals
    m_arcs = len(net.src)
    K = len(finals)
    iM = n  # makespan column
    iR = n + 1  # R column (safety only)
    ncol = n + (2 if objective == "safety" else 1)

    rows = [np.arange(m_arcs), np.arange(m_arcs)]
    cols = [net.dst, net.src]
    vals = [np.ones(m_arcs), -np.ones(m_arcs)]
    row_lo = [net.lb]
    row_hi = [np.where(np.isfinite(net.ub), net.ub, inf)]
    r0 = m_arcs
    # M - t_f >= 0
    rows += [r0 + np.arange(K), r0 + np.arange(K)]
    cols += [np.full(K, iM), finals]
    vals += [np.ones(K), -np.ones(K)]
    row_lo.append(np.zeros(K))
    row_hi.append(np.full(K, inf))
    r0 += K
    if objective == "safety":
        assert isinstance(net, _PieceNetwork)  # safety networks keep their pieces
        pieces = np.flatnonzero((net.kind == PIECE) & (net.length > 0))
        P = len(pieces)
        # t_dst - t_src - len * R <= 0
        rows += [r0 + np.arange(P)] * 3
        cols += [net.dst[pieces], net.src[pieces], np.full(P, iR)]
        vals += [np.ones(P), -np.ones(P), -net.length[pieces]]
        row_lo.append(np.full(P, -inf))
        row_hi.append(np.zeros(P))
        r0 += P
        gen = net.gen if isinstance(net, _Markers) else None
        if gen is not None:  # t_dst - t_src - alpha * R >= beta
            g_src, g_dst, g_beta, g_alpha = gen
            G = len(g_src)
            rows += [r0 + np.arange(G)] * 3
            cols += [g_dst, g_src, np.full(G, iR)]
            vals += [np.ones(G), -np.ones(G), -g_alpha]
            row_lo.append(g_beta)
            row_hi.append(np.full(G, inf))
            r0 += G
    A = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r0, ncol)
    )
    col_lo = np.concatenate([net.release, np.zeros(ncol - n)])
    if objective == "safety":
        col_lo[iR] = net.R_lb  # every merged piece needs R >= lb / length
    col_hi = np.concatenate(
        [np.where(np.isfinite(net.deadline), net.deadline, inf), np.full(ncol - n, inf)]
    )
    cost = np.zeros(ncol)
    if objective == "makespan":
        cost[iM] = 1.0
    elif objective == "flowtime":
        cost[finals] = 1.0
    else:
        cost[iR] = 1.0

    lp: Any = highspy.HighsLp()  # its stubs ask for lists; numpy arrays are accepted
    lp.num_col_ = ncol
    lp.num_row_ = r0
    lp.col_cost_ = cost
    lp.col_lower_ = col_lo
    lp.col_upper_ = col_hi
    lp.row_lower_ = np.concatenate(row_lo)
    lp.row_upper_ = np.concatenate(row_hi)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
    lp.a_matrix_.start_ = A.indptr
    lp.a_matrix_.index_ = A.indices
    lp.a_matrix_.value_ = A.data
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    if time_limit is not None:
        h.setOptionValue("time_limit", float(time_limit))
    h.passModel(lp)
    stats: dict[str, Any] = {"lp_build_time": time.perf_counter() - t_build, "lp_rows": r0}

    def run() -> np.ndarray:
        with watching_highs(h):
            h.run()
        status = h.getModelStatus()
        if status != highspy.HighsModelStatus.kOptimal:
            raise LPError(
                f"the LP was not solved to optimality (HiGHS: {h.modelStatusToString(status)})"
            )
        return np.asarray(h.getSolution().col_value, dtype=float)

    for key, value in options.items():
        h.setOptionValue(key, value)
    t_solve = time.perf_counter()
    x = run()
    stats["lp_solve_time"] = time.perf_counter() - t_solve
    R_val = None
    if objective == "safety":
        R_val = float(x[iR])
        h.changeColBounds(iR, net.R_lb, R_val * (1 + R_SLACK) + 1e-12)
        h.changeColCost(iR, 0.0)
        h.changeColCost(iM, 1.0)
        t_solve = time.perf_counter()
        x = run()
        stats["lp_solve2_time"] = time.perf_counter() - t_solve
    if objective == "safety":
        times = _clean(net.expand(x[:n], R_val, float(x[iR])), stn)
    else:
        times = _clean(net.expand(x[:n], R_val), stn)
    stats["lp_columns"] = ncol
    finals = stn.tpg.final_nodes()
    obj_val = float(times[finals].sum()) if objective == "flowtime" else float(x[iM])
    return LPSolution(times, float(times[finals].max()), obj_val, R_val, "highs", stats)


def _reduce(stn: STN, objective: str, reduction: str = "auto", markers: bool = False) -> _Network:
    """The network the LP is written on.

    ``"auto"``: the exact projection (:func:`_eliminate`) for makespan and flowtime,
    merged chains (:func:`_compress`) for safety, plus :func:`_eliminate_markers`
    when ``markers`` (the HiGHS back end); ``"chains"``: merged chains only;
    ``"none"``: the STN itself.
    """
    if reduction == "none":
        return _Reduced.identity(stn)
    if reduction == "chains":
        return _compress(stn)
    if objective == "safety":
        return _eliminate_markers(_compress(stn)) if markers else _compress(stn)
    return _eliminate(stn)


@dataclass(frozen=True, eq=False)
class _Network:
    """The network an LP is written on: ``n`` nodes, arcs ``src -> dst`` with
    ``lb <= t_dst - t_src <= ub``, node bounds ``release`` / ``deadline`` and the robots'
    last nodes ``finals`` (all in the network's own node ids). :meth:`expand` maps the
    LP's node times back to one time per STN node.
    """

    n: int
    src: np.ndarray
    dst: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    release: np.ndarray
    deadline: np.ndarray
    finals: np.ndarray
    R_lb: float  # lower bound on R from merged pieces (0: none merged)

    def expand(self, x: np.ndarray, R: float | None, R_x: float | None = None) -> np.ndarray:
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class _PieceNetwork(_Network):
    """A network that keeps its pieces (the safety LP's ``t_dst - t_src <= len R``):
    the arcs' kinds and lengths.
    """

    kind: np.ndarray
    length: np.ndarray


@dataclass(frozen=True, eq=False)
class _Reduced(_PieceNetwork):
    """The STN with chains of plain nodes merged (for the direct HiGHS LP).

    A node is merged away when it is neither a robot's first nor last node, has
    default node bounds, and exactly one arc in and one out (its robot's pieces,
    without upper bounds). A chain ``u -> w1 -> ... -> wk -> v`` becomes one piece with
    the summed lower bound and length; the pieces' own speed limits survive as the
    lower bound ``R >= max lb_i / len_i`` on ``R``. :meth:`expand` puts the merged
    nodes back, spreading the chain's extra time over its pieces in proportion to
    ``lb_i`` (or, with ``R``, to the room ``len_i R - lb_i``), which keeps every
    piece within its bounds.
    """

    stn: STN
    kept: np.ndarray | None  # original ids of the reduced nodes (None: identity)

    @classmethod
    def identity(cls, stn: STN) -> _Reduced:
        return cls(
            stn.num_nodes, stn.arc_src, stn.arc_dst, stn.lb, stn.ub, stn.release, stn.deadline,
            stn.tpg.final_nodes(), 0.0, stn.arc_kind, stn.arc_length, stn, None,
        )  # fmt: skip

    def expand(self, x: np.ndarray, R: float | None, R_x: float | None = None) -> np.ndarray:
        if self.kept is None:
            return np.asarray(x, dtype=float)
        stn = self.stn
        n = stn.num_nodes
        t = np.full(n, np.nan)
        t[self.kept] = x
        gone = np.isnan(t)
        if not gone.any():
            return t
        idx = np.arange(n)
        prev_kept = np.maximum.accumulate(np.where(~gone, idx, -1))
        next_kept = np.minimum.accumulate(np.where(~gone, idx, n)[::-1])[::-1]
        # Piece u -> u+1 of every node (0 for last nodes): lower bound and weight.
        piece = (stn.arc_kind == PIECE) & (stn.arc_dst == stn.arc_src + 1)
        P_lb = np.zeros(n)
        P_lb[stn.arc_src[piece]] = stn.lb[piece]
        if R is not None:
            P_len = np.zeros(n)
            P_len[stn.arc_src[piece]] = stn.arc_length[piece]
            W = np.maximum(P_len * R - P_lb, 0.0)
        else:
            W = P_lb.copy()
        C_lb = np.concatenate(([0.0], np.cumsum(P_lb)))  # C[k] = sum of P over nodes < k
        C_w = np.concatenate(([0.0], np.cumsum(W)))
        w = np.flatnonzero(gone)
        u, v = prev_kept[w], next_kept[w]
        span_lb = C_lb[v] - C_lb[u]
        span_w = C_w[v] - C_w[u]
        extra = (t[v] - t[u]) - span_lb
        frac = np.where(span_w > 0, (C_w[w] - C_w[u]) / np.where(span_w > 0, span_w, 1), 0.0)
        t[w] = t[u] + (C_lb[w] - C_lb[u]) + np.maximum(extra, 0.0) * frac
        return t


def _compress(stn: STN) -> _Reduced:
    n = stn.num_nodes
    tpg = stn.tpg
    indeg = np.bincount(stn.arc_dst, minlength=n)
    outdeg = np.bincount(stn.arc_src, minlength=n)
    finite_ub = np.zeros(n, dtype=bool)
    fub = np.isfinite(stn.ub)
    finite_ub[stn.arc_src[fub]] = True
    finite_ub[stn.arc_dst[fub]] = True
    removable = (
        (indeg == 1) & (outdeg == 1) & (stn.release == 0) & ~np.isfinite(stn.deadline) & ~finite_ub
    )
    removable[tpg.start_nodes()] = False
    removable[tpg.final_nodes()] = False
    if not removable.any():
        return _Reduced.identity(stn)
    keep_mask = ~removable
    kept = np.flatnonzero(keep_mask)
    new_id = np.cumsum(keep_mask) - 1
    both = keep_mask[stn.arc_src] & keep_mask[stn.arc_dst]
    # New pieces: from a kept node whose successor was merged away to the next kept node.
    u = kept[(kept + 1 < n)]
    u = u[removable[u + 1]]
    v = kept[np.searchsorted(kept, u + 1)]
    piece = (stn.arc_kind == PIECE) & (stn.arc_dst == stn.arc_src + 1)
    P_lb = np.zeros(n)
    P_lb[stn.arc_src[piece]] = stn.lb[piece]
    C = np.concatenate(([0.0], np.cumsum(P_lb)))
    lb_new = C[v] - C[u]
    len_new = tpg.node_s[v] - tpg.node_s[u]
    touched = piece & (removable[stn.arc_src] | removable[stn.arc_dst])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = stn.lb[touched] / stn.arc_length[touched]
    R_lb = float(np.max(ratio[np.isfinite(ratio)], initial=0.0))
    return _Reduced(
        n=len(kept),
        src=np.concatenate([new_id[stn.arc_src[both]], new_id[u]]),
        dst=np.concatenate([new_id[stn.arc_dst[both]], new_id[v]]),
        lb=np.concatenate([stn.lb[both], lb_new]),
        ub=np.concatenate([stn.ub[both], np.full(len(u), np.inf)]),
        kind=np.concatenate([stn.arc_kind[both], np.full(len(u), PIECE, np.int8)]),
        length=np.concatenate([stn.arc_length[both], len_new]),
        release=stn.release[kept],
        deadline=stn.deadline[kept],
        finals=new_id[tpg.final_nodes()],
        R_lb=R_lb,
        stn=stn,
        kept=kept,
    )


def _clean(times: np.ndarray, stn: STN) -> np.ndarray:
    """Snap LP round-off: clip to the node bounds; tiny negatives become 0."""
    t = np.clip(times, stn.release, stn.deadline)
    t[np.abs(t) < 1e-12] = 0.0
    return t


@dataclass(frozen=True, eq=False)
class _Projected(_Network):
    """The STN with plain nodes eliminated exactly (makespan and flowtime LPs).

    Fourier-Motzkin elimination of a time variable that has lower-bound arcs only: a
    node ``w`` with a single arc in, ``t_w >= t_u + a``, and arcs out
    ``t_x >= t_w + b_x`` is replaced by the arcs ``t_x >= t_u + a + b_x`` (and
    symmetrically for a single arc out). The projection is exact (the reduced LP has
    the same feasible times on the kept nodes and the same optimum) and never adds
    arcs. Passes alternate over "one arc in" and "one arc out" until nothing changes;
    chains of eliminated nodes are resolved by pointer jumping. Protected (never
    eliminated): robots' first and last nodes, nodes with a release time or deadline,
    and both ends of every arc with a finite upper bound. :meth:`expand` puts the
    eliminated nodes back in reverse order: ``t_w = t_u + a`` (earliest after its one
    predecessor) or ``t_w = t_x - b`` (latest before its one successor), both feasible.
    """

    stn: STN
    kept: np.ndarray
    steps: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]  # (nodes, anchors, offsets)

    def expand(self, x: np.ndarray, R: float | None = None, R_x: float | None = None) -> np.ndarray:
        t = np.full(self.stn.num_nodes, np.nan)
        t[self.kept] = x
        for nodes, anchors, offsets in reversed(self.steps):
            t[nodes] = t[anchors] + offsets
        return t


def _eliminate(stn: STN) -> _Projected:
    n = stn.num_nodes
    tpg = stn.tpg
    s, d, w, u = stn.arc_src, stn.arc_dst, stn.lb, stn.ub
    protected = (stn.release != 0) | np.isfinite(stn.deadline)
    protected[tpg.start_nodes()] = True
    protected[tpg.final_nodes()] = True
    fub = np.isfinite(u)
    protected[s[fub]] = True
    protected[d[fub]] = True
    alive = np.ones(n, dtype=bool)
    steps: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    idle = 0
    forward = True
    while idle < 2:
        # forward: nodes with one arc in, t_w = t_u + a (anchor u = the predecessor);
        # backward: nodes with one arc out, t_w = t_x - b (anchor x = the successor).
        near, far = (d, s) if forward else (s, d)
        elim = alive & ~protected & (np.bincount(near, minlength=n) == 1)
        if not elim.any():
            idle += 1
            forward = not forward
            continue
        idle = 0
        single = elim[near]  # the one arc of every eliminated node
        anchor = np.arange(n)
        off = np.zeros(n)
        anchor[near[single]] = far[single]
        off[near[single]] = w[single]
        while True:  # pointer jumping to the first anchor that stays
            nxt = anchor[anchor]
            if np.array_equal(nxt, anchor):
                break
            off = off + off[anchor]
            anchor = nxt
        nodes = np.flatnonzero(elim)
        steps.append((nodes, anchor[nodes], off[nodes] if forward else -off[nodes]))
        keep = ~single
        s, d, w, u = s[keep], d[keep], w[keep], u[keep]
        if forward:  # arcs out of an eliminated node now leave its anchor
            w = w + off[s]
            s = anchor[s]
        else:  # arcs into an eliminated node now enter its anchor
            w = w + off[d]
            d = anchor[d]
        # Parallel arcs without upper bounds: keep the largest lower bound.
        free = ~np.isfinite(u)
        key, inv = np.unique(s[free] * n + d[free], return_inverse=True)
        wmax = np.full(len(key), -np.inf)
        np.maximum.at(wmax, inv, w[free])
        s = np.concatenate([key // n, s[~free]])
        d = np.concatenate([key % n, d[~free]])
        w = np.concatenate([wmax, w[~free]])
        u = np.concatenate([np.full(len(key), np.inf), u[~free]])
        alive &= ~elim
        forward = not forward
    kept = np.flatnonzero(alive)
    new_id = np.cumsum(alive) - 1
    return _Projected(
        n=len(kept),
        src=new_id[s],
        dst=new_id[d],
        lb=w,
        ub=u,
        release=stn.release[kept],
        deadline=stn.deadline[kept],
        finals=new_id[tpg.final_nodes()],
        R_lb=0.0,
        stn=stn,
        kept=kept,
        steps=tuple(steps),
    )


@dataclass(frozen=True, eq=False)
class _Markers(_PieceNetwork):
    """The merged-chain network of the safety LP with single-precedence nodes
    eliminated (Fourier-Motzkin with ``R`` as a parameter; HiGHS back end).

    A node ``w`` with one piece in (``u -> w``: ``lb1 <= t_w - t_u <= len1 R``), one
    piece out (``w -> x``: ``lb2``, ``len2``) and exactly one precedence arc
    (``w -> y`` or ``y -> w`` with ``eps``), nothing else, is eliminated when none of
    its three neighbours is: pairing its lower with its upper bounds gives the piece
    ``u -> x`` (``lb1 + lb2``, length ``len1 + len2``), ``R >= lb1 / len1``,
    ``R >= lb2 / len2``, and for ``w -> y``: ``t_y >= t_u + lb1 + eps`` and the row
    ``t_y - t_x >= eps - len2 R``; for ``y -> w``: ``t_x >= t_y + eps + lb2`` and
    ``t_u - t_y >= eps - len1 R``. One node and one row fewer each; exact.
    The independent set is maximal, chosen by Luby's rounds (random priorities,
    seed 0). ``t_w`` comes back as the largest of its lower bounds.
    """

    gen: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    inner: _Reduced
    kept: np.ndarray
    elim: tuple[np.ndarray, ...]  # w, u, x, lb1, lb2, len2, y, eps, y_is_pred

    def expand(self, x: np.ndarray, R: float | None, R_x: float | None = None) -> np.ndarray:
        y_full = np.full(self.inner.n, np.nan)
        y_full[self.kept] = x
        w, u, xx, lb1, _lb2, len2, y, eps, y_in = self.elim
        r = R_x if R_x is not None else (R if R is not None else 0.0)
        lo = np.maximum(y_full[u] + lb1, y_full[xx] - len2 * r)
        lo = np.where(y_in, np.maximum(lo, y_full[y] + eps), lo)
        y_full[w] = lo
        return self.inner.expand(y_full, R, R_x)


def _eliminate_markers(net: _Reduced) -> _Reduced | _Markers:
    n = net.n
    src, dst, kind = net.src, net.dst, net.kind
    fin = np.isfinite(net.ub)
    piece = (kind == PIECE) & (net.length > 0) & ~fin
    other = ~piece
    pin = np.bincount(dst[piece], minlength=n)
    pout = np.bincount(src[piece], minlength=n)
    oin = np.bincount(dst[other], minlength=n)
    oout = np.bincount(src[other], minlength=n)
    one_prec = oin + oout == 1
    prec_ok = np.zeros(n, dtype=bool)
    po = other & (kind != PIECE) & ~fin
    prec_ok[src[po]] = True
    prec_ok[dst[po]] = True
    elig = (
        (pin == 1) & (pout == 1) & one_prec & prec_ok
        & (net.release == 0) & ~np.isfinite(net.deadline)
    )  # fmt: skip
    elig[net.finals] = False
    if not elig.any():
        return net
    # Neighbours: piece predecessor / successor, precedence partner.
    pred, succ, a_in, a_out = np.full((4, n), -1)  # -1: none
    pi = np.flatnonzero(piece)
    pred[dst[pi]] = src[pi]
    succ[src[pi]] = dst[pi]
    a_in[dst[pi]] = pi
    a_out[src[pi]] = pi
    partner, a_prec = np.full((2, n), -1)
    oi = np.flatnonzero(other)
    partner[src[oi]] = dst[oi]
    partner[dst[oi]] = src[oi]
    a_prec[src[oi]] = oi
    a_prec[dst[oi]] = oi
    # A maximal independent set over (pred, succ, partner) by Luby's rounds: a
    # candidate joins when its random priority beats every candidate neighbour's.
    rng = np.random.default_rng(0)
    nbs = np.stack([pred, succ, partner])  # (3, n), -1 = none
    cand = elig.copy()
    sel = np.zeros(n, dtype=bool)
    for _ in range(64):
        if not cand.any():
            break
        prio = rng.random(n)
        prio[~cand] = np.inf
        prio_ext = np.append(prio, np.inf)  # index -1 -> inf
        win = cand & (prio < prio_ext[nbs]).all(axis=0)
        sel |= win
        cand &= ~win
        hit = nbs[:, win].ravel()
        cand[hit[hit >= 0]] = False
    for nb in nbs:  # independence (cheap check)
        idx = np.flatnonzero(sel & (nb >= 0))
        assert not sel[nb[idx]].any()
    w = np.flatnonzero(sel)
    if not len(w):
        return net
    u, x = pred[w], succ[w]
    ai, ao, ap = a_in[w], a_out[w], a_prec[w]
    lb1, len1 = net.lb[ai], net.length[ai]
    lb2, len2 = net.lb[ao], net.length[ao]
    y, eps = partner[w], net.lb[ap]
    y_in = dst[ap] == w  # precedence y -> w
    drop = np.zeros(len(src), dtype=bool)
    drop[ai] = drop[ao] = drop[ap] = True
    # New arcs: merged piece u -> x, and the plain precedence.
    p_src = np.where(y_in, y, u)
    p_dst = np.where(y_in, x, y)
    p_lb = np.where(y_in, eps + lb2, lb1 + eps)
    g_src = np.where(y_in, y, x)
    g_dst = np.where(y_in, u, y)
    g_beta = eps
    g_alpha = np.where(y_in, -len1, -len2)
    with np.errstate(divide="ignore", invalid="ignore"):
        R_lb = max(net.R_lb, float(np.max(lb1 / len1)), float(np.max(lb2 / len2)))
    keep_mask = ~sel
    kept = np.flatnonzero(keep_mask)
    new_id = np.cumsum(keep_mask) - 1
    k = ~drop
    prec_kind = net.kind[ap]
    return _Markers(
        n=len(kept),
        src=new_id[np.concatenate([src[k], u, p_src])],
        dst=new_id[np.concatenate([dst[k], x, p_dst])],
        lb=np.concatenate([net.lb[k], lb1 + lb2, p_lb]),
        ub=np.concatenate([net.ub[k], np.full(2 * len(w), np.inf)]),
        kind=np.concatenate([kind[k], np.full(len(w), PIECE, np.int8), prec_kind]),
        length=np.concatenate([net.length[k], len1 + len2, np.zeros(len(w))]),
        release=net.release[kept],
        deadline=net.deadline[kept],
        finals=new_id[net.finals],
        R_lb=R_lb,
        gen=(new_id[g_src], new_id[g_dst], g_beta, g_alpha),
        inner=net,
        kept=kept,
        elim=(w, u, x, lb1, lb2, len2, y, eps, y_in),
    )
