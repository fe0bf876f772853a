"""Reading and writing instances and plans.

- MovingAI ``.map`` + ``.scen`` (:mod:`hierplan_opt.io.movingai`),
- libMultiRobotPlanning YAML instances (:mod:`hierplan_opt.io.lmrp_yaml`),
- the project's own YAML format (:mod:`hierplan_opt.io.yaml_format`, see
  ``docs/yaml-format.md``),
- plans in the libMultiRobotPlanning output layout (:mod:`hierplan_opt.io.plans`), and
  the plan files of EECBS / CBSH2-RTC (:mod:`~hierplan_opt.io.eecbs`), LaCAM
  (:mod:`~hierplan_opt.io.lacam`) and MAPF Tracker submissions
  (:mod:`~hierplan_opt.io.tracker`),
- safe file access for all of them (:mod:`hierplan_opt.io.files`: regular files only,
  size and nesting limits, checked and atomic outputs).

Every reader refuses bad input with an :class:`~hierplan_opt.core.errors.InputError`
whose one-line message names the file, the line and the problem.
"""

from __future__ import annotations

from pathlib import Path

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.io import lmrp_yaml, movingai, yaml_format
from hierplan_opt.io.files import write_text
from hierplan_opt.io.plans import PLAN_FORMATS, load_plan, read_plan, save_plan
from hierplan_opt.io.yaml import Ctx, read_yaml

FORMATS = ("hierplan", "lmrp", "movingai")
_ALIASES = {
    "hierplan": "hierplan",
    "yaml": "hierplan",
    "own": "hierplan",
    "lmrp": "lmrp",
    "libmultirobotplanning": "lmrp",
    "movingai": "movingai",
}


def load_instance(
    path: str | Path,
    scen: str | Path | None = None,
    agents: int | None = None,
    *,
    check_scen_map: bool = True,
    shared_goals: bool = False,
) -> Instance:
    """Read an instance: a MovingAI ``.map`` with ``scen``, or a YAML instance file.

    ``shared_goals`` lets two agents of a libMultiRobotPlanning file share a goal (for
    agents that disappear at their goals, :mod:`hierplan_opt.search.libmrp`).

    A YAML file with a top-level ``graph:`` is the hierplan format; one with ``map:``
    and ``agents:`` (or ``roadmap:`` and ``agents:``) is the libMultiRobotPlanning
    format. ``agents`` keeps the first K agents (MovingAI scenarios and MAPF YAML
    instances). A scenario must name the map it is read with, unless
    ``check_scen_map`` is False.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "tiny.yaml")
    >>> _ = open(f, "w").write('''
    ... graph: {type: grid, dimensions: [3, 1]}
    ... agents: [{start: [0, 0], goal: [2, 0]}]
    ... ''')
    >>> load_instance(f)
    Instance('tiny', MAPF, 1 agents, Graph(grid 3x1, 3 free cells))
    """

    p = Path(path)
    ctx = Ctx(p)
    suffix = p.suffix.lower()
    if agents is not None and (isinstance(agents, bool) or not isinstance(agents, int)):
        raise InputError(f"--agents must be an integer, got {agents!r}")
    if agents is not None and agents < 1:
        raise InputError(f"--agents must be at least 1, got {agents}")
    if suffix == ".map":
        if scen is None:
            raise InputError(f"{p}: a MovingAI .map instance needs a scenario (--scen FILE.scen)")
        return movingai.load_movingai(p, scen, agents, check_scen_map=check_scen_map)
    if suffix == ".scen":
        raise InputError(f"{p}: give the .map file as INSTANCE and this scenario with --scen")
    if scen is not None:
        raise InputError(f"--scen only applies to a MovingAI .map instance, not to {p}")
    data = read_yaml(p)
    if yaml_format.looks_like(data):
        inst = yaml_format.from_data(data, p)
    elif lmrp_yaml.looks_like(data):
        inst = lmrp_yaml.from_data(data, p, shared_goals=shared_goals)
    else:
        raise ctx.error(
            "not an instance file: expected a top-level 'graph:' (hierplan format) or "
            "'map:' and 'agents:' (libMultiRobotPlanning format)",
            getattr(data, "line", 1) or 1,
        )
    if agents is not None:
        if inst.is_tapf:
            raise ctx.error("--agents applies only to MAPF instances (this one has teams)")
        if agents > inst.num_agents:
            raise ctx.error(f"--agents {agents} but the instance has {inst.num_agents} agents")
        inst = inst.subset(agents)
    return inst


def save_instance(path: str | Path, instance: Instance, format: str | None = None) -> None:
    """Write ``instance`` in ``format``: "hierplan" (default), "lmrp" or "movingai".

    Without ``format``, a ``.map`` or ``.scen`` path means MovingAI. MovingAI writes
    two files: the ``.map`` and a ``.scen`` with the same stem.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 2, obstacles=[(1, 1)]), [(0, 0)], [(2, 1)])
    >>> d = tempfile.mkdtemp()
    >>> for fmt in ("hierplan", "lmrp"):
    ...     save_instance(os.path.join(d, fmt + ".yaml"), inst, format=fmt)
    ...     print(fmt, load_instance(os.path.join(d, fmt + ".yaml")).soc_lower_bound())
    hierplan 3
    lmrp 3
    """

    p = Path(path)
    if format is None:
        fmt = "movingai" if p.suffix.lower() in (".map", ".scen") else "hierplan"
    else:
        fmt = _ALIASES.get(format.lower(), "")
        if not fmt:
            raise InputError(f"unknown instance format {format!r} (use {', '.join(FORMATS)})")
    if fmt == "hierplan":
        yaml_format.save(p, instance)
    elif fmt == "lmrp":
        lmrp_yaml.save(p, instance)
    else:
        map_path, scen_path = p.with_suffix(".map"), p.with_suffix(".scen")
        scen_text = movingai.scen_text(instance, map_path.name)  # checks before writing
        movingai.save_map(map_path, instance.graph)
        write_text(scen_path, scen_text)


__all__ = [
    "FORMATS",
    "PLAN_FORMATS",
    "load_instance",
    "load_plan",
    "read_plan",
    "save_instance",
    "save_plan",
]
