"""Experiments at scale: sweeps of solvers x instances x agents x seeds.

- :func:`sweep` (:mod:`~hierplan_opt.experiments.sweeps`) runs a spec
  (:mod:`~hierplan_opt.experiments.spec`), one process per run with a time and a memory
  limit, on this machine or on a Dask cluster, and keeps every run in an SQLite database
  (:mod:`~hierplan_opt.experiments.store`);
- :mod:`~hierplan_opt.experiments.reports` prints the field's standard tables and draws
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

# All light: pandas, matplotlib and Dask are imported inside the functions that use them.
from hierplan_opt.experiments.data import canned_spec, canned_specs, instances_dir
from hierplan_opt.experiments.reports import export, read_runs, report
from hierplan_opt.experiments.spec import SweepSpec, load_spec, parse_spec
from hierplan_opt.experiments.sweeps import SweepSummary, sweep

__all__ = [
    "SweepSpec",
    "SweepSummary",
    "canned_spec",
    "canned_specs",
    "export",
    "instances_dir",
    "load_spec",
    "parse_spec",
    "read_runs",
    "report",
    "sweep",
]
