"""Shared builders of the space-time search tests (test_search_core, test_jit_*)."""

from __future__ import annotations

import random

from hierplan_opt.core.graph import Graph


def walk(g: Graph, rng: random.Random, free: list[int], steps: int) -> tuple[int, ...]:
    """A random walk of ``steps`` moves or waits from a random free vertex."""
    p = [rng.choice(free)]
    for _ in range(steps):
        p.append(rng.choice([*g.adj[p[-1]], p[-1]]))
    return tuple(p)
