"""How the student knows where the robots are: the vision modes of the experiments.

- ``truth``: the simulator's poses (the paper's setting).
- ``overhead``: the overhead camera's frames, tracked by ``perception`` (both robots).
- ``head``: the student's own pan-tilt camera, tracked by ``perception``; the camera's pose comes
  from the student's own pose and its head angles. The own pose (``self_localisation``):
  'landmarks' (the default): wheel odometry fused with the wall landmarks the head camera sees
  (``perception.localisation``), from an unknown start, the head shared between the teacher and
  the landmarks (``perception.gaze``); 'odometry': wheel odometry alone from the known start, a
  pan-tilt controller keeping the teacher in view (the comparison).

The overhead camera's pose is either believed as calibrated or registered once from the floor
markers' photo (``OVERHEAD_REGISTRATIONS``, :func:`register_overhead`).

``StudentVision`` reads only the environment's observations (camera frames, wheel encoders, head
angles; the simulator's poses in ``truth`` mode) and camera calibrations, as a real robot would.
Poses are world ``(x_m, y_m, yaw_rad)``, or None when the robot is not known (never seen, or its
track was lost).
"""

from __future__ import annotations

import copy
import math

import numpy as np

from peoplebot_sim import assets, cameras, registration
from peoplebot_sim.entities import BASE_RADIUS_M
from perception.arenafile import read_arena
from perception.gaze import GazeController
from perception.landmarks import LandmarkLocator, read_landmark_map
from perception.localisation import LocalisationEstimate, LocaliserConfig, SelfLocaliser
from perception.markers import MarkerDetector
from perception.odometry import WheelOdometry
from perception.pantilt import HeadMount, PanTiltController, head_camera
from perception.pipeline import Tracker
from perception.registration import register_camera

VISION_MODES = ("truth", "overhead", "head")
#: How the head mode knows the student's own pose.
SELF_LOCALISATIONS = ("landmarks", "odometry")
#: Where the overhead camera's pose comes from: 'believed' (its calibration, as measured on the
#: mount) or 'floor_markers' (fitted to a photo of the floor markers, ``register_overhead``).
OVERHEAD_REGISTRATIONS = ("believed", "floor_markers")
#: The closest the PeopleBot's centre of rotation comes to a wall, metres: half its 0.425 m width
#: (ARIA's ``RobotWidth 425``, ``peoplebot_sim.entities``), rounded down; it bounds the landmark
#: filter's estimate.
ROBOT_HALF_WIDTH_M = 0.2
#: The PeopleBot's outline around its centre of rotation for the landmark filter's contact model,
#: metres ``(front, rear, half_width)``: the outline of the model's chassis and gripper collision
#: geoms at rest (``models/peoplebot/peoplebot.xml``): the gripper's paddles reach 0.365 m ahead
#: (0.285 + 0.045 + 0.035), the chassis box 0.2565 m behind and 0.2125 m to each side (ARIA's
#: ``RobotLength 513``, ``RobotWidth 425``). The wheels' collision spheres (0.095 m radius at
#: +-0.17 m) bulge to 0.265 m, wider than the real robot's wheels, which sit inside its width: the
#: real outline is kept (0.265 m was tried: the bench's seeds 5 and 6 then missed the targets).
ROBOT_FOOTPRINT_M = (0.365, 0.2565, 0.2125)


def check_vision_mode(mode: str) -> str:
    if mode not in VISION_MODES:
        raise ValueError(f"unknown vision mode {mode!r}; allowed: {', '.join(VISION_MODES)}")
    return mode


def check_self_localisation(method: str) -> str:
    if method not in SELF_LOCALISATIONS:
        raise ValueError(
            f"unknown self-localisation {method!r}; allowed: {', '.join(SELF_LOCALISATIONS)}"
        )
    return method


class Calibration:
    """The student's camera calibrations, measured once from the simulator (as one would calibrate a
    real camera): the overhead camera with its fixed pose, the head camera's intrinsics, its
    mount on the robot and the zero offsets of its pan and tilt readings (degrees), and the arena
    and its wall landmarks (their files, as a real robot would read its room's)."""

    def __init__(self, physics, width: int, height: int):
        self.overhead = cameras.camera_model(physics, "overhead", width, height)
        self.head_intrinsics = cameras.camera_model(physics, "student/head_camera", width, height)
        self.head_mount = HeadMount()
        self.head_angle_offsets_deg = (0.0, 0.0)
        self.landmarks = read_landmark_map(assets.LANDMARKS_TOML)
        self.arena = read_arena(assets.ARENA_TOML).arena


def register_overhead(calibration: Calibration) -> Calibration:
    """Returns ``calibration`` with the overhead camera's pose fitted to the overhead camera's
    photo of the floor markers (``peoplebot_sim.registration``), its intrinsics as believed."""
    width, height = calibration.overhead.image_size
    found = MarkerDetector().detect_all_corners(registration.registration_frame(width, height))
    fitted = register_camera(calibration.overhead, found, registration.floor_markers())
    registered = copy.copy(calibration)
    registered.overhead = fitted.camera
    return registered


class StudentVision:
    """Estimates the teacher's and the student's own world poses once per control step.

    Args:
      mode: one of ``VISION_MODES``.
      calibration: camera calibrations (needed by the camera modes).
      watch_teacher: also estimate the teacher (False when the student performs alone).
      self_localisation: the head mode's own pose, one of ``SELF_LOCALISATIONS``.
    """

    def __init__(
        self,
        mode: str = "truth",
        calibration: Calibration | None = None,
        watch_teacher: bool = True,
        self_localisation: str = "landmarks",
    ):
        self.mode = check_vision_mode(mode)
        self.self_localisation = check_self_localisation(self_localisation)
        if mode != "truth" and calibration is None:
            raise ValueError(f"vision mode {mode!r} needs a camera calibration")
        self.calibration = calibration
        self.watch_teacher = watch_teacher
        robots = []
        if watch_teacher:
            robots.append("teacher")
        if mode == "overhead":
            robots.append("student")
        self._robots = tuple(robots)
        self.odometry = None
        self.localiser = None
        self.localisation: LocalisationEstimate | None = None
        self.reset()

    @property
    def uses_landmarks(self) -> bool:
        """Returns True when the own pose comes from the landmark filter (head mode)."""
        return self.mode == "head" and self.self_localisation == "landmarks"

    def reset(self, start_pose=None, wheel_angles=None) -> None:
        """Starts afresh. The head mode's odometry starts from the student's known start pose and
        wheel angles (it cannot update before they are given); the landmark filter ignores the
        start pose and finds itself (it needs the wheel angles)."""
        self.tracker = (
            Tracker(robots=self._robots) if self._robots and self.mode != "truth" else None
        )
        self.head_command = (0.0, 0.0)
        self.pantilt = PanTiltController()
        self.odometry = None
        self.localiser = None
        self.localisation = None
        self._teacher_xy = None
        if self.uses_landmarks and wheel_angles is not None:
            calibration = self.calibration
            self.localiser = SelfLocaliser(
                LandmarkLocator(
                    calibration.landmarks, calibration.head_intrinsics, mount=calibration.head_mount
                ),
                config=LocaliserConfig(
                    free_half_side_m=calibration.arena.half_side_m - ROBOT_HALF_WIDTH_M,
                    wall_half_side_m=calibration.arena.half_side_m,
                    footprint_m=ROBOT_FOOTPRINT_M,
                    obstacle_boxes_m=(calibration.arena.table_box,),
                ),
            )
            self.localiser.reset(None, wheel_angles=wheel_angles)
            self.gaze = GazeController(
                calibration.landmarks, calibration.head_intrinsics, controller=self.pantilt
            )
        elif self.mode == "head" and start_pose is not None and wheel_angles is not None:
            self.odometry = WheelOdometry(start_pose, *wheel_angles)

    def update(self, observation: dict, time_s: float, dt: float) -> dict:
        """Returns ``{'teacher': pose | None, 'student': pose | None}`` from one step's observation."""
        if self.mode == "truth":
            out = {"student": np.asarray(observation["student_pose"], dtype=float)}
            if self.watch_teacher:
                if "teacher_pose" not in observation:
                    raise ValueError("watch_teacher=True but the environment has no teacher")
                out["teacher"] = np.asarray(observation["teacher_pose"], dtype=float)
            return out
        if self.mode == "overhead":
            out = {"teacher": None, "student": None}
            tracked = self.tracker.update(
                observation["overhead_camera"], self.calibration.overhead, time_s
            )
            for robot, track in tracked.items():
                out[robot] = None if track.track.pose is None else track.track.pose.copy()
            return out
        if self.uses_landmarks:
            return self._update_landmarks(observation, time_s, dt)
        if self.odometry is None:
            raise ValueError("the head mode needs reset(start_pose, wheel_angles) before update()")
        own = self.odometry.update(*observation["student_wheel_angles"])
        out = {"student": own, "teacher": None}
        if self.watch_teacher:
            pan, tilt = self._head_angles_deg(observation)
            camera = head_camera(
                self.calibration.head_intrinsics, own, pan, tilt, self.calibration.head_mount
            )
            track = self.tracker.update(observation["head_camera"], camera, time_s)["teacher"]
            if track.track.pose is not None:
                out["teacher"] = track.track.pose.copy()
            target = None if out["teacher"] is None else out["teacher"][:2]
            command = self.pantilt.step(own, target, dt)
            self.head_command = (math.radians(command.pan_deg), math.radians(command.tilt_deg))
        return out

    def _head_angles_deg(self, observation: dict) -> tuple[float, float]:
        """Returns the head's pan and tilt readings in degrees, with the zero offsets the student's
        calibration believes."""
        pan, tilt = (math.degrees(a) for a in observation["student_head_angles"])
        pan_zero, tilt_zero = self.calibration.head_angle_offsets_deg
        return pan + pan_zero, tilt + tilt_zero

    def _update_landmarks(self, observation: dict, time_s: float, dt: float) -> dict:
        """The head mode with the landmark filter: odometry, then this frame's landmarks, then the
        teacher from the camera posed at the filtered pose, then the head's next command."""
        if self.localiser is None:
            raise ValueError("the head mode needs reset(start_pose, wheel_angles) before update()")
        if "head_camera" not in observation:
            raise ValueError(
                "self_localisation='landmarks' needs the head camera's frames: load the "
                "environment with cameras=('head',)"
            )
        pan, tilt = self._head_angles_deg(observation)
        image = observation["head_camera"]
        # The teacher where it was last tracked: an obstacle the student may push against.
        movers = () if self._teacher_xy is None else ((*self._teacher_xy, BASE_RADIUS_M),)
        self.localiser.predict_wheels(observation["student_wheel_angles"], movers)
        # One detection pass for the landmarks and the teacher.
        found = self.localiser.locator.detector.detect_all_corners(image)
        self.localisation = self.localiser.correct(found, pan, tilt)
        own = self.localisation.pose
        out = {"student": None if own is None else own.copy(), "teacher": None}
        if self.watch_teacher and own is not None:
            # The tilt as the landmarks correct it (``LocatorConfig.tilt_search_deg``).
            tilt_seen = tilt + self.localiser.locator.tilt_correction_deg
            camera = head_camera(
                self.calibration.head_intrinsics, own, pan, tilt_seen, self.calibration.head_mount
            )
            track = self.tracker.update(image, camera, time_s, found=found)["teacher"]
            if track.track.pose is not None:
                out["teacher"] = track.track.pose.copy()
        target = None if out["teacher"] is None else out["teacher"][:2]
        if target is not None:  # kept while the teacher is lost (too near to see, say)
            self._teacher_xy = (float(target[0]), float(target[1]))
        command = self.gaze.step(self.localisation, target, dt, watching=self.watch_teacher)
        self.head_command = (math.radians(command.pan_deg), math.radians(command.tilt_deg))
        return out


def pose_or_nan(pose) -> np.ndarray:
    """Returns the pose as an array, or NaNs when unknown."""
    return np.full(3, np.nan) if pose is None else np.asarray(pose, dtype=float)
