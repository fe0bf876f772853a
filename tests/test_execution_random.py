"""Random instances (issue 30 targets): grids with obstacles, point robots and mixed
robot types, random delays and breakdowns. For simulate in agent mode under every policy
but ``naive``, robot mode (closed loop) and ``hierplan_opt.run``, no two robots come
closer than ``r_i + r_j`` (point robots: never on one point), checked by a continuous-time
distance computation written here (not the package's replay).

A handful of instances run in the default suite; 200 under ``pytest -m slow``.
"""

from __future__ import annotations

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt.core.instance import Kinematics
from hierplan_opt.execution import Breakdown, RandomDelays, simulate

POLICIES = ("slack", "stn", "replan", "reorder", "adg")
TYPES = (
    Kinematics("small", "omni", v_max=1.0, a_max=2.0, radius=0.2),
    Kinematics("large", "omni", v_max=0.7, a_max=1.0, radius=0.35),
)


def pair_min_distance(ta: np.ndarray, pa: np.ndarray, tb: np.ndarray, pb: np.ndarray) -> float:
    """Exact smallest distance of two robots moving straight at constant speed between
    their way-points ``(t, p)`` (standing still before the first and after the last)."""
    ts = np.union1d(ta, tb)
    a = np.column_stack([np.interp(ts, ta, pa[:, k]) for k in range(pa.shape[1])])
    b = np.column_stack([np.interp(ts, tb, pb[:, k]) for k in range(pb.shape[1])])
    d = a - b
    if len(ts) == 1:
        return float(np.linalg.norm(d[0]))
    d0, e = d[:-1], d[1:] - d[:-1]
    ee = np.einsum("ij,ij->i", e, e)
    s = np.clip(-np.einsum("ij,ij->i", d0, e) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    return float(np.min(np.linalg.norm(d0 + s[:, None] * e, axis=1)))


def touching_pairs(trajectories, radii) -> list[tuple[int, int, float]]:
    """Pairs closer than ``r_i + r_j`` or on one point (independent of the package)."""
    K = len(trajectories)
    lo = np.array([tr[:, 1:].min(axis=0) for tr in trajectories])
    hi = np.array([tr[:, 1:].max(axis=0) for tr in trajectories])
    bad = []
    for i in range(K):
        for j in range(i + 1, K):
            need = radii[i] + radii[j]
            gap = np.maximum(0.0, np.maximum(lo[i] - hi[j], lo[j] - hi[i]))
            if np.linalg.norm(gap) > need + 1e-6:
                continue  # their whole ways stay apart
            ti, pi = trajectories[i][:, 0], trajectories[i][:, 1:]
            tj, pj = trajectories[j][:, 0], trajectories[j][:, 1:]
            d = pair_min_distance(ti, pi, tj, pj)
            if d < need - 1e-9 * max(1.0, need) or d <= 1e-9:
                bad.append((i, j, d))
    return bad


def random_case(seed: int, robots: int) -> tuple[hp.Instance, list, bool]:
    """A grid with ~12 % obstacles, ``robots`` robots (point robots or mixed types), a
    random-delay model and one or two breakdowns."""
    rng = np.random.default_rng(seed)
    side = int(max(12, np.ceil(np.sqrt(robots * 30))))
    while True:
        blocked = rng.random((side, side)) < 0.12
        g = hp.Graph.grid(side, side, blocked=blocked)
        free = np.flatnonzero(g.passable)
        # One connected piece: keep the largest component's vertices.
        d = g.dist_to(int(free[0]))
        free = free[d[free] < 10**8]
        if len(free) >= 2 * robots + 4:
            break
    starts = rng.choice(free, robots, replace=False)
    goals = rng.choice(free, robots, replace=False)
    points = seed % 2 == 0
    agents = tuple(
        hp.Agent(
            f"r{k}",
            int(starts[k]),
            int(goals[k]),
            None,
            Kinematics() if points else TYPES[int(rng.integers(2))],
        )
        for k in range(robots)
    )
    inst = hp.Instance(g, agents, (), None, f"random-{seed}")
    dist: list = [RandomDelays(0.1, "exponential", 1.5, seed=seed)]
    for k in rng.choice(robots, int(rng.integers(1, 3)), replace=False):
        dist.append(Breakdown(f"r{int(k)}", float(rng.uniform(0.0, 8.0))))
    return inst, dist, points


def planned_run(seed: int, robots: int) -> tuple[hp.Instance, list, bool, object]:
    """The first instance from ``seed`` on whose plan MAPF-POST can keep the robots
    apart (a plan where robots rotate through a cycle of cells it refuses, in one line;
    then the next draw)."""
    for attempt in range(20):
        inst, dist, points = random_case(seed + 1000 * attempt, robots)
        r = hp.run(inst, "lacam", disturbances=dist, time_limit=30, solver_options={"anytime": 0})
        if r.schedule is not None:
            return inst, dist, points, r
        assert r.result.plan is not None and "MAPF-POST" in r.why, r.why
    raise AssertionError(f"no schedulable draw for seed {seed}")


def check_case(seed: int, robots: int, *, robot_mode: bool = True) -> None:
    inst, dist, points, r = planned_run(seed, robots)
    radii = [a.kinematics.radius for a in inst.agents]
    assert r.schedule is not None and r.execution is not None
    s = r.schedule
    runs = {"run": r.execution}
    for policy in POLICIES:
        runs[policy] = simulate(inst, s, disturbances=dist, policy=policy, seed=seed)
    if robot_mode:
        runs["robot"] = simulate(inst, s, disturbances=dist, mode="robot", seed=seed, dt=0.1)
    for name, ex in runs.items():
        bad = touching_pairs(ex.trajectories, radii)
        assert not bad, (seed, name, "points" if points else "mixed", bad[:3])
        assert ex.statistics["collisions"] == 0, (seed, name)
        assert len(ex.trajectories) == robots


@pytest.mark.parametrize("seed", range(4))
def test_random_instances_keep_every_pair_apart(seed: int) -> None:
    check_case(seed, 20 + 5 * seed, robot_mode=seed < 2)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(100, 300))
def test_random_instances_keep_every_pair_apart_many(seed: int) -> None:
    robots = int(np.random.default_rng(seed).integers(20, 201))
    check_case(seed, robots, robot_mode=robots <= 60)


def test_independent_distance_is_exact() -> None:
    t = np.array([0.0, 2.0])
    a = np.array([[0.0, 0.0], [2.0, 0.0]])
    b = np.array([[2.0, 0.0], [0.0, 0.0]])  # head on: they meet at t = 1
    assert pair_min_distance(t, a, t, b) == 0.0
    c = np.array([[1.0, 1.0], [1.0, -1.0]])  # crosses a's way, 0 apart at t = 1
    assert pair_min_distance(t, a, t, c) == pytest.approx(0.0)
    e = np.array([[0.0, 1.0], [2.0, 1.0]])
    assert pair_min_distance(t, a, np.array([0.0, 2.0]), e) == pytest.approx(1.0)
