"""Where the ArUco markers sit on each PeopleBot.

Robot frame: origin on the floor midway between the drive wheels (the centre of rotation), x forward,
y to the robot's left, z up; metres.

Marker frame (OpenCV's ArUco convention): origin at the marker's centre, x towards the right edge and
y towards the top edge of the marker as printed, z out of its face. Corners are listed top-left,
top-right, bottom-right, bottom-left, as ``cv2.aruco`` returns them. ``size_m`` is the side of the black
square (the marker with its black border, without the white quiet zone around it).

The simulator's models (``models/peoplebot``) are generated from this table, so the two cannot drift.
"""

from __future__ import annotations

import dataclasses

import numpy as np

DICTIONARY_NAME = "DICT_4X4_50"
ROBOT_NAMES = ("teacher", "student")
FACE_NAMES = ("top", "back", "left", "right", "front")
ID_BASE = {"teacher": 0, "student": 10}

TOP_MARKER_SIZE_M = 0.30
SIDE_MARKER_SIZE_M = 0.24
#: White quiet zone each side of a marker, metres.
QUIET_ZONE_M = 0.03
#: Height of the top face of the upper deck, metres (ARIA p2pb / MobileSim: about 1.115 m).
TOP_DECK_HEIGHT_M = 1.115
SIDE_MARKER_HEIGHT_M = 0.72

# face -> (centre in robot frame, outward normal = marker z, marker "up" = marker y)
_FACES = {
    "top": ((-0.06, 0.0, TOP_DECK_HEIGHT_M + 0.004), (0, 0, 1), (1, 0, 0)),
    "back": ((-0.184, 0.0, SIDE_MARKER_HEIGHT_M), (-1, 0, 0), (0, 0, 1)),
    "left": ((-0.02, 0.164, SIDE_MARKER_HEIGHT_M), (0, 1, 0), (0, 0, 1)),
    "right": ((-0.02, -0.164, SIDE_MARKER_HEIGHT_M), (0, -1, 0), (0, 0, 1)),
    "front": ((0.144, 0.0, SIDE_MARKER_HEIGHT_M), (1, 0, 0), (0, 0, 1)),
}
_FACE_INDEX = {face: i for i, face in enumerate(FACE_NAMES)}


@dataclasses.dataclass(frozen=True)
class MarkerPlacement:
    """One marker on one robot.

    Attributes:
      marker_id: the id in ``DICTIONARY_NAME``.
      robot: which robot carries it (one of ``ROBOT_NAMES``).
      face: which plate (one of ``FACE_NAMES``).
      size_m: side of the black square in metres.
      position_m: marker centre in the robot frame, metres, shape (3,).
      rotation: robot-from-marker rotation, shape (3, 3); its columns are the marker's x, y, z axes
        expressed in the robot frame.
    """

    marker_id: int
    robot: str
    face: str
    size_m: float
    position_m: np.ndarray
    rotation: np.ndarray

    def corners_robot(self) -> np.ndarray:
        """Returns the four corners in the robot frame, shape (4, 3), in ArUco order (TL, TR, BR, BL)."""
        h = 0.5 * self.size_m
        local = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
        return local @ self.rotation.T + self.position_m


def marker_id(robot: str, face: str) -> int:
    """Returns the id of the marker on ``face`` of ``robot``."""
    if robot not in ID_BASE:
        raise ValueError(f"unknown robot {robot!r}; allowed: {', '.join(ROBOT_NAMES)}")
    if face not in _FACE_INDEX:
        raise ValueError(f"unknown face {face!r}; allowed: {', '.join(FACE_NAMES)}")
    return ID_BASE[robot] + _FACE_INDEX[face]


def _placement(robot: str, face: str) -> MarkerPlacement:
    centre, normal, up = (np.asarray(v, dtype=float) for v in _FACES[face])
    right = np.cross(up, normal)  # marker x = y cross z
    rotation = np.column_stack([right, up, normal])
    size = TOP_MARKER_SIZE_M if face == "top" else SIDE_MARKER_SIZE_M
    return MarkerPlacement(marker_id(robot, face), robot, face, size, centre, rotation)


def default_layout() -> tuple[MarkerPlacement, ...]:
    """Returns every marker on both robots: ids 0-4 on the teacher, 10-14 on the student."""
    return tuple(_placement(robot, face) for robot in ROBOT_NAMES for face in FACE_NAMES)
