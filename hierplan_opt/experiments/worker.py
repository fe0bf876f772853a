"""One sweep run in its own process: ``python -m hierplan_opt.experiments.worker``.

The parent (:mod:`hierplan_opt.experiments.runner`) writes the task as JSON to stdin;
this process limits its own address space (``RLIMIT_AS``, no privileges or cgroups
needed), rebuilds the instance from the file contents or the generator in the task,
solves it through the front door and writes the outcome as JSON to
``task["result_path"]``. A ``MemoryError`` becomes MEMOUT; any other exception ERROR.
A watchdog thread ends the process when the parent dies (so a killed sweep leaves no
orphans) or when the hard wall-clock limit passes.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

MEMOUT = "MEMOUT"
#: Packages whose versions are stored with every run.
VERSIONED = ("hierplan_opt", "numpy", "scipy", "networkx", "ortools", "highspy", "pyomo")


def limit_memory(megabytes: float | None) -> None:
    """Cap this process's address space at ``megabytes`` (``None``: no cap)."""
    if megabytes is None:
        return
    limit = int(megabytes * 1024 * 1024)
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def watchdog(hard_limit: float | None, poll: float = 0.2) -> None:
    """Start a daemon thread that exits the process (code 137) when the parent process
    is gone or after ``hard_limit`` seconds."""
    parent = os.getppid()
    end = None if hard_limit is None else time.monotonic() + hard_limit

    def watch() -> None:
        while True:
            time.sleep(poll)
            if os.getppid() != parent or (end is not None and time.monotonic() > end):
                os._exit(137)

    threading.Thread(target=watch, name="hierplan-watchdog", daemon=True).start()


def versions() -> dict[str, str]:
    """Versions of Python and of the packages in :data:`VERSIONED` that are installed."""
    from importlib import metadata

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
        from hierplan_opt.experiments.generators import GENERATORS

        if agents is None:
            from hierplan_opt.core.errors import InputError

            raise InputError(f"generator {payload['generator']!r} needs an agent count")
        return GENERATORS[payload["generator"]](payload["params"], agents, seed)
    from hierplan_opt.io import load_instance

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
    import hierplan_opt
    from hierplan_opt import registry

    if task.get("target"):
        registry.register(
            task["solver"],
            task["target"],
            problems=set(task.get("problems") or ["mapf"]),
            objectives={"soc", "makespan"},
        )
    with tempfile.TemporaryDirectory(prefix="hierplan-inst-") as tmp:
        inst = build_instance(task["instance"], task["agents"], task["seed"], Path(tmp))
    res = hierplan_opt.solve(
        inst,
        task["solver"],
        time_limit=task["time_limit"],
        seed=task["seed"],
        objective=task.get("objective"),
        **task.get("options", {}),
    )
    stats = {k: v for k, v in res.stats.items() if _json_safe(v)}
    return {
        "status": str(res.status),
        "cost": res.cost,
        "lower_bound": res.lower_bound,
        "runtime": res.runtime,
        "objective": res.objective,
        "agents": inst.num_agents,
        "stats": stats,
        "error": res.stats.get("error") if res.status == hierplan_opt.Status.ERROR else None,
    }


def _json_safe(value: Any) -> bool:
    try:
        json.dumps(value)
    except (TypeError, ValueError):
        return False
    return True


def main() -> int:
    task = json.load(sys.stdin)
    limit_memory(task.get("memory_limit_mb"))
    watchdog(task.get("hard_limit"))
    out: dict[str, Any]
    try:
        out = solve_task(task)
    except MemoryError:
        out = {"status": MEMOUT, "error": "MemoryError: the run exceeded its memory limit"}
    except Exception as exc:  # recorded as the run's outcome; the sweep goes on
        from hierplan_opt.io._yaml import one_line

        out = {"status": "ERROR", "error": one_line(f"{type(exc).__name__}: {exc}")[:500]}
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    out["versions"] = versions()
    import socket

    out["host"] = socket.gethostname()
    path = Path(task["result_path"])
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(out, default=str), encoding="utf-8")
    os.replace(tmp, path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
