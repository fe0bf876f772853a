"""Unit tests of the time-expanded network, the MIP and the CP-SAT formulation."""

from __future__ import annotations

import numpy as np
import pytest
from canned import corridor_lmrp, cross, swap_pocket, tapf_corners, tapf_paper_like

import hierplan_opt as hp
from hierplan_opt.formulations import cpsat, mip
from hierplan_opt.formulations.time_expanded import TimeExpandedNetwork, commodity_min_deadline

FORMULATIONS = [mip, cpsat]


# --------------------------------------------------------------------------- network
@pytest.mark.parametrize("make", [corridor_lmrp, cross, swap_pocket(6, 2), tapf_paper_like])
def test_pruning_matches_definition(make):
    inst = make()
    g = inst.graph
    base = commodity_min_deadline(inst)
    deadlines = [b + 2 for b in base]
    full = TimeExpandedNetwork.build(inst, 0, deadlines=deadlines, prune=False)
    net = TimeExpandedNetwork.build(inst, 0, deadlines=deadlines)
    sinks = [c.sinks for c in net.commodities]

    def node_ok(k: int, v: int, t: int) -> bool:
        c = net.commodities[k]
        d_src = min(g.dist(s, v) for s in c.sources)
        d_snk = min(g.dist(v, s) for s in c.sinks)
        parked = any(
            v in sinks[j] and net.commodities[j].deadline <= t for j in range(len(sinks)) if j != k
        )
        return d_src <= t and d_snk <= c.deadline - t and not parked

    pruned = set(
        zip(
            net.arc_k.tolist(),
            net.arc_u.tolist(),
            net.arc_v.tolist(),
            net.arc_t.tolist(),
            strict=True,
        )
    )
    expected = {
        (k, u, v, t)
        for k, u, v, t in zip(
            full.arc_k.tolist(),
            full.arc_u.tolist(),
            full.arc_v.tolist(),
            full.arc_t.tolist(),
            strict=True,
        )
        if node_ok(k, u, t) and node_ok(k, v, t + 1)
    }
    assert pruned == expected
    assert len(pruned) < full.num_arcs


def test_roundtrip_plan_arcs():
    inst = corridor_lmrp()
    plan = hp.Plan.from_paths([[0, 1, 2, 3, 4], [1, 2, 7, 2, 3]])
    net = TimeExpandedNetwork.build(inst, 4)
    x = net.arcs_of_plan(plan)
    assert x is not None and x.sum() == 8
    assert net.plan(x) == plan
    # A plan that needs a longer horizon does not fit.
    late = hp.Plan.from_paths([[0, 0, 1, 2, 3, 4], [1, 2, 7, 2, 3]])
    assert net.arcs_of_plan(late) is None


def test_pruning_shrinks_model():
    inst = swap_pocket(7, 3)()
    pruned = TimeExpandedNetwork.build(inst, 8).stats("soc")
    full = TimeExpandedNetwork.build(inst, 8, prune=False).stats("soc")
    assert pruned["horizon"] == full["horizon"] == 8
    assert pruned["variables"] < full["variables"]
    assert pruned["constraints"] < full["constraints"]


def test_unpruned_model_has_same_optimum():
    inst = swap_pocket(5, 2)()
    values = []
    for prune in (True, False):
        model, index = cpsat.build(inst, 6, "soc", prune=prune)
        from ortools.sat.python import cp_model

        s = cp_model.CpSolver()
        s.parameters.num_workers = 1
        assert s.solve(model) == cp_model.OPTIMAL
        plan = cpsat.extract([s.value(v) for v in index.x], index)
        assert hp.validate(inst, plan) == []
        values.append(plan.sum_of_costs)
    assert values[0] == values[1]


# --------------------------------------------------------------------------- reductions
def test_mip_reduction_build_and_extract():
    import pyomo.environ as pyo
    from pyomo.contrib.appsi.solvers import Highs

    inst = corridor_lmrp()
    model, index = mip.build(inst, 6, "soc")
    opt = Highs()
    opt.highs_options = {"output_flag": False}
    res = opt.solve(model)
    assert res.termination_condition.name == "optimal"
    plan = mip.extract([pyo.value(model.x[i]) for i in range(index.num_arcs)], index)
    assert hp.validate(inst, plan) == []
    assert plan.sum_of_costs == round(pyo.value(model.cost)) == 8


def test_cpsat_reduction_build_and_extract():
    from ortools.sat.python import cp_model

    inst = corridor_lmrp()
    model, index = cpsat.build(inst, 4, "makespan")
    s = cp_model.CpSolver()
    assert s.solve(model) in (cp_model.OPTIMAL, cp_model.FEASIBLE)
    plan = cpsat.extract([s.value(v) for v in index.x], index)
    assert hp.validate(inst, plan) == [] and plan.makespan == 4
    # Horizon 3 is too short for agent0 (distance 4): infeasible by construction.
    _, short = cpsat.build(inst, 3, "makespan")
    assert short.network.infeasible


@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
def test_result_types_are_domain_types(form):
    inst = corridor_lmrp()
    res = form.solve(inst, cost="soc")
    assert isinstance(res, hp.Result) and isinstance(res.plan, hp.Plan)
    for key in ("variables", "constraints", "horizon"):
        assert isinstance(res.stats[key], int) and res.stats[key] > 0
    assert res.status == hp.Status.OPTIMAL and res.cost == res.lower_bound == 8


# --------------------------------------------------------------------------- objectives
@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
def test_soc_convention_matches_plan(form):
    # Agent 1 must wait for agent 0 at the centre: costs 2 and 3 (no trailing waits).
    inst = cross()
    res = hp.solve(inst, form.__name__.rsplit(".", 1)[-1], cost="soc")
    assert res.plan.costs in ((2, 3), (3, 2))
    assert res.cost == res.plan.sum_of_costs == 5


@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
def test_tapf_makespan_and_soc(form):
    inst = tapf_corners()
    ms = form.solve(inst, cost="makespan")
    soc = form.solve(inst, cost="soc")
    assert (ms.status, ms.cost) == (hp.Status.OPTIMAL, 2)
    assert (soc.status, soc.cost) == (hp.Status.OPTIMAL, 4)
    for r in (ms, soc):
        assert hp.validate(inst, r.plan) == []
    # Each target taken once: the assignment is part of the solution.
    assert sorted(ms.plan.ends) == sorted(inst.teams[0].targets)


def test_tapf_two_teams_respect_teams():
    inst = tapf_paper_like()
    res = hp.solve(inst, "cpsat", cost="makespan")
    assert res.status == hp.Status.OPTIMAL and hp.validate(inst, res.plan) == []
    for team in inst.teams:
        assert {res.plan.ends[i] for i in team.agents} == set(team.targets)


# --------------------------------------------------------------------------- statuses
@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
def test_proven_infeasible(form):
    g = hp.Graph.grid(3, 3)
    inst = hp.Instance.mapf(g, [(0, 0), (2, 2)], [(1, 1), (1, 1)])
    res = form.solve(inst)
    assert res.status == hp.Status.INFEASIBLE and res.plan is None
    assert "share the goal" in res.stats["reason"]


@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_one_way_ring_swap_is_proven_infeasible_by_the_horizon_bound(form, objective):
    # Two robots swap places on a full one-way ring: no plan at any horizon. On directed
    # roadmaps the pebble-motion test does not apply; the horizon bound does: 3 robots on 3
    # vertices have 6 configurations, so a solvable instance has a plan of makespan <= 5,
    # and the network at that bound has none.
    from hierplan_opt.core.feasibility import makespan_upper_bound, quick_infeasibility

    ring = [("A", "B"), ("B", "C"), ("C", "A")]
    g = hp.Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (0, 1)}, ring, directed=True)
    inst = hp.Instance.mapf(g, ["A", "B", "C"], ["B", "A", "C"])
    assert makespan_upper_bound(inst) == 5
    # The front door's exhaustive joint search decides it at once; the formulation alone
    # (.fn) proves it by the horizon bound.
    assert "exhaustive search" in (quick_infeasibility(inst) or "")
    res = form.solve.fn(inst, objective=objective, time_limit=60)
    assert res.status == hp.Status.INFEASIBLE and res.plan is None
    assert "no plan has makespan <= 5" in res.stats["reason"]
    tried = [h for h, _ in res.stats["horizons"]]
    assert max(tried) == (7 if objective == "soc" else 5)  # soc: slack 5 on min deadline 0
    # a user cap below the bound still stops with TIME_LIMIT, not a proof
    res = form.solve.fn(inst, objective=objective, max_horizon=3)
    assert res.status == hp.Status.TIME_LIMIT and res.stats["stopped_by"] == "max_horizon"
    assert res.lower_bound >= (5 if objective == "soc" else 4)


@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_solvable_directed_instance_within_the_bound(form, objective):
    # One-way ring with a hole: the robots can rotate to their goals; optimum found and
    # its makespan is within the bound.
    from hierplan_opt.core.feasibility import makespan_upper_bound

    ring = [("A", "B"), ("B", "C"), ("C", "D"), ("D", "A")]
    g = hp.Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (1, 1), "D": (0, 1)}, ring, directed=True)
    inst = hp.Instance.mapf(g, ["A", "B"], ["C", "D"])
    res = form.solve(inst, cost=objective, time_limit=60)
    assert res.status == hp.Status.OPTIMAL and res.plan is not None
    assert hp.validate(inst, res.plan) == [] and res.plan.makespan <= makespan_upper_bound(inst)
    assert res.cost == (4 if objective == "soc" else 2)


@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
def test_time_limit_is_honoured(form):
    from canned import movingai

    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 30)()
    res = form.solve(inst, cost="soc", time_limit=2.0)
    assert res.status in (hp.Status.TIME_LIMIT, hp.Status.FEASIBLE, hp.Status.OPTIMAL)
    assert res.stats["build_time"] + res.stats["solve_time"] < 15
    assert res.lower_bound is not None and res.lower_bound >= inst.soc_lower_bound()
    if res.plan is not None:
        assert hp.validate(inst, res.plan) == []
        assert res.lower_bound <= res.cost


def test_cpsat_hint_from_another_solver():
    inst = swap_pocket(6, 1)()
    plain = cpsat.solve(inst, cost="soc")
    hinted = cpsat.solve(inst, cost="soc", hint="cpsat")
    assert plain.cost == hinted.cost
    assert hinted.stats.get("hinted") is True


def test_options_are_checked():
    inst = corridor_lmrp()
    with pytest.raises(hp.OptionError, match="workers must be >= 1"):
        hp.solve(inst, "cpsat", workers=0)
    with pytest.raises(hp.OptionError, match="has no option 'w'"):
        hp.solve(inst, "mip", w=1.5)


def test_network_arrays_are_consistent():
    inst = tapf_paper_like()
    net = TimeExpandedNetwork.build(inst, 7)
    g = inst.graph
    for u, v in zip(net.arc_u.tolist(), net.arc_v.tolist(), strict=True):
        assert u == v or g.has_edge(u, v)
    assert np.all(net.arc_t < net.horizon)
    groups = [*net.vertex_groups, *net.swap_groups]
    assert all(len(a) >= 2 for a in groups)


def test_backend_error_becomes_error_status():
    from hierplan_opt.formulations.horizon import Outcome, solve_with

    class Broken:
        name = "broken"

        def __call__(self, net, objective, time_limit, hint, seed):
            return Outcome(hp.Status.ERROR, stats={"error": "solver crashed"})

    res = solve_with(Broken(), swap_pocket(5, 2)(), objective="soc", time_limit=5)
    assert res.status == hp.Status.ERROR and res.plan is None
    assert res.stats["error"] == "solver crashed"


def test_mip_without_lp_check_agrees():
    inst = swap_pocket(6, 1)()
    a = hp.solve(inst, "mip", cost="makespan")
    b = hp.solve(inst, "mip", cost="makespan", lp_check=False)
    assert a.cost == b.cost and a.status == b.status == hp.Status.OPTIMAL
    assert "lp_rejected" not in b.stats
