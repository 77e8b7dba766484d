"""Perception: what the student sees.

Marker tracking (OpenCV ArUco), camera geometry and the paper's wall frame. Pure numpy and OpenCV:
this package never imports mujoco or dm_control, so it runs unchanged on a real robot's images.
"""

from perception.wallframe import (
    WALL_NAMES,
    ArenaGeometry,
    WallPose,
    wall_to_world,
    world_to_wall,
    wrap_degrees,
)

__all__ = [
    "WALL_NAMES",
    "ArenaGeometry",
    "WallPose",
    "wall_to_world",
    "world_to_wall",
    "wrap_degrees",
]
