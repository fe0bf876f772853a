"""Lifelong operation on LoRR problems: reading, delays, action model, replay, the loop."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hierplan_opt.core.errors import InputError
from hierplan_opt.io.lorr import (
    DelayConfig,
    LorrProblem,
    decode_path,
    encode_path,
    load_problem,
    read_log,
)
from hierplan_opt.lifelong import check_log, run_lifelong
from hierplan_opt.lifelong.delays import MT19937, DelayStream, ReplayDelays
from hierplan_opt.lifelong.model import CR, FW, NA, Distances, Grid, RobotState, W, step_state
from hierplan_opt.lifelong.planner import WindowedLaCAM, WindowedPIBT
from hierplan_opt.lifelong.scheduler import assign

ROOT = Path(__file__).resolve().parents[1]
LORR = ROOT / "instances" / "lorr"
DATA = Path(__file__).parent / "data"
MAZE = LORR / "maze.domain" / "maze-example_40.json"
RANDOM = LORR / "random.domain" / "random-example_400.json"
ROOM = LORR / "room.domain" / "room-example_150.json"


def line_problem(n_cells: int, starts, tasks, k: int = 1, **kw) -> LorrProblem:
    return LorrProblem(
        "line",
        1,
        n_cells,
        np.zeros(n_cells, dtype=bool),
        tuple(starts),
        tuple(tasks),
        agent_counter=k,
        **kw,
    )


# ---------------------------------------------------------------- reading problems
def test_reads_the_start_kit_examples() -> None:
    p = load_problem(RANDOM)
    assert (p.rows, p.cols, p.team_size, p.agent_counter, p.agent_size) == (64, 64, 400, 3, 1.0)
    assert p.reveal_count == 600 and len(p.tasks) == 3200
    assert p.tasks[0] == (1717, 1420, 289)  # a multi-errand task, linearised locations
    assert p.delay == DelayConfig(0, 1, 4, "bernoulli", 0.01, "uniform", 0.5, 0.22)
    assert all(not p.blocked[s] for s in p.starts)
    room = load_problem(ROOM)
    assert room.team_size == 150 and room.delay.event_model == "poisson"


def _copy_maze(tmp: Path) -> Path:
    dst = tmp / "maze"
    shutil.copytree(MAZE.parent, dst)
    return dst / MAZE.name


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.pop("mapFile"), r"missing property 'mapFile'"),
        (lambda d: d.update(teamSize="40"), r"teamSize must be an integer"),
        (lambda d: d.update(teamSize=41), r"teamSize is 41 but the file has only 40 agents"),
        (lambda d: d.update(agentSize=0), r"agentSize must be a positive number"),
        (lambda d: d.update(agentCounter=0), r"agentCounter must be at least 1"),
        (lambda d: d["delayConfig"].update(minDelay=0), r"delayConfig.minDelay must be > 0"),
        (lambda d: d["delayConfig"].update(maxDelay=1), r"maxDelay must be >= minDelay"),
        (lambda d: d["delayConfig"].update(eventModel="x"), r"eventModel must be 'bernoulli'"),
        (lambda d: d["delayConfig"].update(pDelay=1.5), r"pDelay must be in \[0, 1\]"),
        (lambda d: d["delayConfig"].update(gaussStdRatio=-1), r"gaussStdRatio must be >= 0"),
        (lambda d: d.update(mapFile="nope.map"), r"nope.map: no such file"),
    ],
)
def test_bad_problem_files_one_line(tmp_path: Path, change, message: str) -> None:
    f = _copy_maze(tmp_path)
    data = json.loads(f.read_text())
    change(data)
    f.write_text(json.dumps(data))
    with pytest.raises(InputError, match=message) as exc:
        load_problem(f)
    assert "\n" not in str(exc.value)


def test_bad_map_agents_tasks(tmp_path: Path) -> None:
    f = _copy_maze(tmp_path)
    d = f.parent
    mp = d / "maps" / "maze-32-32-2.map"
    text = mp.read_text()
    mp.write_text(text.replace(".", "x", 1))
    with pytest.raises(InputError, match=r"maze-32-32-2.map:6: unknown map character 'x'"):
        load_problem(f)
    mp.write_text(text)
    ag = d / "agents" / "maze-example_40.agents"
    lines = ag.read_text().splitlines()
    blocked = load_problem(f).blocked.nonzero()[0][0]
    lines[2] = str(blocked)
    ag.write_text("\n".join(lines))
    with pytest.raises(InputError, match=r"agents:3: start location \d+ .* is blocked"):
        load_problem(f)
    lines[2] = lines[3]
    ag.write_text("\n".join(lines))
    with pytest.raises(InputError, match=r"is taken by line"):
        load_problem(f)
    shutil.copy(MAZE.parent / "agents" / ag.name, ag)
    tk = d / "tasks" / "maze-example_40.tasks"
    tl = tk.read_text().splitlines()
    tl[2] = "12,a"
    tk.write_text("\n".join(tl))
    with pytest.raises(InputError, match=r"tasks:3: expected comma-separated integers, got 'a'"):
        load_problem(f)
    tl[2] = "99999"
    tk.write_text("\n".join(tl))
    with pytest.raises(InputError, match=r"errand location 99999 is outside the map"):
        load_problem(f)
    (d / "bad.json").write_text("{")
    with pytest.raises(InputError, match=r"bad.json:1: not valid JSON"):
        load_problem(d / "bad.json")


# ---------------------------------------------------------------- delays
def test_mt19937_matches_the_standard() -> None:
    g = MT19937(5489)
    words = [g.next() for _ in range(10000)]
    assert words[0] == 3499211612 and words[-1] == 4123659995  # C++ [rand.predef]


@pytest.mark.parametrize(
    ("fixture", "problem"),
    [("lorr_random400_startkit_delays.json", RANDOM), ("lorr_room150_startkit_delays.json", ROOM)],
)
def test_delays_identical_to_the_start_kit(fixture: str, problem: Path) -> None:
    # delayIntervals written by the Start-Kit's own lifelong (9bc75d9) on this problem:
    # Bernoulli + uniform (random) and Poisson + shuffle + uniform (room).
    rec = json.loads((DATA / fixture).read_text())
    p = load_problem(problem)
    s = DelayStream(p.delay, p.team_size)
    for _ in range(rec["ticks"]):
        s.next_tick()
    assert s.exact
    ours = [[list(iv) for iv in ivs] for ivs in s.intervals]
    assert sum(map(len, ours)) > 200
    assert ours == rec["delayIntervals"]


def test_poisson_gaussian_delays_identical_to_the_start_kit() -> None:
    # the warehouse example's stream (Poisson mean 7.5, shuffle, Gaussian 2..8) for its
    # 2,500 robots, as the Start-Kit wrote it; the problem's delayConfig is in the fixture
    from hierplan_opt.io.lorr import parse_delay_config

    rec = json.loads((DATA / "lorr_warehouse2500_startkit_delays.json").read_text())
    cfg = parse_delay_config(rec["delayConfig"])
    assert (cfg.event_model, cfg.duration_model) == ("poisson", "gaussian")
    s = DelayStream(cfg, rec["teamSize"])
    for _ in range(rec["ticks"]):
        s.next_tick()
    assert s.exact and sum(map(len, s.intervals)) > 1000
    assert [[list(iv) for iv in ivs] for ivs in s.intervals] == rec["delayIntervals"]


def test_delay_durations_and_replay() -> None:
    cfg = DelayConfig(
        seed=3,
        min_delay=2,
        max_delay=6,
        p_delay=0.2,
        duration_model="gaussian",
        gauss_mean_ratio=0.5,
        gauss_std_ratio=0.3,
    )
    s = DelayStream(cfg, 50)
    for _ in range(200):
        s.next_tick()
    lengths = [b - a for ivs in s.intervals for a, b in ivs]
    assert lengths and min(lengths) >= 2 and max(lengths) <= 6
    r = ReplayDelays(s.intervals)
    fresh = DelayStream(cfg, 50)
    for _ in range(200):
        r.next_tick()
        fresh.next_tick()
        assert r.remaining == fresh.remaining


# ---------------------------------------------------------------- action model
def test_step_state_is_the_start_kit_rule() -> None:
    moves = (1, 10, -1, -10)
    s = RobotState(0)
    step_state(s, FW, moves, 3)
    step_state(s, W, moves, 3)  # a wait pauses the move in progress
    assert (s.loc, s.count, s.cur) == (0, 1, FW)
    step_state(s, CR, moves, 3)  # any other action continues it
    assert (s.loc, s.count, s.cur) == (0, 2, FW)
    step_state(s, CR, moves, 3)
    assert (s.loc, s.count, s.cur, s.ori) == (1, 0, NA, 0)
    for _ in range(3):
        step_state(s, CR, moves, 3)
    assert (s.loc, s.ori) == (1, 1)


def test_path_strings_round_trip() -> None:
    text = encode_path("FFFRRRWWTT", [(1, 2, 0, 0), (1, 3, 1, 0)], 6)
    assert text == "[(0,1,2,0,0):(F 3,R 3)][(6,1,3,1,0):(W 2,T 2)]"
    assert decode_path(text) == ((1, 2, 0, 0), "FFFRRRWWTT")
    with pytest.raises(InputError, match="bad segment"):
        decode_path("[(0,1):(F 1)]")


# ---------------------------------------------------------------- the independent replay
def _log(paths, ticks, **kw):
    return {"makespan": ticks, "actualPaths": paths, **kw}


def test_replay_finds_each_kind_of_violation() -> None:
    p = line_problem(4, [0, 2], [(3,)], k=2)
    ok = _log(["[(0,0,0,0,0):(F 2)]", "[(0,0,2,0,0):(F 2)]"], 2)
    assert check_log(p, ok).ok  # following in step
    r = check_log(p, _log(["[(0,0,0,0,0):(F 2)]", "[(0,0,2,0,0):(W 2)]"], 2))
    assert r.collisions == 0  # 0 ends in cell 1, 2 stays: touching only
    r = check_log(p, _log(["[(0,0,0,0,0):(F 4)]", "[(0,0,2,0,0):(W 4)]"], 4))
    assert r.collisions >= 1 and "overlap" in r.problems[0]
    r = check_log(p, _log(["[(0,0,0,2,0):(F 1)]", "[(0,0,2,0,0):(W 1)]"], 1))
    assert r.invalid == 1 and "wall" in r.problems[0]
    r = check_log(p, _log(["[(0,0,0,0,0):(F 1,R 1)]", "[(0,0,2,0,0):(W 2)]"], 2))
    assert r.invalid == 1 and "in the middle of F" in r.problems[0]
    r = check_log(
        p, _log(["[(0,0,0,0,0):(R 1)]", "[(0,0,2,0,0):(W 1)]"], 1, delayIntervals=[[[0, 1]], []])
    )
    assert r.invalid == 1 and "while delayed" in r.problems[0]
    r = check_log(
        p,
        _log(
            ["[(0,0,0,0,0):(W 1)]", "[(0,0,2,0,0):(W 1)]"],
            1,
            tasks=[[0, 0, [0, 3]]],
            events=[[1, 0, 0, 1]],
            numTaskFinished=1,
        ),
    )
    assert r.bad_events == 2 and "not on errand" in r.problems[0]  # and the count
    # two robots moving into one cell from two sides, with footprints of 0.5
    p2 = LorrProblem(
        "sq", 2, 2, np.zeros(4, dtype=bool), (0, 3), ((1,),), agent_counter=1, agent_size=0.5
    )
    r = check_log(p2, _log(["[(0,0,0,0,0):(F 1)]", "[(0,1,1,3,0):(F 1)]"], 1))
    assert r.collisions == 1
    # point robots: meeting on one point, and passing through each other, both collide
    tiny = replace(p, agent_size=1e-9)
    r = check_log(tiny, _log(["[(0,0,0,0,0):(F 2)]", "[(0,0,2,2,0):(F 2)]"], 2))
    assert r.collisions >= 1
    r = check_log(tiny, _log(["[(0,0,0,0,0):(F 2)]", "[(0,0,2,0,0):(F 2)]"], 2))
    assert r.ok


# ---------------------------------------------------------------- parts of the loop
def test_planner_never_plans_a_rotation_cycle() -> None:
    # four robots on a 2x2 block, each wanting the next cell clockwise
    g = Grid(2, 2, np.zeros(4, dtype=bool))
    pl = WindowedPIBT(g, Distances(g), window=3, seed=1)
    plan = pl.plan([0, 1, 3, 2], [0, 1, 2, 3], [[1], [3], [2], [0]], [4.0, 3.0, 2.0, 1.0])
    assert plan.cycles_broken == 0
    assert all(not a for a in plan.actions) or any(a and a[0] != FW for a in plan.actions)


def test_windowed_planners_respect_a_deadline() -> None:
    import time

    g = Grid(8, 8, np.zeros(64, dtype=bool))
    locs = list(range(0, 64, 3))
    goals = [[(v * 7 + 5) % 64] for v in locs]
    for kind in (WindowedPIBT, WindowedLaCAM):
        pl = kind(g, Distances(g), window=5, seed=1)
        past = pl.plan(
            locs,
            [0] * len(locs),
            goals,
            [float(i) for i in range(len(locs))],
            deadline=time.perf_counter() - 1.0,
        )
        assert past.cut and past.steps == 0 and not any(past.actions) and not past.order
        full = pl.plan(locs, [0] * len(locs), goals, [float(i) for i in range(len(locs))])
        assert not full.cut and full.steps == 5 and any(full.actions)


def test_windowed_lacam_searches_beyond_the_rollout_and_stays_valid() -> None:
    g = Grid(4, 4, np.zeros(16, dtype=bool))
    pl = WindowedLaCAM(g, Distances(g), window=4, seed=0, max_nodes=50)
    # two robots facing each other in a row: they must get out of each other's way
    plan = pl.plan([4, 7], [0, 2], [[7], [4]], [2.0, 1.0])
    assert plan.nodes > 4 and plan.steps == 4
    p = load_problem(MAZE)
    res = run_lifelong(p, ticks=60, planner="lacam")
    rep = check_log(p, res.log)
    assert rep.ok, rep.problems
    assert res.tasks_finished > 0 and res.log["hierplan"]["planner"] == "lacam"


def test_budget_cuts_calls_and_the_run_stays_safe() -> None:
    p = load_problem(RANDOM)
    res = run_lifelong(p, ticks=30, budget=0.06, preprocess_seconds=0.5)
    rep = check_log(p, res.log)
    assert rep.ok, rep.problems
    s = res.summary()
    assert s["calls_cut_by_deadline"] >= 1 and s["steps_per_call"] < 6
    assert s["budget_s"] == 0.06


def test_hungarian_assignment_is_no_worse_than_greedy() -> None:
    g = Grid(1, 10, np.zeros(10, dtype=bool))
    d = Distances(g)
    robots, locs = [0, 1], [5, 0]  # robot 0 takes the near task, robot 1 goes far
    tasks, errands = [10, 11], [[4], [9]]
    cost = {}
    for kind in ("greedy", "hungarian"):
        got = assign(kind, d, robots, locs, tasks, errands, [0, 0])
        cost[kind] = sum(abs(locs[r] - errands[tasks.index(t)][0]) for r, t in got.items())
    assert cost == {"greedy": 10, "hungarian": 8}


def test_run_is_safe_and_counts_tasks_on_the_maze() -> None:
    p = load_problem(MAZE)
    res = run_lifelong(p, ticks=150, scheduler="greedy", seed=2)
    rep = check_log(p, res.log)
    assert rep.ok, rep.problems
    assert res.tasks_finished == rep.tasks_finished == res.log["numTaskFinished"] > 0
    assert len(res.planner_times) == 15
    assert sum(res.handled.values()) == res.delays


def test_run_under_heavy_delays_stays_safe() -> None:
    # 40 robots on the maze with a delay on ~5 % of robot-ticks: the executor must stop
    # followers behind every delayed robot, whatever the timing.
    p = load_problem(MAZE)
    p = replace(p, delay=replace(p.delay, p_delay=0.05, min_delay=1, max_delay=3))
    res = run_lifelong(p, ticks=120, window=6)
    rep = check_log(p, res.log)
    assert rep.ok, rep.problems
    assert res.delays > 100 and res.handled["adg"] > 0
    assert sum(res.handled.values()) == res.delays  # each delay put down to one layer
    assert res.log["delayIntervals"] == [[list(iv) for iv in ivs] for ivs in _stream(p, 120)]


def test_delay_layers_slack_adg_stn_replan() -> None:
    # Line of 10 cells, ticks per action 2. Robot 0 (cell 0) goes to cell 1, robot 1
    # (cell 5) to cell 9: the window ends at tick 8, robot 0's move has 6 ticks of slack.
    p = line_problem(10, [0, 5], [(1,), (9,)], k=2)

    def layers(intervals, period=100):
        r = run_lifelong(
            p, ticks=20, scheduler="greedy", period=period, delays=ReplayDelays(intervals)
        )
        assert check_log(p, r.log).ok
        return {k: v for k, v in r.handled.items() if v}, r

    assert layers([[[0, 3]], []])[0] == {"adg": 1}  # 3 ticks late, within the slack
    got, r = layers([[[0, 8]], []])  # 8 ticks late: 2 past the window's end
    assert got == {"stn": 1} and r.stn_resolves == 1 and r.stn_pushed == 2.0
    # the leader of a column has no slack: its follower's targets move (STN re-solve)
    q = line_problem(8, [0, 1], [(2,), (5,)], k=2)
    r = run_lifelong(
        q, ticks=20, scheduler="greedy", period=100, delays=ReplayDelays([[], [[0, 3]]])
    )
    assert {k: v for k, v in r.handled.items() if v} == {"stn": 1} and r.stn_pushed == 3.0
    # the same delay while a planning call comes: the re-plan handles it
    r = run_lifelong(q, ticks=20, scheduler="greedy", period=2, delays=ReplayDelays([[], [[0, 3]]]))
    assert {k: v for k, v in r.handled.items() if v} == {"replan": 1}
    # a robot delayed while it had to wait anyway: slack
    assert layers([[], [[12, 14]]])[0] == {"slack": 1}


def _stream(p: LorrProblem, ticks: int):
    s = DelayStream(p.delay, p.team_size)
    for _ in range(ticks):
        s.next_tick()
    return s.intervals


def test_run_refuses_bad_settings() -> None:
    p = line_problem(5, [0], [(4,)])
    with pytest.raises(InputError, match="unknown scheduler 'x'"):
        run_lifelong(p, ticks=5, scheduler="x")
    with pytest.raises(InputError, match="ticks must be at least 1"):
        run_lifelong(p, ticks=0)
    with pytest.raises(InputError, match="agentSize 1.5 > 1"):
        run_lifelong(replace(p, agent_size=1.5), ticks=5)


# ---------------------------------------------------------------- the command
def test_cli_writes_a_log_the_replay_accepts(tmp_path: Path, capsys) -> None:
    from hierplan_opt.cli import main

    out = tmp_path / "log.json"
    assert main(["lifelong", str(MAZE), "--ticks", "60", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "tasks finished" in text and "replay: ok" in text
    log = read_log(out)
    assert log["actionModel"] == "MAPF_T" and log["makespan"] == 60
    assert len(log["actualPaths"]) == 40 and check_log(load_problem(MAZE), log).ok
    args = ["lifelong", str(MAZE), "--ticks", "30", "--planner", "lacam", "--budget", "0.5"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "planner lacam" in text and "STN re-solve" in text and "over the 0.5 s budget" in text
    with pytest.raises(SystemExit) as exc:
        main(["lifelong", str(MAZE), "--budget", "0"])
    assert exc.value.code == 2 and "--budget" in capsys.readouterr().err


def test_cli_bad_input_one_line_no_file(tmp_path: Path, capsys) -> None:
    from hierplan_opt.cli import main

    out = tmp_path / "log.json"
    assert main(["lifelong", str(tmp_path / "missing.json"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "missing.json: no such file" in err
    assert main(["lifelong", str(MAZE), "--out", str(tmp_path / "no" / "x.json")]) == 2
    assert "--out" in capsys.readouterr().err
    assert not out.exists()


def test_bench_runs_ours_and_refuses_unknown_problems(capsys) -> None:
    from hierplan_opt.bench.lifelong import main

    assert main(["--instance", "maze", "--ticks", "30", "--no-baseline"]) == 0
    out = capsys.readouterr().out
    assert "ours (greedy+pibt)" in out and "ours (hungarian+lacam)" in out
    assert out.count(" ok") == 4 and out.count("over budget") == 4
    with pytest.raises(InputError, match="--instance nowhere: unknown problem"):
        main(["--instance", "nowhere", "--no-baseline"])


def test_registry_guided_run_is_safe() -> None:
    # the registry's lacam plans each call's guide paths; the run stays collision-free
    p = load_problem(MAZE)
    res = run_lifelong(p, ticks=40, planner="lacam-guided")
    assert check_log(p, res.log).ok
    assert res.log["hierplan"]["guideCalls"] == 4
    assert res.log["hierplan"]["guidePlans"] >= 1


@pytest.mark.slow
def test_random_400_is_collision_free_and_keeps_finishing_tasks() -> None:
    p = load_problem(RANDOM)
    res = run_lifelong(p, ticks=400)
    rep = check_log(p, res.log)
    assert rep.ok, rep.problems
    late = [e for e in res.log["events"] if e[0] > 300]
    assert res.tasks_finished > 150 and late  # no gridlock: tasks still finish late on


# ---------------------------------------------------------------- start on an errand
def _write_line_problem(d: Path, cols: int, starts, tasks) -> Path:
    """A 1 x cols LoRR problem in the Start-Kit's file formats (no delays)."""
    (d / "c.map").write_text(f"type octile\nheight 1\nwidth {cols}\nmap\n{'.' * cols}\n")
    (d / "c.agents").write_text(f"{len(starts)}\n" + "".join(f"{s}\n" for s in starts))
    (d / "c.tasks").write_text(
        f"{len(tasks)}\n" + "".join(",".join(map(str, t)) + "\n" for t in tasks)
    )
    cfg = {
        "mapFile": "c.map",
        "agentFile": "c.agents",
        "teamSize": len(starts),
        "taskFile": "c.tasks",
        "numTasksReveal": 1,
        "agentCounter": 1,
        "agentSize": 1.0,
        "delayConfig": {
            "seed": 0,
            "minDelay": 1,
            "maxDelay": 2,
            "eventModel": "bernoulli",
            "pDelay": 0.0,
            "durationModel": "uniform",
        },
    }
    path = d / "c.json"
    path.write_text(json.dumps(cfg))
    return path


@pytest.mark.parametrize("planner", ["pibt", "lacam"])
@pytest.mark.parametrize("scheduler", ["greedy", "hungarian"])
def test_robot_starting_on_its_first_errand_does_it_first(scheduler: str, planner: str) -> None:
    # The Start-Kit credits an errand when its robot stands on it at the end of a tick
    # (TaskManager::check_finished_tasks). A robot assigned a task at tick 0 while on
    # its first errand stays one tick (errand 1 at tick 1), then drives to errand 2.
    p = line_problem(6, [0], [(0, 5)])
    r = run_lifelong(p, ticks=30, scheduler=scheduler, planner=planner)
    ev = r.log["events"]
    assert ev[0] == [1, 0, 0, 1]
    assert ev[1] == [1 + 5, 0, 0, 2]  # then five moves east (it faces east)
    assert r.tasks_finished >= 1 and r.tasks_finished == sum(e[3] == 2 for e in ev)
    assert check_log(p, r.log).ok


@pytest.mark.parametrize("planner", ["pibt", "lacam"])
def test_new_task_on_the_cell_where_the_last_one_ended(planner: str) -> None:
    # Task 0 ends on cell 3 at tick 3; task 1 (errands 3 then 5) is assigned at the
    # next planning call (tick 10) while the robot stands on cell 3: errand 1 at tick
    # 11, errand 2 two moves later.
    p = line_problem(6, [0], [(3,), (3, 5)])
    r = run_lifelong(p, ticks=20, planner=planner, period=10)
    ev = r.log["events"]
    assert ev[:3] == [[3, 0, 0, 1], [11, 0, 1, 1], [13, 0, 1, 2]]
    assert check_log(p, r.log).ok


def test_planner_holds_a_robot_on_the_errand_it_stands_on() -> None:
    # the planner's stay that does an errand is an action (W) the executor carries out
    g = Grid(1, 6, np.zeros(6, dtype=bool))
    for kind in (WindowedPIBT, WindowedLaCAM):
        plan = kind(g, Distances(g), window=6).plan([0], [0], [(0, 5)], [0.5])
        assert plan.actions[0] == [W, FW, FW, FW, FW, FW] and plan.enters[0] == [1, 2, 3, 4, 5]


@pytest.mark.parametrize("scheduler", ["greedy", "hungarian"])
def test_cli_credits_the_errand_a_robot_starts_on(tmp_path: Path, capsys, scheduler: str) -> None:
    from hierplan_opt.cli import main

    cfg = _write_line_problem(tmp_path, 6, [0], [(0, 5)])
    out = tmp_path / "c.json.log.json"
    args = ["lifelong", str(cfg), "--ticks", "30", "--scheduler", scheduler, "--out", str(out)]
    assert main(args) == 0
    text = capsys.readouterr().out
    log = json.loads(out.read_text())
    finished = log["numTaskFinished"]
    assert log["events"][:2] == [[1, 0, 0, 1], [6, 0, 0, 2]]  # errand 1 at once, then 2
    assert finished >= 1 and finished == sum(e[3] == 2 for e in log["events"])
    assert f"tasks finished {finished}, throughput {finished / 30:.4f}" in text


@pytest.mark.parametrize("planner", ["pibt", "lacam"])
def test_no_extra_tick_for_an_errand_a_move_in_progress_ends_on(planner: str) -> None:
    # agentCounter 2: at the planning call of tick 3 the robot is half-way into cell 2,
    # its first errand; the move ends there at tick 4 (errand 1 done by the same rule),
    # so the window plans no wait on it: errand 2 four ticks later (two moves), not five
    p = line_problem(6, [0], [(2, 4)], k=2)
    r = run_lifelong(p, ticks=12, period=3, planner=planner)
    assert r.log["events"] == [[4, 0, 0, 1], [4 + 2 * 2, 0, 0, 2]]
    assert check_log(p, r.log).ok
