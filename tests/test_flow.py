"""Anonymous MAPF by max-flow (solver "flow") and the time-expanded network."""

from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from teams_bruteforce import brute_force_makespan

import hierplan_opt as hp
from hierplan_opt import Graph, Instance, OptionError, Status, validate
from hierplan_opt.core.feasibility import quick_infeasibility
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search.flow_network import (
    SHARED,
    WAIT,
    TeamFlowNetwork,
    conflict_free_paths,
    multi_source_bfs,
    smallest_horizon,
)


def random_one_team(seed: int, w: int, h: int, k: int, density: float = 0.2) -> Instance | None:
    """A random one-team instance on a w x h grid (None if it has no plan)."""
    rng = np.random.default_rng(seed)
    blocked = rng.random((h, w)) < density
    g = Graph.grid(w, h, blocked=blocked)
    free = np.flatnonzero(g.passable)
    if len(free) < 2 * k:
        return None
    cells = rng.choice(free, 2 * k, replace=False)
    starts = [g.location(int(v)) for v in cells[:k]]
    targets = [g.location(int(v)) for v in cells[k:]]
    inst = Instance.tapf(g, [(starts, targets)])
    return None if quick_infeasibility(inst) else inst


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(
    seed=st.integers(0, 10_000),
    w=st.integers(2, 4),
    h=st.integers(2, 3),
    k=st.integers(1, 3),
)
def test_flow_makespan_equals_brute_force(seed: int, w: int, h: int, k: int) -> None:
    inst = random_one_team(seed, w, h, k)
    if inst is None:
        return
    expected = brute_force_makespan(inst)
    r = hp.solve(inst, "flow")
    assert r.status == Status.OPTIMAL
    assert not validate(inst, r.plan)
    assert r.cost == expected == r.lower_bound


@pytest.mark.parametrize("search", ["doubling", "linear"])
def test_flow_search_strategies_agree(search: str) -> None:
    for seed in range(6):
        inst = random_one_team(seed, 8, 6, 6)
        if inst is None:
            continue
        a = hp.solve(inst, "flow", search=search)
        b = hp.solve(inst, "flow", search="linear")
        assert a.cost == b.cost


def test_flow_min_cost_minimises_moves() -> None:
    # Two robots in a corridor, targets two cells ahead: the cheapest plan moves
    # each robot twice, the max-flow alone may wander.
    g = Graph.grid(6, 2)
    inst = Instance.tapf(g, [([(0, 0), (1, 0)], [(2, 0), (3, 0)])])
    r = hp.solve(inst, "flow", min_cost=True)
    assert r.cost == 2
    assert r.stats["total_moves"] == 4
    assert r.stats["min_cost"] is True
    r2 = hp.solve(inst, "flow", min_cost=False)
    assert r2.cost == 2 and r2.stats["min_cost"] is False
    assert r2.stats["total_moves"] >= 4


def test_flow_reports_assignment() -> None:
    g = Graph.grid(5, 1)
    inst = Instance.tapf(g, [([(0, 0), (4, 0)], [(1, 0), (3, 0)])])
    r = hp.solve(inst, "flow")
    assert r.cost == 1
    assert r.stats["assignment"] == {"agent0": [1, 0], "agent1": [3, 0]}
    assert r.plan.ends == (g.vertex((1, 0)), g.vertex((3, 0)))


def test_flow_refuses_several_teams() -> None:
    g = Graph.grid(3, 3)
    inst = Instance.tapf(g, [([(0, 0)], [(2, 2)]), ([(2, 0)], [(0, 2)])])
    with pytest.raises(OptionError, match="one team"):
        hp.solve(inst, "flow")


def test_flow_refuses_soc() -> None:
    g = Graph.grid(3, 1)
    inst = Instance.tapf(g, [([(0, 0)], [(2, 0)])])
    with pytest.raises(OptionError, match="makespan"):
        hp.solve(inst, "flow", cost="soc")


def test_flow_infeasible() -> None:
    g = Graph.grid(5, 1, obstacles=[(2, 0)])
    inst = Instance.tapf(g, [([(0, 0), (1, 0)], [(3, 0), (4, 0)])])
    r = hp.solve(inst, "flow")
    assert r.status == Status.INFEASIBLE and r.plan is None


def test_flow_time_limit() -> None:
    g = Graph.grid(40, 40)
    rng = np.random.default_rng(1)
    cells = rng.choice(g.n, 300, replace=False)
    inst = Instance.tapf(
        g,
        [([g.location(int(v)) for v in cells[:150]], [g.location(int(v)) for v in cells[150:]])],
    )
    t0 = time.perf_counter()
    r = hp.solve(inst, "flow", time_limit=0.05, min_cost=False)
    elapsed = time.perf_counter() - t0
    # One OR-Tools call cannot be interrupted; the budget is checked between calls.
    assert elapsed < 5.0
    if r.status == Status.TIME_LIMIT:
        assert r.plan is None and r.lower_bound >= inst.makespan_lower_bound()
    else:
        assert r.status == Status.OPTIMAL and not validate(inst, r.plan)


def test_swap_gadget_forbids_swaps() -> None:
    # Two robots on a 2-vertex graph, waiting disabled: each would have to cross the
    # one edge in opposite directions at once. The shared gadget arc lets one through.
    g = Graph.grid(2, 1)
    net = TeamFlowNetwork(g, [0, 1], [0, 1], 1)
    assert net.max_flow() == 2  # with waiting, both robots simply stay
    caps = net.capacities.copy()
    caps[net.kinds == WAIT] = 0
    assert net.max_flow(caps) == 1
    # A conga line (robot 1 leaves the cell robot 0 enters) is allowed.
    g2 = Graph.grid(3, 1)
    assert conflict_free_paths(g2, [0, 1], [1, 2], 1) == [[0, 1], [1, 2]]


def test_swap_gadget_in_two_team_network() -> None:
    # Built by hand: capacities of the shared gadget arcs are 1, so two robots can
    # never cross one edge in one step in opposite directions.
    g = Graph.grid(2, 1)
    net = TeamFlowNetwork(g, [0], [1], 1)
    shared = net.kinds == SHARED
    assert shared.sum() == 1
    assert int(net.capacities[shared][0]) == 1


def test_vertex_and_edge_blocks() -> None:
    g = Graph.grid(3, 1)
    net = TeamFlowNetwork(g, [0], [2], 3)
    assert net.max_flow() == 1
    v1 = g.vertex((1, 0))
    caps = net.blocked_capacities(vertex_blocks=[(v1, t) for t in range(4)])
    assert net.max_flow(caps) == 0
    caps = net.blocked_capacities(edge_blocks=[(0, 1, t) for t in range(3)])
    assert net.max_flow(caps) == 0
    caps = net.blocked_capacities(edge_blocks=[(0, 1, 0)])
    assert net.max_flow(caps) == 1  # leave at t = 1 instead, arrive at t = 3
    caps = net.blocked_capacities(edge_blocks=[(0, 1, 0), (0, 1, 1)])
    assert net.max_flow(caps) == 0  # too late to make two moves
    caps = net.blocked_capacities(edge_blocks=[(1, 0, t) for t in range(3)])
    assert net.max_flow(caps) == 1  # the opposite direction is not affected


def test_directed_roadmap_one_way_arcs() -> None:
    g = Graph.roadmap(
        {"A": (0, 0), "B": (1, 0), "C": (1, 1)},
        [("A", "B"), ("B", "C"), ("C", "A")],
        directed=True,
    )
    inst = Instance.tapf(g, [(["A"], ["C"])])
    r = hp.solve(inst, "flow")
    assert r.cost == 2 and not validate(inst, r.plan)
    inst2 = Instance.tapf(g, [(["C"], ["B"])])
    assert hp.solve(inst2, "flow").cost == 2


def test_multi_source_bfs_reverse() -> None:
    g = Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B")], directed=True)
    assert multi_source_bfs(g, [g.vertex("B")], reverse=True).tolist() == [1, 0]
    assert multi_source_bfs(g, [g.vertex("B")]).tolist()[0] > 1000


def test_smallest_horizon_deadline() -> None:
    calls = []

    def slow(t: int) -> bool:
        calls.append(t)
        time.sleep(0.02)
        return t >= 10_000

    t, bound = smallest_horizon(slow, 0, deadline=Deadline(0.1), strategy="linear")
    assert t is None and bound == len(calls)
