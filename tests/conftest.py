"""Test-wide settings.

Under CI (``CI`` set) hypothesis runs derandomized, so a red run is reproducible, and
without its shrink phase: a failing example is reported as found instead of spending
minutes minimising it inside the 15-minute budget.

The low levels (CBS's A*, ECBS's focal search) run in Python unless a test chooses
otherwise (``HIERPLAN_LOW_LEVEL``, set here only if the caller has not set it): in
``auto`` mode the first solve that spends 0.5 s in the low level starts a compiler
process for the numba kernels, a third busy process on CI's two cores in the middle of
wall-clock-limited tests. Both paths give identical results; ``tests/test_jit_astar.py``
and ``tests/test_jit_focal.py`` compare them call by call and test the ``auto`` switch.
"""

from __future__ import annotations

import os

import matplotlib
from hypothesis import Phase, settings

matplotlib.use("Agg")
os.environ.setdefault("HIERPLAN_LOW_LEVEL", "python")

settings.register_profile(
    "ci",
    derandomize=True,
    deadline=None,
    print_blob=True,
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
)
if os.environ.get("CI"):
    settings.load_profile("ci")
