"""A robot's acceleration limits estimated from its own response to the commands it sends.

A student not told the firmware limits of the robot it drives (``performance.brake_limits =
"estimated"``) identifies them as it drives. The firmware model is ``hardware.CommandFilter``'s:
each set-point (forward m/s, yaw deg/s) moves towards the command by at most limit x dt per
step. For every candidate limit the estimator runs that model on the commands the student sent
and compares the mean set-point it predicts over each control step with the speed the student
measured over that step (from its last two pose estimates); it keeps, for the forward speed and
the yaw rate separately, the candidate with the least squared error so far: the maximum
likelihood limit under Gaussian measurement noise. The predictions depend on the commands only,
so noise in the measured speeds adds variance, not bias. Candidates tie until a command changes
the speed; a tie goes to "no limit" (the first candidate). Reset at each trial's start.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from peoplebot_sim.hardware import Actuation

#: Where the limits a student brakes ahead at come from (``PerformanceConfig.brake_limits``):
#: the robot's own (told) or this module's estimate.
BRAKE_LIMITS = ("told", "estimated")


def _candidates(low: float, high: float, count: int) -> tuple:
    """Returns "no limit" (0) then ``count`` limits spaced evenly in log from ``low`` to
    ``high``."""
    return (0.0, *(float(v) for v in np.geomspace(low, high, count)))


@dataclasses.dataclass(frozen=True)
class LimitCandidates:
    """The limits the estimator chooses among (0: no limit, the set-point follows at once).

    Attributes:
      linear_mps2: forward accelerations, m/s^2 (default 0.03-3: the nominal robot's servos reach
        0.35 m/s in about 0.15 s, near 3).
      yaw_degps2: yaw accelerations, deg/s^2 (default 10-1,000).
    """

    linear_mps2: tuple = _candidates(0.03, 3.0, 31)
    yaw_degps2: tuple = _candidates(10.0, 1000.0, 31)

    def __post_init__(self):
        for name in ("linear_mps2", "yaw_degps2"):
            values = getattr(self, name)
            if not values or not all(
                isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 for v in values
            ):
                raise ValueError(
                    f"limit candidates {name} must be numbers >= 0 (0: no limit), got {values!r}"
                )


def step_mean(start, target, limit, dt: float):
    """Returns ``(mean over the step, value at its end)`` of set-points that start at ``start``
    and ramp towards ``target`` at ``limit`` per second for ``dt`` seconds (arrays broadcast;
    a limit of 0 follows at once)."""
    start, target, limit = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (start, target, limit))
    )
    gap = target - start
    unlimited = limit <= 0
    reach = np.where(unlimited, 0.0, limit * dt)
    ramping = ~unlimited & (np.abs(gap) >= reach)  # still short of the target at the step's end
    end = np.where(ramping, start + np.sign(gap) * reach, target)
    # Reaching the target after a fraction f of the step, the mean is start + gap (1 - f / 2).
    fraction = np.where(unlimited | ramping, 0.0, np.abs(gap) / np.where(reach > 0, reach, 1.0))
    mean = np.where(
        ramping, start + np.sign(gap) * reach / 2.0, start + gap * (1.0 - fraction / 2.0)
    )
    return mean, end


class AccelerationLimitEstimator:
    """Identifies the forward and yaw acceleration limits of the robot a student drives.

    Args:
      dt: seconds per control step (one command, one pair of measured speeds).
      candidates: the limits chosen among.
    """

    def __init__(self, dt: float, candidates: LimitCandidates = LimitCandidates()):
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        self.dt = float(dt)
        self.candidates = candidates
        self._limits = (
            np.asarray(candidates.linear_mps2, float),
            np.asarray(candidates.yaw_degps2, float),
        )
        self.reset()

    def reset(self) -> None:
        """Starts at rest, knowing nothing: every candidate's set-points 0, errors 0."""
        self._setpoints = [np.zeros(len(limits)) for limits in self._limits]
        self._errors = [np.zeros(len(limits)) for limits in self._limits]
        self.steps_measured = 0

    def update(self, command, measured=None) -> None:
        """Advances one control step.

        Args:
          command: ``(linear m/s, yaw rate rad/s)`` sent at the step's start.
          measured: ``(forward speed m/s, yaw rate deg/s)`` measured over the step, or None
            (no pose estimate: the set-points advance, nothing is compared).
        """
        targets = (float(command[0]), math.degrees(float(command[1])))
        for i, limits in enumerate(self._limits):
            mean, self._setpoints[i] = step_mean(self._setpoints[i], targets[i], limits, self.dt)
            if measured is not None and math.isfinite(measured[i]):
                self._errors[i] += (mean - float(measured[i])) ** 2
        if measured is not None:
            self.steps_measured += 1

    @property
    def limits(self) -> Actuation:
        """Returns the most likely limits so far (0: no limit), as an ``Actuation`` record."""
        linear, yaw = (
            float(limits[int(np.argmin(errors))])
            for limits, errors in zip(self._limits, self._errors, strict=True)
        )
        return Actuation(linear_accel_mps2=linear, yaw_accel_degps2=yaw)
