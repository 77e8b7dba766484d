"""From detected markers to a robot's planar pose in the world and in the paper's wall frame.

The robots stand level on the floor, so a robot's pose has three degrees of freedom: ``x_m``,
``y_m`` (metres, world frame, the robot frame's origin: the centre of rotation on the floor) and
``yaw_rad`` (radians, counter-clockwise from world +x). Each detected corner of the robot's markers,
whose position in the robot frame the layout gives, constrains them.

1. Initial guess: from the largest detected marker's IPPE pose, the marker's pose in the world
   (camera extrinsics) composed with the layout's robot-from-marker transform, keeping only its yaw
   and the floor position (the level constraint removes the lever-arm error of a tilted estimate).
2. Refinement: Levenberg-Marquardt over ``(x, y, yaw)`` minimising the pixel reprojection error of
   all visible corners of the robot's markers, with z = 0 and zero roll and pitch held fixed.

The quality figures are the RMS corner reprojection error after the fit, the number of markers and
corners, and a covariance of ``(x, y, yaw)`` from the fit's Jacobian.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import cv2
import numpy as np

from perception.camera import PinholeCamera
from perception.layout import MarkerPlacement, default_layout
from perception.markers import MarkerDetection
from perception.wallframe import ArenaGeometry, WallPose, world_to_wall

_ARENA = ArenaGeometry()
_DIAGONAL = np.diag_indices(3)


def wrap_radians(angle_rad):
    """Returns ``angle_rad`` wrapped to [-pi, pi)."""
    return (np.asarray(angle_rad, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def check_planar_pose(pose, name: str = "pose") -> tuple[float, float, float]:
    """Returns ``pose`` ``(x_m, y_m, yaw_rad)`` as three floats; raises ValueError naming ``name``
    unless it is three finite numbers."""
    try:
        values = np.asarray(pose, dtype=float)
    except (TypeError, ValueError):
        values = np.empty(0)
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise ValueError(f"{name} must be three finite numbers (x_m, y_m, yaw_rad), got {pose!r}")
    x, y, yaw = values.tolist()
    return x, y, yaw


def robot_to_world(x_m: float, y_m: float, yaw_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Returns ``(rotation_world_from_robot (3, 3), position_world (3,))`` of a level robot on the
    floor."""
    if not (math.isfinite(x_m) and math.isfinite(y_m) and math.isfinite(yaw_rad)):
        raise ValueError(
            f"x_m, y_m and yaw_rad must be finite numbers, got {x_m!r}, {y_m!r}, {yaw_rad!r}"
        )
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return rotation, np.array([x_m, y_m, 0.0])


@dataclasses.dataclass(frozen=True, eq=False)
class RobotPoseEstimate:
    """One robot's planar pose from one image.

    Attributes:
      robot: its name.
      x_m, y_m: position in metres, world frame.
      yaw_rad: heading in radians, counter-clockwise from world +x, in [-pi, pi).
      wall: the same pose in the paper's wall frame (nearest wall).
      reprojection_error_px: RMS distance between detected and model corners after the fit, pixels.
      marker_ids: ids of the markers used, sorted.
      n_corners: number of corners used (4 per marker).
      covariance: covariance of ``(x_m, y_m, yaw_rad)``, shape (3, 3), assuming independent corner
        noise of ``max(reprojection_error_px, pixel_noise_px)``.
    """

    robot: str
    x_m: float
    y_m: float
    yaw_rad: float
    wall: WallPose
    reprojection_error_px: float
    marker_ids: tuple[int, ...]
    n_corners: int
    covariance: np.ndarray

    def as_array(self) -> np.ndarray:
        """Returns ``[x_m, y_m, yaw_rad]`` as float64."""
        return np.array([self.x_m, self.y_m, self.yaw_rad])


def initial_pose_from_marker(
    detection: MarkerDetection, placement: MarkerPlacement, camera: PinholeCamera
) -> np.ndarray:
    """Returns a starting ``(x_m, y_m, yaw_rad)`` for the fit from one marker's own PnP pose: its
    yaw and floor position only (the level constraint removes a tilted estimate's lever-arm
    error)."""
    rotation_wm = camera.rotation_world_from_camera @ detection.rotation_camera_from_marker
    position_wm = camera.camera_to_world(detection.position_camera_m)[0]
    rotation_wr = rotation_wm @ placement.rotation.T
    # Yaw of the robot's x axis; for a top marker seen nearly head-on its in-plane axes are
    # reliable.
    yaw = float(np.arctan2(rotation_wr[1, 0], rotation_wr[0, 0]))
    rotation_level, _ = robot_to_world(0.0, 0.0, yaw)
    origin = position_wm - rotation_level @ placement.position_m
    return np.array([origin[0], origin[1], yaw])


def _normalised_observations(observed_px: np.ndarray, camera: PinholeCamera) -> np.ndarray:
    """Returns the observed pixels as undistorted normalised image coordinates, shape (N, 2)."""
    if camera.distortion.size and camera.distortion.any():
        return cv2.undistortPoints(
            np.ascontiguousarray(observed_px, dtype=float).reshape(-1, 1, 2),
            camera.matrix,
            camera.distortion,
        ).reshape(-1, 2)
    k = camera.matrix
    out = np.subtract(observed_px, (k[0, 2], k[1, 2]))
    out[:, 1] /= k[1, 1]
    if k[0, 1]:
        out[:, 0] -= k[0, 1] * out[:, 1]
    out[:, 0] /= k[0, 0]
    return out


class _Projection:
    """The pinhole constants of one fit, computed once: camera-from-world rotation and translation
    and the focal lengths."""

    def __init__(self, camera: PinholeCamera):
        self.r_cw = camera.rotation_world_from_camera.T
        self.t_cw = -self.r_cw @ camera.position_world
        self.focal = np.array([camera.matrix[0, 0], camera.matrix[1, 1]])
        self.d_planar = self.r_cw[:, :2]  # d p_camera / d (x, y)


def _residuals_and_jacobian(
    params: np.ndarray, corners_robot: np.ndarray, observed_n: np.ndarray, proj: _Projection
) -> tuple[np.ndarray, np.ndarray]:
    """Returns the reprojection residuals in pixels, shape (2N,), and their analytic Jacobian with
    respect to ``(x, y, yaw)``, shape (2N, 3); NaN residuals for corners behind the camera.

    Residuals are taken in undistorted normalised coordinates and scaled by the focal lengths.
    """
    x, y, yaw = (float(v) for v in params)
    c, s = math.cos(yaw), math.sin(yaw)
    # Rows of R_cw @ R(yaw) and of R_cw @ dR/dyaw, from R(yaw)'s two non-trivial columns.
    r_cw = proj.r_cw
    a, b = r_cw[:, 0], r_cw[:, 1]
    rotated = np.column_stack([c * a + s * b, c * b - s * a, r_cw[:, 2]])
    d_rotated = np.column_stack([c * b - s * a, -(c * a + s * b)])
    p = corners_robot @ rotated.T + (x * a + y * b + proj.t_cw)
    dp_yaw = corners_robot[:, :2] @ d_rotated.T
    z = p[:, 2:3]
    if z.min() <= 1e-9:
        z = np.where(z > 1e-9, z, np.nan)
    uv = p[:, :2] / z
    residuals = (uv - observed_n) * proj.focal
    jacobian = np.empty((len(p), 2, 3))
    # d(uv)/dq = (dp_xy/dq - uv * dp_z/dq) / z, for q in x, y (constant dp) and yaw.
    jacobian[:, :, :2] = (proj.d_planar[None, :2, :] - uv[:, :, None] * proj.d_planar[2]) / z[
        :, :, None
    ]
    jacobian[:, :, 2] = (dp_yaw[:, :2] - uv * dp_yaw[:, 2:3]) / z
    jacobian *= proj.focal[None, :, None]
    return residuals.ravel(), jacobian.reshape(-1, 3)


def fit_planar_pose(
    initial: np.ndarray,
    corners_robot: np.ndarray,
    observed_px: np.ndarray,
    camera: PinholeCamera,
    *,
    iterations: int = 20,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Returns ``(params, residuals, jacobian)`` of a Levenberg-Marquardt fit of ``(x, y, yaw)``.

    Minimises ``sum |project(R(yaw) c + (x, y, 0)) - observed|^2`` over the corners ``c``, with the
    analytic Jacobian of the pinhole projection (residuals in pixels).

    Args:
      initial: starting ``(x_m, y_m, yaw_rad)``, shape (3,).
      corners_robot: corner positions in the robot frame, metres, shape (N, 3).
      observed_px: detected pixels, shape (N, 2).
      camera: the camera with its extrinsics.
      iterations: the most Levenberg-Marquardt steps.
    """
    check_planar_pose(initial, "initial")
    observed_n = _normalised_observations(np.asarray(observed_px, dtype=float), camera)
    return _fit_normalised(
        initial, np.asarray(corners_robot, dtype=float), observed_n, _Projection(camera), iterations
    )


def _fit_normalised(
    initial, corners_robot: np.ndarray, observed_n: np.ndarray, proj: _Projection, iterations: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`fit_planar_pose` from normalised image coordinates."""
    params = np.asarray(initial, dtype=float).copy()
    r, jac = _residuals_and_jacobian(params, corners_robot, observed_n, proj)
    if not np.all(np.isfinite(r)):
        raise ValueError("initial pose puts corners behind the camera")
    cost = float(r @ r)
    damping = 1e-6
    for _ in range(iterations):
        normal = jac.T @ jac
        gradient = jac.T @ r
        diagonal = normal.diagonal() + 1e-12
        improved = converged = False
        for _ in range(10):
            damped = normal.copy()
            damped[_DIAGONAL] += damping * diagonal
            step = np.linalg.solve(damped, -gradient)
            trial = params + step
            r_trial, jac_trial = _residuals_and_jacobian(trial, corners_robot, observed_n, proj)
            cost_trial = float(r_trial @ r_trial)
            if cost_trial <= cost:  # False for NaN (a corner behind the camera)
                # 0.1 mm and 0.1 mrad: far below what a pixel resolves (5 mm at 3 m, 320 px).
                converged = cost - cost_trial < 1e-9 * max(cost, 1e-12) or np.abs(step).max() < 1e-4
                params, r, jac, cost = trial, r_trial, jac_trial, cost_trial
                damping, improved = max(damping / 10.0, 1e-9), True
                break
            damping *= 10.0
        if not improved or converged:
            break
    params[2] = float(wrap_radians(params[2]))
    return params, r, jac


def estimate_robot_pose(
    detections: Iterable[MarkerDetection],
    camera: PinholeCamera,
    robot: str,
    *,
    layout: tuple[MarkerPlacement, ...] = default_layout(),
    arena: ArenaGeometry = _ARENA,
    pixel_noise_px: float = 0.3,
) -> RobotPoseEstimate | None:
    """Returns the planar pose of ``robot`` from its detected markers, or None if none was detected.

    Args:
      detections: detections from :meth:`MarkerDetector.detect` (other robots' are ignored).
      camera: the camera the detections came from, with the extrinsics used to detect them.
      robot: which robot.
      layout: where each marker id sits on the robot.
      arena: for the wall-frame pose.
      pixel_noise_px: the smallest corner noise assumed for the covariance, pixels.
    """
    by_id = {p.marker_id: p for p in layout}
    if robot not in {p.robot for p in layout}:
        raise ValueError(f"unknown robot {robot!r}; allowed: {sorted({p.robot for p in layout})}")
    mine = [d for d in detections if d.robot == robot]
    if not mine:
        return None
    for d in mine:
        if d.marker_id not in by_id:
            raise ValueError(
                f"marker id {d.marker_id} is not in the layout; allowed: {sorted(by_id)}"
            )
    largest = max(mine, key=lambda d: d.area_px())
    initial = initial_pose_from_marker(largest, by_id[largest.marker_id], camera)
    return fit_robot_pose(
        [(d.marker_id, d.corners_px) for d in mine],
        camera,
        robot,
        initial,
        layout=layout,
        arena=arena,
        pixel_noise_px=pixel_noise_px,
    )


def quad_area_px(corners_px: np.ndarray) -> float:
    """Returns the area of a corner quadrilateral, shape (4, 2), in square pixels (half the cross
    product of its diagonals)."""
    (x0, y0), (x1, y1), (x2, y2), (x3, y3) = np.asarray(corners_px, dtype=float).tolist()
    return 0.5 * abs((x2 - x0) * (y3 - y1) - (x3 - x1) * (y2 - y0))


def planar_pose_from_horizontal_corners(
    corners_robot: np.ndarray, observed_px: np.ndarray, camera: PinholeCamera
) -> np.ndarray:
    """Returns ``(x_m, y_m, yaw_rad)`` in closed form from corners of horizontal plates.

    Each pixel's ray is cut with the horizontal plane of its corner (the plate's known height), and
    the robot-frame corners are fitted to those floor-plane points by a 2-D rigid least-squares
    (Kabsch) fit. Exact for noise-free corners; needs no starting pose.

    Args:
      corners_robot: corner positions in the robot frame, metres, shape (N, 3), N >= 2.
      observed_px: their pixels, shape (N, 2).
      camera: the camera with its extrinsics.
    """
    normalised = _normalised_observations(np.asarray(observed_px, dtype=float), camera)
    return _horizontal_fit(np.asarray(corners_robot, dtype=float), normalised, camera)


def _horizontal_fit(
    corners_robot: np.ndarray, normalised: np.ndarray, camera: PinholeCamera
) -> np.ndarray:
    """:func:`planar_pose_from_horizontal_corners` from normalised image coordinates."""
    r_wc = camera.rotation_world_from_camera
    rays = normalised @ r_wc[:, :2].T + r_wc[:, 2]
    origin = camera.position_world
    rise = corners_robot[:, 2] - origin[2]
    if not np.all(rise * rays[:, 2] > 0):  # also false for NaN or a ray parallel to the plane
        raise ValueError("a corner's ray does not reach its plate's height in front of the camera")
    points = origin[:2] + (rise / rays[:, 2])[:, None] * rays[:, :2]
    scale = 1.0 / len(points)
    local = corners_robot[:, :2]
    local_mean, points_mean = local.sum(axis=0) * scale, points.sum(axis=0) * scale
    (h00, h01), (h10, h11) = ((local - local_mean).T @ (points - points_mean)).tolist()
    yaw = math.atan2(h01 - h10, h00 + h11)
    c, s = math.cos(yaw), math.sin(yaw)
    lx, ly = local_mean.tolist()
    px, py = points_mean.tolist()
    return np.array([px - (c * lx - s * ly), py - (s * lx + c * ly), yaw])


def fit_robot_pose(
    corners: Iterable[tuple[int, np.ndarray]],
    camera: PinholeCamera,
    robot: str,
    initial,
    *,
    layout: tuple[MarkerPlacement, ...] = default_layout(),
    arena: ArenaGeometry = _ARENA,
    pixel_noise_px: float = 0.3,
    iterations: int = 20,
) -> RobotPoseEstimate:
    """Returns the planar pose of ``robot`` fitted to detected marker corners from a starting pose.

    A tracker that predicts the pose passes its prediction as ``initial`` and skips the per-marker
    PnP of :func:`estimate_robot_pose`.

    Args:
      corners: ``(marker_id, corners_px (4, 2))`` of the robot's detected markers (TL, TR, BR, BL).
      camera: the camera with its extrinsics.
      robot: which robot.
      initial: starting ``(x_m, y_m, yaw_rad)`` (unused, may be None, when every marker is a top
        plate).
      layout, arena, pixel_noise_px: as for :func:`estimate_robot_pose`.
      iterations: the most Levenberg-Marquardt steps (from a tracker's prediction, a few suffice);
        when every marker is a horizontal (top) plate the closed-form
        :func:`planar_pose_from_horizontal_corners` replaces the iterations.
    """
    by_id = {p.marker_id: p for p in layout}
    corners = list(corners)
    for marker_id, _ in corners:
        if marker_id not in by_id or by_id[marker_id].robot != robot:
            raise ValueError(f"marker id {marker_id} is not one of {robot!r}'s in the layout")
    corners_robot = np.concatenate([by_id[i].corners_robot() for i, _ in corners])
    observed = np.concatenate([np.asarray(c, dtype=float).reshape(4, 2) for _, c in corners])
    observed_n = _normalised_observations(observed, camera)
    if all(by_id[i].rotation[2, 2] > 0.999 for i, _ in corners):
        # Only top plates: the closed-form floor-plane fit is already the answer.
        initial = _horizontal_fit(corners_robot, observed_n, camera)
        iterations = 0
    else:
        check_planar_pose(initial, "initial")
    params, residuals, jac = _fit_normalised(
        initial, corners_robot, observed_n, _Projection(camera), iterations
    )
    rms = math.sqrt(float(residuals @ residuals) * 2.0 / len(residuals))
    sigma = max(rms, pixel_noise_px)
    information = jac.T @ jac
    try:  # four or more corners always constrain all three; pinv only for a degenerate view
        covariance = sigma**2 * np.linalg.inv(information)
    except np.linalg.LinAlgError:
        covariance = sigma**2 * np.linalg.pinv(information)
    x, y, yaw = (float(v) for v in params)
    return RobotPoseEstimate(
        robot=robot,
        x_m=x,
        y_m=y,
        yaw_rad=yaw,
        wall=world_to_wall(x, y, yaw, arena),
        reprojection_error_px=rms,
        marker_ids=tuple(sorted(i for i, _ in corners)),
        n_corners=len(observed),
        covariance=covariance,
    )


def estimate_robot_poses(
    detections: Iterable[MarkerDetection],
    camera: PinholeCamera,
    *,
    layout: tuple[MarkerPlacement, ...] = default_layout(),
    arena: ArenaGeometry = _ARENA,
    robots: Iterable[str] | None = None,
    pixel_noise_px: float = 0.3,
) -> dict[str, RobotPoseEstimate]:
    """Returns robot name -> pose for every robot (of ``robots``, default all) with a detected
    marker."""
    detections = tuple(detections)
    names = sorted({p.robot for p in layout}) if robots is None else list(robots)
    out = {}
    for name in names:
        estimate = estimate_robot_pose(
            detections, camera, name, layout=layout, arena=arena, pixel_noise_px=pixel_noise_px
        )
        if estimate is not None:
            out[name] = estimate
    return out
