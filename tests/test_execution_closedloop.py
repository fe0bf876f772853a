"""Closed-loop robot mode (issue 30 item 5): the kinematic plant alone, the monitor over
any Plant, and the robots' dynamics feeding back into the layers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt.core.instance import Kinematics
from hierplan_opt.execution import Slow, Stop, load_disturbances, simulate
from hierplan_opt.execution.closed_loop import ClosedLoop
from hierplan_opt.execution.kinematic import KinematicPlant
from hierplan_opt.execution.plant import Plant
from hierplan_opt.schedule import postprocess
from hierplan_opt.schedule.replay import _pair_min

ROOT = Path(__file__).resolve().parent.parent
WAREHOUSE = ROOT / "instances" / "paper" / "warehouse-part1.yaml"
DISTURBANCES = ROOT / "instances" / "paper" / "warehouse-disturbances.yaml"


def drive(plant: KinematicPlant, steps: int, dt: float) -> np.ndarray:
    out = [plant.positions()[0].copy()]
    for _ in range(steps):
        plant.step(dt)
        out.append(plant.positions()[0].copy())
    return np.array(out)


def test_kinematic_plant_keeps_its_acceleration_and_its_gate() -> None:
    dt = 0.05
    p = KinematicPlant([Kinematics(v_max=1.0, a_max=0.5)], np.zeros((1, 3)))
    route = np.array([[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0], [3.0, 2.0, 0]])
    p.assign(0, route, np.zeros(4))
    p.release(0, 1)  # it may not pass way-point 1
    xs = drive(p, 200, dt)
    assert p.reached(0) == 1 and np.allclose(xs[-1], [2, 0, 0])
    v = np.linalg.norm(np.diff(xs, axis=0), axis=1) / dt
    assert np.all(np.abs(np.diff(v)) / dt <= 0.5 * (1 + 1e-6) + 1e-9)
    assert xs[:, 0].max() <= 2.0 + 1e-12
    p.release(0, 3)
    xs = drive(p, 400, dt)
    assert p.reached(0) == 3 and np.allclose(xs[-1], [3, 2, 0]) and p.violations == 0


def test_differential_robot_turns_in_place_and_slippery_regions_slow_it() -> None:
    kin = Kinematics(drive="differential", v_max=1.0, omega_max=math.pi / 2, a_max=2.0)
    p = KinematicPlant([kin], np.zeros((1, 3)), headings=np.array([0.0]))
    p.assign(0, np.array([[0.0, 1.0, 0.0]]), np.zeros(1))
    p.release(0, 0)
    xs = drive(p, 10, 0.1)  # a quarter turn takes 1 s: it stands still meanwhile
    assert np.allclose(xs, 0.0)
    xs = drive(p, 40, 0.1)
    assert np.allclose(xs[-1], [0, 1, 0])
    # The same straight run, once on ice (speed and speeding up at 0.2): later.
    times = []
    for slippery in ((), [(np.array([[1.0, 0, 0], [2.0, 0, 0]]), 0.5, 0.2, 0.0, math.inf)]):
        q = KinematicPlant([Kinematics(v_max=1.0, a_max=1.0)], np.zeros((1, 3)), slippery=slippery)
        q.assign(0, np.array([[3.0, 0, 0]]), np.zeros(1))
        q.release(0, 0)
        while q.reached(0) < 0:
            q.step(0.05)
        times.append(q.time)
        assert q.violations == 0
    assert times[1] > times[0] + 1.0


class ExactPlant:
    """A trivially exact plant: constant speed ``v`` straight to each way-point, no
    earlier than its time (what agent mode assumes)."""

    def __init__(self, start: np.ndarray, v: np.ndarray) -> None:
        self.time = 0.0
        self.pos = np.array(start, dtype=float)
        self.v = v
        n = len(start)
        self.routes = [self.pos[i : i + 1].copy() for i in range(n)]
        self.times = [np.zeros(1) for _ in range(n)]
        self.gate = [-1] * n
        self.done = [0] * n
        self.broken = [False] * n

    def positions(self) -> np.ndarray:
        return self.pos.copy()

    def assign(self, robot: int, waypoints: np.ndarray, times: np.ndarray) -> None:
        self.routes[robot], self.times[robot] = np.array(waypoints), np.array(times)
        self.gate[robot], self.done[robot] = -1, -1

    def release(self, robot: int, gate: int) -> None:
        self.gate[robot] = gate

    def retime(self, robot: int, times: np.ndarray) -> None:
        self.times[robot] = np.array(times)

    def reached(self, robot: int) -> int:
        return self.done[robot]

    def stop(self, robot: int) -> None:
        self.broken[robot] = True

    def step(self, dt: float) -> None:
        self.time += dt
        for i in range(len(self.pos)):
            s = self.v[i] * dt
            while not self.broken[i] and s > 1e-12:
                k = self.done[i] + 1
                if k > self.gate[i] or k >= len(self.routes[i]):
                    break
                d = float(np.linalg.norm(self.routes[i][k] - self.pos[i]))
                if d <= s:
                    if self.time < self.times[i][k] - 1e-9:
                        self.pos[i] = self.routes[i][k]
                        break
                    self.pos[i], self.done[i], s = self.routes[i][k], k, s - d
                else:
                    self.pos[i] += (self.routes[i][k] - self.pos[i]) / d * s
                    s = 0.0


@pytest.fixture(scope="module")
def warehouse():
    inst = hp.load_instance(WAREHOUSE)
    res = hp.solve(inst, "cbm", time_limit=60)
    assert res.plan is not None
    return inst, postprocess(inst, res.plan)


def min_gap(ex, inst) -> float:
    tr = ex.trajectories
    r = [a.kinematics.radius for a in inst.agents]
    best = math.inf
    for a in range(len(tr)):
        for b in range(a + 1, len(tr)):
            d, _ = _pair_min(tr[a][:, 0], tr[a][:, 1:], tr[b][:, 0], tr[b][:, 1:])
            best = min(best, d - r[a] - r[b])
    return best


def test_monitor_drives_any_plant(warehouse) -> None:
    inst, s = warehouse
    start = np.zeros((inst.num_agents, 3))
    start[:, :2] = np.array([w.coords[0] for w in s.waypoints]) * s.scale
    v = np.array([a.kinematics.v_max for a in inst.agents]) * s.scale
    plant = ExactPlant(start, v)
    assert isinstance(plant, object) and all(
        hasattr(plant, m) for m in Plant.__dict__ if m[0] != "_"
    )
    dist = load_disturbances(DISTURBANCES, tuple(a.name for a in inst.agents))
    ex = ClosedLoop(inst, s, plant, disturbances=dist, dt=0.05).run()
    st = ex.statistics
    assert st["loop"] == "closed" and st["collisions"] == 0 and min_gap(ex, inst) > 0
    assert st["broken"] == ["youbot8"] and st["stranded"] == [] and st["replans"] >= 1


@pytest.mark.parametrize("policy", ["slack", "stn", "replan", "reorder", "adg"])
def test_robot_mode_is_closed_loop_and_safe(warehouse, policy: str) -> None:
    inst, s = warehouse
    dist = load_disturbances(DISTURBANCES, tuple(a.name for a in inst.agents))
    ex = simulate(inst, s, disturbances=dist, policy=policy, mode="robot", dt=0.05)
    st = ex.statistics
    assert st["loop"] == "closed" and st["collisions"] == 0 and min_gap(ex, inst) > 0
    assert st["acceleration_violations"] == 0
    if policy in ("replan", "reorder"):
        assert st["stranded"] == [] and st["replans"] >= 1
    else:  # youbot7 (and whoever waits for it) waits for good, and the report says so
        assert "youbot7" in st["stranded"]
        assert all("blocked" in st["why_unfinished"][n] for n in st["stranded"])


def test_dynamics_feed_back_into_the_layers(warehouse) -> None:
    """Ice on youbot1's way makes it late: the closed loop re-solves the STN; the open
    loop replay of the agent run (no ice in agent mode beyond its speed factor) cannot."""
    inst, s = warehouse
    tpg = s.stn.tpg
    g = inst.graph
    cells = {tuple(int(c) for c in tpg.node_coord[v]) for v in tpg.agent_nodes(0)}
    cells = [c for c in cells if g.passable[g.vertex(c)]]
    ice = [Slow(0.25, tuple(cells))]
    ex = simulate(inst, s, disturbances=ice, policy="stn", mode="robot", dt=0.05)
    late = [e for e in ex.log if e.kind == "late" and e.agent == "youbot1"]
    assert late and {e.layer for e in late} <= {"slack", "stn"} and "stn" in {e.layer for e in late}
    assert ex.statistics["collisions"] == 0 and ex.statistics["stn_resolves"] >= 1


def test_point_robot_waits_before_a_gated_goal() -> None:
    """Point robots at margin 0 (plain TPG): b's goal is a vertex that a passes first.
    a is held, so b is early; it must wait before its goal, not on it (the monitor never
    gated a route's last node, and b stood on the vertex a drove through)."""
    g = hp.Graph.grid(5, 2)
    inst = hp.Instance.mapf(g, [(0, 0), (2, 1)], [(4, 0), (2, 0)])
    plan = hp.solve(inst, "cbs").plan
    assert plan is not None
    s = postprocess(inst, plan, margin=0)
    assert s.stn is not None and s.stn.tpg.regime == "none"
    names = [a.name for a in inst.agents]
    hold = [Stop(names[0], 4.0, at_time=0.5)]
    ex = simulate(inst, s, disturbances=hold, policy="slack", mode="robot", dt=0.05)
    ta, tb = ex.trajectories
    gap, _ = _pair_min(ta[:, 0], ta[:, 1:], tb[:, 0], tb[:, 1:])  # exact, between samples too
    assert gap > 1e-6
    assert ex.statistics["collisions"] == 0
    assert np.allclose(tb[-1, 1:3], [2, 0])  # b still reaches its goal
