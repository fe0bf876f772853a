"""Progress of long work (``--progress``): status lines at the interval on a non-terminal,
hidden by ``-q``, and the counts shown are the solvers' own counts."""

from __future__ import annotations

import logging
import types
from collections.abc import Iterator

import pytest

import hierplan_opt as hp
from hierplan_opt.cli import main
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance, Kinematics
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.progress import Progress, active, note, reporting, tick, watching_highs
from hierplan_opt.experiments.data import movingai_files
from hierplan_opt.io.movingai import load_movingai

progress_module = __import__("hierplan_opt.core.progress", fromlist=["time"])

SCEN = "random-32-32-20-random-1"
K = 20  # CBS expands a few nodes, ECBS too


@pytest.fixture(autouse=True)
def _package_logging() -> Iterator[None]:
    """The package's loggers at their defaults (``hierplan bench teams`` in-process, as
    its doctest runs it, sets ``hierplan_opt`` to WARNING for good)."""
    loggers = [logging.getLogger(n) for n in ("hierplan_opt", "hierplan_opt.progress")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.NOTSET)
    yield
    for lg, level in zip(loggers, levels, strict=True):
        lg.setLevel(level)


def _progress_lines(err: str) -> list[str]:
    prefix = "INFO hierplan_opt.progress: "
    return [ln.removeprefix(prefix) for ln in err.splitlines() if ln.startswith(prefix)]


def _cli(*argv: str) -> list[str]:
    mp, scen = movingai_files(SCEN)
    return [*argv[:1], str(mp), "--scen", str(scen), "--agents", str(K), *argv[1:]]


def test_tick_without_active_progress_does_nothing() -> None:
    assert active() is None
    tick("expanded", 3, lb=1)  # no error, no effect
    note(best=4)
    with reporting(None) as p:
        assert p is None and active() is None
    with reporting(Progress("x", enabled=False)) as p:
        assert active() is p
    assert active() is None


def test_status_lines_come_at_the_interval(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    clock = [0.0]
    monkeypatch.setattr(
        progress_module, "time", types.SimpleNamespace(perf_counter=lambda: clock[0])
    )
    with (
        caplog.at_level("INFO", logger="hierplan_opt.progress"),
        reporting(Progress("solve demo", enabled=True, interval=5.0)),
    ):
        for n in range(1, 21):  # one tick a second for 20 s
            clock[0] = float(n)
            tick("expanded", n, lb=100 + n, best=None)
    lines = [r.getMessage() for r in caplog.records]
    # at 5, 10, 15 and 20 s; the final line would say what the one at 20 s said, so it
    # is not printed again (issue 34: each progress line printed twice)
    assert [ln.split(",")[0] for ln in lines] == [
        "solve demo: 5 expanded",
        "solve demo: 10 expanded",
        "solve demo: 15 expanded",
        "solve demo: 20 expanded",
    ]
    assert lines[0] == "solve demo: 5 expanded, lb 105, 0:05 elapsed"
    assert "best" not in lines[-1]  # None figures are left out
    caplog.clear()
    with (
        caplog.at_level("INFO", logger="hierplan_opt.progress"),
        reporting(Progress("solve demo", enabled=True, interval=5.0)),
    ):
        clock[0] = 30.0
        tick("expanded", 1, lb=1)  # a line (5 s since the start)
        tick("expanded", 2, lb=2)  # not yet shown: the final line shows it
    assert [r.getMessage().split(",")[0] for r in caplog.records] == [
        "solve demo: 1 expanded",
        "solve demo: 2 expanded",
    ]


@pytest.mark.parametrize("solver", ["cbs", "ecbs"])
def test_solve_progress_shows_the_solvers_counts(
    solver: str, capsys: pytest.CaptureFixture[str]
) -> None:
    mp, scen = movingai_files(SCEN)
    ref = hp.solve(load_movingai(mp, scen, K), solver)
    expanded = ref.stats["high_level_expanded"]
    assert expanded > 0
    argv = _cli("solve", "--solver", solver, "--progress", "--progress-interval", "0.000001")
    assert main(argv) == 0
    lines = _progress_lines(capsys.readouterr().err)
    # a line per expansion (the interval is tiny), then the final line with the result
    assert len(lines) >= expanded + 1
    assert lines[-1].startswith(f"solve {solver}: {expanded} expanded, lb ")
    assert f"best {ref.cost:g}" in lines[-1] and f"status {ref.status}" in lines[-1]
    # (heartbeats before the first count say "started": ECBS runs LaCAM first)
    counts = [int(ln.split(": ")[1].split()[0]) for ln in lines if ": started," not in ln]
    assert counts == sorted(counts) and counts[0] == 1

    assert main(["-q", *argv]) == 0
    assert _progress_lines(capsys.readouterr().err) == []
    assert main(argv[:-3]) == 0  # without --progress: no status line either
    assert _progress_lines(capsys.readouterr().err) == []


def test_formulation_ladder_reports_each_horizon() -> None:
    # Two robots swap through a pocket: the horizon search climbs a few horizons.
    g = Graph.grid(3, 2, obstacles=[(0, 1), (2, 1)])
    inst = Instance.mapf(g, [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    with reporting(Progress("solve cpsat", enabled=False)) as p:
        r = hp.solve(inst, "cpsat", cost="makespan")
    assert p is not None and r.status is hp.Status.OPTIMAL
    assert p.unit == "solves" and p.completed == r.stats["solves"] >= 2
    assert p.fields["horizon"] == r.stats["horizons"][-1][0] == r.cost
    assert p.fields["status"] == r.stats["horizons"][-1][1]
    # sum of costs: CP-SAT's solutions show their objective and bound during the solve
    mp, scen = movingai_files(SCEN)
    with reporting(Progress("solve cpsat", enabled=False)) as p:
        r = hp.solve(load_movingai(mp, scen, 6), "cpsat")
    assert p is not None and r.status is hp.Status.OPTIMAL
    assert p.fields["objective"] == r.cost and p.completed == r.stats["solves"]


def test_post_and_refine_report_their_steps_and_robots() -> None:
    from hierplan_opt.schedule import postprocess
    from hierplan_opt.trajectory import refine

    g = Graph.grid(4, 1)
    kin = Kinematics(v_max=1.0, a_max=2.0)
    inst = Instance.mapf(g, [(1, 0), (0, 0)], [(3, 0), (2, 0)], kinematics=kin)
    plan = Plan.from_paths([[1, 2, 3], [0, 1, 2]])
    with reporting(Progress("post lp", enabled=False)) as p:
        sched = postprocess(inst, plan, "makespan", method="lp")
    assert p is not None and (p.completed, p.total, p.unit) == (3, 3, "steps")
    assert p.fields["stn_arcs"] == sched.stats["stn_arcs"]
    with reporting(Progress("refine", enabled=False)) as p:
        traj = refine(inst, sched, stretch="auto")
    assert p is not None and p.unit == "robots"
    assert p.completed == p.total == traj.num_agents == 2


def test_highs_solves_show_their_own_figures(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    from hierplan_opt.schedule import postprocess

    monkeypatch.setattr(progress_module, "CALLBACK_INTERVAL", 0.0)
    mp, scen = movingai_files(SCEN)
    inst = load_movingai(mp, scen, 6)
    # the time-expanded MIP (HiGHS through Pyomo): its incumbent and bound as it runs
    with (
        caplog.at_level("INFO", logger="hierplan_opt.progress"),
        reporting(Progress("solve mip", enabled=True, interval=0.0)) as p,
    ):
        r = hp.solve(inst, "mip")
    assert p is not None and r.status is hp.Status.OPTIMAL
    lines = [rec.getMessage() for rec in caplog.records]
    assert any("mip_nodes" in ln and f"mip_primal {r.cost:g}" in ln for ln in lines[:-1])
    assert p.fields["mip_primal"] == p.fields["mip_dual"] == r.cost
    assert p.fields["mip_gap"] == 0.0 and p.fields["lp_iter"] > 0  # the LP relaxation ran
    # the MAPF-POST LP, both back ends: simplex iterations while it runs
    plan = hp.solve(load_movingai(mp, scen, K), "cbs").plan
    for backend in ("pyomo", "highs"):
        with reporting(Progress("post lp", enabled=False)) as p:
            postprocess(load_movingai(mp, scen, K), plan, "safety", method="lp",
                        lp_backend=backend)  # fmt: skip
        assert p is not None and p.fields["lp_iter"] > 0, backend

    # without an active progress the HiGHS object is not even looked at
    class Untouchable:
        def __getattr__(self, name: str) -> None:
            raise AssertionError(f"callback {name} used without a progress")

    with watching_highs(Untouchable()):
        pass


def test_refine_shows_ipopt_iterations_bisection_steps_and_profile_robots(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    from hierplan_opt.schedule import postprocess
    from hierplan_opt.trajectory import model, refine

    monkeypatch.setattr(progress_module, "CALLBACK_INTERVAL", 0.0)
    # 4 m at v_max 1, a_max 1: 5 s against a schedule of 4 s (stretch 5/4)
    inst = Instance.mapf(
        Graph.grid(5, 1), [(0, 0)], [(4, 0)], kinematics=Kinematics(v_max=1.0, a_max=1.0)
    )
    sched = postprocess(inst, Plan.from_paths([list(range(5))]), acceleration=False)
    # one IPOPT solve: a line per iteration, the last one IPOPT's own count
    with (
        caplog.at_level("INFO", logger="hierplan_opt.progress"),
        reporting(Progress("refine", enabled=True, interval=0.0)) as p,
    ):
        tr = refine(inst, sched, stretch=1.3, solver="ipopt")
    iterations = tr.robots[0].stats["iterations"]
    assert p is not None and p.fields["nlp_iter"] == iterations > 2
    shown = [
        int(ln.split("nlp_iter ")[1].split(",")[0]) for ln in caplog.messages if "nlp_iter" in ln
    ]
    assert shown[: iterations + 1] == list(range(iterations + 1))
    # the stretch search: its bisection steps around 5/4
    with reporting(Progress("refine", enabled=False)) as p:
        tr = refine(inst, sched, stretch="auto", solver="ipopt")
    assert p is not None and p.unit == "stretch steps" and p.completed >= 1
    assert p.fields["robot"] == "agent0" and abs(p.fields["stretch"] - 1.25) < 0.01
    # the profile solver: per robot, with the fleet's factor
    with reporting(Progress("refine", enabled=False)) as p:
        tr = refine(inst, sched, stretch="auto", solver="profile")
    assert p is not None and (p.unit, p.completed, p.total) == ("robots", 1, 1)
    assert tr.stretch is not None and p.fields["stretch"] * sched.makespan >= 5.0 - 1e-6
    # without a progress: the problem built without the callback
    model.clear_cache()
    refine(inst, sched, stretch=1.3, solver="ipopt")
    assert model._CACHE and all(not key[-1] for key in model._CACHE)
