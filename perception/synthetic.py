"""Synthetic marker images with known ground truth, for tests and measurements (no simulator).

Each marker of the layout, with its white quiet zone, is warped into the image through the exact
projection of a :class:`~perception.camera.PinholeCamera`, as OpenCV's own ArUco tests do. Rendering
happens at ``supersample`` times the resolution and is then area-averaged, so edges are anti-aliased
the way a real sensor integrates light over a pixel. Only the marker plates are drawn (no robot
bodies); a plate facing away from the camera is not drawn.
"""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from perception.camera import PinholeCamera
from perception.layout import DICTIONARY_NAME, QUIET_ZONE_M, MarkerPlacement, default_layout
from perception.pose import check_planar_pose, robot_to_world

#: Texture pixels per marker cell (a 4x4 marker with its one-cell border is 6 cells wide).
_CELL_PX = 12


def _marker_texture(dictionary, marker_id: int, size_m: float) -> tuple[np.ndarray, float]:
    """Returns the marker with its quiet zone as a gray texture and the texture's pixels per
    metre."""
    cells = dictionary.markerSize + 2
    side_px = cells * _CELL_PX
    marker = cv2.aruco.generateImageMarker(dictionary, int(marker_id), side_px, borderBits=1)
    px_per_m = side_px / size_m
    quiet_px = int(round(QUIET_ZONE_M * px_per_m))
    texture = cv2.copyMakeBorder(
        marker, quiet_px, quiet_px, quiet_px, quiet_px, cv2.BORDER_CONSTANT, value=255
    )
    return texture, px_per_m


def render_markers(
    camera: PinholeCamera,
    robot_poses: Mapping[str, tuple[float, float, float]],
    layout: tuple[MarkerPlacement, ...] = default_layout(),
    *,
    background: int = 90,
    supersample: int = 4,
    noise_std: float = 0.0,
    rng=None,
    faces: tuple[str, ...] | None = None,
) -> np.ndarray:
    """Returns an RGB image, shape (height, width, 3) uint8, of the robots' marker plates.

    Args:
      camera: an ideal camera (no distortion); its pose is the viewpoint.
      robot_poses: robot name -> planar pose ``(x_m, y_m, yaw_rad)``, world frame, robot on the
        floor.
      layout: the marker placements.
      background: gray level of everything that is not a plate.
      supersample: rendering resolution factor before area averaging (>= 1).
      noise_std: standard deviation of additive Gaussian pixel noise, gray levels.
      rng: seed, ``np.random.Generator`` or None; used only when ``noise_std > 0``.
      faces: draw only these faces (default all).
    """
    if np.any(camera.distortion != 0):
        raise ValueError(
            "render_markers supports ideal cameras only (all distortion coefficients 0)"
        )
    if not isinstance(supersample, (int, np.integer)) or supersample < 1:
        raise ValueError(f"supersample must be an integer >= 1, got {supersample!r}")
    unknown = set(robot_poses) - {p.robot for p in layout}
    if unknown:
        raise ValueError(
            f"unknown robots {sorted(unknown)}; allowed: {sorted({p.robot for p in layout})}"
        )
    for robot, pose in robot_poses.items():
        check_planar_pose(pose, f"robot_poses[{robot!r}]")
    rng = np.random.default_rng(rng)
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DICTIONARY_NAME))
    ss = int(supersample)
    width, height = camera.image_size
    canvas = np.full((height * ss, width * ss), float(background), dtype=np.float32)

    plates = []
    for placement in layout:
        if placement.robot not in robot_poses or (
            faces is not None and placement.face not in faces
        ):
            continue
        rotation_wr, position_wr = robot_to_world(*robot_poses[placement.robot])
        centre = rotation_wr @ placement.position_m + position_wr
        normal = rotation_wr @ placement.rotation[:, 2]
        if np.dot(camera.position_world - centre, normal) <= 0:
            continue  # facing away
        depth = float(camera.world_to_camera(centre)[0, 2])
        plates.append((depth, placement, rotation_wr @ placement.rotation, centre))

    for _, placement, rotation_wm, centre in sorted(plates, key=lambda item: -item[0]):
        texture, px_per_m = _marker_texture(dictionary, placement.marker_id, placement.size_m)
        n = texture.shape[0]
        h = 0.5 * n / px_per_m  # half side of the plate with its quiet zone, metres
        local = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
        corners_world = local @ rotation_wm.T + centre
        if np.any(camera.world_to_camera(corners_world)[:, 2] <= 1e-3):
            continue  # crosses the camera plane: not rendered
        pixels = camera.project(corners_world)
        # Supersampled pixel centres: u_ss = ss * (u + 0.5) - 0.5.
        target = (ss * (pixels + 0.5) - 0.5).astype(np.float32)
        source = np.array(
            [[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, n - 0.5], [-0.5, n - 0.5]], dtype=np.float32
        )
        homography = cv2.getPerspectiveTransform(source, target)
        size = (width * ss, height * ss)
        warped = cv2.warpPerspective(
            texture.astype(np.float32),
            homography,
            size,
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
        )
        mask = cv2.warpPerspective(
            np.ones_like(texture, dtype=np.float32),
            homography,
            size,
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
        )
        canvas = canvas * (1.0 - mask) + warped

    image = cv2.resize(canvas, (width, height), interpolation=cv2.INTER_AREA) if ss > 1 else canvas
    if noise_std > 0:
        image = image + rng.normal(0.0, noise_std, image.shape)
    gray = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    return np.repeat(gray[:, :, None], 3, axis=2)


def true_corners(
    camera: PinholeCamera, robot_pose: tuple[float, float, float], placement: MarkerPlacement
) -> np.ndarray:
    """Returns the exact pixel corners, shape (4, 2), TL, TR, BR, BL, of a placed marker's black
    square."""
    check_planar_pose(robot_pose, "robot_pose")
    rotation_wr, position_wr = robot_to_world(*robot_pose)
    corners_world = placement.corners_robot() @ rotation_wr.T + position_wr
    return camera.project(corners_world)
