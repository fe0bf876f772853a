"""The overview paper's example instances in instances/paper/ (files and solutions)."""

from __future__ import annotations

from pathlib import Path

import pytest

import hierplan_opt as hp
from hierplan_opt import Status, validate
from hierplan_opt.io import load_instance, load_plan

PAPER = Path(__file__).resolve().parent.parent / "instances" / "paper"
NAMES = ["figure3", "warehouse-part1", "warehouse-part2", "formation-usc"]


def load(name: str) -> hp.Instance:
    return load_instance(PAPER / f"{name}.yaml")


@pytest.mark.parametrize("name", NAMES)
def test_cbm_solves_every_paper_instance(name: str) -> None:
    inst = load(name)
    assert inst.is_tapf
    r = hp.solve(inst, "cbm", time_limit=60)
    assert r.status == Status.OPTIMAL
    assert r.cost == r.lower_bound
    assert not validate(inst, r.plan)
    for team in inst.teams:
        assert sorted(r.plan.paths[i][-1] for i in team.agents) == sorted(team.targets)


def test_figure3_file() -> None:
    inst = load("figure3")
    g = inst.graph
    assert [t.name for t in inst.teams] == ["team1", "team2"]
    assert [g.location(a.start) for a in inst.agents] == ["A", "E", "F"]
    assert sorted(g.location(t) for t in inst.teams[1].targets) == ["D", "I"]
    r = hp.solve(inst, "cbm")
    assert r.cost == 4 == r.lower_bound
    # The paper's own plan is valid on the file's graph.
    table = [list("ABFGH"), list("EFGHI"), list("FGHCD")]
    plan = hp.Plan.from_paths([[g.vertex(x) for x in row] for row in table])
    assert not validate(inst, plan)


def test_warehouse_files() -> None:
    p1, p2 = load("warehouse-part1"), load("warehouse-part2")
    assert [len(t.agents) for t in p1.teams] == [10, 2]
    types = {a.kinematics.robot_type for a in p1.agents}
    assert types == {"youbot", "pioneer"}
    for team in p1.teams:
        assert len({p1.agents[i].kinematics.robot_type for i in team.agents}) == 1
    pioneers = [a for a in p1.agents if a.kinematics.robot_type == "pioneer"]
    assert all(a.kinematics.drive == "differential" for a in pioneers)
    assert all(a.kinematics.drive == "omni" for a in p1.agents if a not in pioneers)
    assert len(p2.teams) == 4 and p2.num_agents == 12
    # Part 2 starts where part 1 ends: the pick-up locations.
    assert set(p2.starts) == {t for team in p1.teams for t in team.targets}
    # Red/blue deliver on the left wall (x = 0), green/yellow on the right wall.
    g = p2.graph
    width = g.shape[0]
    for team in p2.teams:
        xs = {g.location(t)[0] for t in team.targets}
        assert xs == ({0} if team.name in ("red", "blue") else {width - 1})
    assert p1.highways and p2.highways


def test_formation_file_flow_and_cbm_agree() -> None:
    inst = load("formation-usc")
    assert len(inst.teams) == 1 and inst.num_agents == 32
    assert inst.graph.dim == 3
    a = hp.solve(inst, "cbm", time_limit=60)
    b = hp.solve(inst, "flow", time_limit=60)
    assert a.status == b.status == Status.OPTIMAL
    assert a.cost == b.cost
    assert not validate(inst, b.plan)
    # Everybody starts inside the building (y >= 6) and ends in the letter plane.
    g = inst.graph
    assert all(g.location(s)[1] >= 6 for s in inst.starts)
    assert {g.location(t)[1] for t in inst.teams[0].targets} == {1}


def test_cli_solve_writes_plan(tmp_path: Path) -> None:
    from hierplan_opt.cli import main

    out = tmp_path / "plan.yaml"
    code = main(["-q", "solve", str(PAPER / "figure3.yaml"), "--solver", "cbm", "--out", str(out)])
    assert code == 0
    inst = load("figure3")
    plan = load_plan(out, inst)
    assert not validate(inst, plan)
    assert plan.makespan == 4


def test_generator_reproduces_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("paper_generate", PAPER / "generate.py")
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    monkeypatch.setattr(mod, "HERE", tmp_path)
    mod.main()
    for name in NAMES:
        assert (tmp_path / f"{name}.yaml").read_text() == (PAPER / f"{name}.yaml").read_text()


@pytest.mark.parametrize("name", ["warehouse-part1", "warehouse-part2", "formation-usc"])
def test_paper_schedules_keep_the_robots_apart(name: str) -> None:
    # Issue 9 item 1: the robots' radii are the contract. youBots (radius 0.35 m) keep
    # 0.7 m between centres, Pioneers (0.3 m) 0.6 m, a youBot and a Pioneer 0.65 m, on
    # the 1 m cells of the warehouse (2 * 0.35 < 1: the tight claims fit).
    from hierplan_opt.schedule import check_bounds, postprocess, replay

    inst = load(name)
    r = hp.solve(inst, "cbm", time_limit=60)
    assert r.plan is not None
    radius = {a.kinematics.robot_type: a.kinematics.radius for a in inst.agents}
    for objective, method in (("makespan", "graph"), ("safety", "lp")):
        s = postprocess(inst, r.plan, objective, method=method)
        assert s.stats["regime"] == "tight"
        assert check_bounds(s.stn, s.times) == []
        rep = replay(s, inst, all_pairs=True)
        assert rep.ok
        for c in s.clearance:
            assert c.guaranteed
            assert c.required == pytest.approx(radius[c.types[0]] + radius[c.types[1]])
            if c.types in rep.by_type:
                assert rep.by_type[c.types][0] >= c.required - 1e-9
        # Every robot needs at least its drive at full speed (1 m cells).
        for j, (a, path) in enumerate(zip(inst.agents, r.plan.paths, strict=True)):
            moves = sum(u != v for u, v in zip(path[:-1], path[1:], strict=True))
            assert s.arrival_times(j)[-1] >= moves / a.kinematics.v_max - 1e-9


def test_cli_post_checks_the_warehouse(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The reproducer: `hierplan post warehouse-part2 ... --check` reported "(ok)"
    # with robot centres 0.066 m apart; now the check compares with r_i + r_j.
    from hierplan_opt.cli import main

    plan = tmp_path / "plan.yaml"
    out = tmp_path / "s.yaml"
    wh = str(PAPER / "warehouse-part2.yaml")
    assert main(["-q", "solve", wh, "--solver", "cbm", "--out", str(plan)]) == 0
    capsys.readouterr()
    assert main(["post", wh, str(plan), "--out", str(out), "--check"]) == 0
    line = capsys.readouterr().out
    assert "youbot/youbot 0.7 m" in line and "guaranteed" in line and "(ok)" in line
    gap = float(line.split("worst pair vs required ")[1].split(" m")[0])
    assert gap >= 0
