"""OR-Tools and highspy must share one process, whichever is imported first.

Known clash: ortools 9.15 bundles HiGHS, and highspy 1.15 then fails to import (undefined
symbol); pyproject.toml pins highspy < 1.15. Each order runs in a fresh interpreter and
solves one tiny model with each library.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

CPSAT = """
from ortools.sat.python import cp_model
m = cp_model.CpModel()
a, b = m.new_bool_var("a"), m.new_bool_var("b")
m.add_bool_or([a, b]); m.maximize(a + 2 * b)
s = cp_model.CpSolver()
assert s.solve(m) == cp_model.OPTIMAL and s.objective_value == 3
"""
HIGHS = """
import highspy
h = highspy.Highs(); h.setOptionValue("output_flag", False)
x = h.addVariable(lb=0, ub=4); y = h.addVariable(lb=0, ub=4)
h.addConstr(x + y <= 5); h.maximize(x + 2 * y)
assert abs(h.getInfo().objective_function_value - 9) < 1e-6
"""
PYOMO = """
import pyomo.environ as pyo
from pyomo.contrib.appsi.solvers import Highs
m = pyo.ConcreteModel(); m.x = pyo.Var(domain=pyo.Binary)
m.o = pyo.Objective(expr=m.x, sense=pyo.maximize)
assert Highs().solve(m).best_feasible_objective == 1
"""


@pytest.mark.parametrize(
    "order",
    [("ortools", "highspy"), ("highspy", "ortools")],
    ids=["ortools-first", "highspy-first"],
)
def test_ortools_and_highspy_share_a_process(order):
    code = {"ortools": CPSAT, "highspy": HIGHS + PYOMO}
    script = "\n".join(code[name] for name in order) + "\nprint('ok')\n"
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().endswith("ok")
