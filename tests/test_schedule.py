"""MAPF-POST: TPG, markers from radii, STN and graph schedules against hand-computed answers."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hierplan_opt import Graph, InputError, Instance, Kinematics, OptionError, Plan, validate
from hierplan_opt.schedule import (
    ClearanceError,
    InconsistentSTNError,
    accel_time,
    build_stn,
    build_tpg,
    check_bounds,
    earliest_times,
    fix_and_propagate,
    postprocess,
    reach_time,
    replay,
    solve_graph,
)
from hierplan_opt.schedule.stn import MOVE, PIECE, PRECEDENCE
from hierplan_opt.schedule.tpg import ENTER, LEAVE, TYPE2, VERTEX

# A plus-shaped map: the centre (1, 1) is the only crossing.
#        (1,2)
#  (0,1) (1,1) (2,1)
#        (1,0)
PLUS = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])


def plus_instance(kinematics=None, graph: Graph = PLUS) -> tuple[Instance, Plan]:
    """agent0 crosses west->east at t=1; agent1 waits, then crosses south->north at t=2."""
    v = graph.vertex
    inst = Instance.mapf(graph, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=kinematics)
    plan = Plan.from_paths(
        [[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]]
    )
    return inst, plan


def type2(tpg) -> list[tuple[str, str]]:
    return sorted(
        (tpg.label(int(a)), tpg.label(int(b)))
        for a, b, t in zip(tpg.arc_src, tpg.arc_dst, tpg.arc_type, strict=True)
        if t == TYPE2
    )


# ---------------------------------------------------------------------- TPG
def test_plain_tpg_structure() -> None:
    inst, plan = plus_instance()
    tpg = build_tpg(inst, plan)
    assert tpg.regime == "none"
    # Waits merged: agent1 has 3 nodes, not 4.
    assert tpg.agent_ptr.tolist() == [0, 3, 6]
    # agent1 may enter (1, 1) once agent0 has left it: reached its next vertex (issue
    # 30: the arc came from agent0's arrival at (1, 1), so both could be there at once).
    assert type2(tpg) == [("agent0 at (2, 1)", "agent1 at (1, 1)")]
    assert tpg.type2_predecessors(4).tolist() == [2]


def test_markers_follow_the_radii() -> None:
    # Radius 0 + margin 0.25: claims reach 1/2 + 0.25/2 = 0.625 around (1, 1).
    inst, plan = plus_instance()
    tpg = build_tpg(inst, plan, margin=0.25)
    assert tpg.regime == "tight"
    kinds = tpg.node_kind.tolist()
    assert kinds.count(VERTEX) == 6
    assert kinds.count(LEAVE) == 1 and kinds.count(ENTER) == 1
    k = int(np.flatnonzero(tpg.arc_type == TYPE2)[0])
    u, w = int(tpg.arc_src[k]), int(tpg.arc_dst[k])
    assert tpg.label(u) == "agent0 0.625 past (1, 1)"
    assert tpg.label(w) == "agent1 0.375 past (1, 0)"
    assert tpg.node_coord[u].tolist() == pytest.approx([1.625, 1.0])
    assert tpg.node_coord[w].tolist() == pytest.approx([1.0, 0.375])
    # Radii add to the claim: robots of radius 0.2 and 0.3 on 2 m cells.
    g2 = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)], cell_size=2.0)
    kin = [Kinematics("a", radius=0.2), Kinematics("b", radius=0.3)]
    inst2, plan2 = plus_instance(kin, g2)
    tpg2 = build_tpg(inst2, plan2)
    assert type2(tpg2) == [("agent0 1.2 past (1, 1)", "agent1 0.7 past (1, 0)")]


def test_first_later_visit_suffices() -> None:
    # Three robots pass (1, 0) of a corridor one after the other: Type-2 arcs join
    # consecutive visitors of each location only.
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
    assert validate(inst, plan) == []
    assert type2(build_tpg(inst, plan)) == [
        ("agent0 at (2, 0)", "agent2 at (1, 0)"),
        ("agent0 at (3, 0)", "agent2 at (2, 0)"),
        ("agent2 at (1, 0)", "agent1 at (1, 1)"),
    ]


# ---------------------------------------------------------------------- hand-computed
def test_point_robots_enter_once_the_cell_is_left() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, margin=0)
    # agent0 at full speed: 0, 1, 2; it has left (1, 1) once it reaches (2, 1) at
    # t = 2, so agent1 (creeping from (1, 0) since t = 0) may arrive there at 2 (issue
    # 30: it arrived at 1, when agent0 was still there).
    assert s.arrival_times("agent0").tolist() == [0.0, 1.0, 2.0]
    assert s.arrival_times("agent1").tolist() == [0.0, 2.0, 3.0]
    assert s.safety_distance == 0.0
    rep = replay(s, inst, all_pairs=True)
    assert rep.ok and rep.min_distance == pytest.approx(math.sqrt(0.2))  # at t = 1.2
    # A precedence lag epsilon keeps them apart in time.
    s = postprocess(inst, plan, epsilon=0.5, margin=0)
    assert s.arrival_times("agent1").tolist() == [0.0, 2.5, 3.5]


def test_markers_schedule_by_hand() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, margin=0.25)
    # agent0: (0,1)@0, (1,1)@1, leaves the claim 0.625 past (1,1)@1.625, (2,1)@2.
    # agent1: enters the claim 0.625 before (1,1) at max(0.375, 1.625) = 1.625; then
    # (1,1)@2.25 and (1,2)@3.25.
    assert s.arrival_times("agent0").tolist() == pytest.approx([0.0, 1.0, 1.625, 2.0])
    assert s.arrival_times("agent1").tolist() == pytest.approx([0.0, 1.625, 2.25, 3.25])
    assert s.makespan == pytest.approx(3.25)
    assert s.safety_distance == 0.25
    wp = s.waypoints[1]
    assert wp.kind == ("vertex", "enter", "vertex", "vertex")
    assert wp.coords[1].tolist() == pytest.approx([1.0, 0.375])
    assert wp.theta.tolist() == pytest.approx([math.pi / 2] * 4)
    rep = replay(s, inst, all_pairs=True)
    # Closest approach while agent0 leaves east, at (t, 1) for t in [1, 1.625], and
    # agent1 creeps north at (1, c t), c = 0.375 / 1.625: d^2 = (t - 1)^2 + (1 - c t)^2
    # is least at t = (1 + c) / (1 + c^2).
    c = 0.375 / 1.625
    t = (1 + c) / (1 + c * c)
    assert rep.ok and rep.min_distance >= 0.25
    assert rep.min_distance == pytest.approx(math.hypot(t - 1, 1 - c * t))
    assert rep.time == pytest.approx(t)


def test_heterogeneous_speeds_radii_and_cell_size() -> None:
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)], cell_size=2.0)
    kin = [Kinematics("slow", v_max=0.5, radius=0.3), Kinematics("fast", v_max=2.0, radius=0.4)]
    inst, plan = plus_instance(kin, g)
    s = postprocess(inst, plan, margin=0.1)
    # Cells are 2 m; claims reach 1 + r + 0.05 m: 1.35 (slow) and 1.45 (fast).
    # agent0 at 0.5 m/s: (1,1)@4, leaves its claim 1.35 m past (1,1)@6.7, (2,1)@8.
    # agent1 at 2 m/s: enters its claim 1.45 m before (1,1) at max(0.275, 6.7) = 6.7,
    # (1,1)@7.425, (1,2)@8.425.
    assert s.arrival_times("agent0").tolist() == pytest.approx([0.0, 4.0, 6.7, 8.0])
    assert s.arrival_times("agent1").tolist() == pytest.approx([0.0, 6.7, 7.425, 8.425])
    # Way-points are in instance coordinates (cells): the marker is 0.275 cell away.
    assert s.waypoints[1].coords[1].tolist() == pytest.approx([1.0, 0.275])
    assert [(c.types, c.required, c.guaranteed) for c in s.clearance] == [
        (("fast", "slow"), pytest.approx(0.8), True)
    ]
    assert replay(s, inst, all_pairs=True).min_distance >= 0.8


def test_roadmap_lengths() -> None:
    g = Graph.roadmap(
        {"A": (0, 0), "B": (3, 4), "C": (3, 0), "D": (6, 4)},
        [("A", "B"), ("B", "D"), ("C", "B", 10.0)],
    )
    inst = Instance.mapf(g, ["A", "C"], ["D", "B"])
    plan = Plan.from_paths([[0, 1, 3], [2, 2, 2, 1]])  # C waits until A's robot left B
    s = postprocess(inst, plan, margin=0)
    assert s.arrival_times("agent0").tolist() == [0.0, 5.0, 8.0]  # 5 m + 3 m at 1 m/s
    # agent1's edge is declared 10 long (longer than the 4 m segment: allowed).
    assert s.arrival_times("agent1").tolist() == [0.0, 10.0]


def test_roadmap_edge_shorter_than_its_segment_refused() -> None:
    # Issue 9 item 6: the replay would exceed v_max on such an edge.
    g = Graph.roadmap({"A": (0, 0), "B": (3, 4)}, [("A", "B", 3.0)])
    inst = Instance.mapf(g, ["A"], ["B"])
    with pytest.raises(InputError, match=r"edge A -> B is 3 long but its end points are 5 apart"):
        postprocess(inst, Plan.from_paths([[0, 1]]))


def test_differential_drive_turning_time() -> None:
    g = Graph.grid(2, 2)
    v = g.vertex
    kin = Kinematics("pioneer", drive="differential", v_max=1.0, omega_max=math.pi / 4)
    inst = Instance.mapf(g, [(0, 0)], [(1, 1)], kinematics=kin)
    plan = Plan.from_paths([[v((0, 0)), v((1, 0)), v((1, 1))]])
    s = postprocess(inst, plan)
    # Starts facing east (its first move): no turn. At (1, 0) it turns 90 degrees at
    # pi/4 rad/s = 2 s, then drives 1 m.
    wp = s.waypoints[0]
    assert wp.arrival.tolist() == [0.0, 1.0, 3.0, 4.0]
    assert wp.kind == ("vertex", "vertex", "turn", "vertex")
    assert wp.theta.tolist() == pytest.approx([0.0, 0.0, math.pi / 2, math.pi / 2])
    omni = Instance.mapf(g, [(0, 0)], [(1, 1)], kinematics=Kinematics(v_max=1.0))
    assert postprocess(omni, plan).makespan == 2.0


def test_a_turning_robot_leaves_after_its_turn() -> None:
    # agent0 turns 90 degrees at (1, 1) (2 s at pi/4 rad/s) before leaving north; the
    # point robot behind it may enter (1, 1) only after that turn.
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    v = g.vertex
    kin = [Kinematics("p", drive="differential", v_max=1.0, omega_max=math.pi / 4), Kinematics()]
    inst = Instance.mapf(g, [(1, 1), (1, 0)], [(1, 2), (1, 1)], kinematics=kin)
    plan = Plan.from_paths([[v((1, 1)), v((1, 2))], [v((1, 0)), v((1, 0)), v((1, 1))]])
    s = postprocess(inst, plan, margin=0)
    assert s.arrival_times("agent1").tolist() == [0.0, 1.0]  # agent0 starts facing north
    s2 = postprocess(
        Instance.mapf(g, [(0, 1), (1, 0)], [(1, 2), (1, 1)], kinematics=kin),
        Plan.from_paths([[v((0, 1)), v((1, 1)), v((1, 2))], [v((1, 0)), v((1, 0)), v((1, 1))]]),
        margin=0,
    )
    # agent0: (1,1)@1, turns until 3, (1,2)@4: it has left (1, 1) at 4, when agent1
    # may arrive there.
    assert s2.arrival_times("agent0").tolist() == [0.0, 1.0, 3.0, 4.0]
    assert s2.arrival_times("agent1").tolist() == [0.0, 4.0]


def test_u_turn_costs_pi() -> None:
    g = Graph.grid(2, 1)
    kin = Kinematics("pioneer", drive="differential", v_max=1.0, omega_max=1.0)
    inst = Instance.mapf(g, [(0, 0)], [(0, 0)], kinematics=kin)
    s = postprocess(inst, Plan.from_paths([[0, 1, 0]]))
    assert s.makespan == pytest.approx(2.0 + math.pi)


def test_acceleration_bound() -> None:
    assert accel_time(1.0, 1.0, 1.0) == 2.0  # triangular: 2 sqrt(l / a)
    assert accel_time(0.5, 2.0, 1.0) == pytest.approx(2 * math.sqrt(0.5))
    assert accel_time(4.0, 1.0, 1.0) == 5.0  # trapezoidal: l / v + v / a
    assert accel_time(9.0, 2.0, 0.5) == pytest.approx(4.5 + 4.0)
    assert reach_time(0.5, 1.0, 1.0) == pytest.approx(1.0)  # sqrt(2 l / a)
    assert reach_time(2.0, 1.0, 1.0) == pytest.approx(2.5)  # l / v + v / (2 a)
    g = Graph.grid(3, 1)
    kin = Kinematics(v_max=1.0, a_max=1.0)
    inst = Instance.mapf(g, [(0, 0)], [(2, 0)], kinematics=kin)
    plan = Plan.from_paths([[0, 1, 2]])
    # Each 1 m move from standstill to standstill: 2 s.
    assert postprocess(inst, plan).makespan == 4.0
    assert postprocess(inst, plan, acceleration=False).makespan == 2.0


def test_acceleration_bounds_every_piece() -> None:
    # Issue 9 item 3: pieces to and from markers get the acceleration bound too.
    inst, plan = plus_instance(kinematics=[Kinematics(v_max=1.0, a_max=1.0), Kinematics()])
    s = postprocess(inst, plan, margin=0.25)
    # agent0: (1,1)@2 (rest to rest); the marker 0.625 m on needs reach_time(0.625) =
    # 0.625 + 0.5 = 1.125 s from rest, not 0.625 s; (2,1) at 2 + accel_time(1) = 4.
    t0 = s.arrival_times("agent0").tolist()
    assert t0 == pytest.approx([0.0, 2.0, 3.125, 4.0])
    assert check_bounds(s.stn, s.times) == []
    stn = s.stn
    assert stn is not None
    # The piece into the marker and the marker's piece on both carry a reach bound,
    # and a move arc holds the rest-to-rest bound of the whole move.
    pieces = {
        (stn.tpg.label(int(a)), stn.tpg.label(int(b))): float(lb)
        for a, b, lb, k in zip(stn.arc_src, stn.arc_dst, stn.lb, stn.arc_kind, strict=True)
        if k in (PIECE, MOVE) and stn.tpg.node_agent[a] == 0
    }
    assert pieces[("agent0 at (1, 1)", "agent0 0.625 past (1, 1)")] == pytest.approx(1.125)
    assert pieces[("agent0 0.625 past (1, 1)", "agent0 at (2, 1)")] == pytest.approx(
        reach_time(0.375, 1.0, 1.0)
    )
    assert pieces[("agent0 at (1, 1)", "agent0 at (2, 1)")] == pytest.approx(2.0)


def test_a_marker_is_never_reached_faster_than_physics_allows() -> None:
    # The example: a pioneer (a_max 0.3) leaving rest must not reach a marker
    # 0.25 m away in 0.25 / v_max s.
    kin = Kinematics("pioneer", "differential", v_max=0.6, omega_max=1.5, a_max=0.3, radius=0.3)
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    inst, plan = plus_instance([kin, kin], g)
    s = postprocess(inst, plan)
    stn = s.stn
    assert stn is not None
    for a, b, lb in zip(stn.arc_src, stn.arc_dst, stn.lb, strict=True):
        if stn.tpg.node_agent[a] != stn.tpg.node_agent[b]:
            continue
        length = float(stn.tpg.node_s[b] - stn.tpg.node_s[a])
        starts_at_rest = stn.tpg.node_kind[a] == VERTEX
        if starts_at_rest and length > 0:
            assert lb >= reach_time(length, 0.6, 0.3) - 1e-12


# ---------------------------------------------------------------------- slack, critical path
def test_slack_and_critical_path() -> None:
    # agent0 runs (0,0)->(2,0) in 2 s; agent1 needs 1 s for one step: 1 s of slack.
    g = Graph.grid(3, 2)
    inst = Instance.mapf(g, [(0, 0), (2, 1)], [(2, 0), (1, 1)])
    s = postprocess(inst, Plan.from_paths([[0, 1, 2], [5, 4]]))
    assert s.makespan == 2.0
    assert s.waypoints[0].slack.tolist() == [0.0, 0.0, 0.0]
    assert s.waypoints[1].slack.tolist() == [0.0, 1.0]  # the start is fixed at 0
    assert s.critical_waypoints() == [("agent0", 0), ("agent0", 1), ("agent0", 2)]


def test_critical_path_crosses_robots() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, margin=0.25)
    # agent1 finishes last; it waited for agent0 to leave its claim around (1, 1).
    assert s.critical_waypoints() == [
        ("agent0", 0),
        ("agent0", 1),
        ("agent0", 2),
        ("agent1", 1),
        ("agent1", 2),
        ("agent1", 3),
    ]
    assert np.allclose(s.slack[list(s.critical_path)], 0)
    # agent0 must leave its claim by 1.625 for agent1's sake; its goal has 1.25 s.
    assert s.waypoints[0].latest.tolist() == pytest.approx([0.0, 1.0, 1.625, 3.25])


# ---------------------------------------------------------------------- deadlines
def test_deadlines() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan, margin=0.25, deadlines={"agent1": 3.25, "agent0": 10})
    assert s.makespan == pytest.approx(3.25)
    with pytest.raises(InconsistentSTNError, match="negative cycle") as info:
        postprocess(inst, plan, margin=0.25, deadlines={"agent1": 3.0})
    msg = str(info.value)
    assert "too tight by 0.25 s" in msg
    # The cycle runs through agent0's claim (the precedence) and agent1's deadline.
    assert "agent0 0.625 past (1, 1)" in msg and "agent1 at (1, 2)" in msg and "X0" in msg
    assert info.value.nodes[0] == info.value.nodes[-1] == -1
    with pytest.raises(InputError, match="unknown agent 'nobody'"):
        postprocess(inst, plan, deadlines={"nobody": 1.0})


@pytest.mark.parametrize("objective,method", [("makespan", "graph"), ("makespan", "lp"),
                                              ("safety", "lp"), ("flowtime", "lp")])  # fmt: skip
def test_loose_deadline_with_inexact_speed(objective: str, method: str) -> None:
    # Issue 9 item 2: v_max 0.7 on (0,0)->(1,0)->(1,1)->(2,1) with a 100 s deadline
    # raised networkx.NetworkXUnbounded (a -4.4e-16 "negative cycle" of round-off).
    g = Graph.grid(3, 3)
    v = g.vertex
    inst = Instance.mapf(g, [(0, 0)], [(2, 1)], kinematics=Kinematics(v_max=0.7))
    plan = Plan.from_paths([[v((0, 0)), v((1, 0)), v((1, 1)), v((2, 1))]])
    s = postprocess(inst, plan, objective, method=method, deadlines={"agent0": 100})
    assert s.makespan == pytest.approx(3 / 0.7)
    assert np.all(s.waypoints[0].slack >= 0)
    # A deadline equal to the makespan computed another way is still consistent.
    t = postprocess(inst, plan, deadlines={"agent0": 1 / 0.7 + 1 / 0.7 + 1 / 0.7})
    assert t.makespan == pytest.approx(3 / 0.7)


def test_bellman_ford_free_passes_match_with_loose_deadlines() -> None:
    inst, plan = plus_instance()
    stn = build_stn(inst, build_tpg(inst, plan, 0.25))
    a = solve_graph(stn)
    loose = build_stn(inst, build_tpg(inst, plan, 0.25), deadlines={"agent0": 100})
    b = solve_graph(loose)
    assert loose.has_upper_bounds and not stn.has_upper_bounds
    assert np.allclose(a.earliest, b.earliest)
    assert np.allclose(a.latest, b.latest)


def test_arc_upper_bound_inconsistent() -> None:
    # agent1 may take at most 1 s from its start to its claim's entry marker, but
    # agent0 leaves its claim only at 1.625: inconsistent by 0.625; 2 s is enough.
    inst, plan = plus_instance()
    stn = build_stn(inst, build_tpg(inst, plan, 0.25))
    labels = [stn.tpg.label(int(v)) for v in range(stn.num_nodes)]
    a, b = labels.index("agent1 at (1, 0)"), labels.index("agent1 0.375 past (1, 0)")
    piece = int(np.flatnonzero((stn.arc_src == a) & (stn.arc_dst == b))[0])
    ub = stn.ub.copy()
    ub[piece] = 1.0
    with pytest.raises(InconsistentSTNError, match="negative cycle") as info:
        solve_graph(stn.with_bounds(ub=ub))
    assert "agent1 at (1, 0)" in str(info.value) and "too tight by 0.625" in str(info.value)
    ub[piece] = 2.0
    sol = solve_graph(stn.with_bounds(ub=ub))
    assert sol.makespan == pytest.approx(3.25)
    assert check_bounds(stn.with_bounds(ub=ub), sol.earliest) == []


def test_upper_bound_cycle_without_deadline_is_named() -> None:
    # An upper bound on a precedence that its own lower bound exceeds: a cycle
    # between two events, found without any deadline.
    inst, plan = plus_instance()
    stn = build_stn(inst, build_tpg(inst, plan), epsilon=0.5)
    k = int(np.flatnonzero(stn.arc_kind == PRECEDENCE)[0])
    ub = stn.ub.copy()
    ub[k] = 0.25
    with pytest.raises(InconsistentSTNError, match="negative cycle"):
        earliest_times(stn.with_bounds(ub=ub))


# ---------------------------------------------------------------------- incremental
def test_fix_and_propagate() -> None:
    inst, plan = plus_instance()
    stn = build_stn(inst, build_tpg(inst, plan, 0.25))
    t = earliest_times(stn)
    labels = [stn.tpg.label(int(v)) for v in range(stn.num_nodes)]
    late = labels.index("agent0 at (1, 1)")
    new = fix_and_propagate(stn, t, {late: 1.5})  # agent0 reached (1, 1) 0.5 s late
    assert new[labels.index("agent0 0.625 past (1, 1)")] == pytest.approx(2.125)
    assert new[labels.index("agent1 at (1, 2)")] == pytest.approx(3.75)
    assert new[labels.index("agent1 at (1, 0)")] == 0.0  # not reachable from the change
    assert check_bounds(stn, new) == []
    # A late robot's remaining pieces slow down: raise their bounds, then propagate.
    lb = stn.lb.copy()
    slow = stn.arc_src == labels.index("agent1 at (1, 1)")
    lb[slow] *= 2
    slower = stn.with_bounds(lb=lb)
    new2 = fix_and_propagate(slower, t, {}, changed=[labels.index("agent1 at (1, 2)")])
    assert new2[labels.index("agent1 at (1, 2)")] == pytest.approx(4.25)
    # Fixing an event before its predecessor allows it is refused.
    with pytest.raises(InconsistentSTNError, match="comes before"):
        fix_and_propagate(stn, t, {labels.index("agent1 0.375 past (1, 0)"): 1.0})
    # So is a delay that breaks a deadline.
    tight = build_stn(inst, build_tpg(inst, plan, 0.25), deadlines={"agent1": 3.25})
    with pytest.raises(InconsistentSTNError, match="too tight by 0.5"):
        fix_and_propagate(tight, earliest_times(tight), {late: 1.5})


# ---------------------------------------------------------------------- rotations
def rotation() -> tuple[Instance, Plan]:
    g = Graph.grid(2, 2)
    v = g.vertex
    ring = [(0, 0), (1, 0), (1, 1), (0, 1)]
    inst = Instance.mapf(g, ring, ring[1:] + ring[:1])
    plan = Plan.from_paths([[v(a), v(b)] for a, b in zip(ring, ring[1:] + ring[:1], strict=True)])
    assert validate(inst, plan) == []
    return inst, plan


def test_rotation_of_point_robots() -> None:
    # Issue 9 item 4: the 2x2 four-robot rotation (what cbs, ecbs and cpsat return).
    # Issue 30: each robot may arrive only once the one ahead has left. In a rotation
    # each would wait for the next to arrive first, so their arcs go through markers a
    # tenth of the move past a vertex: a robot reaches the next vertex once the one
    # there is 0.1 past it. Margin 0: never on one point; a margin > 0 is refused.
    inst, plan = rotation()
    s = postprocess(inst, plan, margin=0)
    assert s.makespan == pytest.approx(1.0)
    rep = replay(s, inst, all_pairs=True)
    assert rep.ok and rep.min_distance > 0.05
    assert all("leave" in w.kind for w in s.waypoints)
    with pytest.raises(ClearanceError) as info:
        postprocess(inst, plan)  # point robots: default margin 0.1
    msg = str(info.value)
    assert "rotate" in msg and "margin 0" in msg and len(msg.splitlines()) == 1


def test_rotation_needs_zero_clearance() -> None:
    inst, plan = rotation()
    with pytest.raises(ClearanceError) as info:
        postprocess(inst, plan, margin=0.1)
    msg = str(info.value)
    assert "they rotate at step 0" in msg and "cells of 1 m" in msg
    assert "type default" in msg and "0.1 m apart" in msg
    assert len(msg.splitlines()) == 1


# ---------------------------------------------------------------------- refusals
@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf])
def test_bad_kinematics_refused(bad: float) -> None:
    with pytest.raises(InputError, match="v_max must be a positive finite number"):
        Kinematics("robot", v_max=bad)
    with pytest.raises(InputError, match="omega_max must be a positive finite number"):
        Kinematics("robot", drive="differential", omega_max=bad)


def test_bad_margin_refused() -> None:
    inst, plan = plus_instance()
    with pytest.raises(InputError, match="margin must be a finite number >= 0"):
        postprocess(inst, plan, margin=-0.1)
    with pytest.raises(InputError, match="margin must be a finite number >= 0"):
        postprocess(inst, plan, margin=math.nan)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = postprocess(inst, plan, delta=0.25)  # the old name still works
    assert any(issubclass(w.category, DeprecationWarning) for w in caught)
    assert old.margin == 0.25 and old.delta == 0.25


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


def test_frozen() -> None:
    inst, plan = plus_instance()
    s = postprocess(inst, plan)
    with pytest.raises(AttributeError):
        s.makespan = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        s.times[0] = 5.0


@pytest.mark.parametrize(
    "graph,kin,match",
    [
        (Graph.grid(3, 1, cell_size=1e308), None, r"position of \(2, 0\) in metres is not"),
        (Graph.grid(2, 1, cell_size=1e308), None, r"distance from \(0, 0\) to \(1, 0\) is not"),
        (Graph.grid(2, 1), Kinematics(v_max=1e-320), r"needs a time that is not a finite"),
        (
            Graph.roadmap({"A": (-1e308, 0), "B": (1e308, 0)}, [("A", "B", 1.0)]),
            None,
            r"distance from A to B is not a finite number",
        ),
    ],
)
def test_non_finite_numbers_refused(graph: Graph, kin, match: str) -> None:
    # Issue 21: huge cells, tiny speeds and huge coordinates gave .nan/.inf schedules.
    last = graph.n - 1
    inst = Instance.mapf(graph, [graph.location(0)], [graph.location(last)], kinematics=kin)
    with pytest.raises(InputError, match=match):
        postprocess(inst, Plan.from_paths([list(range(graph.n))]))
