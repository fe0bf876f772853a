"""The contract between the execution monitor and the robots (issues 30 and 33).

The execution monitor runs in simulated continuous time over a *plant*: something that
moves robots. Agent mode, the kinematic robot mode (:class:`KinematicPlant`) and MuJoCo
physics (``hierplan_opt.physics``) implement the same protocol, so the same monitor and
the same layers (slack -> STN re-solve -> re-plan, reorder) handle the delays each plant
makes.

"Reached" means within a plant-specific tolerance of the way-point (kinematic: exact;
physics: e.g. 0.05 m and heading-independent). Physical disturbances (low-friction region,
payload, weaker motor, wind, stop at time t) are configured on the plant itself at
construction - the monitor only sees their effect as lateness. A plant may give
``still_speed`` (m/s): a robot slower than that counts as standing still (a physical
robot's position hold creeps onto its way-point for seconds); without it any motion counts.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


def pad3(p: np.ndarray) -> np.ndarray:
    """Positions with their last axis padded to 3 (x, y, z): plants work in 3D.

    Example
    -------
    >>> pad3(np.array([[1.0, 2.0]])).tolist()
    [[1.0, 2.0, 0.0]]
    """
    p = np.asarray(p, dtype=float)
    if p.shape[-1] == 3:
        return p
    out = np.zeros(p.shape[:-1] + (3,))
    out[..., : p.shape[-1]] = p
    return out


class Plant(Protocol):
    """Robots that follow way-points; the execution monitor drives them.

    Robot i's *route* is a sequence of way-points (metres, shape (k, 3); z = 0 on 2D maps)
    with planned arrival times (seconds, shape (k,)), as the schedule gives them. The robot
    drives through its route in order, aiming to arrive at each way-point at its time (never
    earlier: it waits), and never passes way-point `gate + 1` before the monitor releases it
    (Type-2 arcs: another robot must have left that vertex first).
    """

    time: float  # simulated seconds since the start

    def positions(self) -> np.ndarray:
        """(n_robots, 3) current positions in metres (measured: physics states)."""
        ...

    def assign(self, robot: int, waypoints: np.ndarray, times: np.ndarray) -> None:
        """Replace robot's remaining route (index 0 = the next way-point to reach).
        Resets its gate to -1 (hold) and its reached index to -1."""
        ...

    def release(self, robot: int, gate: int) -> None:
        """Robot may drive up to way-point index `gate` of its current route; it stops at
        (and holds on) way-point `gate` if not released further. -1 = stay where you are."""
        ...

    def retime(self, robot: int, times: np.ndarray) -> None:
        """New planned arrival times for the current route (same length), e.g. after an
        STN re-solve; the robot keeps its gate and progress."""
        ...

    def reached(self, robot: int) -> int:
        """Index of the last way-point of the current route the robot has reached (-1: none)."""
        ...

    def stop(self, robot: int) -> None:
        """Breakdown: the robot stops as fast as it physically can and stays stopped."""
        ...

    def step(self, dt: float) -> None:
        """Advance the world by dt seconds (physics may take several substeps)."""
        ...
