"""Render-only viewpoints for videos: a camera following a robot from behind and above, and a
close-up of the table. They are MuJoCo free cameras (``mujoco.MjvCamera``), not model cameras, so
they change nothing in the model, its physics or the vision cameras."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from perception.wallframe import ArenaGeometry

#: The views of ``peoplebot demo``: the model's oblique ``showcase`` camera, a ``FollowCamera``
#: on the robot, and the model's ``overhead`` camera.
VIEWS = ("showcase", "follow", "overhead")


def free_camera(
    lookat_m, azimuth_deg: float, elevation_deg: float, distance_m: float
) -> mujoco.MjvCamera:
    """Returns a free camera looking at ``lookat_m`` (world x, y, z metres) along the compass
    ``azimuth_deg`` (0 looks east, 90 north), ``elevation_deg`` (negative looks down), from
    ``distance_m`` away."""
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = lookat_m
    camera.azimuth, camera.elevation, camera.distance = azimuth_deg, elevation_deg, distance_m
    return camera


@dataclasses.dataclass
class FollowCamera:
    """Follows a robot from behind and above: looks at a point ``ahead_m`` in front of the robot,
    ``height_m`` up, from ``distance_m`` away at ``elevation_deg`` (negative looks down) and
    ``side_deg`` to the robot's right of straight behind (so that its column does not hide what
    lies ahead); its heading follows the robot's yaw smoothed with the time constant
    ``smoothing_s``, so that turns on the spot show as the robot turning in the frame."""

    distance_m: float = 3.6
    elevation_deg: float = -50.0
    side_deg: float = 30.0
    height_m: float = 0.4
    ahead_m: float = 0.5
    smoothing_s: float = 1.5

    def __post_init__(self):
        self._azimuth_deg: float | None = None
        self._lookat: np.ndarray | None = None

    def reset(self) -> None:
        """Forgets the smoothed heading (the next ``update`` jumps to the robot)."""
        self._azimuth_deg, self._lookat = None, None

    def update(self, pose, dt_s: float) -> mujoco.MjvCamera:
        """Returns the camera for the robot's planar ``pose`` (world x m, y m, yaw rad) after
        ``dt_s`` seconds since the last update."""
        x, y, yaw = (float(v) for v in pose)
        target = np.array(
            [x + self.ahead_m * math.cos(yaw), y + self.ahead_m * math.sin(yaw), self.height_m]
        )
        heading = math.degrees(yaw) + self.side_deg
        if self._azimuth_deg is None:
            self._azimuth_deg, self._lookat = heading, target
        else:
            gain = 1.0 - math.exp(-dt_s / self.smoothing_s)
            turn = (heading - self._azimuth_deg + 180.0) % 360.0 - 180.0
            self._azimuth_deg += gain * turn
            self._lookat = self._lookat + min(1.0, 3 * gain) * (target - self._lookat)
        return free_camera(self._lookat, self._azimuth_deg, self.elevation_deg, self.distance_m)


def table_closeup(arena: ArenaGeometry = ArenaGeometry()) -> mujoco.MjvCamera:
    """Returns a camera looking down at the table and the docking place in front of it, from the
    front left, steep enough to judge the docked robot's position and heading."""
    x0, x1, y0, _ = arena.table_box
    lookat = (0.5 * (x0 + x1), y0 - 0.35, 0.3)
    return free_camera(lookat, azimuth_deg=20.0, elevation_deg=-62.0, distance_m=2.8)
