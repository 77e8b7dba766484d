"""The overhead camera's registration photo: the arena with the floor markers laid out and no
robots, seen through the overhead camera (``perception.registration`` fits the camera to it)."""

from __future__ import annotations

import functools

import numpy as np
from dm_control import mjcf

from peoplebot_sim import assets, entities
from peoplebot_sim.rendering import FrameRenderer
from perception.landmarks import LandmarkMap, read_landmark_map


@functools.cache
def floor_markers() -> LandmarkMap:
    """Returns the registration layout (``models/arena/floor_markers.toml``)."""
    return read_landmark_map(assets.FLOOR_MARKERS_TOML)


@functools.cache
def _registration_frame(width: int, height: int) -> np.ndarray:
    walls = read_landmark_map(assets.LANDMARKS_TOML)
    layout = floor_markers()
    if layout.quiet_zone_m != walls.quiet_zone_m:
        raise ValueError(
            f"the floor markers' quiet zone ({layout.quiet_zone_m} m) must be the wall "
            f"landmarks' ({walls.quiet_zone_m} m): the arena prints both alike"
        )
    arena = entities.Arena(
        landmarks=LandmarkMap(walls.markers + layout.markers, quiet_zone_m=walls.quiet_zone_m)
    )
    physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    with FrameRenderer(physics, width, height) as renderer:
        frame = renderer.render("overhead")
    frame.setflags(write=False)
    return frame


def registration_frame(width: int = 320, height: int = 240) -> np.ndarray:
    """Returns the overhead camera's (height, width, 3) uint8 RGB frame of the floor markers,
    rendered as the student's camera frames are (no shadows); read-only, made once per size."""
    return _registration_frame(int(width), int(height))
