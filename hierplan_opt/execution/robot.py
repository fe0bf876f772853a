"""``robot`` mode: simple robot dynamics on top of the executed event times.

The agent simulation gives every TPG node an executed time that respects the TPG.
Robot mode then drives each robot along its path with a fixed step ``dt``:

* **time-to-go speed control** (the paper's Control section): the speed command is the
  distance to the next node over the time left until its target time (the agent
  simulation's executed time), capped by ``v_max``;
* **bounded acceleration** ``a_max``: the speed changes by at most ``a_max * dt`` per
  step, and the robot brakes in time (``v <= sqrt(2 a d)``) for every point where it
  must stand still: a node whose Type-2 predecessors have not been passed *by the
  robots of this simulation* (the TPG rule, so the clearance theorem still holds), its
  goal, and, for differential drive, a vertex where it turns;
* **differential drive** turns in place at ``omega_max`` (``node_turn / omega_max``).

A robot never passes a node before its Type-2 predecessors (hard, with braking in
time), so the robot-mode run keeps the TPG order; the target times only pace it (the
controller may arrive a little early where it cannot slow down in time, never before
a predecessor). It is later than the agent run where it must accelerate and brake.
Supported for runs without a re-plan (one schedule).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance

if TYPE_CHECKING:
    from hierplan_opt.execution.simulate import _Sim

#: Distance tolerance (metres).
EPS = 1e-9


def robot_run(sim: _Sim, instance: Instance, dt: float) -> tuple[list[np.ndarray], np.ndarray]:
    """Trajectories ``(time, coords...)`` per robot and arrival times of robot mode."""
    if len(sim.phases) > 1:
        raise InputError(
            "robot mode follows one schedule; this run re-planned (use mode='agent' or a "
            "policy without re-planning)"
        )
    phase = sim.phases[0]
    stn = phase.stn
    tpg = stn.tpg
    K = tpg.num_agents
    target = np.array(phase.times, dtype=float)
    cross = tpg.node_agent[stn.arc_src] != tpg.node_agent[stn.arc_dst]
    preds: list[list[tuple[int, float]]] = [[] for _ in range(tpg.num_nodes)]
    if sim.policy == "naive":
        cross[:] = False  # the baseline ignores the TPG here too
    for k in np.flatnonzero(cross).tolist():
        preds[int(stn.arc_dst[k])].append((int(stn.arc_src[k]), float(stn.lb[k])))
    passed = np.full(tpg.num_nodes, np.nan)
    # Per robot: nodes, their distance along the path, coordinates, turn times.
    nodes = [np.arange(int(tpg.agent_ptr[j]), int(tpg.agent_ptr[j + 1])) for j in range(K)]
    s_of = []
    for j in range(K):
        p = tpg.node_pos[nodes[j]]
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1) if len(p) > 1 else np.zeros(0)
        s_of.append(np.concatenate(([0.0], np.cumsum(seg))))
    kin = [a.kinematics for a in instance.agents]
    turn_time = np.zeros(tpg.num_nodes)
    for j in range(K):
        k = kin[j]
        if k.drive == "differential" and k.omega_max:
            turn_time[nodes[j]] = tpg.node_turn[nodes[j]] / k.omega_max
    broken_at = np.full(K, np.inf)
    for g in np.flatnonzero(sim.broken).tolist():
        broken_at[g] = sim.traj[g][-1][0]
    nxt = np.zeros(K, dtype=np.int64)  # index (in nodes[j]) of the next node to pass
    s = np.zeros(K)
    v = np.zeros(K)
    busy_until = np.zeros(K)  # turning in place
    traj: list[list[tuple[float, np.ndarray]]] = [[] for _ in range(K)]
    for j in range(K):
        first = int(nodes[j][0])
        passed[first] = 0.0
        nxt[j] = 1
        busy_until[j] = turn_time[first]
        traj[j].append((0.0, tpg.node_coord[first].astype(float)))
    arrival = np.full(K, np.nan)
    for j in range(K):
        if len(nodes[j]) == 1:
            arrival[j] = 0.0
    horizon = float(np.nanmax(target)) * 3 + 120.0
    t = 0.0
    while t < horizon and np.isnan(arrival).any():
        for j in range(K):
            if not np.isnan(arrival[j]):
                continue
            if t >= broken_at[j]:
                continue
            if t < busy_until[j]:
                continue
            idx = nodes[j]
            k = int(nxt[j])
            n_k = int(idx[k])
            a_max = kin[j].a_max or math.inf
            v_max = kin[j].v_max
            # Where it must be able to stand still: the first node not released, the
            # goal, a vertex where it turns.
            stop_at = s_of[j][-1]
            for m in range(k, len(idx)):
                w = int(idx[m])
                free = all(
                    not np.isnan(passed[u]) and passed[u] + lb <= t + dt for u, lb in preds[w]
                )
                if not free or turn_time[w] > 0:
                    stop_at = s_of[j][m]
                    break
            d_stop = max(stop_at - s[j], 0.0)
            d_next = max(s_of[j][k] - s[j], 0.0)
            left = target[n_k] - t
            v_cmd = v_max if left <= dt else min(v_max, d_next / left)
            if math.isfinite(a_max):
                # Fastest speed after this step from which it still stops in time
                # (trapezoidal step, then braking at a_max).
                room = d_stop - 0.5 * dt * v[j]
                brake = (
                    a_max * (-0.5 * dt + math.sqrt(0.25 * dt * dt + 2 * room / a_max))
                    if room > 0
                    else 0.0
                )
                v_cmd = min(v_cmd, brake)
                v_new = min(max(v_cmd, v[j] - a_max * dt), v[j] + a_max * dt)
            else:
                v_new = v_cmd
            v_new = max(0.0, min(v_new, v_max))
            s_new = min(s[j] + 0.5 * (v[j] + v_new) * dt, stop_at)
            # Pass nodes reached.
            while k < len(idx) and s_new >= s_of[j][k] - EPS:
                w = int(idx[k])
                ok = all(
                    not np.isnan(passed[u]) and passed[u] + lb <= t + dt + EPS for u, lb in preds[w]
                )
                if not ok:
                    s_new = s_of[j][k]
                    v_new = 0.0
                    break
                passed[w] = t + dt
                if turn_time[w] > 0:
                    busy_until[j] = t + dt + turn_time[w]
                    s_new, v_new = s_of[j][k], 0.0
                k += 1
                if k == len(idx):
                    arrival[j] = t + dt
                    break
            nxt[j] = min(k, len(idx) - 1)
            s[j], v[j] = s_new, v_new
            traj[j].append((t + dt, _coords(tpg, idx, s_of[j], s_new)))
        t += dt
    out = []
    for j in range(K):
        pts = traj[j]
        arr = np.array([[p[0], *p[1]] for p in pts], dtype=float)
        # Drop samples where nothing changes (keeps the two ends of every rest).
        keep = np.ones(len(arr), dtype=bool)
        if len(arr) > 2:
            same_prev = np.all(arr[1:-1, 1:] == arr[:-2, 1:], axis=1)
            same_next = np.all(arr[1:-1, 1:] == arr[2:, 1:], axis=1)
            keep[1:-1] = ~(same_prev & same_next)
        out.append(arr[keep])
    return out, arrival


def _coords(tpg, idx: np.ndarray, s_nodes: np.ndarray, s: float) -> np.ndarray:
    """Instance coordinates at path length ``s`` (straight pieces between nodes)."""
    k = int(np.searchsorted(s_nodes, s, side="right")) - 1
    k = min(max(k, 0), len(idx) - 1)
    if k == len(idx) - 1:
        return tpg.node_coord[int(idx[k])].astype(float)
    a, b = tpg.node_coord[int(idx[k])], tpg.node_coord[int(idx[k + 1])]
    span = s_nodes[k + 1] - s_nodes[k]
    f = (s - s_nodes[k]) / span if span > 0 else 0.0
    return a + f * (b - a)
