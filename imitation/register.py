"""``peoplebot register``: a fixed camera's pose from its photo of floor markers at known places,
written into the arena file ``peoplebot watch`` reads.

On a real floor: print the layout (``peoplebot markers --landmarks FLOOR.toml``), tape the markers
where the file says, take one photo with the camera as it will record, run this, take them away.
The camera's intrinsics come from ``peoplebot calibrate`` (a ROS ``camera_info`` file, at the
resolution the camera records). The simulated arena's layout is
``models/arena/floor_markers.toml``.
"""

from __future__ import annotations

import os
import pathlib

import cv2

from perception import camerainfo
from perception.arenafile import read_arena, write_arena
from perception.landmarks import read_landmark_map
from perception.markers import MarkerDetector
from perception.registration import register_camera


def run(
    photo: str | os.PathLike,
    camera_info: str | os.PathLike,
    markers: str | os.PathLike,
    arena: str | os.PathLike,
    out: str | os.PathLike,
    min_markers: int = 4,
) -> dict:
    """Fits the camera that took ``photo`` to the floor markers of ``markers`` (a landmark map
    file), with the intrinsics of ``camera_info``; writes ``arena``'s room with that camera pose to
    ``out`` and returns the figures (markers used, RMS corner error in pixels, the camera's
    position in metres). ValueError names the file or the count when something is missing."""
    photo = pathlib.Path(photo)
    image = cv2.imread(str(photo), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError(f"{photo}: not an image OpenCV can read")
    intrinsics = camerainfo.read(camera_info).camera
    height, width = image.shape[:2]
    if (width, height) != tuple(intrinsics.image_size):
        raise ValueError(
            f"{photo} is {width}x{height} pixels but {camera_info} describes "
            f"{intrinsics.image_size[0]}x{intrinsics.image_size[1]}: photograph at the "
            "resolution the camera was calibrated at"
        )
    layout = read_landmark_map(markers)
    room = read_arena(arena)
    found = MarkerDetector().detect_all_corners(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
    fit = register_camera(intrinsics, found, layout, min_markers=min_markers)
    path = write_arena(out, room.arena, fit.camera)
    report = {
        "out": str(path),
        "markers": list(fit.marker_ids),
        "rms_error_px": fit.rms_error_px,
        "camera_position_m": [float(v) for v in fit.camera.position_world],
    }
    print(
        f"registered on {len(fit.marker_ids)} of {len(layout)} markers: corners fitted within "
        f"{fit.rms_error_px:.2f} px RMS; camera at "
        + ", ".join(f"{v:.3f}" for v in fit.camera.position_world)
        + f" m; written: {path}"
    )
    return report
