"""MAPF-POST: TPG, STN and graph schedules against hand-computed answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hierplan_opt import Graph, InputError, Instance, Kinematics, OptionError, Plan
from hierplan_opt.schedule import (
    InconsistentSTNError,
    accel_time,
    build_stn,
    build_tpg,
    check_bounds,
    postprocess,
    solve_graph,
)
from hierplan_opt.schedule.tpg import ENTER, LEAVE, TYPE2, VERTEX

# A plus-shaped map: the centre (1, 1) is the only crossing.
#        (1,2)
#  (0,1) (1,1) (2,1)
#        (1,0)
PLUS = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])


def plus_instance(kinematics=None) -> tuple[Instance, Plan]:  # noqa: ANN001
    """agent0 crosses west->east at t=1; agent1 waits, then crosses south->north at t=2."""
    v = PLUS.vertex
    inst = Instance.mapf(PLUS, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=kinematics)
    plan = Plan.from_paths(
        [[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]]
    )
    return inst, plan


# ---------------------------------------------------------------------- TPG
def test_plain_tpg_structure() -> None:
    inst, plan = plus_instance()
    tpg = build_tpg(inst, plan)
    # Waits merged: agent1 has 3 nodes, not 4.
    assert tpg.agent_ptr.tolist() == [0, 3, 6]
    assert tpg.num_type2 == 1
    k = int(np.flatnonzero(tpg.arc_type == TYPE2)[0])
    # agent0 entering (2, 1) precedes agent1 entering (1, 1).
    assert tpg.label(int(tpg.arc_src[k])) == "agent0 at (2, 1)"
    assert tpg.label(int(tpg.arc_dst[k])) == "agent1 at (1, 1)"


def test_augmented_tpg_keeps_only_markers_with_precedences() -> None:
    inst, plan = plus_instance()
    tpg = build_tpg(inst, plan, delta=0.25)
    kinds = tpg.node_kind.tolist()
    assert kinds.count(VERTEX) == 6
    assert kinds.count(LEAVE) == 1 and kinds.count(ENTER) == 1
    k = int(np.flatnonzero(tpg.arc_type == TYPE2)[0])
    u, w = int(tpg.arc_src[k]), int(tpg.arc_dst[k])
    assert tpg.label(u) == "agent0 0.25 past (1, 1)"
    assert tpg.label(w) == "agent1 0.25 before (1, 1)"
    assert tpg.node_coord[u].tolist() == [1.25, 1.0]
    assert tpg.node_coord[w].tolist() == [1.0, 0.75]


def test_first_later_visit_suffices() -> None:
    # Three robots pass (1, 0) of a corridor one after the other: two Type-2 arcs
    # (consecutive visitors), not three.
    g = Graph.grid(4, 2)
    v = g.vertex
    inst = Instance.mapf(g, [(0, 0), (0, 1), (1, 1)], [(3, 0), (2, 1), (2, 0)])
    plan = Plan.from_paths(
        [
            [v((0, 0)), v((1, 0)), v((2, 0)), v((3, 0))],
            [v((0, 1)), v((0, 1)), v((0, 1)), v((1, 1)), v((2, 1))],
            [v((1, 1)), v((1, 1)), v((1, 0)), v((1, 0)), v((2, 0))],
        ]
    )
    from hierplan_opt import validate

    assert validate(inst, plan) == []
    tpg = build_tpg(inst, plan)
    pairs = sorted(
        (tpg.label(int(a)), tpg.label(int(b)))
        for a, b, t in zip(tpg.arc_src, tpg.arc_dst, tpg.arc_type, strict=True)
        if t == TYPE2
    )
    assert ("agent0 at (2, 0)", "agent2 at (1, 0)") in pairs
    assert ("agent2 at (1, 0)", "agent1 at (1, 1)") in pairs  # agent2 left (1, 1)
    assert ("agent0 at (3, 0)", "agent2 at (2, 0)") in pairs
    assert len(pairs) == 3


# ---------------------------------------------------------------------- hand-computed
def test_two_robots_through_one_vertex_plain() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, delta=0)
    # agent0 at full speed: 0, 1, 2. agent1 may enter (1, 1) only when agent0 has
    # entered (2, 1) at t = 2, then needs 1 s to (1, 2).
    assert s.arrival_times("agent0").tolist() == [0.0, 1.0, 2.0]
    assert s.arrival_times("agent1").tolist() == [0.0, 2.0, 3.0]
    assert s.makespan == 3.0 and s.flowtime == 5.0
    assert s.safety_distance == 0.0  # the plain TPG guarantees nothing


def test_two_robots_through_one_vertex_markers() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, delta=0.25)
    # agent0: (0,1)@0, (1,1)@1, marker 0.25 past @1.25, (2,1)@2.
    # agent1: marker 0.25 before (1,1) waits for agent0's marker: max(0.75, 1.25) = 1.25;
    # then (1,1)@1.5 and (1,2)@2.5.
    assert s.arrival_times("agent0").tolist() == [0.0, 1.0, 1.25, 2.0]
    assert s.arrival_times("agent1").tolist() == [0.0, 1.25, 1.5, 2.5]
    assert s.makespan == 2.5
    wp = s.waypoints[1]
    assert wp.kind == ("vertex", "enter", "vertex", "vertex")
    assert wp.coords[1].tolist() == [1.0, 0.75]
    assert wp.theta.tolist() == pytest.approx([math.pi / 2] * 4)


def test_heterogeneous_speeds_and_cell_size() -> None:
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)], cell_size=2.0)
    v = g.vertex
    inst = Instance.mapf(
        g,
        [(0, 1), (1, 0)],
        [(2, 1), (1, 2)],
        kinematics=[Kinematics("slow", v_max=0.5), Kinematics("fast", v_max=2.0)],
    )
    plan = Plan.from_paths(
        [[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]]
    )
    s = postprocess(inst, plan, delta=0.5)
    # Cells are 2 m. agent0 at 0.5 m/s: (1,1)@4, marker 0.5 m past @5, (2,1)@8.
    # agent1 at 2 m/s: marker 0.5 m before (1,1) at max(0.75, 5) = 5, (1,1)@5.25, (1,2)@6.25.
    assert s.arrival_times("agent0").tolist() == [0.0, 4.0, 5.0, 8.0]
    assert s.arrival_times("agent1").tolist() == [0.0, 5.0, 5.25, 6.25]
    assert s.makespan == 8.0
    # Way-points are in instance coordinates (cells): the marker is 0.25 cell away.
    assert s.waypoints[1].coords[1].tolist() == [1.0, 0.75]


def test_roadmap_lengths() -> None:
    g = Graph.roadmap(
        {"A": (0, 0), "B": (3, 4), "C": (3, 0), "D": (6, 4)},
        [("A", "B"), ("B", "D"), ("C", "B", 10.0)],
    )
    inst = Instance.mapf(g, ["A", "C"], ["D", "B"])
    plan = Plan.from_paths([[0, 1, 3], [2, 2, 2, 1]])  # C waits until A's robot left B
    s = postprocess(inst, plan, delta=0)
    assert s.arrival_times("agent0").tolist() == [0.0, 5.0, 8.0]  # 5 m + 3 m at 1 m/s
    # agent1 enters B after agent0 entered D (t = 8); its edge is declared 10 long.
    assert s.arrival_times("agent1").tolist() == [0.0, 10.0]
    assert s.makespan == 10.0


def test_differential_drive_turning_time() -> None:
    g = Graph.grid(2, 2)
    v = g.vertex
    kin = Kinematics("pioneer", drive="differential", v_max=1.0, omega_max=math.pi / 4)
    inst = Instance.mapf(g, [(0, 0)], [(1, 1)], kinematics=kin)
    plan = Plan.from_paths([[v((0, 0)), v((1, 0)), v((1, 1))]])
    s = postprocess(inst, plan, delta=0)
    # Starts facing east (its first move): no turn. At (1, 0) it turns 90 degrees at
    # pi/4 rad/s = 2 s, then drives 1 m.
    wp = s.waypoints[0]
    assert wp.arrival.tolist() == [0.0, 1.0, 3.0, 4.0]
    assert wp.kind == ("vertex", "vertex", "turn", "vertex")
    assert wp.theta.tolist() == pytest.approx([0.0, 0.0, math.pi / 2, math.pi / 2])
    # An omni robot does not pay for the turn.
    omni = Instance.mapf(g, [(0, 0)], [(1, 1)], kinematics=Kinematics(v_max=1.0))
    assert postprocess(omni, plan, delta=0).makespan == 2.0


def test_u_turn_costs_pi() -> None:
    g = Graph.grid(2, 1)
    kin = Kinematics("pioneer", drive="differential", v_max=1.0, omega_max=1.0)
    inst = Instance.mapf(g, [(0, 0)], [(0, 0)], kinematics=kin)
    s = postprocess(inst, Plan.from_paths([[0, 1, 0]]), delta=0)
    assert s.makespan == pytest.approx(2.0 + math.pi)


def test_acceleration_bound() -> None:
    assert accel_time(1.0, 1.0, 1.0) == 2.0  # triangular: 2 sqrt(l / a)
    assert accel_time(0.5, 2.0, 1.0) == pytest.approx(2 * math.sqrt(0.5))
    assert accel_time(4.0, 1.0, 1.0) == 5.0  # trapezoidal: l / v + v / a
    assert accel_time(9.0, 2.0, 0.5) == pytest.approx(4.5 + 4.0)
    g = Graph.grid(3, 1)
    kin = Kinematics(v_max=1.0, a_max=1.0)
    inst = Instance.mapf(g, [(0, 0)], [(2, 0)], kinematics=kin)
    plan = Plan.from_paths([[0, 1, 2]])
    # Each 1 m move from standstill to standstill: 2 s, with or without markers.
    assert postprocess(inst, plan, delta=0).makespan == 4.0
    assert postprocess(inst, plan, delta=0.25).makespan == 4.0
    assert postprocess(inst, plan, delta=0, acceleration=False).makespan == 2.0


def test_acceleration_move_arc_with_markers() -> None:
    # With a kept marker the move has two pieces, so the bound is a separate move arc.
    inst, plan = plus_instance(kinematics=[Kinematics(v_max=1.0, a_max=1.0), Kinematics(v_max=1.0)])
    s = postprocess(inst, plan, delta=0.25)
    # agent0: each move takes 2 s: (1,1)@2, marker past (1,1) >= 2.25, (2,1)@4.
    t0 = s.arrival_times("agent0").tolist()
    assert t0[1] == 2.0 and t0[-1] == 4.0
    assert check_bounds(s.stn, s.times) == []


# ---------------------------------------------------------------------- slack, critical path
def test_slack_and_critical_path() -> None:
    # agent0 runs (0,0)->(2,0) in 2 s; agent1 needs 1 s for one step: 1 s of slack.
    g = Graph.grid(3, 2)
    inst = Instance.mapf(g, [(0, 0), (2, 1)], [(2, 0), (1, 1)])
    s = postprocess(inst, Plan.from_paths([[0, 1, 2], [5, 4]]), delta=0)
    assert s.makespan == 2.0
    assert s.waypoints[0].slack.tolist() == [0.0, 0.0, 0.0]
    assert s.waypoints[1].slack.tolist() == [0.0, 1.0]  # the start is fixed at 0
    assert s.critical_waypoints() == [("agent0", 0), ("agent0", 1), ("agent0", 2)]


def test_critical_path_crosses_robots() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, delta=0)
    # agent1 finishes last; it waited for agent0 to reach (2, 1).
    assert s.critical_waypoints() == [
        ("agent0", 0),
        ("agent0", 1),
        ("agent0", 2),
        ("agent1", 1),
        ("agent1", 2),
    ]
    assert np.all(s.slack[list(s.critical_path)] == 0)
    # agent0's final vertex: must be reached by 2 for agent1's sake, so no slack either.
    assert s.waypoints[0].latest.tolist() == [0.0, 1.0, 2.0]


# ---------------------------------------------------------------------- deadlines
def test_deadlines_bellman_ford() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, delta=0, deadlines={"agent1": 3.0, "agent0": 10})
    assert s.makespan == 3.0
    assert s.arrival_times("agent1").tolist() == [0.0, 2.0, 3.0]
    with pytest.raises(InconsistentSTNError, match="negative cycle") as info:
        postprocess(inst, plan, delta=0, deadlines={"agent1": 2.5})
    msg = str(info.value)
    assert "too tight by 0.5" in msg
    # The cycle runs through agent0's crossing (the precedence) and agent1's deadline.
    assert "agent0 at (2, 1)" in msg and "agent1 at (1, 2)" in msg and "X0" in msg
    with pytest.raises(InputError, match="unknown agent 'nobody'"):
        postprocess(inst, plan, delta=0, deadlines={"nobody": 1.0})


def test_bellman_ford_matches_longest_path() -> None:
    inst, plan = plus_instance()
    stn = build_stn(inst, build_tpg(inst, plan, 0.25))
    a = solve_graph(stn)
    loose = build_stn(inst, build_tpg(inst, plan, 0.25), deadlines={"agent0": 100})
    b = solve_graph(loose)
    assert loose.has_upper_bounds and not stn.has_upper_bounds
    assert np.allclose(a.earliest, b.earliest)
    assert np.allclose(a.latest, b.latest)


# ---------------------------------------------------------------------- refusals
@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf])
def test_bad_kinematics_refused(bad: float) -> None:
    with pytest.raises(InputError, match="v_max must be a positive finite number"):
        Kinematics("robot", v_max=bad)
    with pytest.raises(InputError, match="omega_max must be a positive finite number"):
        Kinematics("robot", drive="differential", omega_max=bad)


def test_bad_delta_refused() -> None:
    inst, plan = plus_instance()
    with pytest.raises(InputError, match="delta must be a finite number >= 0"):
        postprocess(inst, plan, delta=-0.1)
    with pytest.raises(InputError, match="delta must be a finite number >= 0"):
        postprocess(inst, plan, delta=math.nan)
    with pytest.raises(InputError, match=r"below half the shortest move .* length 1\b"):
        postprocess(inst, plan, delta=0.5)


def test_invalid_plan_refused() -> None:
    inst, _ = plus_instance()
    v = PLUS.vertex
    crash = Plan.from_paths([[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 1)), v((1, 2))]])
    with pytest.raises(InputError, match="the plan is invalid: vertex_conflict"):
        postprocess(inst, crash)


def test_options_refused() -> None:
    inst, plan = plus_instance()
    with pytest.raises(OptionError, match="needs method='lp'"):
        postprocess(inst, plan, "safety", method="graph")
    with pytest.raises(OptionError, match="unknown objective 'fast'"):
        postprocess(inst, plan, "fast")
    with pytest.raises(OptionError, match="unknown method"):
        postprocess(inst, plan, method="magic")


def test_default_delta_and_frozen() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan)
    assert s.delta == 0.25
    with pytest.raises(AttributeError):
        s.makespan = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        s.times[0] = 5.0


def test_arc_upper_bound_inconsistent() -> None:
    # agent1 may take at most 1.5 s for its piece (1,0) -> (1,1), but it starts at 0 and
    # may enter (1,1) only at 2: inconsistent; 2.5 s is enough.
    inst, plan = plus_instance()
    stn = build_stn(inst, build_tpg(inst, plan))
    piece = int(np.flatnonzero((stn.arc_src == 3) & (stn.arc_dst == 4))[0])
    ub = stn.ub.copy()
    ub[piece] = 1.5
    with pytest.raises(InconsistentSTNError, match="negative cycle") as info:
        solve_graph(stn.with_bounds(ub=ub))
    assert "agent1 at (1, 0)" in str(info.value)
    ub[piece] = 2.5
    sol = solve_graph(stn.with_bounds(ub=ub))
    assert sol.makespan == 3.0
    assert check_bounds(stn.with_bounds(ub=ub), sol.earliest) == []
