"""CBM (conflict-based min-cost flow): optimal TAPF makespan."""

from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from teams_bruteforce import brute_force_makespan

import hierplan_opt as hp
from hierplan_opt import Graph, Instance, OptionError, Status, validate
from hierplan_opt.core.feasibility import quick_infeasibility


def figure3(extra_grid_edges: bool = False) -> Instance:
    """The paper's Fig. 3 instance, built in code (the YAML file is tested elsewhere)."""
    vertices = {
        "A": (0, 1),
        "B": (1, 1),
        "C": (3, 1),
        "D": (4, 1),
        "E": (0, 0),
        "F": (1, 0),
        "G": (2, 0),
        "H": (3, 0),
        "I": (4, 0),
    }
    edges = [("A", "B"), ("B", "F"), ("E", "F"), ("F", "G"), ("G", "H"), ("H", "I")]
    edges += [("H", "C"), ("C", "D")]
    if extra_grid_edges:
        edges += [("A", "E"), ("D", "I")]
    g = Graph.roadmap(vertices, edges)
    return Instance.tapf(g, [(["A"], ["H"]), (["E", "F"], ["D", "I"])], name="figure3")


def random_teams(seed: int, w: int, h: int, sizes: list[int], density: float = 0.15):
    rng = np.random.default_rng(seed)
    g = Graph.grid(w, h, blocked=rng.random((h, w)) < density)
    free = np.flatnonzero(g.passable)
    k = sum(sizes)
    if len(free) < 2 * k:
        return None
    cells = [g.location(int(v)) for v in rng.choice(free, 2 * k, replace=False)]
    teams, i = [], 0
    for s in sizes:
        teams.append((cells[i : i + s], cells[k + i : k + i + s]))
        i += s
    inst = Instance.tapf(g, teams)
    return None if quick_infeasibility(inst) else inst


@pytest.mark.parametrize("extra", [False, True])
def test_figure3_makespan_4(extra: bool) -> None:
    inst = figure3(extra)
    r = hp.solve(inst, "cbm")
    assert r.status == Status.OPTIMAL
    assert r.cost == 4 == r.lower_bound
    assert not validate(inst, r.plan)
    assert brute_force_makespan(inst) == 4
    g = inst.graph
    # Team 2's robots split D and I; team 1's robot ends at H.
    assert g.location(r.plan.paths[0][-1]) == "H"
    assert {g.location(r.plan.paths[i][-1]) for i in (1, 2)} == {"D", "I"}


def test_figure3_paper_plan_is_valid() -> None:
    inst = figure3()
    g = inst.graph
    table = [list("ABFGH"), list("EFGHI"), list("FGHCD")]
    plan = hp.Plan.from_paths([[g.vertex(x) for x in row] for row in table])
    assert not validate(inst, plan)
    assert plan.makespan == 4


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(2, 3))
def test_cbm_equals_brute_force_two_teams(seed: int, k: int) -> None:
    sizes = [1, k - 1]
    inst = random_teams(seed, 3, 3, sizes)
    if inst is None:
        return
    expected = brute_force_makespan(inst, max_depth=40)
    if expected is None:  # the whole (small) state space has no goal: no plan
        r = hp.solve(inst, "cbm", time_limit=0.3)
        assert r.status in (Status.TIME_LIMIT, Status.INFEASIBLE)
        return
    r = hp.solve(inst, "cbm", time_limit=30)
    assert r.status == Status.OPTIMAL, r.stats
    assert r.cost == expected
    assert not validate(inst, r.plan)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(1, 3))
def test_cbm_equals_brute_force_mapf(seed: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    g = Graph.grid(3, 3, blocked=rng.random((3, 3)) < 0.15)
    free = np.flatnonzero(g.passable)
    if len(free) < 2 * k:
        return
    cells = [g.location(int(v)) for v in rng.choice(free, 2 * k, replace=False)]
    inst = Instance.mapf(g, cells[:k], cells[k:])
    if quick_infeasibility(inst):
        return
    expected = brute_force_makespan(inst, max_depth=40)
    if expected is None:
        r = hp.solve(inst, "cbm", time_limit=0.3)
        assert r.status != Status.OPTIMAL
        return
    r = hp.solve(inst, "cbm", time_limit=30)
    assert r.status == Status.OPTIMAL
    assert r.cost == expected
    assert not validate(inst, r.plan)


@pytest.mark.parametrize("seed", range(8))
def test_cbm_equals_flow_on_one_team(seed: int) -> None:
    rng = np.random.default_rng(seed)
    w, h = int(rng.integers(5, 12)), int(rng.integers(4, 9))
    k = int(rng.integers(2, 9))
    g = Graph.grid(w, h, blocked=rng.random((h, w)) < 0.2)
    free = np.flatnonzero(g.passable)
    if len(free) < 2 * k:
        pytest.skip("grid too blocked for this seed")
    cells = [g.location(int(v)) for v in rng.choice(free, 2 * k, replace=False)]
    inst = Instance.tapf(g, [(cells[:k], cells[k:])])
    if quick_infeasibility(inst):
        assert hp.solve(inst, "cbm").status == Status.INFEASIBLE
        assert hp.solve(inst, "flow").status == Status.INFEASIBLE
        return
    a = hp.solve(inst, "cbm")
    b = hp.solve(inst, "flow")
    assert a.status == b.status == Status.OPTIMAL
    assert a.cost == b.cost
    assert not validate(inst, a.plan) and not validate(inst, b.plan)


@pytest.mark.parametrize("tie_break", ["cost", "avoid", "none", "auto"])
def test_tie_breaks_agree(tie_break: str) -> None:
    for seed in range(3):
        inst = random_teams(seed, 7, 6, [3, 3, 2])
        if inst is None:
            continue
        ref = hp.solve(inst, "cbm", tie_break="cost", time_limit=60)
        r = hp.solve(inst, "cbm", tie_break=tie_break, time_limit=60)
        assert r.status == ref.status == Status.OPTIMAL
        assert r.cost == ref.cost
        assert not validate(inst, r.plan)


def test_tapf_validation_each_target_once() -> None:
    inst = random_teams(3, 8, 6, [4, 3, 3])
    assert inst is not None
    r = hp.solve(inst, "cbm")
    assert r.status == Status.OPTIMAL
    assert not validate(inst, r.plan)
    for team in inst.teams:
        ends = sorted(r.plan.paths[i][-1] for i in team.agents)
        assert ends == sorted(team.targets)
    # The validator notices a robot that ends on another team's target.
    paths = [list(p) for p in r.plan.paths]
    a, b = inst.teams[0].agents[0], inst.teams[1].agents[0]
    paths[a], paths[b] = paths[b], paths[a]
    kinds = {v.kind for v in validate(inst, hp.Plan.from_paths(paths))}
    assert "wrong_start" in kinds and "wrong_goal" in kinds


def test_two_teams_must_pass_proven_infeasible() -> None:
    # A corridor: two teams must pass each other, which is impossible; the exact
    # pebble-motion test (core/pebble_motion.py) proves it before any search.
    g = Graph.grid(4, 1)
    inst = Instance.tapf(g, [([(0, 0)], [(3, 0)]), ([(3, 0)], [(0, 0)])])
    r = hp.solve(inst, "cbm", time_limit=5.0)
    assert r.status == Status.INFEASIBLE and "cannot pass" in r.stats["reason"]


def test_two_teams_must_pass_time_limit() -> None:
    # A full one-way ring only rotates its robots. On a small ring the exhaustive joint
    # search proves that two teams cannot trade places; on a ring of 16 robots in 8 teams
    # (16! / 2^8 configurations) no check proves it, so CBM must stop at the time limit.
    ring = [("A", "B"), ("B", "C"), ("C", "D"), ("D", "A")]
    g = Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (1, 1), "D": (0, 1)}, ring, directed=True)
    inst = Instance.tapf(g, [(["A", "B"], ["A", "C"]), (["C", "D"], ["B", "D"])])
    r = hp.solve(inst, "cbm", time_limit=10.0)
    assert r.status == Status.INFEASIBLE and "exhaustive search" in r.stats["reason"]
    n = 16
    names = [f"v{i}" for i in range(n)]
    big = Graph.roadmap(
        {v: (i, 0) for i, v in enumerate(names)},
        [(names[i], names[(i + 1) % n]) for i in range(n)],
        directed=True,
    )
    # teams of two neighbours; the first two teams trade one robot's place
    teams = [
        ([names[2 * t], names[2 * t + 1]], [names[2 * t], names[2 * t + 1]]) for t in range(n // 2)
    ]
    teams[0] = ([names[0], names[1]], [names[0], names[2]])
    teams[1] = ([names[2], names[3]], [names[1], names[3]])
    inst = Instance.tapf(big, teams)
    t0 = time.perf_counter()
    r = hp.solve(inst, "cbm", time_limit=1.0)
    assert time.perf_counter() - t0 < 3.0
    assert r.status == Status.TIME_LIMIT and r.plan is None
    assert r.lower_bound >= 1 and r.stats["feasibility"] == "undecided"


def test_infeasible_detected() -> None:
    g = Graph.grid(5, 1, obstacles=[(2, 0)])
    inst = Instance.tapf(g, [([(0, 0)], [(4, 0)]), ([(3, 0)], [(1, 0)])])
    r = hp.solve(inst, "cbm")
    assert r.status == Status.INFEASIBLE
    assert "reason" in r.stats


def test_options_refused() -> None:
    inst = figure3()
    with pytest.raises(OptionError):
        hp.solve(inst, "cbm", cost="soc")
    with pytest.raises(OptionError, match="tie_break"):
        hp.solve(inst, "cbm", tie_break="random")


def test_stats_reported() -> None:
    inst = random_teams(5, 8, 6, [3, 3])
    assert inst is not None
    r = hp.solve(inst, "cbm")
    for key in ("high_level_expanded", "high_level_generated", "low_level_calls"):
        assert r.stats[key] >= 1
    assert r.stats["max_flow_solves"] >= len(inst.teams)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 100_000))
def test_conflict_detection_matches_validator(seed: int) -> None:
    # Random walks of robots in two teams: the vectorised conflict finder must see a
    # conflict between different teams exactly when the validator reports one.
    from hierplan_opt.search.cbm import _find_conflicts
    from hierplan_opt.search.conflicts import EDGE

    rng = np.random.default_rng(seed)
    g = Graph.grid(4, 3)
    k = int(rng.integers(2, 6))
    starts = [int(v) for v in rng.choice(g.n, k, replace=False)]
    paths = []
    for s in starts:
        p = [s]
        for _ in range(int(rng.integers(0, 6))):
            p.append(int(rng.choice([p[-1], *g.adj[p[-1]]])))
        paths.append(p)
    team_of = [int(x) for x in rng.integers(0, 2, k)]
    count, first, involved = _find_conflicts(paths, team_of)
    inst = Instance.mapf(g, [g.location(s) for s in starts], [g.location(p[-1]) for p in paths])
    violations = [
        v
        for v in validate(inst, hp.Plan.from_paths(paths))
        if v.kind in ("vertex_conflict", "swap_conflict")
        and team_of[v.agents[0]] != team_of[v.agents[1]]
    ]
    assert (count > 0) == bool(violations)
    if first is not None:
        earliest = min(v.time for v in violations)
        assert first.t - (first.kind == EDGE) == earliest  # an edge conflict: its departure
        assert involved <= {0, 1}


@pytest.mark.parametrize("tie_break", ["cost", "avoid"])
def test_repair_keeps_optimum(tie_break: str) -> None:
    for seed in range(3):
        inst = random_teams(seed + 10, 7, 6, [3, 3, 2])
        if inst is None:
            continue
        ref = hp.solve(inst, "cbm", time_limit=60)
        r = hp.solve(inst, "cbm", tie_break=tie_break, repair_rounds=2, time_limit=60)
        assert r.status == ref.status == Status.OPTIMAL
        assert r.cost == ref.cost
        assert not validate(inst, r.plan)


def test_constraint_that_can_never_be_met_prunes_branch() -> None:
    # A directed roadmap where the only way from A to C passes B: a team constrained
    # away from B at every time it could use it has no plan; the low level must give
    # up (safety cut-off) rather than loop, and CBM must still find the optimum
    # through the other branch.
    g = Graph.roadmap(
        {"A": (0, 0), "B": (1, 0), "C": (2, 0), "D": (1, 1)},
        [("A", "B"), ("B", "C"), ("D", "B")],
        directed=True,
    )
    inst = Instance.tapf(g, [(["A"], ["C"]), (["D"], ["B"])])
    r = hp.solve(inst, "cbm", time_limit=30)
    assert r.status == Status.OPTIMAL
    assert not validate(inst, r.plan)
    assert brute_force_makespan(inst) == r.cost
