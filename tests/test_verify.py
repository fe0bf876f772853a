"""Optimality verification: library call and ``hierplan verify``."""

from __future__ import annotations

import pytest
from canned import corridor_lmrp, cross, movingai, tapf_corridor

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.formulations.verify import verify

OPT = hp.Plan.from_paths([[0, 1, 2, 3, 4], [1, 2, 7, 2, 3]])  # corridor: SOC 8, makespan 4
SLOW = hp.Plan.from_paths([[0, 0, 1, 2, 3, 4], [1, 2, 7, 7, 2, 3]])  # SOC 10, makespan 5
BAD = hp.Plan.from_paths([[0, 1, 2, 3, 4], [1, 2, 3]])  # both at (3, 0) at t=3


@pytest.mark.parametrize("method", ["cpsat", "mip"])
@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_optimal_plan_is_certified(method, objective):
    r = verify(corridor_lmrp(), OPT, objective=objective, method=method)
    assert r.status == "optimal" and r.optimal
    assert r.cost == r.optimum == r.lower_bound == (8 if objective == "soc" else 4)
    assert r.gap == 0
    # The corridor's makespan 4 equals its distance lower bound: no solver needed.
    assert r.proof == (method if objective == "soc" else "lower bound")
    assert r.message().startswith("optimal (")


@pytest.mark.parametrize("method", ["cpsat", "mip"])
@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_suboptimal_plan_gets_gap_and_better_plan(method, objective):
    inst = corridor_lmrp()
    r = verify(inst, SLOW, objective=objective, method=method)
    assert r.status == "suboptimal" and not r.optimal
    expected = {"soc": (10, 8), "makespan": (5, 4)}[objective]
    assert (r.cost, r.optimum) == expected
    assert r.excess == expected[0] - expected[1]
    assert r.gap == pytest.approx((expected[0] - expected[1]) / expected[0])
    assert hp.validate(inst, r.better_plan) == []
    assert r.better_plan.cost(objective) == expected[1]
    assert "not optimal" in r.message()


def test_invalid_plan_is_reported():
    r = verify(corridor_lmrp(), BAD)
    assert r.status == "invalid"
    assert r.violations and r.violations[0].kind == "vertex_conflict"
    assert r.message().startswith("invalid plan: vertex_conflict")


def test_lower_bound_proof_needs_no_solver():
    inst = hp.Instance.mapf(hp.Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    r = verify(inst, hp.Plan.from_paths([[0, 1, 2]]), method="mip")
    assert r.status == "optimal" and r.proof == "lower bound"


def test_cross_waits_are_optimal():
    inst = cross()
    plan = hp.Plan.from_paths([[3, 4, 5], [1, 1, 4, 7]])
    assert hp.validate(inst, plan) == []
    assert verify(inst, plan, objective="soc").optimal
    assert verify(inst, plan, objective="makespan").optimal


def test_tapf_default_objective_is_makespan():
    inst = tapf_corridor()
    plan = hp.Plan.from_paths([[0, 1, 2, 3, 4], [1, 2, 3, 4, 5]])
    r = verify(inst, plan)
    assert r.objective == "makespan" and r.optimal
    late = hp.Plan.from_paths([[0, 0, 1, 2, 3, 4], [1, 2, 3, 4, 5]])
    assert verify(inst, late).status == "suboptimal"


def test_time_limit_gives_unknown_with_bound():
    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 8)()
    res = hp.solve(inst, "cpsat", cost="soc", time_limit=60)
    assert res.plan is not None, res.status
    # Make it worse by one wait at the start, then give almost no time.
    p = res.plan.paths
    worse = hp.Plan.from_paths([[p[0][0], *p[0]], *p[1:]])
    assert hp.validate(inst, worse) == []
    r = verify(inst, worse, objective="soc", time_limit=0.2)
    assert r.status in ("unknown", "suboptimal")
    assert r.lower_bound is not None and r.lower_bound >= inst.soc_lower_bound()
    assert r.gap is not None and r.gap >= 0


def test_bad_method_is_refused():
    with pytest.raises(hp.OptionError, match="unknown verification method 'glpk'"):
        verify(corridor_lmrp(), OPT, method="glpk")
    with pytest.raises(hp.OptionError, match="unknown objective"):
        verify(corridor_lmrp(), OPT, objective="flowtime")


def test_lazy_export():
    assert hp.verify is verify


# --------------------------------------------------------------------------- CLI
MAP = "instances/movingai/random-32-32-20.map"
SCEN = "instances/movingai/random-32-32-20-random-1.scen"


@pytest.fixture
def plans(tmp_path):
    from hierplan_opt.io import load_instance, save_plan

    inst = load_instance(MAP, scen=SCEN, agents=3)
    res = hp.solve(inst, "cpsat", cost="soc")
    assert res.status == hp.Status.OPTIMAL
    good = tmp_path / "good.yaml"
    save_plan(good, inst, res.plan)
    p = res.plan.paths
    slow = tmp_path / "slow.yaml"
    save_plan(slow, inst, hp.Plan.from_paths([[p[0][0], *p[0]], *p[1:]]))
    bad = tmp_path / "bad.yaml"
    save_plan(bad, inst, hp.Plan.from_paths([p[0][:2], *p[1:]]))  # agent0 stops early
    return {"good": good, "slow": slow, "bad": bad, "cost": res.cost}


def _run(capsys, *args: str) -> tuple[int, str]:
    code = main(["-q", "verify", MAP, "--scen", SCEN, "--agents", "3", *args])
    out = capsys.readouterr()
    return code, out.out + out.err


def test_cli_optimal_exit_0(plans, capsys):
    code, out = _run(capsys, str(plans["good"]))
    assert code == 0, out
    assert out.startswith(f"optimal (sum of costs {plans['cost']}, proven by cpsat")


def test_cli_suboptimal_exit_1(plans, capsys):
    code, out = _run(capsys, str(plans["slow"]), "--method", "mip")
    assert code == 1, out
    assert f"not optimal: sum of costs {plans['cost'] + 1}, the optimum is {plans['cost']}" in out


def test_cli_invalid_exit_1(plans, capsys):
    code, out = _run(capsys, str(plans["bad"]))
    assert code == 1, out
    assert out.startswith("invalid plan: wrong_goal")


def test_cli_makespan(plans, capsys):
    code, out = _run(capsys, str(plans["good"]), "--cost", "makespan", "--time-limit", "60")
    assert code in (0, 1), out
    assert "makespan" in out


def test_cli_bad_input_exit_2(tmp_path, capsys):
    code, out = _run(capsys, str(tmp_path / "missing.yaml"))
    assert code == 2
    assert "missing.yaml" in out
