"""The re-plan layer's parts (issue 30 item 3): near pairs by grid hashing, distinct
start vertices, the auto solver choice, per re-plan timing."""

from __future__ import annotations

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt.execution import Breakdown, simulate
from hierplan_opt.execution.replan import (
    _distinct_starts,
    near_pairs,
    replan_solver,
)
from hierplan_opt.schedule import postprocess


@pytest.mark.parametrize("dim", [2, 3])
def test_near_pairs_equals_brute_force(dim: int) -> None:
    rng = np.random.default_rng(dim)
    for reach in (0.05, 0.7, 3.0):
        q = rng.random((200, dim)) * 10
        p = rng.random((300, dim)) * 10
        a, b = near_pairs(q, p, reach)
        brute = np.linalg.norm(q[:, None] - p[None], axis=2) < reach
        assert sorted(zip(a.tolist(), b.tolist(), strict=True)) == sorted(
            zip(*[x.tolist() for x in np.nonzero(brute)], strict=True)
        )


def test_distinct_starts_moves_a_robot_between_vertices_to_the_free_end() -> None:
    assert _distinct_starts({3: [7], 1: [7, 8]}) == {1: 8, 3: 7}
    assert _distinct_starts({3: [7], 1: [7]}) is None


def test_auto_solver_choice() -> None:
    assert replan_solver("auto", 100) == "ecbs"
    assert replan_solver("auto", 101) == "lacam"
    assert replan_solver("cbs", 500) == "cbs"


def test_each_replan_reports_its_layer_and_solve_time() -> None:
    g = hp.Graph.grid(7, 3)
    inst = hp.Instance.mapf(g, [(0, 1), (3, 1)], [(6, 1), (3, 2)])
    res = hp.solve(inst, "cbs")
    assert res.plan is not None
    ex = simulate(inst, postprocess(inst, res.plan), disturbances=[Breakdown("agent1", 0.0)])
    (r,) = ex.statistics["replan_runtime"]
    assert r["robots"] == 1 and r["solver"] == "ecbs"
    parts = r["frontier"] + r["solve"] + r["post"] + r["handover"]
    assert 0 < r["solve"] <= r["layer"] and parts <= r["layer"] + 1e-6
