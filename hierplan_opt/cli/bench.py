"""``hierplan bench AREA [ARGS...]``: run a benchmark and print its table."""

from __future__ import annotations

import argparse
import importlib

from hierplan_opt.bench import AREAS

HELP = "run a benchmark and print a table (areas: " + ", ".join(AREAS) + ")"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("area", choices=sorted(AREAS), help="which benchmark")
    p.add_argument(
        "args", nargs=argparse.REMAINDER, help="options of that benchmark (see AREA --help)"
    )


def run(args: argparse.Namespace) -> int:
    mod = importlib.import_module(f"hierplan_opt.bench.{args.area}")
    return int(mod.main(list(args.args)))
