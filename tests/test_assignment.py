"""Hungarian / bottleneck target assignment, then MAPF (solver "hungarian")."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import hierplan_opt as hp
from hierplan_opt import Graph, Instance, OptionError, Status, validate
from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.search.assignment import assign, bottleneck_value, distance_matrix


def _perms(n: int):
    return itertools.permutations(range(n))


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 5).flatmap(lambda n: arrays(np.int64, (n, n), elements=st.integers(0, 9))))
def test_assignments_match_brute_force(d: np.ndarray) -> None:
    n = d.shape[0]
    rows = np.arange(n)
    best_sum = min(int(d[rows, list(p)].sum()) for p in _perms(n))
    best_max = min(int(d[rows, list(p)].max()) for p in _perms(n))
    best_sum_at_max = min(
        int(d[rows, list(p)].sum()) for p in _perms(n) if d[rows, list(p)].max() == best_max
    )
    assert bottleneck_value(d) == best_max
    soc = assign(d, "soc")
    assert sorted(soc.tolist()) == list(range(n))
    assert int(d[rows, soc].sum()) == best_sum
    ms = assign(d, "makespan")
    assert sorted(ms.tolist()) == list(range(n))
    assert int(d[rows, ms].max()) == best_max
    assert int(d[rows, ms].sum()) == best_sum_at_max


def test_bottleneck_unreachable() -> None:
    d = np.array([[1, UNREACHABLE], [2, UNREACHABLE]])
    assert bottleneck_value(d) == UNREACHABLE


def test_distance_matrix_on_grid() -> None:
    g = Graph.grid(4, 3, obstacles=[(1, 1)])
    d = distance_matrix(g, [g.vertex((0, 1))], [g.vertex((2, 1)), g.vertex((0, 0))])
    assert d.tolist() == [[4, 1]]


def warehouse_like(seed: int) -> Instance:
    rng = np.random.default_rng(seed)
    g = Graph.grid(10, 6, obstacles=[(x, 2) for x in range(2, 8)] + [(x, 4) for x in range(2, 8)])
    free = np.flatnonzero(g.passable)
    cells = [g.location(int(v)) for v in rng.choice(free, 12, replace=False)]
    return Instance.tapf(g, [(cells[0:3], cells[6:9]), (cells[3:6], cells[9:12])])


@pytest.mark.parametrize("seed", range(5))
def test_hungarian_with_cbm_is_valid_and_bounded(seed: int) -> None:
    inst = warehouse_like(seed)
    r = hp.solve(inst, "hungarian", mapf_solver="cbm", time_limit=60)
    assert r.status in (Status.OPTIMAL, Status.FEASIBLE)
    assert not validate(inst, r.plan)
    opt = hp.solve(inst, "cbm", time_limit=60)
    assert opt.status == Status.OPTIMAL
    # The bottleneck bound is a valid lower bound and the fixed assignment can
    # only be as good as the optimal TAPF plan.
    assert r.lower_bound <= opt.cost <= r.cost
    if r.status == Status.OPTIMAL:
        assert r.cost == opt.cost


def test_hungarian_can_be_worse_than_cbm() -> None:
    # Found by a random search: on a 4 x 2 grid the distance-based assignment leaves
    # the robots in each other's way; assigning with the paths (CBM) saves a step.
    g = Graph.grid(4, 2)
    inst = Instance.tapf(g, [([(1, 0), (0, 0), (0, 1)], [(2, 1), (3, 1), (3, 0)])])
    opt = hp.solve(inst, "cbm")
    fixed = hp.solve(inst, "hungarian", mapf_solver="cbm")
    assert opt.status == Status.OPTIMAL and opt.cost == 3
    assert fixed.status == Status.FEASIBLE and fixed.cost == 4
    assert fixed.lower_bound == 3
    assert not validate(inst, opt.plan) and not validate(inst, fixed.plan)


@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_hungarian_with_cbs(objective: str) -> None:
    inst = warehouse_like(7)
    r = hp.solve(inst, "hungarian", cost=objective, time_limit=60)
    assert r.status in (Status.OPTIMAL, Status.FEASIBLE)
    assert not validate(inst, r.plan)
    assert r.lower_bound <= r.cost
    assert r.stats["mapf_solver"] == "cbs"


def test_hungarian_soc_bound_is_assignment_sum() -> None:
    g = Graph.grid(6, 1)
    inst = Instance.tapf(g, [([(0, 0), (1, 0)], [(4, 0), (5, 0)])])
    r = hp.solve(inst, "hungarian", cost="soc")
    assert r.lower_bound == 8  # 4 + 4 (or 5 + 3)
    assert r.cost == 8 and r.status == Status.OPTIMAL


def test_hungarian_refuses_mapf_and_reports_infeasible() -> None:
    g = Graph.grid(3, 1)
    with pytest.raises(OptionError):
        hp.solve(Instance.mapf(g, [(0, 0)], [(2, 0)]), "hungarian")
    g2 = Graph.grid(3, 1, obstacles=[(1, 0)])
    inst = Instance.tapf(g2, [([(0, 0)], [(2, 0)])])
    assert hp.solve(inst, "hungarian", mapf_solver="cbm").status == Status.INFEASIBLE


def test_hungarian_unknown_inner_option_refused() -> None:
    inst = warehouse_like(0)
    with pytest.raises(OptionError):
        hp.solve(inst, "hungarian", mapf_solver="cbm", mapf_options={"bogus": 1})
