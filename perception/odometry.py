"""Wheel odometry: a differential-drive robot's planar pose from its wheel encoders.

Pure geometry, as on the real PeopleBot (ARIA integrates the same way): each wheel's rolled distance
is its angle change times the wheel radius; the mean is the forward motion, the difference over the
track width the turn.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class DriveGeometry:
    """Wheel radius and track width (distance between the wheels), metres."""

    wheel_radius_m: float = 0.095
    track_m: float = 0.34

    def __post_init__(self):
        for name in ("wheel_radius_m", "track_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number of metres, got {value!r}")


class WheelOdometry:
    """Integrates wheel angles (radians, forward positive) into a world pose ``(x, y, yaw)``.

    Args:
      start_pose: the known starting pose ``(x_m, y_m, yaw_rad)``.
      left_angle, right_angle: the wheel encoders' readings at the start, radians.
      geometry: the robot's drive geometry.
    """

    def __init__(
        self,
        start_pose,
        left_angle: float,
        right_angle: float,
        geometry: DriveGeometry = DriveGeometry(),
    ):
        pose = np.asarray(start_pose, dtype=float)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise ValueError(
                f"start_pose must be 3 finite numbers (x_m, y_m, yaw_rad), got {start_pose!r}"
            )
        if not (math.isfinite(left_angle) and math.isfinite(right_angle)):
            raise ValueError(
                f"left_angle and right_angle must be finite radians, got {left_angle!r}, "
                f"{right_angle!r}"
            )
        self.geometry = geometry
        self.pose = pose.copy()
        self._last = (float(left_angle), float(right_angle))

    def update(self, left_angle: float, right_angle: float) -> np.ndarray:
        """Advances the pose with new encoder readings (radians); returns ``(x, y, yaw)``."""
        if not (math.isfinite(left_angle) and math.isfinite(right_angle)):
            raise ValueError(f"wheel angles must be finite, got {left_angle!r}, {right_angle!r}")
        r = self.geometry.wheel_radius_m
        d_left = (left_angle - self._last[0]) * r
        d_right = (right_angle - self._last[1]) * r
        self._last = (float(left_angle), float(right_angle))
        arc = 0.5 * (d_left + d_right)
        turn = (d_right - d_left) / self.geometry.track_m
        chord, heading = arc_chord(self.pose[2], arc, turn)
        self.pose[0] += chord * math.cos(heading)
        self.pose[1] += chord * math.sin(heading)
        self.pose[2] = (self.pose[2] + turn + math.pi) % (2 * math.pi) - math.pi
        return self.pose.copy()


def arc_chord(yaw_rad: float, distance_m: float, turn_rad: float) -> tuple[float, float]:
    """Returns ``(chord_m, heading_rad)`` of a step from heading ``yaw_rad`` along an arc of
    ``distance_m`` turning ``turn_rad``: exact for a constant curvature, the chord points along
    the mean heading and is shorter than the arc by sin(turn / 2) / (turn / 2)."""
    half = 0.5 * turn_rad
    return distance_m * (math.sin(half) / half if abs(half) > 1e-9 else 1.0), yaw_rad + half
