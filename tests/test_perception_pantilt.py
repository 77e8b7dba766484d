"""Pan-tilt head geometry, limits and rate limits."""

import numpy as np
import pytest

from perception.camera import PinholeCamera
from perception.pantilt import (
    PanTiltController,
    PanTiltLimits,
    aim_at,
    head_camera,
    head_camera_rotation,
)


def test_aim_centres_the_target_in_the_head_camera():
    intrinsics = PinholeCamera.from_fovx(320, 240, 45.0)
    observer = (0.5, -0.4, 2.0)
    target = (-0.8, 0.9, 0.72)
    pan, tilt = aim_at(observer, target)
    camera = head_camera(intrinsics, observer, pan, tilt)
    np.testing.assert_allclose(camera.project([target])[0], [159.5, 119.5], atol=1e-6)


def test_zero_angles_look_forward_without_roll():
    rotation = head_camera_rotation(0.0, 0.0, 0.0)
    np.testing.assert_allclose(rotation[:, 2], [1, 0, 0], atol=1e-12)  # optical axis forward
    np.testing.assert_allclose(rotation[:, 1], [0, 0, -1], atol=1e-12)  # image down is world down
    np.testing.assert_allclose(head_camera_rotation(0.0, 90.0, 0.0)[:, 2], [0, 1, 0], atol=1e-12)
    assert head_camera_rotation(0.0, 0.0, 30.0)[2, 2] == pytest.approx(0.5)


def test_limits_and_rates_are_enforced():
    controller = PanTiltController()
    # Target straight behind: pan saturates at a limit, never beyond, 90 deg/s at most.
    angles = []
    for _ in range(30):
        command = controller.step((0.0, 0.0, 0.0), (-2.0, 0.1), 0.1)
        angles.append(command.pan_deg)
        assert not command.reachable
    assert np.max(np.abs(np.diff([0.0, *angles]))) <= 9.0 + 1e-9
    assert angles[-1] == pytest.approx(98.0)
    # Target right at the robot's feet: tilt saturates at -30.
    for _ in range(30):
        command = controller.step((0.0, 0.0, 0.0), (0.2, 0.0), 0.1)
    assert command.tilt_deg == pytest.approx(-30.0)
    assert command.target_tilt_deg < -30.0


def test_tracks_a_reachable_target_and_holds_without_one():
    controller = PanTiltController(search_pan_deg=0.0)
    for _ in range(20):
        command = controller.step((0.0, 0.0, 0.0), (2.0, 1.0), 0.1)
    assert command.reachable
    assert command.pan_deg == pytest.approx(command.target_pan_deg)
    assert command.tilt_deg == pytest.approx(command.target_tilt_deg)
    held = controller.step((0.0, 0.0, 0.0), None, 0.1)
    assert held.pan_deg == command.pan_deg and held.target_pan_deg is None


def test_searches_by_sweeping_the_pan_within_its_rate_and_range():
    controller = PanTiltController(search_pan_deg=60.0, search_tilt_deg=-10.0)
    pans = [controller.step((0.0, 0.0, 0.0), None, 0.1).pan_deg for _ in range(60)]
    steps = np.abs(np.diff([0.0, *pans]))
    assert np.all(steps <= controller.limits.pan_rate_deg_s * 0.1 + 1e-9)
    assert max(pans) == pytest.approx(60.0) and min(pans) == pytest.approx(-60.0)
    assert controller.tilt_deg_ == pytest.approx(-10.0)
    with pytest.raises(ValueError, match="search_pan_deg"):
        PanTiltController(search_pan_deg=120.0)


def test_bad_limits_raise():
    with pytest.raises(ValueError, match="pan_min_deg"):
        PanTiltLimits(pan_min_deg=10.0, pan_max_deg=-10.0)
    with pytest.raises(ValueError, match="tilt"):
        PanTiltLimits(tilt_min_deg=-100.0)
    with pytest.raises(ValueError, match="dt_s"):
        PanTiltController().step((0, 0, 0), (1, 0), 0.0)
