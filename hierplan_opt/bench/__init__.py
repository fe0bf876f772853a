"""Benchmarks that print tables: ``hierplan bench AREA [options]``.

Each area is a module of this package with ``main(argv) -> int``. Speed and memory
targets live here, not in timed unit tests.
"""

from __future__ import annotations

AREAS = {
    "cbs": "optimal CBS on the MovingAI samples (time, cost, lower bound, nodes)",
    "ecbs": "bounded-suboptimal ECBS/EECBS on the MovingAI samples",
    "teams": "CBM and max-flow on warehouse-like TAPF instances",
    "formulations": "MIP and CP-SAT model sizes and time to optimum vs CBS",
    "post": "MAPF-POST: TPG/STN size and time, graph vs LP",
}
