"""Solver registry: name -> (module, capabilities), imported lazily; the checked way in.

Every solver is a function ``solve(instance, *, time_limit, seed, objective,
**its_own_options) -> Result`` decorated with :func:`solver`, which declares its options
(:class:`~hierplan_opt.core.options.Option`) beside it. The table at the end of this
module names every built-in solver and what it can do, without importing it.

:func:`run` is the one way into a solver, used by the front door
(:func:`hierplan_opt.solve`), by a direct call of a solver's ``solve`` and by solvers
that use other solvers: it checks the problem kind and objective against the declared
capabilities, checks every option, runs the cheap infeasibility checks once, and only
then calls the solver. :func:`run` checks no plan: it is the raw path, for solvers that
use other solvers (whose plans the caller's own result is checked with).

:func:`checked` is the one check of a returned plan (the validator, and the reported cost
against the plan's). Every caller outside the solvers goes through it: the front door
(:func:`hierplan_opt.solve`, which every layer above the solvers calls) and a direct
call of a registered solver (``cbs.solve(instance)``), both with the default time limit.
"""

from __future__ import annotations

import importlib
import inspect
import logging
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from hierplan_opt.core.errors import OptionError, UnknownSolverError
from hierplan_opt.core.feasibility import quick_infeasibility
from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.core.options import Option, Options
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline, check_time_limit
from hierplan_opt.core.validate import validate

if TYPE_CHECKING:
    from hierplan_opt.core.instance import Instance
    from hierplan_opt.core.plan import Plan

log = logging.getLogger(__name__)

#: Seconds a solve may take unless told otherwise (the front door's, the CLI's and a
#: registered solver's call's default).
DEFAULT_TIME_LIMIT = 60.0

#: Arguments every solver takes besides its own options.
COMMON = ("instance", "time_limit", "seed", "objective")
OBJECTIVES = ("soc", "makespan")


class Solver:
    """A solve function together with its declared options (made by :func:`solver`).

    Calling it gives the guarantees of the front door (:func:`hierplan_opt.solve`): the
    options and the cheap checks of :func:`run`, the default time limit, and the
    returned plan validated by :func:`checked`. :attr:`fn` is the bare function, private
    to :func:`run` (and to tests that need a solver without the front door's checks).
    """

    def __init__(self, name: str, fn: Callable[..., Result], options: Options) -> None:
        self.name = name
        self.fn = fn
        self.options = options
        self.__doc__ = fn.__doc__
        self.__wrapped__ = fn
        self.__module__ = fn.__module__
        self.__name__ = fn.__name__
        self.__qualname__ = fn.__qualname__

    def __call__(
        self,
        instance: Instance,
        *,
        time_limit: float | None = DEFAULT_TIME_LIMIT,
        seed: int = 0,
        cost: str | None = None,
        objective: str | None = None,
        **options: Any,
    ) -> Result:
        t0 = time.perf_counter()
        kind = cost_keyword(cost, objective)
        result = run(
            self.name, instance, time_limit=time_limit, seed=seed, objective=kind, **options
        )
        return checked(instance, replace(result, runtime=time.perf_counter() - t0))

    def __repr__(self) -> str:
        return f"<solver {self.name!r}: {self.__module__}.{self.__qualname__}>"


def cost_keyword(cost: str | None, objective: str | None, stacklevel: int = 3) -> str | None:
    """The plan's cost (``"soc"`` or ``"makespan"``, steps) from ``cost=``, or from the
    deprecated ``objective=`` of :func:`hierplan_opt.solve` and a solver's call (with a
    :class:`DeprecationWarning`): ``objective`` names a schedule's goal in seconds
    (:func:`hierplan_opt.postprocess`: makespan, safety, flowtime).

    Example
    -------
    >>> cost_keyword("makespan", None), cost_keyword(None, None)
    ('makespan', None)
    """
    if objective is None:
        return cost
    warnings.warn(
        "solve(objective=...) is deprecated: a plan's cost is cost='soc' or 'makespan' "
        "(objective= is a schedule's, in postprocess)",
        DeprecationWarning,
        stacklevel=stacklevel,
    )
    if cost is not None and cost != objective:
        raise OptionError(f"cost={cost!r} and the deprecated objective={objective!r} differ")
    return objective


def _keyword_defaults(fn: Callable[..., Result]) -> dict[str, Any]:
    """The solver's own keyword-only parameters and their defaults."""
    return {
        p.name: None if p.default is inspect.Parameter.empty else p.default
        for p in inspect.signature(fn).parameters.values()
        if p.kind is inspect.Parameter.KEYWORD_ONLY and p.name not in COMMON
    }


def solver(name: str, *options: Option) -> Callable[[Callable[..., Result]], Solver]:
    """Declare a solve function's options; the defaults come from its signature.

    The declared names must be exactly the function's own keyword-only parameters.

    Example
    -------
    >>> @solver("demo", Option("w", "float", "suboptimality bound", low=1))
    ... def solve(instance, *, time_limit=None, seed=0, objective="soc", w=1.5):
    ...     pass
    >>> [o.describe() for o in solve.options]
    ['w: number >= 1 (default 1.5) -- suboptimality bound']
    """

    def wrap(fn: Callable[..., Result]) -> Solver:
        defaults = _keyword_defaults(fn)
        declared = [o.name for o in options]
        if declared != list(defaults):
            raise TypeError(f"{name}: options {declared} do not match the signature {defaults}")
        return Solver(name, fn, Options(options).with_defaults(defaults))

    return wrap


def _undeclared(name: str, fn: Callable[..., Result]) -> Solver:
    """A plain function registered without :func:`solver`: options from its signature."""
    kinds: dict[type, str] = {bool: "bool", int: "int", float: "float"}
    opts: list[Option] = []
    for k, v in _keyword_defaults(fn).items():
        default: object = v
        kind = kinds.get(type(default), "any")
        opts.append(Option(k, kind, "(undeclared)", default=default, optional=True))
    return Solver(name, fn, Options(opts))


@dataclass(frozen=True)
class SolverInfo:
    """A registry entry.

    ``problems`` ⊆ {"mapf", "tapf"}; ``objectives`` ⊆ {"soc", "makespan"};
    ``optimal`` says whether OPTIMAL results are proven optima; ``bounded`` whether
    the solver's ``w`` option bounds suboptimality; ``one_team`` that TAPF instances
    must have a single team (anonymous MAPF).
    """

    name: str
    target: str  # "package.module:function"
    problems: frozenset[str]
    objectives: frozenset[str]
    optimal: bool
    bounded: bool = False
    description: str = ""
    one_team: bool = False
    _fn: list[Callable[..., Result]] = field(
        default_factory=list[Callable[..., Result]], compare=False, repr=False
    )

    def load(self) -> Solver:
        """Import the solver (cached): its function and declared options."""
        if not self._fn:
            mod, fn = self.target.split(":")
            self._fn.append(getattr(importlib.import_module(mod), fn))
        fn = self._fn[0]
        return fn if isinstance(fn, Solver) else _undeclared(self.name, fn)

    def options(self) -> list[str]:
        """Names of the solver's own options (besides the common ones)."""
        return self.load().options.names()

    def objective_for(self, instance: Instance, objective: str | None) -> str:
        """The objective to use (default: soc for MAPF when possible), or OptionError
        when the solver cannot take ``instance`` or optimise ``objective``."""
        problem = "tapf" if instance.is_tapf else "mapf"
        if problem not in self.problems:
            if problem == "tapf":
                hint = "; for teams use 'cbm'" + (
                    ", or 'flow' for one team" if len(instance.teams) == 1 else ""
                )
            else:
                fits = [n for n, i in sorted(_REGISTRY.items()) if "mapf" in i.problems]
                hint = f"; for MAPF use {' or '.join(map(repr, fits))}"
            raise OptionError(
                f"solver {self.name!r} does not solve {problem.upper()} instances "
                f"(it solves: {', '.join(sorted(p.upper() for p in self.problems))}){hint}"
            )
        if self.one_team and len(instance.teams) > 1:
            raise OptionError(
                f"solver {self.name!r} solves anonymous MAPF (one team); this instance has "
                f"{len(instance.teams)} teams (use 'cbm')"
            )
        if objective is None:
            return "soc" if problem == "mapf" and "soc" in self.objectives else "makespan"
        if objective not in OBJECTIVES:
            raise OptionError(f"unknown objective {objective!r} (use 'soc' or 'makespan')")
        if objective not in self.objectives:
            raise OptionError(
                f"solver {self.name!r} does not optimise {objective!r} "
                f"(it does: {', '.join(sorted(self.objectives))})"
            )
        return objective

    def check_options(self, values: dict[str, Any]) -> dict[str, Any]:
        """Every option checked (solver names and nested options too), defaults filled."""
        spec = self.load().options
        out = spec.check(values, self.name)
        for opt in spec:
            value = out[opt.name]
            if opt.kind == "solver" and value is not None and value not in _REGISTRY:
                raise opt.refuse(self.name, value)
        for opt in spec:
            if opt.kind == "options" and out[opt.name] is not None:
                inner = get(out[opt.of])
                try:
                    inner.check_options(out[opt.name])
                except OptionError as exc:
                    raise OptionError(f"{self.name} option {opt.name}: {exc}") from None
        return out


def _targets(instance: Instance) -> set[int]:
    if instance.is_tapf:
        return {v for team in instance.teams for v in team.targets}
    return set(instance.goals)


def cheap_infeasibility(instance: Instance) -> str | None:
    """A one-line reason why no plan exists, from the checks that take milliseconds
    (after the distance tables of every goal: batches the solvers reuse)."""

    instance.graph.fill_distances(_targets(instance))
    return quick_infeasibility(instance)


def quick_lower_bound(instance: Instance, objective: str = "soc") -> int:
    """A proven lower bound on the optimal cost that waits for no distance table.

    Each agent counts the distance to its nearest admissible goal where that goal's
    table is already made, else the Manhattan distance on a 4-connected 2D grid (a move
    changes one coordinate by one), else 0. With every table made this is the sum of
    distances (or their maximum for ``"makespan"``): the bound a solver stopped before
    its tables were done still reports (issue 34: ``lb=-`` on 1,000 agents).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> g = Graph.grid(4, 3, obstacles=[(1, 0), (1, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (3, 2)], [(2, 0), (0, 2)])
    >>> quick_lower_bound(inst)  # Manhattan 2 + 3; the tables say 6 + 3
    5
    >>> _ = g.fill_distances(inst.goals)
    >>> quick_lower_bound(inst), inst.soc_lower_bound()
    (9, 9)
    """
    g = instance.graph
    xy = g.grid_xy if g.kind == "grid" else None
    made = {t for t in _targets(instance) if g.fill_distances([t], Deadline(0))}

    def bound(s: int, t: int) -> int:
        d = g.dist(s, t) if t in made else UNREACHABLE
        if d != UNREACHABLE:  # (an unreachable goal: the cheap checks say INFEASIBLE)
            return d
        return abs(xy[1][s] - xy[1][t]) + abs(xy[2][s] - xy[2][t]) if xy is not None else 0

    bounds = [
        min(bound(agent.start, t) for t in instance.goal_set(i))
        for i, agent in enumerate(instance.agents)
    ]
    if not bounds:
        return 0
    return sum(bounds) if objective == "soc" else max(bounds)


def run(
    name: str,
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str | None = None,
    **options: Any,
) -> Result:
    """Check everything, then solve ``instance`` with solver ``name`` (see the module doc).

    The raw path: unlike :func:`hierplan_opt.solve` (and a registered solver's call), no
    default time limit, no runtime and no plan validation (:func:`checked`). It is the
    way for solvers to use other solvers; everything else calls the front door.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    >>> r = run("ecbs", inst)
    >>> r.status, r.stats["reason"][:30]
    (<Status.INFEASIBLE: 'INFEASIBLE'>, "agent 'agent0' cannot get from")
    """
    info = get(name)
    objective = info.objective_for(instance, objective)
    check_time_limit(time_limit)
    values = info.check_options(options)
    deadline = Deadline(time_limit)
    # The distance tables (about a second for 2000 goals on 4096 cells) in batches
    # between deadline checks; then the exact feasibility test (milliseconds).
    tables = instance.graph.fill_distances(_targets(instance), deadline)
    reason = cheap_infeasibility(instance) if tables else None
    if reason is not None:
        return Result(
            Status.INFEASIBLE, None, solver=name, objective=objective, stats={"reason": reason}
        )
    remaining = deadline.remaining()
    if time_limit is not None and remaining <= 0:
        log.info("%s: time limit %.3g s used up by the checks before the solver", name, time_limit)
        if tables:  # cached: the bound costs a lookup per agent
            bound = (
                instance.soc_lower_bound if objective == "soc" else instance.makespan_lower_bound
            )
            lb = bound()
        else:  # the tables made so far, Manhattan distances for the others
            lb = quick_lower_bound(instance, objective)
        result = Result(
            Status.TIME_LIMIT,
            None,
            lower_bound=lb,
            stats={
                "stopped_by": "time_limit",
                "reason": f"time limit ({time_limit:g} s) reached during the cheap checks "
                "(distance tables, feasibility test), before the solver started",
            },
        )
    else:
        result = info.load().fn(
            instance,
            time_limit=None if time_limit is None else remaining,
            seed=seed,
            objective=objective,
            **values,
        )
    if result.status is Status.TIME_LIMIT and result.plan is None and instance.graph.directed:
        # On directed roadmaps the checks above are exact only for small instances
        # (core/feasibility.joint_reachable): say that nothing decided feasibility.
        result = replace(result, stats={**result.stats, "feasibility": "undecided"})
    return replace(result, solver=name, objective=objective)


def checked(
    instance: Instance,
    result: Result,
    more: Callable[[Instance, Plan], list[Any]] | None = None,
) -> Result:
    """``result`` with its plan validated: the one check of a solver's plan.

    A plan that fails the validator (or ``more``, extra checks such as an annotated
    roadmap's conflicts) is never passed on: the result becomes ERROR, without plan and
    cost, with the violations in ``stats["violations"]``. A reported cost that differs
    from the plan's own is an ERROR too; a missing one is filled in.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> jump = Result(Status.FEASIBLE, Plan.from_paths([[0, 2]]), objective="soc")
    >>> bad = checked(inst, jump)
    >>> bad.status, bad.plan, bad.stats["error"][:30]
    (<Status.ERROR: 'ERROR'>, None, 'invalid plan: non_edge: agent0')
    >>> checked(inst, Result(Status.FEASIBLE, Plan.from_paths([[0, 1, 2]]), objective="soc")).cost
    2
    """
    if result.plan is None:
        return result
    violations: list[Any] = validate(instance, result.plan)
    if not violations and more is not None:
        violations = more(instance, result.plan)
    if violations:
        log.error("solver %s returned an invalid plan: %s", result.solver, violations[0])
        stats = dict(result.stats)
        stats["violations"] = [str(v) for v in violations]
        stats["error"] = f"invalid plan: {violations[0]}"
        return replace(result, status=Status.ERROR, plan=None, cost=None, stats=stats)
    cost = result.plan.cost(result.objective)
    if result.cost is not None and result.cost != cost:
        log.error(
            "solver %s reported cost %s but its plan costs %s", result.solver, result.cost, cost
        )
        stats = dict(result.stats)
        stats["error"] = f"reported cost {result.cost} but the plan costs {cost}"
        return replace(result, status=Status.ERROR, stats=stats)
    return replace(result, cost=cost)


_REGISTRY: dict[str, SolverInfo] = {}


def register(
    name: str,
    target: str,
    *,
    problems: set[str] | frozenset[str] = frozenset({"mapf"}),
    objectives: set[str] | frozenset[str] = frozenset({"soc"}),
    optimal: bool = False,
    bounded: bool = False,
    description: str = "",
    one_team: bool = False,
) -> None:
    """Add a solver to the registry (later registrations of a name replace earlier ones).

    Example
    -------
    >>> register("mine", "mypkg.mine:solve", objectives={"soc"}, optimal=True)
    >>> get("mine").target
    'mypkg.mine:solve'
    >>> _ = _REGISTRY.pop("mine")
    """
    _REGISTRY[name] = SolverInfo(
        name,
        target,
        frozenset(problems),
        frozenset(objectives),
        optimal,
        bounded,
        description,
        one_team,
    )


def get(name: str) -> SolverInfo:
    """The entry of solver ``name``; :class:`UnknownSolverError` names the known ones."""
    try:
        return _REGISTRY[name]
    except KeyError:
        known = ", ".join(sorted(_REGISTRY))
        raise UnknownSolverError(f"unknown solver {name!r} (known: {known})") from None


def names() -> list[str]:
    """Registered solver names, sorted."""
    return sorted(_REGISTRY)


# ---------------------------------------------------------------- built-in solvers
# Each module registers nothing itself; this table is the single place that names
# them, so that importing the package stays cheap. Kind: optimal, bounded (option w),
# heuristic; "one team": TAPF instances must have a single team.
_BUILTIN = [
    ("cbs", "search.cbs", "mapf", "soc makespan", "optimal",
     "Conflict-based search with MDD prioritisation, bypass, WDG heuristic, disjoint "
     "splitting and symmetry reasoning"),
    ("ecbs", "search.ecbs", "mapf", "soc", "bounded",
     "Enhanced CBS: focal search on both levels, cost <= w * optimal"),
    ("eecbs", "search.eecbs", "mapf", "soc", "bounded",
     "Explicit-estimation CBS: cost <= w * optimal"),
    ("cbm", "search.cbm", "mapf tapf", "makespan", "optimal",
     "Conflict-based min-cost flow: optimal makespan for teams (TAPF)"),
    ("flow", "search.flow", "tapf", "makespan", "optimal one team",
     "Max-flow on the time-expanded network: anonymous MAPF (one team)"),
    ("hungarian", "search.hungarian", "tapf", "soc makespan", "heuristic",
     "Hungarian target assignment by distance, then a MAPF solver"),
    ("mip", "formulations.mip", "mapf tapf", "soc makespan", "optimal",
     "Time-expanded network MIP (Pyomo + HiGHS)"),
    ("cpsat", "formulations.cpsat", "mapf tapf", "soc makespan", "optimal",
     "Time-expanded CP-SAT model (OR-Tools)"),
    ("pibt", "search.pibt", "mapf", "soc", "heuristic",
     "PIBT: one-step priority inheritance with backtracking (fast, incomplete)"),
    ("lacam", "search.lacam", "mapf", "soc", "heuristic",
     "LaCAM*: complete, anytime (search + LNS refinement), optimal given time"),
]  # fmt: skip
for _name, _module, _problems, _objectives, _kind, _text in _BUILTIN:
    register(
        _name,
        f"hierplan_opt.{_module}:solve",
        problems=set(_problems.split()),
        objectives=set(_objectives.split()),
        optimal=_kind.startswith("optimal"),
        bounded=_kind == "bounded",
        one_team=_kind.endswith("one team"),
        description=_text,
    )
