"""Run one task in its own process with a time and a memory limit; classify the outcome.

:func:`run_task` is what a local thread or a Dask worker executes. By default the run's
process is forked from a warm worker (``python -m hierplan_opt.experiments.worker
--serve``, one per thread that runs tasks, started on its first task and kept until
:func:`close_servers`): the interpreter, the solvers and the compiled kernels are loaded
once, not once per run. ``HIERPLAN_SWEEP_WORKER=fresh`` (or a task the warm worker
cannot take: an address space over its memory limit, another interpreter) starts
``python -m hierplan_opt.experiments.worker`` per run instead and hands it the task on
stdin. Either way the run's process has the task's memory limit and watchdog, is killed
at the hard wall-clock limit, its wait status and peak resident memory come from
``os.wait4``, and whatever happened becomes the outcome fields of a ``runs`` row:

* the worker's own report (OPTIMAL, FEASIBLE, INFEASIBLE, TIME_LIMIT, ERROR, MEMOUT);
* killed at the hard limit: TIME_LIMIT; MEMOUT if its address space was then at its
  memory limit (:func:`~hierplan_opt.experiments.worker.memory_full`; a run that hangs
  after a failed allocation ran out of memory, not time; the worker's watchdog ends
  such a run itself one second past its time limit, see its module doc);
* died with a memory error (``MemoryError``, ``std::bad_alloc``, ``Cannot allocate
  memory``, LLVM's ``Unable to allocate`` / ``allocation failed``), or killed by a
  signal it was not sent (the kernel's OOM killer): MEMOUT;
* any other crash: ERROR with the signal or exit code and the last line of stderr.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import IO, Any

from hierplan_opt.experiments.worker import TOO_BIG, address_space_mb, memory_full

MEMOUT = "MEMOUT"
#: Seconds a run may overrun its time limit before it is killed (solvers stop on their
#: own at the limit; this catches the ones that do not).
GRACE = 10.0
_MEMORY_SIGNS = (
    "MemoryError",
    "bad_alloc",
    "Cannot allocate memory",
    "out of memory",
    "Unable to allocate",  # LLVM (numba's kernels): "Unable to allocate section memory!"
    "allocation failed",  # LLVM: "Buffer allocation failed"
)


#: Processes of the runs in flight (pid), for :func:`kill_running` on an interrupt.
_RUNNING: set[int] = set()


def kill_running() -> int:
    """Kill the processes of every run in flight (a sweep interrupted by Ctrl-C does
    not wait for them to reach their limits); the number killed."""
    killed = 0
    for pid in list(_RUNNING):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
            killed += 1
    return killed


def hard_limit(time_limit: float) -> float:
    """The wall-clock kill limit of a run with solver limit ``time_limit``.

    Example
    -------
    >>> hard_limit(30.0), hard_limit(600.0)
    (40.0, 720.0)
    """
    return time_limit + max(GRACE, 0.2 * time_limit)


def run_task(task: dict[str, Any], python: str | None = None) -> dict[str, Any]:
    """Run ``task`` (see :mod:`hierplan_opt.experiments.worker`) in a process of its own:
    forked from this thread's warm worker, or a fresh one (see the module doc).

    Returns the outcome fields: status, cost, lower_bound, runtime, wall, peak_mb,
    stats, error, versions, host, agents.
    """
    fresh = os.environ.get("HIERPLAN_SWEEP_WORKER", "fork").strip().lower() == "fresh"
    if not fresh and (python is None or python == sys.executable):
        srv = _server()
        out = None if srv is None else srv.run(task)
        if out is not None:
            return out
    return run_fresh(task, python)


def run_fresh(task: dict[str, Any], python: str | None = None) -> dict[str, Any]:
    """:func:`run_task` in a new interpreter (``python``, default this one)."""
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
            space = [0.0]  # its address space when killed (MB)

            def kill() -> None:
                space[0] = address_space_mb(proc.pid)
                killed.set()
                proc.kill()

            timer = threading.Timer(limit, kill)
            timer.daemon = True
            timer.start()
            _RUNNING.add(proc.pid)
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
                _RUNNING.discard(proc.pid)
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
    full = _full(space[0], task)
    return _crashed(proc.returncode, killed.is_set(), stderr, wall, peak_mb, limit, full)


def _full(space_mb: float, task: dict[str, Any]) -> str:
    """How full the address space of a run killed at the hard limit was, if it was at
    its memory limit (see :func:`memory_full`), else ""."""
    cap = task.get("memory_limit_mb")
    if not memory_full(space_mb, cap):
        return ""
    return f"its address space at {space_mb:.0f} MB of its memory limit of {cap:g} MB"


def _outcome(
    result_path: Path, err: IO[bytes], code: int, killed: bool, wall: float, peak_mb: float,
    limit: float, full: str = "",
) -> dict[str, Any]:  # fmt: skip
    """The row fields of a finished run: its report, or how it crashed."""
    if result_path.exists():
        out = json.loads(result_path.read_text(encoding="utf-8"))
        out["wall"] = wall
        out["peak_mb"] = max(peak_mb, float(out.get("peak_mb") or 0.0))
        return out
    err.seek(0)
    stderr = err.read()[-4000:].decode("utf-8", "replace")
    return _crashed(code, killed, stderr, wall, peak_mb, limit, full)


#: Arguments of the interpreter that runs a warm worker.
SERVE = ("-m", "hierplan_opt.experiments.worker", "--serve")


class _Server:
    """A warm worker (``worker --serve``) and the pipe to it; one task at a time."""

    def __init__(self, key: tuple[int, int]) -> None:
        self.key = key
        self.proc = subprocess.Popen(
            [sys.executable, *SERVE],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.ready = False

    def alive(self) -> bool:
        return self.proc.poll() is None

    def _answer(self) -> dict[str, Any] | None:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        return json.loads(line) if line else None

    def run(self, task: dict[str, Any]) -> dict[str, Any] | None:
        """The outcome of ``task`` run in a forked child; None when the child could not
        take it (the caller runs it in a fresh process)."""
        limit = hard_limit(float(task["time_limit"]))
        if not self.ready:
            if self._answer() is None:  # the server died while loading: not again
                _failed.add(self.key)
                return None
            self.ready = True
        with tempfile.TemporaryDirectory(prefix="hierplan-run-") as tmp:
            result_path = Path(tmp) / "result.json"
            err_path = Path(tmp) / "stderr"
            err_path.touch()
            full = {**task, "result_path": str(result_path), "hard_limit": limit + 5.0}
            req = {"task": full, "stderr_path": str(err_path)}
            assert self.proc.stdin is not None
            t0 = time.perf_counter()
            try:
                self.proc.stdin.write(json.dumps(req).encode() + b"\n")
                self.proc.stdin.flush()
                started = self._answer()
            except (BrokenPipeError, ValueError):
                started = None
            if started is None:
                return None
            pid = int(started["pid"])
            killed = threading.Event()
            space = [0.0]  # its address space when killed (MB)

            def kill() -> None:
                space[0] = address_space_mb(pid)
                killed.set()
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)

            timer = threading.Timer(limit, kill)
            timer.daemon = True
            timer.start()
            _RUNNING.add(pid)
            try:
                done = self._answer()
            finally:
                timer.cancel()
                _RUNNING.discard(pid)
            wall = time.perf_counter() - t0
            full = _full(space[0], task)
            if done is None:  # the server itself died: its child stopped with it
                with open(err_path, "rb") as err:
                    out = _outcome(result_path, err, -signal.SIGKILL, killed.is_set(), wall,
                                   0.0, limit, full)  # fmt: skip
                if out.get("status") == MEMOUT:
                    out["error"] = f"{out['error']} (the warm worker died)"
                return out
            code = os.waitstatus_to_exitcode(int(done["status"]))
            if code == TOO_BIG:
                return None
            peak_mb = float(done["maxrss_kb"]) / 1024.0
            with open(err_path, "rb") as err:
                return _outcome(result_path, err, code, killed.is_set(), wall, peak_mb, limit,
                                full)  # fmt: skip

    def close(self) -> None:
        if self.proc.stdin is not None:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()


_servers: dict[tuple[int, int], _Server] = {}
_servers_lock = threading.Lock()
#: Keys of warm workers that died while loading (their tasks run fresh).
_failed: set[tuple[int, int]] = set()


def _server() -> _Server | None:
    """This thread's warm worker, started with this process's environment as it is now
    (a changed environment, e.g. PYTHONPATH, gets a new one); None if such a worker
    could not start."""
    key = (threading.get_ident(), hash(tuple(sorted(os.environ.items()))))
    with _servers_lock:
        if key in _failed:
            return None
        srv = _servers.get(key)
        if srv is not None and not srv.alive():
            srv.close()
            srv = None
        if srv is None:
            srv = _servers[key] = _Server(key)
    return srv


def close_servers() -> None:
    """Stop every warm worker of this process (they also stop when it exits)."""
    with _servers_lock:
        servers = list(_servers.values())
        _servers.clear()
    for srv in servers:
        srv.close()


atexit.register(close_servers)


def _crashed(
    code: int,
    killed: bool,
    stderr: str,
    wall: float,
    peak_mb: float,
    limit: float,
    full: str = "",
) -> dict[str, Any]:
    """The outcome of a run that left no report (``full``: how full its address space
    was when killed at the hard limit, if it was at its memory limit)."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    last = lines[-1][:300] if lines else ""
    if (killed or (code == 137 and wall >= limit)) and full:
        status, error = MEMOUT, f"out of memory (killed at the hard limit of {limit:g} s, {full})"
    elif killed or (code == 137 and wall >= limit):  # 137: the worker's own watchdog
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
