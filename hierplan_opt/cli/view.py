"""``hierplan view``: one self-contained HTML page that plays a plan, a schedule, refined
trajectories, an execution report or a lifelong (LoRR) log in a browser."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from hierplan_opt.cli.common import (
    OK,
    add_instance_arguments,
    check_outputs,
    load_instance_from_args,
    positive_int,
)
from hierplan_opt.core.errors import InputError

HELP = (
    "write an interactive HTML viewer (one file, opens from disk) of a plan, schedule, "
    "trajectories (.npz), execution report or LoRR lifelong log (.json)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument(
        "file",
        metavar="FILE",
        help="plan or schedule (hierplan solve/post), trajectories .npz (hierplan refine), "
        "execution report (hierplan simulate/run --out) or LoRR output JSON (actualPaths; "
        "INSTANCE is then the .map)",
    )
    p.add_argument("--out", required=True, metavar="HTML", help="the page to write (.html)")
    p.add_argument("--title", metavar="TEXT", help="title shown on the page")
    p.add_argument(
        "--agent-counter",
        type=positive_int,
        metavar="K",
        help="LoRR 3.x logs: ticks per action (the problem's agentCounter; default: the "
        "log's, else 1)",
    )


def _kind(path: str) -> tuple[str, Any]:
    """(kind, parsed data); kind: trajectories, lorr, report, schedule or plan."""
    from hierplan_opt.io.yaml import read_yaml
    from hierplan_opt.viz.scene import is_lorr

    if Path(path).suffix.lower() == ".npz":
        return "trajectories", None
    if Path(path).suffix.lower() == ".json":
        import json

        from hierplan_opt.io.files import read_text

        try:
            data = json.loads(read_text(path))
        except json.JSONDecodeError as exc:
            raise InputError(f"{path}: not JSON ({exc.msg}, line {exc.lineno})") from None
        if is_lorr(data):
            return "lorr", data
        return "plan", data
    try:
        data = read_yaml(path)
    except Exception:  # not YAML: a plan in another format (EECBS, LaCAM, tracker text)
        return "plan", None
    if isinstance(data, dict) and isinstance(data.get("schedule"), dict):
        rows = data["schedule"]
        first = next(iter(rows.values()), None) if rows else None
        if (
            isinstance(first, list)
            and first
            and isinstance(first[0], dict)
            and "arrival" in first[0]
        ):
            return ("report" if "events" in data else "schedule"), data
    return "plan", data


def build_scene(args: argparse.Namespace) -> Any:
    """The :class:`~hierplan_opt.viz.scene.Scene` of ``args.file``."""
    from hierplan_opt.viz import scene as sc

    kind, data = _kind(args.file)
    title = args.title or ""
    if kind == "lorr":
        if Path(args.instance).suffix.lower() == ".map" and not args.scen:
            from hierplan_opt.io.movingai import load_map

            graph = load_map(args.instance)
        else:
            graph = load_instance_from_args(args).graph
        return sc.scene_from_lorr(graph, args.file, data, title, args.agent_counter)
    instance = load_instance_from_args(args)
    if kind == "trajectories":
        from hierplan_opt.trajectory.result import read_trajectories

        return sc.scene_from_trajectories(instance, read_trajectories(args.file), title)
    if kind == "report":
        return sc.scene_from_report(instance, args.file, data, title)
    if kind == "schedule":
        from hierplan_opt.cli.simulate import load_plan_or_schedule

        ns = argparse.Namespace(plan=args.file, margin=None)
        try:  # re-derive the STN for the slack of every way-point
            schedule, _ = load_plan_or_schedule(ns, instance)
            scene = sc.scene_from_schedule(instance, schedule, title)
            keys = sc.scene_from_schedule_file(instance, args.file, data).keys or []
            scene.keys = keys
            if [len(k) for k in keys] != [len(s) for s in scene.slack or []]:
                scene.slack = None
            return scene
        except InputError:  # not re-derivable: the file's way-points without slack
            return sc.scene_from_schedule_file(instance, args.file, data, title)
    from hierplan_opt.io import load_plan

    return sc.scene_from_plan(instance, load_plan(args.file, instance), title)


def run(args: argparse.Namespace) -> int:
    import time

    from hierplan_opt.core.progress import Progress, reporting
    from hierplan_opt.viz.html import write_view

    check_outputs(("--out", args.out, (".html", ".htm")))
    t0 = time.perf_counter()
    show = None if not args.quiet else False  # a bar on a terminal, else status lines
    scene = build_scene(args)  # bad input: one line, before any progress line
    with reporting(Progress("view", enabled=show, interval=2.0)):
        path = write_view(scene, args.out)
    size = path.stat().st_size / 1e6
    print(
        f"view -> {args.out} ({scene.source}, {scene.num_agents} robots, {scene.end:.4g} s, "
        f"{size:.2f} MB, {time.perf_counter() - t0:.2f} s)"
    )
    return OK
