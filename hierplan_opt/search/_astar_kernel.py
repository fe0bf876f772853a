"""Compiled (numba) space-time A*: the same search as :func:`.astar.space_time_astar`.

Imported only through :mod:`hierplan_opt.search.jit`, never on the start-up path:
importing this module imports numba and loads (or, the first time, compiles) the
kernels. Every function here mirrors a Python loop of the package step by step so both
give identical results (same path, same expansion count, same tie-breaking); the tests
compare them call by call.

Data layout (all ``int64`` unless said otherwise):

- ``ptr, idx``: the successor lists of :func:`.spacetime.successors` (neighbours then
  the vertex itself) as CSR; a move ``v -> idx[j]`` is identified by its position ``j``.
- ``vkeys, ekeys``: the agent's vertex / edge constraint keys, sorted.
- ``ff``: ``forbid_from`` per vertex (:data:`NEVER` where absent).
- ``lm_need[t]``: the landmark vertex at ``t`` (-1 if none); ``nxt_tl, nxt_hb, nxt_row``:
  the next landmark's time, ``h`` bound and row of ``lmd`` (its distance table) per ``t``.
- ``cat_vt``: agents per ``t * n + v`` (``int16``, ``cat_h`` timesteps); ``cat_et``:
  agents per ``t * nnz + j`` making the *reverse* of move ``j`` (``v -> u`` is move ``j``:
  the agents moving ``u -> v``) arriving at ``t``, so that the A* reads the swaps of
  the move it tries at that move's own position; ``park_t``: as
  :attr:`.reservations.Reservations.park_t`.
"""

from __future__ import annotations

import heapq
from typing import Any

import numba
import numpy as np

#: ``forbid_from`` / ``park_t`` value meaning "never".
NEVER = 1 << 60
#: Third heap key of a final arrival (see astar.TERMINAL).
TERMINAL = -(1 << 50)


def _njit(f):
    """``numba.njit`` with an on-disk cache when a cache directory is writable."""
    try:
        return numba.njit(cache=True, nogil=True)(f)
    except RuntimeError:  # no writable cache location (numba raises at decoration)
        return numba.njit(nogil=True)(f)


#: Options of a leaf (``_nrt`` is numba's own switch of its runtime, not in its stubs).
_NO_NRT: dict[str, Any] = {"nogil": True, "_nrt": False}


def _leaf(f):
    """``numba.njit`` for a helper of a hot loop that only reads and writes the arrays it
    is given (it allocates none and keeps none): compiled without numba's reference
    counting (``_nrt=False``), so a call costs no atomic increments and decrements of
    each array's count. With them, a helper called per move made the focal kernel 2.2x
    slower (its state update, 15 arrays); without, the same helper costs nothing
    measurable (``bench``-style medians, CPU lock). Numba refuses to compile a leaf that
    allocates."""
    try:
        return numba.njit(cache=True, **_NO_NRT)(f)
    except RuntimeError:  # no writable cache location (numba raises at decoration)
        return numba.njit(**_NO_NRT)(f)


@_leaf
def _contains(keys, x):
    lo = 0
    hi = keys.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if keys[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo < keys.shape[0] and keys[lo] == x


@_leaf
def _move_h(u, v, t, n, need, lrow, ltl, lhb, vkeys, ekeys, ff, dist, lmd, minf, unreachable):
    """``h`` of the move ``v -> u`` arriving at ``t``, -1 if it is not allowed.

    The rule of ``spacetime.Moves``, written once for the A* and the MDD kernels;
    ``need, lrow, ltl, lhb`` are :func:`_landmark`'s at ``t``.
    """
    if need >= 0 and u != need:
        return -1
    base = t * n
    if vkeys.shape[0] > 0 and _contains(vkeys, base + u):
        return -1
    if ekeys.shape[0] > 0 and u != v and _contains(ekeys, (base + v) * n + u):
        return -1
    if t >= ff[u]:
        return -1
    hu = dist[u]
    if hu >= unreachable:
        return -1
    if lrow >= 0:
        if lmd[lrow, u] > ltl:
            return -1
        if lhb > hu:
            hu = lhb
    if minf - t > hu:
        hu = minf - t
    return hu


@_leaf
def _landmark(t, lm_need, nxt_row, nxt_tl, nxt_hb):
    """What the next landmark asks of a move arriving at ``t``: ``(need, lrow, ltl,
    lhb)``, the vertex the move must reach (-1: any), the landmark's row of ``lmd`` (-1:
    no landmark left), the time left to reach it and the bound on ``h`` it gives."""
    if t < lm_need.shape[0]:
        return lm_need[t], nxt_row[t], nxt_tl[t] - t, nxt_hb[t] - t
    return -1, -1, 0, 0


@_njit
def _path_of(pv, pp, top):
    """The vertices from the root entry to ``top`` along the parent links ``pp``."""
    length = 0
    e = top
    while e >= 0:
        length += 1
        e = pp[e]
    path = np.empty(length, np.int64)
    e = top
    k = length - 1
    while e >= 0:
        path[k] = pv[e]
        k -= 1
        e = pp[e]
    return path


# The search's scalars between the calls of _astar_loop (``regs[...]``).
_SIZE, _CNT, _BSIZE, _EXP, _TOP, _NEED = range(6)
_AREGS = 6
#: Status codes of :func:`_astar_loop`: a path (its last entry ``regs[_TOP]``), none
#: (or the node limit hit), or room needed (the caller grows the arrays, calls again).
_A_FOUND = 0
_A_NONE = 1
_A_GROW = 2
#: A ``best`` value meaning "expanded" (below every conflict count); absent: no key.
_CLOSED = -1
_HMUL = 0x5851F42D4C957F2D


@_leaf
def _hslot(keys, key):
    """The slot of ``key`` in the open-addressing table ``keys`` (``-1``: free; its size
    a power of two), or the free slot where it goes: the A* kernel's ``best`` table and
    the focal kernel's state table."""
    mask = keys.shape[0] - 1
    i = ((key * _HMUL) >> 17) & mask
    while keys[i] != -1 and keys[i] != key:
        i = (i + 1) & mask
    return i


@_leaf
def _before(pf, pc, pn, a, b):
    """Entry ``a`` pops before entry ``b``: by ``f`` (``pf``), conflicts (``pc``), ``-t``
    (``pn``), then by number."""
    if pf[a] != pf[b]:
        return pf[a] < pf[b]
    if pc[a] != pc[b]:
        return pc[a] < pc[b]
    if pn[a] != pn[b]:
        return pn[a] < pn[b]
    return a < b


@_leaf
def _lower(bkeys, bvals, key, c):
    """``best[key] = c`` in the open-addressing table if ``c`` is below its value (or
    the key is absent): ``(done, 1 if the key is new else 0)``."""
    slot = _hslot(bkeys, key)
    added = 0
    if bkeys[slot] == key:
        if bvals[slot] <= c:  # (_CLOSED, below every count, included)
            return False, 0
    else:
        bkeys[slot] = key
        added = 1
    bvals[slot] = c
    return True, added


@_leaf
def _sift_down(heap, pf, pc, pn, size):
    """``heap[size]`` into the heap of ``size`` entries, from the root."""
    x = heap[size]
    i = 0
    while True:
        c1 = 2 * i + 1
        if c1 >= size:
            break
        m = heap[c1]
        if c1 + 1 < size and _before(pf, pc, pn, heap[c1 + 1], m):
            m = heap[c1 + 1]
            c1 += 1
        if not _before(pf, pc, pn, m, x):
            break
        heap[i] = m
        i = c1
    heap[i] = x


@_leaf
def _push(heap, pf, pc, pn, pv, pt, pp, e, size, f, c, nn, u, t, par):
    """Entry ``e`` (``f``, conflicts, ``nn``, vertex, ``t``, parent) onto the heap of
    ``size`` entries (sift up)."""
    pf[e] = f
    pc[e] = c
    pn[e] = nn
    pv[e] = u
    pt[e] = t
    pp[e] = par
    i = size
    while i > 0 and _before(pf, pc, pn, e, heap[(i - 1) >> 1]):
        heap[i] = heap[(i - 1) >> 1]
        i = (i - 1) >> 1
    heap[i] = e


# The loop of space_time_astar in one compiled body. Its steps are the
# leaves above (the move rule _move_h and the landmark's _landmark, shared with the MDD
# builder; the heap and the best table), compiled without reference counting: a call
# costs nothing measurable, where helpers compiled with it made the loop 15 % slower
# and closures had to stand in. When an array is about to run out, the loop hands back
# to ``astar``, which grows it and calls again.
@_njit
def _astar_loop(
    ptr, idx, dist, goal, vkeys, ekeys, ff, lm_need, nxt_tl, nxt_hb, nxt_row, lmd, minf,
    maxf, tcap, last_off_goal_lm, use_cat, cat_vt, cat_et, cat_h, park_t, node_limit,
    unreachable, pf, pc, pn, pv, pt, pp, heap, bkeys, bvals, regs,
):  # fmt: skip
    """The loop of ``space_time_astar`` from the state in ``regs`` and the arrays: a
    status (:data:`_A_FOUND`, :data:`_A_NONE` or :data:`_A_GROW`, ``regs`` saved)."""
    n = ptr.shape[0] - 1
    nnz = idx.shape[0]
    cap = pf.shape[0]
    bcap = bkeys.shape[0]
    size = regs[_SIZE]
    cnt = regs[_CNT]
    bsize = regs[_BSIZE]
    expanded = regs[_EXP]
    status = _A_NONE

    while size > 0:
        top = heap[0]
        v = pv[top]
        deg = ptr[v + 1] - ptr[v]
        # Room for this expansion: two entries and one state per move, and its own state.
        if cnt + 2 * deg >= cap or 2 * (bsize + deg + 1) > bcap:
            regs[_NEED] = deg
            status = _A_GROW
            break
        size -= 1
        if size > 0:  # the last entry down from the root
            _sift_down(heap, pf, pc, pn, size)
        t = pt[top]
        conf = pc[top]
        if pn[top] == TERMINAL:
            regs[_TOP] = top
            status = _A_FOUND
            break
        done, added = _lower(bkeys, bvals, (t if t < tcap else tcap) * n + v, _CLOSED)
        if not done:  # expanded before
            continue
        bsize += added
        expanded += 1
        if expanded == node_limit:
            break
        t1 = t + 1
        if t1 > maxf:
            continue
        base = t1 * n
        keyt1 = (t1 if t1 < tcap else tcap) * n
        need, lrow, ltl, lhb = _landmark(t1, lm_need, nxt_row, nxt_tl, nxt_hb)
        in_cat = use_cat and t1 < cat_h
        for j in range(ptr[v], ptr[v + 1]):
            u = idx[j]
            hu = _move_h(
                u, v, t1, n, need, lrow, ltl, lhb, vkeys, ekeys, ff, dist, lmd, minf, unreachable
            )
            if hu < 0:
                continue
            fu = t1 + hu
            if fu > maxf:
                continue
            c = conf
            if use_cat:
                if in_cat:
                    c += cat_vt[base + u]
                    if u != v and cat_et[t1 * nnz + j] > 0:  # a swap: someone moves u -> v
                        c += 1
                if t1 > park_t[u]:
                    c += 1
            # A move into the goal (not a wait there) may be the final arrival.
            if u == goal and v != goal and t1 >= minf and t1 > last_off_goal_lm:
                cnt += 1
                _push(heap, pf, pc, pn, pv, pt, pp, cnt, size, t1, c, TERMINAL, u, t1, top)
                size += 1
            done, added = _lower(bkeys, bvals, keyt1 + u, c)
            if done:
                bsize += added
                cnt += 1
                _push(heap, pf, pc, pn, pv, pt, pp, cnt, size, fu, c, -t1, u, t1, top)
                size += 1
    regs[_SIZE] = size
    regs[_CNT] = cnt
    regs[_BSIZE] = bsize
    regs[_EXP] = expanded
    return status


@_njit
def _rehash(keys, vals, cap):
    """An open-addressing table (``keys`` and their ``vals``; see :func:`_hslot`) in
    ``cap`` slots: the A* kernel's ``best`` and the focal kernel's state table."""
    nk = np.full(cap, -1, np.int64)
    nv = np.empty(cap, np.int64)
    for j in range(keys.shape[0]):
        k = keys[j]
        if k != -1:
            m = _hslot(nk, k)
            nk[m] = k
            nv[m] = vals[j]
    return nk, nv


@_njit
def astar(
    ptr,
    idx,
    dist,
    start,
    goal,
    h0,
    vkeys,
    ekeys,
    ff,
    lm_need,
    nxt_tl,
    nxt_hb,
    nxt_row,
    lmd,
    minf,
    maxf,
    tcap,
    last_off_goal_lm,
    use_cat,
    cat_vt,
    cat_et,
    cat_h,
    park_t,
    node_limit,
    unreachable,
):
    """The loop of ``space_time_astar`` after its early exits: ``(expanded, path)``.

    ``path`` is empty when no path exists (or ``node_limit`` was hit). Entries live in
    a pool of arrays (``f``, conflicts, ``-t`` or :data:`TERMINAL`, vertex, ``t``,
    parent; the pool index is the last heap key), ``heap`` holds pool indices; ``best``
    (state key -> fewest conflicts seen, :data:`_CLOSED` once expanded) is an
    open-addressing table (a dense one over every ``(t, v)`` touches too many pages).
    """
    cap = 1024
    pf = np.empty(cap, np.int64)
    pc = np.empty(cap, np.int64)
    pn = np.empty(cap, np.int64)
    pv = np.empty(cap, np.int64)
    pt = np.empty(cap, np.int64)
    pp = np.empty(cap, np.int64)
    heap = np.empty(cap, np.int64)
    pf[0] = h0
    pc[0] = 0
    pn[0] = 0
    pv[0] = start
    pt[0] = 0
    pp[0] = -1
    heap[0] = 0
    bkeys = np.full(1024, -1, np.int64)
    bvals = np.empty(1024, np.int64)
    slot = _hslot(bkeys, start)
    bkeys[slot] = start
    bvals[slot] = 0
    regs = np.zeros(_AREGS, np.int64)
    regs[_SIZE] = 1
    regs[_BSIZE] = 1
    while True:
        status = _astar_loop(
            ptr, idx, dist, goal, vkeys, ekeys, ff, lm_need, nxt_tl, nxt_hb, nxt_row, lmd,
            minf, maxf, tcap, last_off_goal_lm, use_cat, cat_vt, cat_et, cat_h, park_t,
            node_limit, unreachable, pf, pc, pn, pv, pt, pp, heap, bkeys, bvals, regs,
        )  # fmt: skip
        if status != _A_GROW:
            break
        d = regs[_NEED]
        cnt = regs[_CNT]
        cap = pf.shape[0]
        while cnt + 2 * d >= cap:
            cap *= 2
        if cap > pf.shape[0]:
            pf = _grow(pf, cap)
            pc = _grow(pc, cap)
            pn = _grow(pn, cap)
            pv = _grow(pv, cap)
            pt = _grow(pt, cap)
            pp = _grow(pp, cap)
            heap = _grow(heap, cap)
        cap = bkeys.shape[0]
        while 2 * (regs[_BSIZE] + d + 1) > cap:
            cap *= 2
        if cap > bkeys.shape[0]:
            bkeys, bvals = _rehash(bkeys, bvals, cap)
    expanded = regs[_EXP]
    if status == _A_FOUND:
        return expanded, _path_of(pv, pp, regs[_TOP])
    return expanded, np.empty(0, np.int64)


@_njit
def _grow(a: np.ndarray, cap: int) -> np.ndarray:
    out = np.empty(cap, a.dtype)
    out[: a.shape[0]] = a
    return out


@_njit
def travel(ptr, idx, start, target, h, vkeys, ekeys, ff, tcap, bx, by, upper, seen, stamp):
    """The search of :func:`.symmetry.travel_time` (after its early exits): the earliest
    time at ``target``, or ``upper``. ``seen[(min(t, tcap)) * n + v] == stamp`` marks a
    closed state (the caller's buffer of at least ``(tcap + 1) * n`` entries, a new
    ``stamp`` per call); ``(bx, by)`` the blocked edge (-1, -1 for none)."""
    n = ptr.shape[0] - 1
    heap = [(h[start], 0, start)]  # (f, -t, v): among equal f the deepest first
    while len(heap) > 0:
        _, negt, v = heapq.heappop(heap)
        t = -negt
        if v == target:
            return t
        key = (t if t < tcap else tcap) * n + v
        if seen[key] == stamp:
            continue
        seen[key] = stamp
        t1 = t + 1
        base = t1 * n
        row = (t1 if t1 < tcap else tcap) * n
        for j in range(ptr[v], ptr[v + 1]):
            u = idx[j]
            if (v == bx and u == by) or (v == by and u == bx):
                continue
            if _contains(vkeys, base + u):
                continue
            if u != v and ekeys.shape[0] and _contains(ekeys, (base + v) * n + u):
                continue
            if t1 >= ff[u]:
                continue
            hu = h[u]
            if t1 + hu >= upper or seen[row + u] == stamp:
                continue
            heapq.heappush(heap, (t1 + hu, -t1, u))
    return upper


@_njit
def cat_apply(cat_vt, cat_et, ptr, idx, path, delta):
    """Add ``delta`` (+1 / -1) to the vertex-time and move counts of ``path``.

    A move ``prev -> v`` is counted at the position of the reverse move ``v -> prev``
    (see the module doc); without that arc nobody can meet it head-on.
    """
    n = ptr.shape[0] - 1
    nnz = idx.shape[0]
    prev = path[0]
    for t in range(path.shape[0]):
        v = path[t]
        cat_vt[t * n + v] += delta
        if t > 0 and prev != v:
            for j in range(ptr[v], ptr[v + 1]):
                if idx[j] == prev:
                    cat_et[t * nnz + j] += delta
                    break
        prev = v


@_njit
def dense_add(cat_vt, cat_et, ptr, idx, path, pos, plen, stamp, park_a, park_t, agent, st):
    """:func:`cat_apply` of ``path`` (+1), and ``agent``'s row of the paths, stamp and
    parking: as ``Reservations.add``, the agent is parked at its last vertex."""
    cat_apply(cat_vt, cat_et, ptr, idx, path, 1)
    last = path.shape[0] - 1
    for t in range(last + 1):
        pos[agent, t] = path[t]
    plen[agent] = last + 1
    stamp[agent] = st
    park_a[path[last]] = agent
    park_t[path[last]] = last


@_njit
def dense_remove(cat_vt, cat_et, ptr, idx, pos, plen, park_a, park_t, agent):
    """Undo :func:`dense_add` of ``agent``, its path read from its row of ``pos`` (so the
    caller converts nothing): as ``Reservations.remove``, the agent is unparked at its
    last vertex only if it is the one parked there."""
    last = plen[agent] - 1
    if last < 0:
        return
    cat_apply(cat_vt, cat_et, ptr, idx, pos[agent, : last + 1], -1)
    g = pos[agent, last]
    plen[agent] = 0
    if park_a[g] == agent:
        park_a[g] = -1
        park_t[g] = NEVER


@_njit
def _emit(out, m, t, kind, a, b, u, v):
    if m >= out.shape[0]:
        grown = np.empty((2 * out.shape[0], 6), np.int64)
        grown[:m] = out[:m]
        out = grown
    out[m, 0] = t
    out[m, 1] = kind
    out[m, 2] = a
    out[m, 3] = b
    out[m, 4] = u
    out[m, 5] = v
    return out, m + 1


@_njit
def dense_conflicts(pos, plen, stamp, park_a, park_t, path, r, skip):
    """The loop of ``Reservations.conflicts_of`` on :func:`dense_add`'s arrays.

    Rows ``(t, kind, a, b, u, v)`` in the same order: per timestep the vertex conflicts,
    the target one, the edge ones, each agent list in stamp order (the order in which
    the table's dicts list them); then the targets of ``r`` parked at its goal.
    """
    rows = plen.shape[0]
    ids = np.empty(rows, np.int64)
    keys = np.empty(rows, np.int64)
    k = 0
    far = 0
    for b in range(rows):
        if plen[b] > 0 and b != r and not skip[b]:
            ids[k] = b
            keys[k] = stamp[b]
            k += 1
            if plen[b] > far:
                far = plen[b]
    order = ids[:k][np.argsort(keys[:k], kind="mergesort")]
    out = np.empty((16, 6), np.int64)
    m = 0
    n_t = path.shape[0]
    prev = path[0]
    for t in range(n_t):
        v = path[t]
        for i in range(k):
            b = order[i]
            if t < plen[b] and pos[b, t] == v:
                out, m = _emit(out, m, t, 0, b, r, -1, v)
        e = park_a[v]
        if e >= 0 and e != r and t > park_t[v] and not skip[e]:
            out, m = _emit(out, m, t, 2, e, r, -1, v)
        if prev != v:
            for i in range(k):
                b = order[i]
                if t < plen[b] and pos[b, t] == prev and pos[b, t - 1] == v:
                    out, m = _emit(out, m, t, 1, b, r, v, prev)
        prev = v
    g = path[n_t - 1]
    for t in range(n_t, far):
        for i in range(k):
            b = order[i]
            if t < plen[b] and pos[b, t] == g:
                out, m = _emit(out, m, t, 2, r, b, -1, g)
    return out[:m]


@_njit
def mdd(
    ptr,
    idx,
    dist,
    start,
    goal,
    cost,
    vkeys,
    ekeys,
    ff,
    lm_need,
    nxt_tl,
    nxt_hb,
    nxt_row,
    lmd,
    minf,
    unreachable,
):
    """The two passes of ``mdd.build_mdd`` (``cost >= 1``), same orders.

    Returns ``(ov, ks, ke, kids, lo, hi, last)``: the kept nodes of level ``t`` are
    ``ov[lo[t]:hi[t]]`` (discovery order), node ``i``'s children ``kids[ks[i]:ke[i]]``;
    ``last`` whether level ``cost`` holds the goal.
    """
    n = ptr.shape[0] - 1
    cap = 1024
    fv = np.empty(cap, np.int64)  # forward nodes, level by level
    fks = np.empty(cap, np.int64)  # their children: fkid[fks[i]:fke[i]]
    fke = np.empty(cap, np.int64)
    kcap = 4096
    fkid = np.empty(kcap, np.int64)
    nk = 0
    lvl = np.empty(cost + 2, np.int64)  # level t is fv[lvl[t]:lvl[t + 1]]
    mark = np.full(n, -1, np.int64)
    fv[0] = start
    lvl[0] = 0
    lvl[1] = 1
    nf = 1
    for t in range(1, cost + 1):
        slack = cost - t
        need, lrow, ltl, lhb = _landmark(t, lm_need, nxt_row, nxt_tl, nxt_hb)
        for i in range(lvl[t - 1], lvl[t]):
            v = fv[i]
            fks[i] = nk
            if t == cost and v == goal:
                fke[i] = nk
                continue
            for j in range(ptr[v], ptr[v + 1]):
                u = idx[j]
                if t == cost and u != goal:
                    continue
                hu = _move_h(
                    u, v, t, n, need, lrow, ltl, lhb, vkeys, ekeys, ff, dist, lmd, minf,
                    unreachable,
                )  # fmt: skip
                if hu < 0 or hu > slack:
                    continue
                if nk >= kcap:
                    kcap *= 2
                    fkid = _grow(fkid, kcap)
                fkid[nk] = u
                nk += 1
                if t < cost and mark[u] != t:
                    mark[u] = t
                    if nf >= cap:
                        cap *= 2
                        fv = _grow(fv, cap)
                        fks = _grow(fks, cap)
                        fke = _grow(fke, cap)
                    fv[nf] = u
                    nf += 1
            fke[i] = nk
        lvl[t + 1] = nf
    # Backward: keep the nodes with a child kept at the next level.
    last = False
    for i in range(lvl[cost - 1], lvl[cost]):
        if fke[i] > fks[i]:
            last = True
    alive = np.full(n, -1, np.int64)  # alive[u] == t: u kept at level t
    if last:
        alive[goal] = cost
    ov = np.empty(nf, np.int64)
    ks = np.empty(nf, np.int64)
    ke = np.empty(nf, np.int64)
    kids = np.empty(nk, np.int64)
    lo = np.zeros(cost + 1, np.int64)
    hi = np.zeros(cost + 1, np.int64)
    no = 0
    nkid = 0
    for t in range(cost - 1, -1, -1):
        lo[t] = no
        for i in range(lvl[t], lvl[t + 1]):
            s = nkid
            for x in range(fks[i], fke[i]):
                u = fkid[x]
                if alive[u] == t + 1:
                    kids[nkid] = u
                    nkid += 1
            if nkid > s:
                ov[no] = fv[i]
                ks[no] = s
                ke[no] = nkid
                no += 1
        hi[t] = no
        for i in range(lo[t], hi[t]):
            alive[ov[i]] = t
    return ov, ks, ke, kids, lo, hi, last


# Complexity 35: mdd.restrict's two passes (and the compaction of the arrays) in one
# compiled body, step by step like the Python ones so that tests/test_jit_astar.py can
# compare their levels and orders; splitting it would pass the dozen arrays around.
@_njit
def mdd_restrict(ov, ks, ke, kids, lo, hi, last, cost, goal, drop_t, drop_v, only, cut):
    """The two passes of ``mdd.restrict`` on :func:`mdd`'s arrays (same orders).

    ``drop_t, drop_v``: the vertices dropped per level; ``only[t]``: the vertex level
    ``t`` is reduced to (-2: none given, -1: none left); ``cut``: rows ``(t, u, v)`` of
    cut moves. Returns arrays as :func:`mdd`'s, ``lo`` empty if the cost is gone.
    """
    nv = goal + 1
    for t in range(cost):
        for i in range(lo[t], hi[t]):  # (the arrays may be longer than their use)
            if ov[i] >= nv:
                nv = ov[i] + 1
    for i in range(drop_v.shape[0]):  # (any vertex of the graph)
        if drop_v[i] >= nv:
            nv = drop_v[i] + 1
    mark = np.full(nv, -1, np.int64)  # mark[v] == t: v dropped at level t
    alive = np.full(nv, -1, np.int64)  # alive[v] == t: v kept at level t
    n_drop = drop_t.shape[0]
    n_cut = cut.shape[0]
    # Backward: new nodes level by level (cost - 1 down to 0), like the kernel's mdd.
    bov = np.empty(ov.shape[0], np.int64)
    bks = np.empty(ov.shape[0], np.int64)
    bke = np.empty(ov.shape[0], np.int64)
    bkids = np.empty(kids.shape[0], np.int64)
    blo = np.zeros(cost + 1, np.int64)
    bhi = np.zeros(cost + 1, np.int64)
    empty = np.zeros(0, np.int64)
    ok = last
    for i in range(n_drop):
        if drop_t[i] == cost and drop_v[i] == goal:
            ok = False
    if only[cost] != -2 and only[cost] != goal:
        ok = False
    if not ok:
        return bov, bks, bke, bkids, empty, bhi, False
    alive[goal] = cost
    no = 0
    nkid = 0
    for t in range(cost - 1, -1, -1):
        if t < cost - 1 and bhi[t + 1] == blo[t + 1]:
            return bov, bks, bke, bkids, empty, bhi, False
        for i in range(n_drop):
            if drop_t[i] == t:
                mark[drop_v[i]] = t
        o = only[t]
        blo[t] = no
        for i in range(lo[t], hi[t]):
            v = ov[i]
            if mark[v] == t or (o != -2 and v != o):
                continue
            s = nkid
            for x in range(ks[i], ke[i]):
                u = kids[x]
                if alive[u] != t + 1:
                    continue
                gone = False
                for c in range(n_cut):
                    if cut[c, 0] == t and cut[c, 1] == v and cut[c, 2] == u:
                        gone = True
                        break
                if not gone:
                    bkids[nkid] = u
                    nkid += 1
            if nkid > s:
                bov[no] = v
                bks[no] = s
                bke[no] = nkid
                no += 1
        bhi[t] = no
        for i in range(blo[t], bhi[t]):
            alive[bov[i]] = t
    if bhi[0] == blo[0]:
        return bov, bks, bke, bkids, empty, bhi, False
    # Forward: drop what the start no longer reaches (reach[v] == t: reached at t).
    reach = np.full(nv, -1, np.int64)
    keep = np.zeros(no, np.bool_)
    for i in range(blo[0], bhi[0]):
        keep[i] = True
    for t in range(cost - 1):
        for i in range(blo[t], bhi[t]):
            if keep[i]:
                for x in range(bks[i], bke[i]):
                    reach[bkids[x]] = t + 1
        for i in range(blo[t + 1], bhi[t + 1]):
            if reach[bov[i]] == t + 1:
                keep[i] = True
    # Compact (kept nodes' children are all kept).
    ov2 = np.empty(no, np.int64)
    ks2 = np.empty(no, np.int64)
    ke2 = np.empty(no, np.int64)
    kids2 = np.empty(nkid, np.int64)
    lo2 = np.zeros(cost + 1, np.int64)
    hi2 = np.zeros(cost + 1, np.int64)
    m = 0
    mk = 0
    for t in range(cost - 1, -1, -1):
        lo2[t] = m
        for i in range(blo[t], bhi[t]):
            if keep[i]:
                ov2[m] = bov[i]
                ks2[m] = mk
                for x in range(bks[i], bke[i]):
                    kids2[mk] = bkids[x]
                    mk += 1
                ke2[m] = mk
                m += 1
        hi2[t] = m
    return ov2[:m].copy(), ks2[:m].copy(), ke2[:m].copy(), kids2[:mk].copy(), lo2, hi2, True


@_njit
def bfs_many(indptr, indices, targets, unreachable):
    """Hop distances to each of ``targets`` on an undirected CSR graph, one row each
    (``unreachable`` where there is no path): ``core.graph``'s breadth-first search,
    compiled, for the distance tables of a warm process (see ``Graph.fill_distances``)."""
    n = indptr.shape[0] - 1
    k = targets.shape[0]
    out = np.full((k, n), unreachable, np.int64)
    queue = np.empty(max(n, 1), np.int64)
    for r in range(k):
        d = out[r]
        s = targets[r]
        d[s] = 0
        queue[0] = s
        head = 0
        tail = 1
        while head < tail:
            v = queue[head]
            head += 1
            dv = d[v] + 1
            for j in range(indptr[v], indptr[v + 1]):
                u = indices[j]
                if d[u] == unreachable:
                    d[u] = dv
                    queue[tail] = u
                    tail += 1
    return out


@_njit
def _kid_range(ov, ks, ke, lo, hi, cost, t, u):
    """Where the children of ``u`` at level ``t`` of an MDD's arrays lie in its ``kids``:
    ``(-1, -1)`` from level ``cost`` on (the path parks: the only child is the goal)."""
    if t >= cost:
        return -1, -1
    for i in range(lo[t], hi[t]):
        if ov[i] == u:
            return ks[i], ke[i]
    return 0, 0


@_njit
def mdd_dependent(
    ova, ksa, kea, kidsa, loa, hia, costa, goala, ovb, ksb, keb, kidsb, lob, hib, costb, goalb
):  # fmt: skip
    """``heuristics.dependent`` on two MDDs' arrays (``jit.build_mdd``): whether no pair
    of their paths is free of vertex and swap conflicts (paths park at their goals)."""
    horizon = max(costa, costb)
    if loa[0] == hia[0] or lob[0] == hib[0]:
        return True
    dead = set()
    dead.add((-1, -1, -1))  # (types the set for numba; no state has t = -1)
    cap = horizon + 2
    ft = np.empty(cap, np.int64)
    fu = np.empty(cap, np.int64)
    fv = np.empty(cap, np.int64)
    fas = np.empty(cap, np.int64)
    fae = np.empty(cap, np.int64)
    fbs = np.empty(cap, np.int64)
    fbe = np.empty(cap, np.int64)
    fp = np.empty(cap, np.int64)

    def push(d, t, u, v):  # a frame for the joint state (t, u, v) at depth d
        ft[d] = t
        fu[d] = u
        fv[d] = v
        fas[d], fae[d] = _kid_range(ova, ksa, kea, loa, hia, costa, t, u)
        fbs[d], fbe[d] = _kid_range(ovb, ksb, keb, lob, hib, costb, t, v)
        fp[d] = 0

    push(0, 0, ova[loa[0]], ovb[lob[0]])
    depth = 1
    while depth > 0:
        d = depth - 1
        t = ft[d]
        u = fu[d]
        v = fv[d]
        if t >= horizon:
            return False
        na = 1 if fas[d] < 0 else fae[d] - fas[d]
        nb = 1 if fbs[d] < 0 else fbe[d] - fbs[d]
        pushed = False
        while fp[d] < na * nb:
            p = fp[d]
            fp[d] = p + 1
            u2 = goala if fas[d] < 0 else kidsa[fas[d] + p // nb]
            v2 = goalb if fbs[d] < 0 else kidsb[fbs[d] + p % nb]
            if u2 == v2 or (u2 == v and v2 == u) or (t + 1, u2, v2) in dead:
                continue
            push(depth, t + 1, u2, v2)
            depth += 1
            pushed = True
            break
        if not pushed:
            dead.add((t, u, v))
            depth -= 1
    return True
