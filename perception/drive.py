"""The four motor directives' wheel commands: the drive shared by the teacher, the student and the
inference of directives from observed motion.

A directive is one of the associator's motor units (``associator.encoding.DIRECTIVES``, the paper's
order: forward, backward, turn right, turn left). Its wheel command is the pair of targets of a
differential drive's servos: linear speed in m/s along the robot's heading and yaw rate in rad/s,
counter-clockwise positive (a ROS ``Twist``'s ``linear.x`` and ``angular.z``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from associator.encoding import DIRECTIVES, directive_index


@dataclasses.dataclass(frozen=True)
class DriveSpeeds:
    """Wheel-servo targets of the directives.

    Attributes:
      linear_mps: speed of 'forward' and 'backward' in m/s (PeopleBot top speed: 0.75 m/s).
      turn_deg_s: yaw rate of the turns in deg/s (PeopleBot top rate: 1.74 rad/s, 99.7 deg/s).
    """

    linear_mps: float = 0.35
    turn_deg_s: float = 60.0

    def __post_init__(self):
        if not (isinstance(self.linear_mps, (int, float)) and 0 < self.linear_mps <= 0.75):
            raise ValueError(f"linear_mps must be in (0, 0.75] m/s, got {self.linear_mps!r}")
        if not (isinstance(self.turn_deg_s, (int, float)) and 0 < self.turn_deg_s <= 99.7):
            raise ValueError(f"turn_deg_s must be in (0, 99.7] deg/s, got {self.turn_deg_s!r}")

    @property
    def turn_radps(self) -> float:
        """Returns the turns' yaw rate in rad/s."""
        return float(np.radians(self.turn_deg_s))

    def command(self, directive: str) -> tuple[float, float]:
        """Returns ``(linear m/s, yaw rate rad/s)`` for a directive name."""
        index = directive_index(directive)
        return _UNIT_COMMANDS[index][0] * self.linear_mps, _UNIT_COMMANDS[index][
            1
        ] * self.turn_radps

    def graded_command(self, activations) -> tuple[float, float]:
        """Returns ``(linear m/s, yaw rate rad/s)`` from graded motor activations, shape (4,).

        Forward minus backward drives, turn left minus turn right steers; each is normalised by the
        sum of all activations, so one active unit gives exactly that directive's command.
        """
        a = np.asarray(activations, dtype=float)
        if a.shape != (4,) or not np.all(np.isfinite(a)):
            raise ValueError(
                f"activations must be 4 finite numbers in {DIRECTIVES} order, got {a!r}"
            )
        a = np.clip(a, 0.0, None)
        total = a.sum()
        if total <= 0:
            return 0.0, 0.0
        linear = (a[0] - a[1]) / total * self.linear_mps
        turn = (a[3] - a[2]) / total * self.turn_radps
        return float(linear), float(turn)


# (sign of linear speed, sign of yaw rate) per directive, in DIRECTIVES order.
_UNIT_COMMANDS = ((1.0, 0.0), (-1.0, 0.0), (0.0, -1.0), (0.0, 1.0))
