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
table; per id the fewest conflicts found, the parent id and whether it was expanded.
``live[f]`` and the bucket lists ``bhead[f]`` (entries above the bound, linked by
``enext``) are arrays indexed by ``f``, grown on demand.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from hierplan_opt.search._astar_kernel import _contains, _grow, _njit

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


@intrinsic
def _monotonic(typingctx):
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


@_njit
def monotonic():
    """Seconds of the clock ``time.perf_counter`` reads (for the tests)."""
    return _monotonic()


# ---------------------------------------------------------------- the state table
@_njit
def _hslot(hkeys, enc):
    mask = hkeys.shape[0] - 1
    i = ((enc * 0x5851F42D4C957F2D) >> 17) & mask
    while hkeys[i] != -1 and hkeys[i] != enc:
        i = (i + 1) & mask
    return i


@_njit
def _rehash(hkeys, hids):
    nk = np.full(2 * hkeys.shape[0], -1, np.int64)
    ni = np.empty(2 * hkeys.shape[0], np.int64)
    for j in range(hkeys.shape[0]):
        if hkeys[j] != -1:
            m = _hslot(nk, hkeys[j])
            nk[m] = hkeys[j]
            ni[m] = hids[j]
    return nk, ni


# ---------------------------------------------------------------- FOCAL (a heap of entries)
@_njit
def _less(a, b, fb, ec, et, ef, ek):
    """Entry ``a`` before ``b``: ``(c, tie, f, key)``, or ``(tie, c, f, key)`` if ``fb``."""
    if fb:
        if et[a] != et[b]:
            return et[a] < et[b]
        if ec[a] != ec[b]:
            return ec[a] < ec[b]
    else:
        if ec[a] != ec[b]:
            return ec[a] < ec[b]
        if et[a] != et[b]:
            return et[a] < et[b]
    if ef[a] != ef[b]:
        return ef[a] < ef[b]
    return ek[a] < ek[b]


@_njit
def _push(heap, size, x, fb, ec, et, ef, ek):
    """Put entry ``x`` in the heap of ``size`` entries (room checked by the caller)."""
    i = size
    while i > 0:
        par = (i - 1) >> 1
        if _less(x, heap[par], fb, ec, et, ef, ek):
            heap[i] = heap[par]
            i = par
        else:
            break
    heap[i] = x


@_njit
def _down(heap, i, size, fb, ec, et, ef, ek):
    """Move ``heap[i]`` down into place among the first ``size`` entries."""
    x = heap[i]
    while True:
        c1 = 2 * i + 1
        if c1 >= size:
            break
        m = c1
        c2 = c1 + 1
        if c2 < size and _less(heap[c2], heap[c1], fb, ec, et, ef, ek):
            m = c2
        if _less(heap[m], x, fb, ec, et, ef, ek):
            heap[i] = heap[m]
            i = m
        else:
            break
    heap[i] = x


@_njit
def _suffix(counts_at, length):
    """``out[t]`` = the sum of ``counts_at[s]`` for ``s > t`` (``t < length``)."""
    out = np.zeros(length + 1, np.int64)
    for t in range(length - 1, -1, -1):
        out[t] = out[t + 1] + counts_at[t + 1] if t + 1 < length else 0
    return out


# Complexity: the whole of focal._focal_loop (with _park and _raise_bound written out)
# in one compiled body, step by step like the Python one, so that the tests can hold
# them to identical results; splitting it would pass two dozen arrays around.
@_njit
def focal(
    ptr,
    idx,
    h,
    start,
    goal,
    vkeys,
    ekeys,
    hold,
    max_t,
    cat_vt,
    cat_et,
    cat_h,
    park_t,
    partner,
    pp,
    w,
    end,
    budget,
    avoid,
    limit,
):
    """The search of ``focal._focal_loop``: ``(status, expanded, f_min, path)``.

    ``status`` is :data:`FOUND` (``path`` the result), :data:`NO_PATH`, :data:`TIMEOUT`
    (``end``, a ``perf_counter`` time, passed at a check every 1024 expansions) or
    :data:`DECLINED` (an ``f`` above :data:`F_CAP`).
    """
    n = ptr.shape[0] - 1
    nnz = idx.shape[0]
    pw = PARTNER_WEIGHT
    nv = vkeys.shape[0]
    ne = ekeys.shape[0]
    empty = np.empty(0, np.int64)
    # The later visits of the others to the goal, and of the partner (park conflicts).
    lp = pp.shape[0]
    partner_goal = pp[lp - 1] if lp > 0 else -1
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
    # states
    hcap = 1024
    hkeys = np.full(hcap, -1, np.int64)
    hids = np.empty(hcap, np.int64)
    scap = 512
    s_key = np.empty(scap, np.int64)
    s_best = np.empty(scap, np.int64)
    s_par = np.empty(scap, np.int64)
    s_closed = np.zeros(scap, np.bool_)
    n_s = 0
    # entries
    ecap = 1024
    ec = np.empty(ecap, np.int64)
    et = np.empty(ecap, np.int64)
    ef = np.empty(ecap, np.int64)
    ek = np.empty(ecap, np.int64)
    es = np.empty(ecap, np.int64)
    enext = np.empty(ecap, np.int64)
    n_e = 0
    heap = np.empty(ecap, np.int64)
    size = 0
    # f tables
    f0 = h[start] if h[start] > hold else hold
    if f0 > F_CAP:
        return DECLINED, 0, 0, empty
    fcap = 2 * f0 + 64
    live = np.zeros(fcap, np.int64)
    bhead = np.full(fcap, -1, np.int64)
    lo = f0  # no f below this has a live state
    # the start
    s_key[0] = start
    s_best[0] = 0
    s_par[0] = -1
    n_s = 1
    hkeys[_hslot(hkeys, 2 * start)] = 2 * start
    hids[_hslot(hkeys, 2 * start)] = 0
    live[f0] = 1
    n_live = 1
    ec[0] = 0
    et[0] = (f0 + h[start]) * TIE
    ef[0] = f0
    ek[0] = start
    es[0] = 0
    n_e = 1
    heap[0] = 0
    size = 1
    fmin = f0
    bound = int(w * fmin + 1e-9)
    fb = False
    expanded = 0
    raise_fmin = False
    # The park at time 0 (start == goal), then the loop; each generated state or
    # terminal goes through the same code (``gen``), written once below.
    first_park = start == goal and hold == 0 and not (avoid and goal_after[0] != 0)
    top = 0
    top_key = start
    c = 0
    f = f0
    first = False
    nt = 0
    v = start
    j = ptr[v]
    jend = j
    phase = 0  # 0: the initial park; 1: popping; 2: moving through successors
    if first_park:
        jend = j + 1  # one pass of the generation code, for the terminal only
    else:
        phase = 1
    while True:
        if phase == 1:
            if raise_fmin or size == 0:
                raise_fmin = False
                if n_live == 0:
                    if size == 0:
                        break
                else:
                    if live[fmin] == 0:
                        while live[lo] == 0:
                            lo += 1
                        if lo > fmin:
                            fmin = lo
                    new_bound = int(w * fmin + 1e-9)
                    top_f = new_bound if new_bound < fcap - 1 else fcap - 1
                    for fx in range(bound + 1, top_f + 1):
                        e = bhead[fx]
                        bhead[fx] = -1
                        while e >= 0:
                            nx = enext[e]
                            _push(heap, size, e, fb, ec, et, ef, ek)
                            size += 1
                            e = nx
                    if new_bound > bound:
                        bound = new_bound
                    if size == 0:
                        continue
            top_e = heap[0]
            size -= 1
            if size > 0:
                heap[0] = heap[size]
                _down(heap, 0, size, fb, ec, et, ef, ek)
            c = ec[top_e]
            f = ef[top_e]
            top = es[top_e]
            if s_best[top] != c:
                continue  # stale entry
            top_key = ek[top_e]
            if top_key < 0:  # terminal: the agent parks at its goal from time f on
                length = 1
                x = s_par[top]
                while x >= 0:
                    length += 1
                    x = s_par[x]
                path = np.empty(length, np.int64)
                path[length - 1] = goal
                x = s_par[top]
                i = length - 2
                while x >= 0:
                    path[i] = s_key[x] % n
                    i -= 1
                    x = s_par[x]
                while length > 1 and path[length - 2] == goal:
                    length -= 1
                return FOUND, expanded, fmin, path[:length].copy()
            first = not s_closed[top]
            if first:
                s_closed[top] = True
                live[f] -= 1
                n_live -= 1
            expanded += 1
            if expanded == limit:
                break
            if expanded == budget:
                fb = True  # FOCAL by g + 2h first from now on: re-heapify
                for i in range((size >> 1) - 1, -1, -1):
                    _down(heap, i, size, fb, ec, et, ef, ek)
            if (expanded & 1023) == 0 and _monotonic() >= end:
                return TIMEOUT, expanded, fmin, empty
            t = top_key // n
            v = top_key - t * n
            nt = t + 1
            if nt > max_t:
                if first and f == fmin and live[f] == 0:
                    raise_fmin = True
                continue
            j = ptr[v]
            jend = ptr[v + 1]
            phase = 2
        # ---- the moves out of v arriving at nt (phase 2), or the initial park (phase 0)
        while j < jend:
            if phase == 0:
                u = goal
                nc = 0
                tc = goal_after[0]
            else:
                u = idx[j]
                base = nt * n
                nk = base + u
                if nv > 0 and _contains(vkeys, nk):
                    j += 1
                    continue
                if ne > 0 and u != v and _contains(ekeys, (base + v) * n + u):
                    j += 1
                    continue
                nc = c
                if nt < cat_h:
                    occ = cat_vt[nk]
                    if occ:
                        nc += occ
                        if nt < lp and pp[nt] == u:
                            nc += pw
                if nt > park_t[u]:
                    nc += 1
                    if u == partner_goal:  # the partner is the one parked at u
                        nc += pw
                if u != v and nt < cat_h:
                    occ = cat_et[nt * nnz + j]  # someone moves u -> v: a swap
                    if occ:
                        nc += occ
                        if nt < lp and pp[nt - 1] == u and pp[nt] == v:
                            nc += pw
                if avoid and nc:
                    j += 1
                    continue
                hu = h[u]
                nf = nt + hu if nt + hu > hold else hold
                enc = 2 * nk
                slot = _hslot(hkeys, enc)
                sid = -1
                if hkeys[slot] == enc:
                    sid = hids[slot]
                if sid < 0 or nc < s_best[sid]:
                    if sid < 0:
                        if nf > F_CAP:
                            return DECLINED, expanded, fmin, empty
                        if n_s >= scap:
                            scap *= 2
                            s_key = _grow(s_key, scap)
                            s_best = _grow(s_best, scap)
                            s_par = _grow(s_par, scap)
                            s_closed = _grow(s_closed, scap)
                        sid = n_s
                        n_s += 1
                        s_key[sid] = nk
                        s_closed[sid] = False
                        hkeys[slot] = enc
                        hids[slot] = sid
                        if 2 * n_s > hkeys.shape[0]:
                            hkeys, hids = _rehash(hkeys, hids)
                        if nf >= fcap:
                            nfc = 2 * fcap if 2 * fcap > nf + 1 else nf + 1
                            live = _grow_zero(live, nfc, 0)
                            bhead = _grow_zero(bhead, nfc, -1)
                            fcap = nfc
                        live[nf] += 1
                        n_live += 1
                        if nf < lo:
                            lo = nf
                    s_best[sid] = nc
                    s_par[sid] = top
                    if n_e >= ecap:
                        ecap *= 2
                        ec = _grow(ec, ecap)
                        et = _grow(et, ecap)
                        ef = _grow(ef, ecap)
                        ek = _grow(ek, ecap)
                        es = _grow(es, ecap)
                        enext = _grow(enext, ecap)
                        heap = _grow(heap, ecap)
                    e = n_e
                    n_e += 1
                    ec[e] = nc
                    et[e] = (nf + hu) * TIE - nt
                    ef[e] = nf
                    ek[e] = nk
                    es[e] = sid
                    if nf <= bound:
                        _push(heap, size, e, fb, ec, et, ef, ek)
                        size += 1
                    else:
                        enext[e] = bhead[nf]
                        bhead[nf] = e
                if not (u == goal and nt >= hold):
                    j += 1
                    continue
                tc = nc + goal_after[nt if nt < span else span]
                tc += pw * p_after[nt if nt < span else span]
            # ---- the terminal node (parked at the goal from nt on): focal._park
            j += 1
            if avoid and tc:
                continue
            tk = -(nt * n + goal + 1)
            enc = 2 * (nt * n + goal) + 1
            slot = _hslot(hkeys, enc)
            sid = -1
            if hkeys[slot] == enc:
                sid = hids[slot]
                if tc >= s_best[sid]:
                    continue
            else:
                if nt > F_CAP:
                    return DECLINED, expanded, fmin, empty
                if n_s >= scap:
                    scap *= 2
                    s_key = _grow(s_key, scap)
                    s_best = _grow(s_best, scap)
                    s_par = _grow(s_par, scap)
                    s_closed = _grow(s_closed, scap)
                sid = n_s
                n_s += 1
                s_key[sid] = tk
                s_closed[sid] = False
                hkeys[slot] = enc
                hids[slot] = sid
                if 2 * n_s > hkeys.shape[0]:
                    hkeys, hids = _rehash(hkeys, hids)
                if nt >= fcap:
                    nfc = 2 * fcap if 2 * fcap > nt + 1 else nt + 1
                    live = _grow_zero(live, nfc, 0)
                    bhead = _grow_zero(bhead, nfc, -1)
                    fcap = nfc
                live[nt] += 1
                n_live += 1
                if nt < lo:
                    lo = nt
            s_best[sid] = tc
            s_par[sid] = top
            if n_e >= ecap:
                ecap *= 2
                ec = _grow(ec, ecap)
                et = _grow(et, ecap)
                ef = _grow(ef, ecap)
                ek = _grow(ek, ecap)
                es = _grow(es, ecap)
                enext = _grow(enext, ecap)
                heap = _grow(heap, ecap)
            e = n_e
            n_e += 1
            ec[e] = tc
            et[e] = nt * TIE - nt
            ef[e] = nt
            ek[e] = tk
            es[e] = sid
            if nt <= bound:
                _push(heap, size, e, fb, ec, et, ef, ek)
                size += 1
            else:
                enext[e] = bhead[nt]
                bhead[nt] = e
        if phase == 2 and first and f == fmin and live[f] == 0:
            raise_fmin = True
        phase = 1
    return NO_PATH, expanded, fmin, empty


@_njit
def _grow_zero(a, cap, fill):
    out = np.full(cap, fill, a.dtype)
    out[: a.shape[0]] = a
    return out
