"""MuJoCo physics (issue 33): robot models, controllers, disturbances, measurements."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

from hierplan_opt.core.instance import Kinematics
from hierplan_opt.physics.disturbances import (
    Payload,
    RobotStop,
    Spill,
    WeakMotor,
    Wind,
)
from hierplan_opt.physics.models import robot_model
from hierplan_opt.physics.plant import MujocoPlant

YOUBOT = Kinematics("youbot", drive="omni", v_max=0.8, a_max=1.0, radius=0.35)
PIONEER = Kinematics(
    "pioneer", drive="differential", v_max=0.6, omega_max=1.5, a_max=0.3, radius=0.3
)
CREATE = Kinematics(
    "create2", drive="differential", v_max=0.5, omega_max=2.0, a_max=0.5, radius=0.17
)
QUAD = Kinematics("quad", drive="omni", v_max=1.0, a_max=2.0, radius=0.15)
KINDS = [("omni", YOUBOT, 2), ("diff", PIONEER, 2), ("diff", CREATE, 2), ("quad", QUAD, 3)]


def _plant(k: Kinematics, dim: int, n: int = 1, starts=None, **kw) -> MujocoPlant:
    models = [robot_model(k, dim) for _ in range(n)]
    s = np.zeros((n, 3)) if starts is None else np.asarray(starts, float)
    return MujocoPlant(models, s, **kw)


def _drive(p: MujocoPlant, wp, times, until: float, robot: int = 0) -> None:
    p.assign(robot, np.asarray(wp, float), np.asarray(times, float))
    p.release(robot, len(wp) - 1)
    while p.time < until:
        p.step(0.1)


def _speeds(p: MujocoPlant, robot: int = 0) -> tuple[np.ndarray, np.ndarray]:
    t, pos = p.samples
    v = np.linalg.norm(np.diff(pos[:, robot], axis=0), axis=1) / np.diff(t)
    return t[1:], v


@pytest.mark.parametrize(("kind", "k", "dim"), KINDS)
def test_models_from_robot_types(kind, k, dim):
    m = robot_model(k, dim)
    assert m.kind == kind
    assert m.v_max == k.v_max and m.radius == k.radius
    assert m.mass > 0 and m.force_max > 0


@pytest.mark.parametrize(("kind", "k", "dim"), KINDS)
def test_straight_line_within_limits(kind, k, dim):
    p = _plant(k, dim)
    # Due a little before it can: it drives at full speed and arrives late.
    _drive(p, [[2.0, 0, 0]], [2.0 / k.v_max], until=2.0 / k.v_max + 6.0)
    assert p.reached(0) == 0
    assert np.linalg.norm(p.positions()[0] - [2.0, 0, 0]) < 0.05
    _t, v = _speeds(p)
    assert v.max() <= 1.05 * k.v_max
    # Acceleration over 0.1 s windows within the robot type's a_max (+20 % for the
    # servo's transient), and it did speed up (not a crawl).
    a = np.abs(v[5:] - v[:-5]) / 0.1
    assert a.max() <= 1.2 * (k.a_max or 1.0)
    assert v.max() > 0.9 * k.v_max


@pytest.mark.parametrize(("kind", "k", "dim"), KINDS)
def test_corner(kind, k, dim):
    p = _plant(k, dim)
    c = [1.0, 0, 0]
    e = [1.0, 1.0, 0] if dim == 2 else [1.0, 0, 1.0]
    _drive(p, [c, e], [4.0, 9.0], until=12.0)
    assert p.reached(0) == 1
    assert np.linalg.norm(p.positions()[0] - e) < 0.05
    # It went through the corner: never far from the two legs of the L.
    _t, pos = p.samples
    xy = pos[:, 0]
    off1 = np.abs(xy[:, 1] if dim == 2 else xy[:, 2])  # distance from the first leg
    off2 = np.abs(xy[:, 0] - 1.0)  # from the second
    assert np.minimum(off1, off2).max() < 0.1
    _t, v = _speeds(p)
    assert v.max() <= 1.05 * k.v_max


@pytest.mark.parametrize("k", [PIONEER, CREATE])
def test_turn_in_place(k):
    p = _plant(k, 2)
    # Way-point behind-left: the robot turns in place first, then drives.
    _drive(p, [[0.0, 1.0, 0]], [6.0], until=8.0)
    t, pos = p.samples
    yaw_samples: list[float] = []
    assert p.reached(0) == 0
    # Turning phase: it stays on its spot while its heading changes by pi/2.
    still = np.linalg.norm(pos[:, 0, :2], axis=1) < 0.02
    assert still[: int(0.5 / p.control_period)].all()
    assert abs(p.headings()[0] - math.pi / 2) < 0.1
    # The turn took at least (pi/2) / omega_max.
    moving = np.flatnonzero(~still)
    assert t[moving[0]] >= (math.pi / 2) / k.omega_max * 0.95
    del yaw_samples


def test_omni_does_not_turn():
    p = _plant(YOUBOT, 2)
    _drive(p, [[0.0, 1.0, 0]], [3.0], until=5.0)
    assert p.reached(0) == 0
    assert abs(p.headings()[0]) < 0.05


@pytest.mark.parametrize(("kind", "k", "dim"), KINDS)
def test_controller_stops_at_held_waypoint(kind, k, dim):
    p = _plant(k, dim)
    wp = np.array([[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    p.assign(0, wp, np.array([2.0, 4.0, 6.0]))
    p.release(0, 0)  # may go up to way-point 0 only
    for _ in range(80):
        p.step(0.1)
    assert p.reached(0) == 0
    assert np.linalg.norm(p.positions()[0] - wp[0]) < 0.06
    p.release(0, 2)
    for _ in range(80):
        p.step(0.1)
    assert p.reached(0) == 2
    assert np.linalg.norm(p.positions()[0] - wp[2]) < 0.06


def test_gate_minus_one_holds_in_place():
    p = _plant(YOUBOT, 2)
    p.assign(0, np.array([[1.0, 0, 0]]), np.array([1.0]))
    for _ in range(30):
        p.step(0.1)
    assert p.reached(0) == -1
    assert np.linalg.norm(p.positions()[0]) < 0.01


def test_never_early():
    p = _plant(YOUBOT, 2)
    _drive(p, [[1.0, 0, 0]], [5.0], until=7.0)
    (_k, t_reach) = p.reach_log[0][0]
    assert t_reach >= 5.0 - p.early - 1e-9


def test_retime_changes_arrival():
    p = _plant(YOUBOT, 2)
    p.assign(0, np.array([[1.0, 0, 0]]), np.array([2.0]))
    p.release(0, 0)
    p.retime(0, np.array([6.0]))
    for _ in range(80):
        p.step(0.1)
    assert p.reach_log[0][0][1] >= 6.0 - p.early - 1e-9


def _crossing_time(k, dim, disturbances) -> float:
    p = _plant(k, dim, names=["r"], disturbances=disturbances)
    _drive(p, [[2.0, 0, 0], [2.0, 2.0, 0]], [0.1, 0.2], until=30.0)
    assert p.reached(0) == 1
    return p.reach_log[0][1][1]


@pytest.mark.parametrize("k", [YOUBOT, PIONEER])
def test_low_friction_region_slows_a_robot(k):
    # The robot brakes to a stop at the corner and starts again on the spill.
    base = _crossing_time(k, 2, [])
    spill = Spill(((1.0, -1.0, 3.0, 3.0),), friction=0.02)
    slow = _crossing_time(k, 2, [spill])
    assert slow > base + 0.5


def test_payload_and_weak_motor_slow_a_robot():
    base = _crossing_time(YOUBOT, 2, [])
    heavy = _crossing_time(YOUBOT, 2, [Payload("r", 60.0)])
    weak = _crossing_time(YOUBOT, 2, [WeakMotor("r", 0.2)])
    assert heavy > base + 0.2
    assert weak > base + 0.2


def test_wind_pushes_a_quadcopter():
    def err(dist):
        p = _plant(QUAD, 3, names=["q"], disturbances=dist)
        p.assign(0, np.array([[0.0, 0, 0]]), np.array([0.0]))
        p.release(0, 0)
        worst = 0.0
        while p.time < 3.0:
            p.step(0.05)
            worst = max(worst, float(np.linalg.norm(p.positions()[0])))
        return worst

    calm = err([])
    gust = err([Wind((0.0, 6.0, 0.0), start=0.5, end=1.5)])
    assert calm < 0.01
    assert gust > 0.03


def test_robot_stop_and_breakdown():
    p = _plant(YOUBOT, 2, n=2, starts=[[0, 0, 0], [0, 2, 0]], names=["a", "b"],
               disturbances=[RobotStop("a", 1.0, None), RobotStop("b", 1.0, 3.0)])  # fmt: skip
    p.assign(0, np.array([[4.0, 0, 0]]), np.array([5.0]))
    p.assign(1, np.array([[4.0, 2, 0]]), np.array([5.0]))
    p.release(0, 0)
    p.release(1, 0)
    for _ in range(30):
        p.step(0.1)
    x_a = p.positions()[0, 0]
    for _ in range(100):
        p.step(0.1)
    assert p.broken[0] and not p.broken[1]
    assert abs(p.positions()[0, 0] - x_a) < 0.01  # stays stopped
    assert p.reached(0) == -1 and p.reached(1) == 0
    assert p.reach_log[1][0][1] > 5.0 + 1.0  # the 3 s stop made it late


def test_contacts_and_distances_are_measured():
    # Two youBots driven head-on without gates: the engine reports the contact and
    # the measured distance drops below the sum of the radii.
    p = _plant(YOUBOT, 2, n=2, starts=[[0, 0, 0], [3, 0, 0]])
    p.assign(0, np.array([[3.0, 0, 0]]), np.array([4.0]))
    p.assign(1, np.array([[0.0, 0, 0]]), np.array([4.0]))
    p.release(0, 0)
    p.release(1, 0)
    for _ in range(60):
        p.step(0.1)
    me = p.measure
    assert me.contacts > 0 and me.contact_pairs == {(0, 1)}
    assert me.min_distance < 0.7
    assert me.min_margin < 0


def test_parallel_robots_keep_distance():
    p = _plant(YOUBOT, 2, n=2, starts=[[0, 0, 0], [0, 1, 0]])
    p.assign(0, np.array([[3.0, 0, 0]]), np.array([4.0]))
    p.assign(1, np.array([[3.0, 1, 0]]), np.array([4.0]))
    p.release(0, 0)
    p.release(1, 0)
    for _ in range(60):
        p.step(0.1)
    assert p.measure.contacts == 0
    assert abs(p.measure.min_distance - 1.0) < 0.02
    assert p.measure.min_margin == pytest.approx(p.measure.min_distance - 0.7)


def test_identical_runs_for_identical_seeds():
    def run(seed):
        p = _plant(PIONEER, 2, seed=seed, noise=0.01)
        _drive(p, [[1.0, 0, 0], [1.0, 1.0, 0]], [4.0, 9.0], until=10.0)
        return p.samples[1]

    a, b, c = run(3), run(3), run(4)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_mixed_fleet_omni_moves_sideways():
    # Reproducer: with a differential drive in the world, an omni robot whose heading
    # differs from its direction of travel was held still (the turn-in-place rule
    # applied to every robot).
    models = [robot_model(YOUBOT, 2), robot_model(PIONEER, 2)]
    p = MujocoPlant(models, np.array([[0.0, 0, 0], [5.0, 0, 0]]))
    p.assign(0, np.array([[0.0, 1.5, 0]]), np.array([3.0]))
    p.release(0, 0)
    for _ in range(50):
        p.step(0.1)
    assert p.reached(0) == 0
    assert abs(p.headings()[0]) < 0.05
