"""PIBT: the one-step generator, the solver's honesty when it fails, validity, seeds."""

from __future__ import annotations

import pytest
from lacam_cases import (
    assert_quick_time_limit,
    check,
    movingai,
    random_grid,
    random_roadmap,
    tunnel,
)

import hierplan_opt as hp
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.search.pibt_engine import NIL, PIBT, Space, next_priorities, sum_of_costs


def _step(inst: Instance, order: list[int], q_to: list[int] | None = None, swap: bool = True):
    space = Space(inst)
    q_to = [NIL] * inst.num_agents if q_to is None else q_to
    fixed = [i for i, v in enumerate(q_to) if v != NIL]
    ok = PIBT(space, seed=0, swap=swap).step(space.starts, q_to, order, fixed)
    return ok, q_to


# ---------------------------------------------------------------- the generator
def test_priority_inheritance_pushes_a_chain():
    # Agent 0 wants (1,0), occupied by agent 1, which must move on to (2,0), and so on.
    inst = Instance.mapf(Graph.grid(4, 1), [(0, 0), (1, 0), (2, 0)], [(3, 0), (2, 0), (1, 0)])
    ok, q_to = _step(inst, [0, 1, 2])
    assert ok and q_to == [1, 2, 3]


def test_backtracking_when_the_pushed_agent_is_stuck():
    # 3-cell corridor full of agents: agent 0 cannot push anybody, everybody stays.
    inst = Instance.mapf(Graph.grid(3, 1), [(0, 0), (1, 0), (2, 0)], [(2, 0), (1, 0), (0, 0)])
    ok, q_to = _step(inst, [0, 1, 2])
    assert ok and q_to == [0, 1, 2]


def test_no_swap_conflict_is_generated():
    # Two agents face each other on a 2-cell path: exchanging places is forbidden.
    inst = Instance.mapf(Graph.grid(2, 1), [(0, 0), (1, 0)], [(1, 0), (0, 0)])
    ok, q_to = _step(inst, [0, 1], swap=False)
    assert ok and q_to == [0, 1]


def test_constraints_are_respected_or_refused():
    inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    ok, q_to = _step(inst, [0, 1], q_to=[NIL, 5])  # agent 1 must go down to (2, 1)
    assert ok and q_to[1] == 5 and q_to[0] in (0, 1, 3)
    ok, _ = _step(inst, [0, 1], q_to=[1, 1])  # both on (1, 0): refused
    assert not ok


def test_elapsed_time_priorities_and_sum_of_costs():
    assert next_priorities([0.25, 3.5], [4, 9], [4, 1]) == [0.25, 4.5]
    # agent 1 leaves its goal at t=1 and comes back at t=3: it costs 3, not 0
    assert sum_of_costs([(0, 5), (1, 4), (2, 4), (2, 5)], [2, 5]) == 2 + 3


# ---------------------------------------------------------------- the solver
def test_solves_a_corridor_with_a_pocket_optimally():
    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    res = hp.solve(inst, "pibt", time_limit=10)
    check(inst, res)
    assert res.status == hp.Status.FEASIBLE and res.cost == 8  # optimal, but not proven


def test_tunnel_defeats_pibt_and_it_says_so():
    inst = tunnel(6, 1, 2, 3)
    res = hp.solve(inst, "pibt", max_steps=300)
    assert res.status == hp.Status.TIME_LIMIT and res.plan is None
    assert "step limit" in res.stats["reason"]
    assert res.lower_bound == Space(inst).lower_bound()


def test_swap_extension_resolves_a_head_on_meeting():
    # Two agents meet head-on in a corridor with one side pocket at x = 2, behind
    # agent 0: it must back into the pocket to let agent 1 pass.
    obstacles = [(x, 1) for x in range(7) if x != 2]
    g = Graph.grid(7, 2, obstacles=obstacles)
    inst = Instance.mapf(g, [(3, 0), (5, 0)], [(6, 0), (0, 0)])
    with_swap = hp.solve(inst, "pibt", max_steps=200, swap=True)
    without = hp.solve(inst, "pibt", max_steps=200, swap=False)
    check(inst, with_swap)
    assert with_swap.solved
    assert without.status == hp.Status.TIME_LIMIT and without.plan is None


@pytest.mark.parametrize(
    "inst",
    [
        random_grid(12, 12, None, 0.2, 30, 1),
        random_grid(10, 10, None, 0.1, 40, 2),
        random_grid(5, 5, 4, 0.15, 20, 3),
        random_roadmap(30, 10, 4),
        random_roadmap(30, 8, 5, directed=True),
    ],
    ids=["grid2d-a", "grid2d-b", "grid3d", "roadmap", "roadmap-directed"],
)
def test_plans_are_valid_or_honestly_missing(inst: Instance):
    res = hp.solve(inst, "pibt", time_limit=10, max_steps=500)
    check(inst, res)
    assert res.solved or res.status == hp.Status.TIME_LIMIT


def test_same_seed_same_plan_other_seed_other_plan():
    inst = movingai("random-32-32-10", "random-32-32-10-random-1.scen", 150)
    a = hp.solve(inst, "pibt", seed=3)
    b = hp.solve(inst, "pibt", seed=3)
    c = hp.solve(inst, "pibt", seed=4)
    check(inst, a)
    assert a.plan == b.plan
    assert c.plan != a.plan


def test_infeasible_and_refused_options():
    g = Graph.grid(3, 1, obstacles=[(1, 0)])
    res = hp.solve(Instance.mapf(g, [(0, 0)], [(2, 0)]), "pibt")
    assert res.status == hp.Status.INFEASIBLE and "cannot reach" in res.stats["reason"]
    inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    with pytest.raises(OptionError, match="pibt option max_steps must be >= 1"):
        hp.solve(inst, "pibt", max_steps=0)
    with pytest.raises(OptionError, match="swap must be true or false"):
        hp.solve(inst, "pibt", swap="no")
    with pytest.raises(OptionError, match="does not optimise 'makespan'"):
        hp.solve(inst, "pibt", cost="makespan")


def test_short_time_limit_on_a_large_instance():
    assert_quick_time_limit("pibt")
