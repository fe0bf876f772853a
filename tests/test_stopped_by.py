"""A solver that a limit stops says which one (``stats["stopped_by"]``), and the summary
lines of ``hierplan solve`` and ``hierplan run`` show it with ``plan_from`` and
``bound_met`` (audit: ECBS/EECBS at their time limit printed ``FEASIBLE ...
bound_met=false`` with nothing saying the limit stopped them or that the plan was
LaCAM's; CBS at its node limit said TIME_LIMIT only)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import hierplan_opt as hp
from hierplan_opt import registry
from hierplan_opt.cli import main
from hierplan_opt.search import ecbs_engine

MAI = Path(__file__).resolve().parents[1] / "instances" / "movingai"
ROOM = [str(MAI / "room-32-32-4.map"), "--scen", str(MAI / "room-32-32-4-even-1.scen")]
ROOM += ["--agents", "40"]


def room() -> hp.Instance:
    """40 agents on room-32-32-4: CBS, and ECBS/EECBS with w = 1.01, need far more than
    a second (the audit's instance)."""
    return hp.load_instance(
        MAI / "room-32-32-4.map", scen=MAI / "room-32-32-4-even-1.scen", agents=40
    )


def team_instance() -> hp.Instance:
    """One team of two robots on a 3 x 3 grid (flow, cbm, hungarian)."""
    g = hp.Graph.grid(3, 3)
    return hp.Instance.tapf(g, [([(0, 0), (2, 0)], [(2, 2), (0, 2)])])


# ------------------------------------------------------------- ECBS / EECBS at the limit
@pytest.mark.parametrize("name", ["ecbs", "eecbs"])
def test_bounded_search_at_its_time_limit_says_so(name, tmp_path, monkeypatch, capsys) -> None:
    # LaCAM needs ~0.05 s here; half the limit keeps a loaded machine from missing it
    monkeypatch.setattr(ecbs_engine, "LACAM_SHARE", 0.5)
    out = tmp_path / "p.yaml"
    argv = ["solve", *ROOM, "--solver", name, "--w", "1.01", "--time-limit", "1"]
    code = main([*argv, "--out", str(out)])
    line = capsys.readouterr().out
    assert code == 0 and line.startswith("FEASIBLE")  # a plan at the limit: exit 0
    for fact in ("stopped_by=time_limit", "plan_from=lacam", "bound_met=false"):
        assert fact in line.split(), fact
    doc = yaml.safe_load(out.read_text())["statistics"]
    assert doc["stopped_by"] == "time_limit" and doc["plan_from"] == "lacam"
    assert doc["bound_met"] is False and doc["cost"] > 1.01 * doc["lower_bound"]


@pytest.mark.parametrize("name", ["ecbs", "eecbs"])
def test_bounded_search_without_fallback_at_its_time_limit(name, capsys) -> None:
    r = hp.solve(room(), name, w=1.01, lacam="off", time_limit=0.3)
    assert r.status is hp.Status.TIME_LIMIT and r.plan is None
    assert r.stats["stopped_by"] == "time_limit" and "plan_from" not in r.stats
    argv = ["solve", *ROOM, "--solver", name, "--w", "1.01", "--set", "lacam=off"]
    assert main([*argv, "--time-limit", "0.3"]) == 4
    line = capsys.readouterr().out
    assert line.startswith("TIME_LIMIT") and "stopped_by=time_limit" in line.split()


def test_bounded_search_that_finishes_names_no_limit(capsys) -> None:
    argv = ["solve", str(MAI / "empty-8-8.map"), "--scen", str(MAI / "empty-8-8-even-1.scen")]
    assert main([*argv, "--agents", "8", "--solver", "ecbs", "--w", "1.5"]) == 0
    line = capsys.readouterr().out.split()
    assert "plan_from=search" in line and "bound_met=true" in line
    assert not any(w.startswith("stopped_by=") for w in line)


# ------------------------------------------------------------------------ CBS's limits
@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_cbs_node_limit_is_named(objective, capsys) -> None:
    r = hp.solve(room(), "cbs", node_limit=2, cost=objective, time_limit=30)
    assert r.status is hp.Status.TIME_LIMIT and r.stats["stopped_by"] == "node_limit"
    assert r.runtime < 30
    argv = ["solve", *ROOM, "--solver", "cbs", "--set", "node_limit=2", "--cost", objective]
    assert main(argv) == 4
    line = capsys.readouterr().out
    assert line.startswith("TIME_LIMIT") and "stopped_by=node_limit" in line.split()


def test_cbs_time_limit_is_named() -> None:
    r = hp.solve(room(), "cbs", time_limit=0.3)
    assert r.status is hp.Status.TIME_LIMIT and r.stats["stopped_by"] == "time_limit"


# ----------------------------------------------------------- every solver, out of time
@pytest.mark.parametrize(
    ("name", "make"),
    [
        ("cbs", room),
        ("ecbs", room),
        ("eecbs", room),
        ("lacam", room),
        ("pibt", room),
        ("cbm", team_instance),
        ("flow", team_instance),
        ("hungarian", team_instance),
    ],
)
def test_every_solver_names_the_time_limit(name, make) -> None:
    inst = make()
    r = registry.get(name).load().fn(inst, time_limit=0.0)  # the bare solver, no time
    assert r.status is hp.Status.TIME_LIMIT and r.plan is None
    assert r.stats["stopped_by"] == "time_limit"


def test_time_limit_used_up_by_the_front_doors_checks_is_named() -> None:
    r = hp.solve(room(), "cbs", time_limit=1e-9)
    assert r.status is hp.Status.TIME_LIMIT and r.stats["stopped_by"] == "time_limit"


# ------------------------------------------------------------------- LaCAM and PIBT
def test_lacam_anytime_phase_ended_by_a_limit() -> None:
    inst = room()
    r = hp.solve(inst, "lacam", time_limit=0.5)  # anytime until the limit
    assert r.status is hp.Status.FEASIBLE and r.stats["stopped_by"] == "time_limit"
    r = hp.solve(inst, "lacam", time_limit=30, anytime=0.2)  # its own budget
    assert r.status is hp.Status.FEASIBLE and r.stats["stopped_by"] == "anytime"
    assert r.runtime < 10
    first = hp.solve(inst, "lacam", time_limit=30, anytime=0)  # first plan asked: no limit
    assert first.plan is not None and "stopped_by" not in first.stats


def test_pibt_step_limit_is_named() -> None:
    r = hp.solve(room(), "pibt", max_steps=1, time_limit=30)
    assert r.status is hp.Status.TIME_LIMIT and r.stats["stopped_by"] == "max_steps"


# ------------------------------------------------------------------------ hierplan run
def test_run_plan_line_says_limit_and_fallback(monkeypatch, capsys) -> None:
    monkeypatch.setattr(ecbs_engine, "LACAM_SHARE", 0.5)
    argv = ["run", *ROOM, "--solver", "ecbs", "--set", "w=1.01", "--time-limit", "1"]
    assert main(argv) == 0
    plan_line = capsys.readouterr().out.splitlines()[0]
    assert plan_line.startswith("plan: ecbs FEASIBLE soc")
    for fact in ("stopped_by=time_limit", "plan_from=lacam", "bound_met=false"):
        assert fact in plan_line.split(), fact


def test_run_without_a_plan_says_which_limit(capsys) -> None:
    assert main(["run", *ROOM, "--solver", "cbs", "--set", "node_limit=1"]) == 4
    line = capsys.readouterr().out
    assert "found no plan (TIME_LIMIT, stopped_by=node_limit)" in line
