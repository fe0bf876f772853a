"""Issue 34, "Solvers": plans are never dropped, caps are named, directed roadmaps decided,
bounded solvers say when a plan misses the bound."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import hierplan_opt as hp
from hierplan_opt.formulations import cpsat, mip

FORMULATIONS = [mip, cpsat]


def full_3x2() -> hp.Instance:
    """A 3x2 grid full of agents where two neighbours swap goals (issue 34)."""
    g = hp.Graph.grid(3, 2)
    cells = [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1)]
    goals = [(1, 0), (0, 0), (2, 0), (0, 1), (1, 1), (2, 1)]
    return hp.Instance.mapf(g, cells, goals, name="full-3x2")


def one_way_trap() -> hp.Instance:
    """A robot must leave its goal B for the one-way loop C-D-E, from which no arc leads
    back to B: the other robot can pass, but the first never returns. Infeasible although
    every goal is reachable."""
    pts = {"A": (0, 0), "B": (1, 0), "C": (2, 0), "D": (3, 0), "E": (2, 1)}
    arcs = [("A", "B"), ("B", "C"), ("C", "D"), ("D", "E"), ("E", "C")]
    g = hp.Graph.roadmap(pts, arcs, directed=True)
    return hp.Instance.mapf(g, ["A", "B"], ["C", "B"], name="one-way-trap")


def four_cycle() -> hp.Instance:
    """A full one-way 4-cycle asked to transpose two robots: they can only rotate."""
    ring = [("A", "B"), ("B", "C"), ("C", "D"), ("D", "A")]
    g = hp.Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (1, 1), "D": (0, 1)}, ring, directed=True)
    return hp.Instance.mapf(g, ["A", "B", "C", "D"], ["B", "A", "C", "D"], name="4-cycle")


# ------------------------------------------------------------- cpsat and mip keep plans
def test_cpsat_keeps_the_plan_it_found_full_3x2() -> None:
    inst = full_3x2()
    res = cpsat.solve(inst, cost="soc", time_limit=30)
    assert res.status is hp.Status.OPTIMAL and res.plan is not None
    assert res.cost == res.lower_bound == 16 and hp.validate(inst, res.plan) == []


@pytest.mark.slow
def test_mip_keeps_the_plan_it_found_full_3x2() -> None:
    inst = full_3x2()
    res = mip.solve(inst, cost="soc", time_limit=60)
    assert res.status is hp.Status.OPTIMAL and res.cost == 16
    assert res.plan is not None and hp.validate(inst, res.plan) == []


@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
def test_a_user_cap_returns_the_plan_found_and_names_the_cap(form) -> None:
    inst = full_3x2()
    res = form.solve(inst, cost="soc", time_limit=30, max_horizon=6)
    assert res.status is hp.Status.FEASIBLE and res.plan is not None
    assert hp.validate(inst, res.plan) == [] and res.cost == res.plan.sum_of_costs
    assert res.stats["stopped_by"] == "max_horizon"
    assert res.lower_bound is not None and 2 <= res.lower_bound <= res.cost


def test_summary_line_names_the_cap(tmp_path, capsys) -> None:
    from hierplan_opt.cli import main

    hp.save_instance(tmp_path / "full.yaml", full_3x2())
    code = main(
        ["solve", str(tmp_path / "full.yaml"), "--solver", "cpsat", "--set", "max_horizon=6"]
    )
    line = capsys.readouterr().out.strip()
    assert code == 0 and line.startswith("FEASIBLE cost=")
    assert "stopped_by=max_horizon" in line


@pytest.mark.parametrize("objective", ["soc", "makespan"])
@pytest.mark.parametrize("form", FORMULATIONS, ids=lambda f: f.__name__.rsplit(".", 1)[-1])
def test_formulations_prove_small_directed_roadmaps_infeasible(form, objective) -> None:
    # The formulation itself (.fn: no front door, whose exhaustive search decides it at
    # once): the default cap reaches the horizon bound 19 (default cap 2 + 5 + 2 = 9).
    res = form.solve.fn(one_way_trap(), objective=objective, time_limit=60)
    assert res.status is hp.Status.INFEASIBLE and res.plan is None
    assert "no plan has makespan" in res.stats["reason"]


# ------------------------------------------------- bounded plans outside their bound
@pytest.mark.parametrize("name", ["ecbs", "eecbs"])
def test_lacam_fallback_outside_the_bound_is_labelled(name, tmp_path, capsys) -> None:
    from hierplan_opt.cli import main

    mai = Path(__file__).resolve().parents[1] / "instances" / "movingai"
    out = tmp_path / "plan.yaml"
    argv = ["solve", str(mai / "room-32-32-4.map"), "--scen", str(mai / "room-32-32-4-even-1.scen")]
    argv += ["--agents", "40", "--solver", name, "--w", "1.0", "--time-limit", "3"]
    code = main([*argv, "--out", str(out)])
    line = capsys.readouterr().out
    assert code == 0 and line.startswith("FEASIBLE")
    doc = yaml.safe_load(out.read_text())["statistics"]
    assert doc["plan_from"] == "lacam" and doc["cost"] > doc["lower_bound"]  # w = 1
    assert doc["bound_met"] is False and "bound_met=false" in line


def test_bound_met_on_results() -> None:
    from hierplan_opt.search import ecbs

    inst = full_3x2()
    r = hp.solve(inst, "ecbs", w=1.5, time_limit=10)
    assert r.solved and r.bound_met is True and r.stats["plan_from"] == "search"
    assert hp.solve(inst, "cbs", time_limit=10).bound_met is None
    # LaCAM's plan handed back at the limit: labelled by whether w * LB covers it
    mai = Path(__file__).resolve().parents[1] / "instances" / "movingai"
    room = hp.load_instance(
        mai / "room-32-32-4.map", scen=mai / "room-32-32-4-even-1.scen", agents=40
    )
    r = ecbs.solve.fn(room, time_limit=3.0, w=1.0)
    assert r.stats["plan_from"] == "lacam" and r.plan is not None
    assert r.bound_met is (r.cost <= r.lower_bound)


# ------------------------------------------ directed roadmaps: decided at the front door
def four_cycle_teams() -> hp.Instance:
    """Two teams trade places on a full one-way 4-cycle: they can only rotate."""
    ring = [("A", "B"), ("B", "C"), ("C", "D"), ("D", "A")]
    g = hp.Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (1, 1), "D": (0, 1)}, ring, directed=True)
    return hp.Instance.tapf(g, [(["A", "B"], ["A", "C"]), (["C", "D"], ["B", "D"])])


def one_way_trap_teams() -> hp.Instance:
    inst = one_way_trap()
    return hp.Instance.tapf(inst.graph, [(["A"], ["C"]), (["B"], ["B"])])


CASES = [
    ("cbs", one_way_trap),
    ("cbs", four_cycle),
    ("cbm", four_cycle_teams),
    ("cbm", one_way_trap_teams),
    ("hungarian", four_cycle_teams),
    ("hungarian", one_way_trap_teams),
    ("cpsat", four_cycle),
    ("mip", four_cycle),
]


@pytest.mark.parametrize(("name", "make"), CASES, ids=lambda x: getattr(x, "__name__", x))
def test_directed_infeasible_roadmaps_are_decided_not_timed_out(name, make) -> None:
    import time

    from teams_bruteforce import brute_force_makespan

    inst = make()
    assert brute_force_makespan(inst, max_depth=200) is None  # independent: no plan
    t0 = time.perf_counter()
    res = hp.solve(inst, name, time_limit=20)
    assert time.perf_counter() - t0 < 10
    assert res.status is hp.Status.INFEASIBLE and res.plan is None
    assert "exhaustive search" in res.stats["reason"]


def test_joint_reachable_agrees_with_solvers_on_solvable_directed_instances() -> None:
    from hierplan_opt.core.feasibility import joint_reachable

    ring = [("A", "B"), ("B", "C"), ("C", "D"), ("D", "A")]
    g = hp.Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (1, 1), "D": (0, 1)}, ring, directed=True)
    inst = hp.Instance.mapf(g, ["A", "B"], ["C", "D"])
    assert joint_reachable(inst) is True
    res = hp.solve(inst, "cbs", time_limit=10)
    assert res.status is hp.Status.OPTIMAL and res.cost == 4


def test_directed_time_limit_says_feasibility_is_undecided() -> None:
    # 12 robots fill a one-way ring of 12 and must transpose two: far too many joint
    # configurations to enumerate, so the time limit stops cbs and the result says that
    # nothing decided whether a plan exists.
    n = 12
    names = [f"v{i}" for i in range(n)]
    pts = {v: (i, 0) for i, v in enumerate(names)}
    g = hp.Graph.roadmap(pts, [(names[i], names[(i + 1) % n]) for i in range(n)], directed=True)
    goals = [names[1], names[0], *names[2:]]
    res = hp.solve(hp.Instance.mapf(g, names, goals), "cbs", time_limit=0.5)
    assert res.status is hp.Status.TIME_LIMIT and res.plan is None
    assert res.stats["feasibility"] == "undecided"
