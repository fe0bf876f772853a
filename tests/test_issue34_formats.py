"""Issue 34, "Formats as they are in the wild": MAPF Tracker move strings, libMRP's own
test instances, default solvers for TAPF, lossy conversion to libMRP."""

from __future__ import annotations

from pathlib import Path

import pytest

import hierplan_opt as hp
from hierplan_opt.cli import main

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"


# ----------------------------------------------------------- default solver for TAPF
@pytest.mark.parametrize(
    ("path", "solver"),
    [
        (DATA / "tapf_lmrp.yaml", "cbm"),
        (ROOT / "instances" / "paper" / "warehouse-part1.yaml", "cbm"),
    ],
)
def test_solve_tapf_without_solver_picks_one_and_says_which(path, solver, capsys) -> None:
    code = main(["solve", str(path), "--time-limit", "20"])
    out, err = capsys.readouterr()
    assert code == 0 and out.startswith("OPTIMAL") and f"solver={solver}" in out
    assert f"using {solver} (TAPF with 2 teams)" in err


def test_solve_one_team_without_solver_uses_flow(tmp_path, capsys) -> None:
    inst = hp.Instance.tapf(hp.Graph.grid(3, 3), [([(0, 0), (2, 2)], [(0, 2), (2, 0)])])
    hp.save_instance(tmp_path / "one.yaml", inst)
    code = main(["solve", str(tmp_path / "one.yaml")])
    out, err = capsys.readouterr()
    assert code == 0 and "solver=flow" in out and "using flow (TAPF with one team)" in err


def test_solve_mapf_without_solver_still_uses_cbs(capsys) -> None:
    code = main(["solve", str(DATA / "corridor.yaml")])
    out, err = capsys.readouterr()
    assert code == 0 and "solver=cbs" in out and err == ""


# ------------------------------------------------------------ lossy convert to libMRP
def test_convert_warehouse_to_lmrp_writes_and_warns(tmp_path, capsys) -> None:
    src = ROOT / "instances" / "paper" / "warehouse-part1.yaml"
    out = tmp_path / "wh.yaml"
    code = main(["convert", str(src), "--to", "lmrp", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 0 and out.exists()
    assert "cannot hold highways" in err and "cannot hold robot kinematics" in err
    orig, back = hp.load_instance(src), hp.load_instance(out)
    assert back.highways is None and back.starts == orig.starts
    assert sorted(map(sorted, (t.targets for t in back.teams))) == sorted(
        map(sorted, (t.targets for t in orig.teams))
    )


def test_convert_plain_instance_to_lmrp_warns_nothing(tmp_path, capsys) -> None:
    code = main(
        [
            "convert",
            str(DATA / "corridor_lmrp.yaml"),
            "--to",
            "lmrp",
            "--out",
            str(tmp_path / "c.yaml"),
        ]
    )
    assert code == 0 and "warning" not in capsys.readouterr().err


# ---------------------------------------------------------------- MAPF Tracker files
MAI = ROOT / "instances" / "movingai"
OLD_EXPORT = DATA / "tracker_planviz_random-32-32-20_random_1_300.csv"
MULTI = DATA / "tracker_planviz_random-32-32-20.csv"


def random_32_32_20(kind: str, agents: int) -> hp.Instance:
    return hp.load_instance(
        MAI / "random-32-32-20.map", MAI / f"random-32-32-20-{kind}-1.scen", agents
    )


def test_planviz_300_agent_export_reads_in_the_older_y_convention() -> None:
    from hierplan_opt.io import read_plan

    inst = random_32_32_20("random", 300)
    assert OLD_EXPORT.read_bytes().startswith(b"\xef\xbb\xbf")  # byte-order mark, `path` column
    plan, stats = read_plan(OLD_EXPORT, inst)
    assert stats["tracker_y"] == "up" and stats["tracker_y_from"] == "detected"
    assert hp.validate(inst, plan) == [] and plan.sum_of_costs == 9647 == int(
        stats["solution_cost"]
    )
    # forced: the same with --tracker-y-up; the other convention leaves the map
    assert read_plan(OLD_EXPORT, inst, tracker_y="up")[0] == plan
    with pytest.raises(hp.InputError, match="leaves the 32x32 map"):
        read_plan(OLD_EXPORT, inst, tracker_y="down")


def test_written_submissions_use_the_current_convention_and_read_back(tmp_path) -> None:
    from hierplan_opt.io import read_plan, tracker

    inst = random_32_32_20("random", 300)
    plan = read_plan(OLD_EXPORT, inst)[0]
    out = tmp_path / "sub.csv"
    tracker.save(out, tracker.submission(inst, plan))
    back, stats = read_plan(out, inst)
    assert back == plan and stats["tracker_y"] == "down" == tracker.WRITE_Y
    # the letters: agent 0 starts "drru" in the older file (u = y+1), "urrd" now
    first = out.read_text().split("\n")[1].split(",")[-1].strip('"')
    assert first.startswith("u2rd")


@pytest.mark.parametrize(
    ("kind", "agents", "cost"), [("random", 5, 132), ("even", 3, 29), ("random", 1, 36)]
)
def test_multi_row_download_picks_the_row_of_the_scenario(kind, agents, cost) -> None:
    from hierplan_opt.io import read_plan

    inst = random_32_32_20(kind, agents)
    plan, stats = read_plan(MULTI, inst)
    assert (stats["scen_type"], int(stats["type_id"])) == (kind, 1)
    assert hp.validate(inst, plan) == [] and plan.sum_of_costs == cost


def test_multi_row_download_without_the_scenario_says_so() -> None:
    from hierplan_opt.io import read_plan

    inst = hp.load_instance(MAI / "random-32-32-20.map", MAI / "random-32-32-20-random-1.scen", 7)
    with pytest.raises(hp.InputError, match="no submission for 7 agents"):
        read_plan(MULTI, inst)


def test_cli_says_which_convention_and_takes_the_flags(tmp_path, capsys) -> None:
    base = [str(MAI / "random-32-32-20.map"), "--scen", str(MAI / "random-32-32-20-random-1.scen")]
    base += ["--agents", "300"]
    assert main(["validate", *base, str(OLD_EXPORT)]) == 0
    assert "soc=9647" in (out := capsys.readouterr().out) and "moves=y-up (detected)" in out
    assert main(["validate", *base, str(OLD_EXPORT), "--tracker-y-up"]) == 0
    assert "moves=y-up (given)" in capsys.readouterr().out
    assert main(["validate", *base, str(OLD_EXPORT), "--tracker-y-down"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "leaves the 32x32 map" in err
    out_csv = tmp_path / "t.csv"
    code = main(
        ["convert", *base, "--plan", str(OLD_EXPORT), "--to", "tracker", "--out", str(out_csv)]
    )
    line = capsys.readouterr().out
    assert code == 0 and "moves=y-up (detected)" in line and "d = y+1" in line
