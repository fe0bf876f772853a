"""Issue 30: schedules of point robots keep what the plan promised, checked from outside.

Every check here measures distances itself, from the schedule's way-points only
(brute force: every pair, on the union of all way-point times, where the motion of
every robot is linear, plus a fine sampling), and never calls the replay it checks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.io.movingai import load_map, load_scen
from hierplan_opt.schedule import (
    collides,
    pair_separations,
    postprocess,
    replay,
    required_separation,
)

ROOT = Path(__file__).resolve().parents[1]

FOLLOW = """\
format: hierplan/1
name: follow
graph: {type: grid, rows: [".....", "..@@@"]}
agents:
  - {name: a, start: [0, 0], goal: [4, 0]}
  - {name: b, start: [1, 1], goal: [3, 0]}
"""
FOLLOW_PLAN = """\
schedule:
  a: [{x: 0, y: 0, t: 0}, {x: 1, y: 0, t: 1}, {x: 2, y: 0, t: 2}, {x: 3, y: 0, t: 3},
      {x: 4, y: 0, t: 4}]
  b: [{x: 1, y: 1, t: 0}, {x: 1, y: 1, t: 1}, {x: 1, y: 0, t: 2}, {x: 2, y: 0, t: 3},
      {x: 3, y: 0, t: 4}]
"""


# ---------------------------------------------------------------------- brute force
def _tracks(rows: dict[str, list[dict]], scale: float = 1.0) -> tuple[list[str], list, list]:
    """Names, times and positions (metres) of a schedule tree ``{agent: [way-points]}``."""
    names = list(rows)
    times = [np.array([float(w["arrival"]) for w in rows[n]]) for n in names]
    pos = [
        np.array([[float(w["x"]), float(w["y"])] for w in rows[n]], dtype=float) * scale
        for n in names
    ]
    return names, times, pos


def brute_min_distances(times: list[np.ndarray], pos: list[np.ndarray], samples: int = 4000):
    """``(K, K)`` smallest centre distances of every pair over continuous time.

    Every robot moves in a straight line at constant speed between its way-points and
    stays at its last one. On the union of all way-point times every robot's motion is
    linear, so the relative motion of a pair is linear on each interval: its closest
    approach there is ``|r0 + s dr|`` at ``s = clip(-r0.dr / dr.dr, 0, 1)``. A fine
    uniform sampling is checked against it (never below the exact minimum).
    """
    K = len(times)
    horizon = max(float(t[-1]) for t in times)
    grid = np.union1d(np.concatenate(times), np.linspace(0.0, horizon, samples))
    at = np.stack(
        [np.stack([np.interp(grid, t, p[:, k]) for k in range(p.shape[1])], axis=1)
         for t, p in zip(times, pos, strict=True)]
    )  # (K, T, dim)  # fmt: skip
    out = np.full((K, K), np.inf)
    for i in range(K):
        r = at[i][None, :, :] - at[i + 1 :]  # (K-i-1, T, dim)
        sampled = np.sqrt((r * r).sum(axis=2)).min(axis=1)
        r0, dr = r[:, :-1], np.diff(r, axis=1)
        dd = (dr * dr).sum(axis=2)
        s = np.clip(-(r0 * dr).sum(axis=2) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        closest = r0 + dr * s[..., None]
        exact = np.sqrt((closest * closest).sum(axis=2)).min(axis=1)
        exact = np.minimum(exact, np.sqrt((r[:, -1] ** 2).sum(axis=1)))
        assert np.all(exact <= sampled + 1e-12)
        out[i, i + 1 :] = exact
        out[i + 1 :, i] = exact
    return out


def _files(tmp_path: Path) -> tuple[str, str]:
    (tmp_path / "follow.yaml").write_text(FOLLOW)
    (tmp_path / "follow-plan.yaml").write_text(FOLLOW_PLAN)
    return str(tmp_path / "follow.yaml"), str(tmp_path / "follow-plan.yaml")


# ---------------------------------------------------------------------- the definition
def test_one_definition_of_a_violation() -> None:
    # On one point is a violation whatever the required separation, 0 included.
    assert collides(0.0, 0.0) and collides(0.0, 0.5) and collides(1e-12, 0.0)
    assert not collides(1e-6, 0.0)
    assert collides(0.59, 0.6) and not collides(0.6, 0.6) and not collides(0.7, 0.6)
    assert np.asarray(collides(np.array([0.0, 0.3, 0.7]), np.array([0.0, 0.6, 0.6]))).tolist() == [
        True,
        True,
        False,
    ]
    assert required_separation(0.2, 0.3, 0.1) == pytest.approx(0.6)
    # Two point robots crossing one point: distance 0, one violation, at the meeting time.
    t = [np.array([0.0, 2.0]), np.array([0.0, 2.0])]
    p = [np.array([[0.0, 0.0], [2.0, 0.0]]), np.array([[1.0, -1.0], [1.0, 1.0]])]
    sep = pair_separations(t, p, np.zeros(2))
    assert sep.distance.tolist() == [0.0] and sep.time.tolist() == [1.0] and sep.violations == 1
    assert brute_min_distances(t, p)[0, 1] == pytest.approx(0.0)


# ---------------------------------------------------------------------- the reproducer
@pytest.mark.parametrize("margin", [None, "0", "0.25"])
def test_follow_reproducer_never_on_one_point(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], margin: str | None
) -> None:
    # Issue 30 item 1: b followed a into (1,0), (2,0), (3,0) and post scheduled both at
    # each of them at 1.0, 2.0 and 3.0 s, "replay min distance 0 m (ok)".
    inst, plan = _files(tmp_path)
    out = tmp_path / "s.yaml"
    extra = [] if margin is None else ["--margin", margin]
    args = ["post", inst, plan, "--objective", "makespan", "--check", "--out", str(out)]
    code = main([*args, *extra])
    line = capsys.readouterr().out
    assert code == 0 and "(ok)" in line, line
    data = yaml.safe_load(out.read_text())
    need = {None: 0.1, "0": 0.0, "0.25": 0.25}[margin]  # default: 0.1 x the 1 m cell
    assert data["statistics"]["margin"] == pytest.approx(need)
    names, times, pos = _tracks(data["schedule"])
    d = brute_min_distances(times, pos)[0, 1]
    assert d > 1e-6, f"a and b on one point (distance {d})"
    assert d >= need - 1e-9
    # At no way-point time are a and b at the same place.
    for t in np.union1d(times[0], times[1]):
        pa = [np.interp(t, times[0], pos[0][:, k]) for k in range(2)]
        pb = [np.interp(t, times[1], pos[1][:, k]) for k in range(2)]
        assert np.hypot(pa[0] - pb[0], pa[1] - pb[1]) > 1e-6


def test_follow_replay_agrees_with_brute_force(tmp_path: Path) -> None:
    inst_file, plan_file = _files(tmp_path)
    inst = hp.load_instance(inst_file)
    plan = hp.load_plan(plan_file, inst)
    for margin in (None, 0.0):
        s = postprocess(inst, plan, margin=margin)
        rep = replay(s, inst, all_pairs=True)
        times = [np.asarray(w.arrival) for w in s.waypoints]
        pos = [np.asarray(w.coords) * s.scale for w in s.waypoints]
        assert rep.min_distance == pytest.approx(brute_min_distances(times, pos)[0, 1], abs=1e-9)
        assert rep.ok and rep.violations == 0


# ---------------------------------------------------------------------- warehouse
def warehouse(k: int) -> hp.Instance:
    g = load_map(str(ROOT / "instances/movingai/warehouse-10-20-10-2-1.map"))
    return load_scen(str(ROOT / "instances/movingai/warehouse-10-20-10-2-1-even-1.scen"), g, k)


def test_warehouse_50_point_robots_keep_the_separation() -> None:
    # Issue 30 item 1: on the warehouse map with 50 point agents and no disturbance, 3
    # pairs of robots met. Checked by brute force over every pair.
    inst = warehouse(50)
    res = hp.solve(inst, "ecbs", w=1.5, time_limit=60)
    assert res.plan is not None and hp.validate(inst, res.plan) == []
    s = postprocess(inst, res.plan, check_plan=False)
    assert s.margin == pytest.approx(0.1)  # 0.1 x the 1 m cell: point robots
    times = [np.asarray(w.arrival) for w in s.waypoints]
    pos = [np.asarray(w.coords) * s.scale for w in s.waypoints]
    d = brute_min_distances(times, pos, samples=2000)
    iu = np.triu_indices(len(times), 1)
    closer = int(np.count_nonzero(d[iu] < s.margin - 1e-9))
    assert closer == 0, f"{closer} pairs closer than {s.margin} m (min {d[iu].min()})"
    rep = replay(s, inst)
    assert rep.ok and rep.violations == 0
    assert rep.min_distance == pytest.approx(float(d[iu].min()), abs=1e-9)
    # Margin 0: they may come close, but never onto one point.
    s0 = postprocess(inst, res.plan, margin=0, check_plan=False)
    times = [np.asarray(w.arrival) for w in s0.waypoints]
    pos = [np.asarray(w.coords) * s0.scale for w in s0.waypoints]
    d0 = brute_min_distances(times, pos, samples=2000)[iu]
    assert float(d0.min()) > 1e-6
    assert replay(s0, inst).violations == 0
