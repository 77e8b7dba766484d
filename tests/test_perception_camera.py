"""Tests for perception.camera: intrinsics, projection and validation."""

import numpy as np
import pytest

from perception.camera import PinholeCamera, look_at_rotation


def _overhead():
    rotation = look_at_rotation((0.0, 0.0, 4.9), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    return PinholeCamera.from_fovy(320, 240, 40.0, rotation, (0.0, 0.0, 4.9))


def test_from_fovy_intrinsics():
    camera = PinholeCamera.from_fovy(320, 240, 40.0)
    f = 120.0 / np.tan(np.radians(20.0))
    np.testing.assert_allclose(camera.matrix, [[f, 0, 159.5], [0, f, 119.5], [0, 0, 1]])
    assert camera.image_size == (320, 240)
    assert camera.fovy_deg == pytest.approx(40.0)


def test_from_fovx_matches_horizontal_fov():
    camera = PinholeCamera.from_fovx(320, 240, 45.0)
    assert camera.matrix[0, 0] == pytest.approx(160.0 / np.tan(np.radians(22.5)))
    assert camera.matrix[1, 1] == pytest.approx(camera.matrix[0, 0])


def test_overhead_camera_sees_north_at_top_and_centre_in_middle():
    camera = _overhead()
    centre, north, east = camera.project([[0, 0, 0], [0, 1, 0], [1, 0, 0]])
    np.testing.assert_allclose(centre, [159.5, 119.5], atol=1e-9)
    assert north[1] < centre[1] and abs(north[0] - centre[0]) < 1e-9
    assert east[0] > centre[0] and abs(east[1] - centre[1]) < 1e-9


def test_focal_scale_scales_image_offsets_and_keeps_the_rest():
    camera = _overhead()
    scaled = camera.with_focal_scale(1.02)
    points = [[0.3, -0.2, 0.0], [1.1, 0.7, 0.5]]
    centre = np.array([159.5, 119.5])
    np.testing.assert_allclose(
        scaled.project(points) - centre, 1.02 * (camera.project(points) - centre)
    )
    np.testing.assert_array_equal(scaled.position_world, camera.position_world)
    assert camera.matrix[0, 0] == pytest.approx(scaled.matrix[0, 0] / 1.02)  # the original kept
    with pytest.raises(ValueError, match="focal scale must be a finite number > 0, got 0"):
        camera.with_focal_scale(0)


def test_project_and_ray_round_trip():
    rng = np.random.default_rng(0)
    camera = PinholeCamera(
        np.array([[300.0, 0, 160], [0, 310.0, 118], [0, 0, 1]]),
        np.array([-0.1, 0.02, 0.001, -0.002, 0.0]),
        (320, 240),
        look_at_rotation((1.0, -2.0, 3.0), (0.0, 0.0, 0.5)),
        (1.0, -2.0, 3.0),
    )
    points = rng.uniform([-1, -1, 0], [1, 1, 1], size=(20, 3))
    pixels = camera.project(points)
    rays = camera.pixel_rays(pixels)
    expected = points - camera.position_world
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(rays, expected, atol=1e-6)
    on_floor = camera.intersect_plane_z(camera.project([[0.3, 0.2, 0.0]]), 0.0)
    np.testing.assert_allclose(on_floor[0], [0.3, 0.2, 0.0], atol=1e-6)


def test_points_behind_camera_are_nan():
    camera = _overhead()
    pixels = camera.project([[0, 0, 6.0], [0, 0, 1.0]])
    assert np.all(np.isnan(pixels[0])) and np.all(np.isfinite(pixels[1]))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"fovy_deg": 0.0}, "fovy_deg"),
        ({"fovy_deg": 180.0}, "fovy_deg"),
        ({"fovy_deg": float("nan")}, "fovy_deg"),
        ({"width": 0}, "width"),
        ({"height": 240.5}, "height"),
        ({"rotation_world_from_camera": np.diag([1.0, 1.0, -1.0])}, "determinant"),
        ({"rotation_world_from_camera": np.ones((3, 3))}, "orthonormal"),
        ({"position_world": (0.0, np.inf, 0.0)}, "position_world"),
    ],
)
def test_invalid_fovy_camera_raises(kwargs, match):
    args = {"width": 320, "height": 240, "fovy_deg": 40.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        PinholeCamera.from_fovy(**args)


@pytest.mark.parametrize(
    "matrix, distortion, size, match",
    [
        (np.eye(2), (), (320, 240), "3x3"),
        (np.diag([-1.0, 1.0, 1.0]), (), (320, 240), "focal"),
        (np.array([[1.0, 0, 0], [0, 1, 0], [0, 1, 1]]), (), (320, 240), "form"),
        (np.eye(3), (0.1, 0.2, 0.3), (320, 240), "distortion"),
        (np.eye(3), (), (320,), "image_size"),
        (np.eye(3), (), (-3, 240), "image_size"),
    ],
)
def test_invalid_camera_raises(matrix, distortion, size, match):
    with pytest.raises(ValueError, match=match):
        PinholeCamera(matrix, np.asarray(distortion, dtype=float), size)


def test_camera_arrays_are_read_only():
    camera = _overhead()
    with pytest.raises(ValueError):
        camera.matrix[0, 0] = 1.0


def test_perception_never_imports_the_simulator():
    import subprocess
    import sys

    code = (
        "import importlib, pkgutil, sys, perception; "
        "[importlib.import_module(m.name) for m in pkgutil.walk_packages(perception.__path__, "
        "'perception.')]; "
        "bad = [m for m in sys.modules if m.split('.')[0] in ('mujoco', 'dm_control', 'imitation', "
        "'peoplebot_sim')]; "
        "sys.exit(1 if bad else 0)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
