"""One sweep run in its own process: ``python -m hierplan_opt.experiments.worker``.

The parent (:mod:`hierplan_opt.experiments.runner`) writes the task as JSON to stdin;
this process limits its own address space (``RLIMIT_AS``, no privileges or cgroups
needed), rebuilds the instance from the file contents or the generator in the task,
solves it through the front door and writes the outcome as JSON to
``task["result_path"]``. A ``MemoryError`` becomes MEMOUT; any other exception ERROR.
A watchdog thread ends the process when the parent dies (so a killed sweep leaves no
orphans) or when the hard wall-clock limit passes, and as MEMOUT (exit code 1 and a
``MemoryError`` line on stderr) when the run is :data:`HUNG_S` seconds past its time
limit with its address space at its memory limit (:func:`memory_full`): a run that hung
after a failed allocation ends then, not at the hard limit.

``python -m hierplan_opt.experiments.worker --serve`` is the warm variant (a fork
server, :func:`serve`): it imports the solvers, scipy's graph routines and (when numba's
on-disk cache holds them) the compiled kernels once, then reads one request a line on
stdin and forks one child per task. The child does exactly what a fresh worker does
(memory limit, watchdog, solve, result file; its stderr goes to the request's file) and
leaves with ``os._exit``; the server answers with the child's pid at once (so the parent
can kill it at the hard limit) and, when it is done, with its wait status and peak
resident memory. A child whose inherited address space leaves too little of its memory
limit exits with :data:`TOO_BIG` at once (the parent then runs the task in a fresh
process instead).
"""

from __future__ import annotations

import contextlib
import functools
import gc
import importlib
import json
import os
import resource
import signal
import socket
import sys
import tempfile
import threading
import time
from importlib import metadata
from pathlib import Path
from typing import Any

from hierplan_opt import registry
from hierplan_opt.api import solve
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.options import AMOUNT_CAP
from hierplan_opt.core.result import Status
from hierplan_opt.experiments.generators import GENERATORS
from hierplan_opt.io import load_instance
from hierplan_opt.io.values import to_json
from hierplan_opt.io.yaml import one_line

MEMOUT = "MEMOUT"
#: A forked child's exit code: the server's address space leaves too little of the
#: task's memory limit; run the task in a fresh process instead.
TOO_BIG = 75
#: Megabytes of its memory limit a forked child must have left to start.
HEADROOM_MB = 128
#: A run killed at the hard limit whose address space is within this many MB (or a
#: tenth of the limit, if more) of its memory limit is MEMOUT, not TIME_LIMIT.
FULL_MB = 64.0
#: Seconds past its time limit after which a run at its memory limit is ended (MEMOUT).
HUNG_S = 1.0
_HUNG_LINE = b"MemoryError: the run hung at its memory limit past its time limit\n"
#: Packages whose versions are stored with every run.
VERSIONED = ("hierplan_opt", "numpy", "scipy", "networkx", "ortools", "highspy", "pyomo")


def limit_memory(megabytes: float | None) -> None:
    """Cap this process's address space at ``megabytes`` (``None``: no cap)."""
    if megabytes is None or megabytes * 1024 * 1024 >= AMOUNT_CAP:  # beyond any machine
        return
    limit = int(megabytes * 1024 * 1024)
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def memory_full(space_mb: float, limit_mb: float | None) -> bool:
    """Whether an address space of ``space_mb`` is at the memory limit ``limit_mb``
    (within :data:`FULL_MB` or a tenth of it).

    Example
    -------
    >>> memory_full(480.0, 512), memory_full(300.0, 512), memory_full(480.0, None)
    (True, False, False)
    """
    if limit_mb is None or space_mb <= 0:
        return False
    return space_mb >= limit_mb - max(FULL_MB, 0.1 * limit_mb)


def watchdog(
    hard_limit: float | None,
    poll: float = 0.2,
    time_limit: float | None = None,
    memory_limit_mb: float | None = None,
) -> None:
    """Start a daemon thread that exits the process (code 137) when the parent process
    is gone or after ``hard_limit`` seconds, and (code 1, a ``MemoryError`` line on
    stderr) once it is :data:`HUNG_S` seconds past ``time_limit`` with its address
    space at ``memory_limit_mb``."""
    parent = os.getppid()
    now = time.monotonic()
    end = None if hard_limit is None else now + hard_limit
    hung = None if time_limit is None or memory_limit_mb is None else now + time_limit + HUNG_S

    def watch() -> None:
        while True:
            try:
                time.sleep(poll)
                if os.getppid() != parent or (end is not None and time.monotonic() > end):
                    os._exit(137)
                late = hung is not None and time.monotonic() > hung
                if late and memory_full(address_space_mb(), memory_limit_mb):
                    os.write(2, _HUNG_LINE)
                    os._exit(1)
            except MemoryError:  # (the run's memory is full: look again)
                continue

    threading.Thread(target=watch, name="hierplan-watchdog", daemon=True).start()


@functools.cache
def versions() -> dict[str, str]:
    """Versions of Python and of the packages in :data:`VERSIONED` that are installed
    (looked up once a process: 10-35 ms; a warm worker's children inherit them)."""
    out = {"python": sys.version.split()[0]}
    for name in VERSIONED:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def build_instance(payload: dict[str, Any], agents: int | None, seed: int, tmp: Path) -> Any:
    """The instance of a task: files written to ``tmp`` and read back, or generated."""
    if payload["kind"] == "generator":
        if agents is None:
            raise InputError(f"generator {payload['generator']!r} needs an agent count")
        return GENERATORS[payload["generator"]](payload["params"], agents, seed)

    paths = []
    for name in payload["order"]:
        p = tmp / name
        p.write_text(payload["files"][name], encoding="utf-8")
        paths.append(p)
    if payload["kind"] == "movingai":
        return load_instance(paths[0], scen=paths[1], agents=agents)
    inst = load_instance(paths[0], agents=agents if agents is not None else None)
    return inst


def solve_task(task: dict[str, Any]) -> dict[str, Any]:
    """Solve one task in this process; the fields of a ``runs`` row that it knows."""

    if task.get("target"):
        registry.register(
            task["solver"],
            task["target"],
            problems=set(task.get("problems") or ["mapf"]),
            objectives={"soc", "makespan"},
        )
    with tempfile.TemporaryDirectory(prefix="hierplan-inst-") as tmp:
        inst = build_instance(task["instance"], task["agents"], task["seed"], Path(tmp))
    res = solve(
        inst,
        task["solver"],
        time_limit=task["time_limit"],
        seed=task["seed"],
        cost=task.get("objective"),
        **task.get("options", {}),
    )
    stats = {k: v for k, v in res.stats.items() if _json_safe(v)}
    # a search that stopped itself at the memory limit (core.timer.MEMORY_MARGIN) ran
    # out of memory as much as one that raised MemoryError, and says so with its bound
    memout = res.status is Status.TIME_LIMIT and res.stats.get("stopped_by") == "memory_limit"
    return {
        "status": MEMOUT if memout else str(res.status),
        "cost": res.cost,
        "lower_bound": res.lower_bound,
        "runtime": res.runtime,
        "objective": res.objective,
        "agents": inst.num_agents,
        "stats": stats,
        "error": res.stats.get("error") if res.status == Status.ERROR else None,
    }


def _json_safe(value: Any) -> bool:
    try:
        to_json(value)
    except (TypeError, ValueError):
        return False
    return True


def report(task: dict[str, Any]) -> None:
    """Solve ``task`` (its memory limit and watchdog on) and write its outcome file."""
    versions()  # (before the limit: a run that ran out of memory still reports them)
    limit_memory(task.get("memory_limit_mb"))
    watchdog(task.get("hard_limit"), time_limit=task.get("time_limit"),
             memory_limit_mb=task.get("memory_limit_mb"))  # fmt: skip
    out: dict[str, Any]
    try:
        out = solve_task(task)
    except MemoryError:
        out = {"status": MEMOUT, "error": "MemoryError: the run exceeded its memory limit"}
    except Exception as exc:  # recorded as the run's outcome; the sweep goes on
        out = {"status": "ERROR", "error": one_line(f"{type(exc).__name__}: {exc}")[:500]}
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    out["versions"] = dict(versions())

    out["host"] = socket.gethostname()
    path = Path(task["result_path"])
    tmp = path.with_suffix(".tmp")
    tmp.write_text(to_json(out, default=str), encoding="utf-8")
    os.replace(tmp, path)


def main() -> int:
    if sys.argv[1:] == ["--serve"]:
        return serve()
    report(json.load(sys.stdin))
    return 0


def address_space_mb(pid: int | None = None) -> float:
    """The virtual memory size (what ``RLIMIT_AS`` caps) of process ``pid`` (default:
    this one), in MB; 0 if unknown (no such process, not Linux)."""
    try:
        with open(f"/proc/{'self' if pid is None else pid}/statm", encoding="ascii") as fh:
            pages = int(fh.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 0.0
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def preload() -> list[str]:
    """Import what runs need (solvers, scipy's graph routines) and, if numba's on-disk
    cache holds them, load the compiled kernels; the names of what was loaded."""
    done = []
    for mod in (
        "numpy",
        "scipy.sparse.csgraph",
        "hierplan_opt.api",
        "hierplan_opt.io",
        "hierplan_opt.experiments.generators",
        "hierplan_opt.search.cbs",
        "hierplan_opt.search.ecbs",
        "hierplan_opt.search.eecbs",
        "hierplan_opt.search.lacam",
    ):
        try:
            importlib.import_module(mod)
            done.append(mod)
        except Exception:  # (a missing optional part: the child imports it)
            continue
    versions()

    here = Path(__file__).resolve().parent.parent / "search" / "__pycache__"
    if not os.environ.get("NUMBA_CACHE_DIR") and any(here.glob("_astar_kernel.*.nbi")):
        try:
            from hierplan_opt.search import jit  # heavy module: numba (loaded only here)

            jit.load()
            done.append("kernels")
        except Exception:  # (auto mode falls back to Python in the child)
            pass
    return done


def serve() -> int:
    """The fork server (see the module doc); returns when stdin closes."""
    preload()
    # The children's collector need not scan (and copy, page by page) what they inherit.
    gc.collect()
    gc.freeze()
    # Requests on fd 0, answers on a private copy of fd 1; fd 1 itself goes to /dev/null
    # so that nothing a library prints can garble an answer.
    inp = os.fdopen(0, "rb", buffering=0)
    out = os.fdopen(os.dup(1), "wb", buffering=0)
    null = os.open(os.devnull, os.O_RDWR)
    os.dup2(null, 1)
    watchdog(None)  # the sweep is gone: stop
    out.write(b'{"ready": true}\n')
    while True:
        line = inp.readline()
        if not line:
            return 0
        req = json.loads(line)
        pid = os.fork()
        if pid == 0:  # the child: never returns
            code = 1
            try:
                inp.close()
                out.close()
                signal.signal(signal.SIGINT, signal.SIG_DFL)
                err = os.open(req["stderr_path"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
                os.dup2(err, 2)
                os.dup2(null, 0)
                task = req["task"]
                limit = task.get("memory_limit_mb")
                if limit is not None and address_space_mb() + HEADROOM_MB > limit:
                    code = TOO_BIG
                else:
                    report(task)
                    code = 0
            except BaseException:  # (reported through stderr and the code)
                import traceback

                traceback.print_exc()
            finally:
                with contextlib.suppress(Exception):
                    sys.stderr.flush()
                os._exit(code)
        out.write(json.dumps({"pid": pid}).encode() + b"\n")
        _, status, usage = os.wait4(pid, 0)
        answer = {"status": status, "maxrss_kb": usage.ru_maxrss}
        out.write(json.dumps(answer).encode() + b"\n")


if __name__ == "__main__":
    sys.exit(main())
