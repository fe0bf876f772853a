"""Plan files (libMultiRobotPlanning output layout): round trips and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from io_helpers import DATA, write

from hierplan_opt import Graph, InputError, Instance, Plan, validate
from hierplan_opt.core.result import Result, Status
from hierplan_opt.io import load_instance, load_plan, save_plan


def _corridor() -> tuple[Instance, Plan]:
    inst = load_instance(DATA / "corridor_lmrp.yaml")
    g = inst.graph
    p0 = [g.vertex((x, 0)) for x in range(5)]
    p1 = [g.vertex(c) for c in [(1, 0), (2, 0), (2, 1), (2, 0), (3, 0)]]
    return inst, Plan.from_paths([p0, p1])


def _drones() -> tuple[Instance, Plan]:
    inst = load_instance(DATA / "drones_3d.yaml")
    g = inst.graph
    a = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (2, 1, 0), (2, 2, 0), (2, 2, 1)]
    b = [(2, 2, 1), (1, 2, 1), (0, 2, 1), (0, 1, 1), (0, 0, 1), (0, 0, 0)]
    return inst, Plan.from_paths([[g.vertex(c) for c in a], [g.vertex(c) for c in b]])


def _roadmap() -> tuple[Instance, Plan]:
    inst = load_instance(DATA / "roadmap_teams.yaml")
    g = inst.graph
    # r1 -> F via the loop, r2 -> D, blue -> A along the corridor
    paths = [["A", "B", "E", "E", "F"], ["E", "F", "F", "C", "D"], ["C", "C", "B", "A"]]
    return inst, Plan.from_paths([[g.vertex(v) for v in p] for p in paths])


def _tapf_lmrp() -> tuple[Instance, Plan]:
    inst = load_instance(DATA / "tapf_lmrp.yaml")
    g = inst.graph
    paths = [
        [(0, 0), (1, 0), (2, 0), (3, 0)],
        [(0, 2), (1, 2), (2, 2), (3, 2)],
        [(2, 1), (2, 1), (2, 1), (2, 0), (1, 0), (0, 0), (0, 1)],
    ]
    return inst, Plan.from_paths([[g.vertex(c) for c in p] for p in paths])


@pytest.mark.parametrize("make", [_corridor, _drones, _roadmap, _tapf_lmrp])
def test_sample_plans_are_valid(make) -> None:
    inst, plan = make()
    assert validate(inst, plan) == []


@pytest.mark.parametrize("make", [_corridor, _drones, _roadmap, _tapf_lmrp])
@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_plan_round_trip(tmp_path: Path, make, suffix: str) -> None:
    inst, plan = make()
    path = tmp_path / f"plan{suffix}"
    save_plan(path, inst, plan)
    assert load_plan(path, inst) == plan


def test_corridor_plan_is_valid_and_costs() -> None:
    inst, plan = _corridor()
    assert validate(inst, plan) == []
    assert (plan.sum_of_costs, plan.makespan) == (8, 4)


def test_plan_file_layout(tmp_path: Path) -> None:
    inst, plan = _drones()
    res = Result(
        Status.OPTIMAL,
        plan,
        cost=10,
        lower_bound=10,
        runtime=0.5,
        solver="cbs",
        objective="soc",
        stats={"high_level_expanded": 3, "low_level_expanded": 41, "ratio": 0.5, "obj": object()},
    )
    save_plan(tmp_path / "p.yaml", inst, res)
    data = yaml.safe_load((tmp_path / "p.yaml").read_text())
    st = data["statistics"]
    assert st["cost"] == 10 and st["makespan"] == 5 and st["status"] == "OPTIMAL"
    assert st["solver"] == "cbs" and st["lower_bound"] == 10 and st["objective"] == "soc"
    assert st["highLevelExpanded"] == 3 and st["lowLevelExpanded"] == 41 and st["ratio"] == 0.5
    assert "obj" not in st
    assert data["schedule"]["d0"][1] == {"x": 1, "y": 0, "z": 0, "t": 1}
    save_plan(tmp_path / "p.json", inst, res)
    assert json.loads((tmp_path / "p.json").read_text())["schedule"] == data["schedule"]


def test_save_refuses_result_without_plan(tmp_path: Path) -> None:
    inst, _ = _corridor()
    with pytest.raises(InputError, match="no plan to write"):
        save_plan(tmp_path / "p.yaml", inst, Result(Status.INFEASIBLE, None))


def test_roadmap_names_are_quoted(tmp_path: Path) -> None:
    g = Graph.roadmap({"yes": (0, 0), "a: b": (1, 0)}, [("yes", "a: b")])
    inst = Instance.mapf(g, ["yes"], ["a: b"], names=["null"])
    plan = Plan.from_paths([[0, 1]])
    save_plan(tmp_path / "p.yaml", inst, plan)
    assert load_plan(tmp_path / "p.yaml", inst) == plan


def test_tabbed_json_plan(tmp_path: Path) -> None:
    inst, plan = _corridor()
    doc = {"schedule": {"agent0": [{"x": 0, "y": 0, "t": 0}], "agent1": [{"x": 1, "y": 0, "t": 0}]}}
    p = write(tmp_path, "p.json", json.dumps(doc, indent="\t"))
    assert load_plan(p, inst).paths == ((0,), (1,))
    bad = write(tmp_path, "bad.json", '{\n\t"schedule": {\n\t\t"agent0": [}\n}')
    with pytest.raises(InputError, match=r"bad\.json:\d+: "):
        load_plan(bad, inst)


# ---------------------------------------------------------------- bad plan files
E0 = "  agent0: [{x: 0, y: 0, t: 0}, {x: 1, y: 0, t: 1}]\n"
E1 = "  agent1: [{x: 1, y: 0, t: 0}]\n"
BAD_PLANS = [
    ("schedule:\n" + E0, r"p\.yaml:1: schedule has no path for agent\(s\) 'agent1'"),
    ("statistics: {}\nschedule:\n" + E0 + E1 + "  agent7: []\n", r":5: .*agent 'agent7', which"),
    ("schedule:\n" + E0 + "  agent1: []\n", r"p\.yaml:3: schedule of 'agent1' is empty"),
    (
        "schedule:\n" + E0 + "  agent1: [{x: 1, y: 0, t: 1}]\n",
        r":3: .*must start at t: 0, got t: 1",
    ),
    (
        "schedule:\n" + E0 + "  agent1:\n    - {x: 1, y: 0, t: 0}\n    - {x: 2, y: 0, t: 2}\n",
        r"p\.yaml:5: schedule of 'agent1' must continue with t: 1 after t: 0, got t: 2",
    ),
    ("schedule:\n" + E0 + "  agent1: [{x: 1, y: 0}]\n", r":3: .*is missing the key 't'"),
    ("schedule:\n" + E0 + "  agent1: [{x: 1, y: 0, z: 0, t: 0}]\n", r":3: unknown key 'z'"),
    ("schedule:\n" + E0 + "  agent1: [{x: 9, y: 0, t: 0}]\n", r":3: 'agent1' at t=0: .*outside"),
    ("schedule:\n" + E0 + "  agent1: [{x: 1.5, y: 0, t: 0}]\n", r":3: x of 'agent1' must be an in"),
    (
        "schedule:\n" + E0 + "  agent1: {x: 1, y: 0, t: 0}\n",
        r":3: schedule of 'agent1' must be a l",
    ),
    ("schedule: []\n", r"p\.yaml:1: schedule must be a mapping"),
    ("plan:\n" + E0, r"p\.yaml:1: unknown key 'plan' in the plan file"),
    ("statistics: {}\n", r"p\.yaml:1: the plan file is missing the key 'schedule'"),
    ("", r"p\.yaml:1: empty file"),
    ("schedule:\n" + E0 + E0, r"p\.yaml:3: duplicate key 'agent0'"),
    ("schedule:\n" + E0 + E1 + '  "agent0": []\n', r"p\.yaml:4: duplicate key 'agent0'"),
    ("schedule:\n  agent0: [{x: 0, y: 0, t: 0}\n", r"p\.yaml:\d+: YAML syntax error"),
]


@pytest.mark.parametrize(("text", "match"), BAD_PLANS)
def test_bad_plan(tmp_path: Path, text: str, match: str) -> None:
    inst, _ = _corridor()
    p = write(tmp_path, "p.yaml", text)
    with pytest.raises(InputError, match=match) as info:
        load_plan(p, inst)
    assert "\n" not in str(info.value)


def test_bad_roadmap_plan_vertex(tmp_path: Path) -> None:
    inst, _ = _roadmap()
    p = write(
        tmp_path,
        "p.yaml",
        "schedule:\n  r1: [{v: A, t: 0}]\n  r2: [{v: E, t: 0}]\n  agent2: [{v: Q, t: 0}]\n",
    )
    with pytest.raises(InputError, match=r"p\.yaml:4: 'agent2' at t=0: unknown vertex 'Q'"):
        load_plan(p, inst)


def test_bad_plan_sample_file() -> None:
    inst, _ = _corridor()
    with pytest.raises(InputError, match=r"bad_plan_missing_agent\.yaml:2: .*'agent1'"):
        load_plan(DATA / "bad_plan_missing_agent.yaml", inst)


def test_block_style_libmrp_plan(tmp_path: Path) -> None:
    """libMultiRobotPlanning itself writes one key per line; that layout loads too."""
    inst, plan = _corridor()
    g = inst.graph
    lines = ["statistics:", "  cost: 8", "  makespan: 4", "schedule:"]
    for a, path in zip(inst.agents, plan.paths, strict=True):
        lines.append(f"  {a.name}:")
        for t, v in enumerate(path):
            x, y = g.location(v)
            lines += [f"    - x: {x}", f"      y: {y}", f"      t: {t}"]
    p = write(tmp_path, "p.yaml", "\n".join(lines) + "\n")
    assert load_plan(p, inst) == plan


def test_fast_layout_errors_keep_lines(tmp_path: Path) -> None:
    """Errors in the layout save_plan writes (read without the YAML parser) name the line."""
    inst, plan = _corridor()
    path = tmp_path / "p.yaml"
    save_plan(path, inst, plan)
    lines = path.read_text().splitlines()
    k = lines.index("  agent1:") + 3  # third entry of agent1 (t: 2), 0-based index
    assert lines[k] == "    - {x: 2, y: 1, t: 2}"
    for bad, match in [
        (
            "    - {x: 2, y: 1, t: 3}",
            rf"p\.yaml:{k + 1}: .*continue with t: 2 after t: 1, got t: 3",
        ),
        ("    - {x: 7, y: 1, t: 2}", rf"p\.yaml:{k + 1}: 'agent1' at t=2: location \[7, 1\] is"),
        ("    - {x: 2, y: 1, z: 0, t: 2}", rf"p\.yaml:{k + 1}: unknown key 'z'"),
        ("    - {x: 2, y: 1, t: 2, t: 2}", rf"p\.yaml:{k + 1}: duplicate key 't'"),
        ("    - {x: 010, y: 1, t: 2}", rf"p\.yaml:{k + 1}: 'agent1' at t=2: location \[8, 1\]"),
    ]:
        changed = [*lines[:k], bad, *lines[k + 1 :]]
        path.write_text("\n".join(changed) + "\n")
        with pytest.raises(InputError, match=match):
            load_plan(path, inst)


def test_blocked_cell_in_plan_is_a_violation_not_an_error(tmp_path: Path) -> None:
    inst, _ = _corridor()
    p = write(
        tmp_path,
        "p.yaml",
        "schedule:\n  agent0:\n    - {x: 0, y: 0, t: 0}\n    - {x: 0, y: 1, t: 1}\n"
        "  agent1:\n    - {x: 3, y: 0, t: 0}\n",
    )
    kinds = {v.kind for v in validate(inst, load_plan(p, inst))}
    assert {"blocked", "wrong_start", "wrong_goal"} <= kinds
