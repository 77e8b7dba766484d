"""Camera calibration from a ChArUco board (``perception.calibration``, ``perception.camerainfo``,
``imitation.calibrate``, ``peoplebot_sim.board``): the simulator's focal length recovered from
rendered views of the board, ROS ``camera_info`` files written, read back and refused when
malformed, board spec strings, and the tracker run on calibrated intrinsics."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import functools
import math

import cv2
import mujoco
import numpy as np
import pytest
import yaml
from dm_control import mjcf

from imitation import calibrate as calibrate_command
from peoplebot_sim import cameras, task
from peoplebot_sim.board import CAMERA_NAMES, render_board_views
from peoplebot_sim.rendering import FrameRenderer
from perception import camerainfo
from perception.board import DEFAULT_BOARD, BoardSpec
from perception.calibration import CalibrationConfig, calibrate
from perception.camera import PinholeCamera, look_at_rotation
from perception.pipeline import Tracker
from perception.wallframe import wrap_degrees

#: The renderer has no lens: k1 and k2 are fitted (and come out near 0), p1, p2 and k3 held at 0.
RENDERER = CalibrationConfig(distortion="radial")


@functools.cache
def _calibration(camera_name: str):
    """Returns ``(views, result)``: 25 renders at 320x240 of the default board through a simulator
    camera, and the calibration fitted to them."""
    views = render_board_views(camera_name, n_views=25, width=320, height=240, rng=0)
    return views, calibrate(views.images, DEFAULT_BOARD, RENDERER)


@pytest.fixture(params=CAMERA_NAMES)
def calibrated(request):
    """Returns ``(views, result)`` of each simulator camera."""
    return _calibration(request.param)


@pytest.fixture
def overhead():
    """Returns ``(views, result)`` of the overhead camera."""
    return _calibration("overhead")


# ---------------------------------------------------------------------------------- calibration
def test_calibration_recovers_the_simulators_intrinsics(calibrated):
    """fx and fy within 1% of MuJoCo's (from fovy), the principal point within 2 px, RMS < 0.5 px."""
    views, result = calibrated
    truth = views.camera.matrix
    k = result.matrix
    assert abs(k[0, 0] / truth[0, 0] - 1) < 0.01 and abs(k[1, 1] / truth[1, 1] - 1) < 0.01, k
    np.testing.assert_allclose(k[:2, 2], truth[:2, 2], atol=2.0)
    assert result.rms_px < 0.5
    assert np.all(np.isfinite(result.distortion)) and result.distortion.shape == (5,)
    np.testing.assert_array_equal(result.distortion[2:], 0.0)  # held by the "radial" model
    assert result.image_size == (320, 240)
    assert len(result.used) >= 20 and len(result.view_rms_px) == len(result.used)
    assert sorted(result.used + result.rejected) == list(range(25))
    assert all(result.corners_per_image[i] >= RENDERER.min_corners for i in result.used)


def test_calibration_rejects_images_without_the_board_and_refuses_too_few(overhead):
    views, _ = overhead
    blank = np.full_like(views.images[0], 128)
    result = calibrate([blank, *views.images[:5]], DEFAULT_BOARD, RENDERER)
    assert result.rejected[0] == 0 and result.corners_per_image[0] == 0
    assert 0 not in result.used
    with pytest.raises(ValueError, match="calibration needs 3"):
        calibrate([blank, blank, views.images[0]], DEFAULT_BOARD, RENDERER)
    with pytest.raises(ValueError, match="one size"):
        calibrate([views.images[0], views.images[1][:, :200]], DEFAULT_BOARD, RENDERER)
    with pytest.raises(ValueError, match="uint8"):
        calibrate([views.images[0].astype(float)], DEFAULT_BOARD, RENDERER)


@pytest.mark.parametrize(
    "overrides, match",
    [({"distortion": "fisheye"}, "plumb_bob, radial, none"), ({"min_corners": 3}, ">= 4")],
)
def test_bad_calibration_config_is_refused(overrides, match):
    with pytest.raises(ValueError, match=match):
        CalibrationConfig(**overrides)


# ---------------------------------------------------------------------------------- camera_info
ROS_FILE = """\
image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [430.215550, 0.000000, 306.691343, 0.000000, 430.531693, 227.224800, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.337586, 0.111612, -0.000218, -0.000030, 0.000000]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1.000000, 0.000000, 0.000000, 0.000000, 1.000000, 0.000000, 0.000000, 0.000000, 1.0]
projection_matrix:
  rows: 3
  cols: 4
  data: [356.4, 0.000000, 303.6, 0.000000, 0.000000, 393.1, 225.5, 0.0, 0.0, 0.0, 1.0, 0.0]
"""


def test_a_file_as_ros_writes_it_is_read():
    info = camerainfo.loads(ROS_FILE)
    assert info.camera_name == "narrow_stereo"
    assert info.camera.image_size == (640, 480)
    np.testing.assert_allclose(
        info.camera.matrix, [[430.21555, 0, 306.691343], [0, 430.531693, 227.2248], [0, 0, 1]]
    )
    np.testing.assert_allclose(info.camera.distortion, [-0.337586, 0.111612, -0.000218, -3e-5, 0])
    np.testing.assert_array_equal(info.rectification, np.eye(3))
    assert info.projection.shape == (3, 4) and info.projection[0, 0] == 356.4


def test_camera_info_round_trip(tmp_path):
    """Written and read back: the same matrix, distortion, size and name; the file holds ROS's
    fields; P is [K | 0] without distortion and ROS's alpha-0 rectified matrix with it."""
    distorted = PinholeCamera(
        [[401.25, 0.0, 161.3], [0.0, 399.5, 118.9], [0.0, 0.0, 1.0]],
        [-0.21, 0.043, 0.001, -0.0005, 0.01],
        (320, 240),
        look_at_rotation((1.0, 0.0, 1.0), (3.0, 0.0, 0.5)),
        (1.0, 0.0, 1.0),
    )
    ideal = PinholeCamera.from_fovy(320, 240, 34.5)
    for camera in (distorted, ideal):
        path = camerainfo.write(tmp_path / "calib" / "head.yaml", camera, "head_camera")
        info = camerainfo.read(path)
        assert info.camera_name == "head_camera"
        np.testing.assert_array_equal(info.camera.matrix, camera.matrix)
        expected = np.zeros(5) if camera.distortion.size == 0 else camera.distortion
        np.testing.assert_array_equal(info.camera.distortion, expected)
        assert info.camera.image_size == camera.image_size
        np.testing.assert_array_equal(info.camera.position_world, np.zeros(3))  # no pose in a file
        document = yaml.safe_load(path.read_text())
        assert list(document) == [
            "image_width",
            "image_height",
            "camera_name",
            "camera_matrix",
            "distortion_model",
            "distortion_coefficients",
            "rectification_matrix",
            "projection_matrix",
        ]
        assert document["distortion_model"] == "plumb_bob"
        assert document["distortion_coefficients"]["cols"] == 5
        assert document["camera_matrix"]["data"] == camera.matrix.ravel().tolist()
        np.testing.assert_array_equal(info.rectification, np.eye(3))
    np.testing.assert_array_equal(info.projection, np.column_stack([ideal.matrix, np.zeros(3)]))
    new_k, _ = cv2.getOptimalNewCameraMatrix(
        distorted.matrix, distorted.distortion, distorted.image_size, 0.0
    )
    projection = camerainfo.camera_info(distorted).projection
    np.testing.assert_allclose(projection, np.column_stack([new_k, np.zeros(3)]))


def _mutated(path, edit):
    document = yaml.safe_load(ROS_FILE)
    edit(document)
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


@pytest.mark.parametrize(
    "field, edit",
    [
        ("image_width", lambda d: d.pop("image_width")),
        ("image_height", lambda d: d.update(image_height=-480)),
        ("image_width", lambda d: d.update(image_width=640.5)),
        ("camera_name", lambda d: d.update(camera_name="")),
        ("camera_matrix", lambda d: d.update(camera_matrix=[1, 2, 3])),
        ("camera_matrix.rows", lambda d: d["camera_matrix"].update(rows=4)),
        ("camera_matrix.data", lambda d: d["camera_matrix"]["data"].pop()),
        ("camera_matrix.data", lambda d: d["camera_matrix"]["data"].__setitem__(0, "fx")),
        ("camera_matrix.data", lambda d: d["camera_matrix"]["data"].__setitem__(4, float("nan"))),
        ("camera_matrix", lambda d: d["camera_matrix"]["data"].__setitem__(0, -430.0)),
        ("distortion_model", lambda d: d.update(distortion_model="equidistant")),
        ("distortion_coefficients.cols", lambda d: d["distortion_coefficients"].update(cols=4)),
        ("distortion_coefficients.data", lambda d: d["distortion_coefficients"].update(data=[0])),
        ("rectification_matrix.data", lambda d: d["rectification_matrix"].pop("data")),
        ("projection_matrix.cols", lambda d: d["projection_matrix"].update(cols=3)),
    ],
)
def test_malformed_camera_info_is_refused_naming_the_file_and_field(tmp_path, field, edit):
    path = _mutated(tmp_path / "camera_info.yaml", edit)
    with pytest.raises(ValueError, match=f"{path}: field '{field}'"):
        camerainfo.read(path)


@pytest.mark.parametrize("text", ["", "[1, 2, 3]", "image_width: [unclosed"])
def test_a_file_that_is_not_a_camera_info_mapping_is_refused_naming_it(tmp_path, text):
    path = tmp_path / "broken.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match=str(path)):
        camerainfo.read(path)


def test_with_intrinsics_keeps_the_pose_and_refuses_another_size():
    simulator = PinholeCamera.from_fovy(
        320, 240, 45.0, look_at_rotation((0, 0, 6), (0, 0, 0), (0, 1, 0)), (0, 0, 6)
    )
    calibrated = PinholeCamera(
        [[292.0, 0, 160.2], [0, 291.0, 119.0], [0, 0, 1]], [0.01, -0.02, 0, 0, 0], (320, 240)
    )
    swapped = camerainfo.with_intrinsics(simulator, camerainfo.camera_info(calibrated))
    np.testing.assert_array_equal(swapped.matrix, calibrated.matrix)
    np.testing.assert_array_equal(swapped.distortion, calibrated.distortion)
    np.testing.assert_array_equal(swapped.position_world, simulator.position_world)
    np.testing.assert_array_equal(
        swapped.rotation_world_from_camera, simulator.rotation_world_from_camera
    )
    other = PinholeCamera.from_fovy(640, 480, 45.0)
    with pytest.raises(ValueError, match=r"\(640, 480\)"):
        camerainfo.with_intrinsics(simulator, other)


# ----------------------------------------------------------------------------------- spec strings
def test_board_spec_strings_are_parsed_and_written_back():
    assert calibrate_command.parse_board_spec("7x5:0.03:0.022:DICT_5X5_100") == DEFAULT_BOARD
    assert calibrate_command.parse_board_spec(" 7X5 : 0.03 : 0.022 ") == DEFAULT_BOARD
    assert calibrate_command.DEFAULT_BOARD_SPEC == "7x5:0.03:0.022:DICT_5X5_100"
    spec = BoardSpec(9, 6, 0.0254, 0.01905, "DICT_6X6_250")
    text = calibrate_command.format_board_spec(spec)
    assert calibrate_command.parse_board_spec(text) == spec


@pytest.mark.parametrize(
    "text, match",
    [
        ("7x5", "not of the form"),
        ("7x5:0.03", "not of the form"),
        ("7x5:0.03:0.022:DICT_5X5_100:extra", "not of the form"),
        ("7by5:0.03:0.022", "not of the form"),
        ("7x5:thirty:0.022", "numbers in metres"),
        ("7x5:30:22", "in metres"),
        ("7x5:0.03:0.04", "marker_m < square_m"),
        ("1x5:0.03:0.022", "at least 2 x 2"),
        ("7x5:0.03:0.022:DICT_NOPE", "unknown ArUco dictionary"),
        ("7x5:0.03:0.022:DICT_4X4_50", "robots' dictionary"),
        ("20x20:0.03:0.022:DICT_4X4_100", "holds 100 markers"),
    ],
)
def test_bad_board_spec_strings_are_refused(text, match):
    with pytest.raises(ValueError, match=match):
        calibrate_command.parse_board_spec(text)


# --------------------------------------------------------------------------------------- command
def test_calibrate_command_writes_a_camera_info_from_a_folder(overhead, tmp_path, capsys):
    views, _ = overhead
    folder = tmp_path / "photos"
    folder.mkdir()
    for i, image in enumerate(views.images[:12]):
        cv2.imwrite(str(folder / f"view_{i:02d}.png"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(folder / "view_99_blank.png"), np.full((240, 320), 200, np.uint8))
    (folder / "notes.txt").write_text("not an image")
    out = tmp_path / "camera_info.yaml"
    report = calibrate_command.run(
        folder, "7x5:0.03:0.022:DICT_5X5_100", out, RENDERER, camera_name="overhead"
    )
    assert "reprojection error" in capsys.readouterr().out
    assert len(report["images"]) == 13 and str(folder / "view_99_blank.png") in report["rejected"]
    info = camerainfo.read(out)
    assert info.camera_name == "overhead"
    assert abs(info.camera.matrix[0, 0] / views.camera.matrix[0, 0] - 1) < 0.01
    assert report["rms_px"] < 0.5 and report["image_size"] == [320, 240] and report["used"] >= 10
    with pytest.raises(ValueError, match="no such image file"):
        calibrate_command.run([tmp_path / "missing.png"], DEFAULT_BOARD, out)
    with pytest.raises(ValueError, match="not an image"):
        calibrate_command.run([folder / "notes.txt"], DEFAULT_BOARD, out)


# ------------------------------------------------------------------------ tracking on calibration
def test_tracker_on_overhead_intrinsics_finds_the_teacher_within_2_cm(overhead):
    """The overhead camera's calibrated matrix (on the simulator's pose) in place of MuJoCo's:
    the teacher's planar pose from rendered 320x240 frames within 2 cm and 2 degrees."""
    _, result = overhead
    imitation = task.ImitationTask(task.TaskConfig())
    physics = mjcf.Physics.from_mjcf_model(imitation.root_entity.mjcf_model)
    simulator = cameras.camera_model(physics, "overhead", 320, 240)
    camera = camerainfo.with_intrinsics(simulator, camerainfo.camera_info(result.camera))
    rng = np.random.default_rng(0)
    tracker = Tracker(robots=("teacher",))
    with FrameRenderer(physics, 320, 240) as renderer:
        for _ in range(6):
            truth = imitation.random_free_pose(rng, margin_m=0.45)
            student = imitation.random_free_pose(rng, avoid=truth, margin_m=0.45)
            imitation.teacher.set_planar_pose(physics, *truth)
            imitation.student.set_planar_pose(physics, *student)
            mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
            estimate = tracker.estimate(renderer.render("overhead"), camera).poses["teacher"]
            error_cm = 100 * math.hypot(estimate.x_m - truth[0], estimate.y_m - truth[1])
            error_deg = abs(float(wrap_degrees(math.degrees(estimate.yaw_rad - truth[2]))))
            assert error_cm < 2.0 and error_deg < 2.0, (truth, error_cm, error_deg)
