"""ArUco marker detection and per-marker pose, configured once, in the pupil-apriltags shape.

A :class:`MarkerDetector` is built once from a :class:`DetectorConfig` and the marker layout; then
``detect(image)`` returns one :class:`MarkerDetection` per expected marker found.

Marker pose: ``cv2.solvePnPGeneric`` with ``cv2.SOLVEPNP_IPPE_SQUARE`` on the four corners (TL, TR,
BR, BL, the order ``cv2.aruco`` returns and IPPE_SQUARE expects). A planar square has two poses that
explain its corners almost equally well when it is small or seen nearly head-on (the "flip"
ambiguity). The plates sit on a robot standing level on the floor, so each marker's normal has a
known elevation in the world frame (+90 deg for the top plate, 0 for the vertical side plates).
Among the solutions whose reprojection error is within ``ambiguity_tolerance_px`` of the best, the
one whose world normal elevation is closest to the expected one is kept. This needs the camera's
extrinsics (``PinholeCamera.rotation_world_from_camera``).
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from perception.camera import PinholeCamera
from perception.layout import DICTIONARY_NAME, MarkerPlacement, default_layout

#: Corner refinement methods by name.
CORNER_REFINEMENTS = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
}


@dataclasses.dataclass(frozen=True)
class DetectorConfig:
    """How markers are found and their pose resolved (the defaults and the measurements behind
    them: docs/perception.md, "Detector defaults").

    Attributes:
      corner_refinement: one of ``CORNER_REFINEMENTS``.
      apriltag_offset_px: subtracted from both coordinates of corners refined by "apriltag", which
        come in the AprilTag library's pixel-edge convention (top-left pixel centre at (0.5, 0.5))
        rather than OpenCV's pixel-centre one.
      expected_ids: ids to report (all others are ignored); None means every id in the layout.
      ambiguity_tolerance_px: an IPPE solution is a candidate when its RMS reprojection error is
        within this many pixels of the best solution's.
      subpix_window_px: half-size of the sub-pixel corner search window, pixels (OpenCV's
        ``cornerRefinementWinSize``).
      min_marker_perimeter_rate: smallest marker perimeter as a fraction of the image's larger side
        (OpenCV's ``minMarkerPerimeterRate``).
      threshold_constant: subtracted from the local mean in the adaptive threshold, grey levels
        (OpenCV's ``adaptiveThreshConstant``).
      min_distance_to_border_px: markers closer than this to the image border are dropped, pixels.
      threshold_windows_px: adaptive-threshold window sizes tried, pixels (odd, >= 3).
      bit_pixels_per_cell, bit_margin_per_cell, error_correction_rate: how a candidate's bits are
        read (OpenCV's ``perspectiveRemovePixelPerCell``, ``perspectiveRemoveIgnoredMarginPerCell``
        and ``errorCorrectionRate``).
    """

    corner_refinement: str = "subpix"
    apriltag_offset_px: float = 0.5
    expected_ids: tuple[int, ...] | None = None
    ambiguity_tolerance_px: float = 1.0
    subpix_window_px: int = 3
    min_marker_perimeter_rate: float = 0.15
    threshold_constant: float = 15.0
    min_distance_to_border_px: int = 1
    threshold_windows_px: tuple[int, ...] = (9,)
    bit_pixels_per_cell: int = 8
    bit_margin_per_cell: float = 0.3
    error_correction_rate: float = 1.0

    def __post_init__(self):
        windows = tuple(self.threshold_windows_px)
        steps = {b - a for a, b in zip(windows, windows[1:], strict=False)}
        if (
            not windows
            or any(not isinstance(w, int) or w < 3 or w % 2 == 0 for w in windows)
            or len(steps) > 1
            or (steps and min(steps) <= 0)
        ):
            raise ValueError(
                "threshold_windows_px must be odd integers >= 3, increasing in equal steps, "
                f"got {self.threshold_windows_px!r}"
            )
        if self.corner_refinement not in CORNER_REFINEMENTS:
            raise ValueError(
                f"unknown corner_refinement {self.corner_refinement!r}; allowed: "
                f"{', '.join(CORNER_REFINEMENTS)}"
            )
        if not np.isfinite(self.ambiguity_tolerance_px) or self.ambiguity_tolerance_px < 0:
            raise ValueError(
                f"ambiguity_tolerance_px must be a finite number >= 0, "
                f"got {self.ambiguity_tolerance_px!r}"
            )
        if not np.isfinite(self.apriltag_offset_px) or abs(self.apriltag_offset_px) > 1.0:
            raise ValueError(
                f"apriltag_offset_px must be finite, within [-1, 1] pixels, "
                f"got {self.apriltag_offset_px!r}"
            )
        if not isinstance(self.subpix_window_px, int) or self.subpix_window_px < 1:
            raise ValueError(
                f"subpix_window_px must be an integer >= 1, got {self.subpix_window_px!r}"
            )
        if (
            not isinstance(self.min_distance_to_border_px, int)
            or self.min_distance_to_border_px < 0
        ):
            raise ValueError(
                f"min_distance_to_border_px must be an integer >= 0, "
                f"got {self.min_distance_to_border_px!r}"
            )
        if not isinstance(self.bit_pixels_per_cell, int) or not 2 <= self.bit_pixels_per_cell <= 32:
            raise ValueError(
                f"bit_pixels_per_cell must be an integer in [2, 32], got {self.bit_pixels_per_cell!r}"
            )
        if not 0.0 <= self.bit_margin_per_cell < 0.5:
            raise ValueError(
                f"bit_margin_per_cell must be in [0, 0.5), got {self.bit_margin_per_cell!r}"
            )
        if not 0.0 <= self.error_correction_rate <= 1.0:
            raise ValueError(
                f"error_correction_rate must be in [0, 1], got {self.error_correction_rate!r}"
            )
        if not np.isfinite(self.threshold_constant) or not 0.0 <= self.threshold_constant < 255.0:
            raise ValueError(
                f"threshold_constant must be in [0, 255) grey levels, got {self.threshold_constant!r}"
            )
        if not 0.0 < self.min_marker_perimeter_rate < 4.0:
            raise ValueError(
                f"min_marker_perimeter_rate must be in (0, 4), "
                f"got {self.min_marker_perimeter_rate!r}"
            )


def aruco_detector(config: DetectorConfig = DetectorConfig()) -> cv2.aruco.ArucoDetector:
    """Returns an OpenCV ArUco detector of ``DICTIONARY_NAME`` set up as ``config`` says (every id
    of the dictionary; callers keep the ids they expect)."""
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DICTIONARY_NAME))
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = CORNER_REFINEMENTS[config.corner_refinement]
    params.cornerRefinementWinSize = config.subpix_window_px
    params.minMarkerPerimeterRate = config.min_marker_perimeter_rate
    params.adaptiveThreshConstant = config.threshold_constant
    params.minDistanceToBorder = config.min_distance_to_border_px
    params.perspectiveRemovePixelPerCell = config.bit_pixels_per_cell
    params.perspectiveRemoveIgnoredMarginPerCell = config.bit_margin_per_cell
    params.errorCorrectionRate = config.error_correction_rate
    windows = tuple(config.threshold_windows_px)
    params.adaptiveThreshWinSizeMin = windows[0]
    params.adaptiveThreshWinSizeMax = windows[-1]
    params.adaptiveThreshWinSizeStep = windows[1] - windows[0] if len(windows) > 1 else 1
    return cv2.aruco.ArucoDetector(dictionary, params)


@dataclasses.dataclass(frozen=True, eq=False)
class MarkerDetection:
    """One detected marker.

    Attributes:
      marker_id: id in the layout's dictionary.
      robot: the robot carrying it.
      face: the plate it is on.
      corners_px: pixel corners, shape (4, 2), in the marker's TL, TR, BR, BL order (as printed).
      rotation_camera_from_marker: shape (3, 3); columns are the marker's x, y, z (normal) axes in
        the camera frame (OpenCV axes).
      position_camera_m: the marker centre in the camera frame, metres, shape (3,).
      reprojection_error_px: RMS corner reprojection error of the chosen pose, pixels.
      alternative_error_px: RMS error of the other IPPE solution, pixels (close to the chosen one's
        when the pose is ambiguous).
      normal_error_deg: how far the chosen pose's world normal elevation is from the expected one,
        degrees.
    """

    marker_id: int
    robot: str
    face: str
    corners_px: np.ndarray
    rotation_camera_from_marker: np.ndarray
    position_camera_m: np.ndarray
    reprojection_error_px: float
    alternative_error_px: float
    normal_error_deg: float

    def area_px(self) -> float:
        """Returns the area of the corner quadrilateral in square pixels."""
        x, y = self.corners_px[:, 0], self.corners_px[:, 1]
        return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def to_gray(image) -> np.ndarray:
    """Returns a uint8 gray image from an RGB or gray image; raises ValueError on anything else.

    Accepted: shape (H, W), (H, W, 1) or (H, W, 3) (RGB, as the simulator renders); dtype uint8, or
    float in [0, 1] with no NaN or infinity.
    """
    if not isinstance(image, np.ndarray):
        raise ValueError(f"image must be a numpy array, got {type(image).__name__}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] != 3):
        raise ValueError(
            f"image must have shape (H, W), (H, W, 1) or (H, W, 3) (RGB), got {image.shape}"
        )
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"image is empty, shape {image.shape}")
    if image.dtype == np.uint8:
        pass
    elif np.issubdtype(image.dtype, np.floating):
        if not np.all(np.isfinite(image)):
            raise ValueError(
                "image contains NaN or infinite values; allowed: finite floats in [0, 1]"
            )
        if image.min() < 0.0 or image.max() > 1.0:
            raise ValueError(
                f"float image values must lie in [0, 1], got [{image.min()}, {image.max()}]"
            )
        image = np.rint(image * 255.0).astype(np.uint8)
    else:
        raise ValueError(f"image dtype must be uint8 or float in [0, 1], got {image.dtype}")
    if image.ndim == 3:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
    return np.ascontiguousarray(image)


def _check_layout(layout: tuple[MarkerPlacement, ...], dictionary) -> dict[int, MarkerPlacement]:
    by_id = {}
    n_ids = dictionary.bytesList.shape[0]
    for placement in layout:
        if placement.marker_id in by_id:
            raise ValueError(f"marker id {placement.marker_id} appears twice in the layout")
        if not 0 <= placement.marker_id < n_ids:
            raise ValueError(
                f"marker id {placement.marker_id} is outside the dictionary "
                f"{DICTIONARY_NAME} (allowed 0-{n_ids - 1})"
            )
        by_id[placement.marker_id] = placement
    return by_id


class MarkerDetector:
    """Finds the layout's ArUco markers in an image and estimates each one's pose.

    Args:
      config: detection settings.
      layout: where each marker id sits on which robot (``perception.layout``).
      camera: the default camera for :meth:`detect` (a fixed overhead camera); a moving camera is
        passed to each call instead.
    """

    def __init__(
        self,
        config: DetectorConfig = DetectorConfig(),
        *,
        layout: tuple[MarkerPlacement, ...] = default_layout(),
        camera: PinholeCamera | None = None,
    ):
        self.config = config
        self.layout = tuple(layout)
        self.camera = camera
        self._dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DICTIONARY_NAME))
        self._by_id = _check_layout(self.layout, self._dictionary)
        if config.expected_ids is None:
            expected = set(self._by_id)
        else:
            expected = {int(i) for i in config.expected_ids}
            unknown = sorted(expected - set(self._by_id))
            if unknown:
                raise ValueError(
                    f"expected_ids {unknown} are not in the layout; allowed: {sorted(self._by_id)}"
                )
        self.expected_ids = frozenset(expected)
        self._detector = aruco_detector(config)

    def placement(self, marker_id: int) -> MarkerPlacement:
        """Returns the layout entry of ``marker_id``; raises ValueError for an unknown id."""
        if marker_id not in self._by_id:
            raise ValueError(f"unknown marker id {marker_id!r}; allowed: {sorted(self._by_id)}")
        return self._by_id[marker_id]

    def detect_all_corners(self, image) -> list[tuple[int, np.ndarray]]:
        """Returns ``(marker_id, corners_px (4, 2))`` for every marker of the dictionary found,
        expected or not (one detection pass to share, e.g. with the wall landmarks), no pose.

        Args:
          image: the image (see :meth:`detect`).
        """
        corners, ids, _ = self._detector.detectMarkers(to_gray(image))
        if ids is None:
            return []
        offset = (
            self.config.apriltag_offset_px if self.config.corner_refinement == "apriltag" else 0.0
        )
        return [
            (int(i), np.asarray(c, dtype=float).reshape(4, 2) - offset)
            for i, c in zip(ids.ravel(), corners, strict=True)
        ]

    def detect_corners(self, image, found=None) -> list[tuple[int, np.ndarray]]:
        """Returns ``(marker_id, corners_px (4, 2))`` for each expected marker found, no pose.

        Args:
          image: the image (see :meth:`detect`); not read when ``found`` is given.
          found: this image's :meth:`detect_all_corners`, from a shared pass.
        """
        found = self.detect_all_corners(image) if found is None else found
        return [(i, c) for i, c in found if i in self.expected_ids]

    def detect(self, image, camera: PinholeCamera | None = None) -> tuple[MarkerDetection, ...]:
        """Returns the expected markers seen in ``image``, sorted by id, each with its pose.

        Args:
          image: shape (H, W, 3) RGB or (H, W) gray, uint8 (or float in [0, 1]); its size must
            match the camera's ``image_size``.
          camera: the camera that took it, with its current extrinsics; defaults to the detector's.

        If an id is found twice (only one such marker exists, so one is false), the detection whose
        pose best fits the level-robot prior is kept.
        """
        camera = camera if camera is not None else self.camera
        if camera is None:
            raise ValueError("no camera: pass camera= to detect() or to MarkerDetector()")
        gray = to_gray(image)
        if (gray.shape[1], gray.shape[0]) != camera.image_size:
            raise ValueError(
                f"image size (width, height) {(gray.shape[1], gray.shape[0])} does not "
                f"match the camera's image_size {camera.image_size}"
            )
        best: dict[int, MarkerDetection] = {}
        for marker_id, corners in self.detect_corners(gray):
            detection = self.marker_pose(marker_id, corners, camera)
            if detection is None:
                continue
            previous = best.get(marker_id)
            if previous is None or (detection.normal_error_deg, detection.reprojection_error_px) < (
                previous.normal_error_deg,
                previous.reprojection_error_px,
            ):
                best[marker_id] = detection
        return tuple(best[i] for i in sorted(best))

    def marker_pose(
        self, marker_id: int, corners: np.ndarray, camera: PinholeCamera
    ) -> MarkerDetection | None:
        """Returns the detection record of one marker's corners (TL, TR, BR, BL pixels, shape
        (4, 2)) with its IPPE pose, the level-robot prior resolving the flip; None when PnP fails."""
        placement = self._by_id[marker_id]
        h = 0.5 * placement.size_m
        object_points = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
        n_solutions, rvecs, tvecs, errors = cv2.solvePnPGeneric(
            object_points,
            np.ascontiguousarray(corners),
            camera.matrix,
            camera.distortion if camera.distortion.size else None,
            flags=cv2.SOLVEPNP_IPPE_SQUARE,
        )
        if not n_solutions:
            return None
        distortion = camera.distortion if camera.distortion.size else None
        errors = np.empty(n_solutions)
        for k in range(n_solutions):  # computed here: OpenCV may leave its own errors unset
            projected, _ = cv2.projectPoints(
                object_points, rvecs[k], tvecs[k], camera.matrix, distortion
            )
            errors[k] = np.sqrt(np.mean(np.sum((projected.reshape(4, 2) - corners) ** 2, axis=1)))
        if not np.all(np.isfinite(errors)):
            return None
        expected_elevation = np.degrees(np.arcsin(np.clip(placement.rotation[2, 2], -1.0, 1.0)))
        candidates = []
        for k in range(n_solutions):
            rotation, _ = cv2.Rodrigues(rvecs[k])
            normal_world = camera.rotation_world_from_camera @ rotation[:, 2]
            elevation = np.degrees(np.arcsin(np.clip(normal_world[2], -1.0, 1.0)))
            candidates.append(
                (
                    abs(elevation - expected_elevation),
                    errors[k],
                    rotation,
                    np.asarray(tvecs[k], dtype=float).ravel(),
                )
            )
        plausible = [
            c for c in candidates if c[1] <= errors.min() + self.config.ambiguity_tolerance_px
        ]
        chosen = min(plausible, key=lambda c: (c[0], c[1]))
        others = [c[1] for c in candidates if c is not chosen]
        return MarkerDetection(
            marker_id=marker_id,
            robot=placement.robot,
            face=placement.face,
            corners_px=corners,
            rotation_camera_from_marker=chosen[2],
            position_camera_m=chosen[3],
            reprojection_error_px=float(chosen[1]),
            alternative_error_px=float(others[0]) if others else float("nan"),
            normal_error_deg=float(chosen[0]),
        )
