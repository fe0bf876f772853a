"""Property tests of MAPF-POST over random plans, inexact speeds, radii and deadlines.

Every outcome is a schedule or one of the documented errors (ClearanceError when the
plan's geometry cannot keep ``r_i + r_j + margin``, InconsistentSTNError when a deadline
is too tight). A schedule meets every STN bound within tolerance, every deadline, lies
inside its windows, and its exact continuous-time replay keeps every pair of robots at
least ``r_i + r_j + margin`` apart whenever the guarantee is reported.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import hierplan_opt as hp
from hierplan_opt import Graph, Instance, Kinematics, Status
from hierplan_opt.schedule import (
    ClearanceError,
    InconsistentSTNError,
    check_bounds,
    postprocess,
    replay,
    schedule_text,
)
from hierplan_opt.schedule.replay import _pair_min

SPEEDS = [0.7, 0.3, 1 / 3, 1.0, 0.45, 2.2]
RUNS = [("makespan", "graph"), ("makespan", "lp"), ("safety", "lp"), ("flowtime", "lp")]


@st.composite
def cases(draw: st.DrawFn) -> tuple[Instance, hp.Plan, dict]:
    seed = draw(st.integers(0, 10_000))
    rng = np.random.default_rng(seed)
    three_d = draw(st.booleans()) and draw(st.booleans())
    W, H = draw(st.integers(2, 6)), draw(st.integers(2, 6))
    D = draw(st.integers(2, 3)) if three_d else None
    cell = draw(st.sampled_from([0.5, 1.0, 1.5, 2.0]))
    shape = (H, W) if D is None else (D, H, W)
    g = Graph.grid(W, H, D, blocked=rng.random(shape) < 0.15, cell_size=cell)
    free = np.flatnonzero(g.passable)
    k = draw(st.integers(2, 5))
    assume(len(free) >= 2 * k)
    sel = rng.choice(free, 2 * k, replace=False)
    big = draw(st.booleans()) and draw(st.booleans())  # now and then robots > cells
    points = draw(st.booleans()) and draw(st.booleans())  # now and then point robots
    kins = []
    for i in range(k):
        radius = 0.0 if points else float(rng.uniform(0, (0.6 if big else 0.45) * cell))
        a_max = draw(st.sampled_from([None, 0.3, 1.0, 2 / 3]))
        v = draw(st.sampled_from(SPEEDS))
        if draw(st.booleans()):
            omega = draw(st.sampled_from([1.0, 0.7, math.pi / 3]))
            kin = Kinematics(f"diff{i % 2}", "differential", v, omega, a_max, radius)
        else:
            kin = Kinematics(f"omni{i % 2}", "omni", v, None, a_max, radius)
        kins.append(kin)
    inst = Instance.mapf(
        g,
        [g.location(int(v)) for v in sel[:k]],
        [g.location(int(v)) for v in sel[k:]],
        kinematics=kins,
    )
    assume(all(g.dist(s, t) < 1 << 30 for s, t in zip(inst.starts, inst.goals, strict=True)))
    res = hp.solve(inst, "cbs", time_limit=5)
    assume(res.status == Status.OPTIMAL and res.plan is not None)
    opts: dict = {
        "margin": draw(st.sampled_from([0.0, 0.0, 0.05, 0.1 * cell, 1 / 3 * 0.3])),
        "epsilon": draw(st.sampled_from([0.0, 0.0, 0.1, 1 / 3])),
        "acceleration": draw(st.booleans()),
    }
    if draw(st.booleans()):
        j = draw(st.integers(0, k - 1))
        opts["deadlines"] = {inst.agents[j].name: draw(st.floats(0.5, 60.0))}
    objective, method = draw(st.sampled_from(RUNS))
    opts.update(objective=objective, method=method, lp_backend="highs")
    return inst, res.plan, opts


def _required(inst: Instance, margin: float, i: int, j: int) -> float:
    return inst.agents[i].kinematics.radius + inst.agents[j].kinematics.radius + margin


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(cases())
def test_random_plans_keep_every_promise(case: tuple[Instance, hp.Plan, dict]) -> None:
    inst, plan, opts = case
    try:
        s = postprocess(inst, plan, **opts)
    except ClearanceError as err:
        msg = str(err)
        assert len(msg.splitlines()) == 1 and " m" in msg
        radius = max(a.kinematics.radius for a in inst.agents)
        if 2 * radius + opts["margin"] < inst.graph.cell_size:
            # With room in the cells, only robots that rotate cannot be scheduled.
            assert "rotate" in msg, msg
        return
    except InconsistentSTNError as err:
        assert "deadlines" in opts, err
        name, deadline = next(iter(opts["deadlines"].items()))
        free = dict(opts)
        free.pop("deadlines")
        free.update(objective="makespan", method="graph")
        earliest = postprocess(inst, plan, **free)
        # The deadline really is before the robot's earliest arrival.
        assert earliest.arrival_times(name)[-1] > deadline - 1e-9, (deadline, err)
        return
    stn = s.stn
    assert stn is not None
    assert check_bounds(stn, s.times) == []
    for name, deadline in opts.get("deadlines", {}).items():
        assert s.arrival_times(name)[-1] <= deadline + 1e-9
    for wp in s.waypoints:
        assert np.all(wp.earliest <= wp.arrival + 1e-9)
        assert np.all(wp.arrival <= wp.latest + 1e-9)
    text = schedule_text(s, "yaml")
    assert ".inf" not in text and ".nan" not in text
    # The promise, checked exactly for every pair (not through the replay's pruning).
    if all(c.guaranteed for c in s.clearance):
        m = opts["margin"]
        for i in range(inst.num_agents):
            for j in range(i + 1, inst.num_agents):
                a, b = s.waypoints[i], s.waypoints[j]
                d, _ = _pair_min(a.arrival, a.coords * s.scale, b.arrival, b.coords * s.scale)
                assert d >= _required(inst, m, i, j) - 1e-9, (i, j, d)
        assert replay(s, inst).ok


@pytest.mark.parametrize("seed", range(4))
def test_point_robots_never_refused(seed: int) -> None:
    # Radius 0 and margin 0: the plain TPG is acyclic for every valid plan without a
    # rotation (these CBS plans have none), and no two robots are ever on one point.
    rng = np.random.default_rng(seed)
    g = Graph.grid(5, 5, blocked=rng.random((5, 5)) < 0.1)
    free = np.flatnonzero(g.passable)
    sel = rng.choice(free, 12, replace=False)
    inst = Instance.mapf(
        g, [g.location(int(v)) for v in sel[:6]], [g.location(int(v)) for v in sel[6:]]
    )
    res = hp.solve(inst, "cbs", time_limit=10)
    if res.plan is None:
        pytest.skip(f"seed {seed}: no plan within 10 s ({res.status})")
    for kin in (None, Kinematics(v_max=0.7, a_max=1 / 3)):
        agents = tuple(dataclasses.replace(a, kinematics=kin or a.kinematics) for a in inst.agents)
        kinst = dataclasses.replace(inst, agents=agents)
        s = postprocess(kinst, res.plan, margin=0)
        assert check_bounds(s.stn, s.times) == []
        assert s.stats["regime"] == "none"
        assert replay(s, kinst, all_pairs=True).ok


@st.composite
def roadmap_cases(draw: st.DrawFn) -> tuple[Instance, hp.Plan, dict]:
    """Jittered lattices: edges of any angle and length, some acute corners."""
    seed = draw(st.integers(0, 10_000))
    rng = np.random.default_rng(seed)
    n = draw(st.integers(3, 4))
    jitter = draw(st.sampled_from([0.0, 0.15, 0.35]))
    pts = {
        f"v{x}{y}": (
            x + float(rng.uniform(-jitter, jitter)),
            y + float(rng.uniform(-jitter, jitter)),
        )
        for x in range(n)
        for y in range(n)
    }
    edges = [(f"v{x}{y}", f"v{x + 1}{y}") for x in range(n - 1) for y in range(n)]
    edges += [(f"v{x}{y}", f"v{x}{y + 1}") for x in range(n) for y in range(n - 1)]
    if draw(st.booleans()):
        edges += [(f"v{x}{y}", f"v{x + 1}{y + 1}") for x in range(n - 1) for y in range(n - 1)]
    g = Graph.roadmap(pts, edges)
    k = draw(st.integers(2, 4))
    sel = rng.choice(g.n, 2 * k, replace=False)
    radius = draw(st.sampled_from([0.0, 0.1, 0.2, 0.3]))
    kins = [Kinematics(f"r{i % 2}", v_max=draw(st.sampled_from(SPEEDS)), radius=radius)
            for i in range(k)]  # fmt: skip
    inst = Instance.mapf(
        g, [g.location(int(v)) for v in sel[:k]], [g.location(int(v)) for v in sel[k:]],
        kinematics=kins,
    )  # fmt: skip
    res = hp.solve(inst, "cbs", time_limit=5)
    assume(res.status == Status.OPTIMAL and res.plan is not None)
    objective, method = draw(st.sampled_from(RUNS))
    opts = {"margin": draw(st.sampled_from([0.0, 0.05, 0.2])), "objective": objective,
            "method": method, "lp_backend": "highs"}  # fmt: skip
    return inst, res.plan, opts


@settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(roadmap_cases())
def test_random_roadmaps_keep_the_distance(case: tuple[Instance, hp.Plan, dict]) -> None:
    inst, plan, opts = case
    try:
        s = postprocess(inst, plan, **opts)
    except ClearanceError as err:
        assert len(str(err).splitlines()) == 1
        return
    assert check_bounds(s.stn, s.times) == []
    rep = replay(s, inst, all_pairs=True)
    assert rep.ok, (rep, s.stats["regime"])


@pytest.mark.parametrize("deadline", [None, 1.0])
def test_safety_lp_round_off_below_the_earliest_arrival(deadline: float | None) -> None:
    # Found by the property above: HiGHS put the safety LP's last arrival 2e-9 s before
    # the earliest possible one, and the windows then refused the schedule as
    # inconsistent (with and without a deadline that the robot meets with room).
    passable = np.array([1, 1, 1, 1, 0, 0, 1, 0, 1, 1, 1, 0, 1, 1, 1, 1, 1, 1, 0, 1, 1, 1, 0, 1])
    g = Graph.grid(6, 2, 2, blocked=(passable == 0).reshape(2, 2, 6), cell_size=0.5)
    kins = [
        Kinematics("diff0", "differential", 0.3, 1.0, 1.0, 0.15263980177087538),
        Kinematics("omni1", "omni", 0.7, None, 0.3, 0.02769994844484267),
        Kinematics("omni0", "omni", 0.7, None, None, 0.1168080174894953),
        Kinematics("omni1", "omni", 0.7, None, None, 0.08170220305675396),
    ]
    paths = [
        [(0, 1, 0), (0, 0, 0), (0, 0, 1), (0, 0, 1), (1, 0, 1)],
        [(4, 0, 1), (3, 0, 1), (2, 0, 1), (1, 0, 1), (1, 0, 0)],
        [(2, 1, 0), (2, 0, 0)],
        [(3, 1, 1), (2, 1, 1), (1, 1, 1)],
    ]
    inst = Instance.mapf(g, [p[0] for p in paths], [p[-1] for p in paths], kinematics=kins)
    plan = hp.Plan.from_paths([[g.vertex(c) for c in p] for p in paths])
    deadlines = None if deadline is None else {"agent2": deadline}
    s = postprocess(
        inst,
        plan,
        margin=0.0,
        acceleration=True,
        objective="safety",
        method="lp",
        lp_backend="highs",
        deadlines=deadlines,
    )
    earliest = postprocess(inst, plan, margin=0.0, acceleration=True)
    assert s.stn is not None and check_bounds(s.stn, s.times) == []
    assert s.makespan >= earliest.makespan
    for wp in s.waypoints:
        assert np.all(wp.earliest <= wp.arrival) and np.all(wp.arrival <= wp.latest + 1e-9)
    assert replay(s, inst).ok
