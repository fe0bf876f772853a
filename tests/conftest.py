"""Test-wide settings.

Under CI (``CI`` set) hypothesis runs derandomized, so a red run is reproducible, and
without its shrink phase: a failing example is reported as found instead of spending
minutes minimising it inside the 15-minute budget.
"""

from __future__ import annotations

import os

import matplotlib
from hypothesis import Phase, settings

matplotlib.use("Agg")

settings.register_profile(
    "ci",
    derandomize=True,
    deadline=None,
    print_blob=True,
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
)
if os.environ.get("CI"):
    settings.load_profile("ci")
