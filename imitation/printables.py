"""``peoplebot markers``: the robots' marker plates and the calibration board as a PDF at true scale.

Every fact comes from one place: the plates from ``perception.layout`` (ids, faces, sizes, quiet zone,
positions), the board from ``perception.board.DEFAULT_BOARD``, the robot's outline in the placement
drawing from the PeopleBot model (``models/peoplebot/peoplebot.xml``, read as XML; the simulator is
not imported).

Pages: 1, where each plate goes (top and side view at 1:10, a table, instructions); 2, the ChArUco
board with a 10 cm scale bar, in landscape; then one plate a page, in ``default_layout()`` order;
then, given an arena's landmark map, one wall landmark a page, in id order.

Paper: ``paper`` names a series and its smallest sheet, "A4" (A4, A3, A2, A1, A0), "A3" (A3 up) or
"letter" (letter, tabloid, ANSI C, ANSI D). The placement sheet is printed on ``paper``; the board
and each plate on the smallest sheet of the series, from ``paper`` up, that holds it with
``MARGIN_MM`` all round and its label. A plate is its black square plus the white quiet zone each
side (0.30 + 2 x 0.03 = 0.36 m on the top deck, 0.30 m on the column), so with the present layout
every plate needs A2 (or ANSI C): neither fits A3's 297 mm width.

True scale: each page's figure is exactly the sheet's size in inches, with one axes over the whole
page whose data units are millimetres of paper (x from 0 to the sheet's width, y from 0 up to its
height). Rasters are drawn with ``interpolation="none"``, which the PDF backend embeds unresampled
and places with an exact affine transform ("nearest" would resample them to the figure's dpi and
round their edges to that pixel grid); the scale bars and cut lines are vector paths.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import xml.etree.ElementTree as ElementTree

import cv2
import numpy as np
import peoplebot_models
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from perception import layout
from perception.board import DEFAULT_BOARD, BoardSpec, board_image
from perception.landmarks import LandmarkMap, LandmarkMarker
from perception.layout import MarkerPlacement

MM_PER_INCH = 25.4
#: Blank paper kept all round each page, mm: wider than a printer's unprintable edge (about 5 mm).
MARGIN_MM = 12.0
#: Sheet sizes (width, height) in portrait, mm.
SHEETS_MM = {
    "A4": (210.0, 297.0),
    "A3": (297.0, 420.0),
    "A2": (420.0, 594.0),
    "A1": (594.0, 841.0),
    "A0": (841.0, 1189.0),
    "letter": (215.9, 279.4),
    "tabloid": (279.4, 431.8),
    "ANSI C": (431.8, 558.8),
    "ANSI D": (558.8, 863.6),
}
#: The sheets each ``paper`` may use, smallest first.
PAPER_SERIES = {
    "A4": ("A4", "A3", "A2", "A1", "A0"),
    "A3": ("A3", "A2", "A1", "A0"),
    "letter": ("letter", "tabloid", "ANSI C", "ANSI D"),
}
#: Raster resolution of the marker and board images embedded in the PDF, dots per mm.
PDF_DOTS_PER_MM = 4.0
#: Scale of the placement drawings (paper mm per robot mm).
DRAWING_SCALE = 0.1

# Page furniture of a plate page, mm: band above the plate (its "top edge" note), band below it
# (label and scale bar).
_PLATE_HEAD_MM = 14.0
_PLATE_FOOT_MM = 62.0
_BOARD_HEAD_MM = 10.0
_BOARD_FOOT_MM = 20.0
_CUT_GREY = "0.45"
_PLATE_COLOUR = "tab:blue"

_DIRECTION_WORDS = {
    (1, 0, 0): "forward (+x)",
    (-1, 0, 0): "backward (-x)",
    (0, 1, 0): "left (+y)",
    (0, -1, 0): "right (-y)",
    (0, 0, 1): "up (+z)",
    (0, 0, -1): "down (-z)",
}


@dataclasses.dataclass(frozen=True)
class _Sheet:
    name: str
    width_mm: float
    height_mm: float


_WORLD_DIRECTION_WORDS = {
    (1, 0, 0): "east (+x)",
    (-1, 0, 0): "west (-x)",
    (0, 1, 0): "north (+y)",
    (0, -1, 0): "south (-y)",
    (0, 0, 1): "up (+z)",
    (0, 0, -1): "down (-z)",
}


def _direction_words(vector: np.ndarray, words: dict = _DIRECTION_WORDS) -> str:
    key = tuple(int(v) for v in np.round(vector))
    if np.allclose(vector, key, atol=1e-6) and key in words:
        return words[key]
    return "({:+.2f}, {:+.2f}, {:+.2f})".format(*vector)


def _sheet_for(paper: str, width_mm: float, height_mm: float, landscape: bool = False) -> _Sheet:
    """Returns the smallest sheet of ``paper``'s series holding ``width_mm`` x ``height_mm``."""
    for name in PAPER_SERIES[paper]:
        w, h = SHEETS_MM[name]
        if landscape:
            w, h = h, w
        if w >= width_mm and h >= height_mm:
            return _Sheet(name, w, h)
    raise ValueError(
        f"{width_mm:.0f} x {height_mm:.0f} mm does not fit any sheet of {PAPER_SERIES[paper]}"
    )


def _marker_cells(marker_id: int) -> np.ndarray:
    """Returns the marker with its black border at one pixel per cell, uint8, 0 black, 255 white."""
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, layout.DICTIONARY_NAME))
    cells = dictionary.markerSize + 2
    return cv2.aruco.generateImageMarker(dictionary, int(marker_id), cells, borderBits=1)


def plate_side_mm(placement, quiet_zone_m: float = layout.QUIET_ZONE_M) -> float:
    """Returns the side of the printed plate (black square plus quiet zone both sides), mm, of a
    robot's ``MarkerPlacement`` or a wall's ``LandmarkMarker``."""
    return 1000.0 * (placement.size_m + 2.0 * quiet_zone_m)


def plate_image(
    placement, dots_per_mm: float, quiet_zone_m: float = layout.QUIET_ZONE_M
) -> np.ndarray:
    """Returns the plate as printed: the marker with its white quiet zone, shape (n, n), uint8
    (a robot's ``MarkerPlacement`` or a wall's ``LandmarkMarker``).

    ``n = round(plate_side_mm(placement) * dots_per_mm)``; row 0 is the plate's top edge (the
    marker's +y), 0 is black and 255 white. Each pixel takes the colour of the marker cell under its
    centre, so the black square spans ``size_m * 1000 * dots_per_mm`` pixels (exactly when the
    quiet zone and a cell are whole numbers of pixels, else within one). The PDF embeds this raster
    at ``PDF_DOTS_PER_MM``.
    """
    if not dots_per_mm > 0:
        raise ValueError(f"dots_per_mm must be positive, got {dots_per_mm}")
    cells = _marker_cells(placement.marker_id)
    side_mm = plate_side_mm(placement, quiet_zone_m)
    n = int(round(side_mm * dots_per_mm))
    if n < 2 * cells.shape[0]:
        raise ValueError(f"dots_per_mm={dots_per_mm} gives {n} px for the plate; too few")
    centres_mm = (np.arange(n) + 0.5) * (side_mm / n)
    cell_mm = 1000.0 * placement.size_m / cells.shape[0]
    index = np.floor((centres_mm - 1000.0 * quiet_zone_m) / cell_mm).astype(int)
    inside = (index >= 0) & (index < cells.shape[0])
    clipped = np.clip(index, 0, cells.shape[0] - 1)
    image = cells[np.ix_(clipped, clipped)]
    image[~inside, :] = 255
    image[:, ~inside] = 255
    return np.ascontiguousarray(image)


def _new_page(sheet: _Sheet):
    """Returns a figure the size of ``sheet`` and one axes over it in millimetres of paper."""
    fig = Figure(figsize=(sheet.width_mm / MM_PER_INCH, sheet.height_mm / MM_PER_INCH))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0.0, sheet.width_mm)
    ax.set_ylim(0.0, sheet.height_mm)
    ax.set_aspect("equal")
    ax.set_axis_off()
    return fig, ax


def _draw_raster(ax, image: np.ndarray, left: float, bottom: float, width: float, height: float):
    """Draws a grey uint8 raster (row 0 on top) at exactly ``width`` x ``height`` mm."""
    rgb = np.repeat(image[:, :, None], 3, axis=2)
    ax.imshow(
        rgb,
        extent=(left, left + width, bottom, bottom + height),
        origin="upper",
        interpolation="none",
    )


def _scale_bar(ax, left: float, bottom: float):
    """Draws a 100 mm bar of ten alternating 10 mm blocks, 4 mm high, labelled below."""
    for i in range(10):
        ax.add_patch(
            Rectangle(
                (left + 10.0 * i, bottom),
                10.0,
                4.0,
                facecolor="black" if i % 2 == 0 else "white",
                edgecolor="black",
                linewidth=0.3,
            )
        )
    for cm in (0, 5, 10):
        ax.text(left + 10.0 * cm, bottom - 1.2, f"{cm}", ha="center", va="top", fontsize=7)
    ax.text(
        left + 102.0,
        bottom + 2.0,
        "10 cm: must measure 100 mm",
        ha="left",
        va="center",
        fontsize=7,
    )


def _faces_text(placement: MarkerPlacement) -> str:
    normal = _direction_words(placement.rotation[:, 2])
    if placement.face == "top":
        return f"on the upper deck, facing {normal}"
    return f"on the column's {placement.face} face, facing {normal}"


def _centre_text(placement: MarkerPlacement) -> str:
    x, y, z = 1000.0 * placement.position_m
    return f"x = {x:.0f}, y = {y:.0f}, z = {z:.0f} mm"


def _draw_plate(ax, sheet: _Sheet, image, side: float, up: str) -> float:
    """Draws a plate's image ``side`` mm square, centred under the sheet's head, its cut line and
    the arrow saying which way its top edge points (``up``); returns the plate's bottom (mm)."""
    left = 0.5 * (sheet.width_mm - side)
    top = sheet.height_mm - MARGIN_MM - _PLATE_HEAD_MM
    bottom = top - side
    _draw_raster(ax, image, left, bottom, side, side)
    ax.add_patch(
        Rectangle(
            (left, bottom), side, side, fill=False, edgecolor=_CUT_GREY, linewidth=0.3, zorder=3
        )
    )
    ax.text(
        sheet.width_mm / 2,
        top + 3.0,
        f"\u25b2 TOP EDGE of the marker: mount it pointing {up}",
        ha="center",
        va="bottom",
        fontsize=14,
        weight="bold",
    )
    return bottom


def _draw_plate_page(ax, sheet: _Sheet, placement: MarkerPlacement) -> None:
    side = plate_side_mm(placement)
    bottom = _draw_plate(
        ax,
        sheet,
        plate_image(placement, PDF_DOTS_PER_MM),
        side,
        _direction_words(placement.rotation[:, 1]),
    )
    size_mm = 1000.0 * placement.size_m
    quiet_mm = 1000.0 * layout.QUIET_ZONE_M
    lines = [
        (
            f"{placement.robot.upper()}  \u00b7  {placement.face} plate  \u00b7  "
            f"marker id {placement.marker_id}",
            24,
            "bold",
        ),
        (
            f"ArUco {layout.DICTIONARY_NAME}; black square {size_mm:.1f} x {size_mm:.1f} mm; "
            f"white quiet zone {quiet_mm:.0f} mm each side: plate {side:.1f} mm, "
            "cut on the thin grey line",
            13,
            "normal",
        ),
        (
            f"Goes {_faces_text(placement)}; marker centre at {_centre_text(placement)} "
            "(robot frame, z from the floor)",
            13,
            "normal",
        ),
    ]
    _draw_caption(ax, sheet, lines, bottom)


def _draw_landmark_page(ax, sheet: _Sheet, marker: LandmarkMarker, quiet_zone_m: float) -> None:
    side = plate_side_mm(marker, quiet_zone_m)
    bottom = _draw_plate(
        ax,
        sheet,
        plate_image(marker, PDF_DOTS_PER_MM, quiet_zone_m),
        side,
        _direction_words(marker.rotation[:, 1], _WORLD_DIRECTION_WORDS),
    )
    size_mm = 1000.0 * marker.size_m
    x, y, z = 1000.0 * marker.position_m
    facing = _direction_words(marker.rotation[:, 2], _WORLD_DIRECTION_WORDS)
    lines = [
        (f"WALL LANDMARK  \u00b7  marker id {marker.marker_id}", 24, "bold"),
        (
            f"ArUco {layout.DICTIONARY_NAME}; black square {size_mm:.1f} x {size_mm:.1f} mm; "
            f"white quiet zone {1000.0 * quiet_zone_m:.0f} mm each side: plate {side:.1f} mm, "
            "cut on the thin grey line",
            13,
            "normal",
        ),
        (
            f"Goes on a wall, printed face towards {facing}; marker centre at x = {x:.0f}, "
            f"y = {y:.0f}, z = {z:.0f} mm (arena frame: origin on the floor at the arena's centre, "
            "x east, y north)",
            13,
            "normal",
        ),
    ]
    _draw_caption(ax, sheet, lines, bottom)


def _draw_caption(ax, sheet: _Sheet, lines: list, bottom: float) -> None:
    """Writes a plate's caption ``(text, font size, weight)`` lines below ``bottom`` (mm), then the
    print-at-100% instruction and the 10 cm scale bar."""
    lines = [
        *lines,
        (
            "Print at 100% / actual size (no 'fit to page'); the 10 cm bar below must measure "
            f"100 mm ({sheet.name} sheet)",
            13,
            "bold",
        ),
    ]
    y = bottom - 8.0
    for text, size, weight in lines:
        ax.text(MARGIN_MM + 4.0, y, text, ha="left", va="top", fontsize=size, weight=weight)
        y -= 2.2 + size * MM_PER_INCH / 72.0
    _scale_bar(ax, MARGIN_MM + 4.0, y - 8.0)


def _draw_board_page(ax, sheet: _Sheet, spec: BoardSpec) -> None:
    width, height = (1000.0 * s for s in spec.size_m)
    left = 0.5 * (sheet.width_mm - width)
    top = sheet.height_mm - MARGIN_MM - _BOARD_HEAD_MM
    _draw_raster(ax, board_image(spec, PDF_DOTS_PER_MM), left, top - height, width, height)
    ax.text(
        MARGIN_MM,
        sheet.height_mm - MARGIN_MM,
        f"ChArUco calibration board: {spec.squares_x} x {spec.squares_y} squares of "
        f"{1000 * spec.square_m:.1f} mm, markers {1000 * spec.marker_m:.1f} mm, {spec.dictionary}",
        ha="left",
        va="top",
        fontsize=11,
        weight="bold",
    )
    bar_bottom = top - height - 10.0
    _scale_bar(ax, MARGIN_MM, bar_bottom)
    notes = (
        f"Print at 100% / actual size. One square must measure {1000 * spec.square_m:.1f} mm.\n"
        "Glue flat on rigid board; keep the white margin round it.\n"
        "Definition: perception.board.DEFAULT_BOARD."
    )
    ax.text(MARGIN_MM + 150.0, bar_bottom + 4.0, notes, ha="left", va="top", fontsize=7.5)


def _model_boxes() -> dict:
    """Returns the chassis, column and deck boxes and the wheel of the PeopleBot model.

    name -> (centre (3,), half sizes (3,)) in the robot frame, metres; "wheel" -> (centre of the
    left wheel (3,), (radius, half width)).
    """
    root = ElementTree.parse(
        pathlib.Path(peoplebot_models.MODELS_DIR) / "peoplebot" / "peoplebot.xml"
    ).getroot()

    def floats(text):
        return np.array([float(v) for v in text.split()])

    boxes = {}
    for name in ("chassis", "column", "deck"):
        geom = root.find(f".//geom[@name='{name}_collision']")
        boxes[name] = (floats(geom.get("pos")), floats(geom.get("size")))
    wheel = root.find(".//body[@name='left_wheel']")
    wheel_geom = wheel.find("geom[@name='left_wheel_visual']")
    boxes["wheel"] = (floats(wheel.get("pos")), floats(wheel_geom.get("size")))
    return boxes


def _draw_view(ax, origin, u, v, towards_viewer, boxes, placements):
    """Draws one orthographic view at ``DRAWING_SCALE``: robot-frame axes ``u`` (page right) and
    ``v`` (page up), seen from ``towards_viewer``; ``origin`` is the robot origin on the page, mm."""
    u, v, d = (np.asarray(a, dtype=float) for a in (u, v, towards_viewer))
    ox, oy = origin
    from_above = abs(d[2]) > 0.5

    def page(points):
        points = np.atleast_2d(points)
        return np.column_stack(
            [ox + 1000 * DRAWING_SCALE * points @ u, oy + 1000 * DRAWING_SCALE * points @ v]
        )

    def box_patch(centre, half, **style):
        corners = page([centre - half * (u + v), centre + half * (u - v), centre + half * (u + v)])
        (x0, y0), _, (x1, y1) = corners
        return Rectangle((min(x0, x1), min(y0, y1)), abs(x1 - x0), abs(y1 - y0), **style)

    chassis_c, chassis_h = boxes["chassis"]
    column_c, column_h = boxes["column"]
    deck_c, deck_h = boxes["deck"]
    ax.add_patch(box_patch(chassis_c, chassis_h, facecolor="0.88", edgecolor="0.3", lw=0.5))
    if from_above:  # the deck is drawn see-through over the column
        ax.add_patch(box_patch(column_c, column_h, facecolor="0.7", edgecolor="0.3", lw=0.5))
        ax.add_patch(box_patch(deck_c, deck_h, fill=False, edgecolor="0.3", lw=0.5, ls="--"))
        wheel_c, (radius, half_width) = boxes["wheel"]
        for side in (1, -1):
            centre = wheel_c * np.array([1, side, 1])
            half = np.array([radius, half_width, radius])
            ax.add_patch(box_patch(centre, half, facecolor="0.25", edgecolor="none"))
    else:
        ax.add_patch(box_patch(column_c, column_h, facecolor="0.7", edgecolor="0.3", lw=0.5))
        ax.add_patch(box_patch(deck_c, deck_h, facecolor="0.5", edgecolor="0.3", lw=0.5))
        wheel_c, (radius, _) = boxes["wheel"]
        ax.add_patch(
            Circle(page(wheel_c)[0], 1000 * DRAWING_SCALE * radius, facecolor="0.25", lw=0)
        )
    ax.plot(*page(np.zeros(3))[0], marker="+", color="k", ms=6, mew=0.8)

    for p in placements:
        normal, up = p.rotation[:, 2], p.rotation[:, 1]
        corners = page(p.corners_robot())
        centre = page(p.position_m)[0]
        facing = float(normal @ d)
        if facing > 0.5:
            ax.add_patch(
                Polygon(corners, facecolor=_PLATE_COLOUR, alpha=0.35, edgecolor=_PLATE_COLOUR)
            )
            tip = page(p.position_m + 0.4 * p.size_m * up)[0]
            ax.annotate(
                "", xy=tip, xytext=centre, arrowprops={"arrowstyle": "-|>", "color": "k", "lw": 0.8}
            )
            below = page(p.position_m - 0.2 * p.size_m * up)[0]
            ax.text(*below, p.face, ha="center", va="top", fontsize=7, weight="bold")
        elif facing < -0.5:
            ax.add_patch(Polygon(corners, fill=False, edgecolor=_PLATE_COLOUR, ls=":", lw=0.8))
            below = page(p.position_m - 0.3 * p.size_m * up)[0]
            ax.text(*below, f"({p.face}: far side)", ha="center", va="top", fontsize=6)
        else:
            if np.ptp(corners[:, 0]) > np.ptp(corners[:, 1]):
                ends = corners[[np.argmin(corners[:, 0]), np.argmax(corners[:, 0])]]
            else:
                ends = corners[[np.argmin(corners[:, 1]), np.argmax(corners[:, 1])]]
            ax.plot(ends[:, 0], ends[:, 1], color=_PLATE_COLOUR, lw=2.5, solid_capstyle="butt")
            outward = np.array([normal @ u, normal @ v])
            reach = 0.13 if from_above else 0.04
            label = page(p.position_m + reach * normal)[0]
            ax.plot(*np.column_stack([centre, label]), color="0.3", lw=0.4)
            ha = "left" if outward[0] > 0.5 else "right" if outward[0] < -0.5 else "center"
            va = "bottom" if outward[1] > 0.5 else "top" if outward[1] < -0.5 else "center"
            ax.text(*label, f" {p.face} ", ha=ha, va=va, fontsize=7, weight="bold")


def _draw_placement_page(ax, sheet: _Sheet, placements, pages: dict, spec: BoardSpec, board_page):
    width, height = sheet.width_mm, sheet.height_mm
    m = MARGIN_MM
    robots = tuple(dict.fromkeys(p.robot for p in placements))
    placements_by_face = {}
    for p in placements:
        placements_by_face.setdefault(p.face, []).append(p)
    first = [group[0] for group in placements_by_face.values()]
    for group in placements_by_face.values():
        if any(
            not np.allclose(q.position_m, group[0].position_m)
            or not np.allclose(q.rotation, group[0].rotation)
            or q.size_m != group[0].size_m
            for q in group
        ):
            raise ValueError(
                f"the placement sheet draws one plate per face; the {group[0].face} plates differ "
                "between robots"
            )
    ids = ", ".join(
        f"{robot} {min(p.marker_id for p in placements if p.robot == robot)}-"
        f"{max(p.marker_id for p in placements if p.robot == robot)}"
        for robot in robots
    )
    ax.text(
        m,
        height - m,
        "Where the marker plates go on each PeopleBot",
        fontsize=14,
        weight="bold",
        va="top",
    )
    ax.text(
        m,
        height - m - 8,
        f"Both robots carry the same plates (ArUco {layout.DICTIONARY_NAME}; ids {ids}).\n"
        f"Drawings at 1:{1 / DRAWING_SCALE:.0f}; plates in blue; arrows point to each marker's "
        "top edge.\nRobot frame: origin on the floor midway between the drive wheels (+), "
        "x forward, y to the left, z up.",
        fontsize=8,
        va="top",
    )
    boxes = _model_boxes()
    views_top = height - m - 26.0
    floor_y = views_top - 128.0
    side_origin = (m + 60.0, floor_y)
    _draw_view(
        ax,
        side_origin,
        (1, 0, 0),
        (0, 0, 1),
        (0, -1, 0),
        boxes,
        first,
    )
    ax.plot([side_origin[0] - 32, side_origin[0] + 32], [floor_y, floor_y], color="k", lw=0.8)
    ax.text(
        side_origin[0],
        floor_y - 2.0,
        "Side view, from the robot's right (-y)",
        ha="center",
        va="top",
        fontsize=7.5,
    )
    # Heights from the floor: a ruler left of the side view, ticked at each plate centre.
    ruler_x = side_origin[0] - 1000 * DRAWING_SCALE * 0.36
    heights = sorted({round(1000.0 * p.position_m[2]) for p in first})
    top_z = 1000 * DRAWING_SCALE * max(heights) / 1000.0 + 6.0
    ax.annotate(
        "",
        xy=(ruler_x, floor_y + top_z),
        xytext=(ruler_x, floor_y),
        arrowprops={"arrowstyle": "-|>", "color": "k", "lw": 0.6},
    )
    ax.text(
        ruler_x, floor_y + top_z + 1.0, "height z\nfrom floor", ha="center", va="bottom", fontsize=6
    )
    for z_mm in heights:
        y = floor_y + DRAWING_SCALE * z_mm
        ax.plot([ruler_x - 1.2, ruler_x + 1.2], [y, y], color="k", lw=0.6)
        ax.text(ruler_x - 1.8, y, f"{z_mm} mm", ha="right", va="center", fontsize=7)
    top_origin = (m + 142.0, views_top - 40.0)
    _draw_view(
        ax,
        top_origin,
        (1, 0, 0),
        (0, 1, 0),
        (0, 0, 1),
        boxes,
        first,
    )
    ax.text(
        top_origin[0],
        top_origin[1] - 36.0,
        "Top view, from above (x forward to the right, y left up the page);\n"
        "deck dashed (see-through), column grey, wheels dark",
        ha="center",
        va="top",
        fontsize=7.5,
    )
    # The table: one row per face.
    columns = (
        ("face", 0.0),
        ("ids", 14.0),
        ("pages", 30.0),
        ("black square", 46.0),
        ("plate", 68.0),
        ("centre x, y, z (mm)", 84.0),
        ("faces", 120.0),
        ("marker top edge", 146.0),
    )
    y = floor_y - 18.0
    for title, x in columns:
        ax.text(m + x, y, title, fontsize=7.5, weight="bold", va="top")
    ax.plot([m, width - m], [y - 4.2, y - 4.2], color="0.3", lw=0.4)
    for face, group in placements_by_face.items():
        y -= 5.5
        p = group[0]
        x, yy, z = 1000.0 * p.position_m
        cells = (
            face,
            ", ".join(str(q.marker_id) for q in group),
            ", ".join(str(pages[q.marker_id]) for q in group),
            f"{1000 * p.size_m:.0f} mm",
            f"{plate_side_mm(p):.0f} mm",
            f"{x:.0f}, {yy:.0f}, {z:.0f}",
            _direction_words(p.rotation[:, 2]),
            _direction_words(p.rotation[:, 1]),
        )
        for (_, col), text in zip(columns, cells, strict=True):
            ax.text(m + col, y, text, fontsize=7.5, va="top")
    ax.text(
        m,
        y - 8.0,
        f"ids and pages: {', '.join(robots)}. 'black square' is the marker's side; 'plate' adds "
        f"the {1000 * layout.QUIET_ZONE_M:.0f} mm white quiet zone each side.",
        fontsize=7,
        va="top",
    )
    notes = (
        "1. Print every page at 100% / actual size (never 'fit to page'). Measure the printed 10 cm "
        "bar (this page, the board page and every\n    plate page): it must read 100 mm, within 1 mm. "
        "Otherwise fix the printer's scaling and reprint.\n"
        "2. Cut each plate on its thin grey line, keeping the white border (the quiet zone): "
        "the tracker needs it. Glue it flat on rigid board.\n"
        "3. Mount each plate with the marker's centre at the table's x, y, z: heights z from the "
        "floor, x and y from the centre of rotation\n    (midway between the drive wheels); the top "
        "plate lies flat on the deck, the side plates flat on the column's faces.\n"
        "4. Turn each plate so that its marker's top edge (printed '\u25b2 TOP EDGE') points as in "
        "the table's last column.\n"
        f"5. The ChArUco calibration board is page {board_page} ({spec.squares_x} x "
        f"{spec.squares_y} squares of {1000 * spec.square_m:.0f} mm): glue it flat for the camera "
        "calibration."
    )
    ax.text(m, y - 16.0, notes, fontsize=7, va="top", linespacing=1.5)
    _scale_bar(ax, m, m + 4.0)


def write_plates_pdf(
    path: str | os.PathLike,
    paper: str = "A4",
    board_spec: BoardSpec = DEFAULT_BOARD,
    landmarks: LandmarkMap | None = None,
) -> dict:
    """Writes the placement sheet, the calibration board, every plate of
    ``perception.layout.default_layout()`` and, if given, every wall landmark of ``landmarks`` (an
    arena's marker map, e.g. ``models/arena/landmarks.toml``) to one PDF at true scale; returns a
    summary.

    Returns a dict: "path", "paper", "pages" (one per page, in order: "page" from 1, "content",
    "sheet", "width_mm", "height_mm"), "plates" (one per placement: "marker_id", "robot", "face",
    "size_mm" (black square), "plate_mm" (with the quiet zone), "page", "sheet"), "board"
    ("page" and the spec in mm) and "landmarks" (one per wall landmark: "marker_id", "size_mm",
    "plate_mm", "centre_mm" (arena frame), "page", "sheet"; empty without a map).
    """
    if paper not in PAPER_SERIES:
        raise ValueError(f"unknown paper {paper!r}; allowed: {', '.join(PAPER_SERIES)}")
    placements = layout.default_layout()
    head_foot = 2 * MARGIN_MM + _PLATE_HEAD_MM + _PLATE_FOOT_MM
    plate_sheets = [
        _sheet_for(paper, plate_side_mm(p) + 2 * MARGIN_MM, plate_side_mm(p) + head_foot)
        for p in placements
    ]
    board_w, board_h = (1000.0 * s for s in board_spec.size_m)
    board_sheet = _sheet_for(
        paper,
        board_w + 2 * MARGIN_MM,
        board_h + 2 * MARGIN_MM + _BOARD_HEAD_MM + _BOARD_FOOT_MM,
        landscape=True,
    )
    w, h = SHEETS_MM[paper]
    placement_sheet = _Sheet(paper, w, h)
    board_page = 2
    plate_pages = {p.marker_id: board_page + 1 + i for i, p in enumerate(placements)}
    wall = () if landmarks is None else landmarks.markers
    quiet = layout.QUIET_ZONE_M if landmarks is None else landmarks.quiet_zone_m
    wall_sheets = [
        _sheet_for(
            paper, plate_side_mm(m, quiet) + 2 * MARGIN_MM, plate_side_mm(m, quiet) + head_foot
        )
        for m in wall
    ]
    first_wall_page = board_page + 1 + len(placements)

    pages = []
    with PdfPages(path, metadata={"Title": "PeopleBot marker plates", "CreationDate": None}) as pdf:

        def emit(sheet, content, draw):
            fig, ax = _new_page(sheet)
            draw(ax)
            pdf.savefig(fig)
            pages.append(
                {
                    "page": len(pages) + 1,
                    "content": content,
                    "sheet": sheet.name,
                    "width_mm": sheet.width_mm,
                    "height_mm": sheet.height_mm,
                }
            )

        emit(
            placement_sheet,
            "placement sheet",
            lambda ax: _draw_placement_page(
                ax, placement_sheet, placements, plate_pages, board_spec, board_page
            ),
        )
        emit(
            board_sheet,
            "calibration board",
            lambda ax: _draw_board_page(ax, board_sheet, board_spec),
        )
        for p, sheet in zip(placements, plate_sheets, strict=True):
            emit(
                sheet,
                f"plate {p.robot} {p.face} (id {p.marker_id})",
                lambda ax, p=p, sheet=sheet: _draw_plate_page(ax, sheet, p),
            )
        for m, sheet in zip(wall, wall_sheets, strict=True):
            emit(
                sheet,
                f"wall landmark (id {m.marker_id})",
                lambda ax, m=m, sheet=sheet: _draw_landmark_page(ax, sheet, m, quiet),
            )

    plates = [
        {
            "marker_id": p.marker_id,
            "robot": p.robot,
            "face": p.face,
            "size_mm": 1000.0 * p.size_m,
            "plate_mm": plate_side_mm(p),
            "page": plate_pages[p.marker_id],
            "sheet": sheet.name,
        }
        for p, sheet in zip(placements, plate_sheets, strict=True)
    ]
    board_summary = {
        "page": board_page,
        "sheet": board_sheet.name,
        "squares_x": board_spec.squares_x,
        "squares_y": board_spec.squares_y,
        "square_mm": 1000.0 * board_spec.square_m,
        "marker_mm": 1000.0 * board_spec.marker_m,
        "dictionary": board_spec.dictionary,
    }
    return {
        "path": str(path),
        "paper": paper,
        "pages": pages,
        "plates": plates,
        "board": board_summary,
        "landmarks": [
            {
                "marker_id": m.marker_id,
                "size_mm": 1000.0 * m.size_m,
                "plate_mm": plate_side_mm(m, quiet),
                "centre_mm": tuple(float(v) for v in 1000.0 * m.position_m),
                "page": first_wall_page + i,
                "sheet": sheet.name,
            }
            for i, (m, sheet) in enumerate(zip(wall, wall_sheets, strict=True))
        ],
    }
