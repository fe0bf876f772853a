"""Property tests: random grids, instances and plans survive every writer and reader."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from io_helpers import same_instance

from hierplan_opt import Graph, Instance, Plan
from hierplan_opt.io import load_instance, load_plan, save_instance, save_plan


@st.composite
def instances(draw: st.DrawFn) -> tuple[Instance, Plan]:
    w = draw(st.integers(1, 7))
    h = draw(st.integers(1, 7))
    d = draw(st.sampled_from([None, None, 1, 2]))
    dims = (w, h) if d is None else (w, h, d)
    n = int(np.prod(dims))
    blocked = draw(st.lists(st.booleans(), min_size=n, max_size=n))
    free = [i for i in range(n) if not blocked[i]]
    if len(free) < 1:
        blocked[0] = False
        free = [0]
    arr = np.array(blocked, dtype=bool).reshape(tuple(reversed(dims)))
    g = Graph.grid(w, h, d, blocked=arr)
    k = draw(st.integers(1, min(4, len(free))))
    starts = draw(st.permutations(free))[:k]
    goals = draw(st.permutations(free))[:k]
    inst = Instance.mapf(g, [g.location(v) for v in starts], [g.location(v) for v in goals])
    # any sequence of on-map vertices is a plan the files must carry (validity aside)
    paths = [[s] + draw(st.lists(st.sampled_from(free), max_size=6)) for s in starts]
    return inst, Plan.from_paths(paths)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances())
def test_random_round_trips(case: tuple[Instance, Plan]) -> None:
    inst, plan = case
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        formats = ["hierplan"]
        if len(inst.graph.shape) == 2:
            formats += ["lmrp", "movingai"]
        for fmt in formats:
            path = d / ("x.map" if fmt == "movingai" else f"{fmt}.yaml")
            save_instance(path, inst, format=fmt)
            scen = d / "x.scen" if fmt == "movingai" else None
            back = load_instance(path, scen=scen)
            assert same_instance(back, inst), fmt
        for suffix in (".yaml", ".json"):
            save_plan(d / f"p{suffix}", inst, plan)
            assert load_plan(d / f"p{suffix}", inst) == plan
