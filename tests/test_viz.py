"""Plots of instances and plans (hierplan_opt.viz.plots), under matplotlib's Agg backend."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.collections import LineCollection, PathCollection

import hierplan_opt as hp
from hierplan_opt.core.result import Status
from hierplan_opt.viz.plots import (
    agent_colors,
    format_table,
    plot_instance,
    plot_layers,
    plot_plan,
    plot_runtime_table,
)

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def corridor() -> hp.Instance:
    g = hp.Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    return hp.Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])


def corridor_plan() -> hp.Plan:
    # agent1 steps into the side cell (2, 1) = vertex 7 to let agent0 pass
    return hp.Plan.from_paths([[0, 1, 2, 3, 4], [1, 2, 7, 2, 3]])


def scatter_offsets(ax) -> list[np.ndarray]:
    return [c.get_offsets() for c in ax.collections if isinstance(c, PathCollection)]


# ------------------------------------------------------------------------------ instances
def test_grid_instance_shows_obstacles_starts_and_goals() -> None:
    inst = corridor()
    ax = plot_instance(inst)
    img = ax.get_images()[0].get_array()
    assert img.shape == (2, 5)  # rows = y, columns = x
    assert img[1, 0] == 1.0 and img[0, 0] == 0.0 and img[1, 2] == 0.0
    starts, goals = scatter_offsets(ax)[:2]
    assert starts.tolist() == [[0.0, 0.0], [1.0, 0.0]]
    assert sorted(goals.tolist()) == [[3.0, 0.0], [4.0, 0.0]]
    assert ax.get_ylim()[0] > ax.get_ylim()[1]  # y grows downwards as in MovingAI


def test_roadmap_tapf_instance_uses_team_colours() -> None:
    inst = hp.load_instance(ROOT / "instances" / "paper" / "figure3.yaml")
    colors = agent_colors(inst)
    team_of = [a.team for a in inst.agents]
    assert team_of == [0, 1, 1]
    assert colors[1] == colors[2] and colors[0] != colors[1]
    ax = plot_instance(inst)
    edges = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(edges[0].get_segments()) == inst.graph.num_edges
    labels = {t.get_text() for t in ax.texts}
    assert {"A", "H", "I"} <= labels
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "team2 (2)" in legend


def test_directed_roadmap_draws_arrows() -> None:
    g = hp.Graph.roadmap({"a": (0, 0), "b": (1, 0), "c": (2, 0)}, [("a", "b"), ("b", "c")],
                         directed=True)  # fmt: skip
    inst = hp.Instance.mapf(g, ["a"], ["c"])
    ax = plot_instance(inst)
    arrows = [t for t in ax.texts if t.arrow_patch is not None]
    assert len(arrows) == 2


def test_3d_grid_projection_and_layers() -> None:
    g = hp.Graph.grid(3, 2, 2, obstacles=[(0, 1, 0), (0, 1, 1), (2, 0, 1)])
    inst = hp.Instance.mapf(g, [(0, 0, 0)], [(2, 1, 1)])
    ax = plot_instance(inst)
    img = ax.get_images()[0].get_array()
    assert img[1, 0] == 1.0  # blocked in both layers
    assert img[0, 2] == 0.5  # blocked in one layer of two
    assert "projection" in ax.get_title()
    ax1 = plot_instance(inst, layer=1)
    assert ax1.get_images()[0].get_array()[0, 2] == 1.0
    assert len(scatter_offsets(ax1)[0]) == 0  # the start is in layer 0
    with pytest.raises(ValueError, match="outside the grid's z range"):
        plot_instance(inst, layer=2)
    with pytest.raises(ValueError, match="only to 3D grids"):
        plot_instance(corridor(), layer=0)
    fig = plot_layers(inst)
    assert [a.get_title() for a in fig.axes] == ["z = 0", "z = 1"]


# ------------------------------------------------------------------------------ plans
def test_plan_lines_follow_the_paths() -> None:
    inst, plan = corridor(), corridor_plan()
    ax = plot_plan(inst, plan, spread=0.0)
    lines = [ln for ln in ax.get_lines() if ln.get_label() in ("agent0", "agent1")]
    assert len(lines) == 2
    xy1 = np.column_stack(lines[1].get_data())
    assert xy1.tolist() == [[1, 0], [2, 0], [2, 1], [2, 0], [3, 0]]
    assert ax.get_title() == "instance: SoC 8, makespan 4"


def test_plan_time_window_and_positions() -> None:
    inst, plan = corridor(), corridor_plan()
    ax = plot_plan(inst, plan, times=(1, 2), spread=0.0)
    line = next(ln for ln in ax.get_lines() if ln.get_label() == "agent1")
    assert np.column_stack(line.get_data()).tolist() == [[2, 0], [2, 1]]
    positions = scatter_offsets(ax)[-2:]
    assert [p.tolist() for p in positions] == [[[2.0, 0.0]], [[2.0, 1.0]]]
    assert ax.get_title().endswith("t = 1..2")
    # after the end of a path the robot stays at its last vertex
    ax = plot_plan(inst, plan, times=9, spread=0.0)
    assert [p.tolist() for p in scatter_offsets(ax)[-2:]] == [[[4.0, 0.0]], [[3.0, 0.0]]]


@pytest.mark.parametrize("times", [(3, 1), (-1, 2), 1.5, "2", (1, 2, 3)])
def test_bad_time_windows_are_refused(times) -> None:
    with pytest.raises(ValueError, match="times"):
        plot_plan(corridor(), corridor_plan(), times=times)


def test_plan_for_another_instance_is_refused() -> None:
    with pytest.raises(ValueError, match="1 paths but the instance 2 agents"):
        plot_plan(corridor(), hp.Plan.from_paths([[0, 1]]))


def test_solved_paper_instances_plot_and_save(tmp_path: Path) -> None:
    for name in ("figure3", "warehouse-part2"):
        inst = hp.load_instance(ROOT / "instances" / "paper" / f"{name}.yaml")
        res = hp.solve(inst, "cbm", time_limit=30)
        assert res.plan is not None
        ax = plot_plan(inst, res.plan)
        out = tmp_path / f"{name}.png"
        ax.figure.savefig(out)
        assert out.read_bytes()[:4] == b"\x89PNG"
        team_legend = [t.get_text() for t in ax.get_legend().get_texts()]
        assert [t for t in team_legend if "(" in t] == [
            f"{t.name} ({len(t.agents)})" for t in inst.teams
        ]


def test_layers_of_a_3d_plan_split_the_moves() -> None:
    g = hp.Graph.grid(2, 1, 2)
    inst = hp.Instance.mapf(g, [(0, 0, 0)], [(1, 0, 1)])
    plan = hp.Plan.from_paths([[g.vertex((0, 0, 0)), g.vertex((0, 0, 1)), g.vertex((1, 0, 1))]])
    fig = plot_layers(inst, plan)
    bottom, top = fig.axes
    assert not [ln for ln in bottom.get_lines() if ln.get_label() == "agent0"] or all(
        len(ln.get_xdata()) == 1 for ln in bottom.get_lines()
    )
    top_line = next(ln for ln in top.get_lines() if ln.get_label() == "agent0")
    assert np.column_stack(top_line.get_data()).tolist() == [[0, 0], [1, 0]]
    # the climb out of layer 0 is marked with an upward triangle
    assert any(len(o) == 1 and o.tolist() == [[0.0, 0.0]] for o in scatter_offsets(bottom))


# ------------------------------------------------------------------------------ tables
def test_format_table_aligns_and_marks_missing_values() -> None:
    rows = [
        {"solver": "cbs", "status": Status.OPTIMAL, "cost": 101, "runtime": 0.01234},
        {"solver": "mip", "status": Status.TIME_LIMIT, "cost": None, "runtime": 60.0},
        {"solver": "ecbs(1.2)", "status": "FEASIBLE", "cost": 104, "extra": "x"},
    ]
    text = format_table(rows)
    lines = text.splitlines()
    assert lines[0].split() == ["solver", "status", "cost", "runtime", "extra"]
    assert lines[3].split() == ["mip", "TIME_LIMIT", "-", "60", "-"]
    assert len({len(line) for line in lines[:2]}) == 1
    # numbers are right-aligned: the cost column ends at one place
    ends = {line.index(tok) + len(tok) for line, tok in zip(lines[2:], ("101", "-", "104"),
                                                             strict=True)}  # fmt: skip
    assert len(ends) == 1
    assert format_table(rows, ["cost"]).splitlines()[2:] == [" 101", "   -", " 104"]


def test_runtime_plot_marks_runs_without_result() -> None:
    rows = [
        {"solver": "cbs", "agents": 5, "runtime": 0.0, "status": "OPTIMAL"},
        {"solver": "cbs", "agents": 10, "runtime": 0.5, "status": "OPTIMAL"},
        {"solver": "mip", "agents": 5, "runtime": 3.0, "status": Status.OPTIMAL},
        {"solver": "mip", "agents": 10, "runtime": 20.0, "status": Status.TIME_LIMIT},
    ]
    ax = plot_runtime_table(rows, time_limit=20)
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    assert set(lines) == {"cbs", "mip", "time limit"}
    assert lines["cbs"].get_ydata()[0] > 0  # zero runtimes are clipped for the log axis
    assert ax.get_yscale() == "log"
    hollow = scatter_offsets(ax)
    assert [h.tolist() for h in hollow] == [[[10.0, 20.0]]]
    assert ax.get_lines()[-1].get_ydata()[0] == 20  # the time-limit line


def test_colour_modes_for_one_anonymous_team() -> None:
    inst = hp.Instance.tapf(hp.Graph.grid(3, 1), [([(0, 0), (2, 0)], [(1, 0), (0, 0)])])
    auto, team = agent_colors(inst), agent_colors(inst, "team")
    assert auto[0] != auto[1]  # one team: robots stay distinguishable
    assert team[0] == team[1]
    with pytest.raises(ValueError, match="colour by"):
        agent_colors(inst, "robot")
