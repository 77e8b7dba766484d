"""ROS ``camera_info`` YAML files (``sensor_msgs/CameraInfo``) to and from :class:`PinholeCamera`.

The layout is the one ROS's ``camera_calibration`` writes and ``camera_info_manager`` reads::

    image_width: 320
    image_height: 240
    camera_name: head_camera
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}
    projection_matrix: {rows: 3, cols: 4, data: [fx', 0, cx', 0, 0, fy', cy', 0, 0, 0, 1, 0]}

(written in block style, as ROS does). Pixels follow OpenCV's convention, as ROS's do. A file holds
intrinsics only: a camera read from one stands at the identity pose, and :func:`with_intrinsics`
puts calibrated intrinsics on a posed camera.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib

import cv2
import numpy as np
import yaml

from perception.camera import PinholeCamera

#: ROS distortion models this module reads and writes, with their numbers of coefficients
#: (``plumb_bob``: k1, k2, p1, p2, k3; ``rational_polynomial``: k1, k2, p1, p2, k3, k4, k5, k6).
DISTORTION_MODELS = {"plumb_bob": 5, "rational_polynomial": 8}

_MATRICES = {
    "camera_matrix": (3, 3),
    "distortion_coefficients": (1, None),
    "rectification_matrix": (3, 3),
    "projection_matrix": (3, 4),
}
_FIELDS = (
    "image_width",
    "image_height",
    "camera_name",
    "camera_matrix",
    "distortion_model",
    "distortion_coefficients",
    "rectification_matrix",
    "projection_matrix",
)


@dataclasses.dataclass(frozen=True, eq=False)
class CameraInfo:
    """The contents of a ``camera_info`` file.

    Attributes:
      camera_name: the file's ``camera_name`` (ROS matches it against the camera driver's name).
      camera: the intrinsics (matrix, distortion, image size) at the identity pose.
      rectification: R, shape (3, 3); the identity for a monocular camera.
      projection: P, shape (3, 4), pixels: the intrinsics of the rectified (undistorted) image.
    """

    camera_name: str
    camera: PinholeCamera
    rectification: np.ndarray
    projection: np.ndarray


def projection_matrix(camera: PinholeCamera) -> np.ndarray:
    """Returns the ROS projection matrix P, shape (3, 4), of a monocular camera.

    ``[K | 0]`` for a camera without distortion; otherwise, as ROS's ``camera_calibration`` does,
    the new camera matrix of OpenCV's ``getOptimalNewCameraMatrix`` at ``alpha = 0`` (the rectified
    image keeps only valid pixels) and a zero last column.
    """
    k = camera.matrix
    if camera.distortion.size and np.any(camera.distortion != 0):
        k, _ = cv2.getOptimalNewCameraMatrix(
            camera.matrix, camera.distortion, camera.image_size, 0.0
        )
    return np.column_stack([k, np.zeros(3)])


def camera_info(camera: PinholeCamera, camera_name: str = "camera") -> CameraInfo:
    """Returns the ``camera_info`` of a camera's intrinsics (its pose is dropped)."""
    if not isinstance(camera_name, str) or not camera_name.strip() or "\n" in camera_name:
        raise ValueError(f"camera_name must be a non-empty single line, got {camera_name!r}")
    if camera.distortion.size not in (0, 4, 5, 8):
        raise ValueError(
            f"a camera_info file holds 5 (plumb_bob) or 8 (rational_polynomial) distortion "
            f"coefficients; this camera has {camera.distortion.size}"
        )
    intrinsics = PinholeCamera(camera.matrix, camera.distortion, camera.image_size)
    return CameraInfo(camera_name, intrinsics, np.eye(3), projection_matrix(intrinsics))


def _number(value: float) -> str:
    # repr() of a Python float reads back to the same float; integers stay short ("0", "1").
    value = float(value)
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


def _matrix_yaml(name: str, rows: int, cols: int, values) -> list[str]:
    data = ", ".join(_number(v) for v in np.asarray(values, dtype=float).ravel())
    return [f"{name}:", f"  rows: {rows}", f"  cols: {cols}", f"  data: [{data}]"]


def dumps(info: CameraInfo) -> str:
    """Returns the ``camera_info`` YAML text of ``info``."""
    distortion = info.camera.distortion
    if distortion.size in (0, 4):  # plumb_bob has five coefficients: pad with zeros
        distortion = np.concatenate([distortion, np.zeros(5 - distortion.size)])
    model = {5: "plumb_bob", 8: "rational_polynomial"}.get(distortion.size)
    if model is None:
        raise ValueError(
            f"a camera_info file holds 5 (plumb_bob) or 8 (rational_polynomial) distortion "
            f"coefficients, got {distortion.size}"
        )
    width, height = info.camera.image_size
    lines = [
        f"image_width: {width}",
        f"image_height: {height}",
        f"camera_name: {yaml.safe_dump(info.camera_name, width=math.inf).splitlines()[0]}",
        *_matrix_yaml("camera_matrix", 3, 3, info.camera.matrix),
        f"distortion_model: {model}",
        *_matrix_yaml("distortion_coefficients", 1, distortion.size, distortion),
        *_matrix_yaml("rectification_matrix", 3, 3, info.rectification),
        *_matrix_yaml("projection_matrix", 3, 4, info.projection),
    ]
    return "\n".join(lines) + "\n"


def write(path, camera: PinholeCamera, camera_name: str = "camera") -> pathlib.Path:
    """Writes the ``camera_info`` YAML of a camera's intrinsics to ``path``; returns the path."""
    path = pathlib.Path(path)
    text = dumps(camera_info(camera, camera_name))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _refuse(source: str, field: str, problem: str) -> ValueError:
    return ValueError(f"{source}: field '{field}' {problem}")


def _pixels(document: dict, source: str, field: str) -> int:
    value = document[field]
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise _refuse(source, field, f"must be a positive integer number of pixels, got {value!r}")
    return value


def _matrix(document: dict, source: str, field: str, n_cols: int | None = None) -> np.ndarray:
    value = document[field]
    if not isinstance(value, dict):
        raise _refuse(source, field, f"must be a mapping with rows, cols and data, got {value!r}")
    rows_expected, cols_expected = _MATRICES[field]
    cols_expected = n_cols if cols_expected is None else cols_expected
    for key in ("rows", "cols", "data"):
        if key not in value:
            raise _refuse(source, f"{field}.{key}", "is missing")
    for key, expected in (("rows", rows_expected), ("cols", cols_expected)):
        if isinstance(value[key], bool) or value[key] != expected:
            raise _refuse(source, f"{field}.{key}", f"must be {expected}, got {value[key]!r}")
    data = value["data"]
    if not isinstance(data, list) or len(data) != rows_expected * cols_expected:
        raise _refuse(
            source,
            f"{field}.data",
            f"must be a list of {rows_expected * cols_expected} numbers, got {data!r}",
        )
    if not all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in data
    ):
        raise _refuse(source, f"{field}.data", f"must hold finite numbers only, got {data!r}")
    return np.array(data, dtype=float).reshape(rows_expected, cols_expected)


def loads(text: str, source: str = "<camera_info>") -> CameraInfo:
    """Returns the :class:`CameraInfo` of ``camera_info`` YAML text.

    Raises ValueError naming ``source`` (a file name) and the first missing or malformed field.
    """
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ValueError(f"{source}: not a YAML file: {error}") from None
    if not isinstance(document, dict):
        raise ValueError(f"{source}: a camera_info file must be a YAML mapping of {_FIELDS}")
    for field in _FIELDS:
        if field not in document:
            raise _refuse(source, field, "is missing")
    width = _pixels(document, source, "image_width")
    height = _pixels(document, source, "image_height")
    name = document["camera_name"]
    if not isinstance(name, (str, int)) or isinstance(name, bool) or not str(name).strip():
        raise _refuse(source, "camera_name", f"must be a non-empty name, got {name!r}")
    model = document["distortion_model"]
    if model not in DISTORTION_MODELS:
        raise _refuse(
            source,
            "distortion_model",
            f"must be one of {', '.join(DISTORTION_MODELS)}, got {model!r}",
        )
    matrix = _matrix(document, source, "camera_matrix")
    distortion = _matrix(
        document, source, "distortion_coefficients", DISTORTION_MODELS[model]
    ).ravel()
    rectification = _matrix(document, source, "rectification_matrix")
    projection = _matrix(document, source, "projection_matrix")
    try:
        camera = PinholeCamera(matrix, distortion, (width, height))
    except ValueError as error:
        raise _refuse(source, "camera_matrix", str(error)) from None
    return CameraInfo(str(name), camera, _frozen(rectification), _frozen(projection))


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array


def read(path: str | os.PathLike) -> CameraInfo:
    """Returns the :class:`CameraInfo` of a ``camera_info`` YAML file; ValueError names the file
    and the field when it is malformed."""
    path = pathlib.Path(path)
    return loads(path.read_text(), source=str(path))


def with_intrinsics(camera: PinholeCamera, info: CameraInfo | PinholeCamera) -> PinholeCamera:
    """Returns ``camera``'s pose with the intrinsics (matrix, distortion) of ``info``.

    Swaps a simulator's (or a datasheet's) matrix for a calibrated one; the image sizes must match
    (intrinsics calibrated at one resolution do not apply to another without rescaling).
    """
    intrinsics = info.camera if isinstance(info, CameraInfo) else info
    if not isinstance(intrinsics, PinholeCamera):
        raise ValueError(f"info must be a CameraInfo or a PinholeCamera, got {type(info).__name__}")
    if tuple(intrinsics.image_size) != tuple(camera.image_size):
        raise ValueError(
            f"the calibrated image size {intrinsics.image_size} differs from the camera's "
            f"{camera.image_size}; calibrate at the resolution the camera streams"
        )
    return PinholeCamera(
        intrinsics.matrix,
        intrinsics.distortion,
        camera.image_size,
        camera.rotation_world_from_camera,
        camera.position_world,
    )
