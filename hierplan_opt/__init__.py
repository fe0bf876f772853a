"""hierplan_opt: plan generation, MAPF-POST scheduling and execution for robot teams.

Example
-------
>>> import hierplan_opt as hp
>>> g = hp.Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
>>> inst = hp.Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
>>> res = hp.solve(inst, "cbs", time_limit=10)
>>> res.status.value, res.cost, hp.validate(inst, res.plan)
('OPTIMAL', 8, [])
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

from hierplan_opt.core import blas as _blas  # noqa: F401  (before numpy: the command's BLAS)

# isort: split
from hierplan_opt.api import solve
from hierplan_opt.core.errors import HierplanError, InputError, OptionError, UnknownSolverError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Agent, Instance, Kinematics, Team
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.validate import Violation, validate
from hierplan_opt.core.version import __version__ as __version__

if TYPE_CHECKING:  # the lazily loaded names below, for type checkers and readers
    from hierplan_opt.execution import simulate
    from hierplan_opt.execution.pipeline import run
    from hierplan_opt.formulations.verify import verify
    from hierplan_opt.io import load_instance, load_plan, save_instance, save_plan
    from hierplan_opt.schedule import Schedule, postprocess
    from hierplan_opt.trajectory import Trajectories, refine

logging.getLogger(__name__).addHandler(logging.NullHandler())


# Heavier parts load on first use so that `import hierplan_opt` stays fast. One name a
# line, sorted: a new export is one line here, in the TYPE_CHECKING block and in __all__.
_LAZY = {
    "Schedule": "hierplan_opt.schedule",
    "Trajectories": "hierplan_opt.trajectory",
    "load_instance": "hierplan_opt.io",
    "load_plan": "hierplan_opt.io",
    "postprocess": "hierplan_opt.schedule",
    "refine": "hierplan_opt.trajectory",
    "save_instance": "hierplan_opt.io",
    "save_plan": "hierplan_opt.io",
    "simulate": "hierplan_opt.execution",
    "run": "hierplan_opt.execution.pipeline",
    "verify": "hierplan_opt.formulations.verify",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'hierplan_opt' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The module's names and the lazy ones (``dir(hierplan_opt)`` lists both)."""
    return sorted({*globals(), *_LAZY})


__all__ = [
    "Agent",
    "Graph",
    "HierplanError",
    "InputError",
    "Instance",
    "Kinematics",
    "OptionError",
    "Plan",
    "Result",
    "Status",
    "Team",
    "UnknownSolverError",
    "Violation",
    "solve",
    "validate",
    # lazy (the keys of _LAZY, sorted)
    "Schedule",
    "Trajectories",
    "load_instance",
    "load_plan",
    "postprocess",
    "refine",
    "save_instance",
    "run",
    "save_plan",
    "simulate",
    "verify",
]
