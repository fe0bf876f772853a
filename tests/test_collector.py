"""The scoped pause of the cyclic garbage collector in search loops (core.collector)."""

from __future__ import annotations

import gc
import threading

import pytest

from hierplan_opt.core.collector import paused_gc
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.registry import run


@pytest.fixture
def enabled():
    was = gc.isenabled()
    gc.enable()
    yield
    if not was:  # pragma: no cover - the suite runs with the collector on
        gc.disable()


def test_off_inside_on_after(enabled) -> None:
    with paused_gc():
        assert not gc.isenabled()
    assert gc.isenabled()


def test_back_on_after_an_exception(enabled) -> None:
    with pytest.raises(KeyError), paused_gc():
        raise KeyError("boom")
    assert gc.isenabled()


def test_nested_back_on_at_the_outermost_exit(enabled) -> None:
    with paused_gc():
        with paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()
    assert gc.isenabled()


def test_leaves_a_disabled_collector_off(enabled) -> None:
    gc.disable()
    try:
        with paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_threads_back_on_after_the_last_exit(enabled) -> None:
    inside = threading.Barrier(3)
    leave = threading.Event()
    errors: list[BaseException] = []

    def work() -> None:
        try:
            with paused_gc():
                inside.wait(5)
                leave.wait(5)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    ts = [threading.Thread(target=work) for _ in range(2)]
    for t in ts:
        t.start()
    inside.wait(5)
    assert not gc.isenabled()
    leave.set()
    for t in ts:
        t.join(5)
    assert not errors
    assert gc.isenabled()


def _pair() -> Instance:
    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    return Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])


def test_cbs_pauses_and_turns_it_back_on(enabled, monkeypatch: pytest.MonkeyPatch) -> None:
    import hierplan_opt.search.cbs_engine as cbs

    inst = _pair()
    assert run("cbs", inst).cost == 8
    assert gc.isenabled()

    def broken(*args: object, **kwargs: object) -> None:
        assert not gc.isenabled()  # off during the search
        raise RuntimeError("low level failed")

    monkeypatch.setattr(cbs, "space_time_astar", broken)
    with pytest.raises(RuntimeError, match="low level failed"):
        run("cbs", inst)
    assert gc.isenabled()


def test_ecbs_pauses_and_turns_it_back_on(enabled, monkeypatch: pytest.MonkeyPatch) -> None:
    import hierplan_opt.search.ecbs_engine as ecbs

    inst = _pair()
    seen: list[bool] = []
    search = ecbs._ECBS.search

    def watched(self: ecbs._ECBS) -> object:
        seen.append(gc.isenabled())
        return search(self)

    monkeypatch.setattr(ecbs._ECBS, "search", watched)
    assert run("ecbs", inst, w=1.5, time_limit=10).cost == 8
    assert run("eecbs", inst, w=1.5, time_limit=10).cost == 8
    assert seen == [False, False]
    assert gc.isenabled()


@pytest.mark.parametrize(
    ("solver", "agents"), [("cbs", 14), ("ecbs", 14), ("eecbs", 14), ("cbs", 4)]
)
def test_searches_leave_no_cyclic_garbage(solver: str, agents: int) -> None:
    # With the collector paused, a cycle made per CT node would stay until the search
    # ends: CBS's exact vertex cover left two closures per call (454,400 objects on
    # random-32-32-20-random-1 k50), and a cycle through the search object left its
    # whole tree to the full collection after the block (3.8 s after 60 s of EECBS).
    rng = __import__("numpy").random.default_rng(7)
    g = Graph.grid(8, 8, blocked=rng.random((8, 8)) < 0.2)
    free = [g.location(int(v)) for v in rng.permutation(g.passable.nonzero()[0])]
    inst = Instance.mapf(g, free[:agents], free[agents : 2 * agents])
    opts = {} if solver == "cbs" else {"w": 1.2}
    run(solver, inst, time_limit=10, **opts)  # warm: caches made once per process
    gc.collect()
    gc.disable()
    try:
        gc.set_debug(gc.DEBUG_SAVEALL)
        r = run(solver, inst, time_limit=10, **opts)
        gc.collect()
        garbage = [type(o).__name__ for o in gc.garbage]
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        gc.enable()
    assert r.plan is not None
    if solver == "cbs" and agents > 4:
        assert r.stats["high_level_expanded"] > 5  # the heuristics ran on real conflicts
    assert garbage == []
