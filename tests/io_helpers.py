"""Shared helpers of the I/O and CLI tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hierplan_opt import Graph, Instance

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).parent.parent
MOVINGAI = ROOT / "instances" / "movingai"


def same_graph(a: Graph, b: Graph) -> bool:
    """Structural equality of two graphs (Graph has identity equality)."""
    if (a.kind, a.shape, a.directed, a.names, a.cell_size) != (
        b.kind,
        b.shape,
        b.directed,
        b.names,
        b.cell_size,
    ):
        return False
    if not (np.array_equal(a.passable, b.passable) and np.allclose(a.coords, b.coords)):
        return False
    ea = {e: a.edge_length(*e) for e in a.edges()}
    eb = {e: b.edge_length(*e) for e in b.edges()}
    return ea.keys() == eb.keys() and all(abs(ea[e] - eb[e]) < 1e-9 for e in ea)


def same_instance(a: Instance, b: Instance, *, names: bool = True) -> bool:
    """Graph, agents (names, starts, goals, teams, kinematics), teams and highways equal."""
    if not same_graph(a.graph, b.graph):
        return False
    if a.agents != b.agents or a.highways != b.highways:
        return False
    ta = [(t.name if names else "", t.agents, t.targets) for t in a.teams]
    tb = [(t.name if names else "", t.agents, t.targets) for t in b.teams]
    return ta == tb


def write(tmp: Path, name: str, text: str) -> Path:
    """Write ``text`` to ``tmp/name`` and return the path."""
    p = tmp / name
    p.write_text(text, encoding="utf-8")
    return p
