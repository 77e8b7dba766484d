"""How much of its commanded speeds a robot achieves, estimated as it drives.

A robot whose casters drag, whose floor is soft or whose firmware ramps slowly covers less ground
than its wheel commands say. The support lookahead (``performance.SupportLookahead``) follows each
directive for a fraction of a second to see where it leads; told the achieved fractions, it follows
the directive at the speeds the robot really reaches. Per axis (forward speed, yaw rate), the
fraction is the least-squares slope through the origin of the measured speed on the command sent
at the step's start, over the steps so far with exponential forgetting, started from a prior of
full speed (fraction 1) worth a few steps at the directives' speeds (forgotten alike), and kept
within bounds. The delay between a command and the speeds it causes is not modelled: a ramp or a
latency shows as a lower fraction, which is where the robot really is after the lookahead's
horizon. An axis left unmeasured reports 1 (the nominal speed).
"""

from __future__ import annotations

import dataclasses
import math

from perception.drive import DriveSpeeds

#: The axes, in the order of ``SpeedGainEstimator.gains``.
AXES = ("forward", "yaw")

#: The axes a ``SpeedGainEstimator`` measures under each measured ``SUPPORT_SPEEDS`` value.
MEASURED_AXES = {"measured": AXES, "measured_forward": ("forward",)}

#: What speeds the support lookahead follows each directive at
#: (``PerformanceConfig.support_speeds``): the directives' nominal wheel commands, those scaled
#: by the fractions this module estimates, or the forward speed scaled and the yaw rate nominal.
SUPPORT_SPEEDS = ("nominal", *MEASURED_AXES)


@dataclasses.dataclass(frozen=True)
class SpeedGainSettings:
    """The estimator's hyper-parameters.

    Attributes:
      forgetting: per control step, the weight left on what came before (0-1; 0.95: a memory of
        about 20 steps, 2 s at the 0.1 s step).
      prior_steps: the prior's weight at the start, in steps at the directives' full speeds (> 0).
      bounds: the least and largest fraction reported.
    """

    forgetting: float = 0.95
    prior_steps: float = 2.0
    bounds: tuple[float, float] = (0.1, 1.5)

    def __post_init__(self):
        if not (0 <= self.forgetting < 1):
            raise ValueError(f"speed gain forgetting must be in [0, 1), got {self.forgetting!r}")
        if not (math.isfinite(self.prior_steps) and self.prior_steps > 0):
            raise ValueError(f"speed gain prior_steps must be > 0, got {self.prior_steps!r}")
        low, high = self.bounds
        if not (0 < low <= 1 <= high):
            raise ValueError(
                f"speed gain bounds must hold 0 < low <= 1 <= high, got {self.bounds!r}"
            )


class SpeedGainEstimator:
    """The fractions of the commanded forward speed and yaw rate a robot achieves.

    Args:
      drive: the directives' speeds (the prior's scale).
      settings: the estimator's hyper-parameters.
      axes: the axes measured (of ``AXES``); an axis left out reports the fraction 1.
    """

    def __init__(self, drive: DriveSpeeds = DriveSpeeds(), settings=SpeedGainSettings(), axes=AXES):
        axes = tuple(axes)
        if not axes or any(axis not in AXES for axis in axes) or len(set(axes)) < len(axes):
            raise ValueError(f"speed gain axes must be distinct names of {AXES}, got {axes!r}")
        self.settings, self.axes = settings, axes
        # The prior's command magnitudes (m/s, deg/s) and its weight in their squares.
        scale = (drive.linear_mps, drive.turn_deg_s)
        self._prior = tuple(settings.prior_steps * s * s for s in scale)
        self.reset()

    def reset(self) -> None:
        """Starts knowing nothing but the prior (fraction 1 on both axes)."""
        # Per axis: sum of measured x commanded, sum of commanded squared, the prior's included
        # (forgotten alike with the measurements).
        self._moment = list(self._prior)
        self._power = list(self._prior)

    def update(self, command, measured=None) -> None:
        """Advances one control step.

        Args:
          command: ``(linear m/s, yaw rate rad/s)`` sent at the step's start.
          measured: ``(forward speed m/s, yaw rate deg/s)`` measured over the step, or None
            (no pose estimate: nothing learnt, nothing forgotten).
        """
        if measured is None:
            return
        sent = (float(command[0]), math.degrees(float(command[1])))
        keep = self.settings.forgetting
        for i in range(2):
            if not math.isfinite(measured[i]):
                continue
            self._moment[i] = keep * self._moment[i] + sent[i] * float(measured[i])
            self._power[i] = keep * self._power[i] + sent[i] * sent[i]

    @property
    def gains(self) -> tuple[float, float]:
        """Returns the achieved fractions ``(forward, yaw)`` of the commanded speeds (1 on an
        axis not measured)."""
        low, high = self.settings.bounds
        return tuple(
            min(high, max(low, moment / power)) if axis in self.axes else 1.0
            for axis, moment, power in zip(AXES, self._moment, self._power, strict=True)
        )
