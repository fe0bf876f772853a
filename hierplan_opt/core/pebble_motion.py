# pyright: basic
# (Basic, not strict like the rest of core/: its integer-state tuples from numpy/scipy
# are untyped; typing them is left to the module's owner.)
"""Exact reachability of agent arrangements: pebble motion on graphs with rotations.

The problem class is this project's MAPF: on an undirected graph every agent waits or
moves along one edge per timestep, two agents never share a vertex, two agents never
swap along an edge, and an agent may enter a vertex that is being left at the same
timestep. So a timestep is a set of chains (each ending in an empty vertex) and of
rotations along cycles of length >= 3. Which arrangements are reachable from which is
decided here, per connected component, without search; `docs/feasibility.md` states the
theorems and their proof sketches.

The test gives every agent a *class*: the component of its "marked-pebble state" (where
it stands, and how the empty vertices lie around it) in a small abstract graph whose
edges are the moves that state can make when the other agents are interchangeable. A
class never changes while agents move, and inside a class every permutation can be
realised, except in two kinds of component that get their own invariant: a component
that is one cycle (agents keep their cyclic order), and a component with no empty
vertex (only rotations: agents off every cycle never move, a cycle keeps its cyclic
order, and a cactus of odd cycles only allows even permutations).

Coloured agents (teams, TAPF) are handled the same way: within a class every
arrangement of the colours is reachable, so the counts of each colour per class must
agree, and the two special invariants are checked on colour sequences.
"""

from __future__ import annotations

import sys
import weakref
from collections import Counter
from collections.abc import Hashable, Iterable, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from hierplan_opt.core.graph import Graph, keep_per_map

State = tuple  # ('H', ecc) | ('l', v) | ('c', v, holes_on_side_0) | ('j', v, 'rich' | branch)


class _UnionFind:
    def __init__(self) -> None:
        self.parent: dict[Hashable, Hashable] = {}

    def find(self, x: Hashable) -> Hashable:
        p = self.parent
        root = x
        while True:
            q = p.get(root, root)
            if q == root:
                break
            root = q
        while x != root:  # path compression
            q = p[x]
            p[x] = root
            x = q
        return root

    def union(self, a: Hashable, b: Hashable) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[ra] = rb


@dataclass(frozen=True)
class Violation:
    """Why a target arrangement is unreachable: ``kind`` and the vertices involved.

    ``kind`` is ``"class"`` (a robot/colour cannot reach its goal's class; ``vertex`` is
    its start, ``other`` its goal), ``"cyclic"`` (a ring's cyclic order; ``vertex`` is on
    it), ``"parity"`` (a full cactus of odd cycles; ``vertex`` is in it) or ``"fixed"``
    (a robot on a full component that no cycle passes through; ``vertex`` is its start).
    ``index`` is the robot (or, for colour counts, a robot of the colour) concerned.
    """

    kind: str
    vertex: int
    other: int | None = None
    index: int | None = None


def _samples(lo: int, hi: int, *special: int) -> list[int]:
    """Values of [lo, hi] that meet every case of a state that depends on k only
    through "k == special" tests: both ends, the special values, and a generic one."""
    if lo > hi:
        return []
    out = {lo, hi, *(x for x in special if lo <= x <= hi)}
    out.update(x for x in range(lo, min(hi, lo + len(special) + 2) + 1))
    return sorted(out)


@dataclass(frozen=True)
class _Chain:
    """A maximal path of degree-2 tree vertices, from end A to end B.

    ``toward_a[i]`` is the neighbour of ``verts[i]`` on the A side; ``size_a[i]`` the
    number of vertices on that side. A marked pebble inside keeps its *track* c, the
    number of other pebbles on its A side, until it leaves the chain.
    """

    verts: list[int]
    toward_a: list[int]
    end_a: int
    t_a: int
    end_b: int
    t_b: int
    size_a: list[int]
    n: int


class _Classes:
    """The classes of one component with h holes: union-find over non-chain states
    plus, per chain, which end(s) each track can leave by."""

    def __init__(
        self,
        structure: PebbleStructure,
        uf: _UnionFind,
        chains: list[_Chain],
        exits: list[tuple[tuple[int, int, int], tuple[int, int, int]]],
        p: int,
        h: int,
    ) -> None:
        self.s, self.uf, self.chains, self.exits, self.p, self.h = (
            structure,
            uf,
            chains,
            exits,
            p,
            h,
        )

    def of(self, state: State) -> Hashable:
        """The class of a state (a canonical representative)."""
        if state[0] != "t":
            return self.uf.find(state)
        _, k, c = state
        ch = self.chains[k]
        (alo, ahi, _), (blo, bhi, _) = self.exits[k]
        if alo <= c <= ahi:
            return self.uf.find(self.s._exit_state(ch, 0, c, self.p, self.h))
        if blo <= c <= bhi:
            return self.uf.find(self.s._exit_state(ch, -1, c, self.p, self.h))
        return state  # a track that can leave neither way: agents there never reorder


class PebbleStructure:
    """Bridges, 2-edge-connected components and the bridge tree of an undirected graph.

    Built once per graph (cached) in O(V + E).

    Example
    -------
    >>> g = Graph.grid(3, 3, obstacles=[(1, 1)])  # a ring of 8 cells
    >>> s = PebbleStructure.of(g)
    >>> s.is_cycle_component[s.comp[0]]
    True
    """

    _cache: weakref.WeakKeyDictionary[Graph, PebbleStructure] = weakref.WeakKeyDictionary()
    # The structures of the last maps, by their shared ``Graph.adj`` (graphs of one map
    # share it) and free cells: a map read again per solve is analysed once per process.
    _by_map: ClassVar[dict[tuple[int, int], tuple[object, np.ndarray, PebbleStructure]]] = {}

    @classmethod
    def of(cls, graph: Graph) -> PebbleStructure:
        """The (cached) structure of ``graph``."""
        s = cls._cache.get(graph)
        if s is None:
            adj = graph.adj
            key = (id(adj), hash(graph.passable.tobytes()))
            hit = cls._by_map.get(key)
            if hit is not None and hit[0] is adj and np.array_equal(hit[1], graph.passable):
                s = hit[2]
            else:
                s = cls(graph)
                keep_per_map(cls._by_map, key, (adj, graph.passable, s))
            cls._cache[graph] = s
        return s

    def __init__(self, graph: Graph) -> None:
        # scipy's graph routines cost ~0.2 s to import: a process that has not loaded
        # them (a single small solve from the command line) uses the Python ones below.
        use_scipy = "scipy.sparse.csgraph" in sys.modules

        adj = graph.adj
        n = graph.n
        self.adj = adj
        self.n = n
        indptr, indices = graph.indptr, graph.indices
        passable = graph.passable
        deg = np.diff(indptr)
        rows = np.repeat(np.arange(n), deg)
        mat = None
        if use_scipy:
            import scipy.sparse as sp  # heavy module: scipy
            from scipy.sparse.csgraph import connected_components  # heavy module: scipy

            mat = sp.csr_matrix(
                (np.ones(len(indices), dtype=np.int8), indices, indptr), shape=(n, n)
            )

        # Connected components (blocked cells are isolated and get -1).
        if mat is not None:
            _, labels = connected_components(mat, directed=False)
        else:
            labels = np.array(_component_labels(adj), dtype=np.int64)
        comp = np.full(n, -1, dtype=np.int64)
        free = np.flatnonzero(passable)
        _, first, inv = np.unique(labels[free], return_index=True, return_inverse=True)
        order_c = np.argsort(first, kind="stable")  # number components by first vertex
        rank = np.empty_like(order_c)
        rank[order_c] = np.arange(len(order_c))
        comp[free] = rank[inv]
        ncomp = len(order_c)
        self.comp = comp.tolist()
        self.comp_size = np.bincount(comp[free], minlength=ncomp).tolist()
        members_sorted = free[np.argsort(comp[free], kind="stable")]
        bounds = np.concatenate(([0], np.cumsum(self.comp_size)))
        ms, bs = members_sorted.tolist(), bounds.tolist()
        self.comps = [ms[bs[c] : bs[c + 1]] for c in range(ncomp)]

        # Bridges: a DFS tree per component (C speed); low-link = the smallest preorder
        # index reachable by one back edge from the subtree. Tree edge (parent, v) is a
        # bridge iff no back edge leaves v's subtree upwards, i.e. low[v] == disc[v].
        disc = np.zeros(n, dtype=np.int64)
        parent = np.full(n, -1, dtype=np.int64)
        preorder: list[np.ndarray] = []
        offset = 0
        for c in range(ncomp):
            root = self.comps[c][0]
            if mat is not None:
                from scipy.sparse.csgraph import depth_first_order  # heavy module: scipy

                order, pred = depth_first_order(mat, root, directed=False, return_predecessors=True)
            else:
                order, pred = _dfs_order(adj, root)
            disc[order] = offset + np.arange(len(order))
            parent[order] = pred[order]
            parent[root] = -1
            offset += len(order)
            preorder.append(order)
        nbr_disc = disc[indices].copy()
        nbr_disc[indices == parent[rows]] = np.iinfo(np.int64).max
        low = disc.copy()
        has = deg > 0
        if len(indices):
            mins = np.minimum.reduceat(nbr_disc, indptr[:-1][has])
            low[has] = np.minimum(low[has], mins)
        low_l = low.tolist()
        par_l = parent.tolist()
        for order in preorder:
            for v in order[::-1].tolist():
                p = par_l[v]
                if p >= 0 and low_l[v] < low_l[p]:
                    low_l[p] = low_l[v]
        low = np.array(low_l, dtype=np.int64)
        is_br_child = (parent >= 0) & (low == disc)
        bridge_nbrs: dict[int, set[int]] = {}
        for v in np.flatnonzero(is_br_child).tolist():
            p = par_l[v]
            bridge_nbrs.setdefault(v, set()).add(p)
            bridge_nbrs.setdefault(p, set()).add(v)
        self._bridge_nbrs = bridge_nbrs

        # 2-edge-connected components: components after deleting the bridges.
        child_br = is_br_child[indices] & (parent[indices] == rows)
        parent_br = is_br_child[rows] & (parent[rows] == indices)
        keep = ~(child_br | parent_br)
        if use_scipy:
            import scipy.sparse as sp  # heavy module: scipy
            from scipy.sparse.csgraph import connected_components  # heavy module: scipy

            mat2 = sp.csr_matrix(
                (np.ones(int(keep.sum()), dtype=np.int8), (rows[keep], indices[keep])),
                shape=(n, n),
            )
            _, elabels = connected_components(mat2, directed=False)
        else:
            adj2 = [
                [w for w in nb if w not in bridge_nbrs[v]] if v in bridge_nbrs else nb
                for v, nb in enumerate(adj)
            ]
            elabels = np.array(_component_labels(adj2), dtype=np.int64)
        ecc = np.full(n, -1, dtype=np.int64)
        _, efirst, einv = np.unique(elabels[free], return_index=True, return_inverse=True)
        ecc[free] = einv
        m = len(efirst)
        self.ecc = ecc.tolist()
        esize = np.bincount(ecc[free], minlength=m)
        emembers_sorted = free[np.argsort(ecc[free], kind="stable")]
        ebounds = np.concatenate(([0], np.cumsum(esize)))
        em, eb = emembers_sorted.tolist(), ebounds.tolist()
        self.ecc_members = [em[eb[e] : eb[e + 1]] for e in range(m)]
        self._ecc_array = ecc
        self._free = free
        self.big = (esize >= 3).tolist()
        inner_deg = np.bincount(rows[keep], minlength=n)
        not_two = np.bincount(ecc[free], weights=(inner_deg[free] != 2), minlength=m)
        self.ecc_is_cycle = ((esize >= 3) & (not_two == 0)).tolist()
        self.is_cycle_component = [
            esize[self.ecc[c[0]]] == len(c) and self.ecc_is_cycle[self.ecc[c[0]]]
            for c in self.comps
        ]

        # Bridge tree, rooted at each component's first 2ECC; subtree sizes in vertices.
        tparent = [-1] * m
        torder: list[int] = []
        seen = [False] * m
        ecc_l = self.ecc
        tree_nbrs: dict[int, list[int]] = {}
        for v, ws in bridge_nbrs.items():
            tree_nbrs.setdefault(ecc_l[v], []).extend(ecc_l[w] for w in ws)
        for c in self.comps:
            r = ecc_l[c[0]]
            seen[r] = True
            stack = [r]
            while stack:
                e = stack.pop()
                torder.append(e)
                for f in tree_nbrs.get(e, ()):
                    if not seen[f]:
                        seen[f] = True
                        tparent[f] = e
                        stack.append(f)
        self.tparent = tparent
        self.order = torder
        sub = esize.tolist()
        for e in reversed(torder):
            if tparent[e] >= 0:
                sub[tparent[e]] += sub[e]
        self.sub_size = sub
        self._abstract: dict[tuple[int, int], _Classes] = {}
        self._chains: dict[int, list[_Chain]] = {}
        self._chain_at: dict[int, tuple[int, int]] = {}

    def bridge_nbrs(self, v: int) -> set[int]:
        """Neighbours of ``v`` across a bridge."""
        return self._bridge_nbrs.get(v, set())

    # ------------------------------------------------------------------ sides of bridges
    def side(self, a: int, b: int, sub: Sequence[int], total: int) -> int:
        """Size (or hole count, given subtree ``sub`` values) of b's side of bridge a-b."""
        eb = self.ecc[b]
        if self.tparent[eb] == self.ecc[a]:
            return sub[eb]
        return total - sub[self.ecc[a]]

    def subtree_holes(self, occupied: Sequence[bool]) -> list[int]:
        """Empty vertices in each bridge-tree subtree for one arrangement."""
        empty = ~np.asarray(occupied, dtype=bool)[self._free]
        holes = np.bincount(
            self._ecc_array[self._free], weights=empty, minlength=len(self.ecc_members)
        )
        out = holes.astype(np.int64).tolist()
        tp = self.tparent
        for e in reversed(self.order):
            if tp[e] >= 0:
                out[tp[e]] += out[e]
        return out

    # ------------------------------------------------------------------ abstract graph
    def abstract_classes(self, cid: int, h: int) -> _Classes:
        """Classes of the marked-pebble state graph of component ``cid`` with h holes."""
        key = (cid, h)
        classes = self._abstract.get(key)
        if classes is None:
            classes = self._build_abstract(cid, h)
            self._abstract[key] = classes
        return classes

    def _is_corridor(self, v: int) -> bool:
        return not self.big[self.ecc[v]] and len(self.adj[v]) == 2

    def _chains_of(self, cid: int) -> list[_Chain]:
        """Maximal paths of degree-2 tree vertices of component ``cid`` (h-independent)."""
        chains = self._chains.get(cid)
        if chains is not None:
            return chains
        chains = []
        nc = self.comp_size[cid]
        for v in self.comps[cid]:
            if not self._is_corridor(v) or v in self._chain_at:
                continue
            ends: list[tuple[list[int], int]] = []
            for first in self.adj[v]:  # walk to both ends
                path: list[int] = []
                prev, cur = v, first
                while self._is_corridor(cur):
                    path.append(cur)
                    prev, cur = cur, next(w for w in self.adj[cur] if w != prev)
                ends.append((path, cur))
            (path_a, end_a), (path_b, end_b) = ends
            verts = [*reversed(path_a), v, *path_b]
            toward_a = [end_a, *verts[:-1]]
            chain = _Chain(
                verts=verts,
                toward_a=toward_a,
                end_a=end_a,
                t_a=self.adj[end_a].index(verts[0]),
                end_b=end_b,
                t_b=self.adj[end_b].index(verts[-1]),
                size_a=[
                    self.side(x, y, self.sub_size, nc) for x, y in zip(verts, toward_a, strict=True)
                ],
                n=nc,
            )
            for i, x in enumerate(verts):
                self._chain_at[x] = (len(chains), i)
            chains.append(chain)
        self._chains[cid] = chains
        return chains

    def _arrive(self, b: int, t: int, m: int, h: int) -> State:
        """State of a pebble that enters b (not a corridor vertex) from its neighbour
        index t, with m holes in b's other branches (so h - m on the side it came from)."""
        if self.big[self.ecc[b]]:
            return ("H", self.ecc[b])
        if len(self.adj[b]) == 1:
            return ("l", b)
        return ("j", b, t) if m == 0 else ("j", b, "rich")

    def _build_abstract(self, cid: int, h: int) -> _Classes:
        uf = _UnionFind()
        adj = self.adj
        nc = self.comp_size[cid]
        sub = self.sub_size
        # Moves into or out of corridor vertices are the chains' business (below); the
        # loops over hole counts k only need the values where the target state changes
        # (m = k - 1 = 0 or not), so each enumeration looks at <= 3 values of k.
        relevant = [
            a
            for a in self.comps[cid]
            if (a in self._bridge_nbrs if self.big[self.ecc[a]] else len(adj[a]) != 2)
        ]
        for a in relevant:
            nb = adj[a]
            if self.big[self.ecc[a]]:
                src: State = ("H", self.ecc[a])
                for r in self.bridge_nbrs(a):
                    if self.big[self.ecc[r]]:
                        uf.union(src, ("H", self.ecc[r]))
                    elif not self._is_corridor(r):
                        size_r = self.side(a, r, sub, nc)
                        t = adj[r].index(a)
                        lo, hi = max(0, h - (nc - size_r)), min(size_r - 1, h - 1)
                        for m in _samples(lo, hi):
                            uf.union(src, self._arrive(r, t, m, h))
                continue
            if len(nb) == 1:
                if not self._is_corridor(nb[0]):
                    self._step(uf, ("l", a), a, 0, h, h)
                continue
            sizes = [self.side(a, b, sub, nc) for b in nb]
            rich: State = ("j", a, "rich")
            for i, si in enumerate(sizes):
                if self._is_corridor(nb[i]):
                    continue
                if h >= 2:
                    for k in _samples(max(1, h - (nc - 1 - si)), min(si, h - 1)):
                        self._step(uf, rich, a, i, k, h)
                if si >= h:
                    self._step(uf, ("j", a, i), a, i, h, h)
        chains = self._chains_of(cid)
        p = nc - h
        exits: list[tuple[tuple[int, int, int], tuple[int, int, int]]] = []
        for ch in chains:
            exit_a = self._chain_exit(ch, True, p, h)
            exit_b = self._chain_exit(ch, False, p, h)
            exits.append((exit_a, exit_b))
            lo, hi = max(exit_a[0], exit_b[0]), min(exit_a[1], exit_b[1])
            for c in _samples(lo, hi, exit_a[2], exit_b[2]):
                uf.union(self._exit_state(ch, 0, c, p, h), self._exit_state(ch, -1, c, p, h))
        return _Classes(self, uf, chains, exits, p, h)

    def _chain_exit(self, ch: _Chain, at_a: bool, p: int, h: int) -> tuple[int, int, int]:
        """Tracks c (agents on the A side) that can leave the chain at end A (or B):
        the range [lo, hi] and the one track whose arrival leaves no hole behind."""
        sa = ch.size_a[0 if at_a else -1]
        sb = ch.n - 1 - sa
        lo, hi = max(0, sa - h, p - 1 - sb), min(sa, p - 1)
        if at_a:  # towards A: needs a hole on the A side
            return lo, min(hi, sa - 1), sa - 1
        return max(lo, p - sb), hi, p - sb  # towards B: needs a hole on the B side

    def _exit_state(self, ch: _Chain, end: int, c: int, p: int, h: int) -> State:
        if end == 0:
            holes = ch.size_a[0] - c  # on the A side, one of them is end_a itself
            return self._arrive(ch.end_a, ch.t_a, holes - 1, h)
        sb = ch.n - 1 - ch.size_a[-1]
        holes = sb - (p - 1 - c)
        return self._arrive(ch.end_b, ch.t_b, holes - 1, h)

    def _step(self, uf: _UnionFind, src: State, a: int, i: int, k: int, h: int) -> None:
        """Join ``src`` (pebble on a, k >= 1 holes beyond neighbour i) with the state
        after it steps to that neighbour (never a corridor vertex)."""
        b = self.adj[a][i]
        uf.union(src, self._arrive(b, self.adj[b].index(a), k - 1, h))

    # ------------------------------------------------------------------ per arrangement
    def state(self, v: int, occupied: Sequence[bool], holes_sub: Sequence[int], h: int) -> State:
        """Abstract state of the pebble on ``v`` in one arrangement."""
        if self.big[self.ecc[v]]:
            return ("H", self.ecc[v])
        nb = self.adj[v]
        if len(nb) <= 1:
            return ("l", v)
        if len(nb) == 2:
            self._chains_of(self.comp[v])
            k, i = self._chain_at[v]
            x = self._chains[self.comp[v]][k]
            holes_a = self.side(v, x.toward_a[i], holes_sub, h)
            return ("t", k, x.size_a[i] - holes_a)  # track: agents on the A side
        side = [self.side(v, b, holes_sub, h) for b in nb]
        filled = [i for i, x in enumerate(side) if x > 0]
        return ("j", v, filled[0]) if len(filled) == 1 else ("j", v, "rich")

    def cycle_order(self, e: int) -> list[int]:
        """The vertices of cycle-shaped 2ECC ``e`` in cyclic order."""
        members = self.ecc_members[e]
        start = members[0]
        out = [start]
        prev, cur = -1, start
        while True:
            nxt = [w for w in self.adj[cur] if self.ecc[w] == e and w != prev]
            w = nxt[0]
            if w == start:
                return out
            out.append(w)
            prev, cur = cur, w

    def odd_cactus(self, e: int) -> bool:
        """Whether 2ECC ``e`` has only odd cycles (every block an odd cycle)."""
        import networkx as nx  # heavy module: networkx

        members = set(self.ecc_members[e])
        g = nx.Graph()
        for v in members:
            for w in self.adj[v]:
                if w in members and w not in self.bridge_nbrs(v):
                    g.add_edge(v, w)
        for block in nx.biconnected_component_edges(g):
            verts = {x for edge in block for x in edge}
            if len(block) != len(verts) or len(verts) % 2 == 0:
                return False
        return True


def _is_rotation(a: Sequence[Hashable], b: Sequence[Hashable]) -> bool:
    """Whether sequence b is a cyclic rotation of sequence a (Knuth-Morris-Pratt)."""
    if len(a) != len(b):
        return False
    if not a:
        return True
    pat = list(b)
    fail = [0] * len(pat)
    k = 0
    for i in range(1, len(pat)):
        while k and pat[i] != pat[k]:
            k = fail[k - 1]
        if pat[i] == pat[k]:
            k += 1
        fail[i] = k
    k = 0
    for x in list(a) + list(a)[:-1]:
        while k and x != pat[k]:
            k = fail[k - 1]
        if x == pat[k]:
            k += 1
            if k == len(pat):
                return True
    return False


def _parity(seq: Sequence[int]) -> int:
    """Parity of the permutation that sorts ``seq`` (distinct items)."""
    rank = {x: i for i, x in enumerate(sorted(seq))}
    perm = [rank[x] for x in seq]
    seen = [False] * len(perm)
    parity = 0
    for i in range(len(perm)):
        if not seen[i]:
            j, length = i, 0
            while not seen[j]:
                seen[j] = True
                j = perm[j]
                length += 1
            parity ^= (length - 1) & 1
    return parity


def arrangement_violation(
    graph: Graph,
    starts: Sequence[int],
    colours: Sequence[int],
    targets: Sequence[int],
    target_colours: Sequence[int],
) -> Violation | None:
    """Why no plan moves robots of ``colours`` from ``starts`` onto ``targets``, or None.

    Robot i (on ``starts[i]``) may end on any target of its colour; every target is
    taken. Labelled MAPF gives every robot its own colour. Exact on undirected graphs
    for this project's move rules (see the module docstring); the caller checks that
    every robot can reach a target of its colour in its component.

    Example
    -------
    >>> g = Graph.grid(4, 1)  # a corridor: agents keep their order
    >>> arrangement_violation(g, [0, 1], [0, 1], [3, 2], [0, 1]).kind
    'class'
    >>> arrangement_violation(g, [0, 1], [0, 1], [2, 3], [0, 1]) is None
    True
    """
    s = PebbleStructure.of(graph)
    n = graph.n
    occ_s = [False] * n
    occ_t = [False] * n
    for v in starts:
        occ_s[v] = True
    for v in targets:
        occ_t[v] = True
    holes_s = s.subtree_holes(occ_s)
    holes_t = s.subtree_holes(occ_t)
    robots_in: dict[int, list[int]] = {}
    for i, v in enumerate(starts):
        robots_in.setdefault(s.comp[v], []).append(i)
    targets_in: dict[int, list[int]] = {}
    for j, v in enumerate(targets):
        targets_in.setdefault(s.comp[v], []).append(j)
    for cid in sorted(set(robots_in) | set(targets_in)):
        robots = robots_in.get(cid, [])
        tgts = targets_in.get(cid, [])
        if len(robots) != len(tgts):
            i = (robots or tgts)[0]
            return Violation("class", starts[i] if robots else targets[i], None, i)
        h = s.comp_size[cid] - len(robots)
        if h == 0:
            why = _full_component(s, cid, starts, colours, targets, target_colours, robots, tgts)
            if why is not None:
                return why
            continue
        uf = s.abstract_classes(cid, h)
        have: dict[Hashable, Counter[int]] = {}
        first: dict[tuple[Hashable, int], int] = {}
        for i in robots:
            key = uf.of(s.state(starts[i], occ_s, holes_s, h))
            have.setdefault(key, Counter())[colours[i]] += 1
            first.setdefault((key, colours[i]), i)
        need: dict[Hashable, Counter[int]] = {}
        for j in tgts:
            key = uf.of(s.state(targets[j], occ_t, holes_t, h))
            need.setdefault(key, Counter())[target_colours[j]] += 1
        if have != need:
            for key, cnt in have.items():
                for col, c in cnt.items():
                    if need.get(key, Counter())[col] < c:
                        i = first[(key, col)]
                        goal = next(
                            (targets[j] for j in tgts if target_colours[j] == col), starts[i]
                        )
                        return Violation("class", starts[i], goal, i)
            i = robots[0]  # pragma: no cover - equal totals make some count fall short
            return Violation("class", starts[i], None, i)
        if s.is_cycle_component[cid]:
            order = s.cycle_order(s.ecc[s.comps[cid][0]])
            why = _cyclic(order, starts, colours, targets, target_colours)
            if why is not None:
                return why
    return None


def _cyclic(
    order: Sequence[int],
    starts: Sequence[int],
    colours: Sequence[int],
    targets: Sequence[int],
    target_colours: Sequence[int],
) -> Violation | None:
    at_s = {v: colours[i] for i, v in enumerate(starts)}
    at_t = {v: target_colours[j] for j, v in enumerate(targets)}
    seq_s = [at_s[v] for v in order if v in at_s]
    seq_t = [at_t[v] for v in order if v in at_t]
    if _is_rotation(seq_s, seq_t):
        return None
    return Violation("cyclic", order[0])


def _full_component(
    s: PebbleStructure,
    cid: int,
    starts: Sequence[int],
    colours: Sequence[int],
    targets: Sequence[int],
    target_colours: Sequence[int],
    robots: Sequence[int],
    tgts: Sequence[int],
) -> Violation | None:
    """No empty vertex: only rotations along cycles, inside each 2ECC."""
    at_s = {starts[i]: colours[i] for i in robots}
    at_t = {targets[j]: target_colours[j] for j in tgts}
    who = {starts[i]: i for i in robots}
    for v in s.comps[cid]:
        if not s.big[s.ecc[v]] and at_s[v] != at_t[v]:
            return Violation("fixed", v, None, who[v])
    done: set[int] = set()
    for v in s.comps[cid]:
        e = s.ecc[v]
        if not s.big[e] or e in done:
            continue
        done.add(e)
        members = s.ecc_members[e]
        have, need = Counter(at_s[x] for x in members), Counter(at_t[x] for x in members)
        if have != need:  # agents never leave a full 2ECC
            x = next(x for x in members if have[at_s[x]] > need[at_s[x]])
            return Violation("class", x, None, who[x])
        if s.ecc_is_cycle[e]:
            order = s.cycle_order(e)
            if not _is_rotation([at_s[x] for x in order], [at_t[x] for x in order]):
                return Violation("cyclic", order[0])
            continue
        seq_s = [at_s[x] for x in members]
        distinct = len(set(seq_s)) == len(seq_s)
        if distinct and s.odd_cactus(e) and _parity(seq_s) != _parity([at_t[x] for x in members]):
            return Violation("parity", members[0])
    return None


def _min_rotation(seq: Sequence[int]) -> tuple[int, ...]:
    if not seq:
        return ()
    return min(tuple(seq[i:]) + tuple(seq[:i]) for i in range(len(seq)))


def arrangement_key(graph: Graph, positions: Sequence[int]) -> tuple:
    """A key equal for two arrangements of labelled robots iff each reaches the other.

    ``positions[i]`` is robot i's vertex. Quadratic in the worst case (cyclic keys);
    meant for tests and small instances, :func:`arrangement_violation` is the fast test.

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> arrangement_key(g, [0, 2]) == arrangement_key(g, [1, 2])
    True
    >>> arrangement_key(g, [0, 2]) == arrangement_key(g, [2, 0])
    False
    """
    s = PebbleStructure.of(graph)
    occ = [False] * graph.n
    for v in positions:
        occ[v] = True
    holes = s.subtree_holes(occ)
    at = {v: i for i, v in enumerate(positions)}
    key: list[tuple] = []
    for cid, members in enumerate(s.comps):
        robots = [at[v] for v in members if v in at]
        if not robots:
            continue
        h = len(members) - len(robots)
        if h == 0:
            for v in members:
                if not s.big[s.ecc[v]]:
                    key.append(("fixed", v, at[v]))
            for e in sorted({s.ecc[v] for v in members if s.big[s.ecc[v]]}):
                mem = s.ecc_members[e]
                if s.ecc_is_cycle[e]:
                    key.append(("ring", e, _min_rotation([at[x] for x in s.cycle_order(e)])))
                else:
                    labels = [at[x] for x in mem]
                    par = _parity(labels) if s.odd_cactus(e) else None
                    key.append(("room", e, frozenset(labels), par))
            continue
        uf = s.abstract_classes(cid, h)
        for i in sorted(robots):
            key.append(("class", i, uf.of(s.state(positions[i], occ, holes, h))))
        if s.is_cycle_component[cid]:
            order = s.cycle_order(s.ecc[members[0]])
            key.append(("ring", cid, _min_rotation([at[v] for v in order if v in at])))
    return tuple(key)


#: Agents without a route clear of every endpoint up to which :func:`one_by_one` still
#: tries to move them first or last (a search each; beyond, the exact test decides).
STUCK_MAX = 4


def one_by_one(adj: Sequence[Sequence[int]], starts: Sequence[int], goals: Sequence[int]) -> bool:
    """Whether the agents can reach their goals one at a time: a cheap *sufficient* test.

    True when no agent's goal is another agent's start (starts distinct, goals distinct)
    and every moving agent has a route from its start to its goal whose inner vertices
    are nobody's start or goal (an *endpoint*): a direct edge, or two neighbours in one
    component of the graph without the endpoints. Then a plan exists: the agents move
    in turn along their routes while every other agent waits at its start or already
    stands on its goal -- all endpoints, so off the route, and the goal is free because
    it is nobody else's start or goal (the well-formed instances of Cap et al. 2015).
    O(vertices + edges): one labelling of the endpoint-free components.

    Up to :data:`STUCK_MAX` agents without such a route (an endpoint in a corridor) may
    still move *first*, one at a time, before all the others: then the ones still to
    move stand on their starts and the stuck ones moved before on their goals, so a
    route clear of the other starts and of the other stuck agents' goals does. Or
    *last*, after all the others: a route clear of the other goals and of the other
    stuck agents' starts. False says nothing (the exact test decides).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 2)
    >>> one_by_one(g.adj, [0, 2], [3, 5])  # two columns, the middle one free
    True
    >>> one_by_one(Graph.grid(4, 1).adj, [0, 1], [3, 2])  # must pass in a corridor
    False
    >>> pocket = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])  # cell 7 below
    >>> one_by_one(pocket.adj, [0, 1], [3, 7])  # agent 1 into the pocket, then agent 0 last
    True
    """
    k = len(starts)
    start_set, goal_set = set(starts), set(goals)
    if len(start_set) != k or len(goal_set) != k:
        return False
    moving = [(s, t) for s, t in zip(starts, goals, strict=True) if s != t]
    if any(s in goal_set or t in start_set for s, t in moving):
        return False
    ends = start_set | goal_set
    # The endpoint-free components next to the moving agents' starts.
    comp = _component_labels(adj, (x for s, _ in moving for x in adj[s]), ends)
    stuck: list[tuple[int, int]] = []
    for s, t in moving:
        if t in adj[s]:
            continue
        near = {comp[x] for x in adj[s] if comp[x] >= 0}
        if not any(comp[x] in near for x in adj[t]):
            stuck.append((s, t))
            if len(stuck) > STUCK_MAX:
                return False
    if not stuck:
        return True
    stuck_starts = {s for s, _ in stuck}
    stuck_goals = {t for _, t in stuck}
    first = start_set | stuck_goals
    if all(_route(adj, s, t, first) for s, t in stuck):
        return True
    last = goal_set | stuck_starts
    return all(_route(adj, s, t, last) for s, t in stuck)


def _route(adj: Sequence[Sequence[int]], s: int, t: int, blocked: set[int]) -> bool:
    """Whether a path leads from ``s`` to ``t`` whose inner vertices avoid ``blocked``
    (``s`` and ``t`` themselves may be in it).

    Example
    -------
    >>> _route([[1], [0, 2], [1]], 0, 2, {0, 2}), _route([[1], [0, 2], [1]], 0, 2, {1})
    (True, False)
    """
    seen = set(blocked)
    seen.add(s)
    stack = [s]
    while stack:
        for w in adj[stack.pop()]:
            if w == t:
                return True
            if w not in seen:
                seen.add(w)
                stack.append(w)
    return False


def _component_labels(
    adj: Sequence[Sequence[int]], roots: Iterable[int] | None = None, blocked: Iterable[int] = ()
) -> list[int]:
    """A component label per vertex of an undirected graph (scipy-free).

    With ``blocked``: of the graph without those vertices; with ``roots``: only the
    components of these vertices. Vertices left out keep the label -1.

    Example
    -------
    >>> _component_labels([[1], [0], [], [4], [3]])
    [0, 0, 1, 2, 2]
    >>> _component_labels([[1], [0, 2], [1, 3], [2]], roots=[3], blocked=[1])
    [-1, -1, 0, 0]
    """
    n = len(adj)
    labels = [-1] * n
    out = list(blocked)
    for v in out:
        labels[v] = n  # not a component label: never entered, reset below
    c = 0
    for s in range(n) if roots is None else roots:
        if labels[s] >= 0:
            continue
        labels[s] = c
        stack = [s]
        while stack:
            v = stack.pop()
            for w in adj[v]:
                if labels[w] < 0:
                    labels[w] = c
                    stack.append(w)
        c += 1
    for v in out:
        labels[v] = -1
    return labels


def _dfs_order(adj: Sequence[Sequence[int]], root: int):
    """Depth-first preorder from ``root`` and the predecessor array (-9999 off the tree),
    as ``scipy.sparse.csgraph.depth_first_order`` returns them (scipy-free).

    Example
    -------
    >>> order, pred = _dfs_order([[1, 2], [0, 2], [0, 1], []], 0)
    >>> order.tolist(), pred.tolist()
    ([0, 1, 2], [-9999, 0, 1, -9999])
    """
    pred = [-9999] * len(adj)
    seen = [False] * len(adj)
    seen[root] = True
    order = [root]
    stack = [(root, iter(adj[root]))]
    while stack:
        v, it = stack[-1]
        for w in it:
            if not seen[w]:
                seen[w] = True
                pred[w] = v
                order.append(w)
                stack.append((w, iter(adj[w])))
                break
        else:
            stack.pop()
    return np.array(order, dtype=np.int64), np.array(pred, dtype=np.int64)
