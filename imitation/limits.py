"""A robot's acceleration limits estimated from its own response to the commands it sends.

A student not told the firmware limits of the robot it drives (``performance.brake_limits =
"estimated"``) identifies them as it drives. The firmware model is ``hardware.CommandFilter``'s:
each set-point (forward m/s, yaw deg/s) moves towards the command by at most limit x dt per
step. Between a command and the poses that show its effect lies a delay (the command link's
latency plus the camera pipeline's), which the estimator identifies with the limits: for every
candidate delay and limit it runs that model on the commands the student sent, shifted by the
delay, and compares the mean set-point it predicts over each control step with the speed the
student measured over that step (from its last two pose estimates); it keeps, for the forward
speed and the yaw rate separately, the pair with the least squared error so far: the maximum
likelihood pair under Gaussian measurement noise. The predictions depend on the commands only,
so noise in the measured speeds adds variance, not bias. Candidates tie until a command changes
the speed; a tie goes to no delay and "no limit" (the first candidates). Reset at each trial's
start.
"""

from __future__ import annotations

import collections
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
    """The limits and delays the estimator chooses among (0: no limit, the set-point follows at
    once; no delay).

    Attributes:
      linear_mps2: forward accelerations, m/s^2 (default 0.03-3: the nominal robot's servos reach
        0.35 m/s in about 0.15 s, near 3).
      yaw_degps2: yaw accelerations, deg/s^2 (default 10-1,000).
      delay_resolution: delays are whole multiples of a control step over this (4: 25 ms at the
        0.1 s step).
      max_delay_steps: the longest delay, control steps (5: 0.5 s, past the realistic preset's
        50 ms camera plus 50 ms command latency; 0: no delay model).
    """

    linear_mps2: tuple = _candidates(0.03, 3.0, 31)
    yaw_degps2: tuple = _candidates(10.0, 1000.0, 31)
    delay_resolution: int = 4
    max_delay_steps: int = 5

    def __post_init__(self):
        for name in ("linear_mps2", "yaw_degps2"):
            values = getattr(self, name)
            if not values or not all(
                isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 for v in values
            ):
                raise ValueError(
                    f"limit candidates {name} must be numbers >= 0 (0: no limit), got {values!r}"
                )
        for name, low in (("delay_resolution", 1), ("max_delay_steps", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(
                    f"limit candidates {name} must be a whole number >= {low}, got {value!r}"
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
    """Identifies the forward and yaw acceleration limits of the robot a student drives, and the
    delay between its commands and the poses it measures.

    Args:
      dt: seconds per control step (one command, one pair of measured speeds).
      candidates: the limits and delays chosen among.
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
        resolution = candidates.delay_resolution
        # Candidate delays in sub-steps of dt / resolution, a column against the limits' row.
        self._delays = np.arange(candidates.max_delay_steps * resolution + 1)[:, None]
        self.reset()

    def reset(self) -> None:
        """Starts at rest, knowing nothing: every candidate's set-points 0, errors 0, and the
        commands before the start 0."""
        shape = (len(self._delays),)
        self._setpoints = [np.zeros(shape + limits.shape) for limits in self._limits]
        self._errors = [np.zeros(shape + limits.shape) for limits in self._limits]
        # The commands (m/s, deg/s) sent at the starts of the last steps, the newest last.
        self._sent = collections.deque(
            [np.zeros(2)] * (self.candidates.max_delay_steps + 1),
            maxlen=self.candidates.max_delay_steps + 1,
        )
        self.steps_measured = 0

    def update(self, command, measured=None) -> None:
        """Advances one control step.

        Args:
          command: ``(linear m/s, yaw rate rad/s)`` sent at the step's start.
          measured: ``(forward speed m/s, yaw rate deg/s)`` measured over the step, or None
            (no pose estimate: the set-points advance, nothing is compared).
        """
        self._sent.append(np.array([float(command[0]), math.degrees(float(command[1]))]))
        sent = np.asarray(self._sent)
        resolution = self.candidates.delay_resolution
        substep = self.dt / resolution
        means = [np.zeros_like(setpoints) for setpoints in self._setpoints]
        for s in range(resolution):
            # Delayed by d sub-steps, sub-step s follows the command sent (d - s) / resolution
            # steps before this one, rounded up to a whole step.
            targets = sent[-1 + (s - self._delays) // resolution]  # (delays, 1, 2)
            for i, limits in enumerate(self._limits):
                mean, self._setpoints[i] = step_mean(
                    self._setpoints[i], targets[..., i], limits, substep
                )
                means[i] += mean / resolution
        for i in range(2):
            if measured is not None and math.isfinite(measured[i]):
                self._errors[i] += (means[i] - float(measured[i])) ** 2
        if measured is not None:
            self.steps_measured += 1

    def _best(self, axis: int) -> tuple[int, int]:
        """Returns the (delay, limit) indices of an axis's least error (the first of a tie)."""
        errors = self._errors[axis]
        delay, limit = np.unravel_index(int(np.argmin(errors)), errors.shape)
        return int(delay), int(limit)

    @property
    def limits(self) -> Actuation:
        """Returns the most likely limits so far (0: no limit), as an ``Actuation`` record."""
        linear, yaw = (float(self._limits[i][self._best(i)[1]]) for i in range(2))
        return Actuation(linear_accel_mps2=linear, yaw_accel_degps2=yaw)

    @property
    def delays_s(self) -> tuple[float, float]:
        """Returns the most likely delays so far, seconds, of the forward speed and the yaw
        rate (each identified with its axis's limit)."""
        substep = self.dt / self.candidates.delay_resolution
        return tuple(self._best(i)[0] * substep for i in range(2))
