"""The hierplan YAML format and libMultiRobotPlanning YAML: reading, writing, bad input."""

from __future__ import annotations

from pathlib import Path

import pytest
from io_helpers import DATA, MOVINGAI, same_instance, write

from hierplan_opt import Graph, InputError, Instance, Kinematics
from hierplan_opt.core.instance import Agent
from hierplan_opt.io import lmrp_yaml, load_instance, save_instance, yaml_format


# ---------------------------------------------------------------- reading the samples
def test_corridor_lmrp() -> None:
    inst = load_instance(DATA / "corridor_lmrp.yaml")
    g = inst.graph
    assert g.shape == (5, 2) and g.num_vertices == 6
    assert [a.name for a in inst.agents] == ["agent0", "agent1"]
    assert g.location(inst.agents[1].start) == (1, 0)
    assert g.location(inst.agents[1].goal) == (3, 0)
    assert inst.soc_lower_bound() == 6


def test_corridor_own_format_kinematics_and_highways() -> None:
    inst = load_instance(DATA / "corridor.yaml")
    assert inst.name == "corridor"
    assert inst.graph.cell_size == 0.5
    k0, k1 = (a.kinematics for a in inst.agents)
    assert k0 == Kinematics("youbot", "omni", 0.8, None, 1.0, 0.3)
    assert k1 == Kinematics("pioneer", "differential", 0.6, 1.5, None, 0.25)
    g = inst.graph
    assert inst.highways == {
        (g.vertex((0, 0)), g.vertex((1, 0))),
        (g.vertex((1, 0)), g.vertex((2, 0))),
    }
    lmrp = load_instance(DATA / "corridor_lmrp.yaml")
    assert [a.start for a in inst.agents] == [a.start for a in lmrp.agents]


def test_3d_grid() -> None:
    inst = load_instance(DATA / "drones_3d.yaml")
    g = inst.graph
    assert g.shape == (3, 3, 2)
    assert not g.passable[g.vertex((1, 1, 1))]
    assert [a.name for a in inst.agents] == ["d0", "d1"]
    assert inst.soc_lower_bound() == 10


def test_roadmap_teams() -> None:
    inst = load_instance(DATA / "roadmap_teams.yaml")
    g = inst.graph
    assert inst.name == "roadmap-teams" and g.kind == "roadmap"
    assert g.edge_length(g.vertex("E"), g.vertex("F")) == 1.5
    assert g.edge_length(g.vertex("A"), g.vertex("B")) == 1.0
    assert [t.name for t in inst.teams] == ["red", "blue"]
    assert [a.name for a in inst.agents] == ["r1", "r2", "agent2"]
    assert inst.agents[0].kinematics.robot_type == "pioneer"  # the team's type
    assert inst.agents[2].kinematics == Kinematics()
    assert inst.teams[0].targets == (g.vertex("D"), g.vertex("F"))


def test_rows_and_map_reference(tmp_path: Path) -> None:
    rows = write(
        tmp_path,
        "rows.yaml",
        'graph: {type: grid, rows: ["..@", "..."]}\nagents: [{start: [0, 0], goal: [2, 1]}]\n',
    )
    g = load_instance(rows).graph
    assert g.shape == (3, 2) and not g.passable[g.vertex((2, 0))]
    ref = write(
        tmp_path,
        "ref.yaml",
        f"graph: {{type: grid, map: {MOVINGAI / 'empty-8-8.map'}, cell_size: 2}}\n"
        "agents: [{start: [0, 0], goal: [7, 7]}]\n",
    )
    inst = load_instance(ref)
    assert inst.graph.shape == (8, 8) and inst.graph.cell_size == 2.0
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "t.map").write_text("type octile\nheight 1\nwidth 2\nmap\n..\n")
    rel = write(
        tmp_path,
        "rel.yaml",
        "graph: {type: grid, map: maps/t.map}\nagents: [{start: [0, 0], goal: [1, 0]}]\n",
    )
    assert load_instance(rel).graph.shape == (2, 1)


def test_lmrp_potential_goals_form_teams() -> None:
    inst = load_instance(DATA / "tapf_lmrp.yaml")
    g = inst.graph
    assert inst.is_tapf and len(inst.teams) == 2
    assert inst.teams[0].agents == (0, 1)
    assert set(inst.teams[0].targets) == {g.vertex((3, 2)), g.vertex((3, 0))}
    assert inst.teams[1].targets == (g.vertex((0, 1)),)


def test_agents_option_on_yaml(tmp_path: Path) -> None:
    inst = load_instance(DATA / "corridor_lmrp.yaml", agents=1)
    assert inst.num_agents == 1
    with pytest.raises(InputError, match=r"--agents 3 but the instance has 2 agents"):
        load_instance(DATA / "corridor_lmrp.yaml", agents=3)
    with pytest.raises(InputError, match=r"--agents applies only to MAPF"):
        load_instance(DATA / "tapf_lmrp.yaml", agents=1)
    with pytest.raises(InputError, match=r"--scen only applies to a MovingAI \.map"):
        load_instance(DATA / "corridor_lmrp.yaml", scen=DATA / "x.scen")


# ---------------------------------------------------------------- round trips
def _samples() -> list[Instance]:
    grid3 = Graph.grid(3, 3, 2, obstacles=[(1, 1, 0)], cell_size=0.25)
    rm = Graph.roadmap(
        {"A": (0, 0), "B": (1, 0), "C": (1, 1e-3), "d 4": (2.5, 3)},
        [("A", "B"), ("B", "C", 7.0), ("C", "d 4"), ("d 4", "A")],
        directed=True,
    )
    youbot = Kinematics("youbot", "omni", 0.8, None, 1.0, 0.3)
    pioneer = Kinematics("pioneer", "differential", 0.6, 1.5, None, 0.25)
    other = Kinematics("youbot", "omni", 0.5)  # same type name, other limits
    return [
        load_instance(DATA / "corridor.yaml"),
        load_instance(DATA / "roadmap_teams.yaml"),
        Instance.mapf(grid3, [(0, 0, 0), (2, 2, 1)], [(2, 2, 1), (0, 0, 0)], name="g3"),
        Instance.mapf(
            rm,
            ["A", "d 4"],
            ["C", "B"],
            names=["yes", "a: b"],
            kinematics=[youbot, other],
            highways=[("A", "B")],
            name="odd names",
        ),
        Instance.tapf(
            Graph.grid(4, 4),
            [([(0, 0), (0, 1)], [(3, 3), (3, 2)]), ([(1, 1)], [(2, 2)])],
            kinematics=[pioneer, youbot],
            highways=[],
        ),
    ]


@pytest.mark.parametrize("index", range(5))
def test_own_format_round_trip(tmp_path: Path, index: int) -> None:
    inst = _samples()[index]
    path = tmp_path / "x.yaml"
    save_instance(path, inst)
    back = load_instance(path)
    if index == 3:  # two kinematics named 'youbot' get distinct type names
        assert back.agents[1].kinematics.robot_type == "youbot_2"
        back_kins = [a.kinematics.v_max for a in back.agents]
        assert back_kins == [0.8, 0.5]
        return
    assert same_instance(back, inst)
    assert back.name == inst.name


def test_own_format_rows_round_trip(tmp_path: Path) -> None:
    inst = load_instance(DATA / "corridor_lmrp.yaml")
    path = tmp_path / "rows.yaml"
    yaml_format.save(path, inst, rows=True)
    assert '    - "..@.."' not in path.read_text()
    assert '    - "@@.@@"' in path.read_text()
    assert same_instance(load_instance(path), inst)


@pytest.mark.parametrize("name", ["corridor_lmrp.yaml", "tapf_lmrp.yaml"])
def test_lmrp_round_trip(tmp_path: Path, name: str) -> None:
    inst = load_instance(DATA / name)
    save_instance(tmp_path / "x.yaml", inst, format="lmrp")
    back = load_instance(tmp_path / "x.yaml")
    assert same_instance(back, inst)
    # and through the own format
    save_instance(tmp_path / "y.yaml", back)
    assert same_instance(load_instance(tmp_path / "y.yaml"), inst)


def test_lmrp_refuses_what_it_cannot_hold(tmp_path: Path) -> None:
    for inst, match in [
        (_samples()[2], "2D grids and roadmaps, not 3D"),
        (_samples()[1], "no highways"),
        (load_instance(DATA / "corridor.yaml"), "no highways"),
    ]:
        with pytest.raises(InputError, match=match):
            save_instance(tmp_path / "x.yaml", inst, format="lmrp")
    with pytest.raises(InputError, match="unknown instance format 'xml'"):
        save_instance(tmp_path / "x.yaml", _samples()[0], format="xml")


def test_kinematics_default_written_without_type(tmp_path: Path) -> None:
    g = Graph.grid(2, 1)
    inst = Instance(g, (Agent("a", 0, 1),))
    text = yaml_format.dumps(inst)
    assert "robot_types" not in text and "type:" not in text.replace("type: grid", "")
    assert lmrp_yaml.dumps(inst).count("goal: [1, 0]") == 1


# ---------------------------------------------------------------- bad input
G = "graph: {type: grid, dimensions: [3, 2], obstacles: [[1, 1]]}\n"
A = "agents:\n  - {name: a, start: [0, 0], goal: [2, 0]}\n"

BAD_OWN = [
    (G + A + "extra: 1\n", r"x\.yaml:4: unknown key 'extra' in the instance"),
    (G + "agents:\n  - {name: a, strat: [0, 0], goal: [2, 0]}\n", r":3: unknown key 'strat'"),
    ("graph: {type: grid, dimensions: [3, 2], obstcles: []}\n" + A, r":1: unknown key 'obstcles'"),
    ("format: hierplan/2\n" + G + A, r"x\.yaml:1: format must be 'hierplan/1'"),
    (A, r"x\.yaml:1: .*not an instance file"),
    (G, r"x\.yaml:1: give either 'agents' \(MAPF\) or 'teams' \(TAPF\)"),
    ("graph: {type: hex, dimensions: [3, 2]}\n" + A, r":1: graph type must be 'grid' or 'roadmap'"),
    ("graph: {type: grid}\n" + A, r":1: a grid graph needs exactly one of 'dimensions'"),
    ("graph: {type: grid, dimensions: [3, -2]}\n" + A, r":1: a grid dimension must be >= 1"),
    ("graph: {type: grid, dimensions: [3, 2.5]}\n" + A, r":1: a grid dimension must be an int"),
    ("graph: {type: grid, dimensions: [3, 2, 1, 1]}\n" + A, r":1: dimensions must be \[W, H\]"),
    (
        "graph: {type: grid, dimensions: [3, 2], obstacles: [[3, 0]]}\n" + A,
        r":1: obstacle \[3, 0\]",
    ),
    (
        "graph: {type: grid, dimensions: [3, 2], cell_size: -1}\n" + A,
        r":1: cell_size must be a pos",
    ),
    (
        "graph: {type: grid, dimensions: [3, 2], cell_size: .nan}\n" + A,
        r":1: cell_size must be a fi",
    ),
    ('graph: {type: grid, rows: ["...", ".."]}\n' + A, r":1: row 1 has 2 cells, but row 0 has 3"),
    ('graph: {type: grid, rows: ["...", ".x."]}\n' + A, r":1: unknown map character 'x'"),
    ("graph: {type: grid, map: nothere.map}\n" + A, r":1: map file 'nothere.map' not found"),
    (
        G + "agents:\n  - {name: a, start: [1, 1], goal: [2, 0]}\n",
        r":3: .*start \[1, 1\] is on an ob",
    ),
    (
        G + "agents:\n  - {name: a, start: [0, 0], goal: [5, 0]}\n",
        r":3: .*goal \[5, 0\] is outside",
    ),
    (G + "agents:\n  - {name: a, start: [0, 0.5], goal: [2, 0]}\n", r":3: .*must be an integer"),
    (G + "agents:\n  - {name: a, start: [0], goal: [2, 0]}\n", r":3: .*start must be \[x, y\]"),
    # an agent without a goal is a task-free robot (issue 34); without a start, refused
    (G + "agents:\n  - {goal: [0, 0]}\n", r":3: agent 0 is missing the key 'start'"),
    (G + "agents: []\n", r":2: the instance has no agents"),
    (
        G + A + "  - {name: b, start: [0, 0], goal: [0, 1]}\n",
        r"x\.yaml:4: agent 'b' has the same start \[0, 0\] as agent 'a'",
    ),
    (
        G + A + "  - {name: b, start: [1, 0], goal: [2, 0]}\n",
        r"x\.yaml:4: agent 'b' has the same goal \[2, 0\] as agent 'a'",
    ),
    (G + A + "  - {name: a, start: [1, 0], goal: [0, 1]}\n", r":4: agent name 'a' is used twice"),
    (G + A + "highways: [[[0, 0], [2, 0]]]\n", r":4: highway \[0, 0\] -> \[2, 0\] is not an edge"),
    (G + "robot_types:\n  r: {v_max: -1}\n" + A, r":3: robot type 'r': v_max must be a positive"),
    (G + "robot_types:\n  r: {v_max: .nan}\n" + A, r":3: robot type 'r': v_max must be a finite"),
    (G + "robot_types:\n  r: {radius: -0.1}\n" + A, r":3: robot type 'r': radius must not be neg"),
    (G + "robot_types:\n  r: {drive: tank}\n" + A, r":3: robot type 'r': drive must be one of"),
    (G + "robot_types:\n  r: {drive: differential}\n" + A, r":3: .*differential-drive robot needs"),
    (G + "robot_types:\n  r: {speed: 1}\n" + A, r":3: unknown key 'speed' in robot type 'r'"),
    (G + "agents:\n  - {start: [0, 0], goal: [2, 0], type: r}\n", r":3: .*unknown robot type 'r'"),
    (G + A + "agents: []\n", r"x\.yaml:4: duplicate key 'agents' \(first on line 2\)"),
    (G + "agents:\n  - {start: [0, 0], goal: [2, 0]\n", r"x\.yaml:\d+: YAML syntax error"),
    ("graph: [1, 2]\n" + A, r"x\.yaml:1: graph must be a mapping"),
    (
        G + "teams:\n  - {agents: [{start: [0, 0]}], targets: [[2, 0], [2, 1]]}\n",
        r"x\.yaml:3: team 'team0' has 1 robots but 2 targets",
    ),
    (
        G + "teams:\n  - {agents: [{start: [0, 0]}], targets: [[2, 0]]}\n"
        "  - {agents: [{start: [0, 1]}], targets: [[2, 0]]}\n",
        r"x\.yaml:4: target \[2, 0\] of team 'team1' is also a target of team 'team0'",
    ),
    (G + "teams:\n  - {agents: [], targets: []}\n", r":3: team 'team0' has no robots"),
    (
        G + "teams:\n  - {agents: [{start: [0, 0], goal: [1, 0]}], targets: [[2, 0]]}\n",
        r":3: unknown key 'goal' in robot 0 of team 'team0'",
    ),
]


@pytest.mark.parametrize(("text", "match"), BAD_OWN)
def test_bad_own_format(tmp_path: Path, text: str, match: str) -> None:
    p = write(tmp_path, "x.yaml", text)
    with pytest.raises(InputError, match=match) as info:
        load_instance(p)
    assert "\n" not in str(info.value)
    assert str(info.value).startswith(str(p))


RM = "graph:\n  type: roadmap\n  vertices: {A: [0, 0], B: [1, 0], C: [1, 1]}\n"
BAD_ROADMAPS = [
    (RM + "  edges: [[A, B], [B, X]]\n", r":4: edge \[B, X\] names unknown vertex 'X'"),
    (RM + "  edges: [[A, B], [B, A]]\n", r":4: edge \[B, A\] is listed twice"),
    (RM + "  edges: [[A, A]]\n", r":4: edge \[A, A\] is a self-loop"),
    (RM + "  edges: [[A, B, -1]]\n", r":4: length of edge \[A, B\] must be a positive"),
    (RM + "  edges: [[A, B, .nan]]\n", r":4: length of edge \[A, B\] must be a finite"),
    (RM + "  edges: [[A, B, 1, 2]]\n", r":4: an edge must be \[u, v\] or \[u, v, length\]"),
    (RM + "  directed: maybe\n", r":4: directed must be true or false"),
    (RM + "  weights: []\n", r":4: unknown key 'weights' in a roadmap graph"),
    ("graph:\n  type: roadmap\n  vertices: {A: [0, .inf]}\n", r":3: a coordinate of vertex 'A'"),
    (
        "graph:\n  type: roadmap\n  vertices: {A: [0, 0], B: [1]}\n",
        r":3: vertex 'B' needs \[x, y\]",
    ),
    (
        "graph:\n  type: roadmap\n  vertices: {A: [0, 0], B: [0, 0]}\n  edges: [[A, B]]\n",
        r"one pos",
    ),
]


@pytest.mark.parametrize(("text", "match"), BAD_ROADMAPS)
def test_bad_roadmap(tmp_path: Path, text: str, match: str) -> None:
    agents = "agents: [{start: A, goal: B}]\n"
    p = write(tmp_path, "x.yaml", text + agents)
    with pytest.raises(InputError, match=match) as info:
        load_instance(p)
    assert "\n" not in str(info.value)


def test_roadmap_unknown_agent_vertex(tmp_path: Path) -> None:
    p = write(tmp_path, "x.yaml", RM + "  edges: [[A, B]]\nagents:\n  - {start: A, goal: Z}\n")
    with pytest.raises(InputError, match=r"x\.yaml:6: agent 'agent0' goal 'Z' is not a vertex"):
        load_instance(p)


M = "map:\n  dimensions: [3, 2]\n  obstacles: [[1, 1]]\n"
BAD_LMRP = [
    (
        M + "agents:\n  - {name: a, start: [1, 1], goal: [2, 0]}\n",
        r":5: .*'a' start \[1, 1\] is on an",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0], goal: [3, 0]}\n",
        r":5: .*goal \[3, 0\] is outside",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0], gaol: [2, 0]}\n",
        r":5: unknown key 'gaol' in agent 0",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0]}\n",
        r":5: agent 'a' needs 'goal' or 'potentialGoals'",
    ),
    ("map:\n  dimensions: [3]\nagents: []\n", r"x\.yaml:2: map dimensions must be \[W, H\]"),
    (
        "map:\n  dimensions: [3, 2]\n  obstacles: [[4, 1]]\nagents: []\n",
        r":3: obstacle \[4, 1\] is",
    ),
    ("map:\n  dimensions: [3, 2]\n  size: 1\nagents: []\n", r":3: unknown key 'size' in map"),
    (M + "agents: []\n", r":4: the instance has no agents"),
    (
        M + "agents:\n  - {name: a, start: [0, 0], goal: [2, 0]}\n"
        "  - {name: b, start: [0, 0], goal: [2, 1]}\n",
        r"x\.yaml:6: agent 'b' has the same start \[0, 0\] as agent 'a'",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0], goal: [2, 0]}\n"
        "  - {name: b, start: [0, 1], goal: [2, 0]}\n",
        r"x\.yaml:6: agent 'b' has the same goal \[2, 0\] as agent 'a'",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0], potentialGoals: [[2, 0], [2, 1]]}\n"
        "  - {name: b, start: [0, 1], potentialGoals: [[2, 0], [1, 0]]}\n",
        r"x\.yaml:6: agent 'b' shares the goal \[2, 0\] with agent 'a' but their goal sets differ",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0], potentialGoals: [[2, 0], [2, 1]]}\n",
        r"x\.yaml:5: agents 'a' share 2 potential goals but are 1 agents",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0], potentialGoals: [[2, 0], [2, 0]]}\n",
        r"x\.yaml:5: potentialGoals of agent 'a' lists \[2, 0\] twice",
    ),
    (
        M + "agents:\n  - {name: a, start: [0, 0], goal: [2, 0], potentialGoals: [[2, 0]]}\n",
        r"x\.yaml:5: agent 'a' has both 'goal' and 'potentialGoals'",
    ),
]


@pytest.mark.parametrize(("text", "match"), BAD_LMRP)
def test_bad_lmrp(tmp_path: Path, text: str, match: str) -> None:
    p = write(tmp_path, "x.yaml", text)
    with pytest.raises(InputError, match=match) as info:
        load_instance(p)
    assert "\n" not in str(info.value)


def test_bad_sample_files() -> None:
    with pytest.raises(InputError, match=r"bad_unknown_key\.yaml:4: unknown key 'obstacle'"):
        load_instance(DATA / "bad_unknown_key.yaml")
    with pytest.raises(InputError, match=r"bad_syntax\.yaml:3: YAML syntax error"):
        load_instance(DATA / "bad_syntax.yaml")
    with pytest.raises(InputError, match=r"bad_start_on_obstacle\.yaml:9: agent 'agent1' start"):
        load_instance(DATA / "bad_start_on_obstacle.yaml")


def test_not_yaml_and_empty(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"e\.yaml:1: not an instance file"):
        load_instance(write(tmp_path, "e.yaml", ""))
    (tmp_path / "b.yaml").write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(InputError, match=r"b\.yaml: not a text file"):
        load_instance(tmp_path / "b.yaml")
    with pytest.raises(InputError, match=r"is a directory"):
        load_instance(tmp_path)
