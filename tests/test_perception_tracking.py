"""Kalman tracking: smoothing, coasting, losing, circular yaw."""

import numpy as np
import pytest

from perception.tracking import KalmanTrack, TrackingConfig


def test_never_seen_is_lost_with_no_pose():
    track = KalmanTrack("teacher")
    estimate = track.step(0.0, None)
    assert estimate.status == "lost" and estimate.pose is None and estimate.velocity is None


def test_constant_velocity_is_learned_and_predicted_then_lost():
    track = KalmanTrack("teacher", TrackingConfig(max_coast_s=0.5))
    rng = np.random.default_rng(0)
    for k in range(30):
        t = 0.1 * k
        truth = (0.35 * t, 0.0, 0.0)
        est = track.step(t, np.asarray(truth) + rng.normal(0, 0.003, 3), np.eye(3) * 0.003**2)
        assert est.status == "seen"
    assert est.velocity[0] == pytest.approx(0.35, abs=0.05)
    coast = [track.step(2.9 + 0.1 * k, None) for k in range(1, 8)]  # last seen at 2.9 s
    assert [c.status for c in coast[:4]] == ["predicted"] * 4
    assert coast[3].pose[0] == pytest.approx(0.35 * 3.3, abs=0.03)
    assert coast[3].time_since_seen_s == pytest.approx(0.4)
    assert [c.status for c in coast[5:]] == ["lost", "lost"]
    assert coast[-1].pose is None and coast[-1].covariance is None
    # Restarts from the next measurement.
    again = track.step(4.0, (1.0, 1.0, 0.0))
    assert again.status == "seen" and again.pose[0] == pytest.approx(1.0)


def test_coasting_covariance_grows():
    track = KalmanTrack("teacher")
    track.step(0.0, (0.0, 0.0, 0.0))
    variances = [track.step(0.1 * k, None).covariance[0, 0] for k in range(1, 6)]
    assert np.all(np.diff(variances) > 0)


def test_yaw_across_pi_is_filtered_circularly():
    track = KalmanTrack("teacher")
    yaw = np.pi - 0.2
    for k in range(20):
        est = track.step(0.1 * k, (0.0, 0.0, np.angle(np.exp(1j * yaw))))
        yaw += np.radians(6.0)  # 60 deg/s through +-180
    assert -np.pi <= est.pose[2] < np.pi
    assert np.cos(est.pose[2] - np.angle(np.exp(1j * (yaw - np.radians(6))))) > np.cos(0.05)
    assert est.velocity[2] == pytest.approx(np.radians(60.0), rel=0.2)


def test_outlier_is_gated_and_not_reported_as_seen():
    track = KalmanTrack("teacher")
    for k in range(10):
        track.step(0.1 * k, (0.0, 0.0, 0.0))
    est = track.step(1.0, (2.0, 2.0, 0.0))
    assert est.status == "predicted" and abs(est.pose[0]) < 0.05


def _track_after_a_wrong_first_fix(config: TrackingConfig) -> tuple[int, int, float]:
    """A first fix 40 cm off and turned round (an own pose not yet found), 0.4 s unseen, then a
    robot driving slowly at a steady heading, measured every 0.1 s; returns the steps accepted,
    the steps whose heading points the wrong way and the final yaw rate (rad/s)."""
    track = KalmanTrack("teacher", config)
    track.step(0.0, (-0.118, 0.74, -0.279))
    for k in range(1, 5):
        track.step(0.1 * k, None)
    rng = np.random.default_rng(0)
    accepted = backwards = 0
    for k in range(5, 200):
        truth = np.array([-0.6 - 0.03 * (k - 5), 0.92 + 0.02 * (k - 5), 2.556])
        noisy = truth + rng.normal(0.0, [0.003, 0.003, 0.01])
        est = track.step(0.1 * k, noisy, np.diag([0.003**2, 0.003**2, 0.01**2]))
        accepted += est.status == "seen"
        backwards += est.pose is not None and np.cos(est.pose[2] - truth[2]) < 0
    return accepted, backwards, float(est.velocity[2])


def test_a_wrong_first_fix_does_not_lock_the_track_onto_an_aliased_spin():
    # Without the yaw-rate bound the filter turns about 15.7 rad/s, a whole turn between the
    # frames it accepts (one in four), and points the wrong way on most steps between them.
    unbounded = TrackingConfig(max_speed_mps=1e9, max_yaw_rate_radps=1e9)
    accepted, backwards, yaw_rate = _track_after_a_wrong_first_fix(unbounded)
    assert accepted < 60 and backwards > 90 and abs(yaw_rate) > 10
    accepted, backwards, yaw_rate = _track_after_a_wrong_first_fix(TrackingConfig())
    assert accepted >= 180 and backwards <= 10 and abs(yaw_rate) < 0.5


def test_velocity_is_clipped_to_the_robot_limits():
    track = KalmanTrack("teacher", TrackingConfig(max_speed_mps=0.3, max_yaw_rate_radps=1.0))
    for k in range(20):  # 0.5 m/s along (3, 4) / 5 and 2 rad/s
        t = 0.1 * k
        est = track.step(t, (0.3 * t, 0.4 * t, np.angle(np.exp(2j * t))))
    assert np.hypot(*est.velocity[:2]) == pytest.approx(0.3)
    assert est.velocity[1] / est.velocity[0] == pytest.approx(0.4 / 0.3, rel=0.05)
    assert est.velocity[2] == pytest.approx(1.0)


def test_bad_inputs_raise():
    track = KalmanTrack("teacher")
    track.step(1.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="backwards"):
        track.step(0.5, None)
    with pytest.raises(ValueError, match="measurement"):
        track.step(2.0, (0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match="max_coast_s"):
        TrackingConfig(max_coast_s=0.0)
    with pytest.raises(ValueError, match="max_yaw_rate_radps"):
        TrackingConfig(max_yaw_rate_radps=-1.0)
