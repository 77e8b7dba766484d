"""How the room may look other than the nominal arena: lighting, shadows and surface colours, for
transfer tests of the student's cameras. Applied to the arena's MJCF before it is compiled; a
record of defaults changes nothing.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

#: The colour floor and walls are blended toward by ``surface_tint_fraction``: a dark wood, RGB 0-1.
WOOD_RGB = (0.45, 0.30, 0.18)


@dataclasses.dataclass(frozen=True)
class Appearance:
    """The room's appearance (0 / False: the nominal arena).

    Attributes:
      light_fraction: every light's diffuse intensity (sun, fill, headlight) relative to the
        model's, minus 1 (-0.5: half as bright).
      light_tilt_deg: the sun's direction turned away from its model direction about the world y
        axis, degrees (long, low shadows).
      shadows: the student's cameras render shadows (the nominal cameras do not).
      surface_tint_fraction: floor and wall colours blended toward ``WOOD_RGB`` (0 to 1).
    """

    light_fraction: float = 0.0
    light_tilt_deg: float = 0.0
    shadows: bool = False
    surface_tint_fraction: float = 0.0

    def __post_init__(self):
        for name in ("light_fraction", "light_tilt_deg", "surface_tint_fraction"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (
                isinstance(value, (int, float)) and math.isfinite(value)
            ):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
        if not self.light_fraction > -1:
            raise ValueError(f"light_fraction must be greater than -1, got {self.light_fraction!r}")
        if not -80 <= self.light_tilt_deg <= 80:
            raise ValueError(
                f"light_tilt_deg must be in [-80, 80] degrees, got {self.light_tilt_deg!r}"
            )
        if not 0 <= self.surface_tint_fraction <= 1:
            raise ValueError(
                f"surface_tint_fraction must be in [0, 1], got {self.surface_tint_fraction!r}"
            )
        if not isinstance(self.shadows, bool):
            raise ValueError(f"shadows must be true or false, got {self.shadows!r}")

    @property
    def active(self) -> bool:
        return self != Appearance()


def apply_appearance(arena_mjcf, appearance: Appearance) -> None:
    """Changes the arena's MJCF (lights, headlight, floor texture, wall material) to
    ``appearance``; shadows are the cameras' render flag (``ImitationTask``)."""
    if not appearance.active:
        return
    scale = 1.0 + appearance.light_fraction
    if appearance.light_fraction:
        for light in arena_mjcf.find_all("light"):
            light.diffuse = np.asarray(light.diffuse, float) * scale
        headlight = arena_mjcf.visual.headlight
        headlight.diffuse = np.asarray(headlight.diffuse, float) * scale
        headlight.ambient = np.asarray(headlight.ambient, float) * scale
    if appearance.light_tilt_deg:
        sun = arena_mjcf.find("light", "sun")
        a = math.radians(appearance.light_tilt_deg)
        turn = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
        sun.dir = turn @ np.asarray(sun.dir, float)
    t = appearance.surface_tint_fraction
    if t:
        wood = np.asarray(WOOD_RGB)
        floor = arena_mjcf.find("texture", "floor")
        for name in ("rgb1", "rgb2", "markrgb"):
            setattr(floor, name, (1 - t) * np.asarray(getattr(floor, name), float) + t * wood)
        wall = arena_mjcf.find("material", "wall")
        rgba = np.asarray(wall.rgba, float)
        wall.rgba = np.r_[(1 - t) * rgba[:3] + t * wood, rgba[3]]
