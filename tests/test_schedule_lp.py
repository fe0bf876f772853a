"""MAPF-POST LPs against the graph method, and safety in a continuous-time replay."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hierplan_opt import Graph, Instance, Kinematics, Plan, validate
from hierplan_opt.bench.post import prioritized_plan
from hierplan_opt.schedule import (
    build_stn,
    build_tpg,
    check_bounds,
    postprocess,
    replay,
    solve_graph,
    solve_lp,
)
from hierplan_opt.schedule.stn import PIECE


def random_case(seed: int, *, kinds: bool = True) -> tuple[Instance, Plan] | None:
    """A small random grid instance with mixed robots and a prioritized plan."""
    rng = np.random.default_rng(seed)
    W, H = (int(x) for x in rng.integers(4, 8, 2))
    g = Graph.grid(W, H, blocked=rng.random((H, W)) < 0.15)
    free = np.flatnonzero(g.passable)
    k = int(rng.integers(2, min(7, len(free) // 2) + 1))
    sel = rng.choice(free, 2 * k, replace=False)
    kins = []
    for _ in range(k):
        if kinds and rng.random() < 0.4:
            kins.append(
                Kinematics(
                    "pioneer",
                    drive="differential",
                    v_max=float(rng.choice([0.5, 1.0])),
                    omega_max=float(rng.choice([1.0, 3.0])),
                    a_max=None if rng.random() < 0.5 else 2.0,
                )
            )
        else:
            kins.append(Kinematics("youbot", v_max=float(rng.choice([0.5, 1.0, 2.0]))))
    inst = Instance.mapf(
        g,
        [g.location(int(v)) for v in sel[:k]],
        [g.location(int(v)) for v in sel[k:]],
        kinematics=kins,
    )
    if any(g.dist(s, t) >= 1 << 30 for s, t in zip(inst.starts, inst.goals, strict=True)):
        return None
    plan = prioritized_plan(inst, max_time=60)
    if plan is None:
        return None
    assert validate(inst, plan) == []
    return inst, plan


CASES = [c for c in (random_case(s) for s in range(12)) if c is not None][:6]


def test_enough_cases() -> None:
    assert len(CASES) >= 5


@pytest.mark.parametrize("case", range(len(CASES)))
@pytest.mark.parametrize("backend", ["pyomo", "highs"])
def test_lp_makespan_equals_graph(case: int, backend: str) -> None:
    inst, plan = CASES[case]
    stn = build_stn(inst, build_tpg(inst, plan, margin=0.2))
    g = solve_graph(stn)
    lp = solve_lp(stn, "makespan", backend=backend)
    assert lp.makespan == pytest.approx(g.makespan, rel=1e-7, abs=1e-7)
    assert check_bounds(stn, lp.times) == []
    # Flowtime: the earliest schedule minimises every node, hence the sum too.
    ft = solve_lp(stn, "flowtime", backend=backend)
    finals = stn.tpg.final_nodes()
    assert ft.objective_value == pytest.approx(g.earliest[finals].sum(), rel=1e-7, abs=1e-7)


def test_pyomo_and_highs_agree_on_safety() -> None:
    inst, plan = CASES[0]
    stn = build_stn(inst, build_tpg(inst, plan, margin=0.2))
    a = solve_lp(stn, "safety", backend="pyomo")
    b = solve_lp(stn, "safety", backend="highs")
    r_pyomo, r_highs = a.R, b.R
    assert r_pyomo == pytest.approx(r_highs, rel=1e-6)
    assert a.makespan == pytest.approx(b.makespan, rel=1e-6)


def _slowest_piece_speed(s) -> float:
    stn = s.stn
    p = (stn.arc_kind == PIECE) & (stn.arc_length > 0)
    dur = s.times[stn.arc_dst[p]] - s.times[stn.arc_src[p]]
    return float((stn.arc_length[p] / dur).min())


@pytest.mark.parametrize("case", range(len(CASES)))
def test_clearance_holds_in_replay(case: int) -> None:
    inst, plan = CASES[case]
    graph_s = postprocess(inst, plan, "makespan", margin=0.2)
    safe_s = postprocess(inst, plan, "safety", method="lp", margin=0.2)
    for s in (graph_s, safe_s):
        assert check_bounds(s.stn, s.times) == []
        rep = replay(s, inst, all_pairs=True)
        assert rep.ok, rep
        assert rep.min_distance >= s.safety_distance - 1e-9, (rep, s.safety_distance)
        assert s.safety_distance == pytest.approx(0.2)
        # Item 5: every way-point lies in its window, for the schedule returned.
        for wp in s.waypoints:
            assert np.all(wp.earliest <= wp.arrival + 1e-9)
            assert np.all(wp.arrival <= wp.latest + 1e-9)
    # The safety LP maximises the slowest piece speed (1 / R*) ...
    R = safe_s.stats["R"]
    assert _slowest_piece_speed(safe_s) == pytest.approx(1 / R, rel=1e-6)
    assert _slowest_piece_speed(safe_s) >= _slowest_piece_speed(graph_s) - 1e-9
    # ... and then minimises the makespan, which cannot beat the earliest schedule.
    assert safe_s.makespan >= graph_s.makespan - 1e-9


def test_replay_sees_the_closest_approach() -> None:
    # Two point robots meet at the centre of the plus map. agent1's wait is merged, so
    # it creeps from (1, 0) at t = 0 to (1, 1) at t = 3 (agent0 has left (1, 1) when it
    # reaches (2, 1) at t = 2, plus a lag epsilon = 1): it is at (1, t / 3). agent0 is
    # at (t, 1) for t in [0, 2]. Their squared distance (t - 1)^2 + (1 - t / 3)^2 is
    # minimal at t = 1.2: sqrt(0.4).
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    v = g.vertex
    inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 1)])
    plan = Plan.from_paths([[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 0)), v((1, 1))]])
    s = postprocess(inst, plan, epsilon=1.0, margin=0)
    rep = replay(s)
    assert s.arrival_times("agent1").tolist() == [0.0, 3.0]
    assert rep.min_distance == pytest.approx(math.sqrt(0.4))
    assert rep.time == pytest.approx(1.2)
    assert rep.agents == ("agent0", "agent1")


def test_pair_pruning_is_exact() -> None:
    # Pruned pairs stay farther apart than required + watch; every pair that comes
    # closer is checked and gives the same minimum as the full check.
    for inst, plan in CASES + DENSE:
        s = postprocess(inst, plan, margin=0.2)
        full = replay(s, inst, all_pairs=True)
        pruned = replay(s, inst)
        assert pruned.ok == full.ok
        assert pruned.pairs_checked + pruned.pairs_skipped == full.pairs_checked
        if full.min_distance < 0.2 + s.scale:
            assert pruned.min_distance == pytest.approx(full.min_distance)
        else:
            assert pruned.min_distance >= full.min_distance - 1e-12


def test_roadmap_with_acute_angle() -> None:
    # A roadmap with a 45-degree junction at C: robots on the two edges into C are
    # close long before C; the general claims (half an edge + both radii) keep them
    # apart.
    g = Graph.roadmap(
        {"A": (0, 0), "B": (2, 0), "C": (4, 0), "D": (6, 0), "E": (2, 2)},
        [("A", "B"), ("B", "C"), ("C", "D"), ("E", "C")],
    )
    kin = Kinematics("r", v_max=1.0, radius=0.3)
    inst = Instance.mapf(g, ["A", "E"], ["D", "B"], kinematics=[kin, kin])
    plan = Plan.from_paths([[0, 1, 2, 3], [4, 4, 4, 4, 2, 1]])
    assert validate(inst, plan) == []
    for obj, method in (("makespan", "graph"), ("safety", "lp")):
        s = postprocess(inst, plan, obj, method=method, margin=0.1)
        assert s.stats["regime"] == "general"
        rep = replay(s, inst, all_pairs=True)
        assert rep.ok and rep.min_distance >= 0.7 - 1e-9


@pytest.mark.parametrize("case", range(len(CASES)))
def test_reduced_lp_equals_full_lp(case: int) -> None:
    # The exact projection (makespan, flowtime) and the merged chains (safety) give
    # the same optimum as the LP with one variable per STN node, and the eliminated
    # nodes' recovered times meet every bound.
    inst, plan = CASES[case]
    stn = build_stn(inst, build_tpg(inst, plan, margin=0.2))
    for objective in ("makespan", "flowtime", "safety"):
        full = solve_lp(stn, objective, backend="highs", reduction="none")
        for reduction in ("auto", "chains"):
            red = solve_lp(stn, objective, backend="highs", reduction=reduction)
            assert red.objective_value == pytest.approx(full.objective_value, rel=1e-7, abs=1e-7)
            assert check_bounds(stn, red.times) == []
            if objective == "safety":
                r_red, r_full = red.R, full.R
                assert r_red == pytest.approx(r_full, rel=1e-7)


def test_safety_marker_elimination_is_used_and_exact() -> None:
    from hierplan_opt.schedule.solve_lp import _compress, _eliminate_markers, _Markers

    hits = 0
    for inst, plan in CASES:
        stn = build_stn(inst, build_tpg(inst, plan, margin=0.2))
        chains = _compress(stn)
        net = _eliminate_markers(chains)
        if isinstance(net, _Markers):
            hits += 1
            assert net.n < chains.n and len(net.gen[0]) == chains.n - net.n
        a = solve_lp(stn, "safety", backend="highs")  # chains + markers
        b = solve_lp(stn, "safety", backend="highs", reduction="chains")
        r_a, r_b = a.R, b.R
        assert r_a == pytest.approx(r_b, rel=1e-9)
        assert a.makespan == pytest.approx(b.makespan, rel=1e-9)
        assert check_bounds(stn, a.times) == []
        p = (stn.arc_kind == PIECE) & (stn.arc_length > 0)
        dur = a.times[stn.arc_dst[p]] - a.times[stn.arc_src[p]]
        assert (dur <= stn.arc_length[p] * r_a * (1 + 1e-7) + 1e-9).all()  # speed >= 1/R
    assert hits >= 3


def test_projection_shrinks_the_lp_and_keeps_deadlines() -> None:
    from hierplan_opt.schedule.solve_lp import _eliminate

    inst, plan = CASES[1]
    stn = build_stn(inst, build_tpg(inst, plan, margin=0.2))
    net = _eliminate(stn)
    assert net.n < stn.num_nodes and len(net.src) < stn.num_arcs
    # A deadline on a robot's final node: protected, the bound stays in the LP.
    g = solve_graph(stn)
    finals = stn.tpg.final_nodes()
    j = int(np.argmax(g.earliest[finals]))
    tight = build_stn(inst, build_tpg(inst, plan, margin=0.2), deadlines={j: g.makespan})
    lp = solve_lp(tight, "flowtime", backend="highs")
    assert lp.times[finals[j]] <= g.makespan + 1e-9
    assert check_bounds(tight, lp.times) == []
    assert lp.objective_value == pytest.approx(g.earliest[finals].sum(), rel=1e-7)


def dense_case(seed: int) -> tuple[Instance, Plan] | None:
    """12 robots on an 8 x 8 grid: followers and crossings make the eliminated
    precedence rows of the safety LP bind."""
    rng = np.random.default_rng(seed)
    g = Graph.grid(8, 8, blocked=rng.random((8, 8)) < 0.1)
    free = np.flatnonzero(g.passable)
    sel = rng.choice(free, 24, replace=False)
    kins = [Kinematics("r", v_max=float(rng.choice([0.5, 1.0, 2.0]))) for _ in range(12)]
    inst = Instance.mapf(
        g,
        [g.location(int(v)) for v in sel[:12]],
        [g.location(int(v)) for v in sel[12:]],
        kinematics=kins,
    )
    if any(g.dist(s, t) >= 1 << 30 for s, t in zip(inst.starts, inst.goals, strict=True)):
        return None
    plan = prioritized_plan(inst, max_time=80)
    return None if plan is None else (inst, plan)


DENSE = [c for c in (dense_case(s) for s in range(8, 16)) if c is not None][:5]


@pytest.mark.parametrize("case", range(len(DENSE)))
def test_safety_reductions_agree_on_dense_plans(case: int) -> None:
    inst, plan = DENSE[case]
    stn = build_stn(inst, build_tpg(inst, plan, margin=0.2))
    full = solve_lp(stn, "safety", backend="highs", reduction="none")
    for reduction in ("chains", "auto"):
        red = solve_lp(stn, "safety", backend="highs", reduction=reduction)
        r_red, r_full = red.R, full.R
        assert r_red == pytest.approx(r_full, rel=1e-7)
        assert red.makespan == pytest.approx(full.makespan, rel=1e-7)
        assert check_bounds(stn, red.times) == []
