"""``hierplan refine``: files, exit codes and one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hierplan_opt.cli import main

ROOT = Path(__file__).resolve().parents[1]
PART1 = str(ROOT / "instances" / "paper" / "warehouse-part1.yaml")
FIG3 = str(ROOT / "instances" / "paper" / "figure3.yaml")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    try:
        code = main(list(argv))
    except SystemExit as exc:  # usage errors from argparse
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if not ln.startswith(("INFO", "DEBUG"))]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture(scope="module")
def schedule(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("refine")
    plan, sched = d / "plan.yaml", d / "schedule.yaml"
    assert main(["-q", "solve", PART1, "--solver", "cbm", "--out", str(plan)]) == 0
    assert main(["-q", "post", PART1, str(plan), "--out", str(sched)]) == 0
    return sched


def test_refine_writes_verified_csv_npz_and_plot(
    schedule: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, png = tmp_path / "t.csv", tmp_path / "t.png"
    code, text, _ = run(
        capsys,
        "refine",
        PART1,
        str(schedule),
        "--out",
        str(out),
        "--plot",
        str(png),
        "--stretch",
        "auto",
    )
    assert code == 0, text
    assert text.startswith("refined 12 robots (path mode") and "; verified:" in text
    rows = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    assert rows[0] == "agent,t,x,y,vx,vy,theta"  # the Pioneers drive differentially
    assert png.stat().st_size > 0
    npz = tmp_path / "t.npz"
    code, _, _ = run(capsys, "refine", PART1, str(schedule), "--out", str(npz), "--stretch", "auto")
    assert code == 0
    data = np.load(npz)
    assert data["pos"].shape[0] == 12 and data["pos"].shape[2] == 2


def test_infeasible_windows_exit_3_with_the_factor(
    schedule: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "t.csv"
    code, _, err = run(
        capsys, "refine", PART1, str(schedule), "--out", str(out), "--stretch", "none"
    )
    assert code == 3
    line = one_line(err)
    assert "cannot be passed inside its window" in line and "stretching the schedule by" in line
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--out", "t.txt"], "must end in .csv or .npz"),
        (["--out", "no/such/dir/t.csv"], "does not exist"),
        (["--out", "t.csv", "--plot", "t.gif"], "the plot must end in"),
        (["--out", "t.csv", "--stretch", "0.5"], "expected 'auto', 'none' or a number >= 1"),
        (["--out", "t.csv", "--mode", "tube"], "invalid choice"),
    ],
)
def test_bad_arguments_one_line_exit_2(
    schedule: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    extra: list[str],
    match: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "refine", PART1, str(schedule), *extra)
    assert code == 2
    assert match in one_line(err)


def test_schedule_of_another_instance_is_refused(
    schedule: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(capsys, "refine", FIG3, str(schedule), "--out", str(tmp_path / "t.csv"))
    assert code == 2
    assert "does not belong to this instance" in one_line(err)


def test_edited_schedule_times_are_refused(
    schedule: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import yaml

    data = yaml.safe_load(schedule.read_text())
    name = next(iter(data["schedule"]))
    for wp in data["schedule"][name]:
        wp["x"] = wp["x"] + 0.5  # moved off the map's vertices
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    code, _, err = run(capsys, "refine", PART1, str(bad), "--out", str(tmp_path / "t.csv"))
    assert code == 2
    assert str(bad) in one_line(err)


def test_refine_with_the_profile_solver_turns_unicycles_and_verifies(
    schedule: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "p.csv"
    code, text, _ = run(
        capsys, "refine", PART1, str(schedule), "--out", str(out), "--stretch", "auto",
        "--solver", "profile",
    )  # fmt: skip
    assert code == 0, text
    assert "(path mode, profile)" in text and "; verified:" in text
    rows = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    assert rows[0] == "agent,t,x,y,vx,vy,theta"


# ---------------------------------------------------------------- issue 34
def test_documented_post_refine_chain_works_by_default(
    schedule: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # README: `hierplan refine INSTANCE SCHEDULE --out TRAJ.csv` (no --stretch); it
    # exited 3 asking for --stretch auto
    out = tmp_path / "t.csv"
    code, text, _ = run(capsys, "refine", PART1, str(schedule), "--out", str(out))
    assert code == 0, text
    assert "(path mode, solver auto: ipopt for 12 robots)" in text
    assert "stretch 1.196" in text and "; verified:" in text and out.exists()


def test_auto_solver_picks_profile_qp_for_a_fleet_and_says_so(
    schedule: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    import importlib

    refine_module = importlib.import_module("hierplan_opt.trajectory.refine")

    assert refine_module.auto_solver("path", 200) == "profile+qp"
    monkeypatch.setattr(refine_module, "AUTO_NLP_ROBOTS", 4)  # 12 robots: a "fleet"
    out = tmp_path / "t.csv"
    code, text, _ = run(capsys, "refine", PART1, str(schedule), "--out", str(out))
    assert code == 0, text
    assert "(path mode, solver auto: profile+qp for 12 robots)" in text


def test_accel_ratio_counts_the_a_max_given_on_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan, sched = tmp_path / "plan.yaml", tmp_path / "s.yaml"
    assert main(["-q", "solve", FIG3, "--solver", "cbm", "--out", str(plan)]) == 0
    assert main(["-q", "post", FIG3, str(plan), "--out", str(sched)]) == 0
    capsys.readouterr()
    code, text, _ = run(
        capsys, "refine", FIG3, str(sched), "--out", str(tmp_path / "t.csv"), "--a-max", "1"
    )
    assert code == 0, text
    assert "accel 1.000 of the limits" in text  # was "accel 0.000": a_max not checked


def test_a_result_failing_verification_is_not_written(
    schedule: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    import dataclasses

    from hierplan_opt.trajectory import verify as verify_module

    real = verify_module.verify

    def failing(*args: object, **kwargs: object) -> verify_module.VerifyReport:
        rep = real(*args, **kwargs)  # type: ignore[arg-type]
        return dataclasses.replace(rep, ok=False, problems=("made up",), num_problems=1)

    monkeypatch.setattr(verify_module, "verify", failing)
    out = tmp_path / "t.csv"
    code, text, _ = run(capsys, "refine", PART1, str(schedule), "--out", str(out))
    assert code == 1 and not out.exists()
    assert ", not written; NOT verified" in text
