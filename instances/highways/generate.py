"""Write the highway instances (warehouse of Fig. 2, Kiva-like map, 5 x 20 corridor).

Run ``python instances/highways/generate.py`` to regenerate the files next to this
script; ``instances/README.md`` explains the choices. Everything is deterministic
(NumPy's ``default_rng(seed)``); a test checks that the files are reproduced byte for
byte.

* ``warehouse-fig2.yaml``: the overview paper's Fig. 2 (robots in Area1 and Area2 swap
  sides through narrow passageways between shelves), with user highways along the
  passageways, in the project's YAML;
* ``kiva-22x54.map`` + ``kiva-22x54-seed{0..9}.scen`` (150 agents, 75 each way between
  the two 22 x 5 end areas) + ``kiva-22x54.map.highway`` (user highways in Kei18/pibt's
  iECBS character grid);
* ``corridor-5x20.map`` + ``corridor-5x20.scen`` (20 agents, 10 each way) +
  ``corridor-5x20.hwy`` (user highways in hangma-usc/ECBS_Replan's edge list).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hierplan_opt.core.graph import Graph
from hierplan_opt.core.highways import corridors
from hierplan_opt.core.instance import Instance
from hierplan_opt.io.highways import edges_text, grid_text
from hierplan_opt.io.movingai import map_text, scen_text
from hierplan_opt.io.yaml_format import dumps

HERE = Path(__file__).resolve().parent


def rows_graph(rows: list[str]) -> Graph:
    """A grid from rows of ``.`` (free) and ``@`` (blocked), row y = 0 first."""
    blocked = np.array([[c == "@" for c in row] for row in rows])
    return Graph.grid(len(rows[0]), len(rows), blocked=blocked)


def swap_sides(
    left: list[tuple[int, int]], right: list[tuple[int, int]], k: int, seed: int
) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """``k`` agents from ``left`` to ``right`` and ``k`` back (random distinct cells)."""
    rng = np.random.default_rng(seed)
    ls = [left[i] for i in rng.permutation(len(left))]
    rs = [right[i] for i in rng.permutation(len(right))]
    starts = ls[:k] + rs[:k]
    goals = [rs[len(rs) - 1 - i] for i in range(k)] + [ls[len(ls) - 1 - i] for i in range(k)]
    return starts, goals


# ---------------------------------------------------------------- Fig. 2 warehouse
# 24 x 10 cells: Area1 (x 0-3) and Area2 (x 20-23) joined by four width-1 passageways
# (rows 0, 3, 6, 9) between three rows of shelves (x 4-19).
def warehouse() -> str:
    rows = ["...." + ("." if y % 3 == 0 else "@") * 16 + "...." for y in range(10)]
    g = rows_graph(rows)
    area1 = [(x, y) for x in range(4) for y in range(10)]
    area2 = [(x, y) for x in range(20, 24) for y in range(10)]
    starts, goals = swap_sides(area1, area2, 8, seed=2)
    hw = corridors(g)
    inst = Instance.mapf(g, starts, goals, name="warehouse-fig2")
    inst = Instance(g, inst.agents, (), hw, "warehouse-fig2")
    head = (
        "# Fig. 2 of the overview paper: robots in Area1 (x 0-3) and Area2 (x 20-23) swap\n"
        "# sides through narrow passageways between shelves; the highways (red arrows in\n"
        "# the paper) run one way along each passageway, alternating (the `corridors`\n"
        "# generator). Written by instances/highways/generate.py.\n"
    )
    return head + dumps(inst, rows=True)


# ---------------------------------------------------------------- Kiva-like map
# 22 x 54: end areas x 0-4 and x 49-53; shelf blocks of 10 x 2 (x 5-14, 16-25, 27-36,
# 38-47) between width-1 aisles (rows 0, 3, ..., 21; columns 15, 26, 37, 48).
def kiva_graph() -> Graph:
    rows = []
    for y in range(22):
        if y % 3 == 0:
            rows.append("." * 54)
            continue
        mid = "@" * 10 + "." + "@" * 10 + "." + "@" * 10 + "." + "@" * 10 + "."
        rows.append("." * 5 + mid + "." * 5)
    return rows_graph(rows)


def kiva(seed: int) -> Instance:
    g = kiva_graph()
    left = [(x, y) for x in range(5) for y in range(22)]
    right = [(x, y) for x in range(49, 54) for y in range(22)]
    starts, goals = swap_sides(left, right, 75, seed=seed)
    return Instance.mapf(g, starts, goals, name=f"kiva-22x54-seed{seed}")


# ---------------------------------------------------------------- 5 x 20 corridor
# Two 5 x 5 rooms (x 0-4 and x 15-19) joined by a width-2 corridor (rows 2-3).
def corridor_instance() -> Instance:
    rows = ["....." + ("." * 10 if y in (2, 3) else "@" * 10) + "....." for y in range(5)]
    g = rows_graph(rows)
    left = [(x, y) for x in range(5) for y in range(5)]
    right = [(x, y) for x in range(15, 20) for y in range(5)]
    starts, goals = swap_sides(left, right, 10, seed=0)
    return Instance.mapf(g, starts, goals, name="corridor-5x20")


def files() -> dict[str, str]:
    """Every file this script writes: name -> text."""
    out = {"warehouse-fig2.yaml": warehouse()}
    kg = kiva_graph()
    out["kiva-22x54.map"] = map_text(kg)
    out["kiva-22x54.map.highway"] = grid_text(kg, corridors(kg))
    for seed in range(10):
        out[f"kiva-22x54-seed{seed}.scen"] = scen_text(kiva(seed), "kiva-22x54.map")
    c = corridor_instance()
    out["corridor-5x20.map"] = map_text(c.graph)
    out["corridor-5x20.scen"] = scen_text(c, "corridor-5x20.map")
    out["corridor-5x20.hwy"] = edges_text(c.graph, corridors(c.graph))
    return out


def main(target: Path = HERE) -> None:
    for name, text in files().items():
        (target / name).write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
