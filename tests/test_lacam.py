"""LaCAM*: completeness, anytime optimality against CBS, validity, seeds, time limits,
the finished-flag bookkeeping of the sum of costs, and the LNS refiner."""

from __future__ import annotations

import itertools

import pytest
from canned import CASES
from lacam_cases import (
    assert_quick_time_limit,
    check,
    movingai,
    one_way_ring,
    random_grid,
    random_roadmap,
    tunnel,
)

import hierplan_opt as hp
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search.lacam import _configs, _LaCAM, _paths
from hierplan_opt.search.lns import Refiner
from hierplan_opt.search.pibt_engine import Space, sum_of_costs

MAPF_CASES = {c.name: c for c in CASES if c.kind == "mapf"}


# ---------------------------------------------------------------- completeness
@pytest.mark.parametrize(
    "inst", [tunnel(5, 1, 2, 3), tunnel(6, 1, 3, 4), tunnel(8, 1, 3, 4)], ids=lambda i: i.name
)
def test_tunnels_defeat_pibt_but_not_lacam(inst: Instance):
    assert hp.solve(inst, "pibt", max_steps=300).status == hp.Status.TIME_LIMIT
    res = hp.solve(inst, "lacam", time_limit=30, anytime=0)
    check(inst, res)
    assert res.solved


@pytest.mark.parametrize("case", ["swap5_pocket2", "swap6_pocket1", "swap_three", "train5"])
def test_corridors_and_sidings(case: str):
    inst = MAPF_CASES[case].instance()
    res = hp.solve(inst, "lacam", time_limit=30, anytime=0)
    check(inst, res)
    assert res.solved


def test_exhausted_search_proves_infeasibility():
    # The front door's joint search decides this small ring first; LaCAM alone (.fn)
    # proves it by its own exhausted search.
    from hierplan_opt.search import lacam

    res = hp.solve(one_way_ring(), "lacam", time_limit=30)
    assert res.status == hp.Status.INFEASIBLE and "exhaustive search" in res.stats["reason"]
    res = lacam.solve.fn(one_way_ring(), time_limit=30)
    assert res.status == hp.Status.INFEASIBLE and res.plan is None
    assert "exhausted" in res.stats["reason"]


def test_cheap_infeasibility_checks():
    g = Graph.grid(3, 1, obstacles=[(1, 0)])
    res = hp.solve(Instance.mapf(g, [(0, 0)], [(2, 0)]), "lacam")
    assert res.status == hp.Status.INFEASIBLE and "cannot reach" in res.stats["reason"]
    shared = Instance.mapf(Graph.grid(3, 3), [(0, 0), (2, 2)], [(1, 1), (1, 1)])
    res = hp.solve(shared, "lacam")
    assert res.status == hp.Status.INFEASIBLE and "share the goal" in res.stats["reason"]


# ---------------------------------------------------------------- optimality
@pytest.mark.parametrize(
    "case",
    ["corridor_lmrp", "swap_three", "room9_s1_k3", "random8x8_s3_k4", "random4x4_s9_k6"],
)
def test_reaches_and_proves_the_cbs_optimum(case: str):
    inst = MAPF_CASES[case].instance()
    opt = hp.solve(inst, "cbs", time_limit=60)
    res = hp.solve(inst, "lacam", time_limit=60)
    check(inst, res)
    assert opt.status == hp.Status.OPTIMAL
    assert res.status == hp.Status.OPTIMAL
    assert res.cost == opt.cost and res.lower_bound == opt.cost


def test_tunnel_optimum_proven_by_exhaustion():
    inst = tunnel(5, 1, 2, 3)
    res = hp.solve(inst, "lacam", time_limit=60)
    assert res.status == hp.Status.OPTIMAL and res.cost == 23  # CBS: 23
    assert res.stats["first_cost"] > res.cost  # the first plan was improved


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(MAPF_CASES))
def test_canned_suite_reaches_the_cbs_optimum(case: str):
    inst = MAPF_CASES[case].instance()
    opt = hp.solve(inst, "cbs", time_limit=120)
    res = hp.solve(inst, "lacam", time_limit=30)
    check(inst, res)
    assert res.cost == opt.cost and res.cost is not None and res.lower_bound is not None
    assert res.status == hp.Status.OPTIMAL or res.lower_bound < res.cost


@pytest.mark.slow
def test_larger_tunnel_matches_cbs():
    inst = tunnel(6, 1, 2, 3)
    opt = hp.solve(inst, "cbs", time_limit=120)
    res = hp.solve(inst, "lacam", time_limit=60)
    assert res.status == hp.Status.OPTIMAL and res.cost == opt.cost == 29


# ---------------------------------------------------------------- validity and seeds
@pytest.mark.parametrize(
    "inst",
    [
        random_grid(12, 12, None, 0.2, 40, 1),
        random_grid(10, 10, None, 0.1, 50, 2),
        random_grid(5, 5, 4, 0.15, 25, 3),
        random_grid(4, 4, 3, 0.0, 30, 4),
        random_roadmap(30, 12, 4),
        random_roadmap(24, 10, 5, directed=True),
    ],
    ids=["grid2d-a", "grid2d-dense", "grid3d", "grid3d-dense", "roadmap", "roadmap-directed"],
)
def test_plans_are_valid_first_and_anytime(inst: Instance):
    first = hp.solve(inst, "lacam", time_limit=20, anytime=0)
    check(inst, first)
    assert first.solved
    better = hp.solve(inst, "lacam", time_limit=20, anytime=0.5)
    check(inst, better)
    assert better.cost is not None and first.cost is not None and better.cost <= first.cost
    assert better.stats["first_cost"] == first.cost  # same seed, same first plan


def test_same_seed_same_plan():
    inst = movingai("random-32-32-10", "random-32-32-10-random-1.scen", 200)
    a = hp.solve(inst, "lacam", seed=7, anytime=0)
    b = hp.solve(inst, "lacam", seed=7, anytime=0)
    c = hp.solve(inst, "lacam", seed=8, anytime=0)
    check(inst, a)
    assert a.plan == b.plan and c.plan != a.plan
    small = MAPF_CASES["room9_s1_k3"].instance()  # anytime until proven: same path there
    x = hp.solve(small, "lacam", seed=1, time_limit=60)
    y = hp.solve(small, "lacam", seed=1, time_limit=60)
    assert x.status == y.status == hp.Status.OPTIMAL
    assert x.plan == y.plan and x.stats["iterations"] == y.stats["iterations"]


def test_short_time_limit_on_a_large_instance():
    assert_quick_time_limit("lacam")


def test_time_limit_returns_the_best_plan_so_far():
    inst = movingai("random-32-32-10", "random-32-32-10-random-1.scen", 150)
    res = hp.solve(inst, "lacam", time_limit=1.5)
    check(inst, res)
    assert res.status == hp.Status.FEASIBLE
    assert res.cost <= res.stats["first_cost"]
    assert res.runtime < 3.0


def test_refused_options():
    inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    with pytest.raises(OptionError, match="anytime must be"):
        hp.solve(inst, "lacam", anytime=-1)
    with pytest.raises(OptionError, match="lacam option mc must be >= 1"):
        hp.solve(inst, "lacam", mc=0)
    with pytest.raises(OptionError, match="anytime must be"):
        hp.solve(inst, "lacam", anytime="soon")
    with pytest.raises(OptionError, match="refine must be true or false"):
        hp.solve(inst, "lacam", refine=1)
    with pytest.raises(OptionError, match="does not optimise 'makespan'"):
        hp.solve(inst, "lacam", cost="makespan")


# ---------------------------------------------------------------- bookkeeping
def test_inserted_plan_costs_its_sum_of_costs():
    # Agent 1 starts on its goal, is pushed off and comes back: the finished flags
    # must charge it for the whole time until it is back, not just the steps away.
    inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (1, 0)], [(2, 0), (1, 0)])
    space = Space(inst)
    configs = [(0, 1), (1, 4), (2, 1)]  # agent 1 steps down to (1, 1) and back up
    assert sum_of_costs(configs, space.goals) == 2 + 2
    search = _LaCAM(space, 0)
    search.start_anytime(configs)
    assert search.best == 4
    assert search.plan_configs() == configs


def test_monte_carlo_generation_and_no_refiner():
    inst = MAPF_CASES["room9_s1_k3"].instance()
    res = hp.solve(inst, "lacam", time_limit=60, mc=3, refine=False)
    check(inst, res)
    assert res.status == hp.Status.OPTIMAL and res.cost == 18


# ---------------------------------------------------------------- the LNS refiner
def _brute_force_path(r: Refiner, i: int, horizon: int) -> int | None:
    """Cheapest final arrival of agent ``i`` around the others, by breadth-first search
    over (vertex, time) written from scratch."""
    space = r.space
    paths = [p for j, p in enumerate(r.paths) if j != i]

    def at(p: list[int], t: int) -> int:
        return p[t] if t < len(p) else p[-1]

    def free_forever(v: int, t: int) -> bool:
        return all(at(p, tt) != v for p in paths for tt in range(t, horizon + 2))

    frontier = {space.starts[i]}
    for t in range(horizon + 1):
        if space.goals[i] in frontier and free_forever(space.goals[i], t):
            return t
        nxt = set()
        for v in frontier:
            for u in [v, *space.adj[v]]:
                if any(at(p, t + 1) == u for p in paths):
                    continue
                if u != v and any(at(p, t) == u and at(p, t + 1) == v for p in paths):
                    continue
                nxt.add(u)
        frontier = nxt
    return None


def test_replanning_is_optimal_against_brute_force():
    inst = random_grid(6, 6, None, 0.1, 8, 11)
    space = Space(inst)
    configs = _LaCAM(space, 0).first_solution(Deadline(10))
    assert configs is not None
    r = Refiner(space, _paths(configs, space.goals), seed=0)
    horizon = len(configs) + 12
    for i in range(inst.num_agents):
        r._remove(i)
        got = r.replan(i, horizon)
        want = _brute_force_path(r, i, horizon)
        assert (None if got is None else len(got) - 1) == want
        r._add(i)


def _refiner(seed: int) -> tuple[Instance, Space, Refiner]:
    """A refiner on LaCAM's first plan for 120 agents of random-32-32-20."""
    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 120)
    space = Space(inst)
    configs = _LaCAM(space, 0).first_solution(Deadline(30))
    assert configs is not None
    return inst, space, Refiner(space, _paths(configs, space.goals), seed=seed)


def test_refiner_keeps_plans_valid_and_never_worse():
    inst, space, r = _refiner(2)
    costs = [r.cost]
    for _ in itertools.repeat(None, 60):
        r.step()
        costs.append(r.cost)
    assert costs == sorted(costs, reverse=True) and costs[-1] < costs[0]
    plan = space.plan(_configs(r.paths))
    assert hp.validate(inst, plan) == [] and plan.sum_of_costs == r.cost


def test_path_neighbourhood_starts_with_a_delayed_agent_and_weights_adapt():
    from hierplan_opt.search.lns import MIN_WEIGHT, PATH

    _, space, r = _refiner(4)
    for _ in range(20):
        group = r._path_neighbourhood()
        assert group is not None and len(group) == len(set(group)) >= 1
        a = group[0]
        assert len(r.paths[a]) - 1 > space.dist[a][space.starts[a]]  # delayed
    for _ in range(40):
        r.step()
    assert all(w >= MIN_WEIGHT for w in r.weights) and r.weights != [1.0, 1.0, 1.0]
    assert len(r.weights) == PATH + 1


# ---------------------------------------------------------------- guide paths
def test_guide_paths_are_short_walks_that_spread_out():
    from hierplan_opt.search.guidance import MARGIN, _Table, guide_paths, guide_table

    inst = movingai("random-32-32-10", "random-32-32-10-random-1.scen", 150)
    space = Space(inst)
    one = guide_paths(space, Deadline(30), seed=0, rounds=1)
    two = guide_paths(space, Deadline(30), seed=0, rounds=2)
    assert one is not None and two is not None

    def meetings(paths: list[list[int]]) -> int:
        table = _Table(space.nv)
        for p in paths:
            table.add(p, +1)
        total = 0
        for p in paths:
            for t in range(1, len(p)):
                total += table.meetings(p[t - 1], p[t], t) - 1 - (t == len(p) - 1)
        return total

    for i, p in enumerate(two):
        assert p[0] == space.starts[i] and p[-1] == space.goals[i]
        assert all(v in space.adj[u] for u, v in zip(p, p[1:], strict=False))
        assert len(p) - 1 <= space.dist[i][space.starts[i]] + MARGIN
    shortest = [[space.starts[i]] for i in range(inst.num_agents)]
    for i, p in enumerate(shortest):  # greedy shortest paths, for comparison
        d = space.dist[i]
        while d[p[-1]]:
            p.append(min(space.adj[p[-1]], key=d.__getitem__))
    assert meetings(two) <= meetings(one) < meetings(shortest)
    table = guide_table(two)
    assert all(table[i][p[0]] == p[1] for i, p in enumerate(two) if len(p) > 1)
    assert guide_paths(space, Deadline(0), seed=0) is None  # no time: no guidance


# ---------------------------------------------------------------- ECBS / EECBS anytime
@pytest.mark.parametrize("solver", ["ecbs", "eecbs"])
def test_bounded_solvers_return_lacam_plan_when_their_limit_runs_out(solver: str, monkeypatch):
    from hierplan_opt.search import ecbs_engine as ecbs

    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 250)
    off = hp.solve(inst, solver, time_limit=1.5, lacam="off")
    assert off.status == hp.Status.TIME_LIMIT and off.plan is None  # too many agents
    # LaCAM needs ~0.05 s CPU here; its default share of 1.5 s (0.375 s wall) ran out
    # once on a loaded 2-core machine. Half the limit keeps the test about the fallback.
    monkeypatch.setattr(ecbs, "LACAM_SHARE", 0.5)
    r = hp.solve(inst, solver, time_limit=1.5)  # lacam="fallback" by default
    assert r.status == hp.Status.FEASIBLE and r.stats["plan_from"] == "lacam"
    assert r.plan is not None and hp.validate(inst, r.plan) == []
    assert r.cost == r.plan.sum_of_costs == r.stats["lacam_cost"]
    assert r.lower_bound is not None and r.cost is not None  # the search's own bound:
    assert inst.soc_lower_bound() <= r.lower_bound <= r.cost
    assert r.runtime < 1.5 + 1.0


@pytest.mark.parametrize("solver", ["ecbs", "eecbs"])
def test_bounded_solvers_defer_the_fallback_plan(solver: str, monkeypatch):
    from hierplan_opt.search import ecbs_engine as ecbs

    # A search that ends before FALLBACK_AFTER_S never computes LaCAM's plan.
    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 20)
    quick = hp.solve(inst, solver, time_limit=30)
    assert quick.stats["plan_from"] == "search" and "lacam_status" not in quick.stats
    # Due at once: computed before the first low-level call, the search's plan returned.
    monkeypatch.setattr(ecbs, "FALLBACK_AFTER_S", 0.0)
    due = hp.solve(inst, solver, time_limit=30)
    assert due.stats["plan_from"] == "search" and due.stats["lacam_status"] == "FEASIBLE"
    assert due.cost == quick.cost and due.stats["lacam_cost"] >= due.cost / 1.5
    # LaCAM's proof that no plan exists ends the search when the fallback comes due.
    fn = hp.registry.get(solver).load().fn
    bad = fn(one_way_ring(), time_limit=5)
    assert bad.status == hp.Status.INFEASIBLE and "lacam" in bad.stats["reason"]


@pytest.mark.parametrize("solver", ["ecbs", "eecbs"])
def test_bounded_solvers_start_from_lacam_plan(solver: str):
    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 40)
    plain = hp.solve(inst, solver, time_limit=30, w=1.5, lacam="off")
    r = hp.solve(inst, solver, time_limit=30, w=1.5, lacam="start")
    assert plain.stats["plan_from"] == "search" and r.solved
    assert r.plan is not None and r.cost is not None and r.lower_bound is not None
    assert hp.validate(inst, r.plan) == [] and r.cost <= 1.5 * r.lower_bound + 1e-9
    if r.stats["plan_from"] == "lacam":  # the bound covered LaCAM's plan: early stop
        assert r.cost == r.stats["lacam_cost"]
        assert r.stats["high_level_expanded"] <= plain.stats["high_level_expanded"]
    else:  # the search's plan, cheaper than LaCAM's
        assert r.cost < r.stats["lacam_cost"]
    # A full one-way ring only rotates: without the front door's joint search (.fn),
    # the plain search cannot prove the transposition impossible, LaCAM's exhausted
    # search does (also without a time limit).
    ring = one_way_ring()
    fn = hp.registry.get(solver).load().fn
    assert fn(ring, time_limit=0.3, lacam="off").status == hp.Status.TIME_LIMIT
    bad = fn(ring, lacam="start")
    assert bad.status == hp.Status.INFEASIBLE and "lacam" in bad.stats["reason"]
    with pytest.raises(OptionError, match="lacam must be one of"):
        hp.solve(inst, solver, lacam="yes")


# ---------------------------------------------------------------- command line
@pytest.mark.parametrize("solver", ["pibt", "lacam"])
def test_cli_solve_and_validate(solver: str, tmp_path, capsys: pytest.CaptureFixture[str]):
    from lacam_cases import MOVINGAI

    from hierplan_opt.cli import main

    map_, scen = (
        str(MOVINGAI / "random-32-32-20.map"),
        str(MOVINGAI / "random-32-32-20-random-1.scen"),
    )
    plan = tmp_path / "plan.yaml"
    argv = ["solve", map_, "--scen", scen, "--agents", "100", "--solver", solver]
    argv += ["--time-limit", "5", "--seed", "3"]
    if solver == "lacam":
        argv += ["--set", "anytime=0.5"]
    assert main([*argv, "--out", str(plan)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("FEASIBLE") or out.startswith("OPTIMAL")
    assert main(["validate", map_, "--scen", scen, "--agents", "100", str(plan)]) == 0
    assert main([*argv, "--set", "swap=maybe", "--out", str(tmp_path / "x.yaml")]) == 2
    assert not (tmp_path / "x.yaml").exists()
