"""Audit of the execution and report layer: a collision is never a kept distance, Monte
Carlo runs set the exit code, the minimum distance is the real one (not ``inf``), and
disturbances that can never happen are refused."""

from __future__ import annotations

import importlib
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.core.errors import InputError
from hierplan_opt.execution import Slow, Stop, simulate
from hierplan_opt.io import load_instance
from hierplan_opt.schedule import postprocess, replay
from hierplan_opt.schedule.replay import _pair_min

TRAIN = """map: {dimensions: [5, 1], obstacles: []}
agents:
  - {name: agent0, start: [0, 0], goal: [3, 0]}
  - {name: agent1, start: [1, 0], goal: [4, 0]}
"""
CORNERS = """map: {dimensions: [3, 3], obstacles: [[1, 1]]}
agents:
  - {name: agent0, start: [0, 0], goal: [2, 2]}
  - {name: agent1, start: [2, 2], goal: [0, 0]}
"""


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def files(tmp_path: Path, instance: str, **disturbances: str) -> tuple[str, str, dict[str, str]]:
    """The instance, its solved plan, and disturbance files by name."""
    inst = tmp_path / "inst.yaml"
    inst.write_text(instance)
    plan = tmp_path / "plan.yaml"
    assert main(["solve", str(inst), "--out", str(plan)]) == 0
    out = {}
    for name, items in disturbances.items():
        f = tmp_path / f"{name}.yaml"
        f.write_text(f"disturbances:\n  - {items}\n")
        out[name] = str(f)
    return str(inst), str(plan), out


def all_pairs_min(trajectories) -> float:
    """Independent: the exact minimum centre distance over every pair."""
    best = math.inf
    for a in range(len(trajectories)):
        for b in range(a + 1, len(trajectories)):
            ta, tb = trajectories[a], trajectories[b]
            best = min(best, _pair_min(ta[:, 0], ta[:, 1:], tb[:, 0], tb[:, 1:])[0])
    return best


# ------------------------------------------------------------------ A: kept distance
def test_collision_at_radius_0_margin_0_is_not_a_kept_distance(tmp_path: Path, capsys) -> None:
    stop = "{kind: stop, agent: agent1, at_time: 0.5, duration: 3.0}"
    inst, plan, d = files(tmp_path, TRAIN, stop=stop)
    out = tmp_path / "x.yaml"
    argv = ["simulate", inst, plan, "--disturbances", d["stop"], "--policy", "naive"]
    code, text, _ = cli(capsys, *argv, "--margin", "0", "--out", str(out))
    st = yaml.safe_load(out.read_text())["statistics"]
    assert st["collisions"] >= 1 and st["guaranteed_distance"] == 0
    assert st["distance_kept"] is False
    safety = next(ln for ln in text.splitlines() if ln.startswith("safety:"))
    assert "NOT kept" in safety
    assert code == 1


def test_library_distance_kept_is_false_on_one_point() -> None:
    inst = hp.Instance.mapf(hp.Graph.grid(4, 1), [(0, 0), (1, 0)], [(2, 0), (3, 0)])
    s = postprocess(inst, hp.Plan.from_paths([[0, 1, 2], [1, 2, 3]]), margin=0)
    ex = simulate(inst, s, disturbances=[Stop("agent1", 3.0, at_time=0.5)], policy="naive")
    assert ex.statistics["collisions"] >= 1
    assert all_pairs_min(ex.trajectories) <= 1e-9  # on one point
    assert ex.statistics["distance_kept"] is False


# ------------------------------------------------------------------ B: Monte Carlo
def test_monte_carlo_collision_sets_exit_code_1(tmp_path: Path, capsys) -> None:
    rnd = "{kind: random, probability: 0.5, duration: {exponential: 2.0}, seed: 1}"
    inst, plan, d = files(tmp_path, TRAIN, rnd=rnd)
    for command in (["simulate", inst, plan], ["run", inst]):
        out = tmp_path / "mc.yaml"
        argv = [*command, "--disturbances", d["rnd"], "--runs", "4", "--workers", "1"]
        code, text, _ = cli(capsys, *argv, "--policy", "naive", "--margin", "0", "--out", str(out))
        data = yaml.safe_load(out.read_text())
        mc = data["monte_carlo"]
        # The base run is clean: only the batch can make this fail.
        assert data["statistics"]["collisions"] == 0 and data["statistics"]["distance_kept"]
        assert mc["collisions"] >= 1
        assert code == 1, command
        assert mc["unsafe_runs"] >= 1 and mc["failed_runs"] >= mc["unsafe_runs"]
        assert f"FAILED: {mc['failed_runs']}/4 runs" in text


def test_monte_carlo_stranded_sets_exit_code_5_without_warnings(tmp_path: Path, capsys) -> None:
    inst, plan, d = files(tmp_path, TRAIN, bd="{kind: breakdown, agent: agent1, at_time: 0.5}")
    out = tmp_path / "mc.yaml"
    argv = ["simulate", inst, plan, "--disturbances", d["bd"], "--runs", "4", "--workers", "1"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code, text, err = cli(capsys, *argv, "--policy", "naive", "--out", str(out))
    mc = yaml.safe_load(out.read_text())["monte_carlo"]
    assert "Warning" not in err
    assert mc["stranded_runs"] == 4 and mc["unsafe_runs"] == 0 and mc["failed_runs"] == 4
    assert mc["delay_mean"] is None and mc["makespan_mean"] is None  # none reached
    assert "makespan not reached in any run" in text and "nan" not in text.split("monte")[-1]
    assert code == 5


# ------------------------------------------------------------------ C: min distance
def test_replay_min_distance_is_the_real_one(tmp_path: Path, capsys) -> None:
    inst, plan, _ = files(tmp_path, CORNERS)
    instance = load_instance(inst)
    sched = postprocess(instance, hp.solve(instance, "cbs").plan)
    truth = replay(sched, instance, all_pairs=True).min_distance
    rep = replay(sched, instance)
    assert math.isfinite(truth)
    assert rep.min_distance == pytest.approx(truth) and rep.min_distance_exact
    out = tmp_path / "s.yaml"
    code, text, _ = cli(capsys, "post", inst, plan, "--check", "--out", str(out))
    assert code == 0 and f"replay min distance {truth:.4g} m" in text and "inf" not in text
    code, text, _ = cli(capsys, "validate", inst, str(out))
    assert code == 0 and f"replay min distance {truth:.4g} m" in text and "inf" not in text
    rpt = tmp_path / "r.yaml"
    code, text, _ = cli(capsys, "simulate", inst, plan, "--out", str(rpt))
    st = yaml.safe_load(rpt.read_text())["statistics"]
    ex = simulate(instance, sched)
    assert st["min_distance"] == pytest.approx(all_pairs_min(ex.trajectories))
    assert code == 0 and "min distance inf" not in text


def corners_measuring_no_skipped_pair(monkeypatch) -> tuple[hp.Instance, hp.Schedule]:
    """The corner swap posted, with the replay measuring none of the pairs it prunes."""
    instance = load_instance_text(CORNERS)
    sched = postprocess(instance, hp.solve(instance, "cbs").plan)
    module = importlib.import_module("hierplan_opt.schedule.replay")
    monkeypatch.setattr(module.skipped_minimum, "__defaults__", (0,))  # measure none
    return instance, sched


def test_replay_min_distance_only_bounded_says_so(monkeypatch) -> None:
    instance, sched = corners_measuring_no_skipped_pair(monkeypatch)
    rep = replay(sched, instance)
    truth = replay(sched, instance, all_pairs=True).min_distance
    assert not rep.min_distance_exact
    assert rep.min_distance_text() == f"> {rep.skipped_bound:.4g} m"
    assert truth > rep.skipped_bound  # the statement is true


def load_instance_text(text: str) -> hp.Instance:
    import tempfile

    f = Path(tempfile.mkdtemp()) / "i.yaml"
    f.write_text(text)
    return load_instance(str(f))


# ------------------------------------------------------------------ D: impossible ones
@pytest.mark.parametrize(
    "item, words",
    [
        ("{kind: stop, agent: agent0, at_waypoint: 99, duration: 5.0}", ("way-point 99",)),
        ("{kind: slow, cells: [[9, 9]], factor: 0.5}", ("(9, 9)", "not on the map")),
        ("{kind: slow, edges: [[[0, 0], [2, 0]]], factor: 0.5}", ("not an edge",)),
    ],
)
@pytest.mark.parametrize("command", ["simulate", "run"])
def test_impossible_disturbance_refused(tmp_path: Path, capsys, item, words, command) -> None:
    inst, plan, d = files(tmp_path, TRAIN, bad=item)
    out = tmp_path / "r.yaml"
    head = ["simulate", inst, plan] if command == "simulate" else ["run", inst]
    code, text, err = cli(capsys, *head, "--disturbances", d["bad"], "--out", str(out))
    lines = [ln for ln in err.splitlines() if not ln.startswith(("INFO", "DEBUG"))]
    assert code == 2 and len(lines) == 1, err
    assert d["bad"] in lines[0] and "disturbance 1" in lines[0]
    assert all(w in lines[0] for w in words), lines[0]
    assert not out.exists() and "execution" not in text


def test_library_refuses_impossible_disturbances() -> None:
    inst = hp.Instance.mapf(hp.Graph.grid(4, 1), [(0, 0)], [(3, 0)])
    s = postprocess(inst, hp.Plan.from_paths([[0, 1, 2, 3]]))
    n = len(s.waypoints[0].arrival)
    simulate(inst, s, disturbances=[Stop("agent0", 1.0, at_waypoint=n - 1)])  # the last: fine
    with pytest.raises(InputError, match=f"no way-point {n}"):
        simulate(inst, s, disturbances=[Stop("agent0", 1.0, at_waypoint=n)])
    with pytest.raises(InputError, match="disturbance 2 \\(slow\\)"):
        simulate(inst, s, disturbances=[Slow(0.5, cells=((1, 0),)), Slow(0.5, cells=((4, 0),))])
    assert np.isfinite(s.makespan)


def test_execution_min_distance_only_bounded_says_so(monkeypatch) -> None:
    instance, sched = corners_measuring_no_skipped_pair(monkeypatch)
    ex = simulate(instance, sched)
    st = ex.statistics
    assert st["min_distance"] == math.inf and st["min_distance_above"] is not None
    assert all_pairs_min(ex.trajectories) > st["min_distance_above"]  # a true statement
    from hierplan_opt.execution.report import text_report

    assert f"min distance > {st['min_distance_above']:.4g} m" in text_report(ex)


def test_delay_aware_replan_drops_stops_its_schedule_lacks() -> None:
    from hierplan_opt.execution.montecarlo import _on_schedule

    inst = hp.Instance.mapf(hp.Graph.grid(4, 1), [(0, 0)], [(3, 0)])
    s = postprocess(inst, hp.Plan.from_paths([[0, 1, 2, 3]]))
    n = len(s.waypoints[0].arrival)
    kept, dropped = Stop("agent0", 1.0, at_waypoint=n - 1), Stop("agent0", 1.0, at_waypoint=n)
    assert _on_schedule([kept, dropped, Slow(0.5, cells=((1, 0),))], s)[:1] == [kept]
    assert dropped not in _on_schedule([kept, dropped], s)


def test_no_arrival_is_said_not_averaged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Audit: when no robot arrives, the first line printed "arrivals avg nan s max nan s".
    one = TRAIN.split("  - {name: agent1")[0].replace("agent0", "a")
    inst, plan, d = files(tmp_path, one, bd="{kind: breakdown, agent: a, at_time: 0.5}")
    sched = str(tmp_path / "s.yaml")
    assert main(["post", inst, plan, "--out", sched]) == 0
    capsys.readouterr()
    code, out, _ = cli(capsys, "simulate", inst, sched, "--disturbances", d["bd"],
                       "--out", str(tmp_path / "r.yaml"))  # fmt: skip
    assert "no robot arrived at its goal" in out and "nan" not in out
    assert code == 0  # the only robot broke down: no working robot left unfinished


def test_cbs_with_highways_refuses_a_node_limit(tmp_path: Path) -> None:
    # Audit: cbs with highways hands the solve to ECBS, which has no node_limit: the
    # limit was dropped without a word.
    inst = load_instance_text(TRAIN)
    with pytest.raises(hp.OptionError, match="no node_limit"):
        hp.solve(inst, "cbs", highways="crisscross", node_limit=5)


def test_robot_mode_without_a_max_says_accelerations_not_checked() -> None:
    # Audit: robot mode printed "max |a| / a_max 0, 0 acceleration violation(s)" when no
    # robot type gives a_max, a check against nothing.
    from hierplan_opt.execution.report import text_report

    instance = load_instance_text(TRAIN)
    sched = postprocess(instance, hp.solve(instance, "cbs").plan)
    st = simulate(instance, sched, mode="robot", dt=0.05)
    assert st.statistics["acceleration_checked"] == 0
    assert "accelerations not checked" in text_report(st)
    fast = hp.Kinematics("fast", v_max=1.0, a_max=2.0)
    inst2 = hp.Instance.mapf(instance.graph, [(0, 0), (1, 0)], [(3, 0), (4, 0)], kinematics=fast)
    ex = simulate(inst2, postprocess(inst2, hp.solve(inst2, "cbs").plan), mode="robot", dt=0.05)
    assert ex.statistics["acceleration_checked"] == 2
    assert "max |a| / a_max" in text_report(ex)
