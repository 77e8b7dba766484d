"""Model files shipped with the package, and the ArUco textures of the marker plates."""

from __future__ import annotations

import functools
import pathlib

import cv2
import numpy as np
from dm_control import mjcf

from perception import layout

MODELS_DIR = pathlib.Path(__file__).resolve().parent.parent / "models"
if (
    not MODELS_DIR.is_dir()
):  # installed non-editable: the models ship as the peoplebot_models package
    import peoplebot_models

    MODELS_DIR = peoplebot_models.MODELS_DIR

PEOPLEBOT_XML = MODELS_DIR / "peoplebot" / "peoplebot.xml"
ARENA_XML = MODELS_DIR / "arena" / "arena.xml"
TABLE_XML = MODELS_DIR / "arena" / "table.xml"
OBJECT_XML = MODELS_DIR / "arena" / "object.xml"
#: The simulated arena as an arena file (``perception.arenafile``), for ``peoplebot watch``.
ARENA_TOML = MODELS_DIR / "arena" / "arena.toml"
#: The simulated arena's wall landmarks (``perception.landmarks.read_landmark_map``).
LANDMARKS_TOML = MODELS_DIR / "arena" / "landmarks.toml"
#: The overhead camera's registration layout, floor markers (``perception.registration``).
FLOOR_MARKERS_TOML = MODELS_DIR / "arena" / "floor_markers.toml"

#: Texture pixels per marker cell (a 4x4 marker with its border has 6 cells a side).
_PIXELS_PER_CELL = 20


@functools.cache
def marker_png(marker_id: int, size_m: float, quiet_zone_m: float = layout.QUIET_ZONE_M) -> bytes:
    """Returns a PNG of ArUco ``marker_id`` with its white quiet zone, sized for a plate of side
    ``size_m + 2 * quiet_zone_m`` metres."""
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, layout.DICTIONARY_NAME))
    cells = dictionary.markerSize + 2
    side_px = cells * _PIXELS_PER_CELL
    image = cv2.aruco.generateImageMarker(dictionary, int(marker_id), side_px)
    border = int(round(quiet_zone_m / size_m * side_px))
    image = cv2.copyMakeBorder(
        image, border, border, border, border, cv2.BORDER_CONSTANT, value=255
    )
    ok, encoded = cv2.imencode(".png", np.ascontiguousarray(image))
    if not ok:
        raise RuntimeError(f"could not encode marker {marker_id} as PNG")
    return encoded.tobytes()


def marker_texture_asset(
    marker_id: int, size_m: float, quiet_zone_m: float = layout.QUIET_ZONE_M
) -> mjcf.Asset:
    """Returns the PNG of a marker as an in-memory MJCF asset."""
    return mjcf.Asset(contents=marker_png(marker_id, size_m, quiet_zone_m), extension=".png")
