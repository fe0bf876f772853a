"""A corpus of hostile and malformed inputs for every command that reads or writes files.

Each :class:`Case` names a *slot* (what the file is to the command: instance, map,
scenario, plan, schedule, or an output path), a *hazard* (what is wrong with it) and a
command; :func:`build` writes the files of a case into a folder and returns the
``hierplan`` arguments and the outputs that must not appear. The tests in
``test_bad_inputs.py`` expect: exit code 2, one line on stderr that starts with
``hierplan <command>: error:``, nothing on stdout, no traceback, no output written,
and no hang (a timeout) or signal.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import yaml
from io_helpers import DATA, MOVINGAI

GOOD_INSTANCE = DATA / "corridor_lmrp.yaml"
GOOD_MAP = MOVINGAI / "empty-8-8.map"
GOOD_SCEN = MOVINGAI / "empty-8-8-even-1.scen"

#: A valid plan of the corridor instance (agent1 steps aside into (2, 1)).
GOOD_PLAN = """\
schedule:
  agent0:
    - {x: 0, y: 0, t: 0}
    - {x: 1, y: 0, t: 1}
    - {x: 2, y: 0, t: 2}
    - {x: 3, y: 0, t: 3}
    - {x: 4, y: 0, t: 4}
  agent1:
    - {x: 1, y: 0, t: 0}
    - {x: 2, y: 0, t: 1}
    - {x: 2, y: 1, t: 2}
    - {x: 2, y: 0, t: 3}
    - {x: 3, y: 0, t: 4}
"""

GOOD_SCHEDULE = """\
statistics: {makespan: 4.0}
schedule:
  agent0: [{x: 0, y: 0, theta: 0.0, arrival: 0.0}, {x: 4, y: 0, theta: 0.0, arrival: 4.0}]
  agent1: [{x: 1, y: 0, theta: 0.0, arrival: 0.0}, {x: 3, y: 0, theta: 0.0, arrival: 4.0}]
"""

Writer = Callable[[Path], None]


def _text(s: str) -> Writer:
    return lambda p: p.write_text(s, encoding="utf-8")


def _bytes(b: bytes) -> Writer:
    return lambda p: p.write_bytes(b)


def _symlink(target: str) -> Writer:
    return lambda p: p.symlink_to(target)


def _fifo(p: Path) -> None:
    os.mkfifo(p)


def _dir(p: Path) -> None:
    p.mkdir()


def _missing(p: Path) -> None:
    pass


def _deep_flow(n: int) -> Writer:
    return _text("a: " + "[" * n + "]" * n + "\n")


def _deep_block(n: int) -> Writer:
    return _text("".join(" " * i + "-\n" for i in range(n)))


def _alias_bomb(p: Path) -> None:
    lines = ['bomb: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, 10):
        lines.append(f"b{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _map_ref_fifo(p: Path) -> None:
    os.mkfifo(p.parent / "ref.map")
    p.write_text("graph: {map: ref.map}\nagents: [{start: [0, 0], goal: [1, 0]}]\n")


def _name_bomb(p: Path) -> None:
    """An alias bomb in an agent's name (the issue's case)."""
    lines = ["map:", "  dimensions: [5, 2]", "  obstacles: &o0 [[0, 1], [1, 1], [3, 1], [4, 1]]"]
    lines.append("x: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]")
    for i in range(1, 9):
        lines.append(f"y{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    # put the bomb where a name goes (keys x, y1.. are unknown too; the bomb comes first)
    text = p.read_text()
    text = text.replace("x: &a0", "agents:\n  - name: &a0")
    p.write_text(text, encoding="utf-8")


def _name_bomb_lmrp(p: Path) -> None:
    head = ["bombs:", "  - &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, 9):
        head.append(f"  - &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    body = [
        "map: {dimensions: [5, 2]}",
        "agents:",
        "  - {name: *a8, start: [0, 0], goal: [4, 0]}",
    ]
    p.write_text("\n".join(head + body) + "\n", encoding="utf-8")


COMMON: dict[str, Writer] = {
    "missing": _missing,
    "directory": _dir,
    "fifo": _fifo,
    "dev-zero": _symlink("/dev/zero"),
    "dev-urandom": _symlink("/dev/urandom"),
    "dev-null": _symlink("/dev/null"),
    "empty": _text(""),
    "nul-bytes": _bytes(b"map:\x00\x00\x00\n"),
    "bad-utf8": _bytes(b"map: \xff\xfe\xfa\n"),
    "oversize": _text("# padding\n" * 400),  # 4 KB; the case runs with a 1 KB limit
    "deep-flow-100000": _deep_flow(100000),
    "deep-flow-100": _deep_flow(100),
    "deep-block-200": _deep_block(200),
    "alias-bomb": _alias_bomb,
    "recursive-alias": _text("a: &x [1, *x]\n"),
    "garbage": _text("}{ ][ :: -- !! %% @@\n"),
    "long-line": _text("a" * 200_000 + "\n"),
    "top-level-list": _text("- 1\n- 2\n"),
    "scalar": _text("42\n"),
}

INSTANCE: dict[str, Writer] = {
    "dims-1e30": _text(
        "map: {dimensions: [1000000000000000000000000000000, 1]}\n"
        "agents: [{start: [0, 0], goal: [1, 0]}]\n"
    ),
    "dims-2e63": _text(
        "graph: {dimensions: [9223372036854775808, 1]}\nagents: [{start: [0, 0], goal: [1, 0]}]\n"
    ),
    "dims-terabytes": _text(
        "graph: {dimensions: [1000000, 1000000]}\nagents: [{start: [0, 0], goal: [1, 0]}]\n"
    ),
    "dims-3d-huge": _text(
        "graph: {dimensions: [100000, 100000, 100000]}\n"
        "agents: [{start: [0, 0, 0], goal: [1, 0, 0]}]\n"
    ),
    "dims-float-inf": _text(
        "graph: {dimensions: [.inf, 1]}\nagents: [{start: [0, 0], goal: [0, 0]}]\n"
    ),
    "dims-negative": _text("map: {dimensions: [-5, 2]}\nagents: [{start: [0, 0], goal: [1, 0]}]\n"),
    "dims-string": _text("map: {dimensions: [a, b]}\nagents: [{start: [0, 0], goal: [1, 0]}]\n"),
    "rows-over-cell-limit": _text(  # the case runs with --max-grid-cells 1000
        "graph: {rows: " + json.dumps(["." * 40] * 40) + "}\n"
        "agents: [{start: [0, 0], goal: [1, 0]}]\n"
    ),
    "name-alias-bomb": _name_bomb,
    "name-alias-bomb-lmrp": _name_bomb_lmrp,
    "start-outside": _text("map: {dimensions: [3, 1]}\nagents: [{start: [7, 0], goal: [1, 0]}]\n"),
    "start-huge": _text(
        "map: {dimensions: [3, 1]}\n"
        "agents: [{start: [100000000000000000000000, 0], goal: [1, 0]}]\n"
    ),
    "start-on-obstacle": _text(
        "map: {dimensions: [3, 1], obstacles: [[0, 0]]}\nagents: [{start: [0, 0], goal: [1, 0]}]\n"
    ),
    "duplicate-key": _text("map: {dimensions: [3, 1]}\nmap: {dimensions: [3, 1]}\nagents: []\n"),
    "unknown-key": _text("map: {dimensions: [3, 1]}\nagents: []\nextra: 1\n"),
    "no-agents": _text("map: {dimensions: [3, 1]}\nagents: []\n"),
    "yaml-syntax": _text("map: {dimensions: [3, 1]\nagents: [\n"),
    "json-syntax.json": _text('{"map": {"dimensions": [3, 1]}, "agents": [}\n'),
    "json-deep.json": _text("[" * 100000 + "]" * 100000),
    "map-ref-fifo": lambda p: _map_ref_fifo(p),
    "map-ref-dev-zero": _text("graph: {map: /dev/zero}\nagents: [{start: [0, 0], goal: [1, 0]}]\n"),
    "roadmap-conflicts": _text(
        "roadmap: {undirected: false, allow_wait_actions: false, edges: [[A, B]], "
        "conflicts: [[]]}\nagents: [{name: a, start: A, goal: B}]\n"
    ),
    "roadmap-no-waits": _text(
        "roadmap: {undirected: true, allow_wait_actions: false, edges: [[A, B]]}\n"
        "agents: [{name: a, start: A, goal: B}]\n"
    ),
    "roadmap-unknown-vertex": _text(
        "roadmap: {vertices: {A: [0, 0]}, edges: [[A, Z]]}\n"
        "agents: [{name: a, start: A, goal: A}]\n"
    ),
    "roadmap-nan": _text(
        "graph: {type: roadmap, vertices: {A: [.nan, 0], B: [1, 0]}, edges: [[A, B]]}\n"
        "agents: [{start: A, goal: B}]\n"
    ),
    "potential-goals-overlap": _text(
        "map: {dimensions: [4, 1]}\nagents:\n"
        "  - {name: a, start: [0, 0], potentialGoals: [[2, 0], [3, 0]]}\n"
        "  - {name: b, start: [1, 0], potentialGoals: [[3, 0]]}\n"
    ),
    "teams-count-mismatch": _text(
        "graph: {dimensions: [4, 1]}\n"
        "teams: [{agents: [{start: [0, 0]}], targets: [[2, 0], [3, 0]]}]\n"
    ),
    "format-tag": _text(
        "format: hierplan/9\ngraph: {dimensions: [3, 1]}\nagents: [{start: [0, 0], goal: [1, 0]}]\n"
    ),
}

MAP: dict[str, Writer] = {
    "height-1e30": _text("type octile\nheight 1000000000000000000000000000000\nwidth 1\nmap\n.\n"),
    "width-2e63": _text("type octile\nheight 1\nwidth 9223372036854775808\nmap\n.\n"),
    "header-terabytes": _text("type octile\nheight 1000000\nwidth 1000000\nmap\n"),
    "negative-height": _text("type octile\nheight -8\nwidth 8\nmap\n"),
    "no-header": _text("........\n" * 8),
    "bad-char": _text("type octile\nheight 1\nwidth 3\nmap\n.X.\n"),
    "row-count": _text("type octile\nheight 3\nwidth 3\nmap\n...\n"),
    "row-length": _text("type octile\nheight 1\nwidth 3\nmap\n.....\n"),
    "truncated": _text("type octile\nheight 8\n"),
}

SCEN: dict[str, Writer] = {
    "version": _text("version 9\n0\tempty-8-8.map\t8\t8\t0\t0\t1\t0\t1\n"),
    "fields": _text("version 1\n0\tempty-8-8.map\t8\t8\t0\t0\n"),
    "non-integer": _text("version 1\n0\tempty-8-8.map\t8\t8\ta\t0\t1\t0\t1\n"),
    "coords-1e30": _text(
        "version 1\n0\tempty-8-8.map\t8\t8\t1000000000000000000000000000000\t0\t1\t0\t1\n"
    ),
    "negative": _text("version 1\n0\tempty-8-8.map\t8\t8\t-1\t0\t1\t0\t1\n"),
    "other-map": _text("version 1\n0\tempty-16-16.map\t8\t8\t0\t0\t1\t0\t1\n"),
    "size-mismatch": _text("version 1\n0\tempty-8-8.map\t16\t16\t0\t0\t1\t0\t1\n"),
    "nan-length": _text("version 1\n0\tempty-8-8.map\t8\t8\t0\t0\t1\t0\tnan\n"),
    "no-agents": _text("version 1\n"),
    "duplicate-start": _text(
        "version 1\n0\tempty-8-8.map\t8\t8\t0\t0\t1\t0\t1\n0\tempty-8-8.map\t8\t8\t0\t0\t2\t0\t2\n"
    ),
}

PLAN: dict[str, Writer] = {
    "unknown-agent": _text(GOOD_PLAN + "  ghost:\n    - {x: 0, y: 0, t: 0}\n"),
    "missing-agent": _text(GOOD_PLAN.split("  agent1:")[0]),
    "time-gap": _text(GOOD_PLAN.replace("t: 3}", "t: 7}", 1)),
    "outside": _text(GOOD_PLAN.replace("{x: 4, y: 0, t: 4}", "{x: 40, y: 0, t: 4}")),
    "coord-1e30": _text(
        GOOD_PLAN.replace("{x: 4, y: 0, t: 4}", "{x: 1000000000000000000000000000000, y: 0, t: 4}")
    ),
    "coord-string": _text(GOOD_PLAN.replace("{x: 4, y: 0, t: 4}", "{x: four, y: 0, t: 4}")),
    "no-schedule": _text("statistics: {cost: 1}\n"),
    "json-deep.json": _text('{"schedule": ' + "[" * 100000 + "]" * 100000 + "}"),
    "eecbs-agent-huge": _text("Agent 100000000000000000000: (0,0)->\n"),
    "eecbs-bad-cell": _text("Agent 0: (0,0)->(zero,1)->\nAgent 1: (0,1)->\n"),
    "eecbs-missing-agent": _text("Agent 0: (0,0)->(0,1)->\n"),
    "eecbs-outside": _text("Agent 0: (0,0)->(0,99)->\nAgent 1: (0,1)->\n"),
    "eecbs-duplicate": _text("Agent 0: (0,0)->\nAgent 0: (0,0)->\nAgent 1: (0,1)->\n"),
    "lacam-unsolved": _text("agents=2\nsolved=0\nsolution=\n"),
    "lacam-agents": _text("agents=7\nsolved=1\nsolution=\n0:(0,0),(1,0),\n"),
    "lacam-gap": _text("agents=2\nsolution=\n0:(0,0),(1,0),\n5:(1,0),(2,0),\n"),
    "lacam-count": _text("agents=2\nsolution=\n0:(0,0),\n"),
    "lacam-outside": _text("agents=2\nsolution=\n0:(0,0),(1000000000000,0),\n"),
    "lacam-no-solution": _text("agents=2\nsolved=1\n"),
    "tracker-rle-bomb": _text(
        'map_name,scen_type,type_id,agents,solution_plan\nc,even,1,2,"999999999999999w\nw"\n'
    ),
    "tracker-letter": _text(
        'map_name,scen_type,type_id,agents,solution_plan\nc,even,1,2,"rx\nw"\n'
    ),
    "tracker-leaves-map": _text(
        'map_name,scen_type,type_id,agents,solution_plan\nc,even,1,2,"9l\nw"\n'
    ),
    "tracker-agents": _text("map_name,scen_type,type_id,agents,solution_plan\nc,even,1,5,r\n"),
    "tracker-strings": _text("map_name,scen_type,type_id,agents,solution_plan\nc,even,1,2,r\n"),
    "tracker-json-list": _text('[1, 2, {"solution_plan": "r"}]\n'),
    "tracker-yaml-zero-run": _text(
        "map_name: c\nscen_type: even\ntype_id: 1\nagents: 2\nsolution_plan: [0r, w]\n"
    ),
}

SCHEDULE: dict[str, Writer] = {
    "no-schedule-key": _text("statistics: {makespan: 1}\n"),
    "waypoint-no-arrival": _text("schedule:\n  agent0: [{x: 0, y: 0}]\n"),
    "waypoint-string": _text("schedule:\n  agent0: [{x: zero, y: 0, arrival: 0.0}]\n"),
    "unknown-agent": _text("schedule:\n  ghost: [{x: 0, y: 0, arrival: 0.0}]\n"),
    "json-deep.json": _text("[" * 100000 + "]" * 100000),
}

#: Output paths that must be refused before any work.
OUTPUTS: dict[str, Callable[[Path], str]] = {
    "missing-folder": lambda d: str(d / "no" / "such" / "folder" / "{name}"),
    "parent-is-file": lambda d: (d / "afile").write_text("x") and str(d / "afile" / "{name}"),
    "dev-full": lambda d: "/dev/full",
    "empty": lambda d: "",
    "is-directory": lambda d: (d / "adir").mkdir() or str(d / "adir"),
    "bad-extension": lambda d: str(d / "out.unsupported"),
}

#: Commands that read each input slot.
READERS = {
    "instance": ("info", "solve", "validate", "verify", "post", "convert"),
    "map": ("info", "solve", "validate", "verify", "post", "convert"),
    "scen": ("info", "solve", "validate", "verify", "post", "convert"),
    "plan": ("validate", "verify", "post", "convert"),
    "schedule": ("convert",),
}

#: (command, option) pairs that write files.
WRITERS = (
    ("solve", "--out"),
    ("post", "--out"),
    ("post", "--dot"),
    ("post", "--gantt"),
    ("convert", "--out"),
)

#: Hazards that could crash the process (a signal) if a guard broke: run them in a
#: subprocess, never in the test process.
SUBPROCESS_ONLY = ("deep-flow-100000", "json-deep")


#: Extra arguments of some hazards (small limits instead of large files).
LIMITS = {
    "oversize": ["--max-input-mb", "0.001"],
    "rows-over-cell-limit": ["--max-grid-cells", "1000"],
}


@dataclass(frozen=True)
class Case:
    slot: str  # instance, map, scen, plan, schedule or output
    hazard: str
    command: str
    option: str = ""  # the output option of an output case
    sample: bool = False  # in the fast sample (every hazard of every slot once)

    @property
    def id(self) -> str:
        opt = self.option.lstrip("-")
        return "-".join(x for x in (self.slot, self.hazard, self.command, opt) if x)

    @property
    def in_subprocess(self) -> bool:
        return any(self.hazard.startswith(h) for h in SUBPROCESS_ONLY)


def cases() -> list[Case]:
    """Every case of the corpus."""
    out: list[Case] = []
    slots = {
        "instance": {**COMMON, **INSTANCE},
        "map": {**COMMON, **MAP},
        "scen": {**COMMON, **SCEN},
        "plan": {**COMMON, **PLAN},
        "schedule": {**COMMON, **SCHEDULE},
    }
    for slot, hazards in slots.items():
        for i, hazard in enumerate(hazards):
            commands = READERS[slot]
            for command in commands:
                out.append(
                    Case(slot, hazard, command, sample=command == commands[i % len(commands)])
                )
    for hazard in OUTPUTS:
        for command, option in WRITERS:
            out.append(Case("output", hazard, command, option, sample=True))
    return out


def _suffix(case: Case) -> str:
    if case.hazard.endswith(".json"):
        return ".json"
    return {
        "instance": ".yaml",
        "map": ".map",
        "scen": ".scen",
        "plan": ".yaml",
        "schedule": ".yaml",
        "output": ".yaml",
    }[case.slot]


def build(case: Case, d: Path) -> tuple[list[str], list[Path]]:
    """Write the files of ``case`` into ``d``; return the argv and outputs to watch."""
    slots = {
        "instance": {**COMMON, **INSTANCE},
        "map": {**COMMON, **MAP},
        "scen": {**COMMON, **SCEN},
        "plan": {**COMMON, **PLAN},
        "schedule": {**COMMON, **SCHEDULE},
    }
    plan = d / "good_plan.yaml"
    plan.write_text(GOOD_PLAN)
    schedule = d / "good_schedule.yaml"
    schedule.write_text(GOOD_SCHEDULE)
    outs = {
        "--out": d / "out.yaml",
        "--dot": d / "out.dot",
        "--gantt": d / "out.png",
    }
    bad = d / f"bad{_suffix(case)}"
    if case.slot != "output":
        slots[case.slot][case.hazard](bad)
    instance = [str(GOOD_INSTANCE)]
    if case.slot == "instance":
        instance = [str(bad)]
    elif case.slot == "map":
        instance = [str(bad), "--scen", str(GOOD_SCEN), "--agents", "2"]
    elif case.slot == "scen":
        instance = [str(GOOD_MAP), "--scen", str(bad)]
    if case.slot in ("map", "scen"):
        # a plan for the empty-8-8 instance is not needed: the instance fails first
        pass
    plan_arg = str(bad) if case.slot == "plan" else str(plan)
    if case.slot == "output":
        target = OUTPUTS[case.hazard](d)
        suffix = {"--out": ".yaml", "--dot": ".dot", "--gantt": ".png"}[case.option]
        if case.command == "convert":
            suffix = ".txt" if case.hazard != "bad-extension" else ".xyz"
        target = target.replace("{name}", f"x{suffix}")
        outs[case.option] = Path(target) if target else d / "never"
    limit = LIMITS.get(case.hazard, [])
    cmd = case.command
    if cmd == "info":
        argv = ["info", *instance, *limit]
    elif cmd == "solve":
        argv = ["solve", *instance, "--time-limit", "20", "--out", str(outs["--out"]), *limit]
        if case.slot == "output" and case.option == "--out" and case.hazard == "empty":
            argv[argv.index("--out") + 1] = ""
    elif cmd == "validate":
        argv = ["validate", *instance, plan_arg, *limit]
    elif cmd == "verify":
        argv = ["verify", *instance, plan_arg, "--time-limit", "20", *limit]
    elif cmd == "post":
        argv = ["post", *instance, plan_arg, "--out", str(outs["--out"]), *limit]
        if case.slot == "output":
            if case.option != "--out":
                argv += [case.option, str(outs[case.option])]
            if case.hazard == "empty":
                argv[argv.index(case.option) + 1] = ""
    elif cmd == "convert":
        out = outs["--out"]
        if case.slot == "schedule":
            argv = ["convert", *instance, "--schedule", str(bad), "--out", str(out), *limit]
        elif case.slot == "output":
            argv = ["convert", *instance, "--plan", plan_arg, "--to", "eecbs"]
            if case.hazard == "bad-extension":
                argv[-1] = "tracker"
            argv += ["--out", "" if case.hazard == "empty" else str(out), *limit]
        else:
            argv = ["convert", *instance, "--plan", plan_arg, "--to", "json"]
            argv += ["--out", str(d / "out.json"), *limit]
            outs["--json"] = d / "out.json"
    else:  # pragma: no cover - a new command needs a branch here
        raise AssertionError(cmd)
    watch = [p for p in outs.values() if str(p).startswith(str(d))]
    return argv, watch


def describe() -> str:
    """A one-line summary of the corpus size per slot (for reports)."""
    counts: dict[str, int] = {}
    for c in cases():
        counts[c.slot] = counts.get(c.slot, 0) + 1
    return ", ".join(f"{k}: {v}" for k, v in counts.items()) + f"; total {sum(counts.values())}"


if __name__ == "__main__":  # pragma: no cover
    print(describe())
    print(yaml.safe_dump([c.id for c in cases()][:5]))
