"""Two meanings of "objective" get two names (issue 31): a plan's ``cost`` (steps: soc,
makespan) in solve, a schedule's ``objective`` (seconds: makespan, safety, flowtime) in
postprocess. The old ``objective=`` / ``--objective`` of solve still works, with a warning."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
from io_helpers import DATA

from hierplan_opt.api import solve
from hierplan_opt.cli import main
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.execution.pipeline import run
from hierplan_opt.search import cbs

CORRIDOR = str(DATA / "corridor_lmrp.yaml")


@pytest.fixture
def inst() -> Instance:
    # soc 8 and makespan 5 come from different plans' measures of the same optimum
    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    return Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])


def test_cost_names_what_a_plan_minimises(inst: Instance) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new name warns of nothing
        r = solve(inst, "cbs", cost="makespan", time_limit=10)
        d = cbs.solve(inst, cost="makespan", time_limit=10)
    assert r.objective == d.objective == "makespan" and r.cost == d.cost == r.plan.makespan
    assert solve(inst, "cbs", time_limit=10).objective == "soc"


def test_old_objective_keyword_warns_and_still_works(inst: Instance) -> None:
    with pytest.warns(DeprecationWarning, match="cost='soc' or 'makespan'") as rec:
        r = solve(inst, "cbs", objective="makespan", time_limit=10)
    assert r.objective == "makespan"
    assert rec[0].filename == __file__  # points at the caller
    with pytest.warns(DeprecationWarning):
        assert cbs.solve(inst, objective="makespan", time_limit=10).objective == "makespan"
    with pytest.warns(DeprecationWarning):
        assert run(inst, "cbs", objective="makespan").result.objective == "makespan"
    assert run(inst, "cbs", cost="makespan").result.objective == "makespan"


def test_cost_and_old_objective_that_differ_are_refused(inst: Instance) -> None:
    with pytest.warns(DeprecationWarning), pytest.raises(OptionError, match="differ"):
        solve(inst, "cbs", cost="soc", objective="makespan")


def test_cli_cost_and_deprecated_objective(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "p.yaml"
    assert main(["solve", CORRIDOR, "--cost", "makespan", "--out", str(plan)]) == 0
    out, err = capsys.readouterr()
    assert "objective=makespan" in out and "deprecated" not in err
    assert main(["solve", CORRIDOR, "--objective", "makespan", "--out", str(plan)]) == 0
    out, err = capsys.readouterr()
    assert "objective=makespan" in out
    assert "--objective is deprecated for a plan's cost, use --cost" in err
    code = main(["solve", CORRIDOR, "--cost", "soc", "--objective", "makespan"])
    out, err = capsys.readouterr()
    assert code == 2 and "differ" in err and len(err.strip().splitlines()) == 2
