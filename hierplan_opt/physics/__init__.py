"""Robot simulation in the MuJoCo physics engine (issue 33).

* :mod:`.models`: robot models from the instance's robot types (differential drive,
  omni-directional youBot base, Crazyflie-sized quadcopter), parameters with sources;
* :mod:`.plant`: :class:`~.plant.MujocoPlant`, the world and the controllers, behind the
  execution monitor's Plant protocol (:mod:`hierplan_opt.execution.plant`);
* :mod:`.disturbances`: physical disturbances as data (spill, payload, weak motor, wind,
  robot stop);
* :mod:`.run`: run a schedule in physics and measure it (distances, contacts, arrivals
  against the schedule, tracking error, real-time factor).

Importing this package imports MuJoCo (a heavy module): nothing outside it imports it at
module level.
"""
