"""Perception: what the student sees.

Marker tracking (OpenCV ArUco), camera geometry and the paper's wall frame. Pure numpy and OpenCV:
this package never imports mujoco or dm_control, so it runs unchanged on a real robot's images.
"""

from perception.camera import PinholeCamera, look_at_rotation
from perception.markers import DetectorConfig, MarkerDetection, MarkerDetector
from perception.motion import (
    DIRECTIVES,
    DirectiveAgreement,
    DirectiveConfig,
    directive_agreement,
    infer_directive,
    infer_directives,
)
from perception.pantilt import (
    HeadMount,
    PanTiltCommand,
    PanTiltController,
    PanTiltLimits,
    aim_at,
    head_camera,
)
from perception.pipeline import FrameResult, TrackedRobot, Tracker
from perception.pose import RobotPoseEstimate, estimate_robot_pose, estimate_robot_poses
from perception.tracking import TRACK_STATUSES, KalmanTrack, TrackEstimate, TrackingConfig
from perception.wallframe import (
    WALL_NAMES,
    ArenaGeometry,
    WallPose,
    wall_to_world,
    world_to_wall,
    wrap_degrees,
)

__all__ = [
    "DIRECTIVES",
    "TRACK_STATUSES",
    "WALL_NAMES",
    "ArenaGeometry",
    "DetectorConfig",
    "DirectiveAgreement",
    "DirectiveConfig",
    "FrameResult",
    "HeadMount",
    "KalmanTrack",
    "MarkerDetection",
    "MarkerDetector",
    "PanTiltCommand",
    "PanTiltController",
    "PanTiltLimits",
    "PinholeCamera",
    "RobotPoseEstimate",
    "TrackEstimate",
    "TrackedRobot",
    "Tracker",
    "TrackingConfig",
    "WallPose",
    "aim_at",
    "directive_agreement",
    "estimate_robot_pose",
    "estimate_robot_poses",
    "head_camera",
    "infer_directive",
    "infer_directives",
    "look_at_rotation",
    "wall_to_world",
    "world_to_wall",
    "wrap_degrees",
]
