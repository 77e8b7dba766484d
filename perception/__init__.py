"""Perception: what the student sees.

Marker tracking (OpenCV ArUco), camera geometry, the paper's wall frame and self-localisation from
wall landmarks. Pure numpy and OpenCV: this package never imports mujoco or dm_control, so it runs
unchanged on a real robot's images.
"""

from perception.camera import PinholeCamera, look_at_rotation
from perception.gaze import GazeConfig, GazeController
from perception.landmarks import (
    LandmarkFix,
    LandmarkLocator,
    LandmarkMap,
    LandmarkMarker,
    LocatorConfig,
    landmark_view,
    read_landmark_map,
)
from perception.localisation import LocalisationEstimate, LocaliserConfig, SelfLocaliser
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
    "GazeConfig",
    "GazeController",
    "HeadMount",
    "KalmanTrack",
    "LandmarkFix",
    "LandmarkLocator",
    "LandmarkMap",
    "LandmarkMarker",
    "LocalisationEstimate",
    "LocaliserConfig",
    "LocatorConfig",
    "MarkerDetection",
    "MarkerDetector",
    "PanTiltCommand",
    "PanTiltController",
    "PanTiltLimits",
    "PinholeCamera",
    "RobotPoseEstimate",
    "SelfLocaliser",
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
    "landmark_view",
    "look_at_rotation",
    "read_landmark_map",
    "wall_to_world",
    "world_to_wall",
    "wrap_degrees",
]
