"""libMultiRobotPlanning's problem variants, solved with this toolkit's solvers.

* **Task-free robots** (``potentialGoals: []`` in libMRP's ``cbs_ta`` files): a robot
  without a task ends wherever it likes and must only keep out of the others' way; its
  cost is the time of its last move, like every robot's. The file readers mark them in
  ``instance.meta["free_agents"]`` (their names; each is a team of one whose target is a
  placeholder). :func:`solve_free_robots` enumerates end vertices for them, cheapest
  lower bound first, solves each choice with the named solver and stops when no
  remaining choice can beat the best plan: with an optimal solver the result is optimal
  (OPTIMAL), otherwise, or when the time runs out first, FEASIBLE.
* **Agents that disappear at their goals** (libMRP's ``--disappear-at-goal``): an agent
  stops occupying anything after it arrives. :func:`disappear_at_goals` reduces this to
  ordinary MAPF on a directed roadmap: every agent gets a private exit vertex, reached by
  one one-way arc from its goal, as its new goal; an agent standing in its exit has left.
  The reduced plan passes the ordinary validator on the reduced instance; its sum of costs
  is libMRP's plus one step per agent (:func:`from_disappeared` maps it back).

Example
-------
>>> from hierplan_opt.core.graph import Graph
>>> from hierplan_opt.core.instance import Instance
>>> g = Graph.grid(5, 1)
>>> inst = Instance.mapf(g, [(4, 0), (3, 0)], [(4, 0), (3, 0)])
>>> red = disappear_at_goals(inst)
>>> red.graph.num_vertices, red.graph.directed
(7, True)
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import replace
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.instance import Agent, Instance, Team
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.core.validate import validate

log = logging.getLogger(__name__)

#: Joint end-vertex choices :func:`solve_free_robots` enumerates at most.
MAX_CHOICES = 20_000


# ------------------------------------------------------------ agents that disappear
def disappear_at_goals(instance: Instance) -> Instance:
    """The MAPF instance in which each agent leaves through a private exit at its goal.

    Vertices keep their ids (grids become directed roadmaps named by their coordinates);
    exit ``i`` is vertex ``n + i``, reached only by the arc ``goal_i -> exit_i``. Two
    agents may share a goal here (each has its own exit).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> red = disappear_at_goals(inst)
    >>> red.agents[0].goal, red.graph.location(2)
    (2, 'exit:agent0')
    """
    if instance.is_tapf:
        raise InputError("agents that disappear at their goals need MAPF goals (not teams)")
    g = instance.graph
    names: list[str] = []
    pos: dict[str, tuple[float, ...]] = {}
    for v in range(g.n):
        loc = g.location(v)
        name = loc if isinstance(loc, str) else ",".join(str(c) for c in loc)
        names.append(name if g.passable[v] else f"blocked:{name}")
        pos[names[-1]] = tuple(float(c) for c in g.position(v))
    arcs = sorted({(u, v) for u, v in g.edges()} | {(v, u) for u, v in g.edges() if not g.directed})
    arcs_named: list[tuple[str, str, float]] = [
        (names[u], names[v], g.edge_length(u, v)) for u, v in arcs
    ]
    for a in instance.agents:
        assert a.goal is not None
        exit_name = f"exit:{a.name}"
        pos[exit_name] = pos[names[a.goal]]
        arcs_named.append((names[a.goal], exit_name, 1.0))  # drawn where the goal is
    red = Graph.roadmap(pos, arcs_named, directed=True)
    if red.n != g.n + instance.num_agents or any(
        red.vertex(names[v]) != v for v in range(g.n)
    ):  # Graph.roadmap numbers vertices in insertion order; checked, not assumed
        raise AssertionError("vertex ids changed in the reduction")
    agents = tuple(
        Agent(a.name, a.start, g.n + i, None, a.kinematics) for i, a in enumerate(instance.agents)
    )
    meta = {**instance.meta, "disappear_at_goal": True}
    return Instance(red, agents, (), None, instance.name, meta)


def from_disappeared(instance: Instance, result: Result) -> Result:
    """``result`` of :func:`disappear_at_goals`'s instance in libMRP's terms: every path
    without its step into the exit (it ends at the goal, where the agent disappears), the
    cost and bound less one step per agent, ``stats["disappear_at_goal"] = True``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> r = Result(Status.OPTIMAL, Plan(((0, 1, 2),)), 2, 2, objective="soc")
    >>> back = from_disappeared(inst, r)
    >>> back.plan.paths, back.cost
    (((0, 1),), 1)
    """
    k = instance.num_agents
    stats = {**result.stats, "disappear_at_goal": True}
    if result.objective != "soc":
        raise InputError("agents that disappear at their goals: only the sum of costs")
    if result.plan is None:
        lb = None if result.lower_bound is None else max(0, result.lower_bound - k)
        return replace(result, lower_bound=lb, stats=stats)
    paths = []
    for p in result.plan.paths:
        last = next(i for i, v in enumerate(p) if v >= instance.graph.n)
        paths.append(tuple(p[:last]))
    plan = Plan(tuple(paths))
    lb = None if result.lower_bound is None else result.lower_bound - k
    cost = None if result.cost is None else result.cost - k
    return replace(result, plan=plan, cost=cost, lower_bound=lb, stats=stats)


def solve_disappearing(
    name: str, instance: Instance, *, time_limit: float | None = None, **kwargs: Any
) -> Result:
    """Solve ``instance`` with agents that disappear at their goals (libMRP's
    ``--disappear-at-goal``) by solver ``name`` on :func:`disappear_at_goals`' reduction.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 1)
    >>> inst = Instance.mapf(g, [(4, 0), (3, 0)], [(4, 0), (3, 0)])
    >>> r = solve_disappearing("cbs", inst)
    >>> r.status.value, r.cost
    ('OPTIMAL', 0)
    """
    red = disappear_at_goals(instance)
    res = registry.run(name, red, time_limit=time_limit, **kwargs)
    if res.plan is not None:
        bad = validate(red, res.plan)
        if bad:
            return replace(res, status=Status.ERROR, plan=None, stats={"error": str(bad[0])})
    return from_disappeared(instance, res)


# ------------------------------------------------------------------- task-free robots
def free_agents(instance: Instance) -> list[int]:
    """Indices of the task-free robots (``instance.meta["free_agents"]``: their names)."""
    names = set(instance.meta.get("free_agents", ()))
    return [i for i, a in enumerate(instance.agents) if a.name in names]


def with_ends(instance: Instance, free: list[int], ends: tuple[int, ...]) -> Instance:
    """``instance`` with each task-free robot ``free[j]`` ending at ``ends[j]``: MAPF when
    every team has one robot, else TAPF (the free robots' teams get their end)."""
    meta = {k: v for k, v in instance.meta.items() if k != "free_agents"}
    end_of = dict(zip(free, ends, strict=True))
    if all(len(t.agents) == 1 for t in instance.teams):
        goals = [
            end_of.get(i, instance.teams[a.team].targets[0] if a.team is not None else a.goal)
            for i, a in enumerate(instance.agents)
        ]
        agents = tuple(
            Agent(a.name, a.start, int(gv), None, a.kinematics)  # type: ignore[arg-type]
            for a, gv in zip(instance.agents, goals, strict=True)
        )
        return Instance(instance.graph, agents, (), instance.highways, instance.name, meta)
    teams = tuple(
        Team(t.name, t.agents, (end_of[t.agents[0]],)) if t.agents[0] in end_of else t
        for t in instance.teams
    )
    return replace(instance, teams=teams, meta=meta)


def solve_free_robots(
    name: str,
    instance: Instance,
    *,
    time_limit: float | None = None,
    objective: str | None = None,
    **kwargs: Any,
) -> Result:
    """Solve ``instance`` whose :func:`free_agents` may end anywhere, with solver
    ``name`` (see the module text). ``stats["free_ends"]`` counts the choices solved;
    the plan is one of :func:`solved_free_robots`' instance (the free robots' ends fixed).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.tapf(g, [([(0, 0)], [(4, 0)]), ([(1, 0)], [(1, 0)])])
    >>> inst.meta["free_agents"] = ["agent1"]
    >>> r = solve_free_robots("cbs", inst)
    >>> r.status.value, r.cost, r.plan.paths[1][-1] == g.vertex((2, 1))
    ('OPTIMAL', 6, True)
    """
    return solved_free_robots(name, instance, time_limit=time_limit, objective=objective, **kwargs)[
        0
    ]


def solved_free_robots(
    name: str,
    instance: Instance,
    *,
    time_limit: float | None = None,
    objective: str | None = None,
    **kwargs: Any,
) -> tuple[Result, Instance]:
    """:func:`solve_free_robots`' result and the instance its plan solves (the task-free
    robots' ends fixed; ``instance`` itself when there is no plan)."""
    deadline = Deadline(time_limit)
    free = free_agents(instance)
    if not free:
        res = registry.run(name, instance, time_limit=time_limit, objective=objective, **kwargs)
        return res, instance
    g = instance.graph
    taken = {
        v for ti, t in enumerate(instance.teams) if t.agents[0] not in free for v in t.targets
    } | {a.goal for i, a in enumerate(instance.agents) if a.goal is not None and i not in free}
    cands = []
    for i in free:
        d = g.dist_from(instance.agents[i].start)
        cands.append(
            sorted(
                (int(d[v]), v)
                for v in range(g.n)
                if g.passable[v] and v not in taken and d[v] < UNREACHABLE
            )
        )
    total = 1
    for c in cands:
        total *= len(c)
    if total > MAX_CHOICES:
        raise InputError(
            f"{len(free)} task-free robots have {total} joint end choices (more than "
            f"{MAX_CHOICES}); give them goals"
        )
    choices = [
        combo for combo in itertools.product(*cands) if len({v for _, v in combo}) == len(combo)
    ]
    best: Result | None = None
    best_inst = instance
    proven = True  # every choice that could beat the best was solved to optimality
    solved = 0
    used_objective = objective
    lbs: list[tuple[int, tuple[int, ...]]] = []
    for combo in choices:
        ends = tuple(v for _, v in combo)
        inst = with_ends(instance, free, ends)
        if used_objective is None:
            used_objective = registry.get(name).objective_for(inst, None)
        bound = inst.soc_lower_bound() if used_objective == "soc" else inst.makespan_lower_bound()
        lbs.append((bound, ends))
    lbs.sort()
    lower = lbs[0][0] if lbs else None
    stopped: dict[str, Any] = {}  # why an inner search stopped early, if one did
    for bound, ends in lbs:
        if best is not None and best.cost is not None and bound >= best.cost:
            break
        if time_limit is not None and deadline.expired():
            proven = False
            break
        inst = with_ends(instance, free, ends)
        remaining = None if time_limit is None else max(0.01, deadline.remaining())
        r = registry.run(name, inst, time_limit=remaining, objective=used_objective, **kwargs)
        solved += 1
        if r.stats.get("stopped_by") == "memory_limit" and not r.solved:
            # out of memory: the next choice of ends would stop the same way
            stopped = {k: r.stats[k] for k in ("stopped_by", "reason") if k in r.stats}
            proven = False
            break
        if r.status is Status.INFEASIBLE:
            continue
        if r.status is not Status.OPTIMAL:
            proven = False
        if r.solved and (best is None or (r.cost or 0) < (best.cost or 0)):
            best, best_inst = r, inst
    stats: dict[str, Any] = {"free_ends": solved, "free_agents": len(free)}
    if best is None:
        stats.update(stopped)
        status = Status.INFEASIBLE if proven and solved == len(lbs) else Status.TIME_LIMIT
        res = Result(status, None, lower_bound=lower, solver=name, stats=stats)
        return replace(res, objective=used_objective or "soc"), instance
    stats.update({k: v for k, v in best.stats.items() if k not in stats})
    status = Status.OPTIMAL if proven else Status.FEASIBLE
    lb = best.cost if proven else lower
    return replace(best, status=status, lower_bound=lb, stats=stats), best_inst


# ---------------------------------------------------------- annotated roadmaps' conflicts
#: Solvers that honour ``instance.meta["edge_conflicts"]`` (annotated roadmaps).
ANNOTATED_SOLVERS = ("cpsat", "mip")


def annotated_violations(instance: Instance, plan: Plan) -> list[str]:
    """One line per pair of robots making two moves that an annotated roadmap's extra
    conflicts forbid at the same time (``instance.meta["edge_conflicts"]``; a robot past
    the end of its path waits at its last vertex).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.roadmap({"A": (0, 0), "B": (2, 2), "C": (0, 2), "D": (2, 0)},
    ...                   [("A", "B"), ("C", "D")])
    >>> inst = Instance.mapf(g, ["A", "C"], ["B", "D"])
    >>> inst.meta["edge_conflicts"] = [((0, 1), (2, 3))]
    >>> annotated_violations(inst, Plan(((0, 1), (2, 3))))
    ["agent0 'A' -> 'B' and agent1 'C' -> 'D' at t=0 (annotated conflict)"]
    """
    extra = instance.meta.get("edge_conflicts") or []
    if not extra:
        return []
    clash: dict[tuple[int, int], set[tuple[int, int]]] = {}
    for m1, m2 in extra:
        clash.setdefault(tuple(m1), set()).add(tuple(m2))  # type: ignore[arg-type]
        clash.setdefault(tuple(m2), set()).add(tuple(m1))  # type: ignore[arg-type]
    g = instance.graph
    out: list[str] = []
    for t in range(plan.makespan + 1):
        moves: dict[tuple[int, int], list[int]] = {}
        for i, p in enumerate(plan.paths):
            a, b = p[min(t, len(p) - 1)], p[min(t + 1, len(p) - 1)]
            moves.setdefault((a, b), []).append(i)
        for m, who in moves.items():
            for other in clash.get(m, ()):
                for i in who:
                    for j in moves.get(other, ()):
                        if i < j:
                            ni, nj = instance.agents[i].name, instance.agents[j].name
                            out.append(
                                f"{ni} {g.label(m[0])} -> {g.label(m[1])} and {nj} "
                                f"{g.label(other[0])} -> {g.label(other[1])} at t={t} "
                                "(annotated conflict)"
                            )
    return out


def checked_form(
    instance: Instance, plan: Plan, *, disappear: bool = False
) -> tuple[Instance, Plan]:
    """The instance and plan that the ordinary validator checks for a libMRP variant: the
    task-free robots' ends fixed where the plan leaves them; with ``disappear``, the
    reduction of :func:`disappear_at_goals` and each path with its step into the exit.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.validate import validate
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0), (1, 0)], [(1, 0), (1, 0)])
    >>> validate(*checked_form(inst, Plan(((0, 1), (1,))), disappear=True))
    []
    """
    free = free_agents(instance)
    if free and plan.num_agents == instance.num_agents:
        instance = with_ends(instance, free, tuple(plan.paths[i][-1] for i in free))
    if not disappear:
        return instance, plan
    red = disappear_at_goals(instance)
    n = instance.graph.n
    paths = tuple((*p, n + i) for i, p in enumerate(plan.paths))
    return red, Plan(paths)
