"""Issue 30 item 2: schedule files carry their plan and settings; one reader for all.

Every schedule that ``hierplan post`` writes for a valid plan, from every solver, is
read back by ``load_schedule`` and accepted by ``simulate`` and ``validate``; files of
earlier versions (no plan) are read by the visit order with one log line.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pytest
import yaml

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.core.errors import InputError
from hierplan_opt.execution import simulate
from hierplan_opt.io.movingai import load_map, load_scen
from hierplan_opt.schedule import (
    ClearanceError,
    Schedule,
    check_bounds,
    postprocess,
    replay,
    write_schedule,
)
from hierplan_opt.schedule.files import is_schedule_file, load_schedule

ROOT = Path(__file__).resolve().parents[1]
MAP = str(ROOT / "instances/movingai/warehouse-10-20-10-2-1.map")
SCEN = str(ROOT / "instances/movingai/warehouse-10-20-10-2-1-even-1.scen")
OPTIONS = {"cbs": {}, "ecbs": {"w": 1.5}, "eecbs": {"w": 1.5}, "lacam": {"anytime": 0}}


def warehouse(k: int) -> hp.Instance:
    return load_scen(SCEN, load_map(MAP), k)


def solved(solver: str, k: int) -> tuple[hp.Instance, hp.Plan]:
    inst = warehouse(k)
    res = hp.solve(inst, solver, time_limit=120, **OPTIONS[solver])
    assert res.plan is not None, f"{solver} {k}: {res.status}"
    assert hp.validate(inst, res.plan) == []
    return inst, res.plan


def round_trip(inst: hp.Instance, plan: hp.Plan, path: Path, **kw) -> Schedule:
    """post -> file -> load_schedule: the same plan, times, settings and replay."""
    s = postprocess(inst, plan, check_plan=False, **kw)
    write_schedule(s, path)
    back = load_schedule(path, inst)
    assert back.plan is not None and back.plan.trimmed() == plan.trimmed()
    assert back.settings["margin"] == pytest.approx(s.margin)
    assert back.settings["objective"] == s.objective
    assert back.stn is not None and check_bounds(back.stn, back.times) == []
    assert np.allclose(back.times, s.times, atol=1e-8)
    for a, b in zip(s.waypoints, back.waypoints, strict=True):
        assert np.allclose(a.coords, b.coords) and np.allclose(a.arrival, b.arrival, atol=1e-8)
    assert replay(back, inst).ok
    return back


# ---------------------------------------------------------------------- layout
def test_file_carries_plan_and_settings(tmp_path: Path) -> None:
    inst, plan = solved("cbs", 8)
    s = postprocess(inst, plan)
    data = yaml.safe_load(write_schedule(s, tmp_path / "s.yaml").read_text())
    assert list(data) == ["statistics", "settings", "plan", "schedule"]
    st = data["settings"]
    assert st["objective"] == "makespan" and st["method"] == "graph"
    assert st["margin"] == pytest.approx(0.1) and st["clearance"] is True
    assert st["radii"] == {a.name: 0 for a in inst.agents}
    # The plan block is the plan: per robot its visits [x, y, step].
    g = inst.graph
    for a, path in zip(inst.agents, plan.paths, strict=True):
        rows = data["plan"][a.name]
        assert rows[0] == [*g.location(path[0]), 0]
        for x, y, t in rows:
            assert g.location(path[min(t, len(path) - 1)]) == (x, y)


@pytest.mark.parametrize("ext", ["yaml", "json", "csv"])
def test_round_trip_every_format(tmp_path: Path, ext: str) -> None:
    inst, plan = solved("cbs", 10)
    round_trip(inst, plan, tmp_path / f"s.{ext}")
    assert is_schedule_file(tmp_path / f"s.{ext}")


def test_round_trip_lp_and_margin_and_sizes(tmp_path: Path) -> None:
    inst, plan = solved("cbs", 6)
    # An LP schedule is not the earliest one: its own times come back, within rounding.
    back = round_trip(inst, plan, tmp_path / "lp.yaml", objective="safety", method="lp")
    assert back.objective == "safety" and back.method == "lp"
    round_trip(inst, plan, tmp_path / "m0.yaml", margin=0)
    sized = hp.Instance.mapf(
        inst.graph,
        [inst.graph.location(a.start) for a in inst.agents],
        [inst.graph.location(a.goal) for a in inst.agents],
        kinematics=hp.Kinematics("disc", radius=0.3),
    )
    back = round_trip(sized, plan, tmp_path / "sized.yaml")
    assert back.margin == 0 and back.safety_distance == pytest.approx(0.6)
    # A schedule made for other radii does not belong to this instance.
    with pytest.raises(InputError, match="radius 0.3 m but the instance gives 0 m"):
        load_schedule(tmp_path / "sized.yaml", inst)


# ---------------------------------------------------------------------- bad files
def test_bad_files_one_line(tmp_path: Path) -> None:
    inst, plan = solved("cbs", 6)
    f = tmp_path / "s.yaml"
    write_schedule(postprocess(inst, plan), f)
    data = yaml.safe_load(f.read_text())
    # Times that break a precedence or a speed bound.
    bad = json.loads(json.dumps(data))
    name = inst.agents[0].name
    bad["schedule"][name][1]["arrival"] = 0.01
    (tmp_path / "fast.yaml").write_text(yaml.safe_dump(bad))
    with pytest.raises(InputError, match="the times break a bound") as info:
        load_schedule(tmp_path / "fast.yaml", inst)
    assert len(str(info.value).splitlines()) == 1
    # A plan that is not valid (a robot jumps).
    bad = json.loads(json.dumps(data))
    bad["plan"][name][1][-1] += 0  # same step ...
    bad["plan"][name].insert(1, [*inst.graph.location(inst.agents[1].goal), 1])
    (tmp_path / "jump.yaml").write_text(yaml.safe_dump(bad))
    with pytest.raises(InputError, match="the schedule's plan is invalid|steps must increase"):
        load_schedule(tmp_path / "jump.yaml", inst)
    # Another instance's schedule.
    with pytest.raises(InputError, match="does not belong to this instance"):
        load_schedule(f, warehouse(7))


def test_old_file_without_plan_read_by_visit_order(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    inst, plan = solved("ecbs", 20)
    f = tmp_path / "s.yaml"
    s = postprocess(inst, plan)
    data = yaml.safe_load(write_schedule(s, f).read_text())
    del data["plan"], data["settings"]
    old = tmp_path / "old.yaml"
    old.write_text(yaml.safe_dump(data, default_flow_style=None))
    with caplog.at_level(logging.WARNING):
        back = load_schedule(old, inst)
    said = [r.getMessage() for r in caplog.records if "carries no plan" in r.getMessage()]
    assert len(said) == 1
    assert back.plan is not None and hp.validate(inst, back.plan) == []
    assert np.allclose(back.times, s.times, atol=1e-8)


# ---------------------------------------------------------------------- commands
@pytest.mark.parametrize("solver", ["cbs", "ecbs", "eecbs", "lacam"])
def test_post_then_simulate_and_validate_accept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], solver: str
) -> None:
    # Issue 30 item 2: simulate refused schedules that post wrote from valid plans.
    k = 10 if solver == "cbs" else 20
    inst_args = [MAP, "--scen", SCEN, "--agents", str(k)]
    plan = tmp_path / "plan.yaml"
    sched = tmp_path / "s.yaml"
    argv = ["solve", *inst_args, "--solver", solver, "--time-limit", "60"]
    for key, v in OPTIONS[solver].items():
        argv += ["--set", f"{key}={v}"]
    assert main([*argv, "--out", str(plan)]) == 0, capsys.readouterr().err
    assert main(["post", *inst_args, str(plan), "--out", str(sched), "--check"]) == 0
    assert "(ok)" in capsys.readouterr().out
    assert yaml.safe_load(sched.read_text())["settings"]["solver"] == solver
    assert main(["validate", *inst_args, str(sched)]) == 0
    assert "valid schedule" in capsys.readouterr().out
    code = main(["simulate", *inst_args, str(sched), "--out", str(tmp_path / "r.yaml")])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "not a valid plan" not in err


@pytest.mark.slow
@pytest.mark.parametrize(
    "solver,k",
    [("ecbs", 120), ("ecbs", 150), ("ecbs", 200), ("eecbs", 150), ("eecbs", 200),
     ("lacam", 120), ("lacam", 200)],
)  # fmt: skip
def test_large_plans_round_trip_and_simulate(tmp_path: Path, solver: str, k: int) -> None:
    # The failing cases: 120-agent plans, 150- and 200-agent ECBS/EECBS plans.
    inst, plan = solved(solver, k)
    try:
        back = round_trip(inst, plan, tmp_path / "s.json")
    except ClearanceError as exc:  # a rotation: point robots rotate at margin 0
        assert "rotate" in str(exc) and "margin 0" in str(exc)
        back = round_trip(inst, plan, tmp_path / "s.json", margin=0)
    ex = simulate(inst, back)
    assert ex.statistics["collisions"] == 0
    assert int(np.count_nonzero(np.isnan(ex.arrival))) == 0


def test_validate_cli_on_schedule_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "plus.yaml").write_text(
        "graph: {type: grid, rows: ['@.@', '...', '@.@']}\n"
        "robot_types: {r: {drive: omni, v_max: 1.0, radius: 0.3}}\n"
        "agents:\n"
        "  - {name: a, start: [0, 1], goal: [2, 1], type: r}\n"
        "  - {name: b, start: [1, 0], goal: [1, 2], type: r}\n"
    )
    (tmp_path / "plan.yaml").write_text(
        "schedule:\n"
        "  a: [{x: 0, y: 1, t: 0}, {x: 1, y: 1, t: 1}, {x: 2, y: 1, t: 2}]\n"
        "  b: [{x: 1, y: 0, t: 0}, {x: 1, y: 0, t: 1}, {x: 1, y: 1, t: 2}, {x: 1, y: 2, t: 3}]\n"
    )
    inst, plan, out = (str(tmp_path / n) for n in ("plus.yaml", "plan.yaml", "s.yaml"))
    assert main(["post", inst, plan, "--out", out]) == 0
    assert main(["validate", inst, out]) == 0
    assert "valid schedule" in capsys.readouterr().out
    # Without clearance the robots of radius 0.3 pass the crossing too close: exit 1.
    assert main(["post", inst, plan, "--out", out, "--no-clearance"]) == 0
    capsys.readouterr()
    assert main(["validate", inst, out]) == 1
    assert "pairs too close" in capsys.readouterr().out
    # Times edited by hand that break a bound: an invalid schedule, one line, exit 1.
    data = yaml.safe_load(Path(out).read_text())
    data["schedule"]["a"][1]["arrival"] = 0.1
    Path(out).write_text(yaml.safe_dump(data))
    assert main(["validate", inst, out]) == 1
    got = capsys.readouterr().out
    assert "the times break a bound" in got and len(got.strip().splitlines()) == 1
