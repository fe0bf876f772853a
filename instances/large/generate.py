"""Write the large-fleet instances: an empty 64 x 64 map and random scenarios.

Run ``python instances/large/generate.py`` to regenerate the files next to this script
(a test checks that it reproduces them byte for byte). ``instances/large/README.md``
says why they exist and how they are made.

Scenarios follow the MovingAI ``.scen`` layout. Starts are the first K cells of a
seeded shuffle of the free cells, goals the first K of a second shuffle (the recipe of
lacam3's built-in random instances, with Python's own ``random.Random(seed)`` so that
the files are reproducible). The last column is the 4-connected shortest-path length
(MovingAI files hold the 8-connected octile length there; no reader here uses it).
"""

from __future__ import annotations

import random
from collections import deque
from pathlib import Path

HERE = Path(__file__).resolve().parent
MOVINGAI = HERE.parent / "movingai"

#: (map file, map directory, scenario file, agents, seed)
SCENARIOS = [
    ("empty-64-64.map", HERE, "empty-64-64-gen-1.scen", 2000, 1),
    ("warehouse-10-20-10-2-1.map", MOVINGAI, "warehouse-10-20-10-2-1-gen-1.scen", 1000, 1),
]


def empty_map(width: int, height: int) -> str:
    """A MovingAI map without obstacles."""
    rows = "\n".join("." * width for _ in range(height))
    return f"type octile\nheight {height}\nwidth {width}\nmap\n{rows}\n"


def read_map(text: str) -> list[str]:
    """The rows of a MovingAI map (after the ``map`` line)."""
    lines = text.splitlines()
    return lines[lines.index("map") + 1 :]


def distance(
    rows: list[str], free: list[bool], start: tuple[int, int], goal: tuple[int, int]
) -> int | None:
    """4-connected shortest-path length from ``start`` to ``goal`` (None: unreachable)."""
    h, w = len(rows), len(rows[0])
    dist = [-1] * (w * h)
    s, g = start[0] + w * start[1], goal[0] + w * goal[1]
    dist[g] = 0
    todo = deque([g])
    while todo:
        v = todo.popleft()
        if v == s:
            return dist[v]
        x = v % w
        for u, ok in ((v + 1, x < w - 1), (v - 1, x > 0), (v + w, v + w < w * h), (v - w, v >= w)):
            if ok and free[u] and dist[u] < 0:
                dist[u] = dist[v] + 1
                todo.append(u)
    return None


def scenario(map_name: str, rows: list[str], agents: int, seed: int) -> str:
    """``agents`` random start-goal pairs, each goal reachable from its start."""
    h, w = len(rows), len(rows[0])
    cells = [(x, y) for y in range(h) for x in range(w) if rows[y][x] in ".G"]
    free = [c in ".G" for row in rows for c in row]
    rng = random.Random(seed)
    starts = cells[:]
    rng.shuffle(starts)
    goals = cells[:]
    rng.shuffle(goals)
    out = ["version 1"]
    for k, (s, g) in enumerate(zip(starts[:agents], goals[:agents], strict=True)):
        d = distance(rows, free, s, g)
        if d is None:
            raise SystemExit(f"agent {k}: goal {g} is not reachable from {s}")
        out.append(f"{k // 10}\t{map_name}\t{w}\t{h}\t{s[0]}\t{s[1]}\t{g[0]}\t{g[1]}\t{d}")
    return "\n".join(out) + "\n"


def main() -> None:
    (HERE / "empty-64-64.map").write_text(empty_map(64, 64))
    for map_name, map_dir, scen_name, agents, seed in SCENARIOS:
        rows = read_map((map_dir / map_name).read_text())
        (HERE / scen_name).write_text(scenario(map_name, rows, agents, seed))


if __name__ == "__main__":
    main()
