"""``hierplan run`` and ``hierplan simulate``: reports, layouts, one-line errors."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from hierplan_opt.cli import main

ROOT = Path(__file__).resolve().parent.parent
WAREHOUSE = str(ROOT / "instances" / "paper" / "warehouse-part1.yaml")
DISTURBANCES = str(ROOT / "instances" / "paper" / "warehouse-disturbances.yaml")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_run_the_whole_hierarchy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.yaml"
    argv = ["run", WAREHOUSE, "--solver", "cbm", "--disturbances", DISTURBANCES]
    code, text, _ = run(capsys, *argv, "--out", str(out))
    assert code == 0, text
    assert "0 collisions" in text and "youbot8 breakdown -> replan" in text
    data = yaml.safe_load(out.read_text())
    st = data["statistics"]
    for key in ("collisions", "min_distance", "guaranteed_distance", "makespan"):
        assert key in st
    for key in ("stn_resolves", "reorders", "replans"):
        assert isinstance(st[key], int)
    assert st["collisions"] == 0 and st["replans"] == 1
    assert st["min_distance"] >= st["guaranteed_distance"]
    rows = data["schedule"]["youbot1"]
    assert set(rows[0]) == {"x", "y", "theta", "arrival"}
    assert all(a["arrival"] <= b["arrival"] for a, b in zip(rows, rows[1:], strict=False))
    assert {e["layer"] for e in data["events"]} >= {"slack", "stn", "replan"}


def test_simulate_plan_and_schedule_files(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "plan.yaml"
    sched = tmp_path / "schedule.yaml"
    assert main(["solve", WAREHOUSE, "--solver", "cbm", "--out", str(plan)]) == 0
    assert main(["post", WAREHOUSE, str(plan), "--out", str(sched)]) == 0
    capsys.readouterr()
    reports = []
    for src in (plan, sched):
        out = tmp_path / f"report-{src.stem}.yaml"
        code, text, err = run(capsys, "simulate", WAREHOUSE, str(src), "--out", str(out))
        assert code == 0, err
        reports.append(yaml.safe_load(out.read_text()))
    # The schedule file gives back the same plan order, hence the same execution.
    assert reports[0]["statistics"]["makespan"] == reports[1]["statistics"]["makespan"]
    out = tmp_path / "mc.yaml"
    argv = ["simulate", WAREHOUSE, str(plan), "--disturbances", DISTURBANCES]
    code, text, _ = run(capsys, *argv, "--runs", "4", "--workers", "1", "--out", str(out))
    assert code == 0 and "monte carlo: 4 runs" in text
    assert yaml.safe_load(out.read_text())["monte_carlo"]["collisions"] == 0


def test_bad_disturbance_file_one_line(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("disturbances:\n  - {kind: stop, agent: youbot3, at_time: 4}\n")
    out = tmp_path / "r.yaml"
    argv = ["run", WAREHOUSE, "--solver", "cbm", "--disturbances", str(bad), "--out", str(out)]
    code, _, err = run(capsys, *argv)
    lines = [ln for ln in err.splitlines() if not ln.startswith(("INFO", "DEBUG"))]
    assert code == 2 and len(lines) == 1, err
    assert f"{bad}:2:" in lines[0] and "duration" in lines[0]
    assert not out.exists()


def test_simulate_robot_mode(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "plan.yaml"
    assert main(["solve", WAREHOUSE, "--solver", "cbm", "--out", str(plan)]) == 0
    out = tmp_path / "r.yaml"
    argv = ["simulate", WAREHOUSE, str(plan), "--mode", "robot", "--policy", "stn"]
    code, text, _ = run(capsys, *argv, "--out", str(out))
    assert code == 0 and "robot mode" in text
    assert yaml.safe_load(out.read_text())["statistics"]["mode"] == "robot"
    # The disturbances re-plan (a breakdown): robot mode follows the new plan too.
    argv = ["simulate", WAREHOUSE, str(plan), "--mode", "robot", "--disturbances", DISTURBANCES]
    code, text, _ = run(capsys, *argv, "--out", str(tmp_path / "r2.yaml"))
    st = yaml.safe_load((tmp_path / "r2.yaml").read_text())["statistics"]
    assert code == 0 and "youbot8 breakdown -> replan" in text
    assert st["replans"] == 1 and st["collisions"] == 0 and st["acceleration_violations"] == 0
    assert st["max_acceleration_ratio"] <= 1 + 1e-6


def test_simulate_a_roadmap_schedule(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Schedule files on roadmaps name vertices by their coordinates (figure 3)."""
    inst = str(ROOT / "instances" / "paper" / "figure3.yaml")
    plan, sched, report = (tmp_path / n for n in ("p.yaml", "s.yaml", "r.yaml"))
    assert run(capsys, "solve", inst, "--solver", "cbm", "--out", str(plan))[0] == 0
    code = run(capsys, "post", inst, str(plan), "--objective", "makespan", "--out", str(sched))[0]
    assert code == 0
    code, text, err = run(capsys, "simulate", inst, str(sched), "--out", str(report))
    assert code == 0, err
    st = yaml.safe_load(report.read_text())["statistics"]
    assert st["collisions"] == 0 and st["finished"] == 3
