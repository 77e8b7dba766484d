"""Tests for perception.registration: a fixed camera's pose from markers at known places."""

import math

import numpy as np
import pytest

from perception.camera import PinholeCamera, look_at_rotation
from perception.landmarks import LandmarkMap, LandmarkMarker
from perception.registration import register_camera

TRUE_POSITION = (0.04, -0.03, 6.0)


def _layout() -> LandmarkMap:
    grid = [(x, y) for y in (1.2, 0.0, -1.2) for x in (-1.2, 0.0, 1.2)]
    return LandmarkMap(
        [
            LandmarkMarker.facing(40 + k, 0.5, (x, y, 0.001), (0, 0, 1), (0, 1, 0))
            for k, (x, y) in enumerate(grid)
        ]
    )


def _camera(position=TRUE_POSITION, target=(0.0, 0.02, 0.0), fovy_deg=45.0) -> PinholeCamera:
    rotation = look_at_rotation(position, target, (0.0, 1.0, 0.0))
    return PinholeCamera.from_fovy(320, 240, fovy_deg, rotation, position)


def _seen(camera, layout, noise_px=0.0, seed=0):
    rng = np.random.default_rng(seed)
    return [
        (m.marker_id, camera.project(m.corners_world()) + noise_px * rng.normal(size=(4, 2)))
        for m in layout.markers
    ]


def _angle_deg(a, b) -> float:
    cos = (np.trace(np.asarray(a).T @ np.asarray(b)) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, cos))))


def test_registration_finds_the_pose_whatever_pose_was_believed():
    layout, truth = _layout(), _camera()
    # The mount believed 10 cm and about 3 deg off: only the intrinsics are used.
    believed = _camera(position=(0.12, 0.05, 5.95), target=(0.2, -0.1, 0.0))
    fit = register_camera(believed, _seen(truth, layout, noise_px=0.3), layout)
    assert np.linalg.norm(fit.camera.position_world - truth.position_world) < 0.01
    assert _angle_deg(fit.camera.rotation_world_from_camera, truth.rotation_world_from_camera) < 0.1
    assert fit.marker_ids == tuple(range(40, 49))
    assert 0.15 < fit.rms_error_px < 0.45  # the corners' 0.3 px noise, less the 6 fitted values
    np.testing.assert_array_equal(fit.camera.matrix, believed.matrix)
    exact = register_camera(believed, _seen(truth, layout), layout)
    assert np.linalg.norm(exact.camera.position_world - truth.position_world) < 1e-6
    assert exact.rms_error_px < 1e-6


def test_a_longer_believed_focal_length_moves_the_camera_back_along_its_axis():
    """2% too long a focal length: the fit keeps the floor's image by standing 2% farther."""
    layout, truth = _layout(), _camera()
    believed = truth.with_focal_scale(1.02)
    fit = register_camera(believed, _seen(truth, layout), layout)
    assert fit.camera.position_world[2] == pytest.approx(1.02 * TRUE_POSITION[2], abs=0.005)
    floor = np.array([[x, y, 0.0] for x in (-1.5, 0.3, 1.5) for y in (-1.5, 0.7, 1.5)])
    back = fit.camera.intersect_plane_z(truth.project(floor), 0.0)
    assert np.abs(back - floor).max() < 0.002  # the markers' plane is kept
    raised = floor + (0.0, 0.0, 1.115)  # the robots' top plates: off by about 0.45% of the reach
    back = fit.camera.intersect_plane_z(truth.project(raised), 1.115)
    reach = np.linalg.norm(raised[:, :2] - TRUE_POSITION[:2], axis=1)
    assert np.all(np.linalg.norm(back - raised, axis=1) < 0.007 * reach + 0.002)


def test_too_few_markers_are_refused_and_foreign_or_repeated_ids_ignored():
    layout, truth = _layout(), _camera()
    seen = _seen(truth, layout)
    found = seen[:3] + [(3, seen[3][1]), (44, seen[4][1]), (44, seen[5][1])]  # a plate, 44 twice
    with pytest.raises(
        ValueError, match=r"at least 4 of the map's 9 markers in view, found 3 \(\[40, 41, 42\]\)"
    ):
        register_camera(truth, found, layout)
    fit = register_camera(truth, seen[:3] + [(3, seen[3][1])] + seen[5:6], layout, min_markers=4)
    assert fit.marker_ids == (40, 41, 42, 45)
    with pytest.raises(ValueError, match="min_markers must be an integer >= 1, got 0"):
        register_camera(truth, seen, layout, min_markers=0)
