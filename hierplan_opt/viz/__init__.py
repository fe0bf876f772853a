"""Plots: instances and plans (:mod:`~hierplan_opt.viz.plots`), Gantt charts of schedules
(:mod:`~hierplan_opt.viz.gantt`). Import the submodules; matplotlib loads on use."""
