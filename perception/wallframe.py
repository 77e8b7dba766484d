"""The paper's wall frame (Elshaw et al., Fig. 1): a pose relative to the nearest wall.

The square arena is centred on the world origin, walls parallel to the world axes. Its diagonals split it
into four areas, one per wall; a robot in a wall's area is described by

- ``x``: distance in metres from that wall (0 at the wall, ``half_side`` at the centre);
- ``y``: position in metres along the wall, 0 at its middle, positive to the right of an observer who
  faces the wall from inside the arena;
- ``phi``: heading in degrees relative to facing the wall, in [-180, 180); 0 faces the wall, positive is
  turned counter-clockwise (to the left), +-180 faces away from it.

World frame: x east, y north (towards the ``top`` wall), yaw in radians counter-clockwise from +x.
Points exactly on a diagonal belong to the first of their walls in ``WALL_NAMES`` order.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

WALL_NAMES = ("top", "right", "bottom", "left")

# Outward unit normal of each wall (from the arena centre towards the wall), world frame.
_NORMALS = {
    "top": (0.0, 1.0),
    "right": (1.0, 0.0),
    "bottom": (0.0, -1.0),
    "left": (-1.0, 0.0),
}


_FACING_DEG = {w: math.degrees(math.atan2(n[1], n[0])) for w, n in _NORMALS.items()}


def wrap_degrees(angle_deg):
    """Returns ``angle_deg`` wrapped to [-180, 180)."""
    return (np.asarray(angle_deg, dtype=float) + 180.0) % 360.0 - 180.0


@dataclasses.dataclass(frozen=True)
class ArenaGeometry:
    """A square arena centred on the world origin, with the table against the middle of its top wall.

    The one definition of the arena's and the table's geometry: the world's models, the teacher, the
    success rules and the figures all read it (``tests/test_sim_models.py`` checks the MJCF agrees).

    Attributes:
      side_m: inner side length in metres (wall face to wall face).
      table_width_m: the table's extent along the top wall, metres, centred on the wall's middle.
      table_depth_m: the table's extent out from the top wall, metres.
      table_height_m: the height of the table's top surface, metres.
    """

    side_m: float = 4.0
    table_width_m: float = 1.0
    table_depth_m: float = 0.4
    table_height_m: float = 0.5

    def __post_init__(self):
        for name in ("side_m", "table_width_m", "table_depth_m", "table_height_m"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ValueError(
                    f"{name} must be a positive finite number of metres, got {value!r}"
                )
        if self.table_width_m >= self.side_m or self.table_depth_m >= 0.5 * self.side_m:
            raise ValueError(
                f"the table ({self.table_width_m} x {self.table_depth_m} m) must fit against one "
                f"wall of a {self.side_m} m arena"
            )

    @property
    def half_side_m(self) -> float:
        """Returns the distance in metres from the centre to each wall."""
        return 0.5 * self.side_m

    @property
    def table_box(self) -> tuple[float, float, float, float]:
        """Returns the table's footprint ``(x_min, x_max, y_min, y_max)``, world metres."""
        half_width = 0.5 * self.table_width_m
        return (-half_width, half_width, self.half_side_m - self.table_depth_m, self.half_side_m)

    def clear_of_table(self, x_world: float, y_world: float, margin_m: float) -> bool:
        """Returns whether the world point (metres) lies at least ``margin_m`` outside the table's
        footprint along either axis (a box test, as for a robot's centre with that clearance)."""
        check_finite(x_world=x_world, y_world=y_world, margin_m=margin_m)
        x0, x1, y0, _ = self.table_box
        return not (x0 - margin_m < x_world < x1 + margin_m and y_world > y0 - margin_m)

    def table_gap_m(self, x_world: float, y_world: float) -> float:
        """Returns the distance in metres from the world point to the table's footprint, 0 on or
        inside it (a disc of that radius around the point just touches the table)."""
        check_finite(x_world=x_world, y_world=y_world)
        x0, x1, y0, y1 = self.table_box
        return math.hypot(
            max(x0 - x_world, 0.0, x_world - x1), max(y0 - y_world, 0.0, y_world - y1)
        )


@dataclasses.dataclass(frozen=True)
class WallPose:
    """A pose in the wall frame: ``x_m``, ``y_m`` in metres, ``phi_deg`` in degrees, and the wall."""

    x_m: float
    y_m: float
    phi_deg: float
    wall: str

    def as_array(self) -> np.ndarray:
        """Returns ``[x_m, y_m, phi_deg]`` as float64."""
        return np.array([self.x_m, self.y_m, self.phi_deg], dtype=float)


def check_finite(**values) -> None:
    """Raises ValueError naming the first of ``values`` (name=number) that is not a finite number."""
    for name, value in values.items():
        try:
            finite = math.isfinite(value)
        except TypeError:
            finite = False
        if not finite:
            raise ValueError(f"{name} must be a finite number, got {value!r}")


def _check_wall(wall: str) -> None:
    if wall not in _NORMALS:
        raise ValueError(f"unknown wall {wall!r}; allowed: {', '.join(WALL_NAMES)}")


def nearest_wall(x_world: float, y_world: float) -> str:
    """Returns the name of the wall whose diagonal area holds the world point (metres)."""
    check_finite(x_world=x_world, y_world=y_world)
    best, best_score = WALL_NAMES[0], -math.inf
    for wall in WALL_NAMES:
        nx, ny = _NORMALS[wall]
        score = x_world * nx + y_world * ny
        if score > best_score:
            best, best_score = wall, score
    return best


def world_to_wall(
    x_world: float,
    y_world: float,
    yaw_rad: float,
    arena: ArenaGeometry = ArenaGeometry(),
    wall: str | None = None,
) -> WallPose:
    """Returns the wall-frame pose of a planar world pose.

    Args:
      x_world, y_world: position in metres, world frame.
      yaw_rad: heading in radians, counter-clockwise from world +x.
      arena: the arena's geometry.
      wall: force this wall's frame instead of the nearest one.
    """
    x_world, y_world, yaw_rad = float(x_world), float(y_world), float(yaw_rad)
    if not (math.isfinite(x_world) and math.isfinite(y_world) and math.isfinite(yaw_rad)):
        raise ValueError(f"pose must be finite, got x={x_world!r}, y={y_world!r}, yaw={yaw_rad!r}")
    if wall is None:
        wall = nearest_wall(x_world, y_world)
    _check_wall(wall)
    nx, ny = _NORMALS[wall]
    # Along-wall axis: to the right of an observer facing the wall, i.e. the normal turned by -90 deg.
    tx, ty = ny, -nx
    x_m = arena.half_side_m - (x_world * nx + y_world * ny)
    y_m = x_world * tx + y_world * ty
    phi_deg = (math.degrees(yaw_rad) - _FACING_DEG[wall] + 180.0) % 360.0 - 180.0
    return WallPose(x_m, y_m, phi_deg, wall)


def world_to_wall_batch(
    x_world, y_world, yaw_rad, arena: ArenaGeometry = ArenaGeometry()
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised ``world_to_wall`` over arrays of shape (n,).

    Returns:
      ``x_m, y_m, phi_deg`` (float arrays, shape (n,)) and the wall index into ``WALL_NAMES`` (int).
    """
    x = np.asarray(x_world, dtype=float)
    y = np.asarray(y_world, dtype=float)
    yaw = np.asarray(yaw_rad, dtype=float)
    for name, values in (("x_world", x), ("y_world", y), ("yaw_rad", yaw)):
        if not np.all(np.isfinite(values)):
            raise ValueError(f"{name} must be finite, got {values[~np.isfinite(values)][:3]!r}")
    normals = np.array([_NORMALS[w] for w in WALL_NAMES])
    wall = np.argmax(x[:, None] * normals[:, 0] + y[:, None] * normals[:, 1], axis=1)
    nx, ny = normals[wall, 0], normals[wall, 1]
    x_m = arena.half_side_m - (x * nx + y * ny)
    y_m = x * ny - y * nx
    facing = np.array([_FACING_DEG[w] for w in WALL_NAMES])[wall]
    phi = wrap_degrees(np.degrees(yaw) - facing)
    return x_m, y_m, phi, wall


def wall_to_world(
    pose: WallPose, arena: ArenaGeometry = ArenaGeometry()
) -> tuple[float, float, float]:
    """Returns ``(x_world, y_world, yaw_rad)`` for a wall-frame pose (the inverse of ``world_to_wall``)."""
    _check_wall(pose.wall)
    check_finite(**{f"pose.{name}": getattr(pose, name) for name in ("x_m", "y_m", "phi_deg")})
    nx, ny = _NORMALS[pose.wall]
    tx, ty = ny, -nx
    depth = arena.half_side_m - pose.x_m
    x_world = depth * nx + pose.y_m * tx
    y_world = depth * ny + pose.y_m * ty
    yaw_deg = float(wrap_degrees(pose.phi_deg + np.degrees(np.arctan2(ny, nx))))
    return float(x_world), float(y_world), float(np.radians(yaw_deg))
