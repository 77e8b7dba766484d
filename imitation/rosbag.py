"""Episode logs the ROS 2 tools read: one MCAP file per episode, CDR messages with their ``ros2msg``
schemas, as ``ros2 bag record -s mcap`` writes them; Foxglove opens one and ``ros2 bag play`` replays
it, with no ROS installation needed to write it.

Topics (``TOPICS``), each written only when ``record`` is given its data:

* ``/cmd_vel`` (``geometry_msgs/msg/TwistStamped``, frame ``base_link``): the student's wheel command,
  ``linear.x`` m/s and ``angular.z`` rad/s.
* ``/odom`` (``nav_msgs/msg/Odometry``, frame ``odom``, child ``base_link``): the student's pose and
  its velocity in ``base_link`` (zero when not given); covariances zero (not estimated).
* ``/tf`` (``tf2_msgs/msg/TFMessage``): the tree of REP 105, ``map -> odom -> base_link`` for the
  student (``map -> odom`` the identity: the simulator's odometry has no drift), ``map ->
  teacher/base_link`` for the teacher and ``map -> camera`` for the camera, when known.
* ``/camera/image/compressed`` (``sensor_msgs/msg/CompressedImage``, JPEG) and ``/camera/camera_info``
  (``sensor_msgs/msg/CameraInfo``, ``plumb_bob`` with zero distortion), frame ``camera`` (OpenCV
  axes, as ROS optical frames: x right, y down, z forward).
* ``/markers`` (``geometry_msgs/msg/PoseArray``, frame ``camera``): detected marker poses.
* ``/robots/<robot>/pose`` (``geometry_msgs/msg/PoseStamped``, frame ``map``): estimated poses.
* ``/word`` and ``/directive`` (``std_msgs/msg/String``): the teacher's word and directive.

The world frame of the simulator is ``map``: x, y in metres on the floor, yaw in radians about z.
"""

from __future__ import annotations

import math
import pathlib
import re
from collections.abc import Mapping, Sequence

import cv2
import numpy as np
from mcap_ros2.writer import Writer

from imitation import storage

MAP_FRAME = "map"
ODOM_FRAME = "odom"
BASE_FRAME = "base_link"
TEACHER_BASE_FRAME = "teacher/base_link"
CAMERA_FRAME = "camera"

#: The fixed topics and their ROS 2 types (plus ``/robots/<robot>/pose``, ``geometry_msgs/msg/
#: PoseStamped``, one per robot of ``estimated_poses``).
TOPICS = {
    "/cmd_vel": "geometry_msgs/msg/TwistStamped",
    "/odom": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/camera/camera_info": "sensor_msgs/msg/CameraInfo",
    "/markers": "geometry_msgs/msg/PoseArray",
    "/word": "std_msgs/msg/String",
    "/directive": "std_msgs/msg/String",
}
POSE_TYPE = "geometry_msgs/msg/PoseStamped"

#: JPEG quality of the camera frames (OpenCV's 0-100 scale).
JPEG_QUALITY = 90

# The .msg definitions (ROS 2 Humble and Jazzy, comments left out), by package resource name.
_MSG = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "std_msgs/String": "string data\n",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation\n",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\nPose pose\n",
    "geometry_msgs/PoseArray": "std_msgs/Header header\nPose[] poses\n",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance\n",
    "geometry_msgs/Twist": "Vector3  linear\nVector3  angular\n",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\nTwist twist\n",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance\n",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation\n",
    "geometry_msgs/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
    ),
    "nav_msgs/Odometry": (
        "std_msgs/Header header\nstring child_frame_id\n"
        "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n"
    ),
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "sensor_msgs/RegionOfInterest": (
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"
    ),
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data\n",
    "sensor_msgs/CameraInfo": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
        "float64[] d\nfloat64[9]  k\nfloat64[9]  r\nfloat64[12] p\n"
        "uint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n"
    ),
}
_PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string".split()
)
_DELIMITER = "=" * 80 + "\n"
_ROBOT_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def _dependencies(name: str) -> list[str]:
    """Returns the message types the fields of ``name`` ("pkg/Name") use, sorted."""
    package = name.split("/")[0]
    types = set()
    for line in _MSG[name].splitlines():
        field_type = line.split()[0].split("[")[0]
        if field_type not in _PRIMITIVES:
            types.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(types)


def message_definition(type_name: str) -> str:
    """Returns the complete ``ros2msg`` definition of a type ("pkg/msg/Name"): its .msg text, then each
    dependency once, depth first, after an 80 '=' line and ``MSG: pkg/Name`` (rosbag2's layout)."""
    package, _, name = type_name.partition("/msg/")
    root = f"{package}/{name}"
    if root not in _MSG:
        allowed = ", ".join(f"{k.split('/')[0]}/msg/{k.split('/')[1]}" for k in sorted(_MSG))
        raise ValueError(f"unknown message type {type_name!r}; allowed: {allowed}")
    seen: set[str] = set()

    def text(current: str) -> str:
        result = _MSG[current]
        for dependency in _dependencies(current):
            if dependency not in seen:
                seen.add(dependency)
                result += f"\n{_DELIMITER}MSG: {dependency}\n{text(dependency)}"
        return result

    return text(root)


def _vector(value, length: int, name: str) -> np.ndarray:
    array = np.asarray(value, dtype=float).ravel()
    if array.shape != (length,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be {length} finite numbers, got {value!r}")
    return array


def _yaw_quaternion(yaw_rad: float) -> dict:
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw_rad / 2), "w": math.cos(yaw_rad / 2)}


def _matrix_quaternion(rotation: np.ndarray) -> dict:
    """Returns the unit quaternion of a rotation matrix, shape (3, 3) (Shepperd's method)."""
    r = rotation
    trace = np.trace(r)
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s
    elif r[1, 1] > r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = (r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4, (r[1, 0] - r[0, 1]) / s
    q = np.array(q) / np.linalg.norm(q)
    return dict(zip("xyzw", (float(v) for v in q), strict=True))


def _rotation(value, name: str) -> np.ndarray:
    """Returns a rotation matrix from a matrix, shape (3, 3), or a Rodrigues vector, shape (3,)."""
    array = np.asarray(value, dtype=float)
    if array.size == 3 and np.all(np.isfinite(array)):
        return cv2.Rodrigues(array.reshape(3, 1))[0]
    if array.shape == (3, 3) and np.allclose(array @ array.T, np.eye(3), atol=1e-6):
        if np.linalg.det(array) > 0:
            return array
    raise ValueError(f"{name} must be a rotation matrix (3, 3) or a Rodrigues vector (3,)")


def _pose(rotation: np.ndarray, position: np.ndarray) -> dict:
    return {
        "position": dict(zip("xyz", (float(v) for v in position), strict=True)),
        "orientation": _matrix_quaternion(rotation),
    }


def _planar_pose(pose, name: str) -> dict:
    x, y, yaw = _vector(pose, 3, name)
    return {"position": {"x": x, "y": y, "z": 0.0}, "orientation": _yaw_quaternion(yaw)}


def _marker_pose(value, index: int) -> dict:
    """Returns a Pose of a marker given as a homogeneous matrix (4, 4) or a pair (rotation, tvec)."""
    name = f"marker_poses[{index}]"
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return _pose(_rotation(value[0], name), _vector(value[1], 3, f"{name} tvec"))
    matrix = np.asarray(value, dtype=float)
    if matrix.shape == (4, 4):
        if not (np.all(np.isfinite(matrix)) and np.allclose(matrix[3], (0, 0, 0, 1))):
            raise ValueError(f"{name} must be a homogeneous transform with last row 0, 0, 0, 1")
        return _pose(_rotation(matrix[:3, :3], name), matrix[:3, 3])
    raise ValueError(
        f"{name} must be a 4x4 transform or a pair (rotation matrix 3x3 or rvec (3,), tvec (3,))"
    )


def _transform(parent: str, child: str, header_stamp: dict, pose: dict) -> dict:
    return {
        "header": {"stamp": header_stamp, "frame_id": parent},
        "child_frame_id": child,
        "transform": {"translation": pose["position"], "rotation": pose["orientation"]},
    }


class EpisodeRecorder:
    """Writes one episode to an MCAP file, under a temporary name until ``close`` renames it.

    Args:
      path: the episode's file (``.mcap``); its folder is created.

    Use as a context manager: leaving the block normally keeps the file, an exception drops it. A
    recorder never closed (a crash) leaves at most ``storage.temporary_name(path)``, never ``path``.
    Chunks of 1 MiB, zstd-compressed (the MCAP writer's defaults).
    """

    def __init__(self, path):
        self.path = pathlib.Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = storage.temporary_name(self.path)
        self._file = open(self._tmp, "wb")
        self._writer = Writer(self._file)
        self._schemas: dict = {}
        self._sequences: dict[str, int] = {}
        self._last_ns = 0
        self._image_size: tuple[int, int] | None = None

    def __enter__(self) -> EpisodeRecorder:
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self.close(keep=exc_type is None)

    @property
    def closed(self) -> bool:
        """Returns True once ``close`` was called."""
        return self._file.closed

    def close(self, keep: bool = True) -> None:
        """Finishes the file; ``keep``: rename it to ``path`` (False: a failed episode is dropped)."""
        if self.closed:
            return
        try:
            self._writer.finish()
        finally:
            self._file.close()
        if keep:
            storage.commit(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)

    def _write(self, topic: str, type_name: str, message: dict, time_ns: int) -> None:
        schema = self._schemas.get(type_name)
        if schema is None:
            schema = self._writer.register_msgdef(type_name, message_definition(type_name))
            self._schemas[type_name] = schema
        sequence = self._sequences.get(topic, 0)
        self._sequences[topic] = sequence + 1
        self._writer.write_message(topic, schema, message, log_time=time_ns, sequence=sequence)

    def record(
        self,
        time_s: float,
        *,
        cmd_vel: Sequence[float] | None = None,
        student_pose: Sequence[float] | None = None,
        student_velocity: Sequence[float] | None = None,
        teacher_pose: Sequence[float] | None = None,
        image: np.ndarray | None = None,
        camera_matrix: np.ndarray | None = None,
        camera_pose: tuple | None = None,
        marker_poses: Sequence | None = None,
        estimated_poses: Mapping[str, Sequence[float] | None] | None = None,
        word: str | None = None,
        directive: str | None = None,
    ) -> None:
        """Writes whatever is given, stamped ``time_s``.

        Args:
          time_s: seconds since the episode began (the stamp, and the log time in nanoseconds);
            never less than the previous call's.
          cmd_vel: the student's command ``(linear m/s, yaw rate rad/s)``.
          student_pose, teacher_pose: ``(x m, y m, yaw rad)`` in ``map``.
          student_velocity: ``(v m/s, yaw rate rad/s)`` in ``base_link``; with ``student_pose``.
          image: an RGB frame, shape (height, width, 3), uint8.
          camera_matrix: intrinsics K, shape (3, 3), pixels, for the last image's size.
          camera_pose: ``(rotation_world_from_camera (3, 3), position_world (3,))``, OpenCV axes.
          marker_poses: marker poses in the camera frame, each a 4x4 transform or a pair (rotation
            matrix (3, 3) or Rodrigues vector (3,), translation (3,) m).
          estimated_poses: robot name -> ``(x, y, yaw)`` in ``map`` (None: not seen, skipped).
          word, directive: the teacher's word and directive.
        """
        if self.closed:
            raise ValueError(f"the recorder of {self.path} is closed")
        if not (isinstance(time_s, (int, float, np.number)) and 0 <= time_s < math.inf):
            raise ValueError(f"time_s must be a finite number of seconds >= 0, got {time_s!r}")
        ns = int(round(float(time_s) * 1e9))
        if ns < self._last_ns:
            raise ValueError(f"time_s must not go back: {time_s} s after {self._last_ns / 1e9} s")
        if student_velocity is not None and student_pose is None:
            raise ValueError("student_velocity needs student_pose (they make one /odom message)")
        stamp = {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}

        def header(frame: str) -> dict:
            return {"stamp": stamp, "frame_id": frame}

        # Everything is checked and built before anything is written: a bad argument writes nothing.
        messages: list[tuple[str, str, dict]] = []
        transforms = []
        if cmd_vel is not None:
            linear, angular = _vector(cmd_vel, 2, "cmd_vel")
            twist = {"linear": {"x": linear}, "angular": {"z": angular}}
            message = {"header": header(BASE_FRAME), "twist": twist}
            messages.append(("/cmd_vel", TOPICS["/cmd_vel"], message))
        if student_pose is not None:
            pose = _planar_pose(student_pose, "student_pose")
            v, w = (
                (0.0, 0.0)
                if student_velocity is None
                else _vector(student_velocity, 2, "student_velocity")
            )
            odometry = {
                "header": header(ODOM_FRAME),
                "child_frame_id": BASE_FRAME,
                "pose": {"pose": pose, "covariance": [0.0] * 36},
                "twist": {
                    "twist": {"linear": {"x": v}, "angular": {"z": w}},
                    "covariance": [0.0] * 36,
                },
            }
            messages.append(("/odom", TOPICS["/odom"], odometry))
            identity = {
                "position": {"x": 0.0, "y": 0.0, "z": 0.0},
                "orientation": _yaw_quaternion(0.0),
            }
            transforms.append(_transform(MAP_FRAME, ODOM_FRAME, stamp, identity))
            transforms.append(_transform(ODOM_FRAME, BASE_FRAME, stamp, pose))
        if teacher_pose is not None:
            pose = _planar_pose(teacher_pose, "teacher_pose")
            transforms.append(_transform(MAP_FRAME, TEACHER_BASE_FRAME, stamp, pose))
        if camera_pose is not None:
            if not (isinstance(camera_pose, (tuple, list)) and len(camera_pose) == 2):
                raise ValueError("camera_pose must be (rotation_world_from_camera, position_world)")
            rotation = _rotation(camera_pose[0], "camera_pose rotation")
            pose = _pose(rotation, _vector(camera_pose[1], 3, "camera_pose position"))
            transforms.append(_transform(MAP_FRAME, CAMERA_FRAME, stamp, pose))
        if transforms:
            messages.append(("/tf", TOPICS["/tf"], {"transforms": transforms}))
        image_size = self._image_size
        if image is not None:
            frame = np.asarray(image)
            if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
                raise ValueError(
                    f"image must be RGB, shape (height, width, 3), uint8; got shape "
                    f"{frame.shape}, {frame.dtype}"
                )
            ok, jpeg = cv2.imencode(
                ".jpg", frame[:, :, ::-1], (cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY)
            )
            if not ok:
                raise ValueError(f"OpenCV could not encode an image of shape {frame.shape}")
            image_size = frame.shape[1], frame.shape[0]
            message = {"header": header(CAMERA_FRAME), "format": "jpeg", "data": jpeg.tobytes()}
            topic = "/camera/image/compressed"
            messages.append((topic, TOPICS[topic], message))
        if camera_matrix is not None:
            k = np.asarray(camera_matrix, dtype=float)
            if k.shape != (3, 3) or not np.all(np.isfinite(k)):
                raise ValueError(
                    f"camera_matrix must be a finite 3x3 matrix, got {camera_matrix!r}"
                )
            if image_size is None:
                raise ValueError("camera_matrix needs an image (this call's or an earlier one's)")
            p = np.hstack([k, np.zeros((3, 1))])
            info = {
                "header": header(CAMERA_FRAME),
                "width": image_size[0],
                "height": image_size[1],
                "distortion_model": "plumb_bob",
                "d": [0.0] * 5,
                "k": k.ravel().tolist(),
                "r": np.eye(3).ravel().tolist(),
                "p": p.ravel().tolist(),
            }
            messages.append(("/camera/camera_info", TOPICS["/camera/camera_info"], info))
        if marker_poses is not None:
            poses = [_marker_pose(value, i) for i, value in enumerate(marker_poses)]
            message = {"header": header(CAMERA_FRAME), "poses": poses}
            messages.append(("/markers", TOPICS["/markers"], message))
        for robot, estimate in (estimated_poses or {}).items():
            if not (isinstance(robot, str) and _ROBOT_NAME.match(robot)):
                raise ValueError(
                    f"robot names must be ROS name tokens ([A-Za-z][A-Za-z0-9_]*), got {robot!r}"
                )
            if estimate is not None:
                message = {"header": header(MAP_FRAME), "pose": _planar_pose(estimate, robot)}
                messages.append((f"/robots/{robot}/pose", POSE_TYPE, message))
        for topic, text in (("/word", word), ("/directive", directive)):
            if text is not None:
                if not isinstance(text, str):
                    raise ValueError(f"{topic[1:]} must be a string, got {text!r}")
                messages.append((topic, TOPICS[topic], {"data": text}))
        for topic, type_name, message in messages:
            self._write(topic, type_name, message, ns)
        self._last_ns = ns
        self._image_size = image_size
