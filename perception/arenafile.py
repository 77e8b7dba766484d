"""An arena file: the room a recording was made in, so the wall frame fits a real room of any size.

A small TOML file in metres: the square arena and the table (``ArenaGeometry``'s fields) and,
optionally, where a fixed recording camera hangs (its optical centre and its OpenCV axes in the
world frame: x east, y north, z up; origin at the arena's centre on the floor)::

    side_m = 4.0
    table_width_m = 1.0
    table_depth_m = 0.4
    table_height_m = 0.5

    [camera]
    position_m = [0.0, 0.0, 6.0]
    rotation_world_from_camera = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]

The simulated arena ships as ``models/arena/arena.toml``.
"""

from __future__ import annotations

import dataclasses
import pathlib
import sys

import numpy as np

from perception.camera import check_rotation
from perception.wallframe import ArenaGeometry

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_ARENA_KEYS = tuple(f.name for f in dataclasses.fields(ArenaGeometry))


@dataclasses.dataclass(frozen=True)
class ArenaSetup:
    """An arena and, if given, the fixed recording camera's pose in it (metres; OpenCV axes)."""

    arena: ArenaGeometry
    camera_position_m: tuple | None = None
    camera_rotation: tuple | None = None

    @property
    def has_camera(self) -> bool:
        return self.camera_position_m is not None


def read_arena(path) -> ArenaSetup:
    """Reads an arena file; ValueError naming the file and the key for anything malformed."""
    path = pathlib.Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as error:
        raise ValueError(f"cannot read arena file {path}: {error.strerror or error}") from None
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"arena file {path} is not valid TOML: {error}") from None
    unknown = sorted(set(data) - set(_ARENA_KEYS) - {"camera"})
    if unknown:
        raise ValueError(
            f"arena file {path}: unknown key '{unknown[0]}'; allowed: "
            f"{', '.join(_ARENA_KEYS)}, [camera]"
        )
    values = {}
    for key in _ARENA_KEYS:
        if key in data:
            value = data[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(
                    f"arena file {path}: {key} must be a number of metres, got {value!r}"
                )
            values[key] = float(value)
    try:
        arena = ArenaGeometry(**values)
    except ValueError as error:
        raise ValueError(f"arena file {path}: {error}") from None
    camera = data.get("camera")
    if camera is None:
        return ArenaSetup(arena)
    if not isinstance(camera, dict) or set(camera) != {"position_m", "rotation_world_from_camera"}:
        raise ValueError(
            f"arena file {path}: [camera] must give position_m and rotation_world_from_camera"
        )
    position = np.asarray(camera["position_m"], dtype=float)
    if position.shape != (3,) or not np.all(np.isfinite(position)):
        raise ValueError(f"arena file {path}: camera.position_m must be 3 finite metres")
    try:
        rotation = check_rotation(
            camera["rotation_world_from_camera"], "rotation_world_from_camera"
        )
    except ValueError as error:
        raise ValueError(f"arena file {path}: camera.{error}") from None
    return ArenaSetup(
        arena,
        tuple(float(v) for v in position),
        tuple(tuple(float(v) for v in row) for row in rotation),
    )


def write_arena(path, arena: ArenaGeometry, camera=None) -> pathlib.Path:
    """Writes an arena file (with a fixed camera's pose if ``camera``, a ``PinholeCamera``, is
    given); returns the path."""
    lines = ["# The arena (metres): peoplebot watch --arena reads it."]
    lines += [f"{key} = {float(getattr(arena, key))!r}" for key in _ARENA_KEYS]
    if camera is not None:
        position = ", ".join(repr(float(v)) for v in camera.position_world)
        rows = ", ".join(
            "[" + ", ".join(repr(float(v)) for v in row) + "]"
            for row in camera.rotation_world_from_camera
        )
        lines += [
            "",
            "# The fixed recording camera: optical centre and OpenCV axes in the world frame.",
            "[camera]",
            f"position_m = [{position}]",
            f"rotation_world_from_camera = [{rows}]",
        ]
    path = pathlib.Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path
