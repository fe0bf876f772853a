"""The NLP-free path-mode solver (``refine(solver="profile")``, trajectory.profile)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance, Kinematics
from hierplan_opt.core.plan import Plan
from hierplan_opt.schedule import postprocess
from hierplan_opt.trajectory import InfeasibleWindowsError, refine
from hierplan_opt.trajectory import profile as P
from hierplan_opt.trajectory.verify import verify

R = importlib.import_module("hierplan_opt.trajectory.refine")


def crossing() -> tuple[Instance, Plan]:
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    kin = Kinematics(v_max=1.0, a_max=2.0, radius=0.2)
    inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=kin)
    v = g.vertex
    plan = Plan.from_paths(
        [[v((0, 1)), v((1, 1)), v((2, 1))], [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]]
    )
    return inst, plan


def grid_plan() -> tuple[Instance, Plan]:
    g = Graph.grid(6, 4)
    kin = Kinematics(v_max=1.0, a_max=1.0, radius=0.25)
    inst = Instance.mapf(g, [(0, 0), (5, 3), (0, 3)], [(5, 0), (0, 0), (5, 3)], kinematics=kin)
    import hierplan_opt as hp

    res = hp.solve(inst, "cbs", time_limit=10)
    assert res.plan is not None
    return inst, res.plan


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
        assert rep.max_speed_ratio <= 1 + 1e-6 and rep.max_accel_ratio <= 1 + 1e-6
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
        # every knot at the stretched schedule's time
        knots = (win.lo[ev] > 0) | np.isfinite(win.hi[ev])
        assert np.allclose(et[knots], tp.stretch * net.times[ev][knots], atol=1e-9)


def test_profile_stretch_is_the_smallest_for_its_family() -> None:
    inst, plan = grid_plan()
    sched = postprocess(inst, plan)
    tr = refine(inst, sched, stretch="auto", solver="profile")
    assert tr.stretch > 1.0
    with pytest.raises(InfeasibleWindowsError, match="stretching the schedule by") as ei:
        refine(inst, sched, solver="profile")
    assert ei.value.stretch == pytest.approx(tr.stretch, rel=1e-9)
    # 0.1 % less is not enough for the family, the factor is.
    with pytest.raises(InfeasibleWindowsError):
        refine(inst, sched, stretch=tr.stretch * 0.999, solver="profile")
    assert verify(refine(inst, sched, stretch=tr.stretch, solver="profile"), inst).ok


def test_profile_is_refused_in_corridor_mode() -> None:
    inst, plan = crossing()
    from hierplan_opt.core.errors import OptionError

    with pytest.raises(OptionError, match="profile"):
        refine(inst, postprocess(inst, plan), mode="corridor", solver="profile")


def test_forward_intervals_are_exact_for_one_segment() -> None:
    # One segment between two free knots: the interval of end speeds from a start speed
    # interval equals, on a fine grid, the set of w for which some u makes the
    # segment's linear inequalities hold.
    rng = np.random.default_rng(3)
    for _ in range(200):
        d, tau = float(rng.uniform(0, 3)), float(rng.uniform(0.2, 4))
        vmax, amax = float(rng.uniform(0.5, 2)), float(rng.uniform(0.3, 2))
        ra = float(rng.uniform(0, vmax))
        rb = float(rng.uniform(ra, vmax))
        fl = P.Fleet(
            (), np.zeros(1, dtype=np.int64), np.array([[d]]), np.array([[tau]]),
            np.array([[vmax]]), np.array([[amax]]), np.array([[False]]), np.array([1]),
        )  # fmt: skip
        pos, lo, up, cand = P._segments(fl, 1.0)
        u = np.linspace(ra, rb, 301)[:, None]
        w = np.linspace(0, vmax, 301)[None, :]
        p = 2 * d / tau - (u + w) / 2
        A = amax * tau / 2
        ok = (p >= -1e-12) & (p <= vmax + 1e-12) & (np.abs(p - u) <= A + 1e-12)
        ok &= np.abs(w - p) <= A + 1e-12
        ws = np.broadcast_to(w, ok.shape)[ok]
        # forward from a knot whose interval is [ra, rb]
        B = 1
        ra_ = np.array([ra])
        rb_ = np.array([rb])
        uu = np.clip(np.concatenate([cand[:, 0], ra_[:, None], rb_[:, None]], 1), ra, rb)
        L = np.max(lo[:, 0, None, :] + P._SL * uu[:, :, None], -1)
        U = np.min(up[:, 0, None, :] + P._SL * uu[:, :, None], -1)
        good = L <= U + P.TOL
        assert B == 1
        if ws.size == 0:
            continue  # grid too coarse to see a thin polygon; nothing to compare
        assert good.any()
        wa = max(np.where(good, L, np.inf).min(), 0.0)
        wb = np.where(good, U, -np.inf).max()
        step = vmax / 300 + (rb - ra) / 300 * 3
        assert wa <= ws.min() + 1e-9 and wb >= ws.max() - 1e-9
        assert wa >= ws.min() - step and wb <= ws.max() + step
