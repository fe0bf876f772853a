"""``hierplan view`` in a real browser: Debian's chromium, driven by Playwright.

The module installs chromium with apt-get when it is missing (root and apt needed; no
browser download). Every page is generated here, opened headless, and checked against
the file it was made from, read independently of the viewer's own code: the positions
the page drew (read back), and the pixels of a screenshot at those positions. Mutations
(a robot's data moved, or the drawing code shifted) must make the same checks fail.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.viz.browser import browser, chromium_executable, open_view
from hierplan_opt.viz.html import render_html, write_view
from hierplan_opt.viz.scene import scene_from_plan

ROOT = Path(__file__).resolve().parent.parent
WAREHOUSE = ROOT / "instances" / "paper" / "warehouse-part1.yaml"
DISTURBANCES = ROOT / "instances" / "paper" / "warehouse-disturbances.yaml"
#: Where the map canvas sits on the page (CSS pixels).
MAP_BOX = (
    "(() => { const r = document.getElementById('map').getBoundingClientRect();"
    " return [r.left, r.top]; })()"
)


@pytest.fixture(scope="module")
def chrome() -> Any:
    exe = chromium_executable(install=True)  # apt-get install -y chromium when missing
    with browser(exe) as b:
        yield b


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A cbm plan of the warehouse, its schedule and an execution report (README's run)."""
    d = tmp_path_factory.mktemp("view")
    plan, sched, report = d / "plan.yaml", d / "sched.yaml", d / "run.yaml"
    assert main(["-q", "solve", str(WAREHOUSE), "--solver", "cbm", "--out", str(plan)]) == 0
    assert main(["-q", "post", str(WAREHOUSE), str(plan), "--out", str(sched)]) == 0
    code = main(
        ["-q", "simulate", str(WAREHOUSE), str(sched), "--disturbances", str(DISTURBANCES),
         "--out", str(report)]
    )  # fmt: skip
    assert code == 0
    return {"dir": d, "plan": plan, "schedule": sched, "report": report}


# ---------------------------------------------------------------- the files, read here
def plan_positions(path: Path, t: float) -> np.ndarray:
    """Positions at ``t`` from a plan file's rows ``{x, y, t}`` (straight moves)."""
    data = yaml.safe_load(path.read_text())
    out = []
    for rows in data["schedule"].values():
        ts = [r["t"] for r in rows]
        out.append(
            [np.interp(t, ts, [r["x"] for r in rows]), np.interp(t, ts, [r["y"] for r in rows])]
        )
    return np.array(out)


def rows_positions(path: Path, t: float) -> np.ndarray:
    """Positions at ``t`` from a schedule or report's rows ``{x, y, arrival}``."""
    data = yaml.safe_load(path.read_text())
    out = []
    for rows in data["schedule"].values():
        ts = np.array([r["arrival"] for r in rows])
        xs, ys = [r["x"] for r in rows], [r["y"] for r in rows]
        out.append([np.interp(t, ts, xs), np.interp(t, ts, ys)])
    return np.array(out)


# ---------------------------------------------------------------- checks on the page
def drawn(page: Any, t: float) -> np.ndarray:
    d = page.evaluate(f"hierplan.seek({t})")
    end = page.evaluate("hierplan.head.end")
    assert math.isclose(d["t"], min(t, end), abs_tol=1e-9)  # the clock stops at the end
    return np.array(d["xy"]).reshape(-1, 2)


def check_drawn(page: Any, expected: np.ndarray, t: float) -> None:
    got = drawn(page, t)
    bad = np.flatnonzero(np.abs(got - expected).max(axis=1) > 1e-3)
    assert not len(bad), (
        f"t={t}: robot(s) {bad.tolist()} drawn at {got[bad]}, file says {expected[bad]}"
    )


def _rgb(hexcolor: str) -> np.ndarray:
    return np.array([int(hexcolor[i : i + 2], 16) for i in (1, 3, 5)])


def check_pixels(page: Any, expected: np.ndarray, t: float) -> None:
    """The screenshot shows each robot's colour around where the file puts it."""
    from PIL import Image

    # names off: a neighbour's label may lie over a robot; the check is about the discs
    page.evaluate("document.getElementById('names').checked = false")
    page.evaluate(f"hierplan.seek({t})")
    img = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
    page.evaluate("document.getElementById('names').checked = true")
    head = page.evaluate("({pal: hierplan.head.palette, s: hierplan.pixelsPerUnit()})")
    colors = page.evaluate("Array.from(hierplan.colorIndex())")
    box = page.evaluate(MAP_BOX)
    origin = page.evaluate("hierplan.origin()")
    for k, (x, y) in enumerate(expected):
        cx = box[0] + origin[0] + x * head["s"]
        cy = box[1] + origin[1] + origin[2] * y * head["s"]
        patch = img[
            int(round(cy)) - 2 : int(round(cy)) + 3, int(round(cx)) - 2 : int(round(cx)) + 3
        ]
        want = _rgb(head["pal"][colors[k]])
        share = float((np.abs(patch - want).max(axis=2) <= 40).mean())
        assert share >= 0.5, (
            f"t={t}: robot {k} not seen at its place ({cx:.0f}, {cy:.0f}): {share:.0%}"
        )


@pytest.fixture(scope="module")
def plan_page(chrome: Any, files: dict[str, Path]) -> Any:
    out = files["dir"] / "plan.html"
    assert main(["-q", "view", str(WAREHOUSE), str(files["plan"]), "--out", str(out)]) == 0
    page, errors, load = open_view(chrome, out)
    assert errors == [], errors
    assert load < 3.0
    yield page
    page.close()


# ---------------------------------------------------------------- tests
def test_plan_positions_and_pixels_equal_the_file(plan_page: Any, files: dict[str, Path]) -> None:
    horizon = yaml.safe_load(files["plan"].read_text())["statistics"]["makespan"]
    for t in (0.0, 0.5, 3.25, 7.0, horizon - 0.4, horizon + 2.0):
        exp = plan_positions(files["plan"], t)
        check_drawn(plan_page, exp, t)
        check_pixels(plan_page, exp, t)


def test_map_pixels_show_obstacles_and_free_cells(plan_page: Any) -> None:
    """A blocked cell is drawn dark and a free cell light, at their places."""
    from PIL import Image

    inst = hp.load_instance(WAREHOUSE)
    g = inst.graph
    plan_page.evaluate("document.getElementById('names').checked = false; hierplan.seek(0)")
    img = np.asarray(Image.open(io.BytesIO(plan_page.screenshot())).convert("L")).astype(int)
    plan_page.evaluate("document.getElementById('names').checked = true")
    s = plan_page.evaluate("hierplan.pixelsPerUnit()")
    origin = plan_page.evaluate("hierplan.origin()")
    box = plan_page.evaluate(MAP_BOX)
    marks = list(inst.starts) + [v for team in inst.teams for v in team.targets]
    starts = {tuple(g.coords[v][:2]) for v in marks}
    blocked = np.flatnonzero(~g.passable)
    free = [v for v in np.flatnonzero(g.passable) if tuple(g.coords[v][:2]) not in starts]
    for v, dark in [
        (int(blocked[0]), True),
        (int(blocked[-1]), True),
        (free[0], False),
        (free[-1], False),
    ]:
        x, y = g.coords[v][:2]
        px = img[int(round(box[1] + origin[1] + y * s)), int(round(box[0] + origin[0] + x * s))]
        assert (px < 100) if dark else (px > 220), (v, px)


def test_mutation_robot_data_moved_fails_both_checks(chrome: Any, files: dict[str, Path]) -> None:
    """A page whose robot 0 is one cell off from the file fails the read-back and pixels."""
    inst = hp.load_instance(WAREHOUSE)
    scene = scene_from_plan(inst, hp.load_plan(files["plan"], inst))
    assert scene.steps is not None
    g = inst.graph
    v = int(scene.steps[0, 0])
    x, y = g.coords[v][:2]
    moved = next(
        u
        for u in range(g.n)
        if g.passable[u] and abs(g.coords[u][0] - x) + abs(g.coords[u][1] - y) == 1
    )
    scene.steps[:, 0] = moved  # robot 0 stays one cell away from where the file has it
    out = files["dir"] / "mutant-data.html"
    write_view(scene, out)
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    exp = plan_positions(files["plan"], 0.0)
    with pytest.raises(AssertionError, match="robot\\(s\\) \\[0\\]"):
        check_drawn(page, exp, 0.0)
    with pytest.raises(AssertionError, match="robot 0 not seen"):
        check_pixels(page, exp, 0.0)
    page.close()


def test_mutation_drawing_code_shifted_fails_pixels(chrome: Any, files: dict[str, Path]) -> None:
    """Right positions, wrong drawing: the read-back passes and the pixel check fails."""
    inst = hp.load_instance(WAREHOUSE)
    text = render_html(scene_from_plan(inst, hp.load_plan(files["plan"], inst)))
    line = "const x = (P[2 * k] * s + ox) * dpr"
    assert text.count(line) == 1
    out = files["dir"] / "mutant-draw.html"
    out.write_text(text.replace(line, "const x = ((P[2 * k] + (k === 3 ? 1 : 0)) * s + ox) * dpr"))
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    exp = plan_positions(files["plan"], 0.0)
    check_drawn(page, exp, 0.0)
    with pytest.raises(AssertionError, match="robot 3 not seen"):
        check_pixels(page, exp, 0.0)
    page.close()


def test_scrubbing_and_speed(plan_page: Any, files: dict[str, Path]) -> None:
    end = plan_page.evaluate("hierplan.head.end")
    # scrub: the slider's input event moves the clock and the robots
    for frac in (0.8, 0.25):
        t = frac * end
        plan_page.evaluate(
            "(t) => { const el = document.getElementById('scrub'); el.value = t;"
            " el.dispatchEvent(new Event('input')); }",
            t,
        )
        plan_page.wait_for_function(
            f"Math.abs(hierplan.time() - {t}) < 1e-6 && hierplan.drawn().t === {t}"
        )
        assert f"t = {t:.2f} s" in plan_page.inner_text("#clock")
        got = np.array(plan_page.evaluate("hierplan.drawn().xy")).reshape(-1, 2)
        assert np.abs(got - plan_positions(files["plan"], t)).max() < 1e-3
    # speed: the clock advances `speed` times faster than the page's own clock
    rates = {}
    for speed in (1, 4):
        plan_page.select_option("#speed", str(speed))
        rates[speed] = plan_page.evaluate(
            """() => new Promise((done) => {
                hierplan.seek(0); hierplan.play();
                const t0 = performance.now();
                setTimeout(() => { hierplan.pause();
                  done(hierplan.time() / ((performance.now() - t0) / 1000)); }, 700);
            })"""
        )
    assert 0.6 <= rates[1] <= 1.1, rates
    assert 0.6 * 4 <= rates[4] <= 1.1 * 4, rates
    plan_page.select_option("#speed", "1")


def test_execution_report_events_layers_and_positions(chrome: Any, files: dict[str, Path]) -> None:
    out = files["dir"] / "run.html"
    assert main(["-q", "view", str(WAREHOUSE), str(files["report"]), "--out", str(out)]) == 0
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    report = yaml.safe_load(files["report"].read_text())
    head = page.evaluate("hierplan.head")
    assert head["source"] == "execution"
    assert head["events"]["layer"] == [
        e["layer"] for e in sorted(report["events"], key=lambda e: e["time"])
    ]
    assert head["guaranteed"] == pytest.approx(report["statistics"]["guaranteed_distance"])
    for t in (0.0, 5.3, 11.1, report["statistics"]["makespan"] - 0.2):
        exp = rows_positions(files["report"], t)
        check_drawn(page, exp, t)
        check_pixels(page, exp, t)
    # the closest pair drawn is the file's closest pair within the sampling
    cl = head["closest"]
    assert min(cl["distance"]) >= report["statistics"]["min_distance"] - 1e-6
    assert min(cl["distance"]) <= report["statistics"]["min_distance"] + 0.2
    page.evaluate("hierplan.setColor('delay')")
    legend = page.inner_text("#legend")
    for layer in ("slack", "stn", "replan"):
        assert f"handled by {layer}" in legend
    assert page.evaluate("hierplan.errors") == []
    page.close()


def test_schedule_shows_slack(chrome: Any, files: dict[str, Path]) -> None:
    out = files["dir"] / "sched.html"
    assert main(["-q", "view", str(WAREHOUSE), str(files["schedule"]), "--out", str(out)]) == 0
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    assert page.evaluate("hierplan.head.motion.slack") is True
    for t in (1.0, 9.9):
        check_drawn(page, rows_positions(files["schedule"], t), t)
    page.evaluate("hierplan.setColor('slack')")
    assert "slack < 0.5 s" in page.inner_text("#legend")
    page.close()


def test_lorr_log_positions(chrome: Any, tmp_path: Path) -> None:
    """A LoRR output (MAPF_T actions) decoded here by hand and compared with the page."""
    (tmp_path / "m.map").write_text("type octile\nheight 3\nwidth 4\nmap\n....\n.@..\n....\n")
    log = {
        "actionModel": "MAPF_T",
        "AllValid": "Yes",
        "teamSize": 2,
        "start": [[0, 0, "E"], [2, 3, "N"]],
        "numTaskFinished": 0,
        "sumOfCost": 8,
        "makespan": 4,
        "actualPaths": ["F,F,R,F", "C,F,F,W"],
        "plannerPaths": ["F,F,R,F", "C,F,F,W"],
        "errors": [],
        "events": [[], []],
        "tasks": [],
    }
    f = tmp_path / "log.json"
    f.write_text(json.dumps(log))
    out = tmp_path / "log.html"
    assert main(["-q", "view", str(tmp_path / "m.map"), str(f), "--out", str(out)]) == 0
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    # robot 0: (0,0) facing E, forward twice, turn clockwise to S, forward;
    # robot 1: (3,2) facing N, turn counter-clockwise to W, forward twice along row 2, wait
    cells = np.array(
        [[(0, 0), (1, 0), (2, 0), (2, 0), (2, 1)], [(3, 2), (3, 2), (2, 2), (1, 2), (1, 2)]],
        dtype=float,
    )
    for t in (0.0, 1.0, 1.5, 2.0, 2.75, 4.0, 9.0):
        i = min(int(t), 3)
        f_ = min(t - i, 1.0)
        exp = cells[:, i] + (cells[:, i + 1] - cells[:, i]) * f_
        check_drawn(page, exp, t)
        check_pixels(page, exp, t)
    page.close()


def test_lorr_log_leaving_the_map_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "m.map").write_text("type octile\nheight 3\nwidth 4\nmap\n....\n.@..\n....\n")
    log = {"start": [[2, 3, "W"]], "actualPaths": ["F,C,W,F"], "teamSize": 1}
    f = tmp_path / "log.json"
    f.write_text(json.dumps(log))
    out = tmp_path / "log.html"
    assert main(["view", str(tmp_path / "m.map"), str(f), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "leaves the free cells" in err[0], err
    assert not out.exists()


def test_trajectories_positions_equal_the_npz_samples(chrome: Any, files: dict[str, Path]) -> None:
    """Refined trajectories: the page agrees with the samples stored in the .npz."""
    npz = files["dir"] / "traj.npz"
    args = [str(WAREHOUSE), str(files["schedule"]), "--out", str(npz)]
    assert main(["-q", "refine", *args, "--stretch", "auto", "--solver", "profile"]) == 0
    out = files["dir"] / "traj.html"
    assert main(["-q", "view", str(WAREHOUSE), str(npz), "--out", str(out)]) == 0
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    with np.load(npz) as z:
        ts, pos = z["t"], z["pos"]  # metres, sampled every 0.1 s
    scale = hp.load_instance(WAREHOUSE).graph.scale
    for i in (0, 37, 211, len(ts) - 1):
        exp = pos[:, i, :2] / scale
        t = float(ts[i])
        check_drawn(page, exp, t)
        check_pixels(page, exp, t)
    page.close()


def test_3d_plan_shows_altitude(chrome: Any, tmp_path: Path) -> None:
    g = hp.Graph.grid(4, 3, 3, obstacles=[(1, 1, 0), (1, 1, 1)])
    inst = hp.Instance.mapf(g, [(0, 0, 0), (3, 2, 0)], [(3, 2, 2), (0, 0, 1)])
    plan = hp.solve(inst, "cbs").plan
    assert plan is not None
    out = tmp_path / "3d.html"
    write_view(scene_from_plan(inst, plan), out)
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    for t in (0.0, 1.5, 2.25, float(plan.makespan)):
        d = page.evaluate(f"hierplan.seek({t})")
        i = min(int(t), plan.horizon - 1)
        f = t - i
        for k, path in enumerate(plan.paths):
            a = g.coords[path[min(i, len(path) - 1)]]
            b = g.coords[path[min(i + 1, len(path) - 1)]]
            exp = a + (b - a) * min(f, 1.0)
            assert np.allclose([d["xy"][2 * k], d["xy"][2 * k + 1], d["z"][k]], exp, atol=1e-4)
    page.evaluate("hierplan.setColor('altitude')")
    legend = page.inner_text("#legend")
    assert "z = 2.0" in legend and "altitude" in legend
    page.close()


def test_10000_robots_load_under_3_s_and_play_at_30_fps(chrome: Any, tmp_path: Path) -> None:
    """Ten thousand robots (a made-up motion on an empty 128 x 128 grid: the viewer does
    not need a valid plan; `hierplan bench view` measures a real LaCAM plan)."""
    N, K, T = 128, 10_000, 120
    rng = np.random.default_rng(1)
    cells = rng.permutation(N * N)[:K]
    x0, y0 = cells % N, cells // N
    steps = np.arange(T)[:, None]
    xs = (x0[None, :] + np.round(6 * np.sin(steps / 7 + np.arange(K))).astype(int)) % N
    g = hp.Graph.grid(N, N)
    inst = hp.Instance.mapf(
        g,
        list(zip(x0.tolist(), y0.tolist(), strict=True)),
        list(zip(x0.tolist(), y0.tolist(), strict=True)),
    )
    plan = hp.Plan.from_paths((y0[None, :] * N + xs).T.tolist())
    out = tmp_path / "10k.html"
    write_view(scene_from_plan(inst, plan), out)
    page, errors, load = open_view(chrome, out)
    assert errors == []
    assert load < 3.0, f"first frame after {load:.2f} s"
    m = page.evaluate("hierplan.measure(2000)")
    assert m["fps"] >= 30, m
    t = 17.3
    check_drawn(page, positions_from_steps(g, plan, t), t)
    page.close()


def positions_from_steps(g: hp.Graph, plan: hp.Plan, t: float) -> np.ndarray:
    i = int(math.floor(t))
    a = np.array([g.coords[p[min(i, len(p) - 1)]][:2] for p in plan.paths])
    b = np.array([g.coords[p[min(i + 1, len(p) - 1)]][:2] for p in plan.paths])
    return a + (b - a) * (t - i)


@pytest.mark.parametrize(
    ("args", "what"),
    [
        (["missing.yaml", "--out", "v.html"], "no such file"),
        (["PLAN", "--out", "v.png"], "unsupported extension"),
        (["PLAN", "--out", "nodir/v.html"], "nodir"),
        (["BADJSON", "--out", "v.html"], "not JSON"),
    ],
)
def test_bad_inputs_are_one_line(
    files: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    what: str,
) -> None:
    (tmp_path / "bad.json").write_text("{not json")
    subst = {"PLAN": str(files["plan"]), "BADJSON": str(tmp_path / "bad.json")}
    argv = [subst.get(a, str(tmp_path / a) if a.endswith((".html", ".png")) else a) for a in args]
    capsys.readouterr()
    assert main(["view", str(WAREHOUSE), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and what in err[0], err
    assert not list(tmp_path.glob("*.htm*")) and not list(tmp_path.glob("*.png"))


def test_report_with_fields_added_later_still_reads(files: dict[str, Path], tmp_path: Path) -> None:
    """The execution report may gain fields: the viewer ignores what it does not know."""
    from hierplan_opt.viz.scene import scene_from_report

    data = yaml.safe_load(files["report"].read_text())
    data["statistics"]["new_figure"] = {"nested": [1, 2]}
    data["layers_v2"] = {"anything": True}
    for e in data["events"]:
        e["handled_by"] = {"layer": e["layer"], "when": e["time"]}
    inst = hp.load_instance(WAREHOUSE)
    scene = scene_from_report(inst, "r.yaml", data)
    assert [e["layer"] for e in scene.events] == [e["layer"] for e in data["events"]]
    out = tmp_path / "r.html"
    write_view(scene, out)
    assert "new_figure" not in out.read_text()  # only plain statistics travel


def test_lorr_goals_from_tasks_and_events(tmp_path: Path) -> None:
    from hierplan_opt.viz.scene import scene_from_lorr

    g = hp.Graph.grid(4, 3)
    log = {
        "start": [[0, 0, "E"], [2, 3, "W"]],
        "actualPaths": ["F,W", "W,W"],
        "tasks": [[0, 2, 1], [1, 0, 3]],  # [id, row, col]
        "events": [[[0, 0, "assigned"]], [[1, 0, "assigned"], [1, 2, "finished"]]],
    }
    scene = scene_from_lorr(g, "log.json", log)
    assert scene.goals.tolist() == [[1.0, 2.0], [3.0, 0.0]]
    log["events"] = [[5, 0, 1, "assigned"], [6, 1, 0, "assigned"]]  # another layout: no goals
    assert np.isnan(scene_from_lorr(g, "log.json", log).goals).all()


def test_hover_shows_robot_and_disturbance(chrome: Any, files: dict[str, Path]) -> None:
    out = files["dir"] / "hover.html"
    assert main(["-q", "view", str(WAREHOUSE), str(files["report"]), "--out", str(out)]) == 0
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    page.evaluate("hierplan.seek(10.5)")
    names = page.evaluate("hierplan.head.names")
    x, y = page.evaluate("hierplan.screenOf(3)")
    page.mouse.move(x, y)
    assert page.inner_text("#tip").splitlines()[0] == names[3]
    ev = page.evaluate("hierplan.head.events")
    i = ev["layer"].index("replan")
    left, top, width = page.evaluate(
        "(() => { const r = document.getElementById('timeline').getBoundingClientRect();"
        " return [r.left, r.top, r.width]; })()"
    )
    row = page.evaluate("Object.keys(hierplan.head.layers)").index("replan")
    end = page.evaluate("hierplan.head.end")
    page.mouse.move(left + 40 + ev["t"][i] / end * (width - 50), top + 4 + row * 9 + 4)
    tip = page.inner_text("#tip")
    assert f"{names[ev['a'][i]]}  {ev['kind'][i]} -> replan" in tip, tip
    page.close()


def test_page_is_self_contained(chrome: Any, files: dict[str, Path]) -> None:
    """No server, no network: the page asks for nothing but itself and its data URL."""
    out = files["dir"] / "plan.html"  # written by the plan_page fixture's command
    if not out.exists():
        assert main(["-q", "view", str(WAREHOUSE), str(files["plan"]), "--out", str(out)]) == 0
    text = out.read_text()
    assert "http://" not in text and "https://" not in text and " src=" not in text
    page = chrome.new_page()
    asked: list[str] = []
    page.on("request", lambda r: asked.append(r.url))
    page.goto(out.resolve().as_uri())
    assert page.evaluate("window.hierplan.ready") is True
    assert asked and all(u.startswith(("file://", "data:")) for u in asked), asked
    page.close()


def expected_image(
    g: hp.Graph,
    s: float,
    origin: list[float],
    size: tuple[int, int],
    disc: tuple[float, float, float, str],
) -> tuple[np.ndarray, np.ndarray]:
    """The map canvas as it should look (cells, one robot disc) and a mask of the pixels
    to compare (those not on a cell edge or the disc's rim)."""
    assert g.shape is not None
    W, H = g.shape[0], g.shape[1]
    w, h = size
    xs, ys = np.arange(w) + 0.5, np.arange(h) + 0.5
    mx = (xs - origin[0]) / s  # map coordinates of pixel centres
    my = (ys - origin[1]) / s
    img = np.full((h, w, 3), 255.0)
    cx, cy = np.floor(mx + 0.5).astype(int), np.floor(my + 0.5).astype(int)
    inside = (cx[None, :] >= 0) & (cx[None, :] < W) & (cy[:, None] >= 0) & (cy[:, None] < H)
    blocked = (~g.passable).reshape(H, W)
    yy, xx = np.clip(cy, 0, H - 1)[:, None], np.clip(cx, 0, W - 1)[None, :]
    cell = np.where(blocked[yy, xx], 250 - 255 * 0.8, 250)
    img[inside] = np.round(cell[inside])[:, None]
    edge = (np.abs(mx - np.round(mx - 0.5) - 0.5) * s < 1.5)[None, :] | (
        np.abs(my - np.round(my - 0.5) - 0.5) * s < 1.5
    )[:, None]
    x0, y0, r, color = disc
    px, py = x0 * s + origin[0], y0 * s + origin[1]
    d = np.hypot(xs[None, :] - px, ys[:, None] - py)
    img[d <= r * s] = _rgb(color)
    rim = np.abs(d - r * s) < 1.5
    return img, ~(edge | rim)


def test_screenshot_equals_expected_image(chrome: Any, tmp_path: Path) -> None:
    """The whole map canvas, pixel for pixel (away from edges), against an image computed
    here; and the same comparison fails for a page whose robot is one cell off."""
    from PIL import Image

    g = hp.Graph.grid(7, 4, obstacles=[(2, 1), (3, 1), (4, 1), (5, 3)])
    inst = hp.Instance.mapf(g, [(0, 0)], [(6, 2)])
    plan = hp.Plan.from_paths(
        [[g.vertex((x, 0)) for x in range(7)] + [g.vertex((6, 1)), g.vertex((6, 2))]]
    )

    def compare(page: Any, t: float, x: float, y: float) -> float:
        # goals and names off: the map and the robot only
        page.evaluate("document.getElementById('goals').checked = false; hierplan.redraw()")
        page.evaluate("document.getElementById('names').checked = false")
        page.evaluate(f"hierplan.seek({t})")
        s = page.evaluate("hierplan.pixelsPerUnit()")
        ox, oy, _ = page.evaluate("hierplan.origin()")
        left, top = page.evaluate(MAP_BOX)
        w, h = page.evaluate(
            "[document.getElementById('map').width, document.getElementById('map').height]"
        )
        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(float)
        got = shot[int(top) : int(top) + h, int(left) : int(left) + w]
        exp, mask = expected_image(g, s, [ox, oy], (w, h), (x, y, 0.3, PALETTE_0))
        lx, ly, lw, lh = page.evaluate(
            "(() => { const r = document.getElementById('legend').getBoundingClientRect();"
            " return [r.left, r.top, r.width, r.height]; })()"
        )  # the legend box lies over the map's corner
        mask[
            int(ly - top) - 2 : int(ly - top + lh) + 3, int(lx - left) - 2 : int(lx - left + lw) + 3
        ] = False
        bad = (np.abs(got - exp).max(axis=2) > 12) & mask
        return float(bad.sum()) / float(mask.sum())

    out = tmp_path / "one.html"
    write_view(scene_from_plan(inst, plan), out)
    page, errors, _ = open_view(chrome, out, width=900, height=600)
    assert errors == []
    for t, (x, y) in ((0.0, (0, 0)), (2.5, (2.5, 0)), (7.5, (6, 1.5))):
        assert compare(page, t, x, y) == 0.0, t
    # mutation: the page's robot is one cell below where the plan has it
    scene = scene_from_plan(inst, plan)
    assert scene.steps is not None
    scene.steps[:, 0] = [
        g.vertex((min(x, 6), 1 if x in (0, 1, 6) else 0)) for x in range(len(scene.steps))
    ]
    write_view(scene, tmp_path / "off.html")
    off, errors, _ = open_view(chrome, tmp_path / "off.html", width=900, height=600)
    assert compare(off, 0.0, 0, 0) > 0.001
    page.close()
    off.close()


PALETTE_0 = "#1f77b4"


def test_lorr_3x_segment_paths_with_agent_counter(chrome: Any, tmp_path: Path) -> None:
    """Start-Kit 3.x logs: compressed segments, an action takes agentCounter ticks."""
    (tmp_path / "m.map").write_text("type octile\nheight 3\nwidth 4\nmap\n....\n.@..\n....\n")
    log = {
        "teamSize": 2,
        "actualPaths": ["[(0,0,0,0,0):(F 4,W 1)]", "[(0,2,3,2,0):(R 2,F 2)]"],
        "delayIntervals": [[[4, 6]], []],
    }
    f = tmp_path / "log3.json"
    f.write_text(json.dumps(log))
    out = tmp_path / "log3.html"
    argv = ["-q", "view", str(tmp_path / "m.map"), str(f), "--out", str(out)]
    assert main([*argv, "--agent-counter", "2"]) == 0
    page, errors, _ = open_view(chrome, out)
    assert errors == []
    # robot 0 (row 0, col 0, east): half a cell per tick; robot 1 (row 2, col 3, west)
    # turns clockwise to north in two ticks, then half a cell per tick up
    want = {
        0: [(0, 0), (3, 2)],
        1: [(0.5, 0), (3, 2)],
        2: [(1, 0), (3, 2)],
        3: [(1.5, 0), (3, 1.5)],
        4: [(2, 0), (3, 1)],
        5: [(2, 0), (3, 1)],
    }
    for t, exp in want.items():
        check_drawn(page, np.array(exp, dtype=float), float(t))
    check_drawn(page, np.array([(1.25, 0), (3, 1.75)]), 2.5)
    ev = page.evaluate("hierplan.head.events")
    assert (ev["t"], ev["a"], ev["kind"], ev["delay"]) == ([4.0], [0], ["delay"], [2.0])
    page.close()
