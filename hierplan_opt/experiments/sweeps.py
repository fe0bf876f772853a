"""``sweep(spec)``: every solver x instance x agent count x seed, one process per run.

The runs of a spec are planned in order of growing K, the ones whose key is already in
the database are re-used, and the rest are handed to a backend: a pool of threads on
this machine that each wait on one run's process (``workers`` at a time), or a Dask
cluster (``dask="local"`` starts a ``LocalCluster``; ``dask="tcp://HOST:PORT"`` joins a
running scheduler). Either way each run is :func:`~hierplan_opt.experiments.runner.run_task`
(a process of its own with a time and a memory limit, forked from a warm worker that has
the solvers loaded; ``HIERPLAN_SWEEP_WORKER=fresh``: a new interpreter per run) and its
row comes back to this process, which alone writes the SQLite file, one committed row per
finished run.
"""

from __future__ import annotations

import concurrent.futures as cf
import datetime
import hashlib
import json
import logging
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.progress import Progress
from hierplan_opt.experiments import store
from hierplan_opt.experiments.generators import GENERATORS
from hierplan_opt.experiments.runner import close_servers, kill_running, run_task
from hierplan_opt.experiments.spec import (
    InstanceSpec,
    SolverSpec,
    SweepSpec,
    load_spec,
    parse_spec,
)
from hierplan_opt.io import load_instance
from hierplan_opt.io.yaml import read_yaml

log = logging.getLogger(__name__)

SOLVED = ("OPTIMAL", "FEASIBLE", "INFEASIBLE")  # a definite answer
SKIPPED = "SKIPPED"  # not run: a smaller K of the same chain failed (stop_on_failure)


@dataclass(frozen=True)
class Run:
    """One planned run of a sweep."""

    solver: SolverSpec
    instance: InstanceSpec
    agents: int | None
    seed: int
    time_limit: float
    memory_limit_mb: float | None
    instance_hash: str
    key: str = field(default="", compare=False)

    @property
    def chain(self) -> tuple[str, str, int]:
        """Runs that differ only in K (``stop_on_failure`` skips along a chain)."""
        return (self.solver.label, self.instance.name, self.seed)

    def task(self, payload: dict[str, Any]) -> dict[str, Any]:
        """The JSON task a worker process executes."""
        return {
            "key": self.key,
            "solver": self.solver.name,
            "target": self.solver.target,
            "problems": list(self.solver.problems),
            "options": self.solver.options,
            "objective": self.solver.objective,
            "time_limit": self.time_limit,
            "memory_limit_mb": self.memory_limit_mb,
            "seed": self.seed,
            "agents": self.agents,
            "instance": payload,
        }

    def row(self, sweep_name: str, outcome: Mapping[str, Any]) -> dict[str, Any]:
        """The ``runs`` row of this run with the outcome of its process."""
        stats = outcome.get("stats") or {}
        agents = outcome.get("agents") if self.agents is None else self.agents
        return {
            "key": self.key,
            "sweep": sweep_name,
            "solver": self.solver.name,
            "label": self.solver.label,
            "options": self.solver.options,
            "objective": outcome.get("objective") or self.solver.objective,
            "instance": self.instance.name,
            "instance_hash": self.instance_hash,
            "agents": agents,
            "seed": self.seed,
            "time_limit": self.time_limit,
            "memory_limit_mb": self.memory_limit_mb,
            "status": outcome["status"],
            "cost": outcome.get("cost"),
            "lower_bound": outcome.get("lower_bound"),
            "runtime": outcome.get("runtime"),
            "wall": outcome.get("wall"),
            "peak_mb": outcome.get("peak_mb"),
            "expanded": stats.get("high_level_expanded"),
            "generated": stats.get("high_level_generated"),
            "low_level_expanded": stats.get("low_level_expanded"),
            "stats": stats,
            "error": outcome.get("error"),
            "versions": outcome.get("versions"),
            "host": outcome.get("host"),
            "finished_at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        }


def run_key(run: Run) -> str:
    """A hash of everything that determines a run's outcome.

    Example
    -------
    >>> from hierplan_opt.experiments.spec import InstanceSpec, SolverSpec
    >>> s, i = SolverSpec("cbs", "cbs"), InstanceSpec("generator", "g", generator="x")
    >>> a, b = (run_key(Run(s, i, k, 0, 10.0, None, "h")) for k in (4, 5))
    >>> a == run_key(Run(s, i, 4, 0, 10.0, None, "h")), a == b
    (True, False)
    """
    what = {
        "solver": run.solver.name,
        "target": run.solver.target,
        "options": run.solver.options,
        "objective": run.solver.objective,
        "instance": run.instance_hash,
        "agents": run.agents,
        "seed": run.seed,
        "time_limit": run.time_limit,
        "memory_limit_mb": run.memory_limit_mb,
    }
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()[:24]


def plan_runs(spec: SweepSpec, problems: Mapping[str, str] | None = None) -> list[Run]:
    """Every run of ``spec``, smallest K first (then instance, solver, seed order).

    ``problems`` (instance name -> ``"mapf"`` or ``"tapf"``, from
    :func:`check_instances`) leaves out the pairs of a solver and an instance it does
    not solve (a MAPF-only solver on a TAPF instance).
    """
    runs: list[tuple[tuple, Run]] = []
    for ii, inst in enumerate(spec.instances):
        digest = inst.digest()
        for k in spec.agents_of(inst):
            for si, solver in enumerate(spec.solvers):
                if problems is not None and problems[inst.name] not in solver.problems:
                    continue
                for seed in spec.seeds:
                    tl = solver.time_limit if solver.time_limit is not None else spec.time_limit
                    r = Run(solver, inst, k, seed, tl, spec.memory_limit_mb, digest)
                    r = replace(r, key=run_key(r))
                    order = (float("inf") if k is None else k, ii, si, seed)
                    runs.append((order, r))
    runs.sort(key=lambda t: t[0])
    return [r for _, r in runs]


#: Generated maps up to this many cells are built once per seed (largest K) by the
#: check before the first run; larger ones are left to the runs and their limits.
CHECK_CELLS = 1_000_000


def _check_generated(spec: SweepSpec, inst: Any, gen: Any) -> None:
    """Build a generator's instance with its largest K for every seed, so that values
    it refuses (a negative width, more agents than free cells) are one line before the
    first run rather than an ERROR row per run."""
    params = dict(inst.params or {})
    full = {k: v for k, (_, v) in gen.params.items()} | params
    cells = 1
    for key in ("width", "height"):
        if isinstance(full.get(key), int):
            cells *= max(1, full[key])
    if cells > CHECK_CELLS:
        return
    k = max(a for a in spec.agents_of(inst) if a is not None)
    for seed in spec.seeds:
        try:
            gen(params, agents=k, seed=seed)
        except InputError as exc:
            raise InputError(
                f"{spec.file}: instance {inst.name!r} with {k} agents, seed {seed}: {exc}"
            ) from None


def check_instances(spec: SweepSpec) -> dict[str, str]:
    """Load each file instance once with its largest K, so that bad files and agent
    counts beyond a scenario are refused before the first run; returns the problem
    (``"mapf"`` / ``"tapf"``) of each instance."""

    problems: dict[str, str] = {}
    for inst in spec.instances:
        if inst.kind == "generator":
            if None in spec.agents_of(inst):
                raise InputError(
                    f"{spec.file}: instance {inst.name!r}: a generator needs agent counts "
                    "('agents: [..]')"
                )
            gen = GENERATORS[str(inst.generator)]
            _check_generated(spec, inst, gen)
            problems[inst.name] = gen.problem
            continue
        ks = spec.agents_of(inst)
        k = None if None in ks else max(k for k in ks if k is not None)
        try:
            if inst.kind == "movingai":
                loaded = load_instance(inst.files[0], scen=inst.files[1], agents=k)
            else:
                loaded = load_instance(inst.files[0], agents=k)
        except InputError as exc:
            hint = " (use 'agents: all' on a TAPF instance)" if "teams" in str(exc) else ""
            raise InputError(
                f"{spec.file}: instance {inst.name!r} with {k or 'all'} agents: {exc}{hint}"
            ) from None
        problems[inst.name] = "tapf" if loaded.is_tapf else "mapf"
    return problems


# ---------------------------------------------------------------- backends
class _Local:
    """Threads on this machine, each waiting on one run's process (forked from the
    thread's warm worker, see :mod:`~hierplan_opt.experiments.runner`)."""

    def __init__(self, workers: int) -> None:
        self.pool = cf.ThreadPoolExecutor(max_workers=workers, thread_name_prefix="sweep")

    def submit(self, task: dict[str, Any]) -> Any:
        return self.pool.submit(run_task, task)

    def as_completed(self, futures: Iterable[Any]) -> Iterable[Any]:
        return cf.as_completed(list(futures))

    def cancel(self, future: Any) -> bool:
        return bool(future.cancel())

    def abort(self) -> None:
        """Ctrl-C: cancel the queued runs and kill the ones in flight (not recorded)."""
        self.pool.shutdown(wait=False, cancel_futures=True)
        kill_running()

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)
        close_servers()


class _Dask:
    """A Dask distributed cluster: a new ``LocalCluster`` or a running scheduler."""

    def __init__(self, address: Any, workers: int) -> None:
        try:
            from distributed import Client, LocalCluster  # heavy module: Dask
        except ImportError:
            raise InputError(
                "a Dask sweep needs the 'cluster' extra: pip install 'hierplan_opt[cluster]'"
            ) from None
        self.cluster = None
        if isinstance(address, Client):
            self.client, self.own_client = address, False
            return
        self.own_client = True
        if logging.getLogger().getEffectiveLevel() > logging.DEBUG:  # -v shows Dask's chatter
            logging.getLogger("distributed").setLevel(logging.WARNING)
        if address == "local":
            options: dict[str, Any] = {
                "n_workers": workers,
                "threads_per_worker": 1,
                "processes": True,
                "host": "127.0.0.1",
                "dashboard_address": "127.0.0.1:0",  # its HTTP server: loopback, any free port
                "silence_logs": logging.WARNING,
            }
            self.cluster = LocalCluster(**options)
            self.client = Client(self.cluster)
        else:
            if not str(address).startswith(("tcp://", "tls://", "inproc://", "ucx://")):
                raise InputError(f"--dask-scheduler expects tcp://HOST:PORT, got {address!r}")
            try:
                self.client = Client(address, timeout=20)
            except OSError as exc:
                raise InputError(f"cannot reach the Dask scheduler at {address}: {exc}") from None

    def submit(self, task: dict[str, Any]) -> Any:
        return self.client.submit(run_task, task, key=f"hierplan-run-{task['key']}", pure=False)

    def as_completed(self, futures: Iterable[Any]) -> Iterable[Any]:
        from distributed import as_completed  # heavy module: Dask

        return as_completed(list(futures))

    def cancel(self, future: Any) -> bool:
        if future.done():
            return False
        future.cancel()
        return True

    def close(self) -> None:
        if self.own_client:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


# ---------------------------------------------------------------- the sweep
@dataclass(frozen=True)
class SweepSummary:
    """What a sweep did: runs planned, re-used from the database, run now, skipped."""

    name: str
    db: Path
    total: int
    reused: int
    ran: int
    skipped: int
    statuses: dict[str, int]
    elapsed: float
    #: Sums over the runs run now: their wall-clock seconds and their solvers' runtimes.
    run_wall: float = 0.0
    run_solve: float = 0.0

    def message(self) -> str:
        """One summary line (with the mean wall time per run beyond its solve).

        Example
        -------
        >>> s = SweepSummary("s", Path("r.sqlite"), 2, 0, 2, 0, {"OPTIMAL": 2}, 1.5, 1.2, 1.0)
        >>> s.message().split("; ")[2]
        'per run 0.600 s, 0.100 s beyond the solve'
        """
        counts = ", ".join(f"{k} {v}" for k, v in sorted(self.statuses.items()))
        per_run = ""
        if self.ran:
            per_run = (
                f"; per run {self.run_wall / self.ran:.3f} s, "
                f"{(self.run_wall - self.run_solve) / self.ran:.3f} s beyond the solve"
            )
        return (
            f"sweep {self.name}: {self.total} runs ({self.reused} re-used, {self.ran} run, "
            f"{self.skipped} skipped) in {self.elapsed:.1f} s; {counts or 'nothing run'}"
            f"{per_run}; database {self.db}"
        )


def resolve(spec: SweepSpec | Mapping[str, Any] | str | Path) -> SweepSpec:
    """A spec from a :class:`SweepSpec`, a dict, a spec file, or a sweep database (the
    latest sweep recorded in it, for ``--resume``)."""
    if isinstance(spec, SweepSpec):
        return spec
    if isinstance(spec, Mapping):
        return parse_spec(spec)
    path = Path(spec)
    if store.is_database(path):
        return spec_from_db(path)
    return load_spec(path)


def spec_from_db(path: str | Path) -> SweepSpec:
    """The spec of the latest sweep recorded in the database ``path`` (its results go
    back to that database)."""

    con = store.open_existing(path)
    try:
        last = store.last_sweep(con)
    finally:
        con.close()
    if last is None:
        raise InputError(f"{path}: no sweep recorded in this database")
    name, text, folder, _ = last
    data = read_yaml(f"{path} (stored spec)", text)
    spec = parse_spec(data, folder=folder, file=f"{path} (stored spec)", source=text,
                      default_name=name)  # fmt: skip
    return replace(spec, db=Path(path))


def sweep(
    spec: SweepSpec | Mapping[str, Any] | str | Path,
    *,
    db: str | Path | None = None,
    workers: int | None = None,
    dask: Any = None,
    progress: bool | None = None,
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> SweepSummary:
    """Run a sweep; every finished run is a row of table ``runs`` in the database.

    Parameters
    ----------
    spec
        A :class:`SweepSpec`, spec data (dict), a spec YAML file, or a sweep database
        (continue its latest sweep).
    db
        Database file (default: the spec's ``db``).
    workers
        Runs at the same time (default: the spec's ``workers``); for ``dask="local"``
        the number of Dask workers.
    dask
        ``None`` (processes on this machine), ``"local"`` (a new ``LocalCluster``), a
        scheduler address ``"tcp://HOST:PORT"``, or a ``distributed.Client``.
    progress
        Show a progress bar (``None``: on a terminal; status lines otherwise).
    on_row
        Called with each new row (after it is committed).

    Example
    -------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> s = sweep({"solvers": [{"name": "cbs"}],
    ...            "instances": [{"generator": "random_grid",
    ...                           "params": {"width": 6, "height": 6}}],
    ...            "agents": [2], "time_limit": 10, "db": os.path.join(d, "r.sqlite")},
    ...           progress=False)
    >>> s.ran, s.statuses
    (1, {'OPTIMAL': 1})
    """
    sp = resolve(spec)
    if db is not None:
        sp = replace(sp, db=Path(db))
    n_workers = workers if workers is not None else sp.workers
    problems = check_instances(sp)
    runs = plan_runs(sp, problems)
    left_out = len(plan_runs(sp)) - len(runs)
    if left_out:
        log.info("sweep %s: %d solver/instance pairs left out (problem not solved by the "
                 "solver, e.g. TAPF for a MAPF solver)", sp.name, left_out)  # fmt: skip
    con = store.connect(sp.db)
    t0 = time.perf_counter()
    try:
        done = store.finished_keys(con)
        todo = [r for r in runs if r.key not in done]
        reused = len(runs) - len(todo)
        if reused:
            log.info("sweep %s: %d of %d runs already in %s", sp.name, reused, len(runs), sp.db)
        sweep_id = store.start_sweep(con, sp.name, sp.source, str(sp.folder.resolve()), len(runs))
        statuses: Counter[str] = Counter()
        times = [0.0, 0.0]  # wall, solve runtime of the runs run now

        def count(row: dict[str, Any]) -> None:
            if row["status"] != SKIPPED:
                times[0] += float(row.get("wall") or 0.0)
                times[1] += float(row.get("runtime") or 0.0)
            if on_row is not None:
                on_row(row)

        skipped = _execute(sp, todo, con, n_workers, dask, progress, statuses, count)
        store.finish_sweep(con, sweep_id)
    finally:
        con.close()
    return SweepSummary(
        sp.name,
        sp.db,
        len(runs),
        reused,
        sum(statuses.values()) - skipped,
        skipped,
        dict(statuses),
        time.perf_counter() - t0,
        times[0],
        times[1],
    )


def _execute(
    sp: SweepSpec,
    todo: list[Run],
    con: Any,
    workers: int,
    dask: Any,
    progress: bool | None,
    statuses: Counter[str],
    on_row: Callable[[dict[str, Any]], None] | None,
) -> int:
    """Run ``todo`` on the chosen backend, recording rows as they finish; returns the
    number of runs skipped by ``stop_on_failure``."""
    if not todo:
        return 0
    backend: _Local | _Dask = _Dask(dask, workers) if dask is not None else _Local(workers)
    payloads: dict[str, dict[str, Any]] = {}
    futures: dict[Any, Run] = {}
    skipped = 0
    try:
        for r in todo:
            if r.instance.name not in payloads:
                payloads[r.instance.name] = r.instance.payload()
            futures[backend.submit(r.task(payloads[r.instance.name]))] = r
        failed_at: dict[tuple[str, str, int], int] = {}
        recorded: set[str] = set()

        def record(r: Run, outcome: Mapping[str, Any]) -> None:
            row = r.row(sp.name, outcome)
            store.insert_run(con, row)
            recorded.add(r.key)
            statuses[row["status"]] += 1
            if on_row is not None:
                on_row(row)

        with Progress(f"sweep {sp.name}", len(todo), unit="runs", enabled=progress) as bar:
            for fut in backend.as_completed(futures):
                r = futures[fut]
                if r.key in recorded or fut.cancelled():
                    continue
                try:
                    outcome = fut.result()
                except Exception as exc:  # the backend lost the run (a Dask worker died, ...)
                    outcome = {"status": "ERROR", "error": f"{type(exc).__name__}: {exc}"[:500]}
                record(r, outcome)
                if sp.stop_on_failure and outcome["status"] not in SOLVED:
                    k = r.agents or 0
                    failed_at[r.chain] = min(failed_at.get(r.chain, k), k)
                    for f2, r2 in futures.items():
                        if (
                            r2.chain == r.chain
                            and (r2.agents or 0) > k
                            and r2.key not in recorded
                            and backend.cancel(f2)
                        ):
                            why = f"not run: failed with {r.agents} agents ({outcome['status']})"
                            record(r2, {"status": SKIPPED, "error": why})
                            skipped += 1
                            bar.advance()
                solved = sum(statuses[s] for s in SOLVED)
                bar.advance(solved=solved, failed=sum(statuses.values()) - solved - skipped)
    except KeyboardInterrupt:
        if isinstance(backend, _Local):  # do not wait for the runs in flight
            backend.abort()
        raise
    finally:
        backend.close()
    return skipped


__all__ = ["Run", "SweepSummary", "check_instances", "plan_runs", "resolve", "run_key", "sweep"]
