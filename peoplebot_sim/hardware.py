"""How the student's robot may differ from the nominal model: its firmware's command path and its
body, for transfer tests toward real robots.

- ``Actuation``: what happens between the (linear m/s, yaw rad/s) command and the wheel servos,
  at the physics rate: a command latency and the firmware's acceleration limits (ARIA ramps its
  velocity set-points this way).
- ``Body``: the physical robot: per-wheel radius errors (the servos and the odometry believe the
  nominal radius, so they bias both the motion and the odometry), base mass, floor friction
  under the wheels and caster friction. Applied to the MJCF before it is compiled.

Every field's default (0) is the nominal robot; a record of defaults changes nothing.
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np


def _check_fields(record, signed: tuple = ()) -> None:
    """Raises ValueError naming the field unless every field is a finite number, >= 0 unless
    named in ``signed`` (then > -1, a fraction of a positive quantity)."""
    for field in dataclasses.fields(record):
        value = getattr(record, field.name)
        key = field.name
        if isinstance(value, bool) or not (
            isinstance(value, (int, float)) and math.isfinite(value)
        ):
            raise ValueError(f"{key} must be a finite number, got {value!r}")
        if field.name in signed:
            if not value > -1:
                raise ValueError(f"{key} must be a fraction greater than -1, got {value!r}")
        elif value < 0:
            raise ValueError(f"{key} must be >= 0 (0: off), got {value!r}")


@dataclasses.dataclass(frozen=True)
class Actuation:
    """The student's command path (0: off).

    Attributes:
      command_latency_ms: delay between the agent's command and the servos, milliseconds
        (rounded to whole physics steps).
      linear_accel_mps2: the firmware's limit on the change of the forward set-point, m/s^2.
      yaw_accel_degps2: the same for the yaw-rate set-point, deg/s^2.
    """

    command_latency_ms: float = 0.0
    linear_accel_mps2: float = 0.0
    yaw_accel_degps2: float = 0.0

    def __post_init__(self):
        _check_fields(self)

    @property
    def active(self) -> bool:
        """Returns whether any field differs from the nominal robot."""
        return self != Actuation()


def braking_travel(rate: float, limit: float) -> float:
    """Returns how far a rate carries on while a set-point ramp at ``limit`` brings it to rest,
    ``rate |rate| / (2 limit)`` (signed as ``rate``; units of the rate times seconds, e.g. m/s
    and m/s^2 give metres); 0 without a limit (``limit`` 0: the rate changes at once)."""
    return rate * abs(rate) / (2.0 * limit) if limit > 0 else 0.0


@dataclasses.dataclass(frozen=True)
class Body:
    """The student's body (0: nominal).

    Attributes:
      left_wheel_radius_fraction, right_wheel_radius_fraction: each wheel's true radius relative
        to the nominal 0.095 m minus 1 (the firmware and odometry believe the nominal one).
      mass_fraction: the base's mass and inertia relative to the model's, minus 1.
      floor_friction_fraction: sliding friction under the student's wheels relative to the
        model's, minus 1.
      caster_friction: the casters' sliding friction coefficient (the model's are frictionless).
    """

    left_wheel_radius_fraction: float = 0.0
    right_wheel_radius_fraction: float = 0.0
    mass_fraction: float = 0.0
    floor_friction_fraction: float = 0.0
    caster_friction: float = 0.0

    def __post_init__(self):
        _check_fields(
            self,
            signed=(
                "left_wheel_radius_fraction",
                "right_wheel_radius_fraction",
                "mass_fraction",
                "floor_friction_fraction",
            ),
        )

    @property
    def active(self) -> bool:
        """Returns whether any field differs from the nominal robot."""
        return self != Body()


def apply_body(robot_mjcf, floor_geom, body: Body) -> None:
    """Changes the robot's MJCF (``robot_mjcf``, a PeopleBot model before compiling) and the
    arena's floor geom to ``body``. Wheel radii move the axle to the new radius, so the base
    stays level; the tendons (the servos' idea of the radius) stay nominal."""
    if not body.active:
        return
    for side, fraction in (
        ("left", body.left_wheel_radius_fraction),
        ("right", body.right_wheel_radius_fraction),
    ):
        geom = robot_mjcf.find("geom", f"{side}_wheel")
        radius = float(geom.dclass.geom.size[0]) * (1.0 + fraction)
        geom.size = [radius]
        wheel = robot_mjcf.find("body", f"{side}_wheel")
        wheel.pos = [wheel.pos[0], wheel.pos[1], radius]
    if body.mass_fraction:
        inertial = robot_mjcf.find("body", "base").inertial
        inertial.mass = float(inertial.mass) * (1.0 + body.mass_fraction)
        inertial.diaginertia = np.asarray(inertial.diaginertia, float) * (1.0 + body.mass_fraction)
    if body.floor_friction_fraction:
        scale = 1.0 + body.floor_friction_fraction
        for side in ("left", "right"):
            geom = robot_mjcf.find("geom", f"{side}_wheel")
            geom.friction = np.asarray(geom.dclass.geom.friction, float) * [scale, 1, 1]
        floor_geom.friction = np.asarray(floor_geom.friction, float) * [scale, 1, 1]
    if body.caster_friction:
        for name in ("rear_caster", "front_caster"):
            geom = robot_mjcf.find("geom", name)
            geom.condim = 3
            geom.friction = [body.caster_friction, 0.005, 0.0001]


class CommandFilter:
    """The firmware's command path, stepped once per physics step: a latency of whole physics
    steps, then acceleration limits on the (linear m/s, yaw rad/s) set-points."""

    def __init__(self, actuation: Actuation, physics_timestep: float):
        self.actuation = actuation
        self.dt = float(physics_timestep)
        self.delay_steps = int(round(actuation.command_latency_ms / 1000.0 / self.dt))
        self.reset()

    def reset(self) -> None:
        """Starts at rest: the delayed commands and the set-points are zero."""
        self._queue = collections.deque(
            [np.zeros(2)] * self.delay_steps, maxlen=self.delay_steps + 1
        )
        self.setpoint = np.zeros(2)

    def step(self, command) -> np.ndarray:
        """Returns the set-points ``(linear m/s, yaw rad/s)`` the servos get this physics step."""
        self._queue.append(np.asarray(command, dtype=float)[:2].copy())
        target = self._queue.popleft()
        limits = (self.actuation.linear_accel_mps2, math.radians(self.actuation.yaw_accel_degps2))
        for i, limit in enumerate(limits):
            if limit > 0:
                change = limit * self.dt
                self.setpoint[i] += np.clip(target[i] - self.setpoint[i], -change, change)
            else:
                self.setpoint[i] = target[i]
        return self.setpoint.copy()
