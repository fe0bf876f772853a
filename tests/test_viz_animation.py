"""Animations (GIF, MP4 through imageio-ffmpeg) and Gantt charts of any size."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from PIL import Image

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.core.errors import InputError
from hierplan_opt.viz.animation import _Drawer, animate
from hierplan_opt.viz.gantt import plot_gantt
from hierplan_opt.viz.html import PALETTE
from hierplan_opt.viz.scene import scene_from_plan

ROOT = Path(__file__).resolve().parent.parent
WAREHOUSE = str(ROOT / "instances" / "paper" / "warehouse-part1.yaml")
DISTURBANCES = str(ROOT / "instances" / "paper" / "warehouse-disturbances.yaml")


def corridor() -> tuple[hp.Instance, hp.Plan]:
    g = hp.Graph.grid(6, 3, obstacles=[(2, 1), (3, 1)])
    inst = hp.Instance.mapf(g, [(0, 0), (5, 2), (0, 2)], [(5, 0), (0, 2), (5, 2)])
    plan = hp.solve(inst, "cbs").plan
    assert plan is not None
    return inst, plan


def expected_xy(inst: hp.Instance, plan: hp.Plan, t: float) -> np.ndarray:
    i = int(np.floor(t))
    g = inst.graph
    a = np.array([g.coords[p[min(i, len(p) - 1)]][:2] for p in plan.paths])
    b = np.array([g.coords[p[min(i + 1, len(p) - 1)]][:2] for p in plan.paths])
    return a + (b - a) * (t - i)


def robot_seen(frame: np.ndarray, drawer: _Drawer, xy: np.ndarray, k: int) -> bool:
    px = drawer.ax.transData.transform(np.asarray(xy, dtype=float)[None, :])[0]
    col, row = int(round(px[0])), int(round(frame.shape[0] - px[1]))
    patch = frame[row - 2 : row + 3, col - 2 : col + 3].astype(int)
    want = np.array(to_rgb(PALETTE[k])) * 255
    return bool((np.abs(patch - want).max(axis=2) <= 40).mean() >= 0.5)


def test_frames_draw_each_robot_where_the_plan_has_it() -> None:
    inst, plan = corridor()
    d = _Drawer(scene_from_plan(inst, plan), 640, 400, 3.0, None, 1.0)
    assert d.names  # three robots: names fit
    for t in (0.0, 1.5, 2.0, float(plan.makespan)):
        frame = d.frame(t)
        exp = expected_xy(inst, plan, t)
        for k in range(inst.num_agents):
            assert robot_seen(frame, d, exp[k], k), (t, k)
        # mutation check: one cell off is not where the robot is drawn
        off = exp[0] + np.array([0.0, 1.0 if exp[0][1] < 1 else -1.0])
        assert not robot_seen(frame, d, off, 0), t
    legend = [t.get_text() for t in d.fig.legends[0].get_texts()]
    assert legend[:3] == [a.name for a in inst.agents] and "goal" in legend


def test_gif_frames_and_rate(tmp_path: Path) -> None:
    inst, plan = corridor()
    out = animate(scene_from_plan(inst, plan), None, tmp_path / "a.gif", fps=4, speed=2.0)
    img = Image.open(out)
    assert img.n_frames == int(np.ceil(plan.makespan / 2.0 * 4)) + 1
    assert img.info["duration"] == 250


def test_mp4_through_imageio_ffmpeg(tmp_path: Path) -> None:
    import imageio_ffmpeg

    inst, plan = corridor()
    out = animate(scene_from_plan(inst, plan), None, tmp_path / "a.mp4", fps=5, size=(320, 240))
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = reader.__next__()
    frames = sum(1 for _ in reader)
    assert meta["size"] == (320, 240) and meta["fps"] == 5
    assert frames == plan.makespan * 5 + 1


def test_progress_lines_and_bad_options(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    inst, plan = corridor()
    sc = scene_from_plan(inst, plan)
    with caplog.at_level(logging.INFO, logger="hierplan_opt.progress"):
        animate(sc, None, tmp_path / "p.gif", fps=2, progress=True)
    assert any(
        "animate p.gif" in r.getMessage() and "frames" in r.getMessage() for r in caplog.records
    )
    with pytest.raises(InputError, match="gif or .mp4"):
        animate(sc, None, tmp_path / "p.avi")
    with pytest.raises(InputError, match="positive"):
        animate(sc, None, tmp_path / "p.gif", fps=0)
    with pytest.raises(InputError, match="outside"):
        animate(sc, None, tmp_path / "p.gif", size=(10, 10))
    assert not (tmp_path / "p.avi").exists()


def test_simulate_animate_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, mp4 = tmp_path / "r.yaml", tmp_path / "r.mp4"
    plan = tmp_path / "plan.yaml"
    assert main(["-q", "solve", WAREHOUSE, "--solver", "cbm", "--out", str(plan)]) == 0
    code = main(
        ["-q", "simulate", WAREHOUSE, str(plan), "--disturbances", DISTURBANCES, "--out",
         str(out), "--animate", str(mp4), "--fps", "2", "--animate-size", "480x320",
         "--animate-speed", "4"]
    )  # fmt: skip
    assert code == 0
    import imageio_ffmpeg

    meta = next(imageio_ffmpeg.read_frames(str(mp4)))
    assert meta["size"] == (480, 320)
    capsys.readouterr()
    bad = ["simulate", WAREHOUSE, str(plan), "--out", str(out), "--animate-size", "10x10"]
    with pytest.raises(SystemExit) as exc:  # refused while parsing, before any work
        main(bad)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "64x64" in err[0]


def schedule_of(k: int) -> hp.Schedule:
    g = hp.Graph.grid(16, 16)
    rng = np.random.default_rng(3)
    cells = [(int(v % 16), int(v // 16)) for v in rng.permutation(256)]
    inst = hp.Instance.mapf(g, cells[:k], cells[-k:])
    plan = hp.solve(inst, "pibt").plan
    assert plan is not None
    return hp.postprocess(inst, plan, margin=0)  # PIBT rotates; margin 0 schedules it


def test_gantt_groups_rows_and_says_so(tmp_path: Path) -> None:
    s = schedule_of(130)
    fig = plot_gantt(s, tmp_path / "g.png")
    ax = fig.axes[0]
    assert "all 130 robots, 3 robots per row" in ax.get_title()
    assert len(ax.get_yticks()) == 44
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert labels[-1] == "agent0..agent2" and labels[0] == "agent129"
    # every robot is drawn: one arrival tick per way-point of every robot
    ticks = sum(len(c.get_offsets()) for c in ax.collections if hasattr(c, "get_sizes"))
    assert ticks >= sum(len(w) for w in s.waypoints)
    fig.canvas.draw()
    fb = fig.bbox
    for leg in fig.legends:
        box = leg.get_window_extent()
        assert box.x0 >= fb.x0 and box.y0 >= fb.y0 and box.x1 <= fb.x1 and box.y1 <= fb.y1
    sub = plot_gantt(s, tmp_path / "h.png", agents=(10, 40))
    assert "robots 10..39 of 130 shown" in sub.axes[0].get_title()
    with pytest.raises(InputError, match="not a range"):
        plot_gantt(s, agents=(5, 500))


def test_refine_plot_names_every_robot_in_distinct_colours(tmp_path: Path) -> None:
    from hierplan_opt.trajectory.plot import plot_trajectories
    from hierplan_opt.trajectory.result import read_trajectories

    plan, sched, npz = tmp_path / "p.yaml", tmp_path / "s.yaml", tmp_path / "t.npz"
    assert main(["-q", "solve", WAREHOUSE, "--solver", "cbm", "--out", str(plan)]) == 0
    assert main(["-q", "post", WAREHOUSE, str(plan), "--out", str(sched)]) == 0
    args = [WAREHOUSE, str(sched), "--out", str(npz), "--solver", "profile"]
    assert main(["-q", "refine", *args, "--stretch", "auto"]) == 0
    traj = read_trajectories(npz)
    fig = plot_trajectories(traj, tmp_path / "t.png")
    (legend,) = fig.legends
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels[: traj.num_agents] == [r.name for r in traj.robots]
    colors = {tuple(h.get_color()) if not isinstance(h.get_color(), str) else h.get_color()
              for h in legend.legend_handles[: traj.num_agents]}  # fmt: skip
    assert len(colors) == traj.num_agents
    fig.canvas.draw()
    box, fb = legend.get_window_extent(), fig.bbox
    assert box.x0 >= fb.x0 and box.x1 <= fb.x1 and box.y0 >= fb.y0 and box.y1 <= fb.y1
