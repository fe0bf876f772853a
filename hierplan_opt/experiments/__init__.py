"""Experiments at scale: sweeps of solvers x instances x agents x seeds.

- :func:`sweep` runs a spec (:mod:`~hierplan_opt.experiments.spec`), one process per
  run with a time and a memory limit, on this machine or on a Dask cluster, and keeps
  every run in an SQLite database (:mod:`~hierplan_opt.experiments.store`);
- :mod:`~hierplan_opt.experiments.report` prints the field's standard tables and draws
  success-rate curves and cactus plots; :func:`export` writes CSV or Parquet;
- :mod:`~hierplan_opt.experiments.data` locates the canned specs and the benchmark
  instances shipped with the package.

Example
-------
>>> from hierplan_opt.experiments import canned_specs
>>> "cbs" in canned_specs()
True
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "sweep": "hierplan_opt.experiments.sweep",
    "SweepSummary": "hierplan_opt.experiments.sweep",
    "load_spec": "hierplan_opt.experiments.spec",
    "parse_spec": "hierplan_opt.experiments.spec",
    "SweepSpec": "hierplan_opt.experiments.spec",
    "read_runs": "hierplan_opt.experiments.report",
    "report": "hierplan_opt.experiments.report",
    "export": "hierplan_opt.experiments.report",
    "canned_specs": "hierplan_opt.experiments.data",
    "canned_spec": "hierplan_opt.experiments.data",
    "instances_dir": "hierplan_opt.experiments.data",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'hierplan_opt.experiments' has no attribute {name!r}")


__all__ = list(_LAZY)
