"""Honest outcomes of executions (issue 30, item 4): who is at a goal of its own, why
the others are not, broken robots as physical obstacles, counts that equal the events,
and the exit code of a run that leaves a working robot away from its goal."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.execution import Breakdown, RandomDelays, Stop, simulate
from hierplan_opt.execution.simulate import DISTURBANCE_KINDS
from hierplan_opt.io import load_instance
from hierplan_opt.schedule import postprocess
from hierplan_opt.schedule.replay import _pair_min

ROOT = Path(__file__).resolve().parent.parent
WAREHOUSE = str(ROOT / "instances" / "paper" / "warehouse-part1.yaml")
DISTURBANCES = str(ROOT / "instances" / "paper" / "warehouse-disturbances.yaml")
MAP = ROOT / "instances" / "movingai" / "warehouse-10-20-10-2-1.map"
SCEN = ROOT / "instances" / "movingai" / "warehouse-10-20-10-2-1-even-1.scen"


def closest_pair(ex, radius) -> tuple[float, int]:
    """Independent check: the smallest gap ``d - r_i - r_j`` over every pair of executed
    trajectories (piecewise linear in time, exact), and how many pairs touched."""
    tr = ex.trajectories
    worst, touching = np.inf, 0
    for a in range(len(tr)):
        for b in range(a + 1, len(tr)):
            d, _ = _pair_min(tr[a][:, 0], tr[a][:, 1:], tr[b][:, 0], tr[b][:, 1:])
            gap = d - radius[a] - radius[b]
            worst = min(worst, gap)
            if gap < -1e-9 or d <= 1e-9:
                touching += 1
    return worst, touching


def corridor() -> tuple[hp.Instance, object]:
    """7x3 corridor: agent1 sits on agent0's straight path and leaves it sideways."""
    g = hp.Graph.grid(7, 3)
    inst = hp.Instance.mapf(g, [(0, 1), (3, 1)], [(6, 1), (3, 2)])
    res = hp.solve(inst, "cbs")
    assert res.plan is not None and res.plan.paths[0] == (7, 8, 9, 10, 11, 12, 13)
    return inst, postprocess(inst, res.plan)


@pytest.mark.parametrize("policy", ["slack", "stn", "replan", "reorder", "adg"])
def test_robot_never_drives_through_a_robot_broken_on_its_path(policy: str) -> None:
    inst, s = corridor()
    ex = simulate(inst, s, disturbances=[Breakdown("agent1", at_time=0.0)], policy=policy)
    st = ex.statistics
    gap, touching = closest_pair(ex, [0.0, 0.0])
    assert touching == 0 and gap > 0 and st["collisions"] == 0 and st["min_distance"] > 0
    assert st["broken"] == ["agent1"]
    if policy in ("replan", "reorder"):  # it drives around
        assert st["replans"] == 1 and st["finished"] == 1 and st["stranded"] == []
        assert np.allclose(ex.trajectories[0][-1, 1:], [6, 1])
    else:  # it waits: not at its goal, and the report says so
        assert st["stranded"] == ["agent0"] and st["finished"] == 0
        assert "blocked" in st["why_unfinished"]["agent0"]
        assert np.isnan(st["makespan"])


def test_breakdown_blocks_the_cells_the_robot_covers_not_its_claimed_vertex() -> None:
    from hierplan_opt.execution.replan import footprint_vertices

    g = hp.Graph.grid(5, 3)
    # A robot of radius 0.35 standing 0.9 m from a vertex leaves it to robots of 0.3.
    p = np.array([2.1, 1.0])
    covered = set(footprint_vertices(g, p, 0.35 + 0.3).tolist())
    assert covered == {g.vertex((2, 1))}
    # A point robot mid-edge closes the edge (one end), a point robot at a vertex that vertex.
    assert len(footprint_vertices(g, np.array([2.5, 1.0]), 0.0)) == 1
    assert footprint_vertices(g, np.array([2.0, 1.0]), 0.0).tolist() == [g.vertex((2, 1))]


def test_substituted_goal_is_reported_as_such() -> None:
    # agent1 crosses agent0's goal and breaks down on it: agent0 cannot get there.
    g = hp.Graph.grid(5, 3)
    inst = hp.Instance.mapf(g, [(0, 1), (2, 0)], [(4, 1), (2, 1)])
    inst = hp.Instance(g, (inst.agents[1], inst.agents[0]))  # agent1 crosses first
    res = hp.solve(inst, "cbs")
    assert res.plan is not None
    s = postprocess(inst, res.plan)
    crosser = inst.agents[1].name
    t_at = float(s.times[s.stn.tpg.agent_ptr[1] + 2]) if s.stn is not None else 0.0
    ex = simulate(inst, s, disturbances=[Breakdown(crosser, at_time=t_at)])
    st = ex.statistics
    where = ex.trajectories[1][-1, 1:]
    assert np.allclose(where, [2, 1]), where  # it broke down on the other's goal
    victim = inst.agents[0].name
    assert st["finished"] == 0 and st["stranded"] == [victim]
    assert victim in st["substituted"] and "substituted" in st["why_unfinished"][victim]
    assert any(e.kind == "goal" for e in ex.log)
    assert st["collisions"] == 0


def test_readme_main_job_tells_its_outcome_truthfully(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.yaml"
    code = main(
        ["run", WAREHOUSE, "--solver", "cbm", "--disturbances", DISTURBANCES, "--out", str(out)]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    assert "11/12 robots at their own goals; 1 broke down (youbot8); 0 collisions" in text
    data = yaml.safe_load(out.read_text())
    st, events = data["statistics"], data["events"]
    # Independent check: every working robot ends on a target of its team.
    inst = load_instance(WAREHOUSE)
    g = inst.graph
    for a in inst.agents:
        last = data["schedule"][a.name][-1]
        p = np.array([last["x"], last["y"]])
        targets = inst.teams[a.team].targets if a.goal is None else (a.goal,)
        at = any(np.allclose(g.coords[v], p) for v in targets)
        assert at == (a.name != "youbot8"), (a.name, p)
    # Every count equals what the events show.
    dist = [e for e in events if e["kind"] in DISTURBANCE_KINDS]
    assert st["disturbances"] == len(dist)
    assert st["handled"] == {
        k: sum(e["layer"] == k for e in dist) for k in ("slack", "stn", "replan", "reorder", "none")
    }
    assert st["replans"] == sum(e["kind"] == "replan" and e["layer"] == "replan" for e in events)
    assert st["unfinished"] == ["youbot8"] and st["broken"] == ["youbot8"]
    assert st["stranded"] == [] and st["substituted"] == []


def test_run_with_a_stranded_working_robot_exits_5(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    inst = tmp_path / "corridor.yaml"
    inst.write_text(
        "format: hierplan/1\nname: corridor\n"
        'graph: {type: grid, rows: [".......", ".......", "......."]}\n'
        "agents:\n  - {name: a, start: [0, 1], goal: [6, 1]}\n"
        "  - {name: b, start: [3, 1], goal: [3, 2]}\n"
    )
    dist = tmp_path / "d.yaml"
    dist.write_text("disturbances:\n  - {kind: breakdown, agent: b, at_time: 0.0}\n")
    argv = ["run", str(inst), "--disturbances", str(dist)]
    assert main([*argv, "--policy", "replan"]) == 0
    text = capsys.readouterr().out
    assert "1/2 robots at their own goals; 1 broke down (b); 0 collisions" in text
    assert main([*argv, "--policy", "stn"]) == 5  # a waits behind b for good
    text = capsys.readouterr().out
    assert "FAILED: 1 working robot(s) not at their goals (a)" in text
    assert "makespan not reached" in text


@pytest.fixture(scope="module")
def warehouse50() -> tuple[hp.Instance, object]:
    inst = load_instance(MAP, scen=SCEN, agents=50)
    res = hp.solve(inst, "ecbs", time_limit=60)
    assert res.plan is not None
    return inst, postprocess(inst, res.plan)


@pytest.mark.parametrize("seed", [0, 1])
def test_warehouse_50_delays_and_breakdowns_no_pair_meets(warehouse50, seed: int) -> None:
    inst, s = warehouse50
    dist = [
        RandomDelays(0.1, "exponential", 2.0, seed=seed),
        Breakdown(f"agent{3 + seed}", at_time=5.0 + seed),
        Breakdown(f"agent{30 + seed}", at_time=8.0 + seed),
        Stop(f"agent{11 + seed}", 10.0, at_time=3.0),
    ]
    ex = simulate(inst, s, disturbances=dist)
    st = ex.statistics
    gap, touching = closest_pair(ex, np.zeros(inst.num_agents))
    assert touching == 0 and st["collisions"] == 0, (touching, st["collisions"])
    assert not [e for e in ex.log if e.kind == "replan" and e.layer == "none"], [
        e.detail for e in ex.log if e.kind == "replan"
    ]
    assert st["stranded"] == [] and st["finished"] == inst.num_agents - 2
    dist_events = [e for e in ex.log if e.kind in DISTURBANCE_KINDS]
    assert st["disturbances"] == len(dist_events)
    assert dict(Counter(e.layer for e in dist_events)) == {
        k: v for k, v in st["handled"].items() if v
    }
    assert st["replans"] == sum(e.kind == "replan" and e.layer == "replan" for e in ex.log)


def test_library_run_is_the_whole_hierarchy() -> None:
    from hierplan_opt.execution import Stop

    inst = hp.Instance.mapf(hp.Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    r = hp.run(inst, "cbs", disturbances=[Stop("agent0", 1.5, at_time=0.5)], margin=0)
    assert r.ok and r.result.cost == 4 and r.schedule is not None
    assert r.execution is not None and r.execution.statistics["finished"] == 2
    assert set(r.times) >= {"solve", "post", "simulate", "total"}
    assert hp.simulate is simulate


def test_run_passes_solver_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inst = tmp_path / "corridor.yaml"
    inst.write_text(
        "format: hierplan/1\nname: corridor\n"
        'graph: {type: grid, rows: [".......", ".......", "......."]}\n'
        "agents:\n  - {name: a, start: [0, 1], goal: [6, 1]}\n"
        "  - {name: b, start: [3, 1], goal: [3, 2]}\n"
    )
    assert main(["run", str(inst), "--solver", "ecbs", "--set", "w=1.2"]) == 0
    assert "plan: ecbs" in capsys.readouterr().out
    assert main(["run", str(inst), "--solver", "ecbs", "--set", "nonsense=1"]) == 2
    err = capsys.readouterr().err
    assert "nonsense" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
