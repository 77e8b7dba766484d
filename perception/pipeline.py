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

from perception.camera import PinholeCamera
from perception.layout import ROBOT_NAMES, MarkerPlacement, default_layout
from perception.markers import DetectorConfig, MarkerDetection, MarkerDetector
from perception.pose import RobotPoseEstimate, estimate_robot_poses
from perception.tracking import KalmanTrack, TrackEstimate, TrackingConfig
from perception.wallframe import ArenaGeometry, WallPose, world_to_wall

_DETECTOR_CONFIG = DetectorConfig()
_TRACKING_CONFIG = TrackingConfig()
_ARENA = ArenaGeometry()


@dataclasses.dataclass(frozen=True, eq=False)
class FrameResult:
    """What one image shows.

    Attributes:
      detections: every expected marker detected, sorted by id.
      poses: robot name -> its pose, for each requested robot with at least one detected marker.
    """

    detections: tuple[MarkerDetection, ...]
    poses: dict[str, RobotPoseEstimate]

    def visible_ids(self, robot: str) -> tuple[int, ...]:
        """Returns the ids of ``robot``'s detected markers."""
        return tuple(d.marker_id for d in self.detections if d.robot == robot)


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

    def _check_robots(self, robots) -> tuple[str, ...]:
        robots = self.robots if robots is None else tuple(robots)
        unknown = [r for r in robots if r not in self.tracks]
        if unknown:
            raise ValueError(f"unknown robots {unknown}; allowed: {list(self.robots)}")
        return robots

    def estimate(
        self, image, camera: PinholeCamera, robots: Iterable[str] | None = None
    ) -> FrameResult:
        """Returns the detections and per-robot poses in one image (no filtering).

        Args:
          image: (H, W, 3) RGB or (H, W) gray uint8, of the camera's image size.
          camera: the camera with its extrinsics at the time of the image.
          robots: which robots to estimate (default the tracker's).
        """
        robots = self._check_robots(robots)
        detections = self.detector.detect(image, camera)
        poses = estimate_robot_poses(
            detections, camera, layout=self.layout, arena=self.arena, robots=robots
        )
        return FrameResult(detections, poses)

    def update(
        self, image, camera: PinholeCamera, time_s: float, robots: Iterable[str] | None = None
    ) -> dict[str, TrackedRobot]:
        """Estimates the robots in ``image`` and advances their tracks to ``time_s`` (seconds).

        Every robot in ``robots`` (default the tracker's) gets a step: fused if seen, predicted if
        not, lost after the coast time.
        """
        robots = self._check_robots(robots)
        frame = self.estimate(image, camera, robots)
        out = {}
        for robot in robots:
            measurement = frame.poses.get(robot)
            track = self.tracks[robot].step(time_s, measurement)
            wall = None if track.pose is None else world_to_wall(*track.pose, self.arena)
            out[robot] = TrackedRobot(track, wall, measurement)
        return out
