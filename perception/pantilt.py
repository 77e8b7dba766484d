"""The student's pan-tilt head camera (Canon VC-C4): where it looks, keeping the teacher centred.

Conventions (also what ``peoplebot_sim`` uses to pose the rendered head camera):

- ``pan_deg``: rotation of the head about the robot's z axis, degrees; 0 looks along the robot's +x
  (forward), positive turns to the robot's left (counter-clockwise seen from above).
- ``tilt_deg``: elevation of the optical axis above the horizontal, degrees; positive looks up.
- The optical centre sits at ``HeadMount.position_m`` in the robot frame for every pan and tilt (the
  small offset of the lens from the pan-tilt axes is neglected); the image has no roll.

:func:`head_camera` turns the observer's planar world pose and the head angles into a posed
:class:`~perception.camera.PinholeCamera`, the extrinsics the head-camera pipeline needs.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from perception.camera import PinholeCamera
from perception.layout import SIDE_MARKER_HEIGHT_M
from perception.pose import check_planar_pose, robot_to_world
from perception.wallframe import check_finite, wrap_degrees


@dataclasses.dataclass(frozen=True)
class PanTiltLimits:
    """Mechanical limits of the head, degrees and degrees per second (Canon VC-C4 defaults)."""

    pan_min_deg: float = -98.0
    pan_max_deg: float = 98.0
    tilt_min_deg: float = -30.0
    tilt_max_deg: float = 88.0
    pan_rate_deg_s: float = 90.0
    tilt_rate_deg_s: float = 70.0

    def __post_init__(self):
        values = dataclasses.astuple(self)
        if not np.all(np.isfinite(values)):
            raise ValueError(f"pan-tilt limits must be finite, got {self!r}")
        if not -180.0 < self.pan_min_deg < self.pan_max_deg < 180.0:
            raise ValueError(
                f"need -180 < pan_min_deg < pan_max_deg < 180, got "
                f"{self.pan_min_deg}, {self.pan_max_deg}"
            )
        if not -90.0 <= self.tilt_min_deg < self.tilt_max_deg <= 90.0:
            raise ValueError(
                f"need -90 <= tilt_min_deg < tilt_max_deg <= 90, got "
                f"{self.tilt_min_deg}, {self.tilt_max_deg}"
            )
        if self.pan_rate_deg_s <= 0 or self.tilt_rate_deg_s <= 0:
            raise ValueError(
                f"rates must be > 0 deg/s, got {self.pan_rate_deg_s}, {self.tilt_rate_deg_s}"
            )


@dataclasses.dataclass(frozen=True)
class HeadMount:
    """Where the head's optical centre sits in the robot frame, metres (x forward, y left, z up)."""

    position_m: tuple[float, float, float] = (0.19, 0.0, 1.20)


def head_camera_rotation(yaw_rad: float, pan_deg: float, tilt_deg: float) -> np.ndarray:
    """Returns ``rotation_world_from_camera`` (OpenCV axes) of the head on a robot with heading
    ``yaw_rad``."""
    check_finite(yaw_rad=yaw_rad, pan_deg=pan_deg, tilt_deg=tilt_deg)
    azimuth = yaw_rad + math.radians(pan_deg)
    elevation = math.radians(tilt_deg)
    ca, sa, ce, se = math.cos(azimuth), math.sin(azimuth), math.cos(elevation), math.sin(elevation)
    # Columns: image x (right, level), image y (down) = z cross x, and the optical axis z.
    return np.array([[sa, se * ca, ce * ca], [-ca, se * sa, ce * sa], [0.0, -ce, se]])


def head_position_world(observer_pose, mount: HeadMount = HeadMount()) -> np.ndarray:
    """Returns the head's optical centre in the world, metres, shape (3,), for ``(x_m, y_m,
    yaw_rad)``."""
    check_planar_pose(observer_pose, "observer_pose")
    rotation, position = robot_to_world(*observer_pose)
    return rotation @ np.asarray(mount.position_m, dtype=float) + position


def head_camera(
    intrinsics: PinholeCamera,
    observer_pose,
    pan_deg: float,
    tilt_deg: float,
    mount: HeadMount = HeadMount(),
) -> PinholeCamera:
    """Returns ``intrinsics`` posed as the head camera of a robot at ``observer_pose`` (x_m, y_m,
    yaw_rad)."""
    check_planar_pose(observer_pose, "observer_pose")
    check_finite(pan_deg=pan_deg, tilt_deg=tilt_deg)
    return intrinsics.with_pose(
        head_camera_rotation(observer_pose[2], pan_deg, tilt_deg),
        head_position_world(observer_pose, mount),
    )


def aim_at(observer_pose, target_world, mount: HeadMount = HeadMount()) -> tuple[float, float]:
    """Returns the unlimited ``(pan_deg, tilt_deg)`` that centre ``target_world`` (x, y, z metres).

    Pan is wrapped to [-180, 180).
    """
    head = head_position_world(observer_pose, mount)
    target = np.asarray(target_world, dtype=float)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise ValueError(
            f"target_world must be three finite metres (x, y, z), got {target_world!r}"
        )
    d = target - head
    horizontal = float(np.hypot(d[0], d[1]))
    pan = float(wrap_degrees(np.degrees(np.arctan2(d[1], d[0]) - observer_pose[2])))
    tilt = float(np.degrees(np.arctan2(d[2], horizontal)))
    return pan, tilt


@dataclasses.dataclass(frozen=True)
class PanTiltCommand:
    """One control step.

    Attributes:
      pan_deg, tilt_deg: the commanded head angles, within the limits and the rate limits.
      target_pan_deg, target_tilt_deg: the angles that would centre the target (unlimited); None
        when there was no target.
      reachable: True when the target angles lie within the mechanical limits.
    """

    pan_deg: float
    tilt_deg: float
    target_pan_deg: float | None
    target_tilt_deg: float | None
    reachable: bool


class PanTiltController:
    """Keeps a target (the teacher) centred in the head camera, within the VC-C4's limits and rates.

    Args:
      limits: mechanical limits.
      mount: where the head sits on the robot.
      target_height_m: height of the point to centre on the target robot (default: the side
        markers').
      initial_pan_deg, initial_tilt_deg: the head's starting angles.
      search_pan_deg, search_tilt_deg: with no target, the head sweeps its pan between
        +-``search_pan_deg`` at ``search_tilt_deg`` (looking a little down, at robot-marker height a
        few metres away) until the target is found; ``search_pan_deg=0`` holds still instead.
    """

    def __init__(
        self,
        limits: PanTiltLimits = PanTiltLimits(),
        mount: HeadMount = HeadMount(),
        *,
        target_height_m: float = SIDE_MARKER_HEIGHT_M,
        initial_pan_deg: float = 0.0,
        initial_tilt_deg: float = 0.0,
        search_pan_deg: float = 80.0,
        search_tilt_deg: float = -10.0,
    ):
        if not (np.isfinite(search_pan_deg) and 0.0 <= search_pan_deg <= limits.pan_max_deg):
            raise ValueError(
                f"search_pan_deg must be in [0, {limits.pan_max_deg}], got {search_pan_deg!r}"
            )
        if not (
            np.isfinite(search_tilt_deg)
            and limits.tilt_min_deg <= search_tilt_deg <= limits.tilt_max_deg
        ):
            raise ValueError(
                f"search_tilt_deg must be within the tilt limits, got {search_tilt_deg!r}"
            )
        check_finite(
            target_height_m=target_height_m,
            initial_pan_deg=initial_pan_deg,
            initial_tilt_deg=initial_tilt_deg,
        )
        self.search_pan_deg = float(search_pan_deg)
        self.search_tilt_deg = float(search_tilt_deg)
        self._search_direction = 1.0
        self.limits = limits
        self.mount = mount
        self.target_height_m = float(target_height_m)
        self.pan_deg_ = float(np.clip(initial_pan_deg, limits.pan_min_deg, limits.pan_max_deg))
        self.tilt_deg_ = float(np.clip(initial_tilt_deg, limits.tilt_min_deg, limits.tilt_max_deg))

    def step(self, observer_pose, target_xy, dt_s: float) -> PanTiltCommand:
        """Moves the head towards centring ``target_xy`` for ``dt_s`` seconds; returns the command.

        Args:
          observer_pose: the student's own ``(x_m, y_m, yaw_rad)``, world frame.
          target_xy: the tracked teacher position ``(x_m, y_m)``, world frame, or None (search).
          dt_s: control period, seconds (> 0).
        """
        if not np.isfinite(dt_s) or dt_s <= 0:
            raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s!r}")
        check_planar_pose(observer_pose, "observer_pose")
        if target_xy is not None:
            target = np.asarray(target_xy, dtype=float)
            if target.shape != (2,) or not np.all(np.isfinite(target)):
                raise ValueError(
                    f"target_xy must be None or two finite metres (x, y), got {target_xy!r}"
                )
        lim = self.limits
        if target_xy is None:
            if self.search_pan_deg == 0.0:
                return PanTiltCommand(self.pan_deg_, self.tilt_deg_, None, None, False)
            if self.pan_deg_ * self._search_direction >= self.search_pan_deg - 1e-9:
                self._search_direction = -self._search_direction
            goal_pan = self._search_direction * self.search_pan_deg
            goal_tilt = self.search_tilt_deg
            pan = tilt = None
            reachable = False
        else:
            target = (float(target_xy[0]), float(target_xy[1]), self.target_height_m)
            pan, tilt = aim_at(observer_pose, target, self.mount)
            reachable = (
                lim.pan_min_deg <= pan <= lim.pan_max_deg
                and lim.tilt_min_deg <= tilt <= lim.tilt_max_deg
            )
            goal_pan = float(np.clip(pan, lim.pan_min_deg, lim.pan_max_deg))
            goal_tilt = float(np.clip(tilt, lim.tilt_min_deg, lim.tilt_max_deg))
        max_pan, max_tilt = lim.pan_rate_deg_s * dt_s, lim.tilt_rate_deg_s * dt_s
        self.pan_deg_ += float(np.clip(goal_pan - self.pan_deg_, -max_pan, max_pan))
        self.tilt_deg_ += float(np.clip(goal_tilt - self.tilt_deg_, -max_tilt, max_tilt))
        return PanTiltCommand(self.pan_deg_, self.tilt_deg_, pan, tilt, reachable)

    def step_to(self, pan_deg: float, tilt_deg: float, dt_s: float) -> PanTiltCommand:
        """Moves the head towards the angles ``(pan_deg, tilt_deg)`` (clipped to the limits) for
        ``dt_s`` seconds at the rate limits; returns the command (a glance at landmarks)."""
        if not np.isfinite(dt_s) or dt_s <= 0:
            raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s!r}")
        check_finite(pan_deg=pan_deg, tilt_deg=tilt_deg)
        lim = self.limits
        goal_pan = float(np.clip(pan_deg, lim.pan_min_deg, lim.pan_max_deg))
        goal_tilt = float(np.clip(tilt_deg, lim.tilt_min_deg, lim.tilt_max_deg))
        max_pan, max_tilt = lim.pan_rate_deg_s * dt_s, lim.tilt_rate_deg_s * dt_s
        self.pan_deg_ += float(np.clip(goal_pan - self.pan_deg_, -max_pan, max_pan))
        self.tilt_deg_ += float(np.clip(goal_tilt - self.tilt_deg_, -max_tilt, max_tilt))
        reachable = goal_pan == pan_deg and goal_tilt == tilt_deg
        return PanTiltCommand(self.pan_deg_, self.tilt_deg_, pan_deg, tilt_deg, reachable)
