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
from collections.abc import Iterable

import numpy as np

from perception.camera import PinholeCamera
from perception.layout import MarkerPlacement, default_layout
from perception.markers import MarkerDetection
from perception.wallframe import ArenaGeometry, WallPose, world_to_wall

_ARENA = ArenaGeometry()


def wrap_radians(angle_rad):
    """Returns ``angle_rad`` wrapped to [-pi, pi)."""
    return (np.asarray(angle_rad, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def robot_to_world(x_m: float, y_m: float, yaw_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Returns ``(rotation_world_from_robot (3, 3), position_world (3,))`` of a level robot on the
    floor."""
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


def _initial_guess(
    detection: MarkerDetection, placement: MarkerPlacement, camera: PinholeCamera
) -> np.ndarray:
    rotation_wm = camera.rotation_world_from_camera @ detection.rotation_camera_from_marker
    position_wm = camera.camera_to_world(detection.position_camera_m)[0]
    rotation_wr = rotation_wm @ placement.rotation.T
    # Yaw of the robot's x axis; for a top marker seen nearly head-on its in-plane axes are
    # reliable.
    yaw = float(np.arctan2(rotation_wr[1, 0], rotation_wr[0, 0]))
    rotation_level, _ = robot_to_world(0.0, 0.0, yaw)
    origin = position_wm - rotation_level @ placement.position_m
    return np.array([origin[0], origin[1], yaw])


def _residuals(
    params: np.ndarray, corners_robot: np.ndarray, observed: np.ndarray, camera: PinholeCamera
) -> np.ndarray:
    rotation, position = robot_to_world(*params)
    predicted = camera.project(corners_robot @ rotation.T + position)
    return (predicted - observed).ravel()


def _jacobian(params, corners_robot, observed, camera, step=(1e-5, 1e-5, 1e-6)) -> np.ndarray:
    columns = []
    for k, h in enumerate(step):
        delta = np.zeros(3)
        delta[k] = h
        plus = _residuals(params + delta, corners_robot, observed, camera)
        minus = _residuals(params - delta, corners_robot, observed, camera)
        columns.append((plus - minus) / (2.0 * h))
    return np.column_stack(columns)


def fit_planar_pose(
    initial: np.ndarray,
    corners_robot: np.ndarray,
    observed_px: np.ndarray,
    camera: PinholeCamera,
    *,
    iterations: int = 20,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Returns ``(params, residuals, jacobian)`` of a Levenberg-Marquardt fit of ``(x, y, yaw)``.

    Minimises ``sum |project(R(yaw) c + (x, y, 0)) - observed|^2`` over the corners ``c``.

    Args:
      initial: starting ``(x_m, y_m, yaw_rad)``, shape (3,).
      corners_robot: corner positions in the robot frame, metres, shape (N, 3).
      observed_px: detected pixels, shape (N, 2).
      camera: the camera with its extrinsics.
      iterations: the most Levenberg-Marquardt steps.
    """
    params = np.asarray(initial, dtype=float).copy()
    r = _residuals(params, corners_robot, observed_px, camera)
    if not np.all(np.isfinite(r)):
        raise ValueError("initial pose puts corners behind the camera")
    cost = float(r @ r)
    damping = 1e-3
    for _ in range(iterations):
        jac = _jacobian(params, corners_robot, observed_px, camera)
        normal = jac.T @ jac
        gradient = jac.T @ r
        improved = False
        for _ in range(10):
            step = np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-12), -gradient)
            trial = params + step
            r_trial = _residuals(trial, corners_robot, observed_px, camera)
            cost_trial = float(r_trial @ r_trial) if np.all(np.isfinite(r_trial)) else np.inf
            if cost_trial <= cost:
                params, r, damping, improved = trial, r_trial, max(damping / 10.0, 1e-9), True
                converged = cost - cost_trial < 1e-12 * max(cost, 1e-12) or np.all(
                    np.abs(step) < (1e-8, 1e-8, 1e-9)
                )
                cost = cost_trial
                break
            damping *= 10.0
        if not improved or converged:
            break
    params[2] = float(wrap_radians(params[2]))
    return params, r, _jacobian(params, corners_robot, observed_px, camera)


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
    initial = _initial_guess(largest, by_id[largest.marker_id], camera)
    corners_robot = np.concatenate([by_id[d.marker_id].corners_robot() for d in mine])
    observed = np.concatenate([d.corners_px for d in mine])
    params, residuals, jac = fit_planar_pose(initial, corners_robot, observed, camera)
    rms = float(np.sqrt(np.mean(residuals.reshape(-1, 2) ** 2) * 2.0))
    sigma = max(rms, pixel_noise_px)
    covariance = sigma**2 * np.linalg.pinv(jac.T @ jac)
    x, y, yaw = (float(v) for v in params)
    return RobotPoseEstimate(
        robot=robot,
        x_m=x,
        y_m=y,
        yaw_rad=yaw,
        wall=world_to_wall(x, y, yaw, arena),
        reprojection_error_px=rms,
        marker_ids=tuple(sorted(d.marker_id for d in mine)),
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
