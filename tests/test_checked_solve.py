"""One checked solve (issue 31): every way to call a registered solver outside the
solvers validates the returned plan; only the raw path (``registry.run``, ``.fn``) does not."""

from __future__ import annotations

import pytest

from hierplan_opt import registry
from hierplan_opt.api import solve
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status
from hierplan_opt.registry import DEFAULT_TIME_LIMIT, checked, solver

SEEN: dict[str, object] = {}


@solver("jumper")
def jumper(instance, *, time_limit=None, seed=0, objective="soc") -> Result:
    """A solver whose plan jumps over a cell (invalid): what a buggy solver returns."""
    SEEN["time_limit"] = time_limit
    return Result(Status.OPTIMAL, Plan.from_paths([[0, 2]]), cost=1, objective=objective)


@solver("liar")
def liar(instance, *, time_limit=None, seed=0, objective="soc") -> Result:
    """A valid plan with a wrong reported cost."""
    return Result(Status.OPTIMAL, Plan.from_paths([[0, 1, 2]]), cost=7, objective=objective)


@pytest.fixture
def inst():
    registry.register("jumper", f"{__name__}:jumper", objectives={"soc"})
    registry.register("liar", f"{__name__}:liar", objectives={"soc"})
    yield Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    registry._REGISTRY.pop("jumper")
    registry._REGISTRY.pop("liar")


def test_front_door_catches_an_invalid_plan(inst) -> None:
    r = solve(inst, "jumper")
    assert r.status is Status.ERROR and r.plan is None and r.cost is None
    assert r.stats["error"].startswith("invalid plan:") and r.stats["violations"]
    assert SEEN["time_limit"] is not None and SEEN["time_limit"] <= DEFAULT_TIME_LIMIT


def test_a_direct_call_of_a_solver_is_checked_like_the_front_door(inst) -> None:
    r = jumper(inst)
    assert r.status is Status.ERROR and r.plan is None
    assert r.stats["error"].startswith("invalid plan:")
    # the default time limit of the front door, not none
    assert SEEN["time_limit"] is not None and 0 < SEEN["time_limit"] <= DEFAULT_TIME_LIMIT
    assert r.runtime > 0


def test_a_wrong_reported_cost_is_an_error(inst) -> None:
    for r in (solve(inst, "liar"), liar(inst)):
        assert r.status is Status.ERROR
        assert r.stats["error"] == "reported cost 7 but the plan costs 2"


def test_the_raw_path_checks_no_plan(inst) -> None:
    # registry.run and .fn are private to the solvers: they pass the plan on unchecked,
    # which is why every other caller goes through solve / checked.
    assert registry.run("jumper", inst).status is Status.OPTIMAL
    assert jumper.fn(inst).status is Status.OPTIMAL
    r = checked(inst, registry.run("jumper", inst))
    assert r.status is Status.ERROR


def test_checked_passes_a_valid_plan_and_fills_in_its_cost() -> None:
    inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    good = Result(Status.FEASIBLE, Plan.from_paths([[0, 1, 2]]), objective="soc")
    r = checked(inst, good)
    assert r.status is Status.FEASIBLE and r.cost == 2 and r.plan is good.plan
    none = Result(Status.TIME_LIMIT, None)
    assert checked(inst, none) is none


def test_extra_checks_run_after_the_validator() -> None:
    inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    good = Result(Status.FEASIBLE, Plan.from_paths([[0, 1, 2]]), objective="soc")
    r = checked(inst, good, lambda i, p: ["a conflict the validator does not know"])
    assert r.status is Status.ERROR
    assert r.stats["error"] == "invalid plan: a conflict the validator does not know"
