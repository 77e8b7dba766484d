"""The acceleration-limit estimator (``imitation.limits``) against the firmware model it
identifies (``hardware.CommandFilter``)."""

import math

import numpy as np
import pytest

from imitation.limits import AccelerationLimitEstimator, LimitCandidates, step_mean
from peoplebot_sim.hardware import Actuation, CommandFilter

CONTROL_S, PHYSICS_S = 0.1, 0.01
#: Forward and turn commands (m/s, rad/s) as a student sends them: drive, stop, turn, back.
COMMANDS = (
    [(0.35, 0.0)] * 30
    + [(0.0, 0.0)] * 20
    + [(0.0, math.radians(60.0))] * 20
    + [(0.0, 0.0)] * 10
    + [(-0.35, 0.0)] * 10
)


def test_step_mean_of_a_ramp_by_hand():
    """From 0 towards 0.35 at 0.3 per s for 0.1 s: mean 0.015, end 0.03; from 0.33 it reaches
    0.35 after 2/3 of the step: mean 0.33 + 0.02 (1 - 1/3); no limit: the target at once."""
    mean, end = step_mean([0.0, 0.33, 0.1], 0.35, [0.3, 0.3, 0.0], CONTROL_S)
    np.testing.assert_allclose(mean, [0.015, 0.33 + 0.02 * (2.0 / 3.0), 0.35])
    np.testing.assert_allclose(end, [0.03, 0.35, 0.35])
    mean, end = step_mean(0.0, -0.35, 0.3, CONTROL_S)  # backwards too
    assert (mean, end) == pytest.approx((-0.015, -0.03))


def measured_speeds(
    actuation: Actuation, rng=None, noise=(0.0, 0.0), pose_latency_steps: int = 0
) -> np.ndarray:
    """Returns the mean set-points (m/s, deg/s) over each control step of ``COMMANDS`` through
    the firmware model at the physics rate (its command latency included), seen through poses
    ``pose_latency_steps`` physics steps old, with Gaussian noise of ``noise``'s sd added."""
    firmware = CommandFilter(actuation, PHYSICS_S)
    per_step = round(CONTROL_S / PHYSICS_S)
    setpoints = [np.zeros(2)] * pose_latency_steps
    for command in COMMANDS:
        setpoints += [firmware.step(command) for _ in range(per_step)]
    setpoints = np.asarray(setpoints[: len(COMMANDS) * per_step])
    means = setpoints.reshape(len(COMMANDS), per_step, 2).mean(axis=1) * [1.0, math.degrees(1.0)]
    if rng is not None:
        means += rng.normal(0.0, 1.0, means.shape) * noise
    return means


def identify(speeds, candidates=LimitCandidates()) -> AccelerationLimitEstimator:
    estimator = AccelerationLimitEstimator(CONTROL_S, candidates)
    for command, measured in zip(COMMANDS, speeds, strict=True):
        estimator.update(command, measured)
    assert estimator.steps_measured == len(COMMANDS)
    return estimator


def estimate(speeds) -> Actuation:
    return identify(speeds).limits


@pytest.mark.parametrize("linear, yaw", [(1.0, 300.0), (0.3, 100.0), (0.075, 25.0)])
def test_the_estimator_identifies_the_firmware_limits(linear, yaw):
    """Exact speeds: the limits within one step of the candidate grid (x 1.17); speeds measured
    with noise of 0.05 m/s and 3 deg/s (an overhead camera's): within 25%."""
    step = 10 ** (2 / 30)
    exact = identify(measured_speeds(Actuation(linear_accel_mps2=linear, yaw_accel_degps2=yaw)))
    found = exact.limits
    assert exact.delays_s == (0.0, 0.0)
    assert linear / step <= found.linear_accel_mps2 <= linear * step
    assert yaw / step <= found.yaw_accel_degps2 <= yaw * step
    noisy = measured_speeds(
        Actuation(linear_accel_mps2=linear, yaw_accel_degps2=yaw),
        np.random.default_rng(0),
        noise=(0.05, 3.0),
    )
    found = estimate(noisy)
    assert found.linear_accel_mps2 == pytest.approx(linear, rel=0.25)
    assert found.yaw_accel_degps2 == pytest.approx(yaw, rel=0.25)


@pytest.mark.parametrize("linear, yaw", [(1.0, 300.0), (0.3, 100.0), (0.075, 25.0)])
def test_the_delay_is_identified_with_the_limits(linear, yaw):
    """50 ms of command latency in the firmware and poses 50 ms old (the realistic preset's):
    exact speeds give the 0.1 s delay on both axes and the limits within one grid step; with
    noise of 0.05 m/s and 3 deg/s the limits within 25%. Without the delay model the same
    exact speeds read as slower ramps (at 1 m/s^2 and 300 deg/s^2: forward and yaw both below
    0.8 of the truth)."""
    step = 10 ** (2 / 30)
    robot = Actuation(command_latency_ms=50.0, linear_accel_mps2=linear, yaw_accel_degps2=yaw)
    exact = identify(measured_speeds(robot, pose_latency_steps=5))
    assert exact.delays_s == pytest.approx((0.1, 0.1))
    assert linear / step <= exact.limits.linear_accel_mps2 <= linear * step
    assert yaw / step <= exact.limits.yaw_accel_degps2 <= yaw * step
    noisy = identify(
        measured_speeds(robot, np.random.default_rng(0), (0.05, 3.0), pose_latency_steps=5)
    )
    assert noisy.limits.linear_accel_mps2 == pytest.approx(linear, rel=0.25)
    assert noisy.limits.yaw_accel_degps2 == pytest.approx(yaw, rel=0.25)
    if linear == 1.0:
        blind = identify(
            measured_speeds(robot, pose_latency_steps=5), LimitCandidates(max_delay_steps=0)
        )
        assert blind.delays_s == (0.0, 0.0)
        assert blind.limits.linear_accel_mps2 < 0.8 * linear
        assert blind.limits.yaw_accel_degps2 < 0.8 * yaw


def test_no_limit_is_found_on_a_robot_without_limits_and_before_any_evidence():
    """A firmware without limits gives 0 (no limit); so do speeds that never change (ties go to
    no limit) and steps without a measurement (nothing compared)."""
    assert estimate(measured_speeds(Actuation())) == Actuation()
    estimator = AccelerationLimitEstimator(CONTROL_S)
    for _ in range(10):
        estimator.update((0.0, 0.0), (0.0, 0.0))
        estimator.update((0.35, 0.5), None)
    assert estimator.limits == Actuation() and estimator.steps_measured == 10
    assert estimator.delays_s == (0.0, 0.0)
    estimator.reset()
    assert estimator.steps_measured == 0


def test_bad_estimator_settings_are_refused_by_name():
    with pytest.raises(ValueError, match="dt"):
        AccelerationLimitEstimator(0.0)
    with pytest.raises(ValueError, match="linear_mps2"):
        LimitCandidates(linear_mps2=(0.0, -1.0))
    with pytest.raises(ValueError, match="max_delay_steps"):
        LimitCandidates(max_delay_steps=-1)
    with pytest.raises(ValueError, match="delay_resolution"):
        LimitCandidates(delay_resolution=0)
