"""MAPF-POST output: YAML/JSON/CSV schedules, DOT, Gantt PNG, and ``hierplan post``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml

from hierplan_opt import Graph, Instance, Kinematics, Plan
from hierplan_opt.cli import main
from hierplan_opt.schedule import postprocess, read_schedule, to_dot, write_schedule
from hierplan_opt.viz.gantt import plot_gantt

PLUS = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])


def plus_schedule(**kw):
    v = PLUS.vertex
    kin = [
        Kinematics("youbot", v_max=1.0),
        Kinematics("pioneer", drive="differential", v_max=1.0, omega_max=1.0),
    ]
    inst = Instance.mapf(PLUS, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=kin)
    plan = Plan.from_paths(
        [[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]]
    )
    return postprocess(inst, plan, **kw)


@pytest.mark.parametrize("ext", [".yaml", ".json", ".csv"])
def test_round_trip(tmp_path: Path, ext: str) -> None:
    s = plus_schedule(margin=0.25)
    path = write_schedule(s, tmp_path / f"s{ext}")
    data = read_schedule(path)
    assert data["statistics"]["makespan"] == pytest.approx(s.makespan)
    assert data["statistics"]["objective"] == "makespan"
    assert data["statistics"]["safety_distance"] == pytest.approx(s.safety_distance)
    for name, wp in zip(s.agent_names, s.waypoints, strict=True):
        rows = data["schedule"][name]
        assert [r["arrival"] for r in rows] == pytest.approx(wp.arrival.tolist())
        assert [r["x"] for r in rows] == pytest.approx(wp.coords[:, 0].tolist())
        assert [r["y"] for r in rows] == pytest.approx(wp.coords[:, 1].tolist())
        assert [r["theta"] for r in rows] == pytest.approx(wp.theta.tolist())
        assert "z" not in rows[0]


def test_yaml_layout(tmp_path: Path) -> None:
    s = plus_schedule(margin=0.25)
    data = yaml.safe_load(write_schedule(s, tmp_path / "s.yaml").read_text())
    # Issue 30: the file carries what it came from (settings and the discrete plan).
    assert list(data) == ["statistics", "settings", "plan", "schedule"]
    assert data["plan"] == {"agent0": [[0, 1, 0], [1, 1, 1], [2, 1, 2]],
                            "agent1": [[1, 0, 0], [1, 1, 2], [1, 2, 3]]}  # fmt: skip
    assert data["settings"]["margin"] == 0.25 and data["settings"]["objective"] == "makespan"
    assert set(data["settings"]["radii"]) == {"agent0", "agent1"}
    assert list(data["schedule"]) == ["agent0", "agent1"]
    assert list(data["schedule"]["agent0"][0]) == ["x", "y", "theta", "arrival"]
    for key in ("makespan", "safety_distance", "objective", "method", "tpg_nodes", "stn_arcs"):
        assert key in data["statistics"]
    assert data["statistics"]["margin"] == 0.25
    assert data["statistics"]["clearance"] == [
        {"types": ["pioneer", "youbot"], "required": 0.25, "guaranteed": True}
    ]
    json.dumps(data)  # plain values only


def test_3d_schedule_has_z(tmp_path: Path) -> None:
    g = Graph.grid(2, 1, 2)
    inst = Instance.mapf(g, [(0, 0, 0)], [(1, 0, 1)])
    s = postprocess(inst, Plan.from_paths([[0, 1, 3]]), margin=0.25)
    rows = read_schedule(write_schedule(s, tmp_path / "s.yaml"))["schedule"]["agent0"]
    assert rows[-1]["z"] == 1 and rows[-1]["arrival"] == 2


def test_dot_node_count() -> None:
    s = plus_schedule(margin=0.25)
    text = to_dot(s.stn, s)
    assert text.startswith("digraph STN {") and text.rstrip().endswith("}")
    nodes = re.findall(r"^\s+n\d+ \[label=", text, flags=re.M)
    arcs = re.findall(r"^\s+n\d+ -> n\d+ ", text, flags=re.M)
    assert len(nodes) == s.stn.num_nodes == 8
    assert len(arcs) == s.stn.num_arcs
    assert text.count("style=dashed") == 1  # the one Type-2 precedence
    assert "color=red" in text  # the critical path


def test_gantt_png(tmp_path: Path) -> None:
    s = plus_schedule(margin=0.25)
    out = tmp_path / "g.png"
    plot_gantt(s, out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------- CLI
INSTANCE = """\
graph:
  type: grid
  rows: ["@.@", "...", "@.@"]
robot_types:
  youbot: {drive: omni, v_max: 0.8, a_max: 1.0, radius: 0.3}
  pioneer: {drive: differential, v_max: 0.6, omega_max: 1.5, radius: 0.25}
agents:
  - {name: r1, start: [0, 1], goal: [2, 1], type: youbot}
  - {name: r2, start: [1, 0], goal: [1, 2], type: pioneer}
"""
PLAN = """\
schedule:
  r1: [{x: 0, y: 1, t: 0}, {x: 1, y: 1, t: 1}, {x: 2, y: 1, t: 2}]
  r2: [{x: 1, y: 0, t: 0}, {x: 1, y: 0, t: 1}, {x: 1, y: 1, t: 2}, {x: 1, y: 2, t: 3}]
"""


def _files(tmp_path: Path) -> tuple[str, str]:
    inst = tmp_path / "plus.yaml"
    plan = tmp_path / "plan.yaml"
    inst.write_text(INSTANCE)
    plan.write_text(PLAN)
    return str(inst), str(plan)


@pytest.mark.parametrize("objective", ["makespan", "safety", "flowtime"])
def test_cli_post(tmp_path: Path, capsys: pytest.CaptureFixture[str], objective: str) -> None:
    inst, plan = _files(tmp_path)
    out, dot, png = tmp_path / "s.yaml", tmp_path / "s.dot", tmp_path / "g.png"
    code = main(
        [
            "post", inst, plan, "--objective", objective, "--margin", "0.2",
            "--out", str(out), "--dot", str(dot), "--gantt", str(png), "--check",
        ]
    )  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    lines = captured.out.strip().splitlines()
    assert len(lines) == 1 and f"{objective} schedule" in lines[0] and "ok" in lines[0]
    data = yaml.safe_load(out.read_text())
    assert set(data["schedule"]) == {"r1", "r2"}
    assert data["statistics"]["method"] == ("graph" if objective == "makespan" else "lp")
    assert dot.read_text().startswith("digraph")
    assert png.stat().st_size > 0


def test_cli_post_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inst, plan = _files(tmp_path)
    out = str(tmp_path / "s.yaml")
    with pytest.raises(SystemExit) as exc:
        main(["post", inst, plan, "--margin", "-1", "--out", out])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--margin" in err and len(err.strip().splitlines()) == 1
    code = main(["post", inst, plan, "--objective", "safety", "--method", "graph", "--out", out])
    err = capsys.readouterr().err
    assert code == 2 and "needs method='lp'" in err
    bad = tmp_path / "bad.yaml"
    bad.write_text(PLAN.replace("{x: 1, y: 0, t: 1}", "{x: 1, y: 1, t: 1}"))
    code = main(["post", inst, str(bad), "--out", out])
    err = capsys.readouterr().err
    assert code == 2 and "error:" in err and "Traceback" not in err


def test_cli_post_clearance(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inst, plan = _files(tmp_path)
    out = tmp_path / "s.yaml"
    assert main(["post", inst, plan, "--out", str(out), "--check"]) == 0
    line = capsys.readouterr().out
    assert "clearance pioneer/youbot 0.55 m guaranteed" in line and "(ok)" in line
    assert main(["post", inst, plan, "--no-clearance", "--out", str(out)]) == 0
    assert "pioneer/youbot 0.55 m NOT guaranteed" in capsys.readouterr().out
    data = yaml.safe_load(out.read_text())
    assert data["statistics"]["clearance"][0]["guaranteed"] is False


def test_cli_post_refuses_a_rotation_with_clearance(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "ring.yaml").write_text(
        "graph: {type: grid, dimensions: [2, 2]}\n"
        "robot_types: {r: {drive: omni, v_max: 1.0, radius: 0.2}}\n"
        "agents:\n"
        "  - {name: a, start: [0, 0], goal: [1, 0], type: r}\n"
        "  - {name: b, start: [1, 0], goal: [1, 1], type: r}\n"
        "  - {name: c, start: [1, 1], goal: [0, 1], type: r}\n"
        "  - {name: d, start: [0, 1], goal: [0, 0], type: r}\n"
    )
    (tmp_path / "ring-plan.yaml").write_text(
        "schedule:\n"
        "  a: [{x: 0, y: 0, t: 0}, {x: 1, y: 0, t: 1}]\n"
        "  b: [{x: 1, y: 0, t: 0}, {x: 1, y: 1, t: 1}]\n"
        "  c: [{x: 1, y: 1, t: 0}, {x: 0, y: 1, t: 1}]\n"
        "  d: [{x: 0, y: 1, t: 0}, {x: 0, y: 0, t: 1}]\n"
    )
    out = tmp_path / "s.yaml"
    args = ["post", str(tmp_path / "ring.yaml"), str(tmp_path / "ring-plan.yaml")]
    code = main([*args, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "robots of type r 0.4 m apart" in err and "cells of 1 m" in err and "rotate" in err
    assert not out.exists()
    # Without clearance: the plan's order, robots never on one point (issue 30).
    assert main([*args, "--no-clearance", "--out", str(out), "--check"]) == 0


@pytest.mark.parametrize(
    "old,new,what",
    [
        ('"@.@"]', '"@.@"]\n  cell_size: 1.0e+308', "position"),
        ("v_max: 0.8,", "v_max: 1.0e-320,", "not a finite number"),
    ],
)
def test_cli_post_refuses_unrepresentable_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, what: str
) -> None:
    # Issue 21: huge cells or tiny speeds wrote schedules full of .nan/.inf.
    inst, plan = _files(tmp_path)
    Path(inst).write_text(INSTANCE.replace(old, new))
    out = tmp_path / "s.yaml"
    code = main(["post", inst, plan, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and what in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_bench_post_smoke(capsys: pytest.CaptureFixture[str]) -> None:
    root = Path(__file__).resolve().parents[1] / "instances" / "movingai"
    code = main(
        [
            "bench", "post", "--map", str(root / "empty-8-8.map"),
            "--scen", str(root / "empty-8-8-even-1.scen"), "--agents", "4,8",
            "--repeats", "1", "--planner", "prioritized", "--pyomo-max", "4", "--fleet", "6",
        ]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    rows = [ln.split() for ln in out.splitlines() if ln.strip()[:1].isdigit()]
    assert [r[0] for r in rows] == ["4", "8"]
    fleet = [ln for ln in out.splitlines() if ln.startswith("fleet 6 robots")]
    assert len(fleet) == 1 and "replay ok" in fleet[0]
    for r in rows:
        assert float(r[-3]) == pytest.approx(float(r[-2]))  # graph makespan == LP makespan
