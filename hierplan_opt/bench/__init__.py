"""Benchmarks that print tables: ``hierplan bench AREA [options]``.

Each area is a module of this package with ``main(argv) -> int``. Speed and memory
targets live here, not in timed unit tests. Every area takes the same three flags
(:class:`BenchParser`): ``--quick`` (a small preset), ``--time-limit S`` (per solve) and
``--instance SPEC`` (which instances; repeatable), and refuses bad flags with one line.
An area imports the layers it measures inside its functions, so that ``hierplan bench
AREA`` (and ``hierplan --help``) loads only that area's (heavy) modules.
"""

from __future__ import annotations

import argparse
import math
from typing import NoReturn

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result

AREAS = {
    "cbs": "optimal CBS on the MovingAI samples (time, cost, lower bound, nodes)",
    "ecbs": "bounded-suboptimal ECBS/EECBS on the MovingAI samples",
    "teams": "CBM and max-flow on warehouse-like TAPF instances",
    "formulations": "MIP and CP-SAT model sizes and time to optimum vs CBS",
    "post": "MAPF-POST: TPG/STN size and time, graph vs LP",
    "execution": "execution: STN re-solve vs re-plan, Monte Carlo runs/s, layers per delay rate",
    "trajectory": "trajectory refinement (CasADi): formation and 200 robots, IPOPT vs fatrop",
    "lacam": "PIBT and LaCAM* on large fleets, side by side with lacam3 and the Python ports",
    "highways": "ECBS/CBS with user, crisscross and learned highways (Kiva, corridor)",
    "physics": "robots in MuJoCo: paper warehouse, formation, 200 robots, spill, agreement",
    "view": "browser viewer: 10,000-robot load time and fps; 200-robot picture commands",
    "lifelong": "LoRR problems: our lifelong loop beside the Start-Kit baseline (tasks, time)",
}


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


class BenchParser(argparse.ArgumentParser):
    """The argument parser of one area: the shared flags, one-line errors.

    Example
    -------
    >>> p = BenchParser("demo", "a demo", instance="a name")
    >>> p.parse_args(["--quick", "--instance", "a", "b"]).instance
    ['a', 'b']
    >>> p.parse_args(["--bogus"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: unrecognized arguments: --bogus (see ...)
    """

    def __init__(
        self,
        area: str,
        description: str,
        *,
        instance: str,
        quick: str = "a small preset that runs in seconds",
        time_limit: str = "seconds per solve (default 60, --quick 10)",
        instance_aliases: tuple[str, ...] = (),
    ) -> None:
        super().__init__(prog=f"hierplan bench {area}", description=description)
        self.add_argument("--quick", action="store_true", help=quick)
        self.add_argument("--time-limit", type=_seconds, metavar="S", help=time_limit)
        self.add_argument(
            "--instance",
            *instance_aliases,
            dest="instance",
            action="extend",
            nargs="+",
            metavar="SPEC",
            help=f"{instance} (repeatable)",
        )

    def error(self, message: str) -> NoReturn:
        raise InputError(f"{message} (see '{self.prog} --help')")


#: Header of the columns :func:`search_columns` fills.
SEARCH_HEAD = (
    f"{'status':10} {'time_s':>7} {'cost':>7} {'LB':>7} {'cost/LB':>7} "
    f"{'HL_exp':>7} {'HL_gen':>7} {'LL_exp':>9}"
)


def search_columns(r: Result) -> str:
    """Status, time, cost, lower bound, cost / LB and node counts of a search result.

    Example
    -------
    >>> from hierplan_opt.core.result import Status
    >>> search_columns(Result(Status.OPTIMAL, None, cost=12, lower_bound=10)).split()
    ['OPTIMAL', '0.00', '12', '10', '1.200', '0', '0', '0']
    """
    st = r.stats
    ratio = f"{r.cost / r.lower_bound:.3f}" if r.cost and r.lower_bound else "-"
    cost = "-" if r.cost is None else f"{r.cost:g}"
    lb = "-" if r.lower_bound is None else f"{r.lower_bound:g}"
    return (
        f"{r.status.value:10} {r.runtime:>7.2f} {cost:>7} {lb:>7} {ratio:>7} "
        f"{st.get('high_level_expanded', 0):>7} {st.get('high_level_generated', 0):>7} "
        f"{st.get('low_level_expanded', 0):>9}"
    )


def time_limit(
    given: float | None, quick: bool, *, full: float = 60.0, small: float = 10.0
) -> float:
    """The per-solve limit: the one given, else ``small`` with --quick, else ``full``."""
    if given is not None:
        return given
    return small if quick else full


def scenario(spec: str, agents: int | None = None) -> tuple[str, Instance]:
    """``"SCEN[:K]"`` (a bundled ``.scen`` name without the suffix) -> (name, instance).

    Example
    -------
    >>> name, inst = scenario("empty-8-8-even-1:3")
    >>> name, inst.num_agents
    ('empty-8-8-even-1', 3)
    """
    from hierplan_opt.experiments.data import movingai_files  # shipped with the package
    from hierplan_opt.io.movingai import load_movingai

    name, _, k = spec.partition(":")
    name = name.removesuffix(".scen")
    if k and not k.isdigit():
        raise InputError(f"--instance expects SCEN[:K] with K a number of agents, got {spec!r}")
    mp, scen = movingai_files(name)
    return name, load_movingai(mp, scen, int(k) if k else agents)
