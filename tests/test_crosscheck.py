"""Optimality cross-check: every exact solver returns the same optimum on the canned suite.

Which solvers apply comes from the registry (problem kind, objective, ``optimal`` /
``bounded``); every registered solver must import (a broken one fails the suite).
Bounded solvers (ECBS, EECBS) run with ``w = 1.5`` and must stay within
``w`` times the optimum. Every plan is checked by the validator.
"""

from __future__ import annotations

import networkx as nx
import pytest
from canned import CASES, FAST, Case
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import hierplan_opt as hp
from hierplan_opt import registry

W = 1.5
TIME_LIMIT = 120.0


SOLVERS = registry.names()


@pytest.mark.parametrize("name", SOLVERS)
def test_every_registered_solver_imports(name: str) -> None:
    assert registry.get(name).load().options is not None


# Narrower than the registry's capabilities: max-flow solves one-team TAPF only.
APPLIES = {"flow": lambda inst: inst.is_tapf and len(inst.teams) == 1}


def solvers_for(inst: hp.Instance, objective: str, *, bounded: bool = False) -> list[str]:
    kind = "tapf" if inst.is_tapf else "mapf"
    out = []
    for name in SOLVERS:
        info = registry.get(name)
        if kind not in info.problems or objective not in info.objectives:
            continue
        if name in APPLIES and not APPLIES[name](inst):
            continue
        if (info.bounded and not info.optimal) if bounded else info.optimal:
            out.append(name)
    return out


def crosscheck(inst: hp.Instance, objective: str, golden: int | None = None) -> dict[str, int]:
    """Run every applicable exact and bounded solver; assert agreement; return the costs."""
    exact = solvers_for(inst, objective)
    assert {"mip", "cpsat"} <= set(exact), exact
    costs: dict[str, int] = {}
    for name in exact:
        res = hp.solve(inst, name, cost=objective, time_limit=TIME_LIMIT)
        assert res.status == hp.Status.OPTIMAL, f"{name} on {inst.name}: {res.status} {res.stats}"
        assert res.plan is not None and hp.validate(inst, res.plan) == []
        assert res.cost == res.plan.cost(objective)
        assert res.lower_bound == res.cost, f"{name}: bound {res.lower_bound} != {res.cost}"
        costs[name] = int(res.cost)
    assert len(set(costs.values())) == 1, (
        f"exact solvers disagree on {inst.name}/{objective}: {costs}"
    )
    opt = next(iter(costs.values()))
    if golden is not None:
        assert opt == golden, f"{inst.name}/{objective}: optimum {opt}, hand-derived {golden}"
    for name in solvers_for(inst, objective, bounded=True):
        res = hp.solve(inst, name, cost=objective, time_limit=TIME_LIMIT, w=W)
        assert res.solved, f"{name} on {inst.name}: {res.status}"
        assert res.plan is not None and hp.validate(inst, res.plan) == []
        assert res.cost <= W * opt + 1e-9, f"{name}: cost {res.cost} > {W} * {opt}"
        costs[name] = int(res.cost)
    return costs


def _params(cases: list[Case]) -> list:
    return [pytest.param(c, obj, id=f"{c.name}-{obj}") for c in cases for obj in c.objectives]


def test_suite_size_and_kinds():
    assert len(CASES) >= 40
    kinds = {c.kind for c in CASES}
    assert kinds == {"mapf", "tapf"}
    assert len({c.name for c in CASES}) == len(CASES)
    assert sum(1 for c in CASES if c.golden) >= 5


@pytest.mark.parametrize(("case", "objective"), _params(FAST))
def test_fast_sample_agrees(case: Case, objective: str):
    crosscheck(case.instance(), objective, case.golden.get(objective))


@pytest.mark.slow
@pytest.mark.parametrize(("case", "objective"), _params([c for c in CASES if not c.fast]))
def test_full_suite_agrees(case: Case, objective: str):
    crosscheck(case.instance(), objective, case.golden.get(objective))


# --------------------------------------------------------------------------- property test
@st.composite
def small_instances(draw):
    """Random small grids that are biconnected with two free cells to spare (always solvable)."""
    w = draw(st.integers(3, 5))
    h = draw(st.integers(2, 4))
    cells = [(x, y) for x in range(w) for y in range(h)]
    blocked = draw(st.lists(st.sampled_from(cells), max_size=3, unique=True))
    g = hp.Graph.grid(w, h, obstacles=blocked)
    free = [c for c in cells if c not in blocked]
    G = nx.Graph()
    G.add_nodes_from(free)
    G.add_edges_from((g.location(u), g.location(v)) for u, v in g.edges())
    assume(len(free) >= 4 and nx.is_biconnected(G) and G.number_of_edges() > len(free))
    k = draw(st.integers(1, min(4, len(free) - 2)))
    starts = draw(st.permutations(free))[:k]
    goals = draw(st.permutations(free))[:k]
    return hp.Instance.mapf(g, starts, goals, name="hypothesis")


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_instances(), st.sampled_from(["soc", "makespan"]))
def test_random_small_grids_agree(inst: hp.Instance, objective: str):
    crosscheck(inst, objective)
