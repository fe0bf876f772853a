"""Run one task in a fresh process with a time and a memory limit; classify the outcome.

:func:`run_task` is what a local thread or a Dask worker executes: it starts
``python -m hierplan_opt.experiments.worker``, hands it the task on stdin, waits with
``os.wait4`` (which also gives the child's peak resident memory), kills it at the hard
wall-clock limit, and turns whatever happened into the outcome fields of a ``runs`` row:

* the worker's own report (OPTIMAL, FEASIBLE, INFEASIBLE, TIME_LIMIT, ERROR, MEMOUT);
* killed at the hard limit: TIME_LIMIT;
* died with a memory error (``MemoryError``, ``std::bad_alloc``, ``Cannot allocate
  memory``), or killed by a signal it was not sent (the kernel's OOM killer): MEMOUT;
* any other crash: ERROR with the signal or exit code and the last line of stderr.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

MEMOUT = "MEMOUT"
#: Seconds a run may overrun its time limit before it is killed (solvers stop on their
#: own at the limit; this catches the ones that do not).
GRACE = 10.0
_MEMORY_SIGNS = ("MemoryError", "bad_alloc", "Cannot allocate memory", "out of memory")


def hard_limit(time_limit: float) -> float:
    """The wall-clock kill limit of a run with solver limit ``time_limit``.

    Example
    -------
    >>> hard_limit(30.0), hard_limit(600.0)
    (40.0, 720.0)
    """
    return time_limit + max(GRACE, 0.2 * time_limit)


def run_task(task: dict[str, Any], python: str | None = None) -> dict[str, Any]:
    """Run ``task`` (see :mod:`hierplan_opt.experiments.worker`) in a new process.

    Returns the outcome fields: status, cost, lower_bound, runtime, wall, peak_mb,
    stats, error, versions, host, agents.
    """
    limit = hard_limit(float(task["time_limit"]))
    with tempfile.TemporaryDirectory(prefix="hierplan-run-") as tmp:
        result_path = Path(tmp) / "result.json"
        payload = json.dumps({**task, "result_path": str(result_path), "hard_limit": limit + 5.0})
        with open(Path(tmp) / "stderr", "w+b") as err:
            t0 = time.perf_counter()
            proc = subprocess.Popen(
                [python or sys.executable, "-m", "hierplan_opt.experiments.worker"],
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=err,
                env={**os.environ, "PYTHONUNBUFFERED": "1"},
            )
            killed = threading.Event()

            def kill() -> None:
                killed.set()
                proc.kill()

            timer = threading.Timer(limit, kill)
            timer.daemon = True
            timer.start()
            try:
                assert proc.stdin is not None
                try:
                    proc.stdin.write(payload.encode())
                    proc.stdin.close()
                except BrokenPipeError:
                    pass  # the child died at start; its status tells why
                _, status, usage = os.wait4(proc.pid, 0)
            except BaseException:
                proc.kill()
                proc.wait()
                raise
            finally:
                timer.cancel()
            proc.returncode = os.waitstatus_to_exitcode(status)
            wall = time.perf_counter() - t0
            err.seek(0)
            stderr = err.read()[-4000:].decode("utf-8", "replace")
        peak_mb = usage.ru_maxrss / 1024.0
        if result_path.exists():
            out = json.loads(result_path.read_text(encoding="utf-8"))
            out["wall"] = wall
            out["peak_mb"] = max(peak_mb, float(out.get("peak_mb") or 0.0))
            return out
    return _crashed(proc.returncode, killed.is_set(), stderr, wall, peak_mb, limit)


def _crashed(
    code: int, killed: bool, stderr: str, wall: float, peak_mb: float, limit: float
) -> dict[str, Any]:
    """The outcome of a run that left no report."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    last = lines[-1][:300] if lines else ""
    if killed or (code == 137 and wall >= limit):  # 137: the worker's own watchdog
        status, error = "TIME_LIMIT", f"killed at the hard limit of {limit:g} s"
    elif any(s in stderr for s in _MEMORY_SIGNS) or code == -signal.SIGKILL:
        status = MEMOUT
        error = f"out of memory ({_how(code)}{': ' + last if last else ''})"
    else:
        status, error = "ERROR", f"the run crashed ({_how(code)}{': ' + last if last else ''})"
    return {"status": status, "error": error, "runtime": wall, "wall": wall,
            "peak_mb": peak_mb}  # fmt: skip


def _how(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"
