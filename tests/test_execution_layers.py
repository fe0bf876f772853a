"""Each execution layer alone, on an :class:`ExecState` built without the event loop
(issue 30 item 3): slack, STN re-solve, ADG, re-order, re-plan frontier."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt.execution import ExecState, layers
from hierplan_opt.execution.reorder import arc_locks, try_reorder
from hierplan_opt.execution.replan import restrict_to_frontier
from hierplan_opt.schedule import check_bounds, postprocess

ROOT = Path(__file__).resolve().parent.parent


def state_of(inst, s, policy: str) -> ExecState:
    st = ExecState(inst, s, [], policy, 0, "auto", 30.0)
    targets = layers.initial_targets(policy, np.array(s.times, dtype=float))
    latest = layers.latest_times(policy, s.latest, targets)
    st.start_phase(s, s.stn, tuple(range(inst.num_agents)), targets, 0.0, arc_locks(s.stn), latest)
    return st


@pytest.fixture(scope="module")
def warehouse():
    inst = hp.load_instance(ROOT / "instances" / "paper" / "warehouse-part1.yaml")
    res = hp.solve(inst, "cbm", time_limit=60)
    assert res.plan is not None
    return inst, postprocess(inst, res.plan)


def node_with_slack(s, at_least: float) -> int:
    tpg = s.stn.tpg
    for v in range(tpg.num_nodes):
        if v > 0 and tpg.node_agent[v - 1] == tpg.node_agent[v] and s.slack[v] > at_least:
            return v
    raise AssertionError("no node with that much slack")


def test_slack_layer_absorbs_within_slack_and_escalates_beyond(warehouse) -> None:
    inst, s = warehouse
    st = state_of(inst, s, "stn")
    v = node_with_slack(s, 2.0)
    st.phys[v] = st.T[v] + 1.0
    assert layers.slack_decision(st, v)[0] == "absorbed"
    st.phys[v] = st.T[v] + float(s.slack[v]) + 1.0
    verdict, late, _ = layers.slack_decision(st, v)
    assert verdict == "escalate" and late == pytest.approx(float(s.slack[v]) + 1.0)
    st.phys[v] = st.T[v]
    assert layers.slack_decision(st, v)[0] == "on time"
    # The slack policy never escalates.
    st2 = state_of(inst, s, "slack")
    st2.phys[v] = st2.T[v] + float(s.slack[v]) + 1.0
    assert layers.slack_decision(st2, v)[0] == "absorbed"


def test_stn_layer_pushes_successors_and_meets_every_bound(warehouse) -> None:
    inst, s = warehouse
    st = state_of(inst, s, "stn")
    v = node_with_slack(s, 0.5)
    st.t[v - 1] = s.times[v - 1]  # the robot left on time
    late = float(s.slack[v]) + 3.0
    st.phys[v] = st.T[v] + late
    before = st.T.copy()
    layers.stn_resolve(st, v, float(s.times[v - 1]))
    assert st.T[v] == pytest.approx(before[v] + late)
    assert st.counts["stn_resolves"] == 1
    assert check_bounds(st.stn, st.T) == []
    assert np.all(before - 1e-9 <= st.T)  # nothing moved earlier


def test_adg_layer_has_no_targets_and_no_deadlines() -> None:
    t = np.array([0.0, 2.0, 5.0])
    assert layers.initial_targets("adg", t).tolist() == [0, 0, 0]
    assert np.isinf(layers.latest_times("adg", t, t)).all()
    assert layers.initial_targets("replan", t) is t


def test_reorder_layer_proposes_without_changing_the_state(warehouse) -> None:
    inst, s = warehouse
    st = state_of(inst, s, "reorder")
    T, stn = st.T.copy(), st.stn
    for v in range(stn.num_nodes):  # every robot very late at its second node
        if v > 0 and stn.tpg.node_agent[v - 1] == stn.tpg.node_agent[v]:
            st.phys[v] = st.T[v] + 30.0
    out = try_reorder(st, 0.0)
    assert st.stn is stn and np.array_equal(st.T, T)  # a proposal only
    if out is not None:
        new, locks, targets, switched = out
        assert switched >= 1 and new.topo.is_dag and len(targets) == stn.num_nodes


def test_replan_frontier_stops_robots_before_a_broken_one() -> None:
    g = hp.Graph.grid(7, 3)
    inst = hp.Instance.mapf(g, [(0, 1), (3, 1)], [(6, 1), (3, 2)])
    res = hp.solve(inst, "cbs")
    assert res.plan is not None
    s = postprocess(inst, res.plan)
    st = state_of(inst, s, "replan")
    ptr = s.stn.tpg.agent_ptr
    st.t[ptr[0]] = st.t[ptr[1]] = 0.0  # both at their starts
    st.record(0, 0.0, np.array([0.0, 1.0]))
    st.record(1, 0.0, np.array([3.0, 1.0]))
    st.broken[1] = True
    coords = s.stn.tpg.node_coord
    at = [v for v in range(ptr[0], ptr[1]) if np.allclose(coords[v], [3, 1])]
    st.geo_block = {0: at[0]}  # agent0's first node at (3, 1)
    restrict_to_frontier(st, 0.0)
    nodes0 = np.arange(ptr[0], ptr[1])
    reach = s.stn.tpg.node_coord[nodes0[st.active[nodes0]]]
    assert reach[:, 0].max() < 3  # agent0 never reaches the broken robot's cell
