"""Highways: formats, generators, the heuristic, CBS/ECBS/EECBS+HWY bounds, learned
highways, the CLI and the shipped instances."""

from __future__ import annotations

import ast
import importlib.util
import itertools
import random
import zlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt.cli import main as cli_main
from hierplan_opt.core.errors import InputError, OptionError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.highways import (
    cell_directions,
    check_highways,
    corridors,
    crisscross,
    highway_share,
    reversed_highways,
)
from hierplan_opt.core.highways_learned import flow, learned, min_cut_labels, traffic
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Status
from hierplan_opt.core.validate import validate
from hierplan_opt.io import load_instance
from hierplan_opt.io.highways import (
    edges_text,
    grid_text,
    load_highways,
    parse_edges,
    parse_grid,
    save_highways,
    yaml_text,
)
from hierplan_opt.search import highways as search_highways
from hierplan_opt.search.constraints import AgentConstraints
from hierplan_opt.search.highways import HighwayHeuristic, inflated_focal_path
from hierplan_opt.search.reservations import Reservations

DATA = Path(__file__).resolve().parents[1] / "instances" / "highways"


def random_instance(rng: random.Random, w: int, h: int, k: int, p_obst: float) -> Instance:
    """A random solvable-looking instance: connected free cells, distinct starts/goals."""
    while True:
        obst = [(x, y) for x in range(w) for y in range(h) if rng.random() < p_obst]
        g = Graph.grid(w, h, obstacles=obst)
        free = [g.location(v) for v in range(g.n) if g.passable[v]]
        if len(free) < k + 2:
            continue
        d = g.dist_to(g.vertex(free[0]))
        if any(d[g.vertex(c)] >= 1 << 29 for c in free):
            continue
        starts = rng.sample(free, k)
        goals = rng.sample(free, k)
        return Instance.mapf(g, starts, goals)


# ---------------------------------------------------------------- data and formats
def test_check_highways_refuses_non_edges() -> None:
    g = Graph.grid(3, 2, obstacles=[(1, 1)])
    assert check_highways(g, [(0, 1)]) == {(0, 1)}
    with pytest.raises(InputError, match=r"highway \[0, 1\] -> \[1, 1\] is not an edge"):
        check_highways(g, [(0, 3), (3, 4)])  # (1, 1) is blocked
    with pytest.raises(InputError, match="vertex id 99"):
        check_highways(g, [(0, 99)])


@pytest.mark.parametrize("fmt", ["hierplan", "grid", "edges"])
def test_every_format_round_trips(tmp_path: Path, fmt: str) -> None:
    g = Graph.grid(6, 4, obstacles=[(2, 1), (3, 1), (2, 2)])
    for hw in (crisscross(g), corridors(g), frozenset()):
        suffix = {"hierplan": ".yaml", "grid": ".highway", "edges": ".hwy"}[fmt]
        f = tmp_path / f"h{suffix}"
        save_highways(f, g, hw)
        assert "\n" in f.read_text()
        assert load_highways(f, g) == hw
        assert load_highways(f, g, format=fmt) == hw


def test_yaml_directions_and_edges_combine(tmp_path: Path) -> None:
    g = Graph.grid(3, 2)
    f = tmp_path / "h.yaml"
    f.write_text('highways:\n  - [[0, 1], [0, 0]]\ndirections:\n  - "rr."\n  - "..."\n')
    assert load_highways(f, g) == {(3, 0), (0, 1), (1, 2)}
    f.write_text(yaml_text(g, crisscross(g), directions=True))
    assert load_highways(f, g) == crisscross(g)


def test_shipped_files_in_both_external_formats_parse() -> None:
    kiva = load_instance(DATA / "kiva-22x54.map", scen=DATA / "kiva-22x54-seed0.scen")
    hw = load_highways(DATA / "kiva-22x54.map.highway", kiva.graph)
    assert hw == corridors(kiva.graph) and len(hw) > 300
    assert grid_text(kiva.graph, hw) == (DATA / "kiva-22x54.map.highway").read_text()
    cor = load_instance(DATA / "corridor-5x20.map", scen=DATA / "corridor-5x20.scen")
    hw2 = load_highways(DATA / "corridor-5x20.hwy", cor.graph)
    assert edges_text(cor.graph, hw2) == (DATA / "corridor-5x20.hwy").read_text()
    # every corridor cell has exactly one direction, the two lanes opposite
    dirs = cell_directions(cor.graph, hw2)
    assert {dirs[cor.graph.vertex((x, 2))] for x in range(5, 15)} == {"l"}
    assert {dirs[cor.graph.vertex((x, 3))] for x in range(5, 15)} == {"r"}
    wh = load_instance(DATA / "warehouse-fig2.yaml")
    assert wh.highways == corridors(wh.graph)


BAD_GRIDS = [
    ("r.\n..\n..\n", "the highway grid has 3 rows, the map has 2"),
    ("r..\n..\n", r":1: row 0 has 3 cells, the map is 2 wide"),
    ("rq\n..\n", r":1: unknown highway character 'q' in column 1"),
    ("..\n.d\n", r":2: highway 'd' at \[1, 1\] leads off the graph"),
    ("..\nr@\n", r":2: highway 'r' at \[0, 1\] leads off the graph"),
]


@pytest.mark.parametrize(("text", "message"), BAD_GRIDS)
def test_bad_grids_get_one_line(text: str, message: str) -> None:
    g = Graph.grid(2, 2, obstacles=[(1, 1)])
    with pytest.raises(InputError, match=message) as exc:
        parse_grid(text, g, "h.highway")
    assert "\n" not in str(exc.value) and str(exc.value).startswith("h.highway")


BAD_EDGES = [
    ("e 0 1\n", ":1: the first line must be 'p edges NV NE'"),
    ("p edges 2 x\ne 0 1\n", ":1: 'p edges NV NE' needs two integers"),
    ("p edges 2 2\ne 0 1\n", ":1: the header announces 2 edges, the file has 1"),
    ("p edges 3 1\ne 0 1\n", ":1: the header announces 3 vertices, the edges have 2"),
    ("p edges 2 1\nf 0 1\n", ":2: an edge line must be 'e FROM TO'"),
    ("p edges 2 1\ne 0 a\n", ":2: vertex ids must be integers"),
    ("p edges 2 1\ne 0 4\n", r":2: highway \[0, 0\] -> \[1, 1\] is not an edge"),
]


@pytest.mark.parametrize(("text", "message"), BAD_EDGES)
def test_bad_edge_lists_get_one_line(text: str, message: str) -> None:
    g = Graph.grid(3, 2)
    with pytest.raises(InputError, match=message):
        parse_edges(text, g, "h.hwy")


def test_bad_yaml_highways(tmp_path: Path) -> None:
    g = Graph.grid(3, 1)
    f = tmp_path / "h.yaml"
    for text, message in [
        ("lanes: []\n", "unknown key 'lanes'"),
        ("format: hierplan/1\n", "needs 'highways:'"),
        ("highways:\n  - [[0, 0], [2, 0]]\n", r":2: highway \[0, 0\] -> \[2, 0\] is not an edge"),
        ('directions: ["r?."]\n', "unknown highway character '\\?'"),
    ]:
        f.write_text(text)
        with pytest.raises(InputError, match=message):
            load_highways(f, g)


def test_grid_writer_refuses_opposite_directions() -> None:
    g = Graph.grid(3, 1)
    with pytest.raises(InputError, match=r"cell \[1, 0\] has highway directions 'lr'"):
        grid_text(g, {(1, 0), (1, 2)})


# ---------------------------------------------------------------- generators
def test_crisscross_orients_every_edge_once() -> None:
    g = Graph.grid(7, 5, obstacles=[(3, 2), (1, 1)])
    hw = crisscross(g)
    undirected = {frozenset(e) for e in g.edges()}
    assert len(hw) == len(undirected) and {frozenset(e) for e in hw} == undirected
    # rows alternate: row 0 east, row 1 west
    assert (g.vertex((0, 0)), g.vertex((1, 0))) in hw
    assert (g.vertex((1, 1 + 1)), g.vertex((0, 2))) not in hw


def test_corridors_only_in_narrow_aisles() -> None:
    kiva = load_instance(DATA / "kiva-22x54.map", scen=DATA / "kiva-22x54-seed0.scen").graph
    hw = corridors(kiva)
    ends = {v for e in hw for v in e}
    assert all(not (kiva.location(v)[0] < 4 or kiva.location(v)[0] > 48) for v in ends)
    # neighbouring horizontal aisles run opposite ways
    assert (kiva.vertex((10, 0)), kiva.vertex((11, 0))) in hw
    assert (kiva.vertex((11, 3)), kiva.vertex((10, 3))) in hw


# ---------------------------------------------------------------- heuristic
def test_heuristic_is_sandwiched_and_exact() -> None:
    rng = random.Random(3)
    for _ in range(20):
        inst = random_instance(rng, 6, 5, 1, 0.2)
        g = inst.graph
        hw = frozenset(e for e in g.edges() if rng.random() < 0.5)
        w_hwy = rng.choice([1.0, 1.5, 2.0, 3.0])
        hh = HighwayHeuristic(g, hw, w_hwy)
        goal = inst.goals[0]
        # Bellman-Ford on the inflated costs, independently
        ref = np.full(g.n, np.inf)
        ref[goal] = 0.0
        for _ in range(g.n):
            for u, v in g.edges():
                c = 1.0 if (u, v) in hw else w_hwy
                ref[u] = min(ref[u], c + ref[v])
        np.testing.assert_allclose(hh.exact(goal), ref)
        d = g.dist_to(goal)
        for v in range(g.n):
            if g.passable[v] and np.isfinite(ref[v]):
                assert d[v] <= hh.table(goal)[v] <= w_hwy * d[v] + 1e-9


def test_inflated_search_returns_the_cheapest_inflated_path() -> None:
    g = Graph.grid(4, 3)
    hw = frozenset({(0, 4), (4, 8), (8, 9), (9, 10), (10, 11)})
    hh = HighwayHeuristic(g, hw, 3.0)
    out = inflated_focal_path(
        g.adj, 0, 11, hh.exact(11), hw, 3.0, AgentConstraints(), Reservations(g.n)
    )
    assert out is not None
    assert out[0] == (0, 4, 8, 9, 10, 11) and out[1] == 5.0


# ---------------------------------------------------------------- solvers and bounds
CASES = [
    ("cbs", {}, 1.0),
    ("ecbs", {"w": 1.2}, 1.2),
    ("eecbs", {"w": 1.5}, 1.5),
]


@pytest.mark.parametrize("mode", ["heuristic", "cost"])
@pytest.mark.parametrize(("solver", "extra", "w"), CASES)
def test_bound_holds_against_cbs_optimum(
    solver: str, extra: dict[str, float], w: float, mode: str
) -> None:
    rng = random.Random(zlib.crc32(f"{solver}-{mode}".encode()))
    checked = 0
    for trial in range(30):
        inst = random_instance(rng, rng.randint(4, 6), rng.randint(3, 5), rng.randint(2, 5), 0.15)
        opt = hp.solve(inst, "cbs", time_limit=20)
        if opt.status is not Status.OPTIMAL:
            continue
        assert opt.cost is not None
        kinds = ["crisscross", "reversed", "learned", "flow"]
        kind = kinds[trial % len(kinds)]
        hw = crisscross(inst.graph)
        if kind == "reversed":  # every highway the wrong way
            hw = reversed_highways(hw)
        if kind in ("learned", "flow"):
            hw = learned(inst) if kind == "learned" else flow(inst)
        w_hwy = rng.choice([1.5, 2.0, 3.0])
        r = hp.solve(
            replace(inst, highways=hw),
            solver,
            time_limit=20,
            highways="instance",
            w_hwy=w_hwy,
            hwy_mode=mode,
            **extra,
        )
        assert r.plan is not None, (solver, kind, r.status, r.stats.get("error"))
        assert not validate(inst, r.plan)
        bound = w * w_hwy
        assert r.stats["bound"] == pytest.approx(bound)
        assert r.cost is not None and r.lower_bound is not None
        assert r.cost <= bound * opt.cost + 1e-9, (solver, kind, r.cost, opt.cost)
        assert r.lower_bound <= opt.cost <= r.cost
        assert 0.0 <= r.stats["highway_share"] <= 1.0
        checked += 1
    assert checked >= 25


def test_share_on_highways_is_higher_with_highways() -> None:
    inst = load_instance(DATA / "kiva-22x54.map", scen=DATA / "kiva-22x54-seed0.scen", agents=40)
    hw = load_highways(DATA / "kiva-22x54.map.highway", inst.graph)
    plain = hp.solve(inst, "ecbs", w=1.2, time_limit=60)
    with_hw = hp.solve(replace(inst, highways=hw), "ecbs", w=1.2, highways="instance")
    assert plain.plan is not None and with_hw.plan is not None
    assert with_hw.stats["highway_share"] > highway_share(plain.plan, hw) + 0.1
    assert not validate(inst, with_hw.plan)


def test_corridor_cbs_with_highways_within_target_cost() -> None:
    inst = load_instance(DATA / "corridor-5x20.map", scen=DATA / "corridor-5x20.scen")
    hw = load_highways(DATA / "corridor-5x20.hwy", inst.graph)
    r = hp.solve(replace(inst, highways=hw), "cbs", highways="instance", w_hwy=2.0)
    assert r.plan is not None and r.cost is not None and r.cost <= 423
    assert r.cost <= 2.0 * r.lower_bound


def test_options_are_checked() -> None:
    inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    with pytest.raises(OptionError, match="highways must be one of"):
        hp.solve(inst, "ecbs", highways="sideways")
    with pytest.raises(OptionError, match="the instance has no highways"):
        hp.solve(inst, "ecbs", highways="instance")
    with pytest.raises(OptionError, match="w_hwy must be a number >= 1"):
        hp.solve(inst, "ecbs", highways="crisscross", w_hwy=0.5)
    with pytest.raises(OptionError, match="sum of costs only"):
        hp.solve(inst, "cbs", highways="crisscross", cost="makespan")
    with pytest.raises(OptionError, match="unknown option|does not know|highways"):
        hp.solve(inst, "cbm", highways="crisscross")


def test_cbs_names_itself_when_the_instance_has_no_highways() -> None:
    # cbs hands highways to ecbs through the registry; the error still names cbs.
    inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    with pytest.raises(OptionError, match="^cbs option highways='instance'"):
        hp.solve(inst, "cbs", highways="instance")


@pytest.mark.parametrize("mode", ["heuristic", "cost"])
def test_cbs_with_highways_is_ecbs_1_with_the_highway_low_level(mode: str) -> None:
    # CBS+HWY(w_hwy) runs ECBS(1)+HWY(w_hwy) with CBS's bypass and no polish: the same
    # plan and counts as asking ecbs for that directly.
    inst = load_instance(DATA / "corridor-5x20.map", scen=DATA / "corridor-5x20.scen")
    inst = replace(inst, highways=load_highways(DATA / "corridor-5x20.hwy", inst.graph))
    opts = {"highways": "instance", "w_hwy": 2.0, "hwy_mode": mode}
    a = hp.solve(inst, "cbs", time_limit=None, **opts)
    b = hp.solve(
        inst, "ecbs", time_limit=None, w=1.0, polish=False, lacam="off", bypass=True, **opts
    )
    assert a.plan == b.plan and a.cost == b.cost and a.lower_bound == b.lower_bound
    counts = ("high_level_expanded", "high_level_generated", "low_level_expanded", "bypasses")
    assert [a.stats[k] for k in counts] == [b.stats[k] for k in counts]
    assert a.stats["hwy_mode"] == mode and a.stats["bound"] == 2.0


def test_highway_low_level_imports_no_solver() -> None:
    # The low level sits below the high levels: search/highways.py imports none of them.
    tree = ast.parse(Path(search_highways.__file__).read_text())
    names = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    solvers = {f"hierplan_opt.search.{m}" for m in ("cbs", "ecbs", "eecbs", "lacam")}
    assert names & solvers == set()
    assert not any((m or "").startswith("hierplan_opt.formulations") for m in names)


def test_head_on_conflicts_are_counted() -> None:
    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    inst = Instance.mapf(g, [(0, 0), (4, 0)], [(4, 0), (0, 0)])
    r = hp.solve(inst, "ecbs", w=1.0)
    assert r.plan is not None and r.stats["head_on_conflicts"] >= 1


# ---------------------------------------------------------------- learned highways
def test_min_cut_is_the_exact_map_assignment() -> None:
    rng = np.random.default_rng(0)
    for _ in range(30):
        m = int(rng.integers(1, 7))
        unary = rng.integers(0, 5, size=(m, 2)).astype(float)
        pairs = [
            (i, j, float(rng.integers(0, 4)))
            for i, j in itertools.combinations(range(m), 2)
            if rng.random() < 0.5
        ]
        _, energy = min_cut_labels(unary, pairs)
        best = min(
            sum(unary[i, x[i]] for i in range(m)) + sum(c for i, j, c in pairs if x[i] != x[j])
            for x in itertools.product((0, 1), repeat=m)
        )
        assert energy == pytest.approx(best)


def test_traffic_is_one_unit_per_agent_step() -> None:
    inst = random_instance(random.Random(5), 6, 5, 4, 0.1)
    t = traffic(inst)
    g = inst.graph
    total = sum(g.dist(s, x) for s, x in zip(inst.starts, inst.goals, strict=True))
    assert sum(t.values()) == pytest.approx(total)


def test_learned_highways_follow_the_traffic() -> None:
    inst = load_instance(DATA / "kiva-22x54.map", scen=DATA / "kiva-22x54-seed0.scen")
    t = traffic(inst)
    for hw in (learned(inst), flow(inst)):
        # reversing every edge keeps the pairwise terms and swaps the unary ones, so
        # the MAP drives with at least as much traffic as against it
        with_t = sum(t.get(e, 0.0) for e in hw)
        against = sum(t.get((v, u), 0.0) for u, v in hw)
        assert with_t >= against > 0
        check_highways(inst.graph, hw)
        assert not any((v, u) in hw for u, v in hw)


# ---------------------------------------------------------------- CLI and files
def run_cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = cli_main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_highways(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    m, s = str(DATA / "corridor-5x20.map"), str(DATA / "corridor-5x20.scen")
    code, out, err = run_cli(
        capsys, "solve", m, "--scen", s, "--solver", "cbs", "--highways",
        str(DATA / "corridor-5x20.hwy"), "--w-hwy", "2", "--out", str(tmp_path / "p.yaml"),
    )  # fmt: skip
    assert code == 0, err
    assert out.startswith("FEASIBLE") and (tmp_path / "p.yaml").exists()
    code, out, err = run_cli(
        capsys, "solve", m, "--scen", s, "--solver", "cbm", "--highways", "learned"
    )
    assert code == 2 and err.strip() == (
        "hierplan solve: error: solver 'cbm' does not take highways (use cbs, ecbs or eecbs)"
    )
    code, out, err = run_cli(capsys, "solve", m, "--scen", s, "--solver", "ecbs", "--w-hwy", "2")
    assert code == 2 and "--w-hwy needs --highways" in err
    bad = tmp_path / "bad.highway"
    bad.write_text("r\n")
    code, out, err = run_cli(
        capsys, "solve", m, "--scen", s, "--solver", "ecbs", "--highways", str(bad)
    )
    assert code == 2 and "the highway grid has 1 rows, the map has 5" in err
    assert len(err.strip().splitlines()) == 1


def test_generator_reproduces_files(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("hwy_generate", DATA / "generate.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    for name, text in mod.files().items():
        assert (DATA / name).read_text() == text, name
