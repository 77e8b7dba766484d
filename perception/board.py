"""The ChArUco camera-calibration board, defined once.

``peoplebot markers`` prints it (``imitation.printables``) and a calibration command detects it: both
build the board from the same :class:`BoardSpec`, so the printed squares and the sizes the solver
assumes cannot drift apart. Its markers come from a dictionary other than the robots'
(``perception.layout.DICTIONARY_NAME``), so a robot tracker never mistakes a board marker for a plate.

Board frame (OpenCV's): origin at the board's top-left chessboard corner as printed, x along the
``squares_x`` squares, y along the ``squares_y`` squares, z into the board; metres.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from perception.layout import DICTIONARY_NAME


@dataclasses.dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board.

    Attributes:
      squares_x: chessboard squares along the board's x (the long side as printed).
      squares_y: chessboard squares along its y.
      square_m: side of one chessboard square, metres.
      marker_m: side of the ArUco marker inside each white square (its black square), metres.
      dictionary: name of a ``cv2.aruco`` predefined dictionary, e.g. "DICT_5X5_100"; it must hold
        one id per white square and must not be the robots' dictionary.
    """

    squares_x: int = 7
    squares_y: int = 5
    square_m: float = 0.030
    marker_m: float = 0.022
    dictionary: str = "DICT_5X5_100"

    def __post_init__(self):
        if self.squares_x < 2 or self.squares_y < 2:
            raise ValueError(
                f"a board needs at least 2 x 2 squares, got {self.squares_x} x {self.squares_y}"
            )
        if not 0.0 < self.marker_m < self.square_m:
            raise ValueError(
                f"need 0 < marker_m < square_m, got marker_m={self.marker_m}, "
                f"square_m={self.square_m}"
            )
        if not self.dictionary.startswith("DICT_") or not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(
                f"unknown ArUco dictionary {self.dictionary!r}; allowed: cv2.aruco.DICT_*"
            )
        if self.dictionary == DICTIONARY_NAME:
            raise ValueError(
                f"the board must not use the robots' dictionary {DICTIONARY_NAME!r}: its ids would "
                "collide with the marker plates'"
            )
        available = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        if available.bytesList.shape[0] < self.marker_count:
            raise ValueError(
                f"{self.dictionary} holds {available.bytesList.shape[0]} markers; the board needs "
                f"{self.marker_count}"
            )

    @property
    def marker_count(self) -> int:
        """Returns the number of markers (one per white square)."""
        return (self.squares_x * self.squares_y) // 2

    @property
    def size_m(self) -> tuple[float, float]:
        """Returns the board's printed width and height (x, y), metres."""
        return self.squares_x * self.square_m, self.squares_y * self.square_m


#: The board ``peoplebot markers`` prints: 7 x 5 squares of 30 mm with 22 mm markers, 210 x 150 mm,
#: which fits A4 and US letter in landscape.
DEFAULT_BOARD = BoardSpec()


def board(spec: BoardSpec = DEFAULT_BOARD) -> cv2.aruco.CharucoBoard:
    """Returns the OpenCV board for ``spec`` (object points in metres)."""
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, spec.dictionary))
    return cv2.aruco.CharucoBoard(
        (spec.squares_x, spec.squares_y), spec.square_m, spec.marker_m, dictionary
    )


def board_image(spec: BoardSpec = DEFAULT_BOARD, dots_per_mm: float = 10.0) -> np.ndarray:
    """Returns the board as printed, without margin, shape (rows, cols), uint8, 0 black, 255 white.

    Each square is ``round(square_m * 1000 * dots_per_mm)`` pixels, so the image spans
    ``squares_x`` by ``squares_y`` whole squares; its rows run along the board's y, its columns along x.
    """
    if not dots_per_mm > 0:
        raise ValueError(f"dots_per_mm must be positive, got {dots_per_mm}")
    square_px = int(round(spec.square_m * 1000.0 * dots_per_mm))
    if square_px < 8:
        raise ValueError(
            f"dots_per_mm={dots_per_mm} gives {square_px} px per square; need at least 8"
        )
    size = (spec.squares_x * square_px, spec.squares_y * square_px)
    return board(spec).generateImage(size, marginSize=0, borderBits=1)
