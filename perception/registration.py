"""A fixed camera's pose in the world from markers at known places: the overhead camera's
registration.

Markers laid at surveyed places (a :class:`~perception.landmarks.LandmarkMap`; the simulated
arena's floor layout is ``models/arena/floor_markers.toml``) are photographed once by the camera;
:func:`register_camera` fits the camera's pose to all their corners with its intrinsics held
(OpenCV's SQPnP, refined by Levenberg-Marquardt). What a mount measured by hand leaves (about a
centimetre and a degree) is then replaced by the fit's own error; a focal length error stays, and
the fit moves the camera along its axis to make up for it on the markers' plane.

Frames: world x east, y north, z up (metres); camera axes OpenCV's (``perception.camera``).
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from perception.camera import PinholeCamera
from perception.landmarks import LandmarkMap


@dataclasses.dataclass(frozen=True)
class Registration:
    """A camera's fitted pose.

    Attributes:
      camera: the intrinsics given, at the fitted pose.
      marker_ids: the markers fitted to, ascending.
      rms_error_px: root-mean-square distance of the corners from their fitted projections, pixels.
    """

    camera: PinholeCamera
    marker_ids: tuple[int, ...]
    rms_error_px: float


def register_camera(
    intrinsics: PinholeCamera, found, marker_map: LandmarkMap, *, min_markers: int = 4
) -> Registration:
    """Returns the camera's pose fitted to the corners of the map's markers it sees.

    Args:
      intrinsics: the camera's calibration (its pose is not read).
      found: ``(marker_id, corners_px (4, 2))`` detections in one image, ArUco corner order (e.g.
        ``MarkerDetector.detect_all_corners``); ids not in the map, or found twice, are ignored
        (``LandmarkMap.select``).
      marker_map: where the markers lie.
      min_markers: fewest distinct map markers to fit (4 corners each).

    ValueError names how many markers were seen when they are fewer than ``min_markers``.
    """
    if isinstance(min_markers, bool) or not isinstance(min_markers, int) or min_markers < 1:
        raise ValueError(f"min_markers must be an integer >= 1, got {min_markers!r}")
    seen = marker_map.select(found)
    if len(seen) < min_markers:
        raise ValueError(
            f"registration needs at least {min_markers} of the map's {len(marker_map)} markers in "
            f"view, found {len(seen)} ({[i for i, _ in seen]})"
        )
    world = np.concatenate([marker_map[i].corners_world() for i, _ in seen])
    pixels = np.concatenate([c for _, c in seen])
    matrix = np.asarray(intrinsics.matrix, dtype=float)
    distortion = intrinsics.distortion if intrinsics.distortion.size else None
    ok, rvec, tvec = cv2.solvePnP(world, pixels, matrix, distortion, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:  # pragma: no cover - SQPnP returns a pose for any 3+ points in general position
        raise ValueError("registration failed: the markers' corners admit no camera pose")
    rvec, tvec = cv2.solvePnPRefineLM(world, pixels, matrix, distortion, rvec, tvec)
    rotation_cw, _ = cv2.Rodrigues(rvec)
    projected, _ = cv2.projectPoints(world, rvec, tvec, matrix, distortion)
    residual = projected.reshape(-1, 2) - pixels
    rms = math.sqrt(float(np.mean(np.sum(residual**2, axis=1))))
    camera = intrinsics.with_pose(rotation_cw.T, -rotation_cw.T @ np.ravel(tvec))
    return Registration(camera, tuple(i for i, _ in seen), rms)
