"""Solver options declared once and checked before any work; the front door's other
promises: a default time limit, cheap infeasibility checks for every solver, one meaning
for ``cost`` and ``gap``, uniform benchmark flags."""

from __future__ import annotations

import gc
import inspect
import time
from pathlib import Path

import pytest
import yaml
from io_helpers import DATA

import hierplan_opt as hp
from hierplan_opt import registry
from hierplan_opt.bench import AREAS
from hierplan_opt.cli import main
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.options import Option, parse_bool
from hierplan_opt.search import ecbs

CORRIDOR = str(DATA / "corridor_lmrp.yaml")  # MAPF, 2 agents
ANONYMOUS = str(DATA / "anonymous_lmrp.yaml")  # TAPF, one team
TEAMS = str(DATA / "roadmap_teams.yaml")  # TAPF, two teams


@pytest.fixture(autouse=True)
def _no_leftover_logging(capsys: pytest.CaptureFixture[str]) -> None:
    # Kernel clients left by the notebook tests log a warning when collected, through a
    # handler bound to an earlier test's (closed) stderr; collect them before capturing so
    # the one-line checks below see only this test's output.
    gc.collect()
    capsys.readouterr()


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


# Every case of the issue: (instance, solver, --set, words the one-line error must hold).
BAD_SETS = [
    (CORRIDOR, "cpsat", "workers=abc", "cpsat option workers must be >= 1"),
    (CORRIDOR, "cpsat", "max_horizon=abc", "cpsat option max_horizon must be >= 1"),
    (CORRIDOR, "mip", "max_horizon=abc", "mip option max_horizon must be >= 1"),
    (CORRIDOR, "cpsat", "max_horizon=-7", "cpsat option max_horizon must be >= 1"),
    (CORRIDOR, "mip", "max_horizon=-7", "mip option max_horizon must be >= 1"),
    (ANONYMOUS, "flow", "min_cost_arcs=abc", "flow option min_cost_arcs must be >= 0"),
    (ANONYMOUS, "hungarian", "mapf_options=abc", "hungarian option mapf_options must be"),
    (CORRIDOR, "cpsat", "hint=abc", "cpsat option hint must be a solver name"),
    (CORRIDOR, "mip", "lp_check=-7", "mip option lp_check must be true or false, got '-7'"),
    (CORRIDOR, "ecbs", "polish=abc", "ecbs option polish must be true or false, got 'abc'"),
    (CORRIDOR, "eecbs", "bypass=abc", "eecbs option bypass must be true or false"),
    (ANONYMOUS, "flow", "min_cost=abc", "flow option min_cost must be true or false or none"),
    (CORRIDOR, "cbs", "bypass=maybe", "cbs option bypass must be true or false, got 'maybe'"),
    (CORRIDOR, "cbs", "heuristic=magic", "cbs option heuristic must be one of 'wdg'"),
    (CORRIDOR, "ecbs", "w=0.5", "ecbs option w must be a number >= 1"),
    (ANONYMOUS, "hungarian", "mapf_options={bogus: 1}", "mapf_options: solver 'cbs' has no"),
]


@pytest.mark.parametrize(("inst", "solver", "pair", "needle"), BAD_SETS)
def test_bad_set_is_one_line_before_any_work(
    capsys: pytest.CaptureFixture[str], inst: str, solver: str, pair: str, needle: str
) -> None:
    t0 = time.perf_counter()
    code, out, err = run(capsys, "solve", inst, "--solver", solver, "--set", pair)
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], err
    assert time.perf_counter() - t0 < 5  # refused before solving, not after


@pytest.mark.parametrize(
    ("solver", "options"),
    [
        ("cpsat", {"workers": "abc"}),
        ("cpsat", {"workers": 1.5}),
        ("mip", {"max_horizon": -7}),
        ("mip", {"lp_check": -7}),
        ("cpsat", {"hint": "abc"}),
        ("ecbs", {"polish": "abc"}),
        ("eecbs", {"bypass": 1}),
        ("cbs", {"node_limit": True}),
    ],
)
def test_bad_library_options_refused(solver: str, options: dict) -> None:
    inst = hp.load_instance(CORRIDOR)
    with pytest.raises(OptionError, match=f"{solver} option {next(iter(options))} must be"):
        hp.solve(inst, solver, **options)


def test_booleans_read_the_same_everywhere(capsys: pytest.CaptureFixture[str]) -> None:
    assert [parse_bool(w) for w in ("true", "Yes", "ON", "false", "no", "Off")] == [
        True,
        True,
        True,
        False,
        False,
        False,
    ]
    for word in ("yes", "on", "true"):
        code, out, _ = run(
            capsys, "solve", CORRIDOR, "--solver", "eecbs", "--set", f"bypass={word}"
        )
        assert code == 0 and out.startswith(("OPTIMAL", "FEASIBLE"))
    code, _, _ = run(
        capsys, "bench", "cbs", "--instance", "empty-8-8-even-1:2", "--option", "bypass=off"
    )
    assert code == 0


def test_nested_options_are_parsed_and_checked(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(
        capsys,
        "solve",
        ANONYMOUS,
        "--solver",
        "hungarian",
        "--set",
        "mapf_solver=cbm",
        "--set",
        "mapf_options={tie_break: none}",
    )
    assert code == 0, err
    assert out.startswith(("OPTIMAL", "FEASIBLE"))


def test_every_solver_declares_every_option_once() -> None:
    for name in registry.names():
        spec = registry.get(name).load().options
        sig = inspect.signature(registry.get(name).load().fn)
        own = [p for p in sig.parameters if p not in registry.COMMON]
        assert spec.names() == own, name
        for opt in spec:
            assert opt.help and opt.kind in ("bool", "int", "float", "choice", "solver", "options")
            assert opt.default == sig.parameters[opt.name].default  # from the signature
            if opt.default is not None:
                assert opt.check(opt.default, name) == opt.default


def test_declaration_must_match_the_signature() -> None:
    with pytest.raises(TypeError, match="do not match the signature"):

        @registry.solver("demo", Option("w", "float", "bound"))
        def solve(instance, *, time_limit=None, seed=0, objective="soc", v=1.0):
            return None


def test_options_are_listed(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["solve", "--solver", "ecbs", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "options of solver 'ecbs'" in out
    assert "w: number >= 1" in out and "polish: true/false (default true)" in out
    code, out, _ = run(capsys, "info", "--solvers")
    assert code == 0 and "max_horizon: integer >= 1 or none" in out


# ---------------------------------------------------------------- front door
def test_library_solve_has_a_documented_default_time_limit() -> None:
    default = inspect.signature(hp.solve).parameters["time_limit"].default
    assert default == 60.0
    assert "default 60" in (hp.solve.__doc__ or "")
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    assert "time_limit=60" in readme


@pytest.mark.parametrize("solver", ["cbs", "ecbs", "eecbs", "cbm", "cpsat", "mip"])
def test_every_solver_answers_infeasible_at_once(solver: str) -> None:
    # Two robots must swap ends of a corridor: the cheap checks (the exact pebble-motion
    # test of core/feasibility.py) prove it has no plan.
    inst = hp.Instance.mapf(hp.Graph.grid(3, 1), [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    t0 = time.perf_counter()
    r = hp.solve(inst, solver, time_limit=30)
    assert r.status is hp.Status.INFEASIBLE and "cannot pass" in r.stats["reason"]
    assert time.perf_counter() - t0 < 5


def test_cheap_checks_count_against_the_time_limit() -> None:
    # 2000 goals on 64 x 64: the distance tables of the checks alone take about a second.
    from lacam_cases import large_empty

    limit = 0.02
    for solver in ("lacam", "cbs"):
        inst = large_empty(2000)
        t0 = time.perf_counter()
        r = hp.solve(inst, solver, time_limit=limit)
        elapsed = time.perf_counter() - t0
        assert r.status is hp.Status.TIME_LIMIT and r.plan is None
        assert "during the cheap checks" in r.stats["reason"]
        assert elapsed < 10 * limit + 0.5


_SEEN: list[float | None] = []


def _spy(instance: hp.Instance, *, time_limit: float | None = None, **_: object) -> hp.Result:
    _SEEN.append(time_limit)
    return hp.Result(hp.Status.TIME_LIMIT, None)


def test_solver_gets_what_the_checks_leave() -> None:
    registry.register("spy", f"{__name__}:_spy")
    try:
        inst = hp.Instance.mapf(hp.Graph.grid(3, 3), [(0, 0)], [(2, 2)])
        registry.run("spy", inst, time_limit=5)
        registry.run("spy", inst, time_limit=None)
    finally:
        registry._REGISTRY.pop("spy")  # pyright: ignore[reportPrivateUsage]
    assert _SEEN[-1] is None
    given = _SEEN[-2]
    assert given is not None and 0 < given < 5


def test_direct_solver_call_checks_like_the_front_door() -> None:
    inst = hp.Instance.mapf(hp.Graph.grid(3, 1), [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    assert ecbs.solve(inst).status is hp.Status.INFEASIBLE  # no time limit, no endless loop
    with pytest.raises(OptionError, match="ecbs option w"):
        ecbs.solve(inst, w=0.5)


def test_team_instance_refused_by_cbs_names_cbm_and_flow(
    capsys: pytest.CaptureFixture[str],
) -> None:
    teams = hp.load_instance(TEAMS)
    with pytest.raises(OptionError, match="for teams use 'cbm'$"):
        hp.solve(teams, "cbs")
    one_team = hp.load_instance(ANONYMOUS)
    with pytest.raises(OptionError, match="use 'cbm', or 'flow' for one team"):
        hp.solve(one_team, "cbs")
    code, _, err = run(capsys, "solve", TEAMS, "--solver", "cbs")
    assert code == 2 and "for teams use 'cbm'" in err
    # without --solver, solve picks one that fits the instance and says so (issue 34)
    code, out, err = run(capsys, "solve", TEAMS)
    assert code == 0 and "no --solver given; using" in err


# ---------------------------------------------------------------- one meaning per word
def test_cost_gap_and_plan_file_agree_for_makespan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = tmp_path / "p.yaml"
    code, out, _ = run(capsys, "solve", CORRIDOR, "--cost", "makespan", "--out", str(plan))
    assert code == 0
    words = dict(w.split("=", 1) for w in out.split() if "=" in w)
    st = yaml.safe_load(plan.read_text())["statistics"]
    assert st["objective"] == "makespan" == words["objective"]
    assert st["cost"] == st["makespan"] == int(words["cost"]) == int(words["makespan"])
    assert st["soc"] == int(words["soc"]) and st["soc"] > st["cost"]
    assert st["lower_bound"] == int(words["lb"]) <= st["cost"]
    assert float(words["gap"]) == (st["cost"] - st["lower_bound"]) / st["cost"]


def test_gap_is_relative_to_the_cost() -> None:
    r = hp.Result(hp.Status.FEASIBLE, None, cost=120, lower_bound=100)
    assert r.gap == pytest.approx(20 / 120)
    assert hp.Result(hp.Status.OPTIMAL, None, cost=0, lower_bound=0).gap == 0.0


# ---------------------------------------------------------------- benchmarks
@pytest.mark.parametrize("area", sorted(AREAS))
def test_bench_flags_are_uniform(area: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["bench", area, "--help"])
    out = capsys.readouterr().out
    for flag in ("--quick", "--time-limit", "--instance"):
        assert flag in out, (area, flag)
    code, out, err = run(capsys, "bench", area, "--bogus")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "--bogus" in err


def test_bench_post_quick_runs(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(
        capsys, "bench", "post", "--quick", "--instance", "empty-8-8-even-1", "--agents", "4"
    )
    assert code == 0, err
    assert "empty-8-8-even-1" in out
