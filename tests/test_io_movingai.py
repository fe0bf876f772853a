"""MovingAI .map/.scen reading and writing, and every bad-input message."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from io_helpers import MOVINGAI, same_graph, same_instance, write

from hierplan_opt import Graph, InputError, Instance
from hierplan_opt.io import load_instance, save_instance
from hierplan_opt.io.movingai import load_map, load_scen, map_text, parse_map

MAP = MOVINGAI / "random-32-32-20.map"
SCEN = MOVINGAI / "random-32-32-20-random-1.scen"

TINY_MAP = "type octile\nheight 2\nwidth 3\nmap\n.@.\n...\n"


def test_load_map_coordinates() -> None:
    g = load_map(MAP)
    assert g.shape == (32, 32)
    rows = MAP.read_text().splitlines()[4:]
    # x = column, y = row; '@' blocked
    for y in (0, 1, 17):
        for x in range(32):
            assert bool(g.passable[g.vertex((x, y))]) == (rows[y][x] in ".G")
    assert g.num_vertices == sum(r.count(".") + r.count("G") for r in rows)


def test_load_scen_first_k_agents_in_order() -> None:
    inst = load_instance(MAP, scen=SCEN, agents=20)
    assert inst.num_agents == 20
    assert [a.name for a in inst.agents] == [f"agent{i}" for i in range(20)]
    first = SCEN.read_text().splitlines()[1].split("\t")
    sx, sy, gx, gy = map(int, first[4:8])
    assert inst.graph.location(inst.agents[0].start) == (sx, sy)
    assert inst.graph.location(inst.agents[0].goal) == (gx, gy)
    full = load_instance(MAP, scen=SCEN)
    assert full.num_agents == len(SCEN.read_text().splitlines()) - 1


@pytest.mark.parametrize("name", ["empty-8-8", "maze-32-32-2", "room-32-32-4"])
def test_bundled_even_scenarios_load(name: str) -> None:
    inst = load_instance(MOVINGAI / f"{name}.map", scen=MOVINGAI / f"{name}-even-1.scen")
    assert inst.num_agents > 0
    assert inst.soc_lower_bound() > 0


def test_map_text_round_trip() -> None:
    g = load_map(MAP)
    assert same_graph(parse_map(map_text(g)), g)


def test_movingai_to_own_yaml_and_back(tmp_path: Path) -> None:
    inst = load_instance(MAP, scen=SCEN, agents=30)
    for fmt in ("hierplan", "lmrp"):
        out = tmp_path / f"{fmt}.yaml"
        save_instance(out, inst, format=fmt)
        back = load_instance(out)
        assert same_instance(back, inst), fmt


def test_movingai_write_round_trip(tmp_path: Path) -> None:
    inst = load_instance(MAP, scen=SCEN, agents=10)
    save_instance(tmp_path / "copy.map", inst)
    back = load_instance(tmp_path / "copy.map", scen=tmp_path / "copy.scen")
    assert same_instance(back, inst)


def test_free_characters(tmp_path: Path) -> None:
    m = write(tmp_path, "c.map", "type octile\nheight 1\nwidth 7\nmap\n.GS@OTW\n")
    g = load_map(m)
    assert [bool(x) for x in g.passable] == [True, True, True, False, False, False, False]


def test_crlf_and_trailing_blank_lines(tmp_path: Path) -> None:
    m = write(tmp_path, "c.map", TINY_MAP.replace("\n", "\r\n") + "\r\n\r\n")
    assert load_map(m).num_vertices == 5


# ---------------------------------------------------------------- bad .map files
BAD_MAPS = [
    ("typ octile\nheight 2\nwidth 3\nmap\n.@.\n...\n", r"m\.map:1: expected the header line 'type"),
    ("", r"m\.map:1: empty file"),
    ("type octile\nheight 2\nwidth 3\n.@.\n...\n", r"m\.map:4: expected the header line 'map'"),
    ("type octile\nheight two\nwidth 3\nmap\n", r"m\.map:2: height must be a positive integer"),
    ("type octile\nwidth 3\nwidth 3\nmap\n", r"m\.map:3: expected the header line 'height H'"),
    ("type octile\nheight 2\n", r"m\.map:3: file ends inside the header"),
    ("type octile\nheight 2\nwidth 3\nmap\n.@.\n....\n", r"m\.map:6: row 1 has 4 cells"),
    ("type octile\nheight 2\nwidth 3\nmap\n.@\n...\n", r"m\.map:5: row 0 has 2 cells"),
    ("type octile\nheight 3\nwidth 3\nmap\n.@.\n...\n", r"m\.map:6: the header says height 3 but"),
    ("type octile\nheight 1\nwidth 3\nmap\n.@.\n...\n", r"m\.map:6: .*height 1 but the map has 2"),
    ("type octile\nheight 2\nwidth 3\nmap\n.@.\n.x.\n", r"m\.map:6: unknown map character 'x'"),
]


@pytest.mark.parametrize(("text", "match"), BAD_MAPS)
def test_bad_map(tmp_path: Path, text: str, match: str) -> None:
    m = write(tmp_path, "m.map", text)
    with pytest.raises(InputError, match=match) as info:
        load_map(m)
    assert "\n" not in str(info.value)


# ---------------------------------------------------------------- bad .scen files
def _scen(*rows: str, version: str = "version 1") -> str:
    return "\n".join([version, *rows]) + "\n"


OK_ROW = "0\tm.map\t3\t2\t0\t0\t2\t0\t2"
BAD_SCENS = [
    (_scen(OK_ROW, version="version 2"), r"s\.scen:1: expected the first line 'version 1'"),
    (_scen(OK_ROW, version=""), r"s\.scen:1: expected the first line 'version 1'"),
    (_scen("0\tm.map\t3\t2\t0\t0\t2\t0"), r"s\.scen:2: expected 9 tab-separated fields.*got 8"),
    (_scen(OK_ROW, "0\tm.map\t3\t2\t0.5\t0\t2\t0\t2"), r"s\.scen:3: field start_x must be an int"),
    (_scen("0\tm.map\tthree\t2\t0\t0\t2\t0\t2"), r"s\.scen:2: field width must be an integer"),
    (_scen("0\tm.map\t3\t2\t0\t0\t2\t0\tnan"), r"s\.scen:2: field optimal_length must be a finite"),
    (_scen("0\tm.map\t3\t2\t0\t0\t2\t0\t-2"), r"s\.scen:2: field optimal_length must be .* >= 0"),
    (_scen("0\tm.map\t4\t2\t0\t0\t2\t0\t2"), r"s\.scen:2: the scenario says the map is 4x2 but"),
    (_scen("0\tm.map\t3\t2\t1\t0\t2\t0\t2"), r"s\.scen:2: agent0 start \[1, 0\] is on an obstacle"),
    (_scen("0\tm.map\t3\t2\t0\t0\t1\t0\t2"), r"s\.scen:2: agent0 goal \[1, 0\] is on an obstacle"),
    (_scen("0\tm.map\t3\t2\t0\t0\t3\t0\t2"), r"s\.scen:2: agent0 goal \[3, 0\] is outside the 3x2"),
    (_scen("0\tm.map\t3\t2\t0\t-1\t2\t0\t2"), r"s\.scen:2: agent0 start \[0, -1\] is outside"),
    (
        _scen(OK_ROW, "0\tm.map\t3\t2\t0\t0\t0\t1\t2"),
        r"s\.scen:3: agent1 has the same start \[0, 0\] as agent0",
    ),
    (
        _scen(OK_ROW, "0\tm.map\t3\t2\t0\t1\t2\t0\t2"),
        r"s\.scen:3: agent1 has the same goal \[2, 0\] as agent0",
    ),
    (_scen(), r"s\.scen: the scenario has no agents"),
]


@pytest.mark.parametrize(("text", "match"), BAD_SCENS)
def test_bad_scen(tmp_path: Path, text: str, match: str) -> None:
    m = write(tmp_path, "m.map", TINY_MAP)
    s = write(tmp_path, "s.scen", text)
    with pytest.raises(InputError, match=match) as info:
        load_instance(m, scen=s)
    assert "\n" not in str(info.value)


def test_duplicates_beyond_k_are_ignored(tmp_path: Path) -> None:
    m = write(tmp_path, "m.map", TINY_MAP)
    s = write(tmp_path, "s.scen", _scen(OK_ROW, OK_ROW))
    assert load_instance(m, scen=s, agents=1).num_agents == 1


def test_agents_more_than_scenario() -> None:
    with pytest.raises(InputError, match=r"--agents 500 but the scenario has 409 agents"):
        load_instance(MAP, scen=SCEN, agents=500)


@pytest.mark.parametrize("k", [0, -3])
def test_agents_below_one(k: int) -> None:
    with pytest.raises(InputError, match=rf"--agents must be at least 1, got {k}"):
        load_instance(MAP, scen=SCEN, agents=k)


def test_map_needs_scen_and_scen_is_not_an_instance() -> None:
    with pytest.raises(InputError, match=r"\.map instance needs a scenario \(--scen"):
        load_instance(MAP)
    with pytest.raises(InputError, match=r"give the \.map file as INSTANCE"):
        load_instance(SCEN)


def test_missing_files(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=re.escape(f"{tmp_path / 'no.map'}: no such file")):
        load_instance(tmp_path / "no.map", scen=SCEN)
    with pytest.raises(InputError, match=r"no\.scen: no such file"):
        load_instance(MAP, scen=tmp_path / "no.scen")


def test_scen_on_non_grid_is_refused() -> None:
    g = Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B")])
    with pytest.raises(InputError, match="needs a 2D grid"):
        load_scen(SCEN, g)


def test_save_movingai_refuses_roadmaps(tmp_path: Path) -> None:
    g = Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B")])
    inst = Instance.mapf(g, ["A"], ["B"])
    with pytest.raises(InputError, match="only 2D grids"):
        save_instance(tmp_path / "x.map", inst)
    assert not (tmp_path / "x.map").exists()
