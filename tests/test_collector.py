"""The scoped garbage-collector setting of search loops (core.collector)."""

from __future__ import annotations

import gc
import threading

import pytest

from hierplan_opt.core.collector import GEN0_THRESHOLD, GEN2_NEVER, relaxed_gc
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.registry import run


@pytest.fixture
def thresholds():
    before = gc.get_threshold()
    gc.set_threshold(700, 10, 10)
    yield
    gc.set_threshold(*before)


def test_raised_inside_restored_after(thresholds) -> None:
    with relaxed_gc():
        # No full collection inside: its pauses grow with the search's heap.
        assert gc.get_threshold() == (GEN0_THRESHOLD, 10, GEN2_NEVER)
    assert gc.get_threshold() == (700, 10, 10)


def test_restored_on_exception(thresholds) -> None:
    with pytest.raises(KeyError), relaxed_gc():
        raise KeyError("boom")
    assert gc.get_threshold() == (700, 10, 10)


def test_nested_restores_at_outermost_exit(thresholds) -> None:
    with relaxed_gc():
        with relaxed_gc(5):
            assert gc.get_threshold()[0] == GEN0_THRESHOLD
        assert gc.get_threshold()[0] == GEN0_THRESHOLD
    assert gc.get_threshold() == (700, 10, 10)


def test_never_lowers_and_leaves_disabled_collector(thresholds) -> None:
    gc.set_threshold(500_000, 10, 10)
    with relaxed_gc():
        assert gc.get_threshold() == (500_000, 10, GEN2_NEVER)
    gc.set_threshold(700, 10, 10)
    gc.disable()
    try:
        with relaxed_gc():
            assert gc.get_threshold() == (700, 10, 10)
    finally:
        gc.enable()


def test_threads_restore_after_the_last_exit(thresholds) -> None:
    inside = threading.Barrier(3)
    leave = threading.Event()
    errors: list[BaseException] = []

    def work() -> None:
        try:
            with relaxed_gc():
                inside.wait(5)
                leave.wait(5)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    ts = [threading.Thread(target=work) for _ in range(2)]
    for t in ts:
        t.start()
    inside.wait(5)
    assert gc.get_threshold()[0] == GEN0_THRESHOLD
    leave.set()
    for t in ts:
        t.join(5)
    assert not errors
    assert gc.get_threshold() == (700, 10, 10)


def test_cbs_restores_thresholds(thresholds, monkeypatch: pytest.MonkeyPatch) -> None:
    import hierplan_opt.search.cbs as cbs

    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    assert run("cbs", inst).cost == 8
    assert gc.get_threshold() == (700, 10, 10)

    def broken(*args: object, **kwargs: object) -> None:
        assert gc.get_threshold()[0] == GEN0_THRESHOLD  # raised during the search
        raise RuntimeError("low level failed")

    monkeypatch.setattr(cbs, "space_time_astar", broken)
    with pytest.raises(RuntimeError, match="low level failed"):
        run("cbs", inst)
    assert gc.get_threshold() == (700, 10, 10)


def test_ecbs_relaxes_and_restores(thresholds, monkeypatch: pytest.MonkeyPatch) -> None:
    import hierplan_opt.search.ecbs as ecbs

    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    seen: list[tuple[int, int, int]] = []
    search = ecbs._ECBS.search

    def watched(self: ecbs._ECBS) -> object:
        seen.append(gc.get_threshold())
        return search(self)

    monkeypatch.setattr(ecbs._ECBS, "search", watched)
    assert run("ecbs", inst, w=1.5, time_limit=10).cost == 8
    assert run("eecbs", inst, w=1.5, time_limit=10).cost == 8
    assert seen == [(GEN0_THRESHOLD, 10, GEN2_NEVER)] * 2
    assert gc.get_threshold() == (700, 10, 10)


@pytest.mark.parametrize("solver", ["cbs", "ecbs", "eecbs"])
def test_searches_leave_no_cycles(solver: str) -> None:
    # The trees are freed by reference counting inside the relaxed block (and within
    # the time limit): a cycle through the search object would leave them to the
    # full collection after it (3.8 s after a 60 s EECBS run).
    g = Graph.grid(6, 6)
    inst = Instance.mapf(g, [(0, 0), (5, 0), (0, 5), (5, 5)], [(5, 5), (0, 5), (5, 0), (0, 0)])
    opts = {} if solver == "cbs" else {"w": 1.2}
    run(solver, inst, time_limit=10, **opts)  # warm: caches made once per process
    gc.collect()
    gc.disable()
    try:
        gc.set_debug(gc.DEBUG_SAVEALL)
        run(solver, inst, time_limit=10, **opts)
        gc.collect()
        kinds = {type(o).__name__ for o in gc.garbage}
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        gc.enable()
    assert not {"_ECBS", "_EECBS", "_CBS", "_Node"} & kinds, kinds
