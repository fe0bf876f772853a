"""Write the overview paper's example instances (figure3, warehouse parts, formation).

Run ``python instances/paper/generate.py`` to regenerate the YAML files next to this
script; ``instances/README.md`` explains every choice. The files are committed, so
nobody needs to run this; it documents how the layouts were drawn.
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent

# ---------------------------------------------------------------- figure 3
# Roadmap read off the plan table of the paper's Fig. 3 (robot moves per timestep):
# A-B, B-F, E-F, F-G, G-H, H-I, H-C, C-D. Coordinates put A B _ C D above E F G H I.
FIGURE3 = """\
# Figure 3 of Ma et al., "Overview: A Hierarchical Framework for Plan Generation and
# Execution in Multi-Robot Systems" (IEEE Intelligent Systems 2017): a TAPF instance
# with two teams. Team 1 (pink): one robot, start A, target H. Team 2 (green): two
# robots, starts E and F, targets D and I. The edges are exactly the moves of the
# paper's plan table (A-B, B-F, E-F, F-G, G-H, H-I, H-C, C-D); coordinates follow a
# two-row drawing (A B . C D over E F G H I, 1 m apart). Optimal makespan: 4.
format: hierplan/1
name: figure3
graph:
  type: roadmap
  vertices:
    A: [0, 1]
    B: [1, 1]
    C: [3, 1]
    D: [4, 1]
    E: [0, 0]
    F: [1, 0]
    G: [2, 0]
    H: [3, 0]
    I: [4, 0]
  edges: [[A, B], [B, F], [E, F], [F, G], [G, H], [H, I], [H, C], [C, D]]
teams:
  - name: team1
    agents: [{name: robot1, start: A}]
    targets: [H]
  - name: team2
    agents: [{name: robot2, start: E}, {name: robot3, start: F}]
    targets: [D, I]
"""

# ---------------------------------------------------------------- warehouse
# 21 x 11 cells of 1 m; row y = 0 first. "@" shelf, "O" conveyor belt (both blocked).
WAREHOUSE_ROWS = [
    ".....................",  # y=0  top aisle
    "..@@@@@.@@@@@.@@@@@..",  # y=1  shelves
    ".....................",  # y=2  narrow passageway
    "..@@@@@.@@@@@.@@@@@..",  # y=3
    ".....................",  # y=4  narrow passageway
    "..@@@@@.@@@@@.@@@@@..",  # y=5
    ".....................",  # y=6  main aisle
    ".....................",  # y=7
    "......OOOOOOOOO......",  # y=8  conveyor belt for the large boxes
    ".....................",  # y=9
    ".....................",  # y=10 depot row
]
# Part 1: robots start in the depot; youBots go to shelf pick-up cells (one small box
# each), Pioneers to the two cells below the conveyor belt (one large box each).
YOUBOT_STARTS = [(x, 10) for x in (1, 3, 5, 7, 9, 11, 13, 15, 17, 19)]
PIONEER_STARTS = [(0, 9), (20, 9)]
# Pick-up cells: (cell, colour of the box picked there).
SMALL_PICKUPS = [
    ((3, 2), "red"),
    ((9, 2), "red"),
    ((16, 2), "red"),
    ((5, 4), "blue"),
    ((11, 4), "blue"),
    ((17, 4), "blue"),
    ((4, 6), "green"),
    ((15, 6), "green"),
    ((10, 0), "yellow"),
    ((4, 0), "yellow"),
]
LARGE_PICKUPS = [((8, 9), "red"), ((12, 9), "green")]
# Part 2 delivery targets: red and blue on the left wall, green and yellow on the right.
DELIVERY = {
    "red": [(0, 1), (0, 2), (0, 3), (0, 4)],
    "blue": [(0, 5), (0, 6), (0, 7)],
    "green": [(20, 2), (20, 3), (20, 4)],
    "yellow": [(20, 5), (20, 6)],
}
# Highways (Fig. 2): one-way suggestions along the narrow passageways between the
# shelves, alternating direction row by row, and along the two short cross aisles.
HIGHWAY_ROWS = {0: +1, 2: -1, 4: +1, 6: -1}
HIGHWAY_COLS = {7: +1, 13: -1}  # +1: towards larger y

ROBOT_TYPES = """\
robot_types:
  # KUKA youBot: omni-directional base, max. 0.8 m/s (manufacturer figure); a_max and
  # the footprint radius (half diagonal of the 0.58 m x 0.38 m base) are our choices.
  youbot: {drive: omni, v_max: 0.8, a_max: 1.0, radius: 0.35}
  # Pioneer P3DX: differential drive; datasheet top speeds are about 1.2 m/s and
  # 300 deg/s; we use reduced limits for a robot carrying a large box.
  pioneer: {drive: differential, v_max: 0.6, omega_max: 1.5, a_max: 0.3, radius: 0.3}
"""


def _cell(c: tuple[int, int]) -> str:
    return f"[{c[0]}, {c[1]}]"


def _highways() -> list[tuple[tuple[int, int], tuple[int, int]]]:
    w, h = len(WAREHOUSE_ROWS[0]), len(WAREHOUSE_ROWS)
    free = {(x, y) for y in range(h) for x in range(w) if WAREHOUSE_ROWS[y][x] == "."}
    out = []
    for y, d in HIGHWAY_ROWS.items():
        for x in range(w):
            a, b = (x, y), (x + d, y)
            if a in free and b in free:
                out.append((a, b))
    for x, d in HIGHWAY_COLS.items():
        for y in range(h):
            a, b = (x, y), (x, y + d)
            if a in free and b in free and 0 <= y <= 6 and 0 <= y + d <= 6:
                out.append((a, b))
    return out


def _graph_block() -> str:
    rows = "\n".join(f'    - "{r}"' for r in WAREHOUSE_ROWS)
    return f"graph:\n  type: grid\n  rows:\n{rows}\n  cell_size: 1.0\n"


def _highway_block() -> str:
    lines = "\n".join(f"  - [{_cell(a)}, {_cell(b)}]" for a, b in _highways())
    return f"highways:\n{lines}\n"


def warehouse_part1() -> str:
    small = ", ".join(_cell(c) for c, _ in SMALL_PICKUPS)
    large = ", ".join(_cell(c) for c, _ in LARGE_PICKUPS)
    youbots = "\n".join(
        f"      - {{name: youbot{i + 1}, start: {_cell(s)}}}" for i, s in enumerate(YOUBOT_STARTS)
    )
    pioneers = "\n".join(
        f"      - {{name: pioneer{i + 1}, start: {_cell(s)}}}" for i, s in enumerate(PIONEER_STARTS)
    )
    return (
        "# Automated warehouse (overview paper, Fig. 4), part 1: every robot drives to a\n"
        "# pick-up location for its box size. TAPF with two teams, one per robot type:\n"
        "# ten KUKA youBots (small boxes, shelf cells) and two Pioneer P3DX (large\n"
        "# boxes, conveyor belt). See instances/README.md for the layout choices.\n"
        "format: hierplan/1\nname: warehouse-part1\n"
        + _graph_block()
        + ROBOT_TYPES
        + "teams:\n"
        + f"  - name: youbots\n    type: youbot\n    agents:\n{youbots}\n"
        + f"    targets: [{small}]\n"
        + f"  - name: pioneers\n    type: pioneer\n    agents:\n{pioneers}\n"
        + f"    targets: [{large}]\n"
        + _highway_block()
    )


def warehouse_part2() -> str:
    teams = []
    for colour, targets in DELIVERY.items():
        agents = []
        n = 0
        for c, col in SMALL_PICKUPS:
            if col == colour:
                n += 1
                agents.append(
                    f"      - {{name: {colour}_small{n}, start: {_cell(c)}, type: youbot}}"
                )
        n = 0
        for c, col in LARGE_PICKUPS:
            if col == colour:
                n += 1
                agents.append(
                    f"      - {{name: {colour}_large{n}, start: {_cell(c)}, type: pioneer}}"
                )
        assert len(agents) == len(targets), colour
        tg = ", ".join(_cell(t) for t in targets)
        teams.append(
            f"  - name: {colour}\n    agents:\n" + "\n".join(agents) + f"\n    targets: [{tg}]\n"
        )
    return (
        "# Automated warehouse (overview paper, Fig. 4), part 2: every robot holds the\n"
        "# box it picked in part 1 and delivers it to a target of the box's colour, red\n"
        "# and blue on the left wall, green and yellow on the right. TAPF with four teams\n"
        "# (one per colour); robots keep their type. Starts = the part-1 pick-up cells.\n"
        "format: hierplan/1\nname: warehouse-part2\n"
        + _graph_block()
        + ROBOT_TYPES
        + "teams:\n"
        + "".join(teams)
        + _highway_block()
    )


# ---------------------------------------------------------------- formation U-S-C
# 3D grid, x to the right, y towards the building, z up. The letters stand in the
# vertical plane y = 1, rows z = 1..5; the building occupies y = 5..8, z = 0..2.
FORM_W, FORM_H, FORM_D = 16, 9, 6
LETTER_Y = 1
U = ["#..#", "#..#", "#..#", "#..#", "####"]  # top row first; '#' = a quadcopter
S = ["###", "#..", "###", "..#", "###"]
C = ["###", "#..", "#..", "#..", "###"]
LETTERS = [(U, 1), (S, 7), (C, 12)]  # (pattern, leftmost x)
BUILDING = (1, 14, 5, 8, 0, 2)  # x0, x1, y0, y1, z0, z1 of the walls (inclusive)
DOORS_X = [2, 4, 7, 10, 13]  # five open doors in the front wall y = 5 at z = 0


def formation() -> str:
    x0, x1, y0, y1, z0, z1 = BUILDING
    walls = []
    for x in range(x0, x1 + 1):
        for y in range(y0, y1 + 1):
            for z in range(z0, z1 + 1):
                on_wall = x in (x0, x1) or y in (y0, y1) or z == z1
                if on_wall and not (y == y0 and z == 0 and x in DOORS_X):
                    walls.append((x, y, z))
    inside = [
        (x, y, z) for z in range(z0, z1) for y in range(y0 + 1, y1) for x in range(x0 + 1, x1)
    ]
    goals = []
    for pattern, left in LETTERS:
        for row, line in enumerate(pattern):
            z = 5 - row
            for dx, ch in enumerate(line):
                if ch == "#":
                    goals.append((left + dx, LETTER_Y, z))
    assert len(goals) == 32, len(goals)
    # 32 quadcopters: the inside cells, filled from the back row upwards.
    inside.sort(key=lambda c: (-c[1], c[2], c[0]))
    starts = inside[:32]
    assert len(starts) == 32
    obstacles = ", ".join(f"[{x}, {y}, {z}]" for x, y, z in walls)
    agents = "\n".join(
        f"      - {{name: quad{i + 1}, start: [{s[0]}, {s[1]}, {s[2]}]}}"
        for i, s in enumerate(starts)
    )
    tg = ", ".join(f"[{x}, {y}, {z}]" for x, y, z in goals)
    return (
        "# Formation change (overview paper, Fig. 5): 32 identical quadcopters start\n"
        "# inside a building with five open doors (the text's number; the figure caption\n"
        "# says four) and spell U-S-C outside. Anonymous MAPF: one team. 3D grid of 1 m\n"
        "# cells, 6-connected; x right, y towards the building, z up.\n"
        "format: hierplan/1\nname: formation-usc\n"
        f"graph:\n  type: grid\n  dimensions: [{FORM_W}, {FORM_H}, {FORM_D}]\n"
        f"  obstacles: [{obstacles}]\n"
        "robot_types:\n"
        "  # Small indoor quadcopter (Crazyflie-class): our choice of limits.\n"
        "  quadcopter: {drive: omni, v_max: 1.0, a_max: 2.0, radius: 0.15}\n"
        "teams:\n"
        "  - name: quadcopters\n    type: quadcopter\n    agents:\n"
        f"{agents}\n"
        f"    targets: [{tg}]\n"
    )


def main() -> None:
    files = {
        "figure3.yaml": FIGURE3,
        "warehouse-part1.yaml": warehouse_part1(),
        "warehouse-part2.yaml": warehouse_part2(),
        "formation-usc.yaml": formation(),
    }
    for name, text in files.items():
        (HERE / name).write_text(text)


if __name__ == "__main__":
    main()
