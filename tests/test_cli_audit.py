"""Defects of a user audit of the command line, each with its reproducer.

A. special files (a FIFO) are refused at once by every command that reads them;
B. any ``--seed`` works with every solver (CP-SAT and HiGHS take 32-bit seeds);
C. ``view`` refuses a schedule or execution report of another instance;
D. ``validate`` says a schedule whose times break its STN is invalid (exit 1);
E. ``run``: MAPF-POST's refusal of a rotation is not "proven infeasible"; ``--a-max``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hierplan_opt.cli import main

ROOT = Path(__file__).parent.parent
#: Two robots in a row (the audit's instance).
TRAIN = """\
map: {dimensions: [5, 1], obstacles: []}
agents:
  - {name: agent0, start: [0, 0], goal: [3, 0]}
  - {name: agent1, start: [1, 0], goal: [4, 0]}
"""
TIMEOUT = 60


def hierplan(cwd: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    """``hierplan ARGV`` as its own process (a hang ends in ``TimeoutExpired``)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "hierplan_opt", *argv],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        cwd=cwd,
        env=env,
        check=False,
    )


def one_line_error(err: str, command: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(("INFO", "DEBUG"))]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"hierplan {command}: error: "), lines[0]
    return lines[0]


@pytest.fixture
def train(tmp_path: Path) -> Path:
    p = tmp_path / "train.yaml"
    p.write_text(TRAIN)
    return p


# ---------------------------------------------------------------- A: FIFOs
@pytest.mark.parametrize(
    "argv",
    [
        ["validate", "train.yaml", "fifo.yaml"],
        ["simulate", "train.yaml", "fifo.yaml", "--out", "x.yaml"],
        ["sweep", "fifo.yaml", "--dry-run"],
        ["sweep", "report", "fifo.yaml"],
        ["sweep", "export", "fifo.yaml", "o.csv"],
        ["sweep", "--resume", "--db", "fifo.yaml"],
    ],
    ids=lambda a: " ".join(a[:2]),
)
def test_fifo_refused_at_once(train: Path, argv: list[str]) -> None:
    d = train.parent
    os.mkfifo(d / "fifo.yaml")
    res = hierplan(d, *argv)
    assert res.returncode == 2, res.stderr
    line = one_line_error(res.stderr, argv[0])
    assert "fifo.yaml: is a FIFO (named pipe), not a regular file" in line
    assert not (d / "x.yaml").exists() and not (d / "o.csv").exists()


def test_sweep_db_fifo_refused(tmp_path: Path) -> None:
    """A FIFO given as the sweep's database is refused, not opened by SQLite."""
    spec = tmp_path / "s.yaml"
    spec.write_text(
        "solvers: [{name: cbs}]\n"
        "instances: [{generator: random_grid, params: {width: 8, height: 8}}]\n"
        "agents: [2]\n"
    )
    os.mkfifo(tmp_path / "db.sqlite")
    res = hierplan(tmp_path, "sweep", "s.yaml", "--db", "db.sqlite", "--no-progress")
    assert res.returncode == 2, res.stderr
    assert "db.sqlite: is a FIFO (named pipe), not a regular file" in one_line_error(
        res.stderr, "sweep"
    )


def test_sniffers_refuse_a_fifo(tmp_path: Path) -> None:
    """The format sniffers refuse a FIFO without opening it for a blocking read (a
    watchdog turns a hang into a failure)."""
    import signal

    from hierplan_opt.core.errors import InputError
    from hierplan_opt.experiments import store
    from hierplan_opt.schedule.files import is_schedule_file

    fifo = tmp_path / "f.yaml"
    os.mkfifo(fifo)

    def hang(signum: int, frame: object) -> None:
        raise TimeoutError("blocked on a FIFO")

    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(20)
    try:
        with pytest.raises(InputError, match="is a FIFO"):
            is_schedule_file(fifo)
        assert store.is_database(fifo) is False
        with pytest.raises(InputError, match="is a FIFO"):
            store.open_existing(fifo)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


# ---------------------------------------------------------------- B: seeds
@pytest.mark.parametrize("seed", [2**31, 2**63 + 5, -(2**31) - 1])
@pytest.mark.parametrize("solver", ["cpsat", "mip"])
def test_any_seed_with_the_formulations(
    train: Path, capsys: pytest.CaptureFixture[str], solver: str, seed: int
) -> None:
    """A seed outside the C library's 32-bit range solves (it was an internal error
    with cpsat, and silently ignored by HiGHS)."""
    out = train.parent / "p.yaml"
    code = main(["solve", str(train), "--solver", solver, "--seed", str(seed), "--out", str(out)])
    got, err = capsys.readouterr()
    assert code == 0, err
    assert got.startswith("OPTIMAL cost=6 ") and out.exists()
    assert main(["validate", str(train), str(out)]) == 0


def test_seeds_reach_the_c_libraries_in_range() -> None:
    """What CP-SAT and HiGHS are given: the seed itself when it fits, else a value in
    their range that differs between neighbouring seeds (a batch S, S+1, ... stays
    distinct)."""
    import highspy

    from hierplan_opt.formulations.horizon import fold_seed
    from hierplan_opt.formulations.mip import _highs

    for seed in (0, 12345, 2**31 - 1):
        assert _highs(seed).highs_options["random_seed"] == seed
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    folded = [_highs(s).highs_options["random_seed"] for s in (2**31, 2**31 + 1, -1, 2**70 + 7)]
    assert len(set(folded)) == 4
    for v in folded:
        assert h.setOptionValue("random_seed", v) == highspy.HighsStatus.kOk
        assert h.getOptionValue("random_seed")[1] == v
    for seed in (-5, 2**31 - 1, -(2**31)):
        assert fold_seed(seed, -(2**31), 2**31 - 1) == seed
    assert fold_seed(2**31, -(2**31), 2**31 - 1) != fold_seed(2**31 + 1, -(2**31), 2**31 - 1)


@pytest.mark.parametrize("command", ["simulate", "run"])
def test_negative_execution_seed_refused(
    train: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """NumPy takes no negative seed: one line and exit 2, not an internal error."""
    d = train.parent
    dist = d / "d.yaml"
    dist.write_text(
        "disturbances:\n  - {kind: random, probability: 0.5, duration: {exponential: 2.0}}\n"
    )
    argv = [command, str(train)]
    if command == "simulate":
        argv += [str(train), "--out", str(d / "r.yaml")]  # refused before the plan is read
    with pytest.raises(SystemExit) as info:  # a usage error: argparse exits
        main([*argv, "--disturbances", str(dist), "--seed", "-1"])
    _, err = capsys.readouterr()
    assert info.value.code == 2, err
    assert "--seed: expected an integer >= 0, got '-1'" in one_line_error(err, command)
    assert not (d / "r.yaml").exists()


# ---------------------------------------------------------------- C: view of a foreign file
MOVINGAI = ROOT / "instances" / "movingai"
EIGHT = [str(MOVINGAI / "empty-8-8.map"), "--scen", str(MOVINGAI / "empty-8-8-even-1.scen")]


def _schedule_and_report(d: Path, instance: list[str], tag: str) -> tuple[Path, Path]:
    plan, sched, report = d / f"p{tag}.yaml", d / f"s{tag}.yaml", d / f"r{tag}.yaml"
    assert main(["-q", "solve", *instance, "--out", str(plan)]) == 0
    assert main(["-q", "post", *instance, str(plan), "--out", str(sched)]) == 0
    assert main(["-q", "simulate", *instance, str(sched), "--out", str(report)]) == 0
    return sched, report


@pytest.mark.parametrize("which", ["schedule", "report"])
def test_view_refuses_a_file_of_another_instance(
    train: Path, capsys: pytest.CaptureFixture[str], which: str
) -> None:
    d = train.parent
    sched, report = _schedule_and_report(d, [*EIGHT, "--agents", "8"], "8")
    foreign = sched if which == "schedule" else report
    capsys.readouterr()
    # simulate refuses it ...
    assert main(["simulate", str(train), str(foreign), "--out", str(d / "x.yaml")]) == 2
    _, err = capsys.readouterr()
    expected = one_line_error(err, "simulate").split("error: ", 1)[1]
    assert "does not belong to this instance" in expected
    # ... and view the same way, writing nothing
    page = d / "y.html"
    assert main(["view", str(train), str(foreign), "--out", str(page)]) == 2
    out, err = capsys.readouterr()
    line = one_line_error(err, "view")
    assert f"{foreign}: schedule: unknown agent 'agent2'" in line
    assert f"(the {which} does not belong to this instance)" in line
    assert out == "" and not page.exists()


def test_view_refuses_same_names_other_starts(
    train: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Robots of the same names that start elsewhere: another instance too."""
    d = train.parent
    sched, report = _schedule_and_report(d, [str(train)], "t")
    page = d / "ok.html"
    assert main(["-q", "view", str(train), str(report), "--out", str(page)]) == 0
    assert page.exists()
    other = d / "other.yaml"
    other.write_text(TRAIN.replace("start: [0, 0], goal: [3, 0]", "start: [2, 0], goal: [0, 0]"))
    for f in (sched, report):
        capsys.readouterr()
        assert main(["view", str(other), str(f), "--out", str(d / "y.html")]) == 2
        line = one_line_error(capsys.readouterr().err, "view")
        assert f"{f}: the first way-point of 'agent0' is not its start" in line
        assert not (d / "y.html").exists()


# ---------------------------------------------------------------- D: validate's exit code
def test_validate_schedule_breaking_its_stn_is_invalid(
    train: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """agent0 reaches (2, 0) while agent1 is still there: the schedule is invalid (exit
    1, the broken bound on one line), not bad input (exit 2)."""
    import yaml

    d = train.parent
    plan, sched = d / "p.yaml", d / "s.yaml"
    assert main(["-q", "solve", str(train), "--out", str(plan)]) == 0
    assert main(["-q", "post", str(train), str(plan), "--margin", "0", "--out", str(sched)]) == 0
    assert main(["validate", str(train), str(sched)]) == 0
    data = yaml.safe_load(sched.read_text())
    rows = data["schedule"]["agent0"]
    k = next(i for i, w in enumerate(rows) if (w["x"], w["y"]) == (2, 0))
    leave = next(w["arrival"] for w in data["schedule"]["agent1"] if (w["x"], w["y"]) == (3, 0))
    rows[k]["arrival"] = leave - 0.5  # agent1 still stands on (2, 0)
    sched.write_text(yaml.safe_dump(data))
    capsys.readouterr()
    assert main(["validate", str(train), str(sched)]) == 1
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert len(lines) == 1 and err.strip() == "", (out, err)
    assert lines[0].startswith(f"{sched}: the times break a bound of the plan's STN: ")
    assert "-> agent0 at (2, 0): " in lines[0] and "< lower bound" in lines[0]
    # a file of another instance stays bad input
    other = d / "other.yaml"
    other.write_text(TRAIN.replace("agent1", "agent9"))
    assert main(["validate", str(other), str(sched)]) == 2
    assert "does not belong to this instance" in one_line_error(capsys.readouterr().err, "validate")


# ---------------------------------------------------------------- E: run's two messages
#: Four robots on a 2x2 map, each to the next corner clockwise: the optimal plan rotates
#: them all at once, which MAPF-POST refuses under a margin > 0.
ROTATION = """\
map: {dimensions: [2, 2], obstacles: []}
agents:
  - {name: agent0, start: [0, 0], goal: [0, 1]}
  - {name: agent1, start: [0, 1], goal: [1, 1]}
  - {name: agent2, start: [1, 1], goal: [1, 0]}
  - {name: agent3, start: [1, 0], goal: [0, 0]}
"""


def test_run_rotation_is_not_proven_infeasible(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`run` refuses the rotation as `post` does (one line with post's advice, exit 2),
    not as a proven infeasible instance (exit 3); with `--margin 0` it runs."""
    rot = tmp_path / "rot.yaml"
    rot.write_text(ROTATION)
    plan = tmp_path / "p.yaml"
    assert main(["-q", "solve", str(rot), "--out", str(plan)]) == 0
    capsys.readouterr()
    assert main(["post", str(rot), str(plan), "--out", str(tmp_path / "s.yaml")]) == 2
    post_line = one_line_error(capsys.readouterr().err, "post")
    reason = post_line.split("error: ", 1)[1]
    assert "rotate" in reason and "use margin 0" in reason
    report = tmp_path / "r.yaml"
    code = main(["run", str(rot), "--out", str(report)])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert reason in one_line_error(err, "run") and out == ""
    assert not report.exists()
    assert main(["-q", "run", str(rot), "--margin", "0", "--out", str(report)]) == 0
    assert report.exists()


def test_run_refine_takes_a_max(capsys: pytest.CaptureFixture[str]) -> None:
    """The refinement asks for an acceleration limit: `run` takes `--a-max` as `refine`
    does, and the message names that option."""
    fig3 = str(ROOT / "instances" / "paper" / "figure3.yaml")
    code = main(["run", fig3, "--solver", "cbm", "--refine"])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert "--a-max" in one_line_error(err, "run")
    assert main(["run", fig3, "--solver", "cbm", "--refine", "--a-max", "1.5"]) == 0
    out, _ = capsys.readouterr()
    assert "refined (path mode)" in out and "3/3 robots at their own goals" in out
    assert main(["run", fig3, "--solver", "cbm", "--a-max", "1.5"]) == 2
    assert "--a-max" in one_line_error(capsys.readouterr().err, "run")
