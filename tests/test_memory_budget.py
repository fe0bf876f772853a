"""Model-size estimates and the memory budget of the time-expanded formulations."""

from __future__ import annotations

import resource

import pytest
from canned import corridor_lmrp, movingai, tapf_paper_like

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.core.resources import meminfo
from hierplan_opt.formulations import cpsat, mip
from hierplan_opt.formulations import memory as mem
from hierplan_opt.formulations.time_expanded import TimeExpandedNetwork, commodity_min_deadline
from hierplan_opt.formulations.verify import verify

MAP = "instances/movingai/random-32-32-20.map"
SCEN = "instances/movingai/random-32-32-20-random-1.scen"


@pytest.mark.parametrize("slack", [0, 3, 12])
def test_estimate_is_an_upper_bound_and_tight(slack: int) -> None:
    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 12)()
    base = commodity_min_deadline(inst)
    for kwargs in (
        {"deadlines": [b + slack for b in base]},
        {},
        {"detours": [b + 2 for b in base]},
    ):
        horizon = max(base) + slack
        est = mem.estimate_network(inst, horizon, **kwargs)
        net = TimeExpandedNetwork.build(inst, horizon, **kwargs)
        # the estimate skips only the arcs that parked robots remove
        assert net.num_arcs <= est.arcs <= 1.05 * net.num_arcs + 50, kwargs
        nodes = len(net.conservation) + len(net.source_out) + len(net.sink_in)
        assert len(net.conservation) <= est.nodes <= 1.05 * nodes + 50, kwargs


def test_estimate_for_teams() -> None:
    inst = tapf_paper_like()
    for horizon in (4, 9):
        est = mem.estimate_network(inst, horizon)
        assert TimeExpandedNetwork.build(inst, horizon).num_arcs <= est.arcs


@pytest.mark.parametrize("form", [cpsat, mip], ids=["cpsat", "mip"])
@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_search_stops_before_building_a_model_over_the_budget(
    form, objective: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    inst = movingai("random-32-32-20", "random-32-32-20-random-1.scen", 5)()

    def never(*args: object, **kwargs: object) -> TimeExpandedNetwork:
        raise AssertionError("a model over the budget was built")

    monkeypatch.setattr(TimeExpandedNetwork, "build", never)
    with mem.memory_limit(100_000):  # 100 kB: no model of 5 agents fits
        res = form.solve(inst, cost=objective, time_limit=30)
    assert res.status == hp.Status.TIME_LIMIT and res.plan is None
    assert res.stats["stopped_by"] == "memory_limit"
    assert f"the {form.__name__.rsplit('.', 1)[-1]} model at horizon" in res.stats["reason"]
    assert "over the memory budget of" in res.stats["reason"]
    lb = inst.soc_lower_bound() if objective == "soc" else inst.makespan_lower_bound()
    assert res.lower_bound is not None and res.lower_bound >= lb


@pytest.mark.parametrize("objective", ["soc", "makespan"])
def test_verify_refuses_with_the_size(objective: str) -> None:
    inst = corridor_lmrp()
    slow = hp.Plan.from_paths([[0, 0, 1, 2, 3, 4], [1, 2, 7, 7, 2, 3]])  # not optimal
    with mem.memory_limit(1000):
        r = verify(inst, slow, objective=objective)
    assert r.status == "unknown" and not r.optimal
    assert "would need ~" in r.reason and "over the memory budget of" in r.reason
    line = r.message()
    assert "\n" not in line and line.startswith("unknown: ") and r.reason in line
    with mem.memory_limit(4 * mem.GB):  # within the budget the verdict is unchanged
        assert verify(inst, slow, objective=objective).status == "suboptimal"


def _verify_cli(capsys: pytest.CaptureFixture[str], tmp_path, *extra: str) -> tuple[int, str]:
    from hierplan_opt.io import load_instance, save_plan

    inst = load_instance(MAP, scen=SCEN, agents=3)
    res = hp.solve(inst, "cbs", cost="soc")
    assert res.plan is not None
    p = res.plan.paths
    plan = tmp_path / "slow.yaml"
    save_plan(plan, inst, hp.Plan.from_paths([[p[0][0], *p[0]], *p[1:]]))  # one wait more
    code = main(["-q", "verify", MAP, "--scen", SCEN, "--agents", "3", str(plan), *extra])
    out = capsys.readouterr()
    return code, out.out + out.err


def test_cli_memory_limit_is_exit_4_with_one_line(tmp_path, capsys) -> None:
    before = resource.getrlimit(resource.RLIMIT_DATA)
    budget = mem.memory_budget()
    code, out = _verify_cli(capsys, tmp_path, "--memory-limit", "0.000001")
    assert code == 4, out
    assert len(out.strip().splitlines()) == 1
    assert "would need ~" in out and "over the memory budget of 1e-06 GB" in out
    assert resource.getrlimit(resource.RLIMIT_DATA) == before  # restored
    assert mem.memory_budget() == budget


def test_cli_out_of_memory_is_exit_4(tmp_path, capsys, monkeypatch) -> None:
    import hierplan_opt.cli.verify as cli_verify

    def blow_up(args: object) -> int:
        raise MemoryError

    monkeypatch.setattr(cli_verify, "run", blow_up)
    code, out = _verify_cli(capsys, tmp_path)
    assert code == 4 and out.strip() == (
        "hierplan verify: error: out of memory (over the memory budget; certify fewer "
        "agents or raise --memory-limit)"
    )


def test_cli_data_limit_is_set_while_the_command_runs(tmp_path, capsys, monkeypatch) -> None:
    import hierplan_opt.cli.verify as cli_verify

    seen: list[int] = []

    def look(args: object) -> int:
        seen.append(resource.getrlimit(resource.RLIMIT_DATA)[0])
        return 0

    monkeypatch.setattr(cli_verify, "run", look)
    assert _verify_cli(capsys, tmp_path, "--memory-limit", "3")[0] == 0
    soft = resource.getrlimit(resource.RLIMIT_DATA)[0]
    assert seen and seen[0] != resource.RLIM_INFINITY
    assert 3 * mem.GB < seen[0] <= (soft if soft != resource.RLIM_INFINITY else 1 << 62)


def test_budget_from_environment(monkeypatch, tmp_path, capsys) -> None:
    monkeypatch.setattr(mem, "_budget", None)
    monkeypatch.setenv("HIERPLAN_MEMORY_LIMIT_GB", "2.5")
    assert mem.memory_budget() == int(2.5 * mem.GB)
    monkeypatch.setattr(mem, "_budget", None)
    monkeypatch.setenv("HIERPLAN_MEMORY_LIMIT_GB", "lots")
    code, out = _verify_cli(capsys, tmp_path)
    assert code == 2 and "HIERPLAN_MEMORY_LIMIT_GB must be a positive number of GB" in out
    monkeypatch.setattr(mem, "_budget", None)


def test_default_budget_is_a_fraction_of_the_machine() -> None:
    info = meminfo()
    budget = mem.default_budget()
    if "MemTotal" in info:
        assert budget <= info["MemTotal"] // 2


def test_cli_solve_memory_limit(tmp_path, capsys) -> None:
    out = tmp_path / "p.yaml"
    argv = ["solve", MAP, "--scen", SCEN, "--agents", "5", "--solver", "mip"]
    code = main([*argv, "--memory-limit", "0.0001", "--out", str(out)])
    std = capsys.readouterr()
    assert code == 4 and not out.exists()
    assert "stopped_by=memory_limit" in std.out
    assert std.err.startswith("hierplan solve: the mip model at horizon ")
    assert "over the memory budget of 0.0001 GB" in std.err


@pytest.mark.parametrize("solver", ["cbs", "eecbs"])
def test_search_stops_at_the_memory_limit_with_its_bound(monkeypatch, solver: str) -> None:
    """A long search stops near the process's memory limit, says so and keeps its lower
    bound, instead of dying in a MemoryError (here the limit is set 80 MB above what the
    process uses)."""
    from hierplan_opt.core import timer

    data, _ = timer.memory_use()
    limit = float(data + (80 << 20))  # the margin is then a quarter of that: 20 MB
    monkeypatch.setattr(timer, "memory_limits", lambda: (limit, float("inf")))
    inst = movingai("empty-32-32", "empty-32-32-even-1.scen", 200)()
    options = {"w": 1.001, "lacam": "off"} if solver == "eecbs" else {}
    res = hp.solve(inst, solver, time_limit=120, **options)
    assert res.status is hp.Status.TIME_LIMIT and res.plan is None
    assert res.stats["stopped_by"] == "memory_limit"
    assert res.stats["reason"].startswith(f"{solver.upper()} stopped at the memory limit")
    assert res.runtime < 60 and res.lower_bound >= inst.soc_lower_bound()


@pytest.mark.slow
def test_cli_search_memory_limit_is_one_line_and_exit_4(tmp_path) -> None:
    """``--memory-limit`` also bounds CBS: the result line, then one line saying why."""
    import subprocess
    import sys

    out = tmp_path / "p.yaml"
    argv = [sys.executable, "-m", "hierplan_opt", "solve", "instances/movingai/empty-32-32.map"]
    argv += ["--scen", "instances/movingai/empty-32-32-even-1.scen", "--agents", "200"]
    argv += ["--solver", "cbs", "--time-limit", "120", "--memory-limit", "0.2", "--out", str(out)]
    run = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert run.returncode == 4 and not out.exists()
    assert run.stdout.startswith("TIME_LIMIT lb=") and "stopped_by=memory_limit" in run.stdout
    assert run.stderr.startswith("hierplan solve: CBS stopped at the memory limit (")
    assert run.stderr.count("\n") == 1


def test_search_stops_when_the_machine_runs_short_of_memory(monkeypatch) -> None:
    """Without any limit of its own (a program calling the library), a search stops with
    its bound when the machine or container has less than MEMORY_MARGIN left."""
    from hierplan_opt.core import timer

    monkeypatch.setattr(timer, "memory_available", lambda: float(timer.MEMORY_MARGIN - 1))
    monkeypatch.setattr(timer, "memory_limits", lambda: (float("inf"), float("inf")))
    inst = movingai("room-32-32-4", "room-32-32-4-even-1.scen", 20)()
    res = hp.solve(inst, "cbs", time_limit=60)
    assert res.status is hp.Status.TIME_LIMIT and res.stats["stopped_by"] == "memory_limit"
    assert res.stats["reason"].startswith("CBS stopped at the machine's free memory (under 256 MB")
    assert res.lower_bound >= inst.soc_lower_bound()


def test_the_margin_below_a_small_limit_is_a_quarter_of_the_room(monkeypatch) -> None:
    """A sweep worker of 512 MB has less room than MEMORY_MARGIN once numba is loaded:
    its searches keep a quarter of the room as margin, so they run, and stop near it."""
    from hierplan_opt.core import timer

    data, space = timer.memory_use()
    room = 100 << 20
    monkeypatch.setattr(timer, "memory_limits", lambda: (float("inf"), float(space + room)))
    d = timer.Deadline(60)
    assert d._memory_short() == ""
    monkeypatch.setattr(timer, "memory_use", lambda: (data, space + room - (20 << 20)))
    assert d._memory_short() == "the memory limit (%.1f GB)" % ((space + room) / (1 << 30))
