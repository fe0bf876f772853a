"""The validator: one hand-made broken plan per kind of violation, and valid plans."""

from __future__ import annotations

import pytest

from hierplan_opt import Graph, Instance, Plan, validate
from hierplan_opt.core.validate import KINDS, is_valid


@pytest.fixture
def corridor() -> Instance:
    # libMultiRobotPlanning corridor: 5x2, only (2, 1) is free in the bottom row.
    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    return Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])


def v(inst: Instance, x: int, y: int) -> int:
    return inst.graph.vertex((x, y))


def path(inst: Instance, *cells: tuple[int, int]) -> list[int]:
    return [v(inst, x, y) for x, y in cells]


def kinds(inst: Instance, paths: list[list[int]]) -> list[str]:
    return [x.kind for x in validate(inst, Plan.from_paths(paths))]


def test_optimal_corridor_plan_is_valid(corridor: Instance) -> None:
    # agent1 steps into the pocket (2, 1) and lets agent0 pass.
    p0 = path(corridor, (0, 0), (1, 0), (2, 0), (3, 0), (4, 0))
    p1 = path(corridor, (1, 0), (2, 0), (2, 1), (2, 0), (3, 0))
    plan = Plan.from_paths([p0, p1])
    assert validate(corridor, plan) == []
    assert is_valid(corridor, plan)
    assert (plan.sum_of_costs, plan.makespan) == (8, 4)


def test_agent_count(corridor: Instance) -> None:
    assert kinds(corridor, [path(corridor, (0, 0))]) == ["agent_count"]


def test_empty_path(corridor: Instance) -> None:
    assert kinds(corridor, [[], path(corridor, (1, 0))])[0] == "empty_path"


def test_off_map(corridor: Instance) -> None:
    assert kinds(corridor, [[0, 99], path(corridor, (1, 0))]) == ["off_map"]


def test_wrong_start(corridor: Instance) -> None:
    p0 = path(corridor, (2, 0), (3, 0), (4, 0))
    p1 = path(corridor, (1, 0), (1, 0), (1, 0), (2, 0), (3, 0))
    out = validate(corridor, Plan.from_paths([p0, p1]))
    assert [x.kind for x in out] == ["wrong_start"]
    assert out[0].agents == (0,) and out[0].time == 0
    assert "[2, 0]" in out[0].message and "[0, 0]" in out[0].message


def test_wrong_goal(corridor: Instance) -> None:
    p0 = path(corridor, (0, 0))
    p1 = path(corridor, (1, 0), (2, 0), (3, 0))
    out = validate(corridor, Plan.from_paths([p0, p1]))
    assert [x.kind for x in out] == ["wrong_goal"]
    assert out[0].agents == (0,)


def test_blocked_cell(corridor: Instance) -> None:
    p0 = path(corridor, (0, 0), (1, 0), (1, 1), (1, 0), (2, 0), (3, 0), (4, 0))
    p1 = path(corridor, (1, 0), (2, 0), (3, 0))
    got = kinds(corridor, [p0, p1])
    assert "blocked" in got
    blocked = [x for x in validate(corridor, Plan.from_paths([p0, p1])) if x.kind == "blocked"]
    assert blocked[0].vertex == v(corridor, 1, 1) and blocked[0].time == 2


def test_non_edge(corridor: Instance) -> None:
    # agent0 jumps two cells at once.
    p0 = path(corridor, (0, 0), (0, 0), (0, 0), (2, 0), (3, 0), (4, 0))
    p1 = path(corridor, (1, 0), (2, 0), (2, 1), (2, 1), (2, 0), (3, 0))
    out = validate(corridor, Plan.from_paths([p0, p1]))
    assert [x.kind for x in out] == ["non_edge"]
    assert out[0].time == 2


def test_vertex_conflict(corridor: Instance) -> None:
    p0 = path(corridor, (0, 0), (1, 0), (2, 0), (3, 0), (4, 0))
    p1 = path(corridor, (1, 0), (2, 0), (2, 0), (3, 0))  # waits where agent0 arrives
    out = validate(corridor, Plan.from_paths([p0, p1]))
    assert "vertex_conflict" in [x.kind for x in out]
    vc = next(x for x in out if x.kind == "vertex_conflict")
    assert vc.vertex == v(corridor, 2, 0) and vc.time == 2 and set(vc.agents) == {0, 1}


def test_vertex_conflict_with_parked_agent() -> None:
    # agent1 reaches its goal (1, 0) at t=0 and parks; agent0 drives through it at t=1.
    g = Graph.grid(3, 1)
    inst = Instance.mapf(g, [(0, 0), (1, 0)], [(2, 0), (1, 0)])
    out = validate(inst, Plan.from_paths([[0, 1, 2], [1]]))
    assert [(x.kind, x.time) for x in out] == [("vertex_conflict", 1)]


def test_vertex_conflict_at_parking_after_paths_end() -> None:
    # agent0 ends at (1, 0) at t=1; agent1's path is shorter and it parks there too.
    g = Graph.grid(3, 1)
    inst = Instance.mapf(g, [(0, 0), (2, 0)], [(1, 0), (1, 0)])
    out = validate(inst, Plan.from_paths([[0, 1], [2, 1]]))
    assert [x.kind for x in out] == ["vertex_conflict"]


def test_swap_conflict() -> None:
    g = Graph.grid(2, 1)
    inst = Instance.mapf(g, [(0, 0), (1, 0)], [(1, 0), (0, 0)])
    out = validate(inst, Plan.from_paths([[0, 1], [1, 0]]))
    assert [x.kind for x in out] == ["swap_conflict"]
    assert out[0].time == 0 and set(out[0].agents) == {0, 1}


def test_following_is_allowed() -> None:
    g = Graph.grid(4, 1)
    inst = Instance.mapf(g, [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    assert validate(inst, Plan.from_paths([[1, 2, 3], [0, 1, 2]])) == []


def test_directed_roadmap_non_edge() -> None:
    g = Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B")], directed=True)
    inst = Instance.mapf(g, ["B"], ["A"])
    assert kinds(inst, [[1, 0]]) == ["non_edge"]


@pytest.fixture
def tapf() -> Instance:
    g = Graph.grid(3, 3)
    # team0: robots at (0,0),(2,0) with targets (0,2),(2,2); team1: robot (1,1) -> (1,0)
    return Instance.tapf(g, [([(0, 0), (2, 0)], [(0, 2), (2, 2)]), ([(1, 1)], [(1, 0)])])


def test_tapf_any_assignment_is_valid(tapf: Instance) -> None:
    g = tapf.graph
    a = [g.vertex(c) for c in [(0, 0), (0, 1), (0, 2)]]
    b = [g.vertex(c) for c in [(2, 0), (2, 1), (2, 2)]]
    c = [g.vertex(c) for c in [(1, 1), (1, 0)]]
    assert validate(tapf, Plan.from_paths([a, b, c])) == []


def test_tapf_target_shared_and_missed(tapf: Instance) -> None:
    g = tapf.graph
    a = [g.vertex(c) for c in [(0, 0), (0, 1), (0, 2)]]
    b = [g.vertex(c) for c in [(2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]]
    c = [g.vertex(c) for c in [(1, 1), (1, 0)]]
    got = kinds(tapf, [a, b, c])
    assert "target_shared" in got and "target_missed" in got


def test_tapf_target_of_other_team_is_wrong_goal(tapf: Instance) -> None:
    g = tapf.graph
    a = [g.vertex(c) for c in [(0, 0), (0, 1), (0, 2)]]
    b = [g.vertex(c) for c in [(2, 0), (2, 1), (2, 2)]]
    c = [g.vertex(c) for c in [(1, 1), (1, 2)]]  # (1, 2) is nobody's target
    out = validate(tapf, Plan.from_paths([a, b, c]))
    assert [x.kind for x in out] == ["wrong_goal", "target_missed"]


def test_every_kind_is_exercised() -> None:
    # Guard: if a kind is added to KINDS, a test for it must be added above.
    assert set(KINDS) == {
        "agent_count", "empty_path", "off_map", "wrong_start", "wrong_goal",
        "target_missed", "target_shared", "blocked", "non_edge", "vertex_conflict",
        "swap_conflict",
    }  # fmt: skip
