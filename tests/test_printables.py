"""``peoplebot markers``' PDF: sheet sizes, true scale of the embedded plates, the plate rasters read
back by OpenCV, and the calibration board's definition."""

import pathlib
import re
import zlib

import cv2
import numpy as np
import pytest

from imitation import printables
from perception import layout
from perception.board import DEFAULT_BOARD, BoardSpec, board, board_image
from perception.landmarks import LandmarkMap, read_landmark_map

POINTS_PER_MM = 72.0 / 25.4
_IMAGE_DRAW = re.compile(
    rb"q\s+1 0 0 1 ([-\d.]+) ([-\d.]+) cm\s+([-\d.]+) 0 0\s+([-\d.]+) 0 ([-\d.]+) cm\s+/I\d+ Do"
)


def _pdf_pages(data: bytes) -> list[dict]:
    """Returns each page of a PDF, in order: its MediaBox (points) and the rectangles (points,
    x0, y0, x1, y1) where its content stream draws images."""
    objects = {
        int(m.group(1)): m.group(2) for m in re.finditer(rb"(\d+) 0 obj\s*(.*?)endobj", data, re.S)
    }
    kids = re.search(rb"/Type /Pages\s*/Kids \[([^\]]*)\]", data).group(1)
    pages = []
    for number in re.findall(rb"(\d+) 0 R", kids):
        page = objects[int(number)]
        box = [float(v) for v in re.search(rb"/MediaBox \[([^\]]*)\]", page).group(1).split()]
        content = objects[int(re.search(rb"/Contents (\d+) 0 R", page).group(1))]
        stream = re.search(rb"stream\r?\n(.*?)\r?\nendstream", content, re.S).group(1)
        images = []
        for m in _IMAGE_DRAW.finditer(zlib.decompress(stream)):
            tx, ty, a, d, f = (float(v) for v in m.groups())
            ys = sorted((ty + f, ty + f + d))
            images.append((tx, ys[0], tx + a, ys[1]))
        pages.append({"media_box": box, "images": images})
    return pages


@pytest.fixture(scope="module")
def a4_pdf(tmp_path_factory):
    path = tmp_path_factory.mktemp("markers") / "plates.pdf"
    summary = printables.write_plates_pdf(path, paper="A4")
    return summary, _pdf_pages(path.read_bytes())


def test_every_page_has_its_sheet_size(a4_pdf):
    summary, pages = a4_pdf
    assert len(pages) == len(summary["pages"]) == 2 + len(layout.default_layout())
    for page, listed in zip(pages, summary["pages"], strict=True):
        x0, y0, x1, y1 = page["media_box"]
        assert (x0, y0) == (0.0, 0.0)
        assert x1 == pytest.approx(listed["width_mm"] * POINTS_PER_MM, abs=1e-3)
        assert y1 == pytest.approx(listed["height_mm"] * POINTS_PER_MM, abs=1e-3)
    # A4 portrait for the placement sheet, A4 landscape for the board, A2 for every plate (a
    # 0.30 m plate is wider than A3's 297 mm).
    assert [(p["sheet"], p["width_mm"], p["height_mm"]) for p in summary["pages"][:2]] == [
        ("A4", 210.0, 297.0),
        ("A4", 297.0, 210.0),
    ]
    assert {(p["sheet"], p["width_mm"], p["height_mm"]) for p in summary["pages"][2:]} == {
        ("A2", 420.0, 594.0)
    }


def test_summary_lists_every_placement_at_its_size(a4_pdf):
    summary, _ = a4_pdf
    placements = layout.default_layout()
    assert len(summary["plates"]) == len(placements)
    for plate, p in zip(summary["plates"], placements, strict=True):
        assert (plate["marker_id"], plate["robot"], plate["face"]) == (p.marker_id, p.robot, p.face)
        assert plate["size_mm"] == pytest.approx(1000.0 * p.size_m)
        assert plate["plate_mm"] == pytest.approx(1000.0 * (p.size_m + 2 * layout.QUIET_ZONE_M))
        page = summary["pages"][plate["page"] - 1]
        assert page["content"] == f"plate {p.robot} {p.face} (id {p.marker_id})"
        assert page["sheet"] == plate["sheet"]
        assert (
            min(page["width_mm"], page["height_mm"]) >= plate["plate_mm"] + 2 * printables.MARGIN_MM
        )
    assert len({plate["page"] for plate in summary["plates"]}) == len(placements)
    assert summary["board"]["page"] == 2
    assert summary["board"]["dictionary"] == DEFAULT_BOARD.dictionary


def test_plates_and_board_are_embedded_at_true_scale(a4_pdf):
    summary, pages = a4_pdf
    assert pages[0]["images"] == []
    (board_rect,) = pages[1]["images"]
    x0, y0, x1, y1 = board_rect
    width_mm, height_mm = (1000.0 * s for s in DEFAULT_BOARD.size_m)
    assert x1 - x0 == pytest.approx(width_mm * POINTS_PER_MM, abs=1e-3)
    assert y1 - y0 == pytest.approx(height_mm * POINTS_PER_MM, abs=1e-3)
    for plate in summary["plates"]:
        page = summary["pages"][plate["page"] - 1]
        (rect,) = pages[plate["page"] - 1]["images"]
        x0, y0, x1, y1 = (v / POINTS_PER_MM for v in rect)
        assert x1 - x0 == pytest.approx(plate["plate_mm"], abs=1e-4)
        assert y1 - y0 == pytest.approx(plate["plate_mm"], abs=1e-4)
        margin = printables.MARGIN_MM
        assert margin <= x0 and x1 <= page["width_mm"] - margin
        assert margin <= y0 and y1 <= page["height_mm"] - margin


@pytest.mark.parametrize("dots_per_mm", [2.0, 1.7])
@pytest.mark.parametrize("face", ["top", "left"])
def test_plate_image_is_read_back_at_its_size(face, dots_per_mm):
    placement = next(p for p in layout.default_layout() if p.robot == "student" and p.face == face)
    image = printables.plate_image(placement, dots_per_mm)
    side_mm = 1000.0 * (placement.size_m + 2 * layout.QUIET_ZONE_M)
    assert image.shape == (round(side_mm * dots_per_mm),) * 2
    assert image.dtype == np.uint8
    assert set(np.unique(image)) <= {0, 255}
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, layout.DICTIONARY_NAME))
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(image)
    assert ids is not None and ids.ravel().tolist() == [placement.marker_id]
    # Row 0 is the marker's top edge: the first corner (top-left) is the image's top-left one.
    assert np.argmin(corners[0][0].sum(axis=1)) == 0
    rows = np.flatnonzero((image < 128).any(axis=1))
    cols = np.flatnonzero((image < 128).any(axis=0))
    expected_px = 1000.0 * placement.size_m * dots_per_mm
    assert abs(rows[-1] - rows[0] + 1 - expected_px) <= 1.0
    assert abs(cols[-1] - cols[0] + 1 - expected_px) <= 1.0


def test_plate_image_is_the_simulators_texture():
    assets = pytest.importorskip("peoplebot_sim.assets")
    for placement in layout.default_layout()[:2]:
        texture = cv2.imdecode(
            np.frombuffer(assets.marker_png(placement.marker_id, placement.size_m), np.uint8),
            cv2.IMREAD_GRAYSCALE,
        )
        side_mm = 1000.0 * (placement.size_m + 2 * layout.QUIET_ZONE_M)
        printed = printables.plate_image(placement, texture.shape[0] / side_mm)
        np.testing.assert_array_equal(printed, texture)


def test_letter_puts_plates_on_ansi_c(tmp_path):
    summary = printables.write_plates_pdf(tmp_path / "letter.pdf", paper="letter")
    assert [p["sheet"] for p in summary["pages"][:2]] == ["letter", "letter"]
    assert {p["sheet"] for p in summary["plates"]} == {"ANSI C"}
    boxes = [page["media_box"] for page in _pdf_pages((tmp_path / "letter.pdf").read_bytes())]
    assert boxes[0][2:] == pytest.approx([612.0, 792.0], abs=1e-3)


def test_bad_input_is_refused(tmp_path):
    with pytest.raises(ValueError, match="allowed: A4, A3, letter"):
        printables.write_plates_pdf(tmp_path / "x.pdf", paper="B5")
    placement = layout.default_layout()[0]
    with pytest.raises(ValueError, match="dots_per_mm"):
        printables.plate_image(placement, 0.0)
    with pytest.raises(ValueError, match="marker_m < square_m"):
        BoardSpec(marker_m=0.03, square_m=0.03)
    with pytest.raises(ValueError, match="robots' dictionary"):
        BoardSpec(dictionary=layout.DICTIONARY_NAME)
    with pytest.raises(ValueError, match="unknown ArUco dictionary"):
        BoardSpec(dictionary="DICT_NOPE")


def test_board_is_found_and_its_markers_are_not_robot_markers():
    image = cv2.copyMakeBorder(
        board_image(DEFAULT_BOARD, 8.0), 40, 40, 40, 40, cv2.BORDER_CONSTANT, value=255
    )
    assert image.shape == (150 * 8 + 80, 210 * 8 + 80)
    corners, ids, _, marker_ids = cv2.aruco.CharucoDetector(board(DEFAULT_BOARD)).detectBoard(image)
    inner = (DEFAULT_BOARD.squares_x - 1) * (DEFAULT_BOARD.squares_y - 1)
    assert ids is not None and len(ids) == inner
    assert len(marker_ids) == DEFAULT_BOARD.marker_count
    # Neighbouring inner corners are one square apart (8 px per mm).
    points = corners.reshape(-1, 2)[np.argsort(ids.ravel())]
    steps = np.linalg.norm(np.diff(points[: DEFAULT_BOARD.squares_x - 1], axis=0), axis=1)
    np.testing.assert_allclose(steps, 1000.0 * DEFAULT_BOARD.square_m * 8.0, atol=0.5)
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, layout.DICTIONARY_NAME))
    _, robot_ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(image)
    # OpenCV 5.0 answers None when it finds no marker, 5.1 an empty array.
    assert robot_ids is None or len(robot_ids) == 0


def test_wall_landmarks_print_from_the_arenas_map(tmp_path):
    """Given a marker map, one page per wall landmark after the robots' plates, each at true size
    and read back by OpenCV as its id; the map's first and last markers stand in for all 19."""
    full = read_landmark_map(
        pathlib.Path(__file__).parent.parent / "models" / "arena" / "landmarks.toml"
    )
    landmarks = LandmarkMap([full.markers[0], full.markers[-1]], full.quiet_zone_m)
    summary = printables.write_plates_pdf(tmp_path / "wall.pdf", landmarks=landmarks)
    pages = _pdf_pages((tmp_path / "wall.pdf").read_bytes())
    robot_pages = 2 + len(layout.default_layout())
    assert len(pages) == robot_pages + 2
    for entry, marker in zip(summary["landmarks"], landmarks.markers, strict=True):
        assert entry["marker_id"] == marker.marker_id and entry["page"] > robot_pages
        page = pages[entry["page"] - 1]
        assert (
            summary["pages"][entry["page"] - 1]["content"]
            == f"wall landmark (id {marker.marker_id})"
        )
        ((x0, y0, x1, y1),) = page["images"]
        assert (x1 - x0) / POINTS_PER_MM == pytest.approx(entry["plate_mm"], abs=1e-3)
        assert entry["plate_mm"] == pytest.approx(1000 * (marker.size_m + 2 * full.quiet_zone_m))
        image = printables.plate_image(marker, 1.0, full.quiet_zone_m)
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, layout.DICTIONARY_NAME))
        _, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(image)
        assert ids is not None and ids.ravel().tolist() == [marker.marker_id]
