"""``peoplebot calibrate``: a camera's intrinsics and distortion from photos of the ChArUco board,
written as a ROS ``camera_info`` YAML file.

The board is given as a spec string, ``SQUARES_XxSQUARES_Y:SQUARE_M:MARKER_M[:DICTIONARY]``, e.g.
``7x5:0.03:0.022:DICT_5X5_100`` (the board ``peoplebot markers`` prints, ``DEFAULT_BOARD``): squares
along x and y, the square's and the marker's sides in metres as measured on the print, and the ArUco
dictionary (``DEFAULT_BOARD``'s when left out).
"""

from __future__ import annotations

import os
import pathlib
import re
from collections.abc import Sequence

import cv2

from perception import camerainfo
from perception.board import DEFAULT_BOARD, BoardSpec
from perception.calibration import CalibrationConfig, CalibrationResult, calibrate

#: File name endings read from an image folder (lower case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")

_SPEC = re.compile(
    r"^\s*(?P<x>\d+)\s*[xX]\s*(?P<y>\d+)\s*:\s*(?P<square>[^:\s]+)\s*:\s*(?P<marker>[^:\s]+)"
    r"\s*(?::\s*(?P<dictionary>\w+)\s*)?$"
)
SPEC_FORMAT = "SQUARES_XxSQUARES_Y:SQUARE_M:MARKER_M[:DICTIONARY], e.g. 7x5:0.03:0.022:DICT_5X5_100"


def parse_board_spec(text: str) -> BoardSpec:
    """Returns the :class:`BoardSpec` of a spec string (see the module's docstring); ValueError
    names the string and the format when it is malformed or describes no valid board."""
    match = _SPEC.match(text) if isinstance(text, str) else None
    if match is None:
        raise ValueError(f"board spec {text!r} is not of the form {SPEC_FORMAT}")
    try:
        square_m, marker_m = float(match["square"]), float(match["marker"])
    except ValueError:
        raise ValueError(
            f"board spec {text!r}: square and marker sides must be numbers in metres ({SPEC_FORMAT})"
        ) from None
    if not (0.0 < square_m < 10.0 and 0.0 < marker_m < 10.0):
        raise ValueError(
            f"board spec {text!r}: square and marker sides must be in metres, in (0, 10), got "
            f"{square_m} and {marker_m}"
        )
    try:
        return BoardSpec(
            squares_x=int(match["x"]),
            squares_y=int(match["y"]),
            square_m=square_m,
            marker_m=marker_m,
            dictionary=match["dictionary"] or DEFAULT_BOARD.dictionary,
        )
    except ValueError as error:
        raise ValueError(f"board spec {text!r}: {error}") from None


def format_board_spec(spec: BoardSpec) -> str:
    """Returns the spec string of ``spec`` (``parse_board_spec`` reads it back)."""
    square_m, marker_m = float(spec.square_m), float(spec.marker_m)
    return f"{spec.squares_x}x{spec.squares_y}:{square_m!r}:{marker_m!r}:{spec.dictionary}"


#: The ``--board`` default: the board ``peoplebot markers`` prints.
DEFAULT_BOARD_SPEC = format_board_spec(DEFAULT_BOARD)


def image_paths(images: str | os.PathLike | Sequence[str | os.PathLike]) -> list[pathlib.Path]:
    """Returns the image files of ``images``: files as given, folders' image files (by their
    ``IMAGE_SUFFIXES``) sorted by name."""
    if isinstance(images, (str, os.PathLike)):
        images = [images]
    paths = []
    for item in images:
        path = pathlib.Path(item)
        if path.is_dir():
            found = sorted(
                p for p in path.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
            )
            if not found:
                raise ValueError(
                    f"folder {path} holds no images (file names ending {', '.join(IMAGE_SUFFIXES)})"
                )
            paths.extend(found)
        elif path.is_file():
            paths.append(path)
        else:
            raise ValueError(f"no such image file or folder: {path}")
    if not paths:
        raise ValueError("no images given")
    return paths


def _read_gray(paths: list[pathlib.Path]) -> list:
    grays = []
    for path in paths:
        gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            raise ValueError(f"{path}: not an image OpenCV can read")
        if grays and gray.shape != grays[0].shape:
            raise ValueError(
                f"{path} is {gray.shape[1]}x{gray.shape[0]} pixels but {paths[0]} is "
                f"{grays[0].shape[1]}x{grays[0].shape[0]}: calibrate one camera mode at a time"
            )
        grays.append(gray)
    return grays


def summary(result: CalibrationResult, paths: Sequence[pathlib.Path], out: pathlib.Path) -> dict:
    """Returns the calibration's figures as a JSON-ready dict."""
    k = result.matrix
    return {
        "out": str(out),
        "image_size": list(result.image_size),
        "rms_px": result.rms_px,
        "fx_px": float(k[0, 0]),
        "fy_px": float(k[1, 1]),
        "cx_px": float(k[0, 2]),
        "cy_px": float(k[1, 2]),
        "distortion": result.distortion.tolist(),
        "config": {
            "distortion": result.config.distortion,
            "fix_principal_point": result.config.fix_principal_point,
            "square_pixels": result.config.square_pixels,
            "min_corners": result.config.min_corners,
        },
        "images": [
            {"path": str(path), "corners": n, "used": i in result.used}
            for i, (path, n) in enumerate(zip(paths, result.corners_per_image, strict=True))
        ],
        "used": len(result.used),
        "rejected": [str(paths[i]) for i in result.rejected],
    }


def run(
    images: str | os.PathLike | Sequence[str | os.PathLike],
    board: BoardSpec | str = DEFAULT_BOARD,
    out: str | os.PathLike = "camera_info.yaml",
    config: CalibrationConfig = CalibrationConfig(),
    camera_name: str = "camera",
) -> dict:
    """Calibrates a camera from photos of the board, writes ``out`` (ROS ``camera_info`` YAML),
    prints the reprojection error and returns :func:`summary`'s figures.

    Args:
      images: image files, or folders of them, all from one camera at one resolution.
      board: a :class:`BoardSpec` or a spec string (``SPEC_FORMAT``).
      out: the ``camera_info`` YAML file to write.
      config: what to fit (distortion model, fixed principal point, square pixels).
      camera_name: the file's ``camera_name``.
    """
    spec = parse_board_spec(board) if isinstance(board, str) else board
    if not isinstance(spec, BoardSpec):
        raise ValueError(
            f"board must be a BoardSpec or a spec string ({SPEC_FORMAT}), got {board!r}"
        )
    paths = image_paths(images)
    result = calibrate(_read_gray(paths), spec, config)
    out = camerainfo.write(out, result.camera, camera_name)
    report = summary(result, paths, out)
    print(
        f"calibrated on {report['used']} of {len(paths)} images: reprojection error "
        f"{result.rms_px:.3f} px RMS; fx {report['fx_px']:.2f} fy {report['fy_px']:.2f} "
        f"cx {report['cx_px']:.2f} cy {report['cy_px']:.2f} px; written: {out}"
    )
    return report
