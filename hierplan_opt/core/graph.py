"""Graphs the robots move on: 2D grids, 3D grids and general roadmaps.

Every graph stores its adjacency in CSR form (``indptr``, ``indices``, ``lengths``)
with integer vertex ids. On grids the vertex id *is* the cell index
``x + W * (y + H * z)``, blocked cells included (they have no edges and
``passable[v]`` is False), so coordinates convert to ids by arithmetic and the
validator can name a blocked cell that a plan steps on.

Distances used by the solvers are *timestep* distances (unit edges, BFS); the
geometric edge lengths matter only to scheduling (MAPF-POST).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp

    from hierplan_opt.core.timer import Deadline

from hierplan_opt.core.errors import InputError

#: Timestep distance of a vertex that cannot reach the target. Large, so that any
#: sum of a few of them still fits in a Python int comparison without special cases.
UNREACHABLE = 1 << 30
#: Free vertices times targets up to which a distance batch is made without scipy while
#: scipy is not loaded: importing ``scipy.sparse.csgraph`` costs 0.15-0.5 s of a fresh
#: process; without it a table costs about 90 ns a free vertex (Python BFS) or 35-65 ns
#: (numpy, :func:`_bfs_many`) against scipy's 25 ns. Measured per process on
#: ``warehouse-10-20-10-2-1`` k100 (570k): 0.84 s of CPU for the solve against 1.01 s
#: with the import; up to 2M the import does not pay (the Python BFS of a maze-like map,
#: about 0.2 s at 2M, is checked against the deadline every few tables).
SMALL_BFS_WORK = 2_000_000
#: The numpy BFS of many targets at once (:func:`_bfs_many`) pays about 10 us per level
#: (its array calls) where the Python BFS pays about 90 ns per free vertex and table,
#: itself about 35 ns: so it runs when the tables still to make times the free vertices
#: reach this many times the levels (the first table's, made by the Python BFS). Measured
#: on the reference maps: 0.5-0.8x the Python BFS's time from about 150 on (warehouse
#: k10 4.3 ms against 5.8 ms, random-32-32-10 k50 2.2 against 4.3), 1.1-2.2x below 100
#: (maze-32-32-2 k5-k20, whose corridors make 140 levels).
MANY_BFS_RATIO = 150
#: Most neighbours a vertex may have for :func:`_bfs_many` (its table is vertices times
#: this): grids have 4 or 6.
MANY_BFS_DEGREE = 8
#: Vertices up to which a table is a Python BFS also when scipy is loaded (9 us a table
#: on 64 cells against 21 us for a scipy breadth-first order; even at about 180 cells).
SMALL_BFS_CELLS = 128
#: Vertices up to which the tables come from one scipy call per batch (beats a
#: breadth-first order per table there: 12 us against 27 us a table on 256 cells).
DIST_BATCH_CELLS = 512
#: Vertices times targets per scipy batch of :meth:`Graph.fill_distances`: a few
#: hundredths of a second between deadline checks, and a bounded temporary matrix.
DIST_BATCH_WORK = 1 << 19

#: Maps whose ``Graph.adj`` is kept for graphs with the same edges (see there): a
#: warm process (a notebook, ``hierplan bench cbs --reference``) that reads a map again
#: per run then sets up the search's per-map arrays once per map (a C++ solver's map
#: loading is not part of its runtime either).
SHARED_ADJ_GRAPHS = 4
_SHARED_ADJ: dict[tuple[int, int, int], tuple[np.ndarray, np.ndarray, list[list[int]]]] = {}


def keep_per_map(cache: dict[Any, Any], key: Any, value: Any) -> None:
    """``cache[key] = value``, dropping the oldest entry when ``cache`` holds
    :data:`SHARED_ADJ_GRAPHS` already (the caches kept per map, as ``Graph.adj``'s)."""
    if len(cache) >= SHARED_ADJ_GRAPHS:
        del cache[next(iter(cache))]
    cache[key] = value


#: A compiled breadth-first search of many targets, ``fn(indptr, indices, targets,
#: unreachable)`` -> one row of hop distances per target, for undirected graphs: set by
#: :mod:`hierplan_opt.search.jit` when it loads its kernels (the search layer may import
#: this one, not the other way), so that a warm process makes its distance tables at
#: compiled speed; None (a fresh process, no numba) keeps the tables below.
_compiled_bfs: Callable[[np.ndarray, np.ndarray, np.ndarray, int], np.ndarray] | None = None


def set_compiled_bfs(
    fn: Callable[[np.ndarray, np.ndarray, np.ndarray, int], np.ndarray] | None,
) -> None:
    """Make :meth:`Graph.fill_distances` use ``fn`` (see :data:`_compiled_bfs`; None: not)."""
    global _compiled_bfs
    _compiled_bfs = fn


Location = tuple[int, ...] | str


class Graph:
    """An immutable graph with integer vertex ids, coordinates and cached distances.

    Build one with :meth:`grid`, :meth:`roadmap` or :meth:`from_networkx`.

    Example
    -------
    >>> g = Graph.grid(3, 2, obstacles=[(1, 1)])
    >>> g.vertex((2, 1)), g.location(5), bool(g.passable[4])
    (5, (2, 1), False)
    >>> sorted(g.location(u) for u in g.neighbors(g.vertex((1, 0))))
    [(0, 0), (2, 0)]
    >>> int(g.dist_to(g.vertex((0, 1)))[g.vertex((2, 1))])
    4
    """

    def __init__(
        self,
        *,
        kind: str,
        coords: np.ndarray,
        passable: np.ndarray,
        indptr: np.ndarray,
        indices: np.ndarray,
        lengths: np.ndarray,
        directed: bool = False,
        shape: tuple[int, ...] | None = None,
        names: Sequence[str] | None = None,
        cell_size: float = 1.0,
    ) -> None:
        self.kind = kind
        self.coords = np.asarray(coords, dtype=float)
        self.passable = np.asarray(passable, dtype=bool)
        self.indptr = np.asarray(indptr, dtype=np.int64)
        self.indices = np.asarray(indices, dtype=np.int64)
        self.lengths = np.asarray(lengths, dtype=float)
        self.directed = directed
        self.shape = shape
        self.names = tuple(names) if names is not None else None
        self.cell_size = float(cell_size)
        for arr in (self.coords, self.passable, self.indptr, self.indices, self.lengths):
            arr.setflags(write=False)
        self._name_to_id = (
            {name: i for i, name in enumerate(self.names)} if self.names is not None else None
        )
        self._dist_cache: dict[int, np.ndarray] = {}
        self._dist_list_cache: dict[int, list[int]] = {}
        self._dist_from_cache: dict[int, np.ndarray] = {}
        self._axis_edges = False  # known to join axis neighbours only (set by :meth:`grid`)

    # ------------------------------------------------------------------ builders
    @classmethod
    def grid(
        cls,
        width: int,
        height: int,
        depth: int | None = None,
        *,
        obstacles: Iterable[Sequence[int]] = (),
        blocked: np.ndarray | None = None,
        cell_size: float = 1.0,
    ) -> Graph:
        """A 4-connected 2D grid (``depth=None``) or a 6-connected 3D grid.

        ``blocked`` is a boolean array indexed ``[y, x]`` (2D) or ``[z, y, x]`` (3D);
        ``obstacles`` lists blocked cells as ``(x, y[, z])``.

        Example
        -------
        >>> Graph.grid(2, 2, 2).num_edges
        12
        """
        dims = (width, height) if depth is None else (width, height, depth)
        for d in dims:
            if not isinstance(cast(object, d), (int, np.integer)) or d <= 0:
                raise InputError(f"grid dimensions must be positive integers, got {list(dims)}")
        if not math.isfinite(cell_size) or cell_size <= 0:
            raise InputError(f"cell_size must be a positive number, got {cell_size!r}")
        n = int(np.prod(dims))
        free = np.ones(n, dtype=bool)
        if blocked is not None:
            b = np.asarray(blocked, dtype=bool)
            if b.shape != tuple(reversed(dims)):
                raise InputError(
                    f"blocked array has shape {b.shape}, expected {tuple(reversed(dims))}"
                )
            free &= ~b.reshape(-1)
        for cell in obstacles:
            c = tuple(int(x) for x in cell)
            if len(c) != len(dims) or any(not 0 <= c[i] < dims[i] for i in range(len(dims))):
                size = "x".join(map(str, dims))
                raise InputError(f"obstacle {list(c)} is outside the {size} grid")
            free[_cell_index(c, dims)] = False

        # Coordinates of every cell (x fastest).
        grids = np.meshgrid(*[np.arange(d) for d in reversed(dims)], indexing="ij")
        coords = np.stack([g.reshape(-1) for g in reversed(grids)], axis=1)

        # Edges between free neighbours along every axis, both directions.
        src: list[np.ndarray] = []
        dst: list[np.ndarray] = []
        stride = 1
        ids = np.arange(n)
        for axis, d in enumerate(dims):
            has_next = coords[:, axis] < d - 1
            a = ids[has_next]
            b = a + stride
            ok = free[a] & free[b]
            src += [a[ok], b[ok]]
            dst += [b[ok], a[ok]]
            stride *= d
        s = np.concatenate(src) if src else np.zeros(0, dtype=np.int64)
        t = np.concatenate(dst) if dst else np.zeros(0, dtype=np.int64)
        indptr, indices = _csr(n, s, t)
        lengths = np.full(len(indices), float(cell_size))
        g = cls(
            kind="grid",
            coords=coords,
            passable=free,
            indptr=indptr,
            indices=indices,
            lengths=lengths,
            directed=False,
            shape=tuple(int(d) for d in dims),
            cell_size=cell_size,
        )
        g._axis_edges = True  # every edge joins axis neighbours: no need to check (grid_xy)
        return g

    @classmethod
    def roadmap(
        cls,
        vertices: Mapping[str, Sequence[float]],
        edges: Iterable[Sequence[Any]],
        *,
        directed: bool = False,
    ) -> Graph:
        """A general graph: named vertices with coordinates, edges ``(u, v[, length])``.

        Edge length defaults to the Euclidean distance between the coordinates.

        Example
        -------
        >>> g = Graph.roadmap({"A": (0, 0), "B": (3, 4)}, [("A", "B")])
        >>> g.edge_length(g.vertex("A"), g.vertex("B"))
        5.0
        """
        names = [str(k) for k in vertices]
        if not names:
            raise InputError("a roadmap needs at least one vertex")
        dims = {len(c) for c in vertices.values()}
        if len(dims) != 1 or dims.pop() not in (2, 3):
            raise InputError("roadmap vertex coordinates must all have 2 or all have 3 numbers")
        coords = np.array([[float(x) for x in vertices[k]] for k in vertices], dtype=float)
        if not np.all(np.isfinite(coords)):
            bad = names[int(np.argwhere(~np.isfinite(coords))[0][0])]
            raise InputError(f"roadmap vertex {bad!r} has a coordinate that is not finite")
        index = {name: i for i, name in enumerate(names)}
        src: list[int] = []
        dst: list[int] = []
        lens: list[float] = []
        seen: set[tuple[int, int]] = set()
        for e in edges:
            if len(e) not in (2, 3):
                raise InputError(f"roadmap edge {list(e)} must be [u, v] or [u, v, length]")
            u, v = str(e[0]), str(e[1])
            for x in (u, v):
                if x not in index:
                    raise InputError(f"roadmap edge {[u, v]} names unknown vertex {x!r}")
            if u == v:
                raise InputError(f"roadmap edge {[u, v]} is a self-loop; waiting is implicit")
            a, b = index[u], index[v]
            if len(e) == 3:
                length = e[2]
                if not isinstance(length, (int, float)) or not math.isfinite(length) or length <= 0:
                    raise InputError(f"roadmap edge {[u, v]} has bad length {length!r}")
                length = float(length)
            else:
                # math.dist scales like hypot: no overflow (nor numpy warning) on 1e308
                length = math.dist(coords[a].tolist(), coords[b].tolist())
                if length <= 0:
                    raise InputError(f"roadmap edge {[u, v]} joins two vertices at one position")
                if not math.isfinite(length):
                    raise InputError(
                        f"roadmap edge {[u, v]} is longer than the largest float; "
                        "scale the coordinates down"
                    )
            pairs = [(a, b)] if directed else [(a, b), (b, a)]
            for p, q in pairs:
                if (p, q) in seen:
                    raise InputError(f"roadmap edge {[names[p], names[q]]} is listed twice")
                seen.add((p, q))
                src.append(p)
                dst.append(q)
                lens.append(length)
        n = len(names)
        order = np.lexsort((np.array(dst, dtype=np.int64), np.array(src, dtype=np.int64)))
        s = np.array(src, dtype=np.int64)[order]
        t = np.array(dst, dtype=np.int64)[order]
        lengths = np.array(lens, dtype=float)[order]
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.add.at(indptr, s + 1, 1)
        indptr = np.cumsum(indptr)
        return cls(
            kind="roadmap",
            coords=coords,
            passable=np.ones(n, dtype=bool),
            indptr=indptr,
            indices=t,
            lengths=lengths,
            directed=directed,
            names=names,
        )

    @classmethod
    def from_networkx(cls, g: Any, *, pos: str = "pos", length: str = "length") -> Graph:
        """A roadmap from a ``networkx`` (Di)Graph.

        A node's coordinates are its ``pos`` attribute or, without one, the node itself
        when it is a tuple of 2 or 3 numbers (``nx.grid_2d_graph``'s ``(i, j)``); the
        vertex is named ``str(node)``, so ``vertex((i, j))`` finds it. Edge lengths come
        from the ``length`` attribute, else the Euclidean distance.

        Example
        -------
        >>> import networkx as nx
        >>> G = nx.path_graph(3)
        >>> nx.set_node_attributes(G, {0: (0, 0), 1: (1, 0), 2: (2, 0)}, "pos")
        >>> Graph.from_networkx(G).num_edges
        2
        >>> grid = Graph.from_networkx(nx.grid_2d_graph(6, 6))
        >>> grid.num_vertices, grid.num_edges, grid.dist(grid.vertex((0, 0)), grid.vertex((5, 5)))
        (36, 60, 10)
        """
        vertices: dict[str, Sequence[float]] = {}
        for node, data in g.nodes(data=True):
            if pos in data:
                vertices[str(node)] = data[pos]
            elif _is_point(node):
                vertices[str(node)] = node
            else:
                raise InputError(
                    f"networkx node {node!r} has no {pos!r} attribute and is not a tuple of "
                    "2 or 3 coordinates"
                )
        edges: list[tuple[str, ...] | tuple[str, str, float]] = []
        for u, v, data in g.edges(data=True):
            edges.append((str(u), str(v), data[length]) if length in data else (str(u), str(v)))
        return cls.roadmap(vertices, edges, directed=bool(g.is_directed()))

    # ------------------------------------------------------------------ queries
    @property
    def n(self) -> int:
        """Number of vertex ids (on grids: cells, blocked ones included)."""
        return len(self.passable)

    @property
    def dim(self) -> int:
        """2 or 3: the number of coordinates of a vertex."""
        return int(self.coords.shape[1])

    @cached_property
    def num_vertices(self) -> int:
        """Number of passable vertices."""
        return int(self.passable.sum())

    @cached_property
    def num_edges(self) -> int:
        """Number of edges (undirected edges counted once)."""
        m = len(self.indices)
        return m if self.directed else m // 2

    @cached_property
    def adj(self) -> list[list[int]]:
        """Neighbour lists as plain Python ints (fastest for pure-Python search loops).

        Read-only: vertices without neighbours (blocked cells) share one empty list, as
        making a list per cell is most of the cost on maps with many blocked cells; and
        graphs with the same edges (the same map read again) share one ``adj`` (the
        last :data:`SHARED_ADJ_GRAPHS` of them), so that what the search keeps per
        ``adj`` (successor lists, the compiled kernel's arrays and buffers) is made once
        per map and process. Distance tables stay per graph.

        Example
        -------
        >>> Graph.grid(3, 2).adj is Graph.grid(3, 2).adj
        True
        """
        key = (self.indptr.shape[0], hash(self.indptr.tobytes()), hash(self.indices.tobytes()))
        hit = _SHARED_ADJ.get(key)
        if (
            hit is not None
            and np.array_equal(hit[0], self.indptr)
            and np.array_equal(hit[1], self.indices)
        ):
            return hit[2]
        ip = self.indptr.tolist()
        ind = self.indices.tolist()
        none: list[int] = []
        adj = [ind[a:b] if a != b else none for a, b in zip(ip[:-1], ip[1:], strict=True)]
        keep_per_map(_SHARED_ADJ, key, (self.indptr, self.indices, adj))
        return adj

    @cached_property
    def grid_xy(self) -> tuple[int, list[int], list[int]] | None:
        """``(W, xs, ys)`` on a 4-connected 2D grid (one layer of a 3D one), else None.

        ``xs[v]``, ``ys[v]`` are the cell coordinates of id ``v = x + W * y``. None unless
        every edge joins cells one unit apart in x or y (always so for :meth:`grid`; a
        grid built by hand is checked).

        Example
        -------
        >>> w, xs, ys = Graph.grid(3, 2).grid_xy
        >>> w, xs, ys
        (3, [0, 1, 2, 0, 1, 2], [0, 0, 0, 1, 1, 1])
        >>> Graph.grid(2, 2, 2).grid_xy is None
        True
        """
        shape = self.shape
        if self.kind != "grid" or shape is None or not 2 <= len(shape) <= 3:
            return None
        if len(shape) == 3 and shape[2] != 1:
            return None
        w, h = shape[0], shape[1]
        if not self._axis_edges:
            cx = self.coords[:, 0].astype(np.int64)
            cy = self.coords[:, 1].astype(np.int64)
            if not np.array_equal(cx + w * cy, np.arange(self.n)):
                return None
            src = np.repeat(np.arange(self.n), np.diff(self.indptr))
            dst = self.indices
            if np.any(np.abs(cx[dst] - cx[src]) + np.abs(cy[dst] - cy[src]) != 1):
                return None
        return w, list(range(w)) * h, np.repeat(np.arange(h), w).tolist()

    @cached_property
    def _edge_len(self) -> dict[tuple[int, int], float]:
        out: dict[tuple[int, int], float] = {}
        ind = self.indices.tolist()
        lens = self.lengths.tolist()
        for u, nbrs in enumerate(self.adj):
            start = int(self.indptr[u])
            for k in range(len(nbrs)):
                out[(u, ind[start + k])] = lens[start + k]
        return out

    @cached_property
    def reverse_adj(self) -> list[list[int]]:
        """Predecessor lists (equal to :attr:`adj` on undirected graphs)."""
        if not self.directed:
            return self.adj
        rev: list[list[int]] = [[] for _ in range(self.n)]
        for u, nbrs in enumerate(self.adj):
            for v in nbrs:
                rev[v].append(u)
        return rev

    def neighbors(self, v: int) -> np.ndarray:
        """Successors of ``v`` (not including ``v`` itself)."""
        return self.indices[self.indptr[v] : self.indptr[v + 1]]

    def has_edge(self, u: int, v: int) -> bool:
        """Whether a robot may move from ``u`` to ``v`` in one timestep.

        A look-up in ``u``'s successor list: the validator asks this for every move of
        a plan, and the table of every edge's length would cost a short solve more than
        its validation (6 ms on the 10k cells of ``warehouse-10-20-10-2-1``).

        Example
        -------
        >>> g = Graph.grid(3, 1)
        >>> g.has_edge(0, 1), g.has_edge(0, 2), g.has_edge(0, 7), g.has_edge(-1, 0)
        (True, False, False, False)
        """
        adj = self.adj
        return 0 <= u < len(adj) and v in adj[u]

    def edge_length(self, u: int, v: int) -> float:
        """Geometric length of edge ``(u, v)``; 0.0 for a wait (``u == v``)."""
        if u == v:
            return 0.0
        try:
            return self._edge_len[(u, v)]
        except KeyError:
            raise InputError(f"{self.location(u)} -> {self.location(v)} is not an edge") from None

    def edges(self) -> Iterable[tuple[int, int]]:
        """Every directed arc ``(u, v)`` (both directions for undirected graphs)."""
        return iter(self._edge_len)

    def is_vertex(self, v: int) -> bool:
        """Whether ``v`` is a valid id of a passable vertex."""
        return 0 <= v < self.n and bool(self.passable[v])

    def vertex(self, loc: Location | Sequence[int]) -> int:
        """The id of a location: ``(x, y[, z])`` on grids, a vertex name on roadmaps.

        Raises :class:`InputError` for a location outside the map (a blocked cell
        still has an id; check :attr:`passable`).
        """
        if self.kind == "roadmap":
            assert self._name_to_id is not None
            key = str(loc)
            if key not in self._name_to_id:
                raise InputError(f"unknown vertex {loc!r}")
            return self._name_to_id[key]
        assert self.shape is not None
        if isinstance(loc, str) or not hasattr(loc, "__len__") or len(loc) != len(self.shape):
            raise InputError(f"location {loc!r} must have {len(self.shape)} integer coordinates")
        c: list[int] = []
        for x in cast(Sequence[object], loc):
            if isinstance(x, bool) or not isinstance(x, _NUMBER) or x != int(cast(float, x)):
                raise InputError(f"location {list(loc)} has a non-integer coordinate")
            c.append(int(cast(float, x)))
        if any(not 0 <= c[i] < self.shape[i] for i in range(len(c))):
            raise InputError(f"location {c} is outside the {'x'.join(map(str, self.shape))} map")
        return _cell_index(tuple(c), self.shape)

    def location(self, v: int) -> Location:
        """Inverse of :meth:`vertex`: grid coordinates as a tuple, or the vertex name."""
        if self.names is not None:
            return self.names[v]
        return tuple(int(x) for x in self.coords[v])

    def label(self, v: int, quote: Callable[[str], str] = repr) -> str:
        """``v`` as people read it: ``[x, y]`` (``[x, y, z]``), the quoted vertex name, or
        ``vertex id v`` for an id outside the graph. The one formatter of locations.

        Example
        -------
        >>> g = Graph.grid(3, 2)
        >>> g.label(4), g.label(99)
        ('[1, 1]', 'vertex id 99')
        """
        if not 0 <= v < self.n:
            return f"vertex id {v}"
        loc = self.location(v)
        return quote(loc) if isinstance(loc, str) else str(list(loc))

    def plain_location(self, v: int) -> list[int] | str:
        """:meth:`location` as plain data (a list, or the name) for files and statistics."""
        loc = self.location(v)
        return loc if isinstance(loc, str) else list(loc)

    @property
    def scale(self) -> float:
        """Metres per coordinate unit: :attr:`cell_size` on grids, 1 on roadmaps."""
        return self.cell_size if self.kind == "grid" else 1.0

    def position(self, v: int) -> np.ndarray:
        """Geometric position of ``v`` (grid cells scaled by :attr:`cell_size`)."""
        return self.coords[v] * self.scale

    # ------------------------------------------------------------------ distances
    def dist_to(self, target: int) -> np.ndarray:
        """Timestep distance from every vertex to ``target`` (cached, read-only).

        Unreachable vertices get :data:`UNREACHABLE`.
        """
        d = self._dist_cache.get(target)
        if d is None:
            lst = self._dist_list_cache.get(target)
            if lst is None:
                self.fill_distances([target])
                d = self._dist_cache.get(target)
                lst = self._dist_list_cache.get(target)
            if d is None:  # a table made by the Python BFS: its array on first request
                d = np.array(lst, dtype=np.int64)
                d.setflags(write=False)
                self._dist_cache[target] = d
        return d

    def dist_from(self, source: int) -> np.ndarray:
        """Timestep distance from ``source`` to every vertex (cached; :meth:`dist_to` on
        undirected graphs).

        Example
        -------
        >>> g = Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B")], directed=True)
        >>> a = g.vertex("A")
        >>> g.dist_from(a).tolist()[1], g.dist_to(a).tolist()[1] == UNREACHABLE
        (1, True)
        """
        if not self.directed:
            return self.dist_to(source)
        d = self._dist_from_cache.get(source)
        if d is None:
            d = _bfs_levels(self._csgraph, source)
            d.setflags(write=False)
            self._dist_from_cache[source] = d
        return d

    def dist_list(self, target: int) -> list[int]:
        """:meth:`dist_to` as a plain list (fast lookups in Python loops)."""
        d = self._dist_list_cache.get(target)
        if d is None:
            d = self.dist_to(target).tolist()
            self._dist_list_cache[target] = d
        return d

    def dist(self, source: int, target: int) -> int:
        """Timestep distance from ``source`` to ``target`` (:data:`UNREACHABLE` if none)."""
        return int(self.dist_to(target)[source])

    def precompute_distances(self, targets: Iterable[int]) -> list[np.ndarray]:
        """Fill the distance cache for many targets in C-level BFS batches.

        A small batch on an undirected graph is a pure-Python BFS while scipy is not
        loaded yet (importing it costs more than the BFS; the distances are the same).

        Example
        -------
        >>> g = Graph.grid(3, 2, obstacles=[(1, 0)])
        >>> d = g.precompute_distances([g.vertex((0, 0))])[0].tolist()
        >>> d[g.vertex((2, 0))], d[1] == UNREACHABLE  # around the blocked cell 1
        (4, True)
        """
        targets = list(targets)
        self.fill_distances(targets)
        return [self.dist_to(t) for t in targets]

    def fill_distances(self, targets: Iterable[int], deadline: Deadline | None = None) -> bool:
        """Fill the distance cache for ``targets``, checking ``deadline`` between batches.

        Returns False when the deadline passed before every table was made (the ones
        made stay cached); a batch takes a few hundredths of a second.

        Example
        -------
        >>> from hierplan_opt.core.timer import Deadline
        >>> g = Graph.grid(4, 4)
        >>> g.fill_distances(range(16), Deadline(0)), g.fill_distances(range(16))
        (False, True)
        """
        cached, lists = self._dist_cache, self._dist_list_cache
        todo = [t for t in dict.fromkeys(targets) if t not in cached and t not in lists]
        if not todo:
            return True
        if deadline is not None and deadline.expired():
            return False
        if self._open_grid:
            # Every cell free and joined to its axis neighbours: the distance is the
            # Manhattan distance of the cells (a BFS gives the same, slower).
            c = self._cells

            def manhattan(batch: list[int]) -> np.ndarray:
                arr = np.abs(c[0][None, :] - c[0][batch][:, None])
                for ax in c[1:]:
                    arr += np.abs(ax[None, :] - ax[batch][:, None])
                return arr

            return self._fill_batches(todo, 1, manhattan, deadline)
        bfs_fn = _compiled_bfs
        if bfs_fn is not None and not self.directed:
            ip, ind = self.indptr, self.indices

            def compiled(batch: list[int]) -> np.ndarray:
                return bfs_fn(ip, ind, np.asarray(batch, dtype=np.int64), UNREACHABLE)

            return self._fill_batches(todo, 1, compiled, deadline)
        if self._small_bfs(len(todo)):
            # Plain lists, what the search loops read; the array is made on request. The
            # first table's levels tell whether numpy's BFS of the others at once is faster.
            lists[todo[0]], levels = _bfs_depth(self.adj, todo[0])
            rest = todo[1:]
            if rest and len(rest) * self.num_vertices >= MANY_BFS_RATIO * max(levels, 1):
                nbr = self._neighbour_table
                if nbr is not None:
                    return self._fill_batches(rest, 1, lambda b: _bfs_many(nbr, b), deadline)
            for k, t in enumerate(rest, 1):
                if k % 16 == 0 and deadline is not None and deadline.expired():
                    return False
                lists[t] = _bfs(self.adj, t)
            return True
        # Distances *to* a target are distances *from* it on the reversed graph.
        mat = self._csgraph_reversed if self.directed else self._csgraph
        if self.n <= DIST_BATCH_CELLS:
            # One C call per batch: on small graphs scipy's per-call overhead dominates
            # a table, and a batch pays it once.
            from scipy.sparse.csgraph import shortest_path

            def bfs(batch: list[int]) -> np.ndarray:
                d = shortest_path(mat, method="D", directed=True, unweighted=True, indices=batch)
                d[np.isinf(d)] = UNREACHABLE
                return d.astype(np.int64)

            return self._fill_batches(todo, 8, bfs, deadline)
        step = max(8, DIST_BATCH_WORK // max(1, self.n))
        for k, t in enumerate(todo):
            if k and k % step == 0 and deadline is not None and deadline.expired():
                return False
            arr = _bfs_levels(mat, t)
            arr.setflags(write=False)
            cached[t] = arr
        return True

    def _fill_batches(
        self,
        todo: list[int],
        least: int,
        rows: Callable[[list[int]], np.ndarray],
        deadline: Deadline | None,
    ) -> bool:
        """Cache ``rows(batch)`` (one table per target of ``batch``, as arrays and lists)
        for ``todo`` in batches of ``DIST_BATCH_WORK`` cells (at least ``least`` targets),
        checking ``deadline`` between batches; False if it expired."""
        step = max(least, DIST_BATCH_WORK // max(1, self.n))
        for k in range(0, len(todo), step):
            if k and deadline is not None and deadline.expired():
                return False
            batch = todo[k : k + step]
            arr = rows(batch)
            arr.setflags(write=False)
            for t, row, lst in zip(batch, arr, arr.tolist(), strict=True):
                self._dist_cache[t] = row
                self._dist_list_cache[t] = lst
        return True

    @cached_property
    def _open_grid(self) -> bool:
        """Whether this is a :meth:`grid` without blocked cells (distances are Manhattan)."""
        return self._axis_edges and bool(self.passable.all())

    @cached_property
    def _cells(self) -> list[np.ndarray]:
        """The integer grid coordinates, one array per axis."""
        return [np.ascontiguousarray(self.coords[:, i], dtype=np.int64) for i in range(self.dim)]

    @cached_property
    def _neighbour_table(self) -> np.ndarray | None:
        """The neighbours as a ``(n + 1, degree)`` table for :func:`_bfs_many`: row ``v``
        lists ``v``'s neighbours, then the sentinel id ``n`` (row ``n``: only ``n``);
        None on directed graphs and where a vertex has more than ``MANY_BFS_DEGREE``."""
        if self.directed or self.n == 0:
            return None
        deg = np.diff(self.indptr)
        width = int(deg.max()) if len(deg) else 0
        if not 0 < width <= MANY_BFS_DEGREE:
            return None
        table = np.full((self.n + 1, width), self.n, dtype=np.int64)
        rows = np.repeat(np.arange(self.n), deg)
        table[rows, np.arange(len(self.indices)) - self.indptr[rows]] = self.indices
        return table

    def _small_bfs(self, count: int) -> bool:
        """Whether ``count`` tables without scipy (Python and numpy BFS) beat scipy (its
        import, if not loaded yet)."""
        if self.directed:
            return False
        if "scipy.sparse.csgraph" not in sys.modules:
            return self.num_vertices * count <= SMALL_BFS_WORK
        return self.n <= SMALL_BFS_CELLS

    @cached_property
    def _csgraph(self) -> sp.csr_matrix:
        import scipy.sparse as sp  # heavy module: scipy

        data = np.ones(len(self.indices), dtype=float)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))

    @cached_property
    def _csgraph_reversed(self) -> sp.csr_matrix:
        return self._csgraph.T.tocsr()

    def __repr__(self) -> str:
        if self.kind == "grid":
            size = "x".join(map(str, self.shape or ()))
            return f"Graph(grid {size}, {self.num_vertices} free cells)"
        return f"Graph(roadmap, {self.n} vertices, {self.num_edges} edges)"


#: Types accepted as grid coordinates (whole numbers only).
_NUMBER: tuple[type, ...] = (int, np.integer, float)


def _bfs(adj: Sequence[Sequence[int]], target: int) -> list[int]:
    """Hop distances to ``target`` on an undirected graph (:data:`UNREACHABLE` if none)."""
    return _bfs_depth(adj, target)[0]


def _bfs_depth(adj: Sequence[Sequence[int]], target: int) -> tuple[list[int], int]:
    """:func:`_bfs` and the largest finite distance in its table."""
    dist = [UNREACHABLE] * len(adj)
    dist[target] = 0
    frontier = [target]
    d = 0
    while frontier:
        d += 1
        nxt: list[int] = []
        for v in frontier:
            for u in adj[v]:
                if dist[u] == UNREACHABLE:
                    dist[u] = d
                    nxt.append(u)
        frontier = nxt
    return dist, d - 1


def _bfs_many(nbr: np.ndarray, targets: list[int]) -> np.ndarray:
    """Hop distances to each of ``targets`` (one row each) on an undirected graph, all
    searched at once, level by level, in numpy (:data:`UNREACHABLE` if none): the same
    tables as :func:`_bfs`.

    ``nbr`` is :attr:`Graph._neighbour_table` (neighbours padded with the sentinel id
    ``n``). The states are ``(row, vertex)`` pairs, flat ``row * (n + 1) + vertex``; a
    level is the unvisited neighbours of the last one, each state kept once.

    Example
    -------
    >>> g = Graph.grid(3, 2, obstacles=[(1, 0)])
    >>> _bfs_many(g._neighbour_table, [0, 5]).tolist() == [_bfs(g.adj, 0), _bfs(g.adj, 5)]
    True
    """
    stride = nbr.shape[0]  # n + 1
    n = stride - 1
    k = len(targets)
    dist = np.full(k * stride, UNREACHABLE, dtype=np.int64)
    dist[n::stride] = -1  # the sentinel: never a new state
    bases = np.arange(k, dtype=np.int64) * stride
    frontier = bases + np.asarray(targets, dtype=np.int64)
    dist[frontier] = 0
    slot = np.empty(k * stride, dtype=np.int64)  # a state's place among a level's candidates
    level = 0
    while frontier.size:
        level += 1
        row, v = np.divmod(frontier, stride)
        cand = (nbr[v] + (row * stride)[:, None]).ravel()
        cand = cand[dist[cand] == UNREACHABLE]
        at = np.arange(len(cand), dtype=np.int64)
        slot[cand] = at  # a repeated state keeps its last place: only that copy stays
        cand = cand[slot[cand] == at]
        dist[cand] = level
        frontier = cand
    return dist.reshape(k, stride)[:, :n]


def _bfs_levels(mat: sp.csr_matrix, source: int) -> np.ndarray:
    """Hop distances from ``source`` along the edges of ``mat`` (:data:`UNREACHABLE` if none).

    One C-level breadth-first order (scipy), then the levels from the predecessors: in
    that order every vertex comes after its BFS parent and the parents' positions never
    decrease, so level ``L + 1`` ends where the vertices whose parent lies before the end
    of level ``L`` end (a prefix count of the parents' positions). Two to three times
    faster than scipy's ``shortest_path(unweighted=True)`` (a Dijkstra): 0.14 ms against 0.41 ms a
    table on the 10k cells of ``warehouse-10-20-10-2-1``, 0.08 against 0.17 on ``den312d``.

    Example
    -------
    >>> g = Graph.grid(3, 2, obstacles=[(1, 0)])
    >>> _bfs_levels(g._csgraph, 0).tolist()[2:]
    [4, 1, 2, 3]
    """
    from scipy.sparse.csgraph import breadth_first_order  # heavy module: scipy

    n = mat.shape[0]
    order, pred = breadth_first_order(mat, source, directed=True, return_predecessors=True)
    m = order.shape[0]
    pos = np.empty(n, np.int64)
    pos[order] = np.arange(m)
    # ends[x]: 1 + how many non-root vertices have their parent among the first x.
    ends = np.zeros(m + 1, np.int64)
    np.cumsum(np.bincount(pos[pred[order[1:]]], minlength=m), out=ends[1:])
    ends += 1
    bounds = [0, 1]
    x = 1
    while x < m:
        x = int(ends[x])
        bounds.append(x)
    out = np.full(n, UNREACHABLE, np.int64)
    out[order] = np.repeat(np.arange(len(bounds) - 1), np.diff(bounds))
    return out


def _cell_index(c: tuple[int, ...], dims: Sequence[int]) -> int:
    idx = 0
    stride = 1
    for i, x in enumerate(c):
        idx += x * stride
        stride *= dims[i]
    return idx


def _csr(n: int, src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.lexsort((dst, src))
    src = src[order]
    dst = dst[order]
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, src + 1, 1)
    return np.cumsum(indptr), dst


def _is_point(node: object) -> bool:
    """Whether a networkx node is itself a coordinate tuple: 2 or 3 real numbers."""
    return (
        isinstance(node, tuple)
        and len(node) in (2, 3)  # pyright: ignore[reportUnknownArgumentType]
        and all(
            isinstance(x, _NUMBER) and not isinstance(x, bool)
            for x in node  # pyright: ignore[reportUnknownVariableType]
        )
    )
