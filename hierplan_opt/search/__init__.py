"""Search solvers and the layer they share.

The shared layer (what a new search solver builds on):

* :mod:`.conflicts`: :class:`~.conflicts.Conflict` ``(t, kind, a, b, u, v)`` with kinds
  VERTEX, EDGE (arrival time ``t``), TARGET, and :func:`~.conflicts.find_conflicts`.
* :mod:`.reservations`: :class:`~.reservations.Reservations`, the one table of other
  agents' paths (vertex-time and move keys, parked goals) with ``add``, ``remove``,
  ``sync(paths)``, ``visits(v)`` and ``conflicts_of(agent, path)``.
* :mod:`.constraints`: the constraint tuples (``NEG_V``, ``NEG_E``, ``POS_V``, ...) and
  :class:`~.constraints.AgentConstraints` (one agent's compiled constraints).
* :mod:`.spacetime`: the space-time core, :func:`~.spacetime.successors` (move order)
  and :class:`~.spacetime.Moves` (the successor rule: allowed moves with admissible h
  values), terminal nodes and the deadline.
* The space-time search family over that core, all on ``AgentConstraints`` and
  ``Reservations``: :func:`.astar.space_time_astar` (optimal, ties by conflicts),
  :func:`.focal.focal_path` (bounded by ``w``, FOCAL by conflicts; ``avoid=True`` is
  prioritized planning), :func:`.highways.inflated_focal_path` (edge costs),
  :func:`.mdd.build_mdd` (all optimal paths).
* High levels shaped alike: ``cbs_engine._CBS``, ``ecbs_engine._ECBS``
  (``eecbs._EECBS`` subclasses it), ``cbm._CBM``; ECBS and EECBS take their low level
  as a strategy object (:class:`.focal.FocalLowLevel`, :class:`.highways.HighwayLowLevel`).
* Solver modules and library modules: a solver module declares one solver's ``solve``
  with its options (:func:`hierplan_opt.registry.solver`; the registry's table names
  it) and reaches other solvers only through the registry
  (:func:`hierplan_opt.registry.run`, :func:`hierplan_opt.registry.get`); the engines
  two solvers share are library modules that register nothing (:mod:`.cbs_engine`,
  :mod:`.ecbs_engine`, :mod:`.pibt_engine`, :mod:`.assignment`).
  ``tests/test_layers.py`` checks that no solver module imports another.
"""
