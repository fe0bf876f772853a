"""Robot models for the MuJoCo world, built from the instance's robot types.

A robot type of the instance (:class:`~hierplan_opt.core.instance.Kinematics`: ``drive``,
``radius``, ``v_max``, ``a_max``, ``omega_max``) gives the *limits* the planner assumed;
a preset of a real robot gives the *body* (mass, wheel radius, track, inertia). The
model's motors are sized so the robot can just do what the planner assumed (with the
headroom ``MOTOR_HEADROOM``), so a heavier payload or a weaker motor makes it measurably
slower.

Three models (every parameter with its source; "ours" marks a modelling choice):

* **Differential drive** (``drive: differential``): a rigid chassis (a cylinder of the
  robot's footprint radius) on a planar base, driven by two wheels at ``+-track/2``. Each
  wheel is a velocity-servo motor at the wheel's contact point pushing along the chassis'
  heading, limited in speed (motor speed = ``v_max`` plus headroom) and in force (motor
  torque / wheel radius, and traction ``mu * m * g / 2`` of the floor under the robot).
  A third servo at the axle centre holds the lateral velocity at 0 with a force up to
  ``mu * m * g`` (the tyres' side friction: a robot on a spill skids). The caster carries
  weight only (no force). Presets: Pioneer P3DX (robots with radius >= 0.22 m) and
  iRobot Create 2 (smaller ones).
* **Omni-directional** (``drive: omni`` on 2D maps): the KUKA youBot base, a chassis on a
  planar base with force-limited velocity servos along x, y and yaw (four mecanum wheels:
  their traction limits the force to ``mu_mecanum * m * g``).
* **Quadcopter** (3D maps): a Crazyflie-2.x-sized free rigid body (6 DOF, gravity) with
  a thrust along its body z axis in ``[0, T_max]`` and body torques limited by arm x
  motor thrust; a cascaded position / attitude controller (:mod:`.control`) commands
  them.

Sources:

* Pioneer P3DX: Adept MobileRobots, "Pioneer 3-DX" datasheet (2011): mass 9 kg, wheel
  diameter 195 mm, max. speed 1.2 m/s, max. rotation 300 deg/s, payload 17 kg; track
  0.33 m measured from the datasheet drawing (381 mm wide body, 47 mm wheels).
* iRobot Create 2: iRobot, "Create 2 Open Interface Spec" (2015): mass 3.6 kg, wheel
  diameter 72 mm, wheel base 235 mm, max. speed 0.5 m/s.
* KUKA youBot: KUKA, "youBot Hardware" (youBot store wiki, 2012): base 580 x 380 mm,
  mass about 20 kg without the arm, mecanum wheels 100 mm diameter, max. 0.8 m/s.
* Crazyflie 2.x: Bitcraze datasheet (2019): mass 27 g, 92 mm motor-to-motor diagonal
  (arm 46 mm), max. take-off weight 42 g (so about 0.6 N total thrust); inertia
  ``diag(1.4e-5, 1.4e-5, 2.17e-5) kg m^2`` from J. Foerster, "System identification of
  the Crazyflie 2.0 nano quadrocopter" (ETH Zurich, 2015).
* Floor friction: rubber on dry concrete ``mu = 0.8`` (ours, textbook value);
  mecanum traction 0.3 of that (ours: rollers give a fraction of a tyre's grip).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from hierplan_opt.core.instance import Kinematics

#: Gravity (m/s^2).
G = 9.81
#: Rubber on dry concrete (ours).
MU_FLOOR = 0.8
#: Motors can give this multiple of what the planner's a_max / omega_max need (ours).
MOTOR_HEADROOM = 2.0
#: Chassis height (m) of ground robots (only for the collision body; ours).
CHASSIS_HEIGHT = 0.2
#: Rolling resistance and drivetrain drag of ground robots: N s/m per kg (ours).
ROLLING_DAMPING = 0.2


@dataclass(frozen=True)
class Preset:
    """One real robot's body (see the module text for sources)."""

    name: str
    mass: float  # kg
    wheel_radius: float  # m (0 for quadcopters)
    track: float  # m: distance between the driven wheels (diff drive)
    v_top: float  # m/s: manufacturer top speed
    arm: float = 0.0  # m: quadcopter motor arm
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)  # quadcopter body inertia
    thrust_max: float = 0.0  # N: total thrust (quadcopter)


PIONEER = Preset("Pioneer P3DX", 9.0, 0.0975, 0.33, 1.2)
CREATE2 = Preset("iRobot Create 2", 3.6, 0.036, 0.235, 0.5)
YOUBOT = Preset("KUKA youBot base", 20.0, 0.05, 0.38, 0.8)
CRAZYFLIE = Preset(
    "Crazyflie 2.x",
    0.027,
    0.0,
    0.0,
    1.0,
    arm=0.046,
    inertia=(1.4e-5, 1.4e-5, 2.17e-5),
    thrust_max=0.6,
)


@dataclass(frozen=True)
class RobotModel:
    """The physical model of one robot.

    ``kind`` is ``"diff"``, ``"omni"`` or ``"quad"``; ``v_max``, ``a_max`` and
    ``omega_max`` are the controller's limits (from the instance); ``force_max`` the
    motor force per driven axis / wheel (N) before traction; ``torque_max`` the yaw (or,
    quadcopter, roll/pitch/yaw) torque limit (N m).

    Example
    -------
    >>> from hierplan_opt.core.instance import Kinematics
    >>> m = robot_model(Kinematics("p", drive="differential", v_max=0.6,
    ...                            omega_max=1.5, a_max=0.3, radius=0.3), dim=2)
    >>> m.kind, m.preset.name, m.mass
    ('diff', 'Pioneer P3DX', 9.0)
    """

    kind: str
    preset: Preset
    radius: float
    v_max: float
    a_max: float
    omega_max: float
    mass: float
    force_max: float
    torque_max: float
    track: float
    inertia: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0))
    thrust_max: float = 0.0


def robot_model(k: Kinematics, dim: int, *, payload: float = 0.0) -> RobotModel:
    """The model of a robot of kinematics ``k`` on a ``dim``-dimensional map.

    ``payload`` (kg) is added to the body's mass (the motors stay as sized for the empty
    robot). A robot without ``a_max`` is given ``v_max`` per second (reaches top speed in
    one second: ours); one without ``omega_max`` turns at 2 rad/s (ours).

    Example
    -------
    >>> from hierplan_opt.core.instance import Kinematics
    >>> robot_model(Kinematics("q", v_max=1.0, a_max=2.0, radius=0.15), dim=3).kind
    'quad'
    """
    a_max = float(k.a_max) if k.a_max else float(k.v_max)
    omega = float(k.omega_max) if k.omega_max else 2.0
    radius = max(float(k.radius), 0.05)
    if dim == 3:
        p = CRAZYFLIE
        mass = p.mass + payload
        # Thrust to hover plus a_max in any direction, with headroom, never below the
        # real Crazyflie's.
        thrust = max(p.thrust_max, MOTOR_HEADROOM * p.mass * (G + a_max))
        torque = p.arm * thrust / 4.0
        return RobotModel(
            "quad", p, radius, float(k.v_max), a_max, omega, mass, thrust, torque, 0.0,
            inertia=p.inertia, thrust_max=thrust,
        )  # fmt: skip
    if k.drive == "differential":
        p = PIONEER if radius >= 0.22 else CREATE2
        mass = p.mass + payload
        track = min(p.track, 1.6 * radius)
        # Per wheel: half the force to accelerate at a_max, and enough difference to
        # turn at omega_max within a quarter second, with headroom.
        inertia_z = 0.5 * p.mass * radius**2
        force = MOTOR_HEADROOM * max(
            0.5 * p.mass * a_max, inertia_z * omega / 0.25 / track + 0.5 * p.mass * 0.1
        )
        return RobotModel("diff", p, radius, float(k.v_max), a_max, omega, mass, force, 0.0, track)
    p = YOUBOT
    mass = p.mass + payload
    force = MOTOR_HEADROOM * p.mass * a_max
    inertia_z = 0.5 * p.mass * radius**2
    torque = MOTOR_HEADROOM * inertia_z * omega / 0.25
    return RobotModel("omni", p, radius, float(k.v_max), a_max, omega, mass, force, torque, 0.0)


def traction(model: RobotModel, mu: float) -> float:
    """Largest horizontal force (N) the floor gives the robot at friction ``mu``
    (all wheels; mecanum rollers 0.3 of a tyre's grip). Quadcopters: infinite."""
    if model.kind == "quad":
        return math.inf
    share = 0.3 if model.kind == "omni" else 1.0
    return share * mu * model.mass * G
