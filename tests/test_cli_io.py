"""The command line's own surface: --version, usage errors, help texts, output paths."""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path

import pytest
from io_helpers import DATA

from hierplan_opt import __version__
from hierplan_opt.bench import AREAS
from hierplan_opt.cli import COMMANDS, build_parser, main
from hierplan_opt.io.files import Limits, limits

CORRIDOR = str(DATA / "corridor_lmrp.yaml")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse's --version / --help / usage errors
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--version")
    assert code == 0 and out.strip() == f"hierplan {__version__}"


@pytest.mark.parametrize("argv", [[], ["-q"], ["--debug"], ["nosuch"]])
def test_missing_or_unknown_subcommand_is_one_line(
    capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("hierplan: error: ")


def test_every_command_is_registered() -> None:
    """A subcommand module that fails to import breaks the CLI instead of vanishing."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert tuple(sub.choices) == COMMANDS  # type: ignore[union-attr]


def test_help_texts_name_no_internal_issue(capsys: pytest.CaptureFixture[str]) -> None:
    texts = [run(capsys, "--help")[1]]
    texts += [run(capsys, name, "--help")[1] for name in COMMANDS]
    texts += [run(capsys, "bench", area, "--help")[1] for area in AREAS]
    for text in texts:
        assert text.strip()
        assert not re.search(r"\bissues?[ -]?#?\d", text, re.IGNORECASE), text


def test_limit_options_apply_for_one_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(capsys, "info", CORRIDOR, "--max-input-mb", "0.0001")
    assert code == 2 and "more than the input limit of 104 bytes" in err
    code, _, err = run(capsys, "info", CORRIDOR, "--max-grid-cells", "5")
    assert code == 2 and "a 5x2 grid has 10 cells" in err
    assert limits() == Limits.from_environment()  # restored after the command
    assert run(capsys, "info", CORRIDOR)[0] == 0


def test_outputs_are_checked_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = tmp_path / "plan.yaml"
    assert run(capsys, "solve", CORRIDOR, "--out", str(plan))[0] == 0
    sched = tmp_path / "s.yaml"
    for extra, match in [
        (["--gantt", str(tmp_path / "g.xyz")], "--gantt .*g.xyz: unsupported extension '.xyz'"),
        (["--gantt", "/dev/full"], "unsupported extension none"),
        (["--dot", str(tmp_path / "no" / "s.dot")], "--dot .*: the folder .* does not exist"),
        (["--dot", str(sched)], "unsupported extension '.yaml'"),
    ]:
        code, out, err = run(capsys, "post", CORRIDOR, str(plan), "--out", str(sched), *extra)
        assert code == 2 and out == "" and re.search(match, err), err
        assert not sched.exists()  # the schedule is not written first
    code, _, err = run(capsys, "solve", CORRIDOR, "--out", "")
    assert code == 2 and "--out: the file name is empty" in err
    code, _, err = run(capsys, "solve", CORRIDOR, "--out", str(tmp_path / "p.txt"))
    assert code == 2 and "unsupported extension '.txt' (use .yaml, .yml, .json)" in err


def test_full_disk_while_writing_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    out = tmp_path / "plan.yaml"
    code, stdout, err = run(capsys, "solve", CORRIDOR, "--out", str(out))
    assert code == 2 and stdout == ""
    assert err.strip() == f"hierplan solve: error: {out}: cannot write (No space left on device)"
    assert os.listdir(tmp_path) == []


def test_unexpected_os_error_is_one_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import hierplan_opt.cli.info as info

    def broken(args: object) -> int:
        raise OSError(errno.EIO, "Input/output error", "somefile")

    monkeypatch.setattr(info, "run", broken)
    code, _, err = run(capsys, "info", CORRIDOR)
    assert code == 2 and err.strip() == "hierplan info: error: somefile: Input/output error"


def test_convert_instance_formats(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from io_helpers import same_instance

    from hierplan_opt.io import load_instance

    inst = load_instance(CORRIDOR)
    for to, name in (("hierplan", "a.yaml"), ("lmrp", "b.yaml"), ("movingai", "c.map")):
        code, out, _ = run(capsys, "convert", CORRIDOR, "--to", to, "--out", str(tmp_path / name))
        assert code == 0 and f"as {to} ->" in out
    back = load_instance(tmp_path / "c.map", scen=tmp_path / "c.scen")
    assert same_instance(back, inst, names=False)
    assert same_instance(load_instance(tmp_path / "b.yaml"), inst)
    code, _, err = run(capsys, "convert", CORRIDOR, "--out", str(tmp_path / "x.txt"))
    assert code == 2 and "give --to (hierplan, lmrp, movingai) for an instance" in err
    code, _, err = run(capsys, "convert", CORRIDOR, "--to", "eecbs", "--out", str(tmp_path / "x"))
    assert code == 2 and "--to eecbs does not apply to an instance" in err


@pytest.mark.parametrize("area", sorted(AREAS))
def test_bench_usage_errors_are_one_line(capsys: pytest.CaptureFixture[str], area: str) -> None:
    import argparse

    before = argparse.ArgumentParser.error
    code, out, err = run(capsys, "bench", area, "--bogus")
    assert code == 2 and out == ""
    assert err.strip() == (
        "hierplan bench: error: unrecognized arguments: --bogus "
        f"(see 'hierplan bench {area} --help')"
    )
    assert argparse.ArgumentParser.error is before  # argparse is left as it was


def test_wrong_solver_for_teams_names_the_ones_that_fit(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, _, err = run(capsys, "solve", str(DATA / "tapf_lmrp.yaml"), "--solver", "cbs")
    assert code == 2 and "does not solve TAPF instances" in err and "use 'cbm'" in err


def test_roadmap_too_long_for_floats_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "far.yaml"
    f.write_text(
        "graph:\n  type: roadmap\n"
        "  vertices: {A: [0.0, 0.0], B: [1.0e+308, 0.0], C: [-1.0e+308, 0.0]}\n"
        "  edges: [[A, B], [A, C], [B, C]]\n"
        "agents:\n  - {start: B, goal: C}\n"
    )
    code, _, err = run(capsys, "info", str(f))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "edge ['B', 'C'] is longer than the largest float" in err
    f.write_text(f.read_text().replace(", [B, C]", ""))  # 1e308 each: representable
    code, out, err = run(capsys, "info", str(f))
    assert code == 0 and err == "" and "3 vertices, 2 edges" in out


@pytest.mark.parametrize("area", sorted(AREAS))
def test_every_bench_area_has_the_readme_quick_preset(
    capsys: pytest.CaptureFixture[str], area: str
) -> None:
    """The README's synopsis ``hierplan bench AREA [--quick]`` holds for every area."""
    readme = (Path(__file__).parents[1] / "README.md").read_text()
    synopsis = re.search(r"hierplan bench +(\S+) \[--quick\]", readme)
    assert synopsis and set(synopsis.group(1).split("|")) == set(AREAS)
    code, out, _ = run(capsys, "bench", area, "--help")
    assert code == 0 and re.search(r"--quick\s+\S", out), out


@pytest.mark.parametrize("command", ["simulate", "run"])
@pytest.mark.parametrize(
    ("option", "name", "message"),
    [
        ("--out", "missing/r.yaml", "does not exist"),
        ("--plot", "d.xyz", "unsupported extension '.xyz'"),
        ("--animate", "a.png", "unsupported extension '.png'"),
    ],
)
def test_execution_outputs_checked_before_work(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    command: str,
    option: str,
    name: str,
    message: str,
) -> None:
    args = [command, CORRIDOR] + ([str(tmp_path / "no-plan.yaml")] if command == "simulate" else [])
    outs = {"--out": str(tmp_path / "r.yaml"), option: str(tmp_path / name)}
    code, out, err = run(capsys, *args, *[x for kv in outs.items() for x in kv])
    assert code == 2 and out == "" and message in err  # before the plan is read or made
    assert len(err.strip().splitlines()) == 1 and os.listdir(tmp_path) == []
