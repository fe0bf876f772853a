"""Which low level runs: the pure-Python searches or their compiled (numba) twins.

Three searches have a twin: CBS's space-time A* (:func:`.astar.space_time_astar`, kernel
module ``_astar_kernel``), the earliest-arrival search of its corridor reasoning
(:func:`.symmetry.travel_time`, the same module; :func:`travel`) and the focal search of
ECBS / EECBS (:func:`.focal.focal_path`, ``_focal_kernel``; :func:`run_focal`). Each pair
gives identical results (same path, same bound, same expansion count, same
tie-breaking; the same earliest time), so the choice only changes the speed. Both kernel
modules are loaded, compiled and cached together, and one policy picks for all three.
``HIERPLAN_LOW_LEVEL`` (or :func:`set_low_level`) picks:

``auto`` (default)
    Python first. Once the Python low level (A* and focal calls together) has spent
    :data:`JIT_AFTER_S` seconds in one solve (:func:`new_solve` starts the count), a
    helper process compiles the kernels into numba's on-disk cache (about 15 s of CPU
    the first time on a fresh checkout, the A* and the focal kernel; about 1 s once
    cached; on the other core, so it does not slow the search, which a compiling thread
    would through the GIL); when it is done, the next call loads the kernels from the
    cache (a pause of about 0.6 s) and runs them. A small solve never imports numba;
    a long one is never blocked by the compiler. Should the helper outlive its parent,
    it finishes writing the cache. In a process where an earlier solve loaded the
    kernel, a solve switches after :data:`JIT_WARM_S_PER_VERTEX` seconds of Python low
    level per vertex of the map instead (0.5 ms on a 32x32 grid, 5 ms on
    warehouse-10-20-10-2-1): the kernel's set-up per map is made once per process (the
    graph's arrays, kept per ``Graph.adj``, which graphs of one map share), but its
    conflict table (time steps times vertices) is made per solve.
``python``
    Never the kernel.
``jit``
    The kernel from the first call on (loaded synchronously; an error if numba is missing).

The conflict-avoidance table reaches the kernel as a :class:`CatMirror`: dense count
arrays that :class:`~hierplan_opt.search.reservations.Reservations` keeps up to date as
paths are added and removed, so a call does not convert the table. CBS's own table is
taken over by a :class:`DenseMirror` (the paths too, and ``conflicts_of``), and MDDs
built by the kernel stay its arrays (:func:`mdd_singles`, :func:`mdd_restrict`) until
their levels are asked for (:func:`mdd_levels`).

Example
-------
>>> set_low_level("python")
>>> kernel(9) is None
True
>>> set_low_level(None)  # back to HIERPLAN_LOW_LEVEL / auto
"""

from __future__ import annotations

import logging
import math
import os
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence
from time import perf_counter
from types import ModuleType
from typing import Any

import numpy as np

from hierplan_opt.core import graph as core_graph
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search.conflicts import Conflict
from hierplan_opt.search.constraints import AgentConstraints
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.spacetime import Moves, SearchTimeout, successors

log = logging.getLogger(__name__)

MODES = ("auto", "python", "jit")
#: Seconds of Python low-level search in one solve after which ``auto`` loads the kernel.
JIT_AFTER_S = 0.5
#: The same once the kernel is loaded (an earlier solve of the process loaded it), per
#: vertex of the map: no pause to pay then, only the kernel's per-solve set-up, whose
#: dense conflict table (``DenseMirror``: time steps times vertices and moves) grows
#: with the map. Measured in one warm process on the reference instances under 0.5 s
#: (medians of 11 interleaved runs; see docs/cbs.md, "Fixed costs of small solves").
JIT_WARM_S_PER_VERTEX = 5e-7
#: ``forbid_from`` / ``park_t`` value meaning "never" (as reservations.NEVER).
NEVER = 1 << 60
#: The focal kernel reads the clock by Linux's id of ``CLOCK_MONOTONIC``.
_LINUX = sys.platform.startswith("linux")

_mode: str | None = None
_kernel: ModuleType | None = None
_focal: ModuleType | None = None  # the focal kernel, loaded with _kernel
_loading = False
_failed = False
_cached = False  # the compiler process is done: the kernels are in the cache
_proc: subprocess.Popen[bytes] | None = None
_lock = threading.Lock()
#: Seconds the Python low level has run in the current solve (see :func:`new_solve`).
python_seconds = 0.0


def set_low_level(mode: str | None) -> None:
    """Force ``"python"``, ``"jit"`` or ``"auto"``; None re-reads ``HIERPLAN_LOW_LEVEL``."""
    global _mode
    if mode is not None and mode not in MODES:
        raise OptionError(f"low level {mode!r}: expected one of {', '.join(MODES)}")
    _mode = mode


def low_level() -> str:
    """The mode in force (``HIERPLAN_LOW_LEVEL``, default ``auto``)."""
    global _mode
    if _mode is None:
        m = os.environ.get("HIERPLAN_LOW_LEVEL", "auto").strip().lower() or "auto"
        if m not in MODES:
            raise OptionError(f"HIERPLAN_LOW_LEVEL={m!r}: expected one of {', '.join(MODES)}")
        _mode = m
    return _mode


def new_solve() -> None:
    """A solver starts: ``auto`` counts Python low-level time from zero again, and the
    arrays kept per distance list and constraint set (A* and focal) are dropped: they
    held earlier solves' lists and constraints alive (up to 1,024 distance lists, on
    warehouse-10-20-10-2-1 10k entries each, for nothing once their graph is gone).
    """
    global python_seconds
    python_seconds = 0.0
    _ARRAYS.clear()
    _CONS.clear()
    _FCONS.clear()


def note_python(seconds: float) -> None:
    """Account Python low-level time; in ``auto`` mode start loading the kernel in time.

    Only a solve that has itself spent :data:`JIT_AFTER_S` seconds there starts the
    compiler process or pays the pause of loading the kernel, so a small solve never
    does, also in a process where a large one ran before.
    """
    global python_seconds, _proc, _failed, _cached
    python_seconds += seconds
    if python_seconds < JIT_AFTER_S or _failed or _kernel is not None:
        return
    if _proc is not None:
        code = _proc.poll()
        if code is None:
            return
        _proc = None
        if code != 0:
            _failed = True
            log.info("compiling the low level failed (exit %s): staying with Python", code)
            return
        _cached = True
    if _cached:
        _load_cached()
    elif not _loading and low_level() == "auto":
        _start_loading()


def kernel(n: int) -> ModuleType | None:
    """The loaded kernel module if the compiled low level should run now, else None
    (``n``: the graph's vertices, for ``auto``'s switch once the kernel is loaded)."""
    k = _kernel
    m = _mode if _mode is not None else low_level()
    if m == "python":
        return None
    if k is None and m == "jit":
        k = load()
    elif m == "auto" and python_seconds < (JIT_AFTER_S if k is None else n * JIT_WARM_S_PER_VERTEX):
        return None  # a short solve stays in Python, also once a long one loaded the kernel
    return k


def focal_kernel(n: int) -> ModuleType | None:
    """The loaded focal kernel module if the compiled low level should run now, else None
    (the policy of :func:`kernel`).

    Example
    -------
    >>> set_low_level("python")
    >>> focal_kernel(9) is None
    True
    >>> set_low_level(None)
    """
    if not _LINUX:  # the kernel reads the clock by Linux's id of CLOCK_MONOTONIC
        return None
    return _focal if kernel(n) is not None else None


def load() -> ModuleType:
    """Import numba and the kernels and run them once (compiles or reads the cache)."""
    global _kernel, _focal, _failed
    with _lock:
        if _kernel is not None:
            return _kernel
        try:
            from hierplan_opt.search import _astar_kernel as k  # heavy module: numba
            from hierplan_opt.search import _focal_kernel as fk  # heavy module: numba

            drop_stale_cache(fk, k.__file__)
            _warm_up(k)
            _warm_up_focal(k, fk)
        except Exception:
            _failed = True
            raise
        _focal = fk
        _kernel = k
        # The distance tables of later solves come from the compiled BFS too.
        core_graph.set_compiled_bfs(k.bfs_many)
        return k


def drop_stale_cache(module: ModuleType, source: str) -> int:
    """Drop the on-disk cache entries of ``module``'s kernels older than ``source``;
    how many.

    numba checks a cached function against the file that defines it only. The focal
    kernel calls functions of the A* kernel's file (``_contains``, ``_hslot``,
    ``_rehash``, ``_grow``, ``_path_of``), so after an edit of ``_astar_kernel.py``
    alone its cache would still hold a loop compiled with the old ones; :func:`load`
    drops those entries first, and they are compiled again.
    """
    try:
        newest = os.path.getmtime(source)
    except OSError:
        return 0
    dropped = 0
    for obj in list(vars(module).values()):
        if getattr(getattr(obj, "py_func", None), "__module__", None) != module.__name__:
            continue
        cache = getattr(obj, "_cache", None)
        index = getattr(getattr(cache, "_cache_file", None), "_index_path", None)
        try:
            stale = index is not None and os.path.getmtime(index) < newest
        except OSError:  # nothing cached yet
            continue
        if stale and cache is not None:
            cache.flush()
            dropped += 1
    return dropped


def compile_to_cache() -> None:
    """The helper process: load (compile) the kernels; exit 3 if they cannot be cached.

    Loading uncached kernels in the solving process would compile them again there (a
    pause of seconds), so ``auto`` then stays with Python.
    """
    k = load()
    assert _focal is not None
    for f in (k.astar, _focal.focal):
        if type(f._cache).__name__ == "NullCache":  # no writable cache location
            raise SystemExit(3)


def _start_loading() -> None:
    """Compile (or find in the cache) the kernels in a helper process."""
    global _loading, _proc, _failed
    _loading = True
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(x for x in (root, env.get("PYTHONPATH")) if x)
    try:
        _proc = subprocess.Popen(
            [sys.executable, "-c", "from hierplan_opt.search import jit; jit.compile_to_cache()"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
    except OSError as e:
        _failed = True
        log.info("cannot start the compiler process (%s): staying with Python", e)


def _load_cached() -> None:
    """Load the kernels the helper process left in the cache (about 0.6 s, numba's
    import included). In this thread: a loading thread would hold the GIL for about
    half the time for several seconds, slowing the search more than the pause does."""
    global _failed
    try:
        load()
        log.debug("compiled low level ready")
    except Exception as e:  # auto mode keeps the Python path
        _failed = True
        log.info("compiled low level unavailable (%s): staying with Python", e)


def _warm_up(k: ModuleType) -> None:
    """One tiny call of every kernel with the argument types real calls use."""
    g = Graph.grid(3, 1)
    res = Reservations(g.n)
    res.add(0, (2, 1, 0))
    root = AgentConstraints.root(g.n, 2)
    run(k, g.adj, 0, 2, g.dist_list(2), root, res, None, None)
    own = Reservations(g.n, dense_ok=True)  # CBS's own table: the kernel takes it over
    own.add(0, (2, 1, 0))
    run(k, g.adj, 0, 2, g.dist_list(2), root, own, None, None)
    own.conflicts_of(1, (0, 1, 2))
    own.remove(0)
    raw = build_mdd(k, g.adj, 0, 2, g.dist_list(2), root, 2, None)
    mdd_restrict(raw, 2, 2, [None, {0}, None], [None, None, 2], {(0, 0, 1)}, k)
    mdd_dependent(raw, 2, 2, raw, 2, 2, k)
    k.bfs_many(g.indptr, g.indices, np.array([0, 2], np.int64), UNREACHABLE)
    travel(k, g.adj, 0, 2, g.dist_list(2), root, (0, 1), UNREACHABLE)


def _warm_up_focal(k: ModuleType, fk: ModuleType) -> None:
    """One tiny focal call with the argument types real calls use."""
    g = Graph.grid(3, 1)
    res = Reservations(g.n)
    res.add(0, (2, 1, 0))
    root = AgentConstraints.root(g.n, 2)
    run_focal(
        fk, g.adj, 0, 2, g.dist_list(2), root, res, hold=0, max_t=8, partner=0, w=1.0,
        deadline=Deadline(None), budget=-1, avoid=False, limit=-1, k=k,
    )  # fmt: skip


# ---------------------------------------------------------------------- data
class _Graph:
    """The CSR successor lists of one ``adj`` (neighbours then the vertex: a wait)."""

    __slots__ = ("adj", "ptr", "idx")

    def __init__(self, adj: Sequence[Sequence[int]]) -> None:
        succ = successors(adj)
        self.adj = adj
        self.ptr = np.zeros(len(succ) + 1, np.int64)
        np.cumsum([len(s) for s in succ], out=self.ptr[1:])
        self.idx = np.fromiter((u for s in succ for u in s), np.int64, int(self.ptr[-1]))


_GRAPHS: dict[int, _Graph] = {}
_ARRAYS: dict[int, tuple[Sequence[int], Any]] = {}
_CONS: dict[int, tuple[Any, ...]] = {}


def _graph(adj: Sequence[Sequence[int]]) -> _Graph:
    g = _GRAPHS.get(id(adj))
    if g is None or g.adj is not adj:
        if len(_GRAPHS) > 16:
            _GRAPHS.clear()
        g = _GRAPHS[id(adj)] = _Graph(adj)
    return g


def _array(lst: Sequence[int]) -> np.ndarray:
    """``lst`` (a cached distance list) as an int64 array, cached by identity."""
    hit = _ARRAYS.get(id(lst))
    if hit is not None and hit[0] is lst:
        return hit[1]
    if len(_ARRAYS) > 1024:
        _ARRAYS.clear()
    arr = np.asarray(lst, np.int64)
    _ARRAYS[id(lst)] = (lst, arr)
    return arr


def _cons_arrays(
    cons: AgentConstraints, n: int, goal: int, nxt: list[tuple[int, int, Sequence[int], int]]
) -> tuple[Any, ...]:
    """The agent's constraints as kernel arrays.

    The small ones (constraint keys, landmark tables per timestep) are cached by
    ``cons.ver`` (the object is immutable); the ones of ``n`` entries (``forbid_from``
    per vertex, distance rows of the landmarks) are made per call, so the cache stays
    small on large maps.
    """
    hit = _CONS.get(cons.ver)
    if hit is None or hit[0] != goal or hit[1] != n:
        lms = cons.landmarks
        n_lm = len(nxt)
        lm_need = np.full(n_lm, -1, np.int64)
        nxt_tl = np.zeros(n_lm, np.int64)
        nxt_hb = np.zeros(n_lm, np.int64)
        nxt_row = np.zeros(n_lm, np.int64)
        rows: dict[int, int] = {}
        tables: list[Sequence[int]] = []
        for t, (tl, vl, dl, hb) in enumerate(nxt):
            need = lms.get(t)
            if need is not None:
                lm_need[t] = need
            nxt_tl[t] = tl
            nxt_hb[t] = hb
            r = rows.get(vl)
            if r is None:
                r = rows[vl] = len(tables)
                tables.append(dl)
            nxt_row[t] = r
        hit = (
            goal,
            n,
            np.array(sorted(cons.vertex), np.int64),
            np.array(sorted(cons.edge), np.int64),
            lm_need,
            nxt_tl,
            nxt_hb,
            nxt_row,
            tables,
            max((t for t, v in lms.items() if v != goal), default=-1),
        )
        if len(_CONS) > 4096:
            _CONS.clear()
        _CONS[cons.ver] = hit
    _, _, vkeys, ekeys, lm_need, nxt_tl, nxt_hb, nxt_row, tables, off = hit
    ff = _forbid_array(cons, n)
    if tables:
        lmd = np.stack([_array(dl) for dl in tables])
    else:
        lmd = _NO_ROWS.get(n)
        if lmd is None:
            lmd = _NO_ROWS[n] = np.zeros((0, n), np.int64)
    return vkeys, ekeys, ff, lm_need, nxt_tl, nxt_hb, nxt_row, lmd, off


def _search_args(
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    nxt: list[tuple[int, int, Sequence[int], int]],
    sixth: int,
) -> tuple[_Graph, tuple[Any, ...], int]:
    """The graph, the arguments the A* and MDD kernels share, and the last off-goal landmark.

    The shared arguments: the CSR successor lists, the distances, ``start``, ``goal``,
    ``sixth`` (the A*'s ``h0``, the MDD's cost), the constraint arrays of
    :func:`_cons_arrays` and ``min_finish``.
    """
    g = _graph(adj)
    vkeys, ekeys, ff, lm_need, nxt_tl, nxt_hb, nxt_row, lmd, off = _cons_arrays(
        cons, len(adj), goal, nxt
    )
    args = (g.ptr, g.idx, _array(dist), start, goal, sixth, vkeys, ekeys, ff, lm_need)
    return g, (*args, nxt_tl, nxt_hb, nxt_row, lmd, cons.min_finish), off


_NEVER: dict[int, Any] = {}
_NO_ROWS: dict[int, Any] = {}


def _forbid_array(cons: AgentConstraints, n: int) -> np.ndarray:
    """``cons.forbid_from`` per vertex (NEVER where absent)."""
    if not cons.forbid_from:
        return _never(n)
    ff = np.full(n, NEVER, np.int64)
    for v, t in cons.forbid_from.items():
        ff[v] = t
    return ff


def _never(n: int) -> np.ndarray:
    """A shared read-only array of ``n`` times NEVER (no ``forbid_from``)."""
    a = _NEVER.get(n)
    if a is None:
        a = _NEVER[n] = np.full(n, NEVER, np.int64)
    return a


class CatMirror:
    """Dense counts of one :class:`Reservations` at a time, for the kernel.

    ``vt[t * n + v]`` agents at ``v`` at ``t`` and ``et[t * nnz + j]`` agents making the
    reverse of move ``j`` (CSR position) arriving at ``t`` (those a move ``j`` would meet
    head-on), for ``t < h``; ``park_t`` as the table's.
    Zeroing such arrays per table would cost more than the searches (the WDG pair
    searches make a table each), so a few buffers (:data:`MIRRORS`) are shared: the
    table that needs one takes the least recently used, whose previous owner's paths are
    counted out (its ``mirror`` then no longer points here). While ``owner`` is a table,
    the counts equal its paths: :class:`Reservations` calls :meth:`update` on every
    change.
    """

    __slots__ = ("graph", "k", "n", "h", "vt", "et", "park_t", "owner")

    def __init__(self, k: ModuleType, graph: _Graph) -> None:
        self.graph = graph
        self.k = k
        self.n = len(graph.ptr) - 1
        self.h = 0
        self.vt = np.zeros(0, np.int16)
        self.et = np.zeros(0, np.int16)
        self.park_t = np.full(self.n, NEVER, np.int64)
        self.owner: Reservations | None = None

    def _grow(self, need: int) -> None:
        h = max(need, 2 * self.h, 64)
        vt = np.zeros(h * self.n, np.int16)
        vt[: self.vt.shape[0]] = self.vt
        et = np.zeros(h * self.graph.idx.shape[0], np.int16)
        et[: self.et.shape[0]] = self.et
        self.vt, self.et, self.h = vt, et, h

    def _count(self, path: Sequence[int], delta: int) -> None:
        if len(path) > self.h:
            self._grow(len(path))
        g = self.graph
        self.k.cat_apply(self.vt, self.et, g.ptr, g.idx, np.asarray(path, np.int64), delta)

    def attach(self, res: Reservations) -> None:
        """Count out the previous owner's paths and count in ``res``'s."""
        self.detach()
        if res.horizon + 1 > self.h:
            self._grow(res.horizon + 1)
        for p in res.paths:
            if p is not None:
                self._count(p, 1)
                self.park_t[p[-1]] = res.park_t[p[-1]]
        self.owner = res
        res.mirror = self

    def detach(self) -> None:
        """Count the owner's paths out (the arrays become all zero / NEVER again)."""
        old = self.owner
        if old is None:
            return
        for p in old.paths:
            if p is not None:
                self._count(p, -1)
                self.park_t[p[-1]] = NEVER
        old.mirror = None
        self.owner = None

    def update(self, path: Sequence[int], delta: int, park: int) -> None:
        """``path`` was reserved (``delta`` 1) or released (-1); ``park`` is the new
        ``park_t`` of its last vertex."""
        self._count(path, delta)
        self.park_t[path[-1]] = park


class DenseMirror(CatMirror):
    """The whole reservation table of one :class:`Reservations` (its ``dense``).

    Besides the counts of :class:`CatMirror`, the paths themselves: ``pos[a, t]`` (for
    ``t < plen[a]``; ``plen[a] == 0`` when ``a`` holds none), when each was added
    (``stamp``) and who is parked where (``park_a``, with ``park_t``), so that
    :meth:`conflicts_of` answers as the table's dicts would, in the same order. Owned by
    its table alone (not one of the shared buffers): patching it is one kernel call.
    """

    __slots__ = ("pos", "plen", "stamp", "park_a")

    def __init__(self, k: ModuleType, graph: _Graph, res: Reservations) -> None:
        super().__init__(k, graph)
        self._grow(res.horizon + 1)
        rows = max(len(res.paths), 1)
        self.pos = np.zeros((rows, self.h), np.int64)
        self.plen = np.zeros(rows, np.int64)
        self.stamp = np.zeros(rows, np.int64)
        self.park_a = np.full(self.n, -1, np.int64)
        for a, p in enumerate(res.paths):
            if p is not None:
                self.add(a, p, res.stamps[a])
        # The parked agents as the dicts have them (each add above parked its agent).
        self.park_a.fill(-1)
        self.park_t.fill(NEVER)
        for v, (a, t) in res.parked.items():
            self.park_a[v] = a
            self.park_t[v] = t
        # No ``owner``: the table holds this mirror (``res.dense``), and a reference back
        # would make a cycle that keeps its arrays (tens of MB on a 10k-vertex map)
        # until the next full garbage collection (numpy's bytes do not count towards
        # it), which then pauses a warm process: warehouse-10-20-10-2-1-even-1 k10
        # under the kernel took 11-55 ms a solve with the cycle, 15 ms without.

    def add(self, agent: int, path: Sequence[int], stamp: int) -> None:
        """Reserve ``path`` for ``agent``, added at ``stamp`` (see ``Reservations.add``)."""
        n_t = len(path)
        if n_t > self.h:
            self._grow(n_t)
        pos = self.pos
        if agent >= pos.shape[0] or n_t > pos.shape[1]:
            rows = max(agent + 1, pos.shape[0])
            new = np.zeros((rows, max(self.h, pos.shape[1])), np.int64)
            new[: pos.shape[0], : pos.shape[1]] = pos
            self.pos = new
            for name in ("plen", "stamp"):
                old = getattr(self, name)
                grown = np.zeros(rows, np.int64)
                grown[: old.shape[0]] = old
                setattr(self, name, grown)
        g = self.graph
        self.k.dense_add(
            self.vt, self.et, g.ptr, g.idx, np.array(path, np.int64), self.pos, self.plen,
            self.stamp, self.park_a, self.park_t, agent, stamp,
        )  # fmt: skip

    def remove(self, agent: int, path: Sequence[int]) -> None:
        """Release ``agent``'s ``path`` (see ``Reservations.remove``): the one its
        :meth:`add` wrote into the agent's row, which the kernel reads."""
        g = self.graph
        self.k.dense_remove(
            self.vt, self.et, g.ptr, g.idx, self.pos, self.plen, self.park_a, self.park_t, agent
        )

    def conflicts_of(
        self, r: int, path: Sequence[int], skip: set[int] | frozenset[int]
    ) -> list[Conflict]:
        """``Reservations.conflicts_of`` from the arrays: same conflicts, same order."""
        rows = self.plen.shape[0]
        mask = np.zeros(rows, np.bool_)
        for b in skip:
            if b < rows:
                mask[b] = True
        out = self.k.dense_conflicts(
            self.pos, self.plen, self.stamp, self.park_a, self.park_t,
            np.array(path, np.int64), r, mask,
        )  # fmt: skip
        return [Conflict(*c) for c in out.tolist()]

    def parked(self) -> tuple[dict[int, tuple[int, int]], list[int]]:
        """The table's ``parked`` and ``park_t`` from the arrays."""
        park_t = self.park_t.tolist()
        agents = self.park_a.tolist()
        return {v: (a, park_t[v]) for v, a in enumerate(agents) if a >= 0}, park_t


#: How many :class:`CatMirror` buffers are shared (the main search's, pair searches').
MIRRORS = 3
_mirrors: list[CatMirror] = []  # most recently used last


def _mirror(k: ModuleType, g: _Graph, res: Reservations) -> CatMirror:
    if res.dense_ok:
        d = res.dense
        if not isinstance(d, DenseMirror) or d.graph is not g:
            res.undense()
            if res.mirror is not None:
                res.mirror.detach()
            d = DenseMirror(k, g, res)
            res.dense = d
            res.vt, res.et, res.parked = {}, {}, {}
        return d
    m = res.mirror
    if isinstance(m, CatMirror) and m.owner is res and m.graph is g:
        if _mirrors[-1] is not m:
            _mirrors.remove(m)
            _mirrors.append(m)
        return m
    if _mirrors and _mirrors[0].graph is not g:
        for old in _mirrors:
            old.detach()
        _mirrors.clear()
    m = CatMirror(k, g) if len(_mirrors) < MIRRORS else _mirrors.pop(0)
    _mirrors.append(m)
    m.attach(res)
    return m


def run(
    k: ModuleType,
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    res: Reservations | None,
    dist_of: Callable[[int], Sequence[int]] | None,
    node_limit: int | None,
    *,
    nxt: list[tuple[int, int, Sequence[int], int]] | None = None,
    tcap: int | None = None,
    h0: int | None = None,
) -> tuple[tuple[int, ...] | None, int]:
    """The search of ``space_time_astar`` (after its early exits) in the kernel ``k``."""
    if nxt is None or tcap is None or h0 is None:  # a direct call (the warm-up)
        moves = Moves(adj, goal, dist, cons, dist_of)
        nxt, tcap, h0 = moves.nxt, moves.horizon(), moves.h0(start)
    g, args, off = _search_args(adj, start, goal, dist, cons, nxt, h0)
    if res is not None:
        m = _mirror(k, g, res)
        vt, et, cat_h, park_t = m.vt, m.et, m.h, m.park_t
    else:
        vt = et = np.zeros(0, np.int16)
        cat_h = 0
        park_t = args[8]  # unread without a table (an int64 array of n entries: forbid_from)
    expanded, path = k.astar(
        *args,
        cons.max_finish,
        tcap,
        off,
        res is not None,
        vt,
        et,
        cat_h,
        park_t,
        node_limit if node_limit is not None else -1,
        UNREACHABLE,
    )
    return (tuple(path.tolist()) if path.shape[0] else None), int(expanded)


def build_mdd(
    k: ModuleType,
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    cost: int,
    dist_of: Callable[[int], Sequence[int]] | None,
) -> tuple[Any, ...]:
    """The MDD of ``mdd.build_mdd`` (``cost >= 1``) from the kernel ``k``, as its arrays.

    :func:`mdd_levels` makes the levels of them, :func:`mdd_singles` the one-vertex
    levels.
    """

    nxt = Moves(adj, goal, dist, cons, dist_of).nxt
    _, args, _ = _search_args(adj, start, goal, dist, cons, nxt, cost)
    return k.mdd(*args, UNREACHABLE)


def mdd_restrict(
    raw: tuple[Any, ...],
    cost: int,
    goal: int,
    drop: Sequence[set[int] | None],
    only: Sequence[int | None],
    cut: set[tuple[int, int, int]],
    k: ModuleType | None = None,
) -> tuple[Any, ...] | None:
    """The passes of ``mdd.restrict`` on :func:`build_mdd`'s arrays; None if the cost is
    gone. ``drop``, ``only`` and ``cut`` as that function makes them; ``k`` the kernel
    (default: the loaded one, which made the arrays)."""
    k = k or _kernel
    assert k is not None
    dt = [t for t, d in enumerate(drop) if d is not None for _ in d]
    dv = [v for d in drop if d is not None for v in d]
    on = [-2 if o is None else o for o in only]
    cuts = np.array(sorted(cut), np.int64).reshape(len(cut), 3)
    ov, ks, ke, kids, lo, hi, last = raw
    out = k.mdd_restrict(
        ov, ks, ke, kids, lo, hi, last, cost, goal, np.array(dt, np.int64),
        np.array(dv, np.int64), np.array(on, np.int64), cuts,
    )  # fmt: skip
    return out if out[4].shape[0] else None


def mdd_dependent(
    a: tuple[Any, ...],
    cost_a: int,
    goal_a: int,
    b: tuple[Any, ...],
    cost_b: int,
    goal_b: int,
    k: ModuleType | None = None,
) -> bool:
    """:func:`.heuristics.dependent` on two MDDs kept as :func:`build_mdd`'s arrays
    (which exist only once the kernel is loaded; ``k`` defaults to it): the same answer,
    without making their levels."""
    k = k or _kernel
    assert k is not None
    ova, ksa, kea, kidsa, loa, hia, _ = a
    ovb, ksb, keb, kidsb, lob, hib, _ = b
    return bool(
        k.mdd_dependent(
            ova, ksa, kea, kidsa, loa, hia, cost_a, goal_a,
            ovb, ksb, keb, kidsb, lob, hib, cost_b, goal_b,
        )
    )  # fmt: skip


def mdd_singles(raw: tuple[Any, ...], cost: int, goal: int) -> list[int]:
    """Per level of :func:`build_mdd`'s arrays ``raw``: its vertex if it has one, else -1."""
    ov, _, _, _, lo, hi, last = raw
    one = [-1] * (cost + 1)
    for t, (a, b) in enumerate(zip(lo.tolist(), hi.tolist(), strict=True)):
        if b - a == 1:
            one[t] = int(ov[a])
    one[cost] = goal if last else -1
    return one


def mdd_levels(raw: tuple[Any, ...], cost: int, goal: int) -> list[dict[int, list[int]]]:
    """The levels (as ``mdd.MDD.levels``) of :func:`build_mdd`'s arrays ``raw``."""
    ov, ks, ke, kids, lo, hi, last = raw
    vl = ov.tolist()
    kl = kids.tolist()
    kid_lists = [kl[a:b] for a, b in zip(ks.tolist(), ke.tolist(), strict=True)]
    levels = [
        dict(zip(vl[a:b], kid_lists[a:b], strict=True))
        for a, b in zip(lo.tolist(), hi.tolist(), strict=True)
    ]
    levels[cost] = {goal: []} if last else {}
    return levels


# ---------------------------------------------------------------------- travel times
_SEEN = [np.zeros(0, np.int64), 0]  # the closed marks of :func:`travel` and their stamp


def travel(
    k: ModuleType,
    adj: Sequence[Sequence[int]],
    start: int,
    target: int,
    h: Sequence[int],
    cons: AgentConstraints,
    blocked: tuple[int, int] | None,
    upper: int,
) -> int:
    """The search of :func:`.symmetry.travel_time` (after its early exits) in ``k``.

    Example
    -------
    >>> from hierplan_opt.search.constraints import NEG_V
    >>> k = load()
    >>> g = Graph.grid(3, 1)
    >>> c = AgentConstraints.root(g.n, 2).add((NEG_V, 0, 1, -1, 1), n=g.n, goal=2)
    >>> travel(k, g.adj, 0, 2, g.dist_list(2), c, None, UNREACHABLE)
    3
    """
    g = _graph(adj)
    n = len(adj)
    tcap = cons.tmax + 1
    seen, stamp = _SEEN
    if seen.shape[0] < (tcap + 1) * n:
        seen = np.zeros(max((tcap + 1) * n, 2 * seen.shape[0]), np.int64)
        stamp = 0
    _SEEN[0], _SEEN[1] = seen, stamp + 1
    vk, ek = _sorted_keys(cons)
    ff = _forbid_array(cons, n)
    bx, by = blocked if blocked is not None else (-1, -1)
    return int(
        k.travel(
            g.ptr, g.idx, start, target, _array(h), vk, ek, ff, tcap, bx, by, upper, seen, stamp + 1
        )
    )


# ---------------------------------------------------------------------- focal search
_FCONS: dict[int, tuple[AgentConstraints, np.ndarray, np.ndarray]] = {}
_NO_KEYS = np.zeros(0, np.int64)


def _sorted_keys(cons: AgentConstraints) -> tuple[np.ndarray, np.ndarray]:
    """The vertex and edge constraint keys of ``cons``, sorted (cached per object)."""
    hit = _FCONS.get(cons.ver)
    if hit is None or hit[0] is not cons:
        if len(_FCONS) > 4096:
            _FCONS.clear()
        vk = np.array(sorted(cons.vertex), np.int64) if cons.vertex else _NO_KEYS
        ek = np.array(sorted(cons.edge), np.int64) if cons.edge else _NO_KEYS
        hit = _FCONS[cons.ver] = (cons, vk, ek)
    return hit[1], hit[2]


def run_focal(
    fk: ModuleType,
    adj: Sequence[Sequence[int]],
    start: int,
    goal: int,
    dist: Sequence[int],
    cons: AgentConstraints,
    res: Reservations,
    *,
    hold: int,
    max_t: int,
    partner: int,
    w: float,
    deadline: Deadline | None,
    budget: int,
    avoid: bool,
    limit: int,
    k: ModuleType | None = None,
) -> tuple[tuple[tuple[int, ...], int] | None, int] | None:
    """The search of ``focal._focal_loop`` in the focal kernel ``fk``: ``(its result,
    expansions)``, or None when the kernel declines the call (an ``f`` beyond its
    tables: a reachable vertex at an unreachable distance), which the Python loop then
    runs. Raises :class:`~hierplan_opt.search.spacetime.SearchTimeout` as the loop does.

    The reservations reach the kernel as the table's :class:`CatMirror` (``k``: the A*
    kernel whose routines keep it, default the loaded one); ``res`` must keep its moves.
    """
    k = k or _kernel
    assert k is not None and res.moves
    g = _graph(adj)
    m = _mirror(k, g, res)
    vkeys, ekeys = _sorted_keys(cons)
    pp = res.paths[partner] if 0 <= partner < len(res.paths) else None
    end = math.inf if deadline is None else perf_counter() + deadline.remaining()
    status, expanded, fmin, path = fk.focal(
        g.ptr, g.idx, _array(dist), start, goal, vkeys, ekeys, hold, max_t, m.vt, m.et, m.h,
        m.park_t, _NO_KEYS if pp is None else np.array(pp, np.int64), float(w), end, budget,
        bool(avoid), limit,
    )  # fmt: skip
    if status == fk.DECLINED:
        return None
    if status == fk.TIMEOUT:
        raise SearchTimeout
    if status == fk.FOUND:
        return (tuple(path.tolist()), int(fmin)), int(expanded)
    return None, int(expanded)
