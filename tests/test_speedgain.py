"""The achieved-speed estimator (``imitation.speedgain``) and the lookahead that follows each
directive at the speeds it finds."""

import math

import numpy as np
import pytest

from imitation import performance
from imitation.speedgain import SpeedGainEstimator, SpeedGainSettings
from perception.drive import DriveSpeeds

DRIVE = DriveSpeeds()


def drive_through(estimator, fractions, steps, rng=None, noise=(0.0, 0.0)):
    """Feeds ``steps`` of alternating forward and turning commands whose measured speeds are
    ``fractions`` of them (plus Gaussian noise of ``noise``'s sd, m/s and deg/s)."""
    for k in range(steps):
        command = DRIVE.command("forward" if (k // 5) % 2 == 0 else "turn_left")
        measured = [fractions[0] * command[0], fractions[1] * math.degrees(command[1])]
        if rng is not None:
            measured = [m + rng.normal(0.0, sd) for m, sd in zip(measured, noise, strict=True)]
        estimator.update(command, measured)


def test_the_estimator_starts_at_full_speed_and_finds_the_fractions_the_robot_achieves():
    """Before any measurement both fractions are 1 (the prior); a robot at 40% of its forward
    speed and 55% of its yaw rate is found within 0.02 after 6 s of driving, within 0.06 under
    noise of 3 cm/s and 6 deg/s a step; a missing pose changes nothing, a NaN axis leaves that
    axis alone, and reset forgets."""
    estimator = SpeedGainEstimator(DRIVE)
    assert estimator.gains == (1.0, 1.0)
    drive_through(estimator, (0.4, 0.55), 60)
    np.testing.assert_allclose(estimator.gains, (0.4, 0.55), atol=0.02)
    before = estimator.gains
    estimator.update(DRIVE.command("forward"), None)
    assert estimator.gains == before
    estimator.update(DRIVE.command("turn_left"), (float("nan"), 60.0))
    assert estimator.gains[0] == before[0] and estimator.gains[1] > before[1]
    estimator.reset()
    assert estimator.gains == (1.0, 1.0)
    drive_through(estimator, (0.4, 0.55), 60, np.random.default_rng(0), noise=(0.03, 6.0))
    np.testing.assert_allclose(estimator.gains, (0.4, 0.55), atol=0.06)


def test_the_estimator_forgets_and_keeps_within_its_bounds():
    """After the robot recovers from 30% to full speed its fractions come within 0.03 of it in
    8 s (four memories of 2 s); a robot that does not move reports the lower bound, one measured faster
    than commanded at most the upper; the settings refuse values by name."""
    estimator = SpeedGainEstimator(DRIVE)
    drive_through(estimator, (0.3, 0.3), 40)
    drive_through(estimator, (1.0, 1.0), 80)
    np.testing.assert_allclose(estimator.gains, (1.0, 1.0), atol=0.03)
    drive_through(estimator, (0.0, 0.0), 200)
    assert estimator.gains == (0.1, 0.1)
    drive_through(estimator, (3.0, 3.0), 200)
    assert estimator.gains == (1.5, 1.5)
    for field, value in (("forgetting", 1.0), ("prior_steps", 0.0), ("bounds", (0.0, 1.5))):
        with pytest.raises(ValueError, match=f"speed gain {field}"):
            SpeedGainSettings(**{field: value})


def test_an_axis_left_unmeasured_reports_full_speed_and_the_other_is_measured_as_before():
    """Measuring the forward axis only, the forward fraction is the two-axis estimator's and the
    yaw fraction stays 1; unknown or repeated axes are refused by name."""
    both, forward = SpeedGainEstimator(DRIVE), SpeedGainEstimator(DRIVE, axes=("forward",))
    for estimator in (both, forward):
        drive_through(estimator, (0.4, 0.55), 60)
    assert forward.gains == (both.gains[0], 1.0) and both.gains[1] < 0.6
    for axes in ((), ("sideways",), ("yaw", "yaw")):
        with pytest.raises(ValueError, match="speed gain axes"):
            SpeedGainEstimator(DRIVE, axes=axes)


def test_the_lookahead_follows_each_directive_at_the_achieved_speeds():
    """With fractions (0.5, 0.25) the forward outcome lies half as far and the turns a quarter
    as far round as at the nominal speeds."""
    lookahead = performance.SupportLookahead(horizon_s=0.5, weight=1.0)
    ends = lookahead.outcomes((0.0, 0.0, 0.0), DRIVE, gains=(0.5, 0.25))
    np.testing.assert_allclose(ends[0], (0.0875, 0.0, 0.0), atol=1e-12)  # forward
    np.testing.assert_allclose(ends[2], (0.0, 0.0, -math.radians(7.5)), atol=1e-12)
    np.testing.assert_allclose(ends[3], (0.0, 0.0, math.radians(7.5)), atol=1e-12)
