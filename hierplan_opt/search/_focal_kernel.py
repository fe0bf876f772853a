"""Compiled (numba) focal search: the same search as :func:`.focal._focal_loop`.

Imported only through :mod:`hierplan_opt.search.jit`, never on the start-up path
(importing it imports numba and loads, or the first time compiles, the kernel). It
mirrors the Python loop step by step, so both give identical results: the same path,
the same ``f_min`` and the same expansion count (tests/test_jit_focal.py compares them
call by call).

Why the order agrees exactly: every FOCAL entry is a tuple of four integers
``(conflicts, tie, f, key)`` (``(tie, conflicts, f, key)`` after the fallback), and no
two entries are equal (a state is pushed again only with fewer conflicts), so any
priority queue pops them in the same order as Python's ``heapq``. The kernel keeps the
entries in a pool of arrays and a binary heap of pool indices compared as those tuples.

Data layout (``int64`` unless said otherwise), shared with :mod:`._astar_kernel`:

- ``ptr, idx``: the CSR successor lists (neighbours then the vertex itself); move ``j``
  is ``v -> idx[j]`` for ``ptr[v] <= j < ptr[v + 1]``.
- ``h``: the distances to the goal; ``vkeys, ekeys``: the sorted constraint keys.
- ``cat_vt`` (``int16``): agents per ``t * n + v`` for ``t < cat_h``; ``cat_et``
  (``int16``): agents making the reverse of move ``j`` arriving at ``t``, per
  ``t * nnz + j``; ``park_t``: when an agent parks at each vertex
  (:class:`.jit.CatMirror`, kept in step with the reservation table).
- ``pp``: the partner's path (empty if none).

States (``key = t * n + v``, terminal ``-(key + 1)``) get ids in an open-addressing
table; per id its vertex, the fewest conflicts found, the parent id and whether it was
expanded. Entries: their two leading keys ``p0, p1`` (conflicts and tie, swapped by the
fallback), ``f``, key, state id. ``live[f]`` and the bucket lists ``bhead[f]`` (entries
above the bound, linked by ``enext``) are arrays indexed by ``f``, grown on demand.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from hierplan_opt.search._astar_kernel import (
    _contains,
    _grow,
    _hslot,
    _leaf,
    _njit,
    _path_of,
    _rehash,
)

#: As :data:`.focal._TIE` and :data:`.focal.PARTNER_WEIGHT` (tests check they agree).
TIE = 1 << 20
PARTNER_WEIGHT = 1 << 10
#: Status codes of :func:`focal`.
FOUND = 0
NO_PATH = 1
TIMEOUT = 2
#: An ``f`` above this (an unreachable vertex's distance) makes the kernel decline the
#: call (the Python loop runs it instead): the ``f`` tables are dense arrays.
F_CAP = 1 << 22
DECLINED = 3


def _clock(typingctx):
    """``time.perf_counter()`` inside the kernel: ``clock_gettime(CLOCK_MONOTONIC)``
    (what CPython's perf_counter reads on Linux), called by its symbol name so the
    kernel stays cacheable."""
    sig = types.float64()

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        i64 = ir.IntType(64)
        dbl = ir.DoubleType()
        ts = cgutils.alloca_once(builder, ir.ArrayType(i64, 2))  # struct timespec
        fnty = ir.FunctionType(i32, [i32, ts.type])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "clock_gettime")
        builder.call(fn, [ir.Constant(i32, 1), ts])  # CLOCK_MONOTONIC
        zero = ir.Constant(i32, 0)
        sec = builder.load(builder.gep(ts, [zero, zero]))
        nsec = builder.load(builder.gep(ts, [zero, ir.Constant(i32, 1)]))
        frac = builder.fmul(builder.sitofp(nsec, dbl), ir.Constant(dbl, 1e-9))
        return builder.fadd(builder.sitofp(sec, dbl), frac)

    return sig, codegen


_monotonic: Any = intrinsic(_clock)


@_njit
def monotonic():
    """Seconds of the clock ``time.perf_counter`` reads (for the tests)."""
    return _monotonic()


@_leaf
def _lt(a0, a1, a2, a3, b0, b1, b2, b3):
    """``(a0, a1, a2, a3) < (b0, b1, b2, b3)``: the order of two FOCAL entries."""
    if a0 != b0:
        return a0 < b0
    if a1 != b1:
        return a1 < b1
    if a2 != b2:
        return a2 < b2
    return a3 < b3


@_njit
def _suffix(counts_at, length):
    """``out[t]`` = the sum of ``counts_at[s]`` for ``s > t`` (``t < length``)."""
    out = np.zeros(length + 1, np.int64)
    for t in range(length - 2, -1, -1):
        out[t] = out[t + 1] + counts_at[t + 1]
    return out


@_njit
def _grow_fill(a, cap, fill):
    out = np.full(cap, fill, a.dtype)
    out[: a.shape[0]] = a
    return out


@_leaf
def _before(p0, p1, ef, ek, a, b):
    """Entry ``a`` pops before entry ``b``."""
    return _lt(p0[a], p1[a], ef[a], ek[a], p0[b], p1[b], ef[b], ek[b])


@_leaf
def _sift_up(heap, p0, p1, ef, ek, x, i):
    """Entry ``x`` into the heap at free position ``i``."""
    while i > 0 and _before(p0, p1, ef, ek, x, heap[(i - 1) >> 1]):
        heap[i] = heap[(i - 1) >> 1]
        i = (i - 1) >> 1
    heap[i] = x


@_leaf
def _sift_down(heap, p0, p1, ef, ek, x, i, size):
    """Entry ``x`` into the heap of ``size`` entries at position ``i``."""
    while True:
        c1 = 2 * i + 1
        if c1 >= size:
            break
        m = heap[c1]
        if c1 + 1 < size and _before(p0, p1, ef, ek, heap[c1 + 1], m):
            m = heap[c1 + 1]
            c1 += 1
        if not _before(p0, p1, ef, ek, m, x):
            break
        heap[i] = m
        i = c1
    heap[i] = x


@_leaf
def _raise_bound(live, bhead, enext, heap, p0, p1, ef, ek, w, fmin, bound, lo, size):
    """``focal._raise_bound``: ``f_min`` up to the next live ``f`` (``lo``: no live ``f``
    below it) and the bucketed entries the new bound admits pushed; the new ``(fmin,
    bound, lo, size)``."""
    if live[fmin] == 0:
        while live[lo] == 0:
            lo += 1
        if lo > fmin:
            fmin = lo
    new_bound = int(w * fmin + 1e-9)
    fcap = live.shape[0]
    top_f = new_bound if new_bound < fcap - 1 else fcap - 1
    for fx in range(bound + 1, top_f + 1):
        x = bhead[fx]
        bhead[fx] = -1
        while x >= 0:
            nx = enext[x]
            _sift_up(heap, p0, p1, ef, ek, x, size)
            size += 1
            x = nx
    if new_bound > bound:
        bound = new_bound
    return fmin, bound, lo, size


@_leaf
def _to_fallback(heap, p0, p1, ef, ek, n_e, size):
    """FOCAL by ``g + 2h`` first from now on: every entry's two leading keys swap, then
    the heap is made again (sift downs)."""
    for x in range(n_e):
        y = p0[x]
        p0[x] = p1[x]
        p1[x] = y
    for r in range((size >> 1) - 1, -1, -1):
        _sift_down(heap, p0, p1, ef, ek, heap[r], r, size)


@_leaf
def _max_f(ptr, idx, h, v, nt, hold):
    """The largest ``f`` of a state the expansion of ``v`` (arriving at ``nt``) makes."""
    mf = nt
    for j in range(ptr[v], ptr[v + 1]):
        hu = h[idx[j]]
        x = nt + hu if nt + hu > hold else hold
        if x > mf:
            mf = x
    return mf


@_leaf
def _offer(
    hkeys, hids, s_v, s_best, s_par, s_closed, live, p0, p1, ef, ek, es, enext, bhead,
    pend, enc, nc, vx, nf, tie, key, par, fb, bound, cnt,
):  # fmt: skip
    """A state (``enc``: 2 key, + 1 a terminal) reached with ``nc`` conflicts, ``f =
    nf``, from state ``par``: kept and given a FOCAL entry if new or with fewer conflicts
    than before. ``cnt = (n_s, n_e, n_live, lo, n_pend)``, returned updated."""
    n_s, n_e, n_live, lo, n_pend = cnt
    slot = _hslot(hkeys, enc)
    sid = hids[slot] if hkeys[slot] == enc else -1
    if sid >= 0 and nc >= s_best[sid]:
        return cnt
    if sid < 0:
        sid = n_s
        n_s += 1
        s_v[sid] = vx
        s_closed[sid] = False
        hkeys[slot] = enc
        hids[slot] = sid
        live[nf] += 1
        n_live += 1
        if nf < lo:
            lo = nf
    s_best[sid] = nc
    s_par[sid] = par
    e = n_e
    n_e += 1
    p0[e] = tie if fb else nc
    p1[e] = nc if fb else tie
    ef[e] = nf
    ek[e] = key
    es[e] = sid
    if nf <= bound:
        pend[n_pend] = e
        n_pend += 1
    else:
        enext[e] = bhead[nf]
        bhead[nf] = e
    return n_s, n_e, n_live, lo, n_pend


@_leaf
def _move_conflicts(cat_vt, cat_et, cat_h, park_t, pp, j, v, u, nt, n, nnz):
    """The conflicts of move ``j`` (``v -> u`` arriving at ``nt``), as
    ``focal.scored_moves`` counts them: each other agent at ``u`` at ``nt``, parked at
    ``u`` before ``nt`` or moving ``u -> v`` (a swap) is one, :data:`PARTNER_WEIGHT` more
    when it is the partner (``pp``, its path)."""
    lp = pp.shape[0]
    nc = 0
    if nt < cat_h:
        occ = cat_vt[nt * n + u]
        if occ:
            nc += occ
            if nt < lp and pp[nt] == u:
                nc += PARTNER_WEIGHT
    if nt > park_t[u]:
        nc += 1
        if lp > 0 and u == pp[lp - 1]:  # the partner is the one parked at u
            nc += PARTNER_WEIGHT
    if u != v and nt < cat_h:
        occ = cat_et[nt * nnz + j]  # someone moves u -> v: a swap
        if occ:
            nc += occ
            if nt < lp and pp[nt - 1] == u and pp[nt] == v:
                nc += PARTNER_WEIGHT
    return nc


# The search's scalars between the calls of _loop (``regs[...]``).
_N_S, _N_E, _SIZE, _FMIN, _BOUND, _FB, _EXP, _RAISE, _LO, _NLIVE, _NPEND = range(11)
_TOP, _NEED_F, _NEED_D = 11, 12, 13
_REGS = 14
#: ``_loop`` ran out of room: the caller grows the arrays and calls it again.
_GROW = 4


# Complexity: focal._focal_loop (with _park and _raise_bound) in one compiled body, step
# by step like the Python one, so the tests can hold them to identical results. Its
# steps are the leaves above (heap, bound, conflicts of a move, state update), compiled
# without reference counting (see ``_astar_kernel._leaf``: with it, the state update as
# a helper made the loop 2.2x slower). No array is reassigned in the loop: when one is
# about to run out, the loop hands back to ``focal``, which grows it and calls again.
@_njit
def _loop(
    ptr, idx, h, goal, vkeys, ekeys, hold, max_t, cat_vt, cat_et, cat_h, park_t, pp,
    goal_after, p_after, span, w, end, budget, avoid, limit, hkeys, hids, s_v, s_best,
    s_par, s_closed, p0, p1, ef, ek, es, enext, heap, live, bhead, pend, regs,
):  # fmt: skip
    """The main loop of ``focal._focal_loop`` from the state in ``regs`` and the arrays:
    a status (:data:`FOUND`: the terminal's id in ``regs[_TOP]``; :data:`NO_PATH`,
    :data:`TIMEOUT`, :data:`DECLINED`, or ``_GROW``: room needed, ``regs`` saved).

    New FOCAL entries wait in ``pend`` until the expansion is done (one place pushes
    them); so does the entry put back when the arrays must grow first.
    """
    n = ptr.shape[0] - 1
    nnz = idx.shape[0]
    pw = PARTNER_WEIGHT
    nv = vkeys.shape[0]
    ne = ekeys.shape[0]
    scap = s_v.shape[0]
    ecap = p0.shape[0]
    hcap = hkeys.shape[0]
    fcap = live.shape[0]
    n_s = regs[_N_S]
    n_e = regs[_N_E]
    size = regs[_SIZE]
    fmin = regs[_FMIN]
    bound = regs[_BOUND]
    fb = regs[_FB] != 0
    expanded = regs[_EXP]
    raise_fmin = regs[_RAISE] != 0
    lo = regs[_LO]
    n_live = regs[_NLIVE]
    n_pend = regs[_NPEND]
    status = NO_PATH

    while True:
        while n_pend > 0:  # push the waiting entries
            n_pend -= 1
            _sift_up(heap, p0, p1, ef, ek, pend[n_pend], size)
            size += 1
        if raise_fmin or size == 0:
            raise_fmin = False
            if n_live == 0:
                if size == 0:
                    break
            else:
                fmin, bound, lo, size = _raise_bound(
                    live, bhead, enext, heap, p0, p1, ef, ek, w, fmin, bound, lo, size
                )
                if size == 0:
                    continue
        top_e = heap[0]
        size -= 1
        if size > 0:  # the last entry down from the root
            _sift_down(heap, p0, p1, ef, ek, heap[size], 0, size)
        c = p1[top_e] if fb else p0[top_e]
        f = ef[top_e]
        top = es[top_e]
        if s_best[top] != c:
            continue  # stale entry
        key = ek[top_e]
        if key < 0:  # terminal: the agent parks at its goal from time f on
            regs[_TOP] = top
            status = FOUND
            break
        t = key // n
        v = key - t * n
        nt = t + 1
        if nt <= max_t:
            # Room for this expansion's states and entries (each move a state and a
            # terminal at most) and for their f; else back to the caller, entry put back.
            deg = ptr[v + 1] - ptr[v]
            mf = _max_f(ptr, idx, h, v, nt, hold)
            if mf > F_CAP:
                status = DECLINED
                break
            if (
                n_s + 2 * deg > scap
                or n_e + 2 * deg > ecap
                or 2 * (n_s + 2 * deg) > hcap
                or mf >= fcap
                or 2 * deg + 1 > pend.shape[0]
            ):
                pend[n_pend] = top_e
                n_pend += 1
                regs[_NEED_F] = mf
                regs[_NEED_D] = 2 * deg + 1
                status = _GROW
                break
        first = not s_closed[top]
        if first:
            s_closed[top] = True
            live[f] -= 1
            n_live -= 1
        expanded += 1
        if expanded == limit:
            break
        if expanded == budget:
            fb = True  # FOCAL by g + 2h first from now on
            _to_fallback(heap, p0, p1, ef, ek, n_e, size)
        if (expanded & 1023) == 0 and _monotonic() >= end:
            status = TIMEOUT
            break
        if nt > max_t:
            if first and f == fmin and live[f] == 0:
                raise_fmin = True
            continue
        base = nt * n
        cnt = (n_s, n_e, n_live, lo, n_pend)
        for j in range(ptr[v], ptr[v + 1]):
            u = idx[j]
            nk = base + u
            if nv > 0 and _contains(vkeys, nk):  # a vertex constraint
                continue
            if ne > 0 and u != v and _contains(ekeys, (base + v) * n + u):  # an edge one
                continue
            nc = c + _move_conflicts(cat_vt, cat_et, cat_h, park_t, pp, j, v, u, nt, n, nnz)
            if avoid and nc:
                continue
            hu = h[u]
            nf = nt + hu if nt + hu > hold else hold
            cnt = _offer(
                hkeys, hids, s_v, s_best, s_par, s_closed, live, p0, p1, ef, ek, es, enext,
                bhead, pend, 2 * nk, nc, u, nf, (nf + hu) * TIE - nt, nk, top, fb, bound, cnt,
            )  # fmt: skip
            if u == goal and nt >= hold:
                ix = nt if nt < span else span
                tc = nc + goal_after[ix] + pw * p_after[ix]
                if not (avoid and tc):  # focal._park: parked at the goal from nt on
                    cnt = _offer(
                        hkeys, hids, s_v, s_best, s_par, s_closed, live, p0, p1, ef, ek, es,
                        enext, bhead, pend, 2 * nk + 1, tc, goal, nt, nt * TIE - nt, -(nk + 1),
                        top, fb, bound, cnt,
                    )  # fmt: skip
        n_s, n_e, n_live, lo, n_pend = cnt
        if first and f == fmin and live[f] == 0:
            raise_fmin = True
    regs[_N_S] = n_s
    regs[_N_E] = n_e
    regs[_SIZE] = size
    regs[_FMIN] = fmin
    regs[_BOUND] = bound
    regs[_FB] = 1 if fb else 0
    regs[_EXP] = expanded
    regs[_RAISE] = 1 if raise_fmin else 0
    regs[_LO] = lo
    regs[_NLIVE] = n_live
    regs[_NPEND] = n_pend
    return status


@_njit
def focal(
    ptr, idx, h, start, goal, vkeys, ekeys, hold, max_t, cat_vt, cat_et, cat_h, park_t,
    pp, w, end, budget, avoid, limit,
):  # fmt: skip
    """The search of ``focal._focal_loop``: ``(status, expanded, f_min, path)``.

    ``status`` is :data:`FOUND` (``path`` the result), :data:`NO_PATH`, :data:`TIMEOUT`
    (``end``, a ``perf_counter`` time, passed at a check every 1024 expansions) or
    :data:`DECLINED` (an ``f`` above :data:`F_CAP`). ``pp``: the partner's path.
    """
    n = ptr.shape[0] - 1
    empty = np.empty(0, np.int64)
    f0 = h[start] if h[start] > hold else hold
    if f0 > F_CAP:
        return DECLINED, 0, 0, empty
    # The later visits of the others to the goal, and of the partner (park conflicts).
    lp = pp.shape[0]
    span = cat_h if cat_h > lp else lp
    at_goal = np.zeros(span + 1, np.int64)
    p_at_goal = np.zeros(span + 1, np.int64)
    for t in range(cat_h):
        at_goal[t] = cat_vt[t * n + goal]
    for t in range(lp):
        if pp[t] == goal:
            p_at_goal[t] = 1
    goal_after = _suffix(at_goal, span + 1)
    p_after = _suffix(p_at_goal, span + 1)
    hkeys = np.full(1024, -1, np.int64)
    hids = np.empty(1024, np.int64)
    s_v = np.empty(256, np.int64)
    s_best = np.empty(256, np.int64)
    s_par = np.empty(256, np.int64)
    s_closed = np.zeros(256, np.bool_)
    p0 = np.empty(512, np.int64)
    p1 = np.empty(512, np.int64)
    ef = np.empty(512, np.int64)
    ek = np.empty(512, np.int64)
    es = np.empty(512, np.int64)
    enext = np.empty(512, np.int64)
    heap = np.empty(512, np.int64)
    pend = np.empty(16, np.int64)
    live = np.zeros(2 * f0 + 64, np.int64)
    bhead = np.full(2 * f0 + 64, -1, np.int64)
    regs = np.zeros(_REGS, np.int64)
    # The start: state 0, entry 0, waiting in pend; parked at time 0 if it is the goal.
    slot = _hslot(hkeys, 2 * start)
    hkeys[slot] = 2 * start
    hids[slot] = 0
    s_v[0] = start
    s_best[0] = 0
    s_par[0] = -1
    live[f0] = 1
    p0[0] = 0
    p1[0] = (f0 + h[start]) * TIE
    ef[0] = f0
    ek[0] = start
    es[0] = 0
    pend[0] = 0
    n_s = 1
    n_live = 1
    c = goal_after[0]
    if start == goal and hold == 0 and not (avoid and c):
        slot = _hslot(hkeys, 2 * start + 1)
        hkeys[slot] = 2 * start + 1
        hids[slot] = 1
        s_v[1] = goal
        s_best[1] = c
        s_par[1] = 0
        live[0] += 1
        p0[1] = c
        p1[1] = 0
        ef[1] = 0
        ek[1] = -(start + 1)
        es[1] = 1
        pend[1] = 1  # f = 0 <= the bound
        n_s = 2
        n_live = 2
    regs[_N_S] = n_s
    regs[_N_E] = n_s
    regs[_NPEND] = n_s
    regs[_NLIVE] = n_live
    regs[_FMIN] = f0
    regs[_BOUND] = int(w * f0 + 1e-9)
    regs[_LO] = f0 if n_s == 1 else 0
    while True:
        status = _loop(
            ptr, idx, h, goal, vkeys, ekeys, hold, max_t, cat_vt, cat_et, cat_h, park_t, pp,
            goal_after, p_after, span, w, end, budget, avoid, limit, hkeys, hids, s_v,
            s_best, s_par, s_closed, p0, p1, ef, ek, es, enext, heap, live, bhead, pend, regs,
        )  # fmt: skip
        if status != _GROW:
            break
        n_s = regs[_N_S]
        n_e = regs[_N_E]
        d = regs[_NEED_D]
        cap = s_v.shape[0]
        while n_s + d > cap:
            cap *= 2
        if cap > s_v.shape[0]:
            s_v = _grow(s_v, cap)
            s_best = _grow(s_best, cap)
            s_par = _grow(s_par, cap)
            s_closed = _grow(s_closed, cap)
        cap = hkeys.shape[0]
        while 2 * (n_s + d) > cap:
            cap *= 2
        if cap > hkeys.shape[0]:
            hkeys, hids = _rehash(hkeys, hids, cap)
        cap = p0.shape[0]
        while n_e + d > cap:
            cap *= 2
        if cap > p0.shape[0]:
            p0 = _grow(p0, cap)
            p1 = _grow(p1, cap)
            ef = _grow(ef, cap)
            ek = _grow(ek, cap)
            es = _grow(es, cap)
            enext = _grow(enext, cap)
            heap = _grow(heap, cap)
        cap = pend.shape[0]
        while d > cap:
            cap *= 2
        if cap > pend.shape[0]:
            pend = _grow(pend, cap)
        cap = live.shape[0]
        while regs[_NEED_F] >= cap:
            cap *= 2
        if cap > live.shape[0]:
            live = _grow_fill(live, cap, 0)
            bhead = _grow_fill(bhead, cap, -1)
    expanded = regs[_EXP]
    fmin = regs[_FMIN]
    if status != FOUND:
        return status, expanded, fmin, empty
    path = _path_of(s_v, s_par, regs[_TOP])
    length = path.shape[0]
    while length > 1 and path[length - 2] == goal:
        length -= 1  # (focal._focal_loop's trailing waits at the goal)
    return FOUND, expanded, fmin, path[:length].copy()
