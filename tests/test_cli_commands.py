"""``hierplan solve``, ``validate`` and ``info``: exit codes, output, one-line errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from io_helpers import DATA, MOVINGAI, write

from hierplan_opt import Plan, registry
from hierplan_opt.cli import main
from hierplan_opt.core.result import Result, Status

MAP = str(MOVINGAI / "random-32-32-20.map")
SCEN = str(MOVINGAI / "random-32-32-20-random-1.scen")
CORRIDOR = str(DATA / "corridor_lmrp.yaml")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(err: str) -> None:
    lines = [ln for ln in err.splitlines() if not ln.startswith(("INFO", "DEBUG"))]
    assert len(lines) == 1, err
    assert "Traceback" not in err and "error:" in lines[0]


# ---------------------------------------------------------------- solve + validate
def test_golden_corridor(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_plan = tmp_path / "plan.yaml"
    code, out, _ = run(capsys, "solve", CORRIDOR, "--solver", "cbs", "--out", str(out_plan))
    assert code == 0
    assert out.startswith("OPTIMAL cost=8 lb=8 gap=0.0000 soc=8 makespan=4")
    data = yaml.safe_load(out_plan.read_text())
    assert data["statistics"]["cost"] == 8 and data["statistics"]["status"] == "OPTIMAL"
    assert set(data["schedule"]) == {"agent0", "agent1"}
    code, out, _ = run(capsys, "validate", CORRIDOR, str(out_plan))
    assert code == 0
    assert out.startswith("valid: soc=8 makespan=4")


def test_acceptance_random_32_32_20(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = tmp_path / "plan.yaml"
    args = [MAP, "--scen", SCEN, "--agents", "20"]
    code, out, _ = run(capsys, "solve", *args, "--solver", "cbs", "--out", str(plan))
    assert code == 0, out
    words = dict(w.split("=", 1) for w in out.split() if "=" in w)
    assert out.startswith("OPTIMAL") and words["cost"] == words["lb"]
    code, out, _ = run(capsys, "validate", *args, str(plan))
    assert code == 0 and out.startswith(f"valid: soc={words['cost']} ")


def test_json_plan_and_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = tmp_path / "plan.json"
    code, out, _ = run(
        capsys,
        "solve",
        CORRIDOR,
        "--solver=cbs",
        "--cost",
        "makespan",
        "--set",
        "bypass=false",
        "--seed",
        "3",
        "--time-limit",
        "20",
        "--out",
        str(plan),
    )
    assert code == 0 and "objective=makespan" in out
    code, out, _ = run(capsys, "validate", CORRIDOR, str(plan))
    assert code == 0 and "makespan=4" in out


def test_tapf_plan_round_trip(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inst = str(DATA / "anonymous_lmrp.yaml")
    plan = tmp_path / "plan.yaml"
    code, out, _ = run(capsys, "solve", inst, "--solver", "flow", "--out", str(plan))
    assert code == 0 and "objective=makespan" in out and "makespan=3" in out
    assert set(yaml.safe_load(plan.read_text())["schedule"]) == {"a", "b", "c"}
    code, out, _ = run(capsys, "validate", inst, str(plan))
    assert code == 0 and "makespan=3" in out


def test_no_out_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "solve", CORRIDOR)
    assert code == 0 and "->" not in out


def test_infeasible_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inst = write(
        tmp_path,
        "wall.yaml",
        "map: {dimensions: [3, 1], obstacles: [[1, 0]]}\n"
        "agents: [{name: a, start: [0, 0], goal: [2, 0]}]\n",
    )
    plan = tmp_path / "plan.yaml"
    code, out, _ = run(capsys, "solve", str(inst), "--out", str(plan))
    assert code == 3 and out.startswith("INFEASIBLE")
    assert not plan.exists()


def test_time_limit_exit_4(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Two robots swapping on a two-cell corridor: unsolvable, but no quick check proves it.
    inst = write(
        tmp_path,
        "swap.yaml",
        "map: {dimensions: [2, 1]}\n"
        "agents: [{start: [0, 0], goal: [1, 0]}, {start: [1, 0], goal: [0, 0]}]\n",
    )
    plan = tmp_path / "plan.yaml"
    code, out, _ = run(capsys, "solve", str(inst), "--time-limit", "0.5", "--out", str(plan))
    assert code in (3, 4), out  # INFEASIBLE if the solver proves it, else TIME_LIMIT
    assert not plan.exists()
    assert out.startswith("INFEASIBLE" if code == 3 else "TIME_LIMIT")


def broken_solve(instance, *, time_limit=None, seed=0, objective="soc"):
    """A 'solver' whose plan teleports: the front door must turn it into ERROR."""
    paths = [[a.goal] for a in instance.agents]
    return Result(Status.OPTIMAL, Plan.from_paths(paths), cost=0)


def test_solver_error_exit_70(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    registry.register("broken-test", f"{__name__}:broken_solve", objectives={"soc"})
    try:
        plan = tmp_path / "plan.yaml"
        code, out, err = run(
            capsys, "solve", CORRIDOR, "--solver", "broken-test", "--out", str(plan)
        )
    finally:
        registry._REGISTRY.pop("broken-test", None)
    assert code == 70
    assert out.startswith("ERROR") and "solver error: invalid plan" in err
    assert not plan.exists()


def test_validate_reports_violations(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "validate", CORRIDOR, str(DATA / "corridor_plan_conflict.yaml"))
    assert code == 1
    lines = out.splitlines()
    assert len(lines) == 1  # the first violation and the count of the others
    assert "vertex_conflict: agent0 and agent1 are both at [2, 0] at t=2" in lines[0]
    assert lines[0].endswith("(and 1 further problem: 1 vertex_conflict)")
    code, out, _ = run(
        capsys, "validate", CORRIDOR, str(DATA / "corridor_plan_conflict.yaml"), "--all"
    )
    lines = out.splitlines()
    assert code == 1 and len(lines) == 2
    assert "vertex_conflict: agent0 and agent1 are both at [2, 0] at t=2" in lines[0]


# ---------------------------------------------------------------- info
def test_info(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "info", MAP, "--scen", SCEN, "--agents", "20")
    assert code == 0
    assert "graph: grid 32x32, 819 free cells" in out
    assert "problem: MAPF, 20 agents" in out
    assert "soc lower bound: 405" in out and "makespan lower bound: 48" in out
    code, out, _ = run(capsys, "info", str(DATA / "roadmap_teams.yaml"))
    assert code == 0 and "TAPF, 3 agents in 2 teams (red=2, blue=1)" in out


def test_info_infeasible_and_solvers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inst = write(
        tmp_path,
        "wall.yaml",
        "graph: {type: grid, rows: ['.@.']}\nagents: [{name: a, start: [0, 0], goal: [2, 0]}]\n",
    )
    code, out, _ = run(capsys, "info", str(inst))
    assert code == 0 and "infeasible: yes, agent 'a' cannot reach its goal" in out
    code, out, _ = run(capsys, "info", "--solvers")
    assert code == 0
    assert any(ln.startswith("cbs ") and "optimal" in ln for ln in out.splitlines())


# ---------------------------------------------------------------- bad input: exit 2, one line
BAD = [
    (["info", str(DATA / "bad_header.map"), "--scen", SCEN], "bad_header.map:4: expected"),
    (["info", str(DATA / "bad_unknown_key.yaml")], "bad_unknown_key.yaml:4: unknown key"),
    (["info", str(DATA / "bad_syntax.yaml")], "bad_syntax.yaml:3: YAML syntax error"),
    (["solve", str(DATA / "bad_start_on_obstacle.yaml")], ":9: agent 'agent1' start [3, 1]"),
    (["solve", MAP, "--scen", SCEN, "--agents", "500"], "--agents 500 but the scenario has 409"),
    (["solve", MAP], "needs a scenario (--scen"),
    (["solve", CORRIDOR, "--scen", SCEN], "--scen only applies"),
    (["solve", "nothere.yaml"], "nothere.yaml: no such file"),
    (["solve", CORRIDOR, "--solver", "nosuch"], "unknown solver 'nosuch'"),
    (["solve", CORRIDOR, "--w", "1.5"], "solver 'cbs' has no option 'w'"),
    (["solve", CORRIDOR, "--set", "colour=red"], "solver 'cbs' has no option 'colour'"),
    (["solve", CORRIDOR, "--set", "oops"], "--set expects KEY=VALUE"),
    (["solve", CORRIDOR, "--set", "seed=3"], "use --seed instead"),
    (["solve", str(DATA / "tapf_lmrp.yaml"), "--solver", "cbs"], "does not solve TAPF"),
    (["validate", CORRIDOR, str(DATA / "bad_plan_missing_agent.yaml")], "no path for agent(s)"),
    (["validate", CORRIDOR, "nothere.yaml"], "nothere.yaml: no such file"),
    (["info"], "give an INSTANCE file"),
]


@pytest.mark.parametrize(("argv", "needle"), BAD)
def test_bad_input_exit_2(capsys: pytest.CaptureFixture[str], argv: list[str], needle: str) -> None:
    code, out, err = run(capsys, *argv)
    assert code == 2, out + err
    assert_one_line_error(err)
    assert needle in err


def test_out_directory_missing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "solve", CORRIDOR, "--out", str(tmp_path / "no" / "plan.yaml"))
    assert code == 2
    assert_one_line_error(err)


@pytest.mark.parametrize(
    "argv",
    [
        ["solve", CORRIDOR, "--agents", "0"],
        ["solve", CORRIDOR, "--time-limit", "-1"],
        ["solve", CORRIDOR, "--objective", "fastest"],
        ["solve", CORRIDOR, "--cost", "fastest"],
        ["validate", CORRIDOR],
    ],
)
def test_usage_errors_exit_2(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert_one_line_error(err)
    assert err.startswith(f"hierplan {argv[0]}: error: ")


# ---------------------------------------------------------------- the installed entry point
def _hierplan() -> list[str]:
    exe = Path(sys.executable).with_name("hierplan")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "hierplan_opt"]


def test_entry_point_solve_and_validate(tmp_path: Path) -> None:
    plan = tmp_path / "plan.yaml"
    res = subprocess.run(
        [*_hierplan(), "-q", "solve", CORRIDOR, "--out", str(plan)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("OPTIMAL cost=8")
    res = subprocess.run(
        [sys.executable, "-m", "hierplan_opt", "validate", CORRIDOR, str(plan)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0 and res.stdout.startswith("valid: soc=8")


def test_entry_point_bad_input_one_line() -> None:
    res = subprocess.run(
        [*_hierplan(), "solve", MAP, "--scen", SCEN, "--agents", "500"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "Traceback" not in res.stderr
    assert "--agents 500 but the scenario has 409 agents" in res.stderr
