"""Image to per-robot poses: detection, planar pose, wall frame and, over time, tracking.

Two viewpoints use the same :class:`Tracker`:

- Overhead (the default): a fixed camera over the arena, posed once; pass it to every call.
- Head camera: the student's pan-tilt camera. Its extrinsics change every frame, and the caller
  builds them from the student's own world pose (overhead tracker or odometry) and the head angles
  with :func:`perception.pantilt.head_camera`; pass ``robots=("teacher",)``. Errors in the student's
  own pose pass straight into the teacher's estimate (they are not modelled in the quality figures).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import numpy as np

from perception.camera import PinholeCamera
from perception.layout import ROBOT_NAMES, MarkerPlacement, default_layout
from perception.markers import DetectorConfig, MarkerDetection, MarkerDetector, to_gray
from perception.pose import (
    RobotPoseEstimate,
    estimate_robot_poses,
    fit_robot_pose,
    initial_pose_from_marker,
    quad_area_px,
)
from perception.tracking import KalmanTrack, TrackEstimate, TrackingConfig
from perception.wallframe import ArenaGeometry, WallPose, world_to_wall

_DETECTOR_CONFIG = DetectorConfig()
_TRACKING_CONFIG = TrackingConfig()
_ARENA = ArenaGeometry()


@dataclasses.dataclass(frozen=True, eq=False)
class FrameResult:
    """What one image shows.

    Attributes:
      poses: robot name -> its pose, for each requested robot with at least one detected marker.
      detections: per-marker records with each marker's own PnP pose, sorted by id, when asked for
        (``Tracker.estimate(..., marker_poses=True)``); empty otherwise, because a robot's pose is
        fitted to all its corners at once and needs no per-marker pose.
    """

    poses: dict[str, RobotPoseEstimate]
    detections: tuple[MarkerDetection, ...] = ()

    def visible_ids(self, robot: str) -> tuple[int, ...]:
        """Returns the ids of ``robot``'s markers used for its pose (empty when not seen)."""
        pose = self.poses.get(robot)
        return () if pose is None else pose.marker_ids


@dataclasses.dataclass(frozen=True, eq=False)
class TrackedRobot:
    """One robot after a tracking step: the filtered track, its wall-frame pose and this frame's
    view.

    Attributes:
      track: the filter's estimate (status "seen", "predicted" or "lost").
      wall: the track's pose in the wall frame; None when lost.
      measurement: this frame's single-image estimate; None when not seen in this frame.
    """

    track: TrackEstimate
    wall: WallPose | None
    measurement: RobotPoseEstimate | None


class Tracker:
    """Finds the robots' markers in images and tracks their planar poses.

    Args:
      detector_config: marker detection settings.
      tracking_config: Kalman filter settings.
      layout: marker placements.
      arena: for wall-frame poses.
      robots: which robots to report (default both).
    """

    def __init__(
        self,
        *,
        detector_config: DetectorConfig = _DETECTOR_CONFIG,
        tracking_config: TrackingConfig = _TRACKING_CONFIG,
        layout: tuple[MarkerPlacement, ...] = default_layout(),
        arena: ArenaGeometry = _ARENA,
        robots: Iterable[str] = ROBOT_NAMES,
    ):
        self.layout = tuple(layout)
        self.arena = arena
        self.robots = tuple(robots)
        known = {p.robot for p in self.layout}
        unknown = [r for r in self.robots if r not in known]
        if unknown:
            raise ValueError(f"unknown robots {unknown}; allowed: {sorted(known)}")
        self.detector = MarkerDetector(detector_config, layout=self.layout)
        self.tracks = {robot: KalmanTrack(robot, tracking_config) for robot in self.robots}
        self.last_frame: FrameResult | None = None

    def _check_robots(self, robots) -> tuple[str, ...]:
        robots = self.robots if robots is None else tuple(robots)
        unknown = [r for r in robots if r not in self.tracks]
        if unknown:
            raise ValueError(f"unknown robots {unknown}; allowed: {list(self.robots)}")
        return robots

    def estimate(
        self,
        image,
        camera: PinholeCamera,
        robots: Iterable[str] | None = None,
        *,
        marker_poses: bool = False,
        predictions: dict | None = None,
        found: list | None = None,
    ) -> FrameResult:
        """Returns the per-robot poses in one image from a full detection (no filtering).

        Args:
          image: (H, W, 3) RGB or (H, W) gray uint8, of the camera's image size.
          camera: the camera with its extrinsics at the time of the image.
          robots: which robots to estimate (default the tracker's).
          marker_poses: also return every marker's own PnP pose (``FrameResult.detections``).
          predictions: robot name -> a predicted ``(x_m, y_m, yaw_rad)`` (a tracker's) to start the
            fit from instead of a marker's PnP pose; a fit from it that misses the corners by more
            than 2 px is redone from the PnP pose.
          found: this image's ``(marker_id, corners_px)`` of every id, from a detection pass
          shared with other users (``MarkerDetector.detect_all_corners`` with the same settings);
          None detects here.

        A robot seen only by its top plate is posed in closed form
        (:func:`~perception.pose.planar_pose_from_horizontal_corners`); one with a side plate in
        view starts from the prediction or its largest marker's PnP pose and is refined over all
        its corners. An id found twice (one of them false) is resolved by the detector's per-marker
        poses.
        """
        robots = self._check_robots(robots)
        gray = self._gray(image, camera)
        found = None if marker_poses else self.detector.detect_corners(gray, found)
        if found is None or len({i for i, _ in found}) < len(found):
            detections = self.detector.detect(gray, camera)
            poses = estimate_robot_poses(
                detections, camera, layout=self.layout, arena=self.arena, robots=robots
            )
            return FrameResult(poses, detections if marker_poses else ())
        return FrameResult(self._fit_robots(found, camera, robots, predictions))

    def _gray(self, image, camera: PinholeCamera) -> np.ndarray:
        gray = to_gray(image)
        if (gray.shape[1], gray.shape[0]) != camera.image_size:
            raise ValueError(
                f"image size (width, height) {(gray.shape[1], gray.shape[0])} does not "
                f"match the camera's image_size {camera.image_size}"
            )
        return gray

    def _fit_robots(self, found, camera, robots, predictions) -> dict[str, RobotPoseEstimate]:
        """Returns robot -> pose fitted to its markers' corners in ``found`` (unique ids)."""
        poses = {}
        for robot in robots:
            mine = sorted(
                (m for m in found if self.detector.placement(m[0]).robot == robot),
                key=lambda m: m[0],
            )
            if not mine:
                continue
            if all(self.detector.placement(i).rotation[2, 2] > 0.999 for i, _ in mine):
                poses[robot] = fit_robot_pose(
                    mine, camera, robot, None, layout=self.layout, arena=self.arena
                )
                continue
            predicted = None if predictions is None else predictions.get(robot)
            if predicted is not None:
                try:
                    pose = fit_robot_pose(
                        mine, camera, robot, predicted, layout=self.layout, arena=self.arena
                    )
                except ValueError:  # the prediction puts a corner behind the camera
                    pose = None
                if pose is not None and pose.reprojection_error_px <= 2.0:
                    poses[robot] = pose
                    continue
            initial = self._initial_from_largest_marker(mine, camera)
            if initial is not None:
                poses[robot] = fit_robot_pose(
                    mine, camera, robot, initial, layout=self.layout, arena=self.arena
                )
        return poses

    def _initial_from_largest_marker(self, mine, camera: PinholeCamera) -> np.ndarray | None:
        """Returns a starting pose from the largest marker whose PnP succeeds, or None."""
        for marker_id, corners in sorted(mine, key=lambda m: -quad_area_px(m[1])):
            detection = self.detector.marker_pose(marker_id, corners, camera)
            if detection is not None:
                placement = self.detector.placement(marker_id)
                return initial_pose_from_marker(detection, placement, camera)
        return None

    def update(
        self,
        image,
        camera: PinholeCamera,
        time_s: float,
        robots: Iterable[str] | None = None,
        found: list | None = None,
    ) -> dict[str, TrackedRobot]:
        """Estimates the robots in ``image`` and advances their tracks to ``time_s`` (seconds);
        ``found``: a shared detection pass (see :meth:`estimate`).

        Every robot in ``robots`` (default the tracker's) gets a step: fused if seen, predicted if
        not, lost after the coast time. A robot seen by a side plate is fitted from its track's
        prediction when it has one (no per-marker PnP).
        """
        robots = self._check_robots(robots)
        predictions = {robot: self.tracks[robot].predict_pose(time_s) for robot in robots}
        frame = self.estimate(image, camera, robots, predictions=predictions, found=found)
        self.last_frame = frame
        out = {}
        for robot in robots:
            measurement = frame.poses.get(robot)
            track = self.tracks[robot].step(time_s, measurement)
            wall = None if track.pose is None else world_to_wall(*track.pose, self.arena)
            out[robot] = TrackedRobot(track, wall, measurement)
        return out
