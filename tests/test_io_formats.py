"""Other tools' formats: EECBS / CBSH2-RTC paths, LaCAM results, MAPF Tracker
submissions, libMultiRobotPlanning roadmaps and schedules for its ``visualize.py``.

Each format: a file written exactly as the other tool writes it (row/column order,
separators) read here, a round trip through our writer and reader, and the CLI
(``validate``, ``post``, ``convert``) accepting it.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from io_helpers import DATA, MOVINGAI, same_instance, write

from hierplan_opt import Graph, InputError, Instance, Plan, solve, validate
from hierplan_opt.cli import main
from hierplan_opt.io import (
    eecbs,
    load_instance,
    read_plan,
    save_instance,
    save_plan,
    tracker,
)
from hierplan_opt.io.lmrp_yaml import schedule_document

MAP = MOVINGAI / "random-32-32-20.map"
SCEN = MOVINGAI / "random-32-32-20-random-1.scen"


def _movingai(k: int = 8) -> tuple[Instance, Plan]:
    inst = load_instance(MAP, scen=SCEN, agents=k)
    res = solve(inst, "cbs", time_limit=30)
    assert res.plan is not None
    return inst, res.plan


def _rect() -> Instance:
    """A 4 x 2 grid (wide, so that swapped rows and columns would be noticed)."""
    return Instance.mapf(Graph.grid(4, 2), [(0, 0), (3, 1)], [(3, 0), (0, 1)])


# ---------------------------------------------------------------- EECBS / CBSH2-RTC
def test_eecbs_reads_row_column_pairs(tmp_path: Path) -> None:
    # written as EECBS's savePaths does: "Agent i: " then "(row,col)->" per step
    f = write(
        tmp_path,
        "paths.txt",
        "Agent 0: (0,0)->(0,1)->(0,2)->(0,3)->\nAgent 1: (1,3)->(1,2)->(1,1)->(1,0)->\n",
    )
    inst = _rect()
    plan, stats = read_plan(f, inst)
    g = inst.graph
    assert [g.location(v) for v in plan.paths[0]] == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert [g.location(v) for v in plan.paths[1]] == [(3, 1), (2, 1), (1, 1), (0, 1)]
    assert stats == {} and validate(inst, plan) == []


def test_eecbs_round_trip_and_trailing_waits(tmp_path: Path) -> None:
    inst, plan = _movingai()
    f = tmp_path / "p.txt"
    save_plan(f, inst, plan, format="eecbs")
    lines = f.read_text().splitlines()
    assert len(lines) == inst.num_agents and all(ln.endswith(")->") for ln in lines)
    back, _ = read_plan(f, inst)
    assert back == plan.trimmed() and back.sum_of_costs == plan.sum_of_costs
    x, y = inst.graph.location(inst.agents[0].start)  # type: ignore[misc]
    assert lines[0].startswith(f"Agent 0: ({y},{x})->")


def test_eecbs_refusals(tmp_path: Path) -> None:
    inst = _rect()
    for text, match in [
        ("Agent 0: (0,0)->\n", r"no path for agent\(s\) 1"),
        ("Agent 0: (0,0)->\nAgent 5: (1,0)->\n", "agent 5 but the instance has 2 agents"),
        ("Agent 0: (0,0)->(2,0)->\nAgent 1: (1,3)->\n", r"p.txt:1: .* outside the 4x2 map"),
        ("Agent 0: (0,0)->x\nAgent 1: (1,3)->\n", "expected '\\(row,col\\)'"),
    ]:
        with pytest.raises(InputError, match=match):
            read_plan(write(tmp_path, "p.txt", text), inst)
    with pytest.raises(InputError, match="2D grids only"):
        eecbs.dumps(load_instance(DATA / "drones_3d.yaml"), Plan.from_paths([[0], [1]]))


# ---------------------------------------------------------------- LaCAM
LACAM = """\
agents=2
map_file=rect.map
solver=planner
solved=1
soc=6
soc_lb=6
makespan=3
makespan_lb=3
sum_of_loss=6
sum_of_loss_lb=6
comp_time=1
seed=0
checkpoints=-1,
comp_time_initial_solution=0
cost_initial_solution=6
search_iteration=3
num_high_level_node=4
num_low_level_node=5
starts=(0,0),(3,1),
goals=(3,0),(0,1),
solution=
0:(0,0),(3,1),
1:(1,0),(2,1),
2:(2,0),(1,1),
3:(3,0),(0,1),
"""


def test_lacam_reads_x_y_configurations(tmp_path: Path) -> None:
    inst = _rect()
    plan, stats = read_plan(write(tmp_path, "result.txt", LACAM), inst)
    g = inst.graph
    assert [g.location(v) for v in plan.paths[1]] == [(3, 1), (2, 1), (1, 1), (0, 1)]
    assert stats["soc"] == 6 and stats["map_file"] == "rect.map"
    assert validate(inst, plan) == [] and plan.sum_of_costs == 6


def test_lacam_round_trip(tmp_path: Path) -> None:
    inst, plan = _movingai()
    f = tmp_path / "result.txt"
    save_plan(f, inst, plan, format="lacam")
    text = f.read_text()
    assert "map_file=random-32-32-20.map" in text and f"soc={plan.sum_of_costs}" in text
    back, stats = read_plan(f, inst)
    assert back.trimmed() == plan.trimmed() and stats["makespan"] == plan.makespan
    # every configuration lists every agent
    steps = text.split("solution=\n")[1].splitlines()
    assert len(steps) == plan.makespan + 1
    assert all(s.count("(") == inst.num_agents for s in steps)


def test_lacam_refusals(tmp_path: Path) -> None:
    inst = _rect()
    for text, match in [
        ("agents=2\nsolved=0\n", "solved=0"),
        ("agents=3\nsolution=\n", "agents=3 but the instance has 2"),
        ("agents=2\nsoc=1\n", "no 'solution=' line"),
        ("agents=2\nsolution=\n0:(0,0),(3,1),\n2:(1,0),(2,1),\n", "timestep 2 where 1"),
        ("agents=2\nsolution=\n0:(0,0),\n", "t=0 lists 1 agents, expected 2"),
    ]:
        with pytest.raises(InputError, match=match):
            read_plan(write(tmp_path, "r.txt", text), inst)


# ---------------------------------------------------------------- MAPF Tracker
def test_tracker_moves_follow_the_tracker_docs() -> None:
    # the tracker's example: (0,0)->(0,1)->(1,1)->(2,1)->(2,0)->(2,0)->(1,0) is "drruwl"
    g = Graph.grid(3, 2)
    path = tuple(g.vertex(c) for c in [(0, 0), (0, 1), (1, 1), (2, 1), (2, 0), (2, 0), (1, 0)])
    assert tracker.path_moves(g, path) == "drruwl"
    assert tracker.encode_moves("rrrrrddwwwdddd") == "5r2d3w4d"
    assert tracker.decode_moves("5r2d3w4d") == "rrrrrddwwwdddd"
    with pytest.raises(InputError, match="more than 10 steps"):
        tracker.decode_moves("11w", budget=10)


@pytest.mark.parametrize("ext", [".csv", ".json", ".yaml"])
def test_tracker_round_trip(tmp_path: Path, ext: str) -> None:
    inst, plan = _movingai()
    res = solve(inst, "cbs", time_limit=30)
    f = tmp_path / f"sub{ext}"
    save_plan(f, inst, res, format="tracker")
    back, stats = read_plan(f, inst)
    assert back.trimmed() == plan.trimmed()
    assert stats["map_name"] == "random-32-32-20" and stats["scen_type"] == "random"
    assert int(stats["type_id"]) == 1
    assert int(stats["solution_cost"]) == plan.sum_of_costs == int(stats["lower_cost"])
    if ext == ".csv":
        head = f.read_text().splitlines()[0]
        assert head == "map_name,scen_type,type_id,agents,lower_cost,solution_cost,solution_plan"


def test_tracker_download_picks_the_agent_count_and_flip(tmp_path: Path) -> None:
    inst = load_instance(
        MOVINGAI / "empty-8-8.map", scen=MOVINGAI / "empty-8-8-even-1.scen", agents=1
    )
    g = inst.graph
    x, y = g.location(inst.agents[0].start)  # type: ignore[misc]
    gx, gy = g.location(inst.agents[0].goal)  # type: ignore[misc]
    dx, dy = gx - x, gy - y
    moves = ("r" if dx > 0 else "l") * abs(dx) + ("d" if dy > 0 else "u") * abs(dy)
    flipped = moves.replace("d", "U").replace("u", "d").replace("U", "u")
    text = (
        "map_name,scen_type,type_id,agents,lower_cost,solution_cost,solution_plan,flip_up_down\n"
        'empty-8-8,even,1,2,,,"r\nr",FALSE\n'
        f"empty-8-8,even,1,1,,,{tracker.encode_moves(flipped)},TRUE\n"
    )
    plan, _ = read_plan(write(tmp_path, "empty-8-8.csv", text), inst)
    assert plan.paths[0][-1] == inst.agents[0].goal and validate(inst, plan) == []
    other = write(tmp_path, "o.csv", text.replace("empty-8-8,even,1,1", "maze,even,1,1"))
    with pytest.raises(InputError, match="no submission for 1 agents on map 'empty-8-8'"):
        read_plan(other, inst)


def test_tracker_needs_benchmark_names() -> None:
    inst = _rect()
    with pytest.raises(InputError, match="map name, scenario type and id"):
        tracker.submission(inst, Plan.from_paths([[0], [7]]))
    with pytest.raises(InputError, match="even-<id>.scen"):
        tracker.scenario_name("my-scenario.scen")


# ---------------------------------------------------------------- libMultiRobotPlanning
ROADMAP = """\
roadmap:
  undirected: True
  allow_wait_actions: True
  edges:
    - [A, B]
    - [B, C]
    - [C, D]
    - [D, E]
    - [C, F]
agents:
  - name: agent0
    start: A
    goal: E
  - name: agent1
    start: B
    goal: D
"""


def test_lmrp_roadmap_without_positions(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = write(tmp_path, "rm.yaml", ROADMAP)
    inst = load_instance(f)
    assert inst.graph.kind == "roadmap" and inst.graph.num_vertices == 6
    res = solve(inst, "cbs", time_limit=10)
    assert res.status.value == "OPTIMAL" and res.cost == 8  # agent1 steps aside into F
    out = tmp_path / "plan.yaml"
    assert main(["solve", str(f), "--out", str(out)]) == 0
    assert {"v": "A", "t": 0} in yaml.safe_load(out.read_text())["schedule"]["agent0"]
    assert main(["validate", str(f), str(out)]) == 0
    capsys.readouterr()


def test_lmrp_annotated_roadmap_forms(tmp_path: Path) -> None:
    directed = (
        "roadmap:\n  undirected: false\n  allow_wait_actions: false\n"
        "  vertices: {A: [0, 0], B: [1, 0]}\n"
        "  edges: [[A, B], [B, A], [A, A], [B, B]]\n"
        "agents: [{name: a, start: A, goal: B}]\n"
    )
    inst = load_instance(write(tmp_path, "d.yaml", directed))
    assert inst.graph.directed and inst.graph.num_edges == 2
    with pytest.raises(InputError, match=r"d2.yaml:3: allow_wait_actions is false and vertex 'B'"):
        load_instance(write(tmp_path, "d2.yaml", directed.replace(", [B, B]", "")))
    # annotated roadmaps are read (issue 34): one conflict list per edge, in file order
    with pytest.raises(InputError, match="conflicts has 1 entries for 4 edges"):
        load_instance(
            write(tmp_path, "c.yaml", directed.replace("edges:", "conflicts: [[1]]\n  edges:"))
        )
    ok = directed.replace("edges:", "conflicts: [[1, 2, 3], [0, 2, 3], [0, 1], [0, 1]]\n  edges:")
    inst = load_instance(write(tmp_path, "c2.yaml", ok))
    assert inst.meta["annotated_conflicts"] == 5 and inst.meta["edge_conflicts"] == []


def test_lmrp_roadmap_round_trip(tmp_path: Path) -> None:
    text = ROADMAP.replace(
        "  edges:",
        "  vertices: {A: [0, 0], B: [1, 0], C: [2, 0], D: [3, 0], E: [4, 0], F: [2, 1]}\n  edges:",
    )
    inst = load_instance(write(tmp_path, "rm.yaml", text))
    save_instance(tmp_path / "back.yaml", inst, format="lmrp")
    assert same_instance(load_instance(tmp_path / "back.yaml"), inst)


def test_lmrp_general_potential_goals_are_refused_with_the_reason(tmp_path: Path) -> None:
    # cbs_ta lets every agent have its own goal set; this toolkit's teams need equal or
    # disjoint sets (see docs/formats.md)
    text = (
        "map: {dimensions: [4, 1]}\nagents:\n"
        "  - {name: a, start: [0, 0], potentialGoals: [[2, 0], [3, 0]]}\n"
        "  - {name: b, start: [1, 0], potentialGoals: [[3, 0]]}\n"
    )
    with pytest.raises(InputError, match="equal or disjoint goal sets"):
        load_instance(write(tmp_path, "ta.yaml", text))


def test_schedule_for_lmrp_visualize(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from hierplan_opt.schedule import postprocess, write_schedule

    inst = load_instance(DATA / "corridor_lmrp.yaml")
    res = solve(inst, "cbs", time_limit=10)
    assert res.plan is not None
    sched = postprocess(inst, res.plan, "makespan")
    doc = schedule_document(sched)
    for name, wp in zip(sched.agent_names, sched.waypoints, strict=True):
        rows = doc["schedule"][name]
        assert [r["t"] for r in rows] == pytest.approx(list(wp.arrival))
        assert all(set(r) == {"x", "y", "t"} for r in rows)
    # the CLI: schedule file -> lmrp layout, instance -> lmrp map (what visualize.py reads)
    s = write_schedule(sched, tmp_path / "s.yaml")
    assert (
        main(
            [
                "convert",
                str(DATA / "corridor_lmrp.yaml"),
                "--schedule",
                str(s),
                "--out",
                str(tmp_path / "anim.yaml"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "convert",
                str(DATA / "corridor_lmrp.yaml"),
                "--to",
                "lmrp",
                "--out",
                str(tmp_path / "map.yaml"),
            ]
        )
        == 0
    )
    capsys.readouterr()
    anim = yaml.safe_load((tmp_path / "anim.yaml").read_text())
    world = yaml.safe_load((tmp_path / "map.yaml").read_text())
    assert "obstacles" in world["map"] and [a["name"] for a in world["agents"]] == [
        "agent0",
        "agent1",
    ]
    horizon = max(rows[-1]["t"] for rows in anim["schedule"].values())
    assert horizon == pytest.approx(sched.makespan)
    for rows in anim["schedule"].values():
        ts = [r["t"] for r in rows]
        assert ts == sorted(ts) and isinstance(rows[0]["x"], (int, float))


# ---------------------------------------------------------------- the CLI accepts them
def test_cli_validate_post_and_convert_other_formats(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    inst, plan = _movingai(6)
    args = [str(MAP), "--scen", str(SCEN), "--agents", "6"]
    for fmt in ("eecbs", "lacam"):
        f = tmp_path / f"{fmt}.txt"
        save_plan(f, inst, plan, format=fmt)
        assert main(["validate", *args, str(f)]) == 0
        out = capsys.readouterr().out
        assert out.startswith(f"valid: soc={plan.sum_of_costs} ")
    sched = tmp_path / "s.yaml"
    assert main(["post", *args, str(tmp_path / "eecbs.txt"), "--out", str(sched)]) == 0
    assert sched.exists()
    sub = tmp_path / "sub.csv"
    assert main(["convert", *args, "--plan", str(tmp_path / "lacam.txt"), "--out", str(sub)]) == 0
    out = capsys.readouterr().out
    assert "plan (lacam, 6 agents" in out and "valid) as tracker" in out
    assert main(["validate", *args, str(sub)]) == 0
    js = tmp_path / "p.json"
    assert main(["convert", *args, "--plan", str(sub), "--out", str(js)]) == 0
    assert json.loads(js.read_text())["statistics"]["soc"] == plan.sum_of_costs
    capsys.readouterr()


# ---------------------------------------------------------------- scenario map names
def test_scenario_for_another_map_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # random-32-32-10 and random-32-32-20 are both 32 x 32: only the name tells them apart
    other = write(
        tmp_path,
        "other.scen",
        SCEN.read_text().replace("random-32-32-20.map", "random-32-32-10.map"),
    )
    with pytest.raises(
        InputError, match=r"scenario is for map 'random-32-32-10.map', not 'random-32-32-20.map'"
    ):
        load_instance(MAP, scen=other, agents=3)
    inst = load_instance(MAP, scen=other, agents=3, check_scen_map=False)
    assert inst.num_agents == 3
    assert main(["info", str(MAP), "--scen", str(other), "--agents", "3"]) == 2
    assert "--ignore-scen-map" in capsys.readouterr().err
    assert main(["info", str(MAP), "--scen", str(other), "--agents", "3", "--ignore-scen-map"]) == 0
    capsys.readouterr()
