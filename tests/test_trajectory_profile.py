"""The NLP-free path-mode solver (``refine(solver="profile")``, trajectory.profile) and its
QP polish (``solver="profile+qp"``, trajectory.polish)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance, Kinematics
from hierplan_opt.core.plan import Plan
from hierplan_opt.schedule import postprocess
from hierplan_opt.trajectory import InfeasibleWindowsError, refine
from hierplan_opt.trajectory import polish as Q
from hierplan_opt.trajectory import profile as P
from hierplan_opt.trajectory.paths import Limits, RobotPath
from hierplan_opt.trajectory.verify import verify

R = importlib.import_module("hierplan_opt.trajectory.refine")


def crossing() -> tuple[Instance, Plan]:
    # Two robots exchange ends of a 5 x 2 strip (they must pass each other).
    g = Graph.grid(5, 2)
    kin = Kinematics(v_max=1.0, a_max=2.0, radius=0.2)
    inst = Instance.mapf(g, [(0, 0), (4, 0)], [(4, 0), (0, 0)], kinematics=kin)
    res = hp.solve(inst, "cbs", time_limit=10)
    assert res.plan is not None
    return inst, res.plan


def grid_plan() -> tuple[Instance, Plan]:
    g = Graph.grid(6, 4)
    kin = Kinematics(v_max=1.0, a_max=1.0, radius=0.25)
    inst = Instance.mapf(g, [(0, 0), (5, 3), (0, 3)], [(5, 0), (0, 0), (5, 3)], kinematics=kin)
    res = hp.solve(inst, "cbs", time_limit=10)
    assert res.plan is not None
    return inst, res.plan


def line_path(sigma, t, stop) -> RobotPath:
    """A straight 1-D path with knots at ``sigma`` (v_max = a_max = 1)."""
    n = len(sigma)
    one = np.ones(n - 1)
    dirs = np.tile([1.0, 0.0], (n - 1, 1))
    return RobotPath(
        "r", "double_integrator", Limits(1.0, 1.0, np.inf, np.inf), np.asarray(sigma, float),
        np.arange(n), np.asarray(stop), np.asarray(t, float), np.zeros((n, 2)),
        np.zeros(n - 1, bool), dirs, np.zeros(n - 1), one, one, one, 0.0, np.arange(n),
        np.asarray(sigma, float),
    )  # fmt: skip


@pytest.mark.parametrize("case", [crossing, grid_plan])
def test_profile_keeps_windows_limits_and_distance_like_the_nlp(case) -> None:
    inst, plan = case()
    sched = postprocess(inst, plan)
    tp = refine(inst, sched, stretch="auto", solver="profile")
    ti = refine(inst, sched, stretch="auto", solver="ipopt")
    for tr in (tp, ti):
        rep = verify(tr, inst)
        assert rep.ok, rep.message()
        assert rep.min_distance >= tr.safety_distance > 0
        assert rep.max_speed_ratio <= 1 + 1e-5 and rep.max_accel_ratio <= 1 + 1e-5
    assert tp.safety_distance == ti.safety_distance
    # The restricted family never needs less stretch than the NLP (up to its tolerance).
    assert tp.stretch >= ti.stretch * (1 - 2e-3)
    win, net = tp.windows, tp.windows.network
    for j, r in enumerate(tp.robots):
        assert r.stats["solver"] == "profile"
        ev = np.array(list(net.events(j)))
        et = np.asarray(r.event_times)
        assert np.all(et >= win.lo[ev] - 1e-9) and np.all(et <= win.hi[ev] + 1e-9)
        assert np.allclose(r.state(et)["p"], net.pos[ev], atol=1e-9)
        assert np.all(np.diff(et) >= -1e-12)


def test_profile_factor_is_reported_and_works() -> None:
    inst, plan = grid_plan()
    sched = postprocess(inst, plan)
    tr = refine(inst, sched, stretch="auto", solver="profile")
    assert tr.stretch > 1.0
    with pytest.raises(InfeasibleWindowsError, match="stretching the schedule by") as ei:
        refine(inst, sched, solver="profile")
    assert ei.value.stretch == pytest.approx(tr.stretch, rel=2e-3)
    assert verify(refine(inst, sched, stretch=tr.stretch, solver="profile"), inst).ok


def test_profile_is_refused_in_corridor_mode() -> None:
    inst, plan = crossing()
    with pytest.raises(OptionError, match="profile"):
        refine(inst, postprocess(inst, plan), mode="corridor", solver="profile")


def test_late_knots_are_delayed_inside_their_windows() -> None:
    # 2 m in 1 s is beyond v_max = 1: the middle knot (window [1, 5]) is delayed to
    # 2.5 s at least (1 s accelerating, then 1.5 m at 1 m/s), the goal with it.
    path = line_path([0.0, 2.0, 4.0], [0.0, 1.0, 2.0], [True, False, True])
    lo, hi = np.array([0.0, 1.0, 2.0]), np.array([0.0, 5.0, np.inf])
    pr = P.solve(path, 1.0, lo, hi)
    assert pr.ok and pr.delays >= 1
    assert pr.X is not None and pr.U is not None and pr.pp is not None
    t1 = float(pr.X[2][pr.pp.knot_node[1]])
    assert 2.5 - 1e-9 <= t1 <= 5.0
    assert R._feasible(pr.X, pr.U, R.path_bounds(pr.pp, _plain(lo, hi)))
    # With the middle window closing at 2 s nothing helps at factor 1 ...
    assert not P.solve(path, 1.0, lo, np.array([0.0, 2.0, np.inf])).ok
    # ... and the factor is an upper bound of the smallest, 2.5 / 2 (from rest to 1 m/s,
    # then cruise): the shapes' fixed ramp fractions reach 4/3.
    found = P.smallest(path, lo, np.array([0.0, 2.0, np.inf]), 256.0, 1e-4)
    assert found is not None and 1.25 <= found[0] <= 1.34
    assert not P.solve(path, found[0] * 0.999, lo, np.array([0.0, 2.0, np.inf])).ok


class _plain:
    """Windows as bare arrays (what ``path_bounds`` reads)."""

    def __init__(self, lo, hi) -> None:
        self.lo, self.hi, self.stretch = lo, hi, 1.0


def test_reach_intervals_are_exact_for_every_shape() -> None:
    # The interval of end speeds from start speeds in [a, b] equals, on a fine grid, the
    # set of w for which some u makes the shape's inequalities hold.
    rng = np.random.default_rng(3)
    compared = 0
    for _ in range(150):
        d, tau = float(rng.uniform(0, 3)), float(rng.uniform(0.2, 4))
        vmax, amax = float(rng.uniform(0.5, 2)), float(rng.uniform(0.3, 2))
        a = float(rng.uniform(0, vmax))
        b = float(rng.uniform(a, vmax))
        rows = P._tables(np.array([d]), np.array([tau]), np.array([vmax]), np.array([amax]))
        wa, wb, ok = P._reach(a, b, rows[0].tolist())
        u = np.linspace(a, b, 401)[:, None]
        w = np.linspace(0, vmax, 401)[None, :]
        for i, (t1, t2) in enumerate(P.SHAPES.tolist()):
            p = (d / tau - t1 / 2 * u - (1 - t2) / 2 * w) / ((1 + t2 - t1) / 2)
            good = (p >= -1e-12) & (p <= vmax + 1e-12) & (np.abs(p - u) <= amax * t1 * tau)
            good &= np.abs(w - p) <= amax * (1 - t2) * tau
            ws = np.broadcast_to(w, good.shape)[good]
            if ws.size == 0:
                continue  # too thin for the grid to see
            compared += 1
            assert ok[i]
            assert wa[i] <= ws.min() + 1e-9 and wb[i] >= ws.max() - 1e-9
            step = 4 * (vmax + b - a) / 400 * 4
            assert wa[i] >= ws.min() - step and wb[i] <= ws.max() + step
    assert compared > 100


# ---- the QP polish (solver="profile+qp", trajectory.polish) -----------------------------


@pytest.mark.parametrize("case", [crossing, grid_plan])
def test_polish_verifies_and_lowers_the_acceleration_objective(case) -> None:
    inst, plan = case()
    sched = postprocess(inst, plan)
    tp = refine(inst, sched, stretch="auto", solver="profile")
    tq = refine(inst, sched, stretch="auto", solver="profile+qp")
    rep = verify(tq, inst)
    assert rep.ok, rep.message()
    assert rep.max_speed_ratio <= 1 + 1e-5 and rep.max_accel_ratio <= 1 + 1e-5
    assert rep.min_distance >= tq.safety_distance == tp.safety_distance > 0
    assert tq.stretch == tp.stretch
    assert tq.stats["qp_fallbacks"] == 0
    win, net = tq.windows, tq.windows.network
    for j, (p, q) in enumerate(zip(tp.robots, tq.robots, strict=True)):
        assert q.stats["solver"] == "profile+qp" and q.stats["qp_ok"]
        # The knots (events with a window) keep their times; every event stays inside
        # its window; the integral of |a|^2 does not grow.
        ev = np.array(list(net.events(j)))
        knot = (win.lo[ev] > 0) | np.isfinite(win.hi[ev])
        et = np.asarray(q.event_times)
        assert np.allclose(et[knot], np.asarray(p.event_times)[knot], atol=1e-9)
        assert np.all(et >= win.lo[ev] - 1e-9) and np.all(et <= win.hi[ev] + 1e-9)
        ea = float(np.sum(np.diff(p.t) * np.sum(p.a**2, axis=1)))
        eb = float(np.sum(np.diff(q.t) * np.sum(q.a**2, axis=1)))
        assert eb <= ea + 1e-9
        assert q.stats["accel_after"] <= q.stats["accel_before"] + 1e-12
        assert q.stats["accel_before"] == pytest.approx(ea, rel=1e-9, abs=1e-12)
    assert tq.stats["accel_after"] < tq.stats["accel_before"]


def test_polish_of_a_line_is_the_minimum_energy_motion() -> None:
    # 4 m in 6 s from rest to rest, no window in between: the QP on the profile's grid
    # keeps the ends and limits, is no worse than the profile, and no better than the
    # continuous minimum of the integral of a^2 (linear acceleration).
    path = line_path([0.0, 4.0], [0.0, 6.0], [True, True])
    pr = P.solve(path, 1.0, np.array([0.0, 0.0]), np.array([0.0, np.inf]))
    assert pr.ok and pr.pp is not None and pr.X is not None and pr.U is not None

    r = Q.polish(pr.pp, pr.X, pr.U, _plain(np.array([0.0, 0.0]), np.array([0.0, np.inf])))
    assert r.ok, r.status
    assert r.after <= r.before * (1 + 1e-9)
    s, v, t = r.X[0], r.X[1], r.X[2]
    assert s[0] == 0.0 and s[-1] == 4.0 and v[0] == 0.0 and abs(v[-1]) <= 1e-9
    assert np.all(v >= -1e-9) and np.all(v <= 1.0 + 1e-9)
    assert np.all(np.abs(r.U[0]) <= 1.0 + 1e-9)
    assert t[-1] == pytest.approx(6.0)
    # Lower bound: the unconstrained minimum 12 d^2 / T^3 (cubic position, linear a).
    assert r.after >= 12 * 16 / 6**3 - 1e-9


def test_compress_drops_zero_length_intervals_only() -> None:

    path = line_path([0.0, 2.0, 4.0], [0.0, 3.0, 6.0], [True, False, True])
    pr = P.solve(path, 1.0, np.array([0.0, 3.0, 0.0]), np.array([0.0, 3.5, np.inf]))
    assert pr.pp is not None and pr.X is not None and pr.U is not None
    pp, X, U = Q.compress(pr.pp, pr.X, pr.U)
    assert np.all(U[1] > 0) and int(np.sum(pr.U[1] > 0)) == pp.N
    assert np.allclose(X[2, pp.knot_node], pr.X[2, pr.pp.knot_node])
    assert Q.accel_energy(U) == pytest.approx(Q.accel_energy(pr.U))
