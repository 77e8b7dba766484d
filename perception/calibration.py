"""Camera intrinsics and lens distortion from images of a ChArUco board (OpenCV only).

Each image's board corners are found by ``cv2.aruco.CharucoDetector`` with OpenCV's defaults (the
ArUco markers, then the chessboard corners between pairs of them, refined to sub-pixel; its second
search for missed markers, ``tryRefineMarkers``, adds corners but worse ones on small views), matched
to the board's corners in metres by ``CharucoBoard.matchImagePoints``, and all views are fitted at
once by ``cv2.calibrateCamera`` (Zhang's method, then Levenberg-Marquardt on the reprojection
error). An image is rejected when it shows fewer than ``min_corners`` corners or only corners on one
line (they fix no homography).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import cv2
import numpy as np

from perception.board import BoardSpec, board
from perception.camera import PinholeCamera

#: Distortion models of :class:`CalibrationConfig`, with the OpenCV flags that fix the others:
#: ``plumb_bob`` fits k1, k2, p1, p2, k3 (ROS's default); ``radial`` fits k1, k2 (tangential
#: distortion and k3 held at 0), for a good lens; ``none`` holds all five at 0 (a renderer).
DISTORTION_FLAGS = {
    "plumb_bob": 0,
    "radial": cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3,
    "none": cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3,
}

#: Fewest usable views a calibration accepts (Zhang's method needs three for a general K).
MIN_VIEWS = 3


@dataclasses.dataclass(frozen=True)
class CalibrationConfig:
    """What a calibration fits.

    Attributes:
      distortion: one of ``DISTORTION_FLAGS``.
      fix_principal_point: hold (cx, cy) at the image centre, ``((w - 1) / 2, (h - 1) / 2)``.
      square_pixels: fit one focal length (fx = fy).
      min_corners: fewest ChArUco corners an image must show to be used (at least 4).
    """

    distortion: str = "plumb_bob"
    fix_principal_point: bool = False
    square_pixels: bool = False
    min_corners: int = 6

    def __post_init__(self):
        if self.distortion not in DISTORTION_FLAGS:
            raise ValueError(
                f"distortion must be one of {', '.join(DISTORTION_FLAGS)}, got {self.distortion!r}"
            )
        if (
            isinstance(self.min_corners, bool)
            or not isinstance(self.min_corners, int)
            or self.min_corners < 4
        ):
            raise ValueError(f"min_corners must be an integer >= 4, got {self.min_corners!r}")

    @property
    def flags(self) -> int:
        """Returns the ``cv2.calibrateCamera`` flags."""
        flags = DISTORTION_FLAGS[self.distortion]
        if self.fix_principal_point:
            flags |= cv2.CALIB_FIX_PRINCIPAL_POINT
        if self.square_pixels:
            flags |= cv2.CALIB_FIX_ASPECT_RATIO
        return flags


@dataclasses.dataclass(frozen=True, eq=False)
class CalibrationResult:
    """A fitted camera.

    Attributes:
      camera: the intrinsics (matrix, 5 plumb_bob distortion coefficients, image size) at the
        identity pose.
      rms_px: root-mean-square reprojection error over all corners of the used images, pixels.
      corners_per_image: ChArUco corners found in each input image, in input order (0: none).
      used: indices of the images the fit used.
      rejected: indices of the images it did not (too few corners, or all on one line).
      view_rms_px: each used image's own RMS reprojection error, pixels, in the order of ``used``.
      config: the calibration's configuration.
    """

    camera: PinholeCamera
    rms_px: float
    corners_per_image: tuple[int, ...]
    used: tuple[int, ...]
    rejected: tuple[int, ...]
    view_rms_px: tuple[float, ...]
    config: CalibrationConfig

    @property
    def matrix(self) -> np.ndarray:
        """Returns K, shape (3, 3), pixels."""
        return self.camera.matrix

    @property
    def distortion(self) -> np.ndarray:
        """Returns ``(k1, k2, p1, p2, k3)``, shape (5,)."""
        return self.camera.distortion

    @property
    def image_size(self) -> tuple[int, int]:
        """Returns ``(width, height)`` in pixels."""
        return self.camera.image_size


def _gray(image, index: int) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise ValueError(
            f"image {index} must be a uint8 (H, W) or (H, W, 3) array, got {image.dtype} "
            f"{image.shape}"
        )
    if image.ndim == 3:
        if image.shape[2] != 3:
            raise ValueError(f"image {index} must have 3 channels, got shape {image.shape}")
        image = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
    return np.ascontiguousarray(image)


def calibrate(
    images: Sequence[np.ndarray],
    spec: BoardSpec,
    config: CalibrationConfig = CalibrationConfig(),
) -> CalibrationResult:
    """Returns the camera fitted to images of the ChArUco board ``spec``.

    Args:
      images: uint8 frames of one camera, gray (H, W) or RGB (H, W, 3), all of one size.
      spec: the board the images show.
      config: what to fit (distortion model, fixed principal point, square pixels).

    Raises ValueError when the images differ in size or fewer than ``MIN_VIEWS`` show the board.
    """
    if not isinstance(config, CalibrationConfig):
        raise ValueError(f"config must be a CalibrationConfig, got {type(config).__name__}")
    charuco = board(spec)
    grays = [_gray(image, i) for i, image in enumerate(images)]
    if not grays:
        raise ValueError("no images to calibrate from")
    sizes = {g.shape for g in grays}
    if len(sizes) != 1:
        raise ValueError(f"images must all have one size, got (H, W) sizes {sorted(sizes)}")
    height, width = grays[0].shape
    detector = cv2.aruco.CharucoDetector(charuco)
    counts, used, rejected, object_points, image_points = [], [], [], [], []
    for i, gray in enumerate(grays):
        corners, ids, _, _ = detector.detectBoard(gray)
        n = 0 if ids is None else len(ids)
        counts.append(n)
        if n < config.min_corners or charuco.checkCharucoCornersCollinear(ids):
            rejected.append(i)
            continue
        board_points, pixels = charuco.matchImagePoints(corners, ids)
        used.append(i)
        object_points.append(board_points.reshape(-1, 1, 3).astype(np.float32))
        image_points.append(pixels.reshape(-1, 1, 2).astype(np.float32))
    if len(used) < MIN_VIEWS:
        raise ValueError(
            f"only {len(used)} of {len(grays)} images show at least {config.min_corners} "
            f"non-collinear board corners; calibration needs {MIN_VIEWS} (corners per image: "
            f"{counts})"
        )
    # Initial K: square pixels (the ratio CALIB_FIX_ASPECT_RATIO keeps), centred principal point.
    initial = np.array([[1.0, 0.0, 0.5 * (width - 1)], [0.0, 1.0, 0.5 * (height - 1)], [0, 0, 1]])
    rms, matrix, distortion, rvecs, tvecs = cv2.calibrateCamera(
        object_points, image_points, (width, height), initial, np.zeros(5), flags=config.flags
    )
    view_rms = []
    for points, pixels, rvec, tvec in zip(object_points, image_points, rvecs, tvecs, strict=True):
        projected, _ = cv2.projectPoints(points, rvec, tvec, matrix, distortion)
        view_rms.append(float(np.sqrt(np.mean(np.sum((projected - pixels) ** 2, axis=-1)))))
    camera = PinholeCamera(matrix, np.asarray(distortion).ravel()[:5], (width, height))
    return CalibrationResult(
        camera=camera,
        rms_px=float(rms),
        corners_per_image=tuple(counts),
        used=tuple(used),
        rejected=tuple(rejected),
        view_rms_px=tuple(view_rms),
        config=config,
    )
