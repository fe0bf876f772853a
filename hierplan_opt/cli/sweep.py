"""``hierplan sweep``: run a sweep spec, resume it, report on it, export it.

::

    hierplan sweep SPEC.yaml [--db FILE] [--workers N] [--dask local | --dask-scheduler ADDR]
    hierplan sweep --canned NAME [--instances-dir DIR] [--db FILE] ...   |  --list-canned
    hierplan sweep --resume --db FILE      (or: hierplan sweep FILE.sqlite --resume)
    hierplan sweep report DB [--plots DIR] [--stats KEY,...]
    hierplan sweep export DB OUT.csv|OUT.parquet
"""

from __future__ import annotations

import argparse
import os
from dataclasses import replace
from pathlib import Path

from hierplan_opt.cli.common import OK, check_outputs, positive_int
from hierplan_opt.core.errors import InputError

HELP = "run solvers x instances x agents x seeds, one process per run, into SQLite"

USAGE = """\
hierplan sweep SPEC.yaml [--db FILE] [--workers N] [--dask local | --dask-scheduler ADDR]
       hierplan sweep --canned NAME [--instances-dir DIR] [options]  |  --list-canned
       hierplan sweep --resume --db FILE
       hierplan sweep report DB [--plots DIR] [--stats KEY,...]
       hierplan sweep export DB OUT.csv|OUT.parquet"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.usage = USAGE
    p.add_argument(
        "what",
        nargs="?",
        metavar="SPEC|report|export",
        help="a sweep spec (YAML), a sweep database to continue, or the verb report/export",
    )
    p.add_argument("paths", nargs="*", metavar="FILE", help="DB (report), DB OUT (export)")
    p.add_argument("--db", metavar="FILE", help="SQLite file for the runs (default: the spec's db)")
    p.add_argument("--workers", type=positive_int, metavar="N", help="runs at the same time")
    cluster = p.add_mutually_exclusive_group()
    cluster.add_argument(
        "--dask", choices=["local"], help="run on a new Dask LocalCluster (--workers workers)"
    )
    cluster.add_argument(
        "--dask-scheduler", metavar="tcp://HOST:PORT", help="run on a running Dask cluster"
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the latest sweep recorded in --db (SPEC may be omitted); finished "
        "runs are never repeated",
    )
    p.add_argument("--canned", metavar="NAME", help="a canned spec (see --list-canned)")
    p.add_argument("--list-canned", action="store_true", help="list the canned specs")
    p.add_argument(
        "--instances-dir",
        metavar="DIR",
        help="folder of benchmark instances for $instances in specs (default: the package's)",
    )
    p.add_argument("--dry-run", action="store_true", help="only count the runs to do")
    p.add_argument("--no-progress", action="store_true", help="no progress bar or status lines")
    p.add_argument(
        "--plots", metavar="DIR", help="report: write success_rate.png, runtime.png, cactus.png"
    )
    p.add_argument(
        "--stats",
        metavar="KEY,...",
        help="report: also the median of these run statistics (node counts, stage sizes "
        "and times, e.g. high_level_expanded or post_stn_arcs) by solver and agents",
    )


def run(args: argparse.Namespace) -> int:
    if args.instances_dir:
        from hierplan_opt.experiments.data import ENV

        if not Path(args.instances_dir).is_dir():
            raise InputError(f"--instances-dir {args.instances_dir}: no such folder")
        os.environ[ENV] = str(Path(args.instances_dir).resolve())
    if args.what == "report":
        return _report(args)
    if args.what == "export":
        return _export(args)
    if args.paths:
        raise InputError(f"unexpected argument {args.paths[0]!r} after the spec")
    if args.list_canned:
        from hierplan_opt.experiments.data import canned_specs

        for name, text in canned_specs().items():
            print(f"{name:16} {text}")
        return OK
    return _sweep(args)


def _sweep(args: argparse.Namespace) -> int:
    from hierplan_opt.experiments import store
    from hierplan_opt.experiments.data import canned_spec
    from hierplan_opt.experiments.sweeps import (
        check_instances,
        plan_runs,
        resolve,
        spec_from_db,
        sweep,
    )

    sources = [x for x in (args.what, args.canned) if x]
    if len(sources) > 1:
        raise InputError("give either a SPEC or --canned NAME, not both")
    if args.resume and not sources:
        if not args.db:
            raise InputError("--resume needs the database: --db FILE (or a SPEC)")
        spec = spec_from_db(args.db)
    elif not sources:
        raise InputError("give a sweep SPEC.yaml, --canned NAME, or --resume --db FILE")
    elif args.canned:
        spec = resolve(canned_spec(args.canned))
        # a canned spec's database goes to the working directory, not into the package
        spec = replace(spec, db=Path(spec.db.name))
    else:
        spec = resolve(args.what)
    if args.db:
        spec = replace(spec, db=Path(args.db))
    if args.resume:
        con = store.open_existing(spec.db)
        last = store.last_sweep(con)
        con.close()
        if last is None:
            raise InputError(f"{spec.db}: no sweep recorded, nothing to resume")
    if args.dry_run:
        runs = plan_runs(spec, check_instances(spec))
        done = set()
        if spec.db.exists():
            con = store.open_existing(spec.db)
            done = store.finished_keys(con)
            con.close()
        todo = sum(r.key not in done for r in runs)
        print(f"sweep {spec.name}: {len(runs)} runs, {len(runs) - todo} already in {spec.db}, "
              f"{todo} to run")  # fmt: skip
        return OK
    progress = False if (args.quiet or args.no_progress) else None
    dask = args.dask_scheduler or args.dask
    summary = sweep(spec, workers=args.workers, dask=dask, progress=progress)
    print(summary.message())
    return OK


def _report(args: argparse.Namespace) -> int:
    from hierplan_opt.experiments.reports import report, save_figures

    if len(args.paths) != 1:
        raise InputError("usage: hierplan sweep report DB [--plots DIR] [--stats KEY,...]")
    keys = [k.strip() for k in (args.stats or "").split(",") if k.strip()]
    if args.plots and Path(args.plots).exists() and not Path(args.plots).is_dir():
        raise InputError(f"--plots {args.plots}: a file, not a folder for the figures")
    print(report(args.paths[0], stats=keys))
    if args.plots:
        for p in save_figures(args.paths[0], args.plots):
            print(f"wrote {p}")
    return OK


def _export(args: argparse.Namespace) -> int:
    from hierplan_opt.experiments.reports import export

    if len(args.paths) != 2:
        raise InputError("usage: hierplan sweep export DB OUT.csv|OUT.parquet")
    check_outputs(("OUT", args.paths[1], (".csv", ".parquet")))
    n = export(args.paths[0], args.paths[1])
    print(f"wrote {n} runs to {args.paths[1]}")
    return OK
