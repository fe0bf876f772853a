"""Solver registry: name -> (module, function, capabilities), imported lazily.

Every solver is a function ``solve(instance, *, time_limit, seed, objective,
**its_own_options) -> Result``. The front door :func:`hierplan_opt.solve` looks the name
up here, refuses options the solver's signature does not name, checks the problem kind
and objective against the declared capabilities, and validates the returned plan.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable
from dataclasses import dataclass, field

from hierplan_opt.core.errors import UnknownSolverError


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
    _fn: list[Callable] = field(default_factory=list, compare=False, repr=False)

    def load(self) -> Callable:
        """Import and return the solve function (cached)."""
        if not self._fn:
            mod, fn = self.target.split(":")
            self._fn.append(getattr(importlib.import_module(mod), fn))
        return self._fn[0]

    def options(self) -> list[str]:
        """Names of the solver's own keyword options (besides the common ones)."""
        sig = inspect.signature(self.load())
        common = {"instance", "time_limit", "seed", "objective"}
        return [
            p.name
            for p in sig.parameters.values()
            if p.kind is inspect.Parameter.KEYWORD_ONLY and p.name not in common
        ]


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
# Each module registers nothing itself; the table below is the single place that
# names them, so that importing the package stays cheap.
_BUILTIN = [
    (
        "cbs",
        "hierplan_opt.search.cbs:solve",
        {"mapf"},
        {"soc", "makespan"},
        True,
        False,
        "Conflict-based search with MDD prioritisation, bypass, WDG heuristic, "
        "disjoint splitting and symmetry reasoning",
    ),
    (
        "ecbs",
        "hierplan_opt.search.ecbs:solve",
        {"mapf"},
        {"soc"},
        False,
        True,
        "Enhanced CBS: focal search on both levels, cost <= w * optimal",
    ),
    (
        "eecbs",
        "hierplan_opt.search.eecbs:solve",
        {"mapf"},
        {"soc"},
        False,
        True,
        "Explicit-estimation CBS: cost <= w * optimal",
    ),
    (
        "cbm",
        "hierplan_opt.search.cbm:solve",
        {"mapf", "tapf"},
        {"makespan"},
        True,
        False,
        "Conflict-based min-cost flow: optimal makespan for teams (TAPF)",
    ),
    (
        "flow",
        "hierplan_opt.search.flow:solve",
        {"tapf"},
        {"makespan"},
        True,
        False,
        "Max-flow on the time-expanded network: anonymous MAPF (one team)",
    ),
    (
        "hungarian",
        "hierplan_opt.search.assignment:solve",
        {"tapf"},
        {"soc", "makespan"},
        False,
        False,
        "Hungarian target assignment by distance, then CBS",
    ),
    (
        "mip",
        "hierplan_opt.formulations.mip:solve",
        {"mapf", "tapf"},
        {"soc", "makespan"},
        True,
        False,
        "Time-expanded network MIP (Pyomo + HiGHS)",
    ),
    (
        "cpsat",
        "hierplan_opt.formulations.cpsat:solve",
        {"mapf", "tapf"},
        {"soc", "makespan"},
        True,
        False,
        "Time-expanded CP-SAT model (OR-Tools)",
    ),
]
for _n, _t, _p, _o, _opt, _b, _d in _BUILTIN:
    register(
        _n,
        _t,
        problems=_p,
        objectives=_o,
        optimal=_opt,
        bounded=_b,
        description=_d,
        one_team=_n == "flow",
    )
