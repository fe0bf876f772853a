"""``hierplan info``: what an instance holds, its lower bounds, and the solvers."""

from __future__ import annotations

import argparse

from hierplan_opt import registry
from hierplan_opt.cli.common import OK, add_instance_arguments, load_instance_from_args
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import UNREACHABLE

HELP = "describe an instance (size, agents, lower bounds, quick infeasibility) or the solvers"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p, optional=True)  # INSTANCE is optional with --solvers
    p.add_argument(
        "--solvers",
        action="store_true",
        help="list the registered solvers with their options (set with `hierplan solve --set`)",
    )


def run(args: argparse.Namespace) -> int:
    if args.solvers:
        for line in solver_lines():
            print(line)
        if args.instance is None:
            return OK
    if args.instance is None:
        raise InputError("give an INSTANCE file (or --solvers)")

    for line in instance_lines(load_instance_from_args(args)):
        print(line)
    return OK


def instance_lines(instance) -> list[str]:
    """The report lines for one instance.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)], name="t")
    >>> for line in instance_lines(inst)[:3]:
    ...     print(line)
    instance: t
    graph: grid 3x1, 3 free cells, 0 blocked, 2 edges, cell_size 1
    problem: MAPF, 1 agents
    """
    from hierplan_opt.core.feasibility import quick_infeasibility

    g = instance.graph
    out = [f"instance: {instance.name}"]
    if g.kind == "grid":
        size = "x".join(map(str, g.shape))
        kind = "3D grid" if len(g.shape) == 3 else "grid"
        out.append(
            f"graph: {kind} {size}, {g.num_vertices} free cells, {g.n - g.num_vertices} "
            f"blocked, {g.num_edges} edges, cell_size {g.cell_size:g}"
        )
    else:
        out.append(
            f"graph: roadmap, {g.n} vertices, {g.num_edges} "
            f"{'directed ' if g.directed else ''}edges"
        )
    if instance.is_tapf:
        sizes = ", ".join(f"{t.name}={len(t.agents)}" for t in instance.teams)
        out.append(
            f"problem: TAPF, {instance.num_agents} agents in {len(instance.teams)} teams ({sizes})"
        )
    else:
        out.append(f"problem: MAPF, {instance.num_agents} agents")
    kins = sorted({a.kinematics.robot_type for a in instance.agents})
    out.append(f"robot types: {', '.join(kins)}")
    if instance.highways is not None:
        out.append(f"highways: {len(instance.highways)} directed edges")
    soc, mk = instance.soc_lower_bound(), instance.makespan_lower_bound()
    out.append(f"soc lower bound: {soc if soc < UNREACHABLE else '- (a goal is unreachable)'}")
    out.append(f"makespan lower bound: {mk if mk < UNREACHABLE else '- (a goal is unreachable)'}")
    reason = quick_infeasibility(instance)
    if reason is None:
        out.append("infeasible: not shown by the quick checks")
    else:
        out.append(f"infeasible: yes, {reason}")
    return out


def solver_lines() -> list[str]:
    """Per registered solver: name, problems, objectives, kind, description and options.

    Example
    -------
    >>> any(line.startswith("cbs ") for line in solver_lines())
    True
    """

    out = []
    for name in registry.names():
        info = registry.get(name)
        problems = "/".join(sorted(p.upper() for p in info.problems))
        objectives = "/".join(sorted(info.objectives))
        kind = "optimal" if info.optimal else "bounded" if info.bounded else "heuristic"
        out.append(f"{name:10s} {problems:10s} {objectives:13s} {kind}")
        if info.description:
            out.append(f"{'':10s} {info.description}")
        spec = info.load().options
        out.extend(f"{'':10s}   {o.describe()}" for o in spec)
        if not len(spec):
            out.append(f"{'':10s}   (no options)")
    return out
