"""Sweep specifications: which solvers, on which instances, with how many agents.

A spec is a YAML file (or the same data as a dict)::

    name: cbs-vs-ecbs                  # optional (default: the file's stem)
    solvers:
      - {name: cbs}
      - {name: ecbs, options: {w: 1.2}}          # label defaults to "ecbs(w=1.2)"
      - {name: mine, target: "my_pkg.solver:solve", label: mine}   # a solver of your own
    instances:
      - {map: maps/random-32-32-20.map, scen: scen/random-32-32-20-even-*.scen}
      - {yaml: instances/figure3.yaml}
      - {generator: random_grid, params: {width: 16, height: 16, obstacles: 0.1}}
    agents: [10, 20, 30]             # first K agents (default: all of them)
    seeds: [0]                       # solver seed (and generator seed)
    time_limit: 30                   # seconds per run
    memory_limit_mb: 4000            # address-space limit per run (null: none)
    db: results.sqlite               # the SQLite file that keeps every run
    workers: 2                       # runs at the same time on this machine
    stop_on_failure: false           # skip larger K once a solver failed at a smaller K

Relative paths are resolved against the spec's folder; a path that starts with
``$instances`` is taken from the shipped benchmark instances
(:func:`~hierplan_opt.experiments.data.instances_dir`); ``scen`` (and ``yaml``) may be a
glob pattern that names a set of files. Each solver may override ``time_limit`` and
``objective``, each instance ``agents``. Everything is checked before the first run,
and a bad spec is refused with one line naming the file, the line and the problem.
"""

from __future__ import annotations

import glob
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.errors import InputError
from hierplan_opt.experiments.data import instances_dir
from hierplan_opt.experiments.generators import GENERATORS
from hierplan_opt.io.values import plain, to_json
from hierplan_opt.io.yaml import Ctx, read_text, read_yaml

TOP_KEYS = (
    "name",
    "solvers",
    "instances",
    "agents",
    "seeds",
    "time_limit",
    "memory_limit_mb",
    "db",
    "workers",
    "stop_on_failure",
    "objective",
)
SOLVER_KEYS = ("name", "options", "label", "objective", "time_limit", "target", "problems")
INSTANCE_KEYS = ("map", "scen", "yaml", "generator", "params", "name", "agents")
OBJECTIVES = ("soc", "makespan")
#: The limit caps the address space, and importing numpy alone reserves ~300 MB of it
#: (thread pools); below this a run could only fail.
MIN_MEMORY_MB = 512


@dataclass(frozen=True)
class SolverSpec:
    """One solver configuration of a sweep (``label`` names it in tables and plots)."""

    name: str
    label: str
    options: dict[str, Any] = field(default_factory=dict)
    objective: str | None = None
    time_limit: float | None = None
    target: str | None = None  # "package.module:function" of a solver outside the registry
    problems: tuple[str, ...] = ("mapf",)


@dataclass(frozen=True)
class InstanceSpec:
    """One instance source: MovingAI ``map`` + ``scen``, a ``yaml`` file, or a generator."""

    kind: str  # "movingai" | "yaml" | "generator"
    name: str
    files: tuple[Path, ...] = ()
    generator: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    agents: tuple[int | None, ...] | None = None

    def payload(self) -> dict[str, Any]:
        """What a worker process needs to rebuild the instance (file contents, not paths,
        so that workers on other machines need no shared file system)."""
        if self.kind == "generator":
            return {"kind": self.kind, "name": self.name, "generator": self.generator,
                    "params": self.params}  # fmt: skip
        files = {p.name: p.read_text(encoding="utf-8") for p in self.files}
        return {"kind": self.kind, "name": self.name, "files": files,
                "order": [p.name for p in self.files]}  # fmt: skip

    def digest(self) -> str:
        """A hash of the instance's content (files) or of its generator and parameters."""
        h = hashlib.sha256()
        if self.kind == "generator":
            h.update(json.dumps([self.generator, self.params], sort_keys=True).encode())
        for p in self.files:
            h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
        return h.hexdigest()[:16]


@dataclass(frozen=True)
class SweepSpec:
    """A parsed, checked sweep: solvers x instances x agents x seeds."""

    name: str
    solvers: tuple[SolverSpec, ...]
    instances: tuple[InstanceSpec, ...]
    agents: tuple[int | None, ...] = (None,)
    seeds: tuple[int, ...] = (0,)
    time_limit: float = 60.0
    memory_limit_mb: float | None = 4000.0
    db: Path = Path("results.sqlite")
    workers: int = 1
    stop_on_failure: bool = False
    objective: str | None = None
    source: str = ""  # the spec's text (stored with the sweep, so --resume needs only the DB)
    folder: Path = Path(".")
    file: str = "<spec>"  # where the spec came from, for messages

    def agents_of(self, inst: InstanceSpec) -> tuple[int | None, ...]:
        """The agent counts run on ``inst`` (its own list, else the sweep's)."""
        return inst.agents if inst.agents is not None else self.agents


#: The longest time limit of a run (a week): the kill timer cannot wait much longer.
MAX_TIME_LIMIT = 7 * 24 * 3600.0


def _check_time_limit(ctx: Any, value: float, what: str, line: int | None) -> None:
    if value > MAX_TIME_LIMIT:
        raise ctx.error(
            f"{what} must be at most {MAX_TIME_LIMIT:g} s (a week), got {value:g}", line
        )


def load_spec(path: str | Path) -> SweepSpec:
    """Read and check a sweep spec file.

    Example
    -------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> _ = open(os.path.join(d, "s.yaml"), "w").write('''
    ... solvers: [{name: cbs}, {name: ecbs, options: {w: 1.5}}]
    ... instances: [{generator: random_grid, params: {width: 8, height: 8}}]
    ... agents: [2, 4]
    ... ''')
    >>> spec = load_spec(os.path.join(d, "s.yaml"))
    >>> [s.label for s in spec.solvers], spec.agents, spec.db.name
    (['cbs', 'ecbs(w=1.5)'], (2, 4), 's.sqlite')
    """
    p = Path(path)

    text = read_text(p)
    return parse_spec(read_yaml(p, text), folder=p.resolve().parent, file=str(p), source=text,
                      default_name=p.stem)  # fmt: skip


def parse_spec(
    data: Any,
    *,
    folder: str | Path = ".",
    file: str = "<spec>",
    source: str = "",
    default_name: str = "sweep",
) -> SweepSpec:
    """Check spec data (a mapping as read from YAML); relative paths are taken from
    ``folder``. Errors are one-line :class:`InputError` messages ``file:line: ...``.

    Example
    -------
    >>> parse_spec({"solvers": [{"name": "cbs"}], "instances": []})
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: <spec>: instances must list at least one instance
    """
    ctx = Ctx(file)
    folder = Path(folder)
    top = ctx.mapping(data, "a sweep spec", 1)
    ctx.check_keys(top, "the sweep spec", TOP_KEYS, required=("solvers", "instances"))
    line = top.lines.get

    objective = None
    if "objective" in top:
        objective = _objective(ctx, top["objective"], "objective", line("objective"))
    solvers = _solvers(ctx, top["solvers"], line("solvers"), objective)
    instances = _instances(ctx, top["instances"], line("instances"), folder)
    agents = (None,)
    if "agents" in top:
        agents = _agents(ctx, top["agents"], "agents", line("agents"))
    seeds = (0,)
    if "seeds" in top:
        seq = ctx.sequence(top["seeds"], "seeds", line("seeds"))
        if not seq:
            raise ctx.error("seeds must list at least one seed", line("seeds"))
        seeds = tuple(
            ctx.integer(v, f"seeds[{i}]", ctx.line_of(seq, i), minimum=0) for i, v in enumerate(seq)
        )
    time_limit = 60.0
    if "time_limit" in top:
        time_limit = ctx.number(top["time_limit"], "time_limit", line("time_limit"), positive=True)
        _check_time_limit(ctx, time_limit, "time_limit", line("time_limit"))
    memory: float | None = 4000.0
    if "memory_limit_mb" in top:
        memory = _memory(ctx, top["memory_limit_mb"], line("memory_limit_mb"))
    name = default_name
    if "name" in top:
        name = ctx.string(top["name"], "name", line("name"))
    db = folder / f"{default_name}.sqlite"
    if "db" in top:
        db = folder / ctx.string(top["db"], "db", line("db"))
    workers = 1
    if "workers" in top:
        workers = ctx.integer(top["workers"], "workers", line("workers"), minimum=1)
    stop = False
    if "stop_on_failure" in top:
        stop = ctx.boolean(top["stop_on_failure"], "stop_on_failure", line("stop_on_failure"))
    if source == "":
        source = to_json(top, sort_keys=True)
    return SweepSpec(
        name=name,
        solvers=solvers,
        instances=instances,
        agents=agents,
        seeds=seeds,
        time_limit=time_limit,
        memory_limit_mb=memory,
        db=db,
        workers=workers,
        stop_on_failure=stop,
        objective=objective,
        source=source,
        folder=folder,
        file=file,
    )


# ---------------------------------------------------------------- the parts
def _objective(ctx: Ctx, value: Any, what: str, line: int | None) -> str:
    text = ctx.string(value, what, line)
    if text not in OBJECTIVES:
        raise ctx.error(f"{what} must be one of {', '.join(OBJECTIVES)}, got {text!r}", line)
    return text


def _memory(ctx: Ctx, value: Any, line: int | None) -> float | None:
    if value is None:
        return None
    mb = ctx.number(value, "memory_limit_mb", line, positive=True)
    if mb < MIN_MEMORY_MB:
        raise ctx.error(
            f"memory_limit_mb must be at least {MIN_MEMORY_MB} (it caps the address space, "
            f"and importing numpy alone reserves ~300 MB), got {value!r}",
            line,
        )
    return mb


def _agents(ctx: Ctx, value: Any, what: str, line: int | None) -> tuple[int | None, ...]:
    if value == "all" or value is None:
        return (None,)
    seq = ctx.sequence(value, what, line)
    if not seq:
        raise ctx.error(f"{what} must list at least one agent count (or be 'all')", line)
    out = tuple(
        ctx.integer(v, f"{what}[{i}]", ctx.line_of(seq, i), minimum=1) for i, v in enumerate(seq)
    )
    if len(set(out)) != len(out):
        raise ctx.error(f"{what} lists an agent count twice: {list(out)}", line)
    return out


def default_label(name: str, options: Mapping[str, Any]) -> str:
    """``"ecbs(w=1.2)"``: the solver's name with its options.

    Example
    -------
    >>> default_label("cbs", {}), default_label("ecbs", {"w": 1.2, "polish": False})
    ('cbs', 'ecbs(polish=False,w=1.2)')
    """
    if not options:
        return name
    return name + "(" + ",".join(f"{k}={options[k]}" for k in sorted(options)) + ")"


def _solvers(
    ctx: Ctx, value: Any, line: int | None, objective: str | None
) -> tuple[SolverSpec, ...]:

    seq = ctx.sequence(value, "solvers", line)
    if not seq:
        raise ctx.error("solvers must list at least one solver", line)
    out: list[SolverSpec] = []
    labels: dict[str, int | None] = {}
    for i, item in enumerate(seq):
        what = f"solvers[{i}]"
        d = ctx.mapping(item, what, ctx.line_of(seq, i))
        ctx.check_keys(d, what, SOLVER_KEYS, required=("name",))
        name = ctx.string(d["name"], f"{what}.name", d.lines.get("name", d.line))
        options: dict[str, Any] = {}
        if "options" in d:
            opts = ctx.mapping(d["options"], f"{what}.options", d.lines.get("options", d.line))
            options = {
                str(k): _plain(v, ctx, f"{what}.options.{k}", opts.lines.get(k))
                for k, v in opts.items()
            }
        target = None
        problems: tuple[str, ...] = ("mapf",)
        if "target" in d:
            target = ctx.string(d["target"], f"{what}.target", d.lines.get("target"))
            if ":" not in target:
                raise ctx.error(
                    f"{what}.target must be 'package.module:function', got {target!r}",
                    d.lines.get("target"),
                )
            if "problems" in d:
                seqp = ctx.sequence(d["problems"], f"{what}.problems", d.lines.get("problems"))
                problems = tuple(str(p).lower() for p in seqp)
                if not problems or not set(problems) <= {"mapf", "tapf"}:
                    raise ctx.error(
                        f"{what}.problems must list mapf and/or tapf", d.lines.get("problems")
                    )
        else:
            if "problems" in d:
                raise ctx.error(
                    f"{what}.problems is only for a solver given by 'target'",
                    d.key_lines.get("problems"),
                )
            try:
                info = registry.get(name)
            except InputError as exc:
                raise ctx.error(f"{what}.name: {exc}", d.lines.get("name", d.line)) from None
            try:  # names and values, before any run (the solver's declared options)
                info.check_options(options)
            except InputError as exc:
                raise ctx.error(f"{what}.options: {exc}", d.lines.get("options", d.line)) from None
            problems = tuple(sorted(info.problems))
        obj = objective
        if "objective" in d:
            obj = _objective(ctx, d["objective"], f"{what}.objective", d.lines.get("objective"))
        if obj is not None and target is None and obj not in registry.get(name).objectives:
            raise ctx.error(
                f"{what}: solver {name!r} does not optimise {obj!r} (it does: "
                f"{', '.join(sorted(registry.get(name).objectives))})",
                d.lines.get("objective", d.line),
            )
        tl = None
        if "time_limit" in d:
            tl = ctx.number(d["time_limit"], f"{what}.time_limit", d.lines.get("time_limit"),
                            positive=True)  # fmt: skip
            _check_time_limit(ctx, tl, f"{what}.time_limit", d.lines.get("time_limit"))
        label = default_label(name, options)
        if "label" in d:
            label = ctx.string(d["label"], f"{what}.label", d.lines.get("label"))
        if label in labels:
            raise ctx.error(
                f"{what}: label {label!r} is already used by another solver entry "
                f"(line {labels[label]}); give one of them a 'label'",
                d.line,
            )
        labels[label] = d.line
        out.append(SolverSpec(name, label, options, obj, tl, target, problems))
    return tuple(out)


def _instances(ctx: Ctx, value: Any, line: int | None, folder: Path) -> tuple[InstanceSpec, ...]:

    seq = ctx.sequence(value, "instances", line)
    if not seq:
        raise ctx.error("instances must list at least one instance", line)
    out: list[InstanceSpec] = []
    for i, item in enumerate(seq):
        what = f"instances[{i}]"
        d = ctx.mapping(item, what, ctx.line_of(seq, i))
        ctx.check_keys(d, what, INSTANCE_KEYS)
        kinds = [k for k in ("map", "yaml", "generator") if k in d]
        if len(kinds) != 1:
            raise ctx.error(
                f"{what} needs exactly one of 'map' (with 'scen'), 'yaml' or 'generator'", d.line
            )
        agents = None
        if "agents" in d:
            agents = _agents(ctx, d["agents"], f"{what}.agents", d.lines.get("agents"))
        name = None
        if "name" in d:
            name = ctx.string(d["name"], f"{what}.name", d.lines.get("name"))
        kind = kinds[0]
        if kind == "generator":
            gen = ctx.string(d["generator"], f"{what}.generator", d.lines.get("generator"))
            if gen not in GENERATORS:
                raise ctx.error(
                    f"{what}.generator: unknown generator {gen!r} "
                    f"(known: {', '.join(sorted(GENERATORS))})",
                    d.lines.get("generator"),
                )
            params: dict[str, Any] = {}
            if "params" in d:
                pd = ctx.mapping(d["params"], f"{what}.params", d.lines.get("params"))
                params = {
                    str(k): _plain(v, ctx, f"{what}.params.{k}", pd.lines.get(k))
                    for k, v in pd.items()
                }
            try:
                GENERATORS[gen].check(params)
            except InputError as exc:
                raise ctx.error(f"{what}.params: {exc}", d.lines.get("params", d.line)) from None
            out.append(
                InstanceSpec(
                    "generator",
                    name or default_label(gen, params),
                    generator=gen,
                    params=params,
                    agents=agents,
                )
            )
            continue
        if "params" in d:
            raise ctx.error(f"{what}.params is only for a generator", d.key_lines.get("params"))
        if kind == "map":
            if "scen" not in d:
                raise ctx.error(f"{what}: a MovingAI 'map' needs a 'scen'", d.line)
            mp = _files(ctx, folder, d["map"], f"{what}.map", d.lines.get("map"), single=True)[0]
            scens = _files(ctx, folder, d["scen"], f"{what}.scen", d.lines.get("scen"))
            for s in scens:
                nm = name if name and len(scens) == 1 else s.stem
                out.append(InstanceSpec("movingai", nm, (mp, s), agents=agents))
        else:
            if "scen" in d:
                raise ctx.error(f"{what}: 'scen' goes with 'map', not 'yaml'", d.key_lines["scen"])
            ys = _files(ctx, folder, d["yaml"], f"{what}.yaml", d.lines.get("yaml"))
            for y in ys:
                nm = name if name and len(ys) == 1 else y.stem
                out.append(InstanceSpec("yaml", nm, (y,), agents=agents))
    names = [inst.name for inst in out]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise ctx.error(f"instances: two instances are named {dup!r}; give them a 'name'", line)
    return tuple(out)


def _files(
    ctx: Ctx, folder: Path, value: Any, what: str, line: int | None, *, single: bool = False
) -> list[Path]:
    text = ctx.string(value, what, line)
    if text.startswith("$instances"):
        text = str(instances_dir()) + text[len("$instances") :]
    pattern = Path(text) if Path(text).is_absolute() else folder / text
    if glob.has_magic(text):
        found = sorted(Path(p) for p in glob.glob(str(pattern)))
        if not found:
            raise ctx.error(f"{what}: no file matches {text!r} (in {folder})", line)
        if single and len(found) > 1:
            raise ctx.error(f"{what}: {text!r} matches {len(found)} files, expected one", line)
    else:
        found = [pattern]
    for p in found:
        if not p.is_file():
            raise ctx.error(f"{what}: no such file: {p}", line)
    return found


def _plain(value: Any, ctx: Ctx, what: str, line: int | None) -> Any:
    """A spec's option or parameter values as plain data (:func:`~hierplan_opt.io.values.plain`);
    a non-finite number is refused (plain would make it null, which means "default")."""
    out = plain(value)
    if not _same_finite(value, out):
        raise ctx.error(f"{what}: a value is not a finite number ({value!r})", line)
    return out


def _same_finite(value: Any, out: Any) -> bool:
    if isinstance(value, float):
        return out is not None
    if isinstance(value, dict):
        return all(_same_finite(v, out[str(k)]) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return all(_same_finite(v, o) for v, o in zip(value, out, strict=True))
    return True


__all__ = ["InstanceSpec", "SolverSpec", "SweepSpec", "default_label", "load_spec", "parse_spec"]
