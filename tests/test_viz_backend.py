"""Library plotting never touches matplotlib's backend or pyplot's state.

The issue: ``plot_gantt`` switched the backend to Agg, so in a real Jupyter kernel that
figure and every later one vanished. Here every plotting function runs in a fresh
interpreter whose backend is ``svg`` (a non-interactive backend that is not Agg, so a
switch would show), and the backend must be the same after every call.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parent.parent

SCRIPT = r"""
import sys
import matplotlib
import matplotlib.pyplot as plt
import hierplan_opt as hp
from hierplan_opt.schedule import postprocess
from hierplan_opt.viz.gantt import plot_gantt
from hierplan_opt.viz.plots import plot_instance, plot_layers, plot_plan, plot_runtime_table

out = sys.argv[1]
start = matplotlib.get_backend()
assert start == "svg", start

def same(what):
    now = matplotlib.get_backend()
    assert now == start, f"{what} switched the backend {start} -> {now}"
    assert matplotlib.rcParams["backend"] == start, what

g = hp.Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
inst = hp.Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
plan = hp.solve(inst, "cbs", time_limit=10).plan
sched = postprocess(inst, plan, "makespan")

ax = plot_instance(inst); same("plot_instance")
ax = plot_plan(inst, plan); same("plot_plan")
g3 = hp.Graph.grid(2, 2, 2)
fig = plot_layers(hp.Instance.mapf(g3, [(0, 0, 0)], [(1, 1, 1)])); same("plot_layers")
rows = [{"solver": "cbs", "agents": k, "runtime": 0.1 * k, "status": "OPTIMAL"} for k in (1, 2)]
ax = plot_runtime_table(rows); same("plot_runtime_table")
before = plt.get_fignums()
fig = plot_gantt(sched, out); same("plot_gantt(path)")
assert plt.get_fignums() == before, "plot_gantt(path) left a pyplot figure open"
assert type(fig).__name__ == "Figure"
fig = plot_gantt(sched); same("plot_gantt()")
assert len(plt.get_fignums()) == len(before) + 1, "plot_gantt() should make a pyplot figure"
_, ax = plt.subplots()
fig = plot_gantt(sched, ax=ax); same("plot_gantt(ax=)")
assert fig is ax.figure
print("ok", matplotlib.get_backend())
"""


def test_plotting_keeps_the_backend(tmp_path: Path) -> None:
    env = {**os.environ, "MPLBACKEND": "svg"}
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path / "gantt.png")],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        cwd=tmp_path,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ok svg"
    assert (tmp_path / "gantt.png").read_bytes()[:4] == b"\x89PNG"


def test_no_backend_selection_in_the_package() -> None:
    """No module of the package calls ``matplotlib.use`` or ``pyplot.switch_backend``."""
    pattern = re.compile(r"matplotlib\.use\(|switch_backend\(")
    hits = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "hierplan_opt").rglob("*.py")
        if pattern.search(p.read_text())
    ]
    assert hits == []
