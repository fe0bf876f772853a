"""Trajectory refinement: analytic profiles, windows, limits, decoupling, infeasibility,
3D quadcopters, unicycles turning in place, corridor mode and the verifier."""

from __future__ import annotations

import importlib
import math
from dataclasses import replace

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance, Kinematics
from hierplan_opt.core.plan import Plan
from hierplan_opt.schedule import ClearanceError, postprocess
from hierplan_opt.schedule.stn import accel_time
from hierplan_opt.trajectory import (
    InfeasibleWindowsError,
    decouple,
    from_schedule,
    refine,
)
from hierplan_opt.trajectory.verify import verify
from hierplan_opt.trajectory.windows import violations

R = importlib.import_module("hierplan_opt.trajectory.refine")


def line_instance(n: int, kin: Kinematics) -> tuple[Instance, Plan]:
    g = Graph.grid(n + 1, 1)
    inst = Instance.mapf(g, [(0, 0)], [(n, 0)], kinematics=kin)
    return inst, Plan.from_paths([list(range(n + 1))])


def fd_limits(traj, dt: float = 0.005) -> tuple[float, float]:
    """Largest speed and acceleration from finite differences of sampled positions."""
    s = traj.sample(dt)
    P = s["pos"]
    v = np.linalg.norm(np.diff(P, axis=1), axis=2) / dt
    a = np.linalg.norm(P[:, 2:] - 2 * P[:, 1:-1] + P[:, :-2], axis=2) / dt**2
    return float(v.max()), float(a.max())


# ---------------------------------------------------------------------- analytic profile
def test_straight_line_reproduces_bang_bang_and_the_stretch_factor() -> None:
    # 4 m at v_max 1 and a_max 1: the minimum time is 4/1 + 1/1 = 5 s (accelerate 1 s,
    # cruise 3 s, brake 1 s). The schedule without the acceleration bound asks for 4 s,
    # so the smallest stretch factor is exactly 5/4.
    inst, plan = line_instance(4, Kinematics(v_max=1.0, a_max=1.0))
    sched = postprocess(inst, plan, acceleration=False)
    assert sched.makespan == pytest.approx(4.0)
    with pytest.raises(InfeasibleWindowsError, match=r"agent0 way-point 4 .*stretching") as ei:
        refine(inst, sched)
    assert ei.value.stretch == pytest.approx(1.25, rel=2e-3)
    tr = refine(inst, sched, stretch="auto")
    assert tr.stretch == pytest.approx(1.25, rel=2e-3)
    r = tr.robots[0]
    assert r.arrival == pytest.approx(5.0, rel=3e-3)
    t = np.linspace(0, r.arrival, 401)
    v = np.linalg.norm(r.state(t)["v"], axis=1)
    bang = np.minimum(np.minimum(t, 1.0), np.maximum(r.arrival - t, 0.0))
    assert np.max(np.abs(v - bang)) < 0.03
    assert verify(tr, inst).ok


def test_short_line_is_triangular() -> None:
    # 1 m at a_max 1 with v_max 2: no cruise, 2 sqrt(1/1) = 2 s, peak speed 1 m/s.
    inst, plan = line_instance(1, Kinematics(v_max=2.0, a_max=1.0))
    sched = postprocess(inst, plan, acceleration=False)
    tr = refine(inst, sched, stretch="auto")
    r = tr.robots[0]
    assert tr.stretch * sched.makespan == pytest.approx(accel_time(1.0, 2.0, 1.0), rel=3e-3)
    vmax = np.linalg.norm(r.state(np.linspace(0, r.arrival, 201))["v"], axis=1).max()
    # Within the factor's precision (1e-3) the profile may round its peak by
    # O(sqrt(1e-3)): 2 s + 2 ms allow a peak of about 0.96 m/s.
    assert vmax == pytest.approx(1.0, abs=0.05)


# ---------------------------------------------------------------------- windows and limits
def crossing() -> tuple[Instance, Plan]:
    # Two robots cross at the centre of a plus-shaped map; agent1 waits one step.
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    kin = Kinematics(v_max=1.0, a_max=2.0, radius=0.2)
    inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=kin)
    v = g.vertex
    plan = Plan.from_paths(
        [[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]]
    )
    return inst, plan


def test_windows_and_limits_are_kept() -> None:
    inst, plan = crossing()
    sched = postprocess(inst, plan)
    tr = refine(inst, sched, stretch="auto")
    win = tr.windows
    net = win.network
    for j, r in enumerate(tr.robots):
        ev = np.array(list(net.events(j)))
        et = np.asarray(r.event_times)
        assert np.all(et >= win.lo[ev] - 1e-6) and np.all(et <= win.hi[ev] + 1e-6)
        # At each event time the robot is at the event.
        assert np.allclose(r.state(et)["p"], net.pos[ev], atol=1e-6)
    vmax, amax = fd_limits(tr)
    assert vmax <= 1.0 + 1e-5 and amax <= 2.0 + 1e-3
    rep = verify(tr, inst)
    assert rep.ok, rep.message()
    assert rep.min_distance >= tr.safety_distance > 0
    # The precedence of the crossing holds in the refined motion.
    u, w = int(net.arc_src[0]), int(net.arc_dst[0])
    tu = tr.robots[int(net.agent[u])].event_times[u - int(net.agent_ptr[int(net.agent[u])])]
    tw = tr.robots[int(net.agent[w])].event_times[w - int(net.agent_ptr[int(net.agent[w])])]
    assert tw - tu >= net.arc_lb[0] - 1e-6


def goal_reached(r, dt: float = 1e-3) -> float:
    """First time (within ``dt``) a refined robot is at its goal and stays there."""
    t = np.arange(0.0, r.arrival + dt, dt)
    off = np.linalg.norm(r.state(t)["p"] - r.p[-1], axis=1) > 1e-6
    return float(t[np.flatnonzero(off)[-1] + 1]) if off.any() else 0.0


@pytest.mark.parametrize(
    ("mode", "a_max_in_schedule"), [("path", False), ("path", True), ("corridor", True)]
)
def test_a_robot_that_finishes_early_is_not_dragged_to_the_makespan(
    mode: str, a_max_in_schedule: bool
) -> None:
    # The audit's g1: "short" has 1 m to go, "long" 7 m. With IPOPT (the default for
    # two robots) "short" used to creep to its goal at up to 0.2 m/s and arrive at the
    # refined makespan (7.67 s), where the profile solver has it at 1.9 s: its last
    # window reaches the makespan and the objective rewarded taking all of it (corridor
    # mode, also IPOPT, did the same).
    g = Graph.grid(8, 2)
    kin = Kinematics(v_max=1.0, a_max=1.5 if a_max_in_schedule else None)
    inst = Instance.mapf(g, [(0, 1), (0, 0)], [(1, 1), (7, 0)], kinematics=kin)
    sched = postprocess(inst, hp.solve(inst, "cbs").plan)
    tr = refine(inst, sched, stretch="auto", a_max=1.5, mode=mode)
    assert tr.stats["solver"] == "ipopt"
    short = tr.robots[0]
    scheduled = float(sched.arrival_times(0)[-1])
    # Its scheduled arrival stretched by the fleet's factor, or (the schedule without
    # a_max asks for 1 m in 1 s) the least time its limits allow, with 25 % room.
    least = accel_time(1.0, 1.0, 1.5)
    expected = max(tr.stretch * scheduled, least)
    arrived = goal_reached(short)
    assert arrived <= 1.25 * expected, (arrived, expected)
    assert short.arrival <= 1.25 * expected
    assert arrived < 0.5 * tr.makespan
    # The makespan is the stretched schedule's, the limits and the distances hold.
    assert tr.makespan == pytest.approx(tr.stretch * sched.makespan, rel=1e-6)
    vmax, amax = fd_limits(tr)
    assert vmax <= 1.0 + 1e-5 and amax <= 1.5 + 1e-3
    rep = verify(tr, inst)
    assert rep.ok, rep.message()


def random_schedules(count: int):
    rng = np.random.default_rng(7)
    made = 0
    while made < count:
        g = Graph.grid(5, 5, obstacles=[(2, 2)])
        free = [c for c in ((x, y) for x in range(5) for y in range(5)) if c != (2, 2)]
        pick = rng.permutation(len(free))[:8]
        k = int(rng.integers(3, 5))
        starts = [free[i] for i in pick[:k]]
        goals = [free[i] for i in pick[k : 2 * k]]
        kin = Kinematics(
            v_max=float(rng.uniform(0.5, 1.5)),
            a_max=float(rng.uniform(0.5, 2)),
            radius=float(rng.uniform(0.1, 0.3)),
        )
        inst = Instance.mapf(g, starts, goals, kinematics=kin)
        res = hp.solve(inst, "cbs", time_limit=10)
        if res.plan is None:
            continue
        try:
            sched = postprocess(inst, res.plan, margin=float(rng.uniform(0.0, 0.2)))
        except ClearanceError:
            continue  # a rotation: robots with a size cannot follow this plan
        made += 1
        yield inst, sched, res.plan


def test_decoupled_windows_never_violate_a_precedence() -> None:
    rng = np.random.default_rng(1)
    for _inst, sched, _plan in random_schedules(6):
        for net in (from_schedule(sched),):
            for split in (0.0, 0.5, 1.0):
                w = decouple(net, split)
                assert violations(w) == []
                assert np.all(w.lo <= net.times + 1e-12) and np.all(net.times <= w.hi + 1e-12)
                lo = w.lo
                hi = np.where(np.isfinite(w.hi), w.hi, lo + 100.0)
                for _ in range(200):
                    # Any times inside the windows, including their ends.
                    t = lo + rng.random(len(lo)) * (hi - lo)
                    ends = rng.random(len(lo))
                    t = np.where(ends < 0.1, lo, np.where(ends > 0.9, hi, t))
                    gap = t[net.arc_dst] - t[net.arc_src]
                    assert np.all(gap >= net.arc_lb - 1e-9)


def test_processes_give_the_same_trajectories() -> None:
    inst, sched = next((i, s) for i, s, _ in random_schedules(10) if i.num_agents >= 4)
    one = refine(inst, sched, stretch="auto")
    two = refine(inst, sched, stretch="auto", workers=2)
    assert two.stretch == pytest.approx(one.stretch)
    for a, b in zip(one.robots, two.robots, strict=True):
        assert np.allclose(a.event_times, b.event_times, atol=1e-6)
    assert verify(two, inst).ok


def test_stretched_windows_stay_decoupled() -> None:
    inst, plan = crossing()
    w = decouple(from_schedule(postprocess(inst, plan)))
    assert violations(w.stretched(1.7)) == []
    with pytest.raises(hp.InputError, match="stretch factor must be >= 1"):
        w.stretched(0.5)


# ---------------------------------------------------------------------- infeasibility
def test_infeasible_windows_name_robot_waypoint_and_factor() -> None:
    inst, plan = crossing()
    sched = postprocess(inst, plan, acceleration=False)
    with pytest.raises(InfeasibleWindowsError) as ei:
        refine(inst, sched)
    msg = str(ei.value)
    assert "\n" not in msg
    assert ei.value.robot in ("agent0", "agent1")
    assert "way-point" in msg and "cannot be passed inside its window" in msg
    f = ei.value.stretch
    assert f is not None and f > 1
    # The factor is the smallest that works: a bit less fails, the factor itself works.
    assert refine(inst, sched, stretch=f).stretch == pytest.approx(f)
    with pytest.raises(InfeasibleWindowsError):
        refine(inst, sched, stretch=f / (1 + 5e-3))


def test_robot_without_acceleration_limit_is_refused() -> None:
    inst, plan = line_instance(2, Kinematics(v_max=1.0))
    with pytest.raises(hp.InputError, match="has no a_max"):
        refine(inst, postprocess(inst, plan))
    tr = refine(inst, postprocess(inst, plan), a_max=1.0, stretch="auto")
    assert tr.robots[0].limits["a_max"] == 1.0


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"model": "bicycle"}, "unknown model"),
        ({"mode": "tube"}, "unknown mode"),
        ({"solver": "snopt"}, "unknown solver"),
        ({"stretch": 0.5}, "stretch must be"),
        ({"accel_weight": -1.0}, "accel_weight must be"),
        ({"arrival_weight": float("nan")}, "arrival_weight must be"),
        ({"intervals_per_piece": 0}, "intervals_per_piece must be"),
        ({"workers": 0}, "workers must be"),
    ],
)
def test_bad_options_are_refused(kw: dict, match: str) -> None:
    inst, plan = line_instance(2, Kinematics(a_max=1.0))
    with pytest.raises(hp.OptionError, match=match):
        refine(inst, postprocess(inst, plan), **kw)


# ---------------------------------------------------------------------- 3D and unicycles
def test_quadcopters_in_3d() -> None:
    g = Graph.grid(3, 3, 3)
    kin = Kinematics("quad", v_max=1.0, a_max=2.0, radius=0.15)
    inst = Instance.mapf(g, [(0, 1, 1), (1, 0, 1)], [(2, 1, 1), (1, 2, 1)], kinematics=kin)
    res = hp.solve(inst, "cbs", time_limit=10)
    sched = postprocess(inst, res.plan)
    tr = refine(inst, sched, stretch="auto")
    assert tr.dim == 3
    rep = verify(tr, inst)
    assert rep.ok, rep.message()
    from hierplan_opt.trajectory.result import trajectories_csv

    header = [ln for ln in trajectories_csv(tr).splitlines() if not ln.startswith("#")][0]
    assert header == "agent,t,x,y,z,vx,vy,vz"


def test_unicycle_turns_in_place_at_corners() -> None:
    g = Graph.grid(3, 3)
    kin = Kinematics("pioneer", drive="differential", v_max=0.5, a_max=1.0, omega_max=1.0)
    inst = Instance.mapf(g, [(0, 0)], [(2, 2)], kinematics=kin)
    v = g.vertex
    plan = Plan.from_paths([[v((0, 0)), v((1, 0)), v((2, 0)), v((2, 1)), v((2, 2))]])
    sched = postprocess(inst, plan)
    tr = refine(inst, sched, stretch="auto")
    r = tr.robots[0]
    assert r.model == "unicycle"
    ts = np.linspace(0, r.arrival, 4001)
    st = r.state(ts)
    at_corner = np.linalg.norm(st["p"] - np.array([2.0, 0.0]), axis=1) < 1e-9
    # While at the corner the robot turns from heading 0 to pi/2 without moving.
    assert at_corner.any()
    th = st["theta"][at_corner]
    assert th.min() == pytest.approx(0.0, abs=1e-6) and th.max() == pytest.approx(
        math.pi / 2, abs=1e-6
    )
    assert np.all(np.linalg.norm(st["v"][at_corner], axis=1) < 1e-6)
    assert np.abs(st["omega"]).max() <= 1.0 + 1e-6
    # Never sideways: the velocity points along the heading.
    head = np.stack([np.cos(st["theta"]), np.sin(st["theta"])], axis=1)
    side = np.abs(st["v"][:, 0] * head[:, 1] - st["v"][:, 1] * head[:, 0])
    assert side.max() < 1e-6
    assert verify(tr, inst).ok
    from hierplan_opt.trajectory.result import trajectories_csv

    header = [ln for ln in trajectories_csv(tr).splitlines() if not ln.startswith("#")][0]
    assert header == "agent,t,x,y,vx,vy,theta"


def test_unicycle_model_needs_omega_max() -> None:
    inst, plan = line_instance(2, Kinematics(a_max=1.0))
    with pytest.raises(hp.InputError, match="needs omega_max"):
        refine(inst, postprocess(inst, plan), model="unicycle")


# ---------------------------------------------------------------------- clearance, corridor
def motion_in_windows(net, w, j: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """A random motion of robot ``j`` forward along its path that passes every event with a
    window at a random time inside it (its ends included), the others in between, and
    between two events dawdles: it covers a random part of the piece at once, then stops
    or creeps. Times increase strictly (a continuous motion, however fast)."""
    ev = np.array(list(net.events(j)))
    tied = (w.lo[ev] > 0) | np.isfinite(w.hi[ev])
    tied[0] = tied[-1] = True
    k = np.flatnonzero(tied)
    lo = np.maximum.accumulate(w.lo[ev[k]])
    hi = np.where(np.isfinite(w.hi[ev[k]]), w.hi[ev[k]], lo + 5.0)
    hi = np.maximum(np.minimum.accumulate(hi[::-1])[::-1], lo)
    tk = np.empty(len(k))
    t_prev = -1.0
    for q in range(len(k)):
        nxt = hi[q + 1] if q + 1 < len(k) else np.inf
        u = rng.random()
        if u < 0.2 and lo[q] > t_prev:
            t = lo[q]
        elif u > 0.8 and hi[q] < nxt and hi[q] > t_prev:
            t = hi[q]
        else:
            a = max(lo[q], t_prev)
            t = a + (0.001 + 0.998 * rng.random()) * (hi[q] - a)
        tk[q] = t_prev = t
    times = np.interp(np.arange(len(ev)), k, tk)  # the others in between, then jittered
    for q in range(len(k) - 1):
        inner = np.arange(k[q] + 1, k[q + 1])
        if len(inner):
            f = np.sort(rng.uniform(0.001, 0.999, len(inner)))
            times[inner] = tk[q] + f * (tk[q + 1] - tk[q])
    ts, ps = [float(times[0])], [net.pos[ev[0]].astype(float)]
    for i in range(1, len(ev)):
        f, g = rng.random(), 0.001 + 0.998 * rng.random() ** 3
        ts.append(ts[-1] + g * (times[i] - ts[-1]))
        ps.append(ps[-1] + f * (net.pos[ev[i]] - ps[-1]))
        ts.append(float(times[i]))
        ps.append(net.pos[ev[i]].astype(float))
    return np.array(ts), np.array(ps)


def closest(ta, pa, tb, pb) -> float:
    """Exact minimum distance of two piecewise-linear motions (at rest outside them)."""
    T = np.union1d(ta, tb)
    A = np.stack([np.interp(T, ta, pa[:, d]) for d in range(pa.shape[1])], axis=1)
    B = np.stack([np.interp(T, tb, pb[:, d]) for d in range(pb.shape[1])], axis=1)
    r0 = (A - B)[:-1]
    dr = (A - B)[1:] - r0
    dd = (dr * dr).sum(axis=1)
    s = np.clip(-(r0 * dr).sum(axis=1) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    d = np.linalg.norm(r0 + dr * s[:, None], axis=1)
    return float(min(d.min(initial=np.inf), np.linalg.norm(A[-1] - B[-1])))


def worst_gap(sched, rng, motions: int) -> float:
    """Smallest ``distance - (r_i + r_j + margin)`` over random motions in the windows."""
    net = from_schedule(sched)
    worst = np.inf
    for split in (0.0, 0.5, 1.0):
        w = decouple(net, split)
        for _ in range(motions):
            mo = [motion_in_windows(net, w, j, rng) for j in range(net.num_agents)]
            for i in range(net.num_agents):
                for j in range(i + 1, net.num_agents):
                    d = closest(*mo[i], *mo[j])
                    worst = min(worst, d - float(net.radius[i] + net.radius[j] + sched.margin))
    return worst


def test_any_motion_inside_the_decoupled_windows_keeps_the_clearance() -> None:
    # The claim argument of MAPF-POST (docs/post.md) for refined robots: robots that move
    # forward on their paths and pass every event inside its decoupled window keep
    # r_i + r_j + margin, however they speed up, stop or creep between the events
    # (the case the following points of earlier versions were for). Without the
    # clearance markers (clearance=False) the same motions collide.
    rng = np.random.default_rng(3)
    plain = []
    for inst, sched, plan in random_schedules(6):
        assert worst_gap(sched, rng, 30) >= -1e-9
        plain.append(worst_gap(postprocess(inst, plan, clearance=False), rng, 5))
    assert min(plain) < -0.05


def test_a_refined_follower_keeps_its_distance() -> None:
    g = Graph.grid(6, 1)
    kin = Kinematics(v_max=1.0, a_max=1.0, radius=0.3)
    inst = Instance.mapf(g, [(1, 0), (0, 0)], [(5, 0), (4, 0)], kinematics=kin)
    plan = Plan.from_paths([[1, 2, 3, 4, 5], [0, 1, 2, 3, 4]])
    sched = postprocess(inst, plan)
    tr = refine(inst, sched, stretch="auto")
    assert tr.safety_distance == pytest.approx(0.6) == sched.safety_distance
    assert tr.required(0, 1) == pytest.approx(0.6)
    rep = verify(tr, inst)
    assert rep.ok, rep.message()
    assert rep.min_distance >= 0.6 - 1e-9 and rep.worst_gap >= -1e-9
    # Without clearance the schedule guarantees nothing, and the refinement says so.
    loose = refine(inst, postprocess(inst, plan, clearance=False), stretch="auto")
    assert loose.safety_distance == 0 and "without clearance" in loose.guarantee


def test_corridor_cuts_corners_and_loses_2c() -> None:
    g = Graph.grid(4, 4)
    kin = Kinematics(v_max=1.0, a_max=1.0)
    inst = Instance.mapf(g, [(0, 0)], [(3, 3)], kinematics=kin)
    v = g.vertex
    plan = Plan.from_paths(
        [[v((0, 0)), v((1, 0)), v((1, 1)), v((2, 1)), v((2, 2)), v((3, 2)), v((3, 3))]]
    )
    sched = postprocess(inst, plan)
    c = 0.2
    path = refine(inst, sched, stretch="auto")
    corr = refine(inst, sched, mode="corridor", corridor=c, stretch="auto")
    assert corr.corridor == c and "2c" in corr.guarantee
    rep = verify(corr, inst)
    assert rep.ok, rep.message()
    from hierplan_opt.schedule.geometry import segment_distance

    P = corr.sample(0.01)["pos"][0]
    W = corr.windows.network.pos
    d = np.min(
        [
            segment_distance(
                P, P, np.repeat(W[i : i + 1], len(P), 0), np.repeat(W[i + 1 : i + 2], len(P), 0)
            )
            for i in range(len(W) - 1)
        ],
        axis=0,
    )
    assert 0.05 < d.max() <= c + 1e-6  # it left the polyline, but not the corridor
    # Cutting the staircase's corners is faster than stopping at each of them.
    assert corr.makespan <= path.makespan + 1e-6


def test_corridor_mode_refuses_unicycles() -> None:
    g = Graph.grid(3, 1)
    kin = Kinematics("p", drive="differential", v_max=0.5, a_max=1.0, omega_max=1.0)
    inst = Instance.mapf(g, [(0, 0)], [(2, 0)], kinematics=kin)
    sched = postprocess(inst, Plan.from_paths([[0, 1, 2]]))
    with pytest.raises(hp.OptionError, match="corridor mode"):
        refine(inst, sched, mode="corridor")


# ---------------------------------------------------------------------- the verifier
def test_verifier_catches_broken_trajectories() -> None:
    inst, plan = crossing()
    sched = postprocess(inst, plan)
    tr = refine(inst, sched, stretch="auto")
    assert verify(tr, inst).ok
    r0 = tr.robots[0]
    # Twice as fast: every limit and window broken.
    fast = replace(r0, t=r0.t / 2, v=r0.v * 2, a=r0.a * 4, event_times=r0.event_times / 2)
    rep = verify(replace(tr, robots=(fast, *tr.robots[1:])), inst)
    assert not rep.ok
    assert any("speed" in p for p in rep.problems)
    assert any("outside its window" in p for p in rep.problems)
    # A robot moved off its path.
    off = replace(r0, p=r0.p + np.array([0.0, 0.3]))
    rep = verify(replace(tr, robots=(off, *tr.robots[1:])), inst)
    assert any("off its path" in p for p in rep.problems)
    # A claim the motion does not keep.
    rep = verify(replace(tr, safety_distance=5.0), inst)
    assert not rep.ok and "they must keep" in rep.problems[-1]
    # A robot standing at its goal after it arrives is checked there as on the way:
    # the same report when the rest is an explicit piece of motion up to the makespan.
    H = 2 * tr.makespan
    for r in (r0, fast):
        z = np.zeros((1, r.p.shape[1]))
        held = replace(
            r,
            t=np.append(r.t, H),
            p=np.vstack([r.p, r.p[-1:]]),
            v=np.vstack([r.v, z]),
            a=np.vstack([r.a, z]),
            theta=np.append(r.theta, r.theta[-1]),
            omega=np.append(r.omega, 0.0),
            alpha=np.append(r.alpha, 0.0),
        )
        reps = [verify(replace(tr, robots=(x, *tr.robots[1:])), inst) for x in (r, held)]
        a_, b_ = (
            (x.ok, x.num_problems, x.min_distance, x.min_time, x.worst_gap, x.max_speed_ratio)
            for x in reps
        )
        assert a_ == pytest.approx(b_, abs=1e-12)
        assert reps[0].max_accel_ratio == pytest.approx(reps[1].max_accel_ratio)
        assert reps[0].max_path_error == pytest.approx(reps[1].max_path_error, abs=1e-12)


def test_output_files(tmp_path) -> None:
    from hierplan_opt.trajectory import write_trajectories

    inst, plan = crossing()
    tr = refine(inst, postprocess(inst, plan), stretch="auto")
    csv_path = write_trajectories(tr, tmp_path / "t.csv", dt=0.5)
    rows = [ln for ln in csv_path.read_text().splitlines() if not ln.startswith("#")]
    assert rows[0] == "agent,t,x,y,vx,vy"
    S = len(tr.sample(0.5)["t"])
    assert len(rows) == 1 + 2 * S
    npz = np.load(write_trajectories(tr, tmp_path / "t.npz"))
    assert npz["pos"].shape == (2, len(npz["t"]), 2)
    with pytest.raises(hp.InputError, match="must end in .csv or .npz"):
        write_trajectories(tr, tmp_path / "t.txt")


# ---------------------------------------------------------------- issue 34
def test_a_pair_exactly_at_its_distance_verifies() -> None:
    # Two robots of radius 0.5 one cell apart: the sampled bound subtracted
    # (a_i + a_j) dt^2 / 8 and read 0.9999 for the 1 m they keep exactly
    import hierplan_opt as hp
    from hierplan_opt.core.instance import Kinematics
    from hierplan_opt.schedule import postprocess
    from hierplan_opt.trajectory import refine
    from hierplan_opt.trajectory.verify import verify

    kin = Kinematics(v_max=1.0, a_max=1.0, radius=0.5)
    inst = hp.Instance.mapf(hp.Graph.grid(5, 1), [(0, 0), (1, 0)], [(3, 0), (4, 0)],
                            kinematics=kin)  # fmt: skip
    res = hp.solve(inst, "cbs")
    assert res.plan is not None
    sched = postprocess(inst, res.plan)
    for solver in ("ipopt", "profile", "profile+qp"):
        rep = verify(refine(inst, sched, stretch="auto", solver=solver), inst)
        assert rep.ok, (solver, rep.problems)
        assert abs(rep.min_distance - 1.0) < 1e-9


def test_exact_check_still_catches_a_pair_too_close() -> None:
    from hierplan_opt.trajectory.result import RobotTrajectory
    from hierplan_opt.trajectory.verify import _exact_min_distance

    z = np.zeros((2, 2))
    still = RobotTrajectory("a", "double_integrator", np.array([0.0, 2.0]), z, z,
                            np.zeros((1, 2)), np.zeros(2), np.zeros(2), np.zeros(1),
                            np.zeros(1), {})  # fmt: skip
    # passes 0.69 m from the other, between two samples of any grid
    mover = RobotTrajectory("b", "double_integrator", np.array([0.0, 2.0]),
                            np.array([[-1.0, 0.69], [1.0, 0.69]]),
                            np.array([[1.0, 0.0], [1.0, 0.0]]), np.zeros((1, 2)),
                            np.zeros(2), np.zeros(2), np.zeros(1), np.zeros(1), {})  # fmt: skip
    d, t = _exact_min_distance(still, mover, 0.0, 2.0)
    assert abs(d - 0.69) < 1e-12 and abs(t - 1.0) < 1e-12


def test_passage_time_with_round_off_acceleration() -> None:
    # a = -1.5e-12 (a profile's round-off): (disc - v) / a lost 3e-5 s to cancellation
    import importlib

    R = importlib.import_module("hierplan_opt.trajectory.refine")
    v, a = 0.38777744, -1.52688837e-12
    t = R.passage_times(np.array([0.0, 0.5]), np.array([v, v]), np.array([0.0, 0.5 / v]),
                        np.array([a]), np.array([0.3]))  # fmt: skip
    assert abs(float(t[0]) - 0.3 / v) < 1e-9  # was off by 2.6e-5 s
