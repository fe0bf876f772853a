"""Hostile and malformed files for every command that reads or writes them.

The corpus (``bad_inputs.py``) crosses every reader slot (instance, map, scenario, plan,
schedule) with generic hazards (FIFOs, devices, empty, binary, oversize, deep nesting,
alias bombs, ...) and slot-specific ones (terabyte grids, 10^30 coordinates, run-length
bombs, ...), and every writing option with bad output paths. Every case must end with
exit code 2 and one line on stderr naming the problem: no traceback, no output file, no
hang and no signal.

Most cases run in this process (fast; a watchdog alarm interrupts a hang, e.g. a
blocking read of a FIFO). Those that could kill the process with a signal if a guard
broke (100000-deep nesting, which the C YAML composer would recurse on) run in a
subprocess with a timeout. By default one command per hazard runs (the fast sample);
``-m slow`` runs every command on every hazard, in process and again each in its own
``hierplan`` process, as a user's shell would.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from bad_inputs import Case, build, cases

from hierplan_opt.cli import main

ALL = cases()
TIMEOUT = 60


def _params(selected: list[Case], fast: bool) -> list[object]:
    """The fast sample runs by default; the rest of the corpus under ``-m slow``."""
    return [
        pytest.param(c, id=c.id, marks=() if (fast and c.sample) else pytest.mark.slow)
        for c in selected
    ]


IN_PROCESS = [c for c in ALL if not c.in_subprocess]
SUBPROCESS = [c for c in ALL if c.in_subprocess]


class Hang(Exception):
    pass


@contextmanager
def watchdog(seconds: int) -> Iterator[None]:
    def on_alarm(signum: int, frame: object) -> None:
        raise Hang(f"no answer within {seconds} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def check(case: Case, code: int, out: str, err: str, watch: list[Path], d: Path) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(("INFO", "DEBUG"))]
    assert code == 2, f"{case.id}: exit {code}\nstdout: {out}\nstderr: {err}"
    assert len(lines) == 1, f"{case.id}: stderr is not one line:\n{err}"
    assert lines[0].startswith(f"hierplan {case.command}: error: "), lines[0]
    assert "Traceback" not in err and "internal error" not in err, err
    assert out.strip() == "", f"{case.id}: stdout: {out}"
    for p in watch:
        assert not p.exists() or p.is_dir(), f"{case.id}: {p} was written"
    leftovers = [p.name for p in d.iterdir() if p.name.startswith(".")]
    assert not leftovers, f"{case.id}: temporary files left: {leftovers}"


def test_corpus_size() -> None:
    """The corpus covers every slot and command (the issue's run had 435 cases)."""
    slots = {c.slot for c in ALL}
    assert slots == {"instance", "map", "scen", "plan", "schedule", "output"}
    assert {c.command for c in ALL} == {"info", "solve", "validate", "verify", "post", "convert"}
    assert len(ALL) >= 435


@pytest.mark.parametrize("case", _params(IN_PROCESS, fast=True))
def test_bad_input_in_process(
    case: Case, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv, watch = build(case, tmp_path)
    with watchdog(TIMEOUT):
        code = main(argv)
    out, err = capsys.readouterr()
    check(case, code, out, err, watch, tmp_path)


def run_process(case: Case, d: Path) -> None:
    """Run ``case`` as its own ``hierplan`` process and check it (never a signal)."""
    argv, watch = build(case, d)
    proc = subprocess.run(
        [sys.executable, "-m", "hierplan_opt", *argv],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        cwd=d,
        env={**os.environ, "PYTHONFAULTHANDLER": "1"},
        check=False,
    )
    assert proc.returncode >= 0, f"{case.id}: killed by signal {-proc.returncode}"
    check(case, proc.returncode, proc.stdout, proc.stderr, watch, d)


@pytest.mark.parametrize("case", _params(SUBPROCESS, fast=True))
def test_bad_input_subprocess(case: Case, tmp_path: Path) -> None:
    run_process(case, tmp_path)


@pytest.mark.parametrize("case", _params(IN_PROCESS, fast=False))
def test_bad_input_whole_process(case: Case, tmp_path: Path) -> None:
    """The in-process cases again, each as its own ``hierplan`` process."""
    run_process(case, tmp_path)
