"""``hierplan lifelong PROBLEM.json --ticks N --out LOG.json``: a LoRR run with a summary."""

from __future__ import annotations

import argparse
import logging
import math

from hierplan_opt.cli.common import (
    add_progress_arguments,
    check_outputs,
    fraction,
    positive_int,
    progress_of,
)
from hierplan_opt.core.errors import InputError
from hierplan_opt.io.values import to_json

log = logging.getLogger(__name__)

HELP = "run a League of Robot Runners problem lifelong (tasks, delays) and write its log"


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def _budget(text: str) -> float:
    """argparse type of ``--budget``: seconds above the planner's reserve."""
    from hierplan_opt.lifelong.run import BUDGET_MARGIN

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > BUDGET_MARGIN):
        raise argparse.ArgumentTypeError(
            f"expected seconds above {BUDGET_MARGIN:g} (the planner's reserve), got {text!r}"
        )
    return value


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("problem", metavar="PROBLEM.json", help="LoRR problem file (Start-Kit 3.x)")
    p.add_argument(
        "--ticks", type=positive_int, default=1000, help="execution ticks (default 1000)"
    )
    p.add_argument("--out", metavar="LOG.json", help="write the LoRR log (PlanViz reads it)")
    p.add_argument(
        "--scheduler",
        choices=("greedy", "hungarian"),
        default="hungarian",
        help="task assignment (default: hungarian, min-cost matching)",
    )
    p.add_argument(
        "--planner",
        choices=("pibt", "lacam", "pibt-guided", "lacam-guided"),
        default="pibt",
        help="windowed PIBT (default) or windowed LaCAM (search/windowed), or windowed "
        "PIBT guided by the registry's pibt / lacam plan of each call",
    )
    p.add_argument(
        "--budget",
        type=_budget,
        default=1.0,
        metavar="S",
        help="seconds per planning call, above 0.05 (default 1, the Start-Kit's); the "
        "planner returns the steps done by then and robots without a plan wait",
    )
    p.add_argument(
        "--period", type=positive_int, default=10, help="ticks between planning calls (default 10)"
    )
    p.add_argument(
        "--window",
        type=positive_int,
        help="actions planned per call (default 6; 4 above 1,000 robots)",
    )
    p.add_argument(
        "--congestion",
        type=_non_negative,
        default=0.0,
        help="weight of recent traffic in the planner's choices (default 0)",
    )
    p.add_argument("--seed", type=int, default=0, help="planner seed (default 0)")
    p.add_argument("--p-delay", type=fraction, metavar="P", help="override delayConfig.pDelay")
    p.add_argument(
        "--event-model", choices=("bernoulli", "poisson"), help="override delayConfig.eventModel"
    )
    p.add_argument(
        "--replay-delays",
        metavar="LOG.json",
        help="take the delays from a recorded log's delayIntervals (e.g. the Start-Kit's)",
    )
    p.add_argument(
        "--no-check",
        action="store_true",
        help="skip the independent replay of the log (footprints, moves, task events)",
    )
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_progress_arguments(p)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from hierplan_opt.io.lorr import load_problem, parse_delay_intervals, read_log, write_log
    from hierplan_opt.lifelong import check_log, run_lifelong
    from hierplan_opt.lifelong.delays import ReplayDelays

    check_outputs(("--out", args.out, (".json",)))
    problem = load_problem(args.problem)
    if args.p_delay is not None or args.event_model is not None:
        d = problem.delay
        d = replace(
            d,
            p_delay=d.p_delay if args.p_delay is None else args.p_delay,
            event_model=d.event_model if args.event_model is None else args.event_model,
        )
        problem = replace(problem, delay=d)
    delays = None
    if args.replay_delays:
        if args.p_delay is not None or args.event_model is not None:
            raise InputError(
                "--replay-delays takes the delays from the log; drop --p-delay/--event-model"
            )
        recorded = read_log(args.replay_delays)
        intervals = parse_delay_intervals(
            recorded.get("delayIntervals"), problem.team_size, str(args.replay_delays)
        )
        span = recorded.get("makespan")
        if isinstance(span, int) and not isinstance(span, bool) and span < args.ticks:
            log.warning(
                "%s records %d ticks: from tick %d on no delays are replayed",
                args.replay_delays, span, span,
            )  # fmt: skip
        delays = ReplayDelays(intervals)
    with progress_of(args, f"lifelong {problem.name}"):
        res = run_lifelong(
            problem,
            ticks=args.ticks,
            scheduler=args.scheduler,
            planner=args.planner,
            period=args.period,
            window=args.window,
            seed=args.seed,
            congestion=args.congestion,
            delays=delays,
            budget=args.budget,
        )
    summary = res.summary()
    failed = False
    if not args.no_check:
        rep = check_log(problem, res.log)
        res.log["numPlannerErrors"] = rep.invalid + rep.collisions
        summary["replay"] = (
            "ok"
            if rep.ok
            else (
                f"{rep.invalid} invalid, {rep.collisions} collisions, {rep.bad_events} bad events: "
                + (rep.problems[0] if rep.problems else "")
            )
        )
        failed = not rep.ok
    if args.out:
        write_log(args.out, res.log)
    if args.json:
        print(to_json(summary))
    else:
        pt = res.planner_times
        print(
            f"{problem.name}: {problem.team_size} robots, {res.ticks} ticks, "
            f"scheduler {args.scheduler}, planner {args.planner}, "
            f"window {res.log['hierplan']['window']}, "
            f"period {args.period}"
        )
        print(f"tasks finished {res.tasks_finished}, throughput {res.throughput:.4f} per tick")
        h = res.handled
        print(
            f"delays {res.delays} (slack {h['slack']}, action dependencies {h['adg']}, "
            f"STN re-solve {h['stn']}, re-plan {h['replan']}); "
            f"waits behind a delayed robot {res.waits_on_delayed}"
        )
        print(
            f"planner: {len(pt)} calls, median {summary['planner_s_median']:.3f} s, "
            f"max {summary['planner_s_max']:.3f} s, over the {args.budget:g} s budget "
            f"{summary['over_budget_calls']}, cut by the deadline "
            f"{summary['calls_cut_by_deadline']}; wall {res.wall_time:.1f} s"
        )
        if "replay" in summary:
            print(f"replay: {summary['replay']}")
        if args.out:
            print(f"log written to {args.out}")
    return 1 if failed else 0
