"""libMultiRobotPlanning's own test instances (``tests/data/lmrp``, MIT, copied from
whoenig/libMultiRobotPlanning ``test/``) with the costs its tests expect, and the three
variants its tests exercise: task-free robots, agents that disappear at their goals,
annotated roadmaps' extra conflicts (issue 34)."""

from __future__ import annotations

import heapq
from pathlib import Path

import pytest

import hierplan_opt as hp
from hierplan_opt.cli import main

LMRP = Path(__file__).resolve().parent / "data" / "lmrp"


def load(name: str, **kw) -> hp.Instance:
    return hp.load_instance(LMRP / f"{name}.yaml", **kw)


# ----------------------------------------------------- test_cbs.py, test_cbs_roadmap.py
@pytest.mark.parametrize(
    ("name", "cost"),
    [
        ("mapf_simple1", 8),
        ("mapf_circle", 4),
        ("mapf_atGoal", 0),
        ("mapf_simple1_roadmap", 8),
        ("mapf_circle_roadmap", 4),
        ("mapf_atGoal_roadmap", 0),
        ("issue28", 8),  # test_ecbs/test_cbs run it with --disappear-at-goal: also 8
        ("mapf_swap2", 12),
        ("mapf_swap4", 28),
    ],
)
@pytest.mark.parametrize("solver", ["cbs", "ecbs"])
def test_expected_costs(name: str, cost: int, solver: str) -> None:
    inst = load(name)
    opts = {"w": 1.0} if solver == "ecbs" else {}
    res = hp.solve(inst, solver, time_limit=30, **opts)
    assert res.solved and res.cost == cost and hp.validate(inst, res.plan) == []


@pytest.mark.parametrize("name", ["mapf_crossover_roadmap", "issue33", "issue33_annotated"])
def test_instances_libmrp_times_out_on_are_proven_infeasible(name: str) -> None:
    # libMRP's tests expect a time-out (crossover) or success: false (issue33)
    res = hp.solve(load(name), "cbs" if "annotated" not in name else "cpsat", time_limit=10)
    assert res.status is hp.Status.INFEASIBLE and res.plan is None


@pytest.mark.parametrize("name", ["mapf_someAtGoal", "mapf_someAtGoal_roadmap", "issue30"])
def test_shared_goals_and_starts_are_refused_as_bad_input(name: str) -> None:
    # two agents with one goal (libMRP: "impossible ... a timeout is expected"), or one start
    with pytest.raises(hp.InputError, match="has the same (goal|start)"):
        load(name)


# ------------------------------------------------------ --disappear-at-goal (test_cbs.py)
@pytest.mark.parametrize(
    ("name", "cost"),
    [
        ("mapf_someAtGoal", 1),
        ("mapf_someAtGoal_roadmap", 1),
        ("mapf_crossover_roadmap", 6),  # test_cbs_roadmap.test_crossover_disappearingAgents
        ("issue28", 8),
    ],
)
@pytest.mark.parametrize("solver", ["cbs", "ecbs"])
def test_disappear_at_goal(name: str, cost: int, solver: str) -> None:
    from hierplan_opt.search.libmrp import disappear_at_goals, from_disappeared

    inst = load(name, shared_goals=True)
    red = disappear_at_goals(inst)
    opts = {"w": 1.0} if solver == "ecbs" else {}
    res = hp.solve(red, solver, time_limit=30, **opts)
    assert res.solved and hp.validate(red, res.plan) == []
    back = from_disappeared(inst, res)
    assert back.cost == cost == back.plan.sum_of_costs
    assert [p[-1] for p in back.plan.paths] == [a.goal for a in inst.agents]


def test_disappear_at_goal_cli(tmp_path, capsys) -> None:
    out = tmp_path / "plan.yaml"
    args = ["solve", str(LMRP / "mapf_someAtGoal.yaml"), "--disappear-at-goal"]
    assert main([*args, "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert line.startswith("OPTIMAL cost=1 ") and "disappear_at_goal=true" in line
    import yaml

    sched = yaml.safe_load(out.read_text())["schedule"]
    assert sched["agent0"] == [{"x": 4, "y": 0, "t": 0}]
    assert sched["agent1"][-1] == {"x": 4, "y": 0, "t": 1}


# ------------------------------------------------------- task-free robots (test_cbs_ta.py)
@pytest.mark.parametrize(
    ("name", "cost", "end0", "end1"),
    [
        ("mapfta_simple1_a2", 6, (4, 0, 4), (2, 1, None)),
        ("mapfta_simple1_a3", 5, (3, 0, 3), (None, None, None)),
    ],
)
@pytest.mark.parametrize("solver", ["cbs", "cpsat"])
def test_task_free_robots(name, cost, end0, end1, solver) -> None:
    inst = load(name)
    assert inst.meta["free_agents"] == ["agent1"]
    res = hp.solve(inst, solver, time_limit=30, cost="soc")
    assert res.status is hp.Status.OPTIMAL and res.cost == cost
    g = inst.graph
    for path, end in zip(res.plan.paths, (end0, end1), strict=True):
        x, y, t = end
        if x is not None:
            assert list(g.location(path[-1])) == [x, y]
        if t is not None:
            assert len(path) - 1 == t


def test_mapfta_a1_soc_matches_cbs_ta() -> None:
    res = hp.solve(load("mapfta_simple1_a1"), "cpsat", cost="soc", time_limit=30)
    assert res.status is hp.Status.OPTIMAL and res.cost == 6


def test_task_free_robot_in_the_cli_picks_cbs(capsys) -> None:
    assert main(["solve", str(LMRP / "mapfta_simple1_a3.yaml")]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("OPTIMAL cost=5 ") and "solver=cbs" in out and "free_agents=1" in out


# ------------------------------------------------------------------ annotated roadmaps
def test_annotated_unit_roadmap_has_no_extra_conflicts() -> None:
    # annotate_roadmap.py (radius 0.3) on mapf_simple1_roadmap_to_annotate: every listed
    # conflict is a vertex or swap conflict, so any solver answers libMRP's cost 8
    inst = load("mapf_simple1_roadmap_annotated")
    assert inst.meta["annotated_conflicts"] == 35 and inst.meta["edge_conflicts"] == []
    assert hp.solve(inst, "cbs", time_limit=10).cost == 8


@pytest.mark.parametrize("solver", ["cpsat", "mip"])
def test_crossing_edges_of_an_annotated_roadmap(solver) -> None:
    # Two diagonals cross at their middles: annotate_roadmap.py (radius 0.3) lists them
    # as conflicting; without the annotation both robots cross at once (soc 2).
    plain = load("hierplan_cross")
    assert hp.solve(plain, "cbs", time_limit=10).cost == 2
    inst = load("hierplan_cross_annotated")
    assert len(inst.meta["edge_conflicts"]) == 4
    for objective, cost in (("soc", 3), ("makespan", 2)):
        res = hp.solve(inst, solver, cost=objective, time_limit=30)
        assert res.status is hp.Status.OPTIMAL and res.cost == cost
    with pytest.raises(hp.OptionError, match="knows vertex and swap conflicts only"):
        hp.solve(inst, "cbs")


def joint_optimum(inst: hp.Instance) -> int | None:
    """Independent optimal sum of costs with extra conflicts: Dijkstra over (positions,
    done flags); a done robot stays (its wait is a move that can conflict)."""
    g = inst.graph
    clash = set()
    for m1, m2 in inst.meta["edge_conflicts"]:
        clash |= {(tuple(m1), tuple(m2)), (tuple(m2), tuple(m1))}
    goals = tuple(a.goal for a in inst.agents)
    k = len(goals)
    start = (tuple(a.start for a in inst.agents), (False,) * k)
    dist = {start: 0}
    heap = [(0, start)]
    while heap:
        d, (pos, done) = heapq.heappop(heap)
        if all(done):
            return d
        if d > dist[(pos, done)]:
            continue
        # each robot: done ones wait; others wait, move, or finish (if at goal)
        options = []
        for i in range(k):
            if done[i]:
                options.append([(pos[i], True)])
            else:
                opts = [(pos[i], False), *[(int(v), False) for v in g.neighbors(pos[i])]]
                if pos[i] == goals[i]:
                    opts.append((pos[i], True))
                options.append(opts)
        import itertools

        for choice in itertools.product(*options):
            nxt = tuple(v for v, _ in choice)
            if len(set(nxt)) < k:
                continue
            moves = list(zip(pos, nxt, strict=True))
            bad = any(
                (moves[i][0] == moves[j][1] and moves[i][1] == moves[j][0] and nxt[i] != pos[i])
                or (moves[i], moves[j]) in clash
                for i in range(k)
                for j in range(i + 1, k)
            )
            if bad:
                continue
            # finishing now means staying put from this step on, at no further cost
            nd = tuple(f for _, f in choice)
            cost = d + sum(1 for i in range(k) if not nd[i])
            key = (nxt, nd)
            if cost < dist.get(key, 1 << 30):
                dist[key] = cost
                heapq.heappush(heap, (cost, key))
    return None


@pytest.mark.parametrize("solver", ["cpsat", "mip"])
def test_annotated_conflict_with_a_parked_robot(solver) -> None:
    # A robot parked at A may not wait there while another moves B -> C (an annotation
    # written by hand): the formulations fix those arcs after A's deadline.
    g = hp.Graph.roadmap(
        {"A": (0, 0), "B": (1, 0), "C": (2, 0), "D": (1, 1), "E": (0, 1)},
        [("A", "B"), ("B", "C"), ("B", "D"), ("D", "E"), ("E", "A")],
    )
    inst = hp.Instance.mapf(g, ["B", "D"], ["A", "C"])
    inst.meta["edge_conflicts"] = [((g.vertex("A"), g.vertex("A")), (g.vertex("B"), g.vertex("C")))]
    from hierplan_opt.search.libmrp import annotated_violations

    best = joint_optimum(inst)
    plain = hp.solve(hp.Instance.mapf(g, ["B", "D"], ["A", "C"]), "cbs", time_limit=10)
    assert plain.cost == 3 and annotated_violations(inst, plain.plan)  # the plain plan clashes
    res = hp.solve(inst, solver, cost="soc", time_limit=30)
    assert res.status is hp.Status.OPTIMAL and res.cost == best and best > 3
    assert annotated_violations(inst, res.plan) == []


def test_validate_checks_the_variants(tmp_path, capsys) -> None:
    def solve_and_validate(name: str, *flags: str) -> tuple[int, str]:
        out = tmp_path / f"{name}.yaml"
        assert main(["solve", str(LMRP / f"{name}.yaml"), *flags, "--out", str(out)]) == 0
        capsys.readouterr()
        code = main(["validate", str(LMRP / f"{name}.yaml"), str(out), *flags])
        return code, capsys.readouterr().out

    assert solve_and_validate("mapf_someAtGoal", "--disappear-at-goal") == (
        0,
        "valid: soc=1 makespan=1 agents=2 (lower bounds: soc>=1, makespan>=1)\n",
    )
    code, out = solve_and_validate("mapfta_simple1_a2")  # the free robot ends in the pocket
    assert code == 0 and out.startswith("valid: soc=6")
    code, out = solve_and_validate("hierplan_cross_annotated")
    assert code == 0 and out.startswith("valid: soc=3")
    # the plain crossing plan breaks the annotation
    plain = tmp_path / "plain.yaml"
    assert main(["solve", str(LMRP / "hierplan_cross.yaml"), "--out", str(plain)]) == 0
    capsys.readouterr()
    assert main(["validate", str(LMRP / "hierplan_cross_annotated.yaml"), str(plain)]) == 1
    assert "(annotated conflict)" in capsys.readouterr().out


def test_task_free_robot_in_the_hierplan_format_and_round_trips(tmp_path) -> None:
    text = (
        "format: hierplan/1\nname: free\n"
        "graph: {type: grid, dimensions: [5, 2], obstacles: [[0, 1], [1, 1], [3, 1], [4, 1]]}\n"
        "agents:\n  - {name: a, start: [0, 0], goal: [3, 0]}\n  - {name: b, start: [1, 0]}\n"
    )
    (tmp_path / "free.yaml").write_text(text)
    inst = hp.load_instance(tmp_path / "free.yaml")
    assert not inst.is_tapf and inst.meta["free_agents"] == ["b"]
    res = hp.solve(inst, "cbs", time_limit=10)
    assert res.status is hp.Status.OPTIMAL and res.cost == 5  # as mapfta_simple1_a3
    for fmt in ("hierplan", "lmrp"):
        hp.save_instance(tmp_path / f"{fmt}.yaml", inst, format=fmt)
        back = hp.load_instance(tmp_path / f"{fmt}.yaml")
        assert back.meta["free_agents"] == ["b"]
        assert hp.solve(back, "cbs", time_limit=10).cost == 5
