"""Active perception: one pan-tilt head shared between watching the teacher and glancing at the
wall landmarks the student localises itself by.

The policy (:class:`GazeController`), once per control step:

1. No own pose yet (the filter is searching): sweep the pan (``PanTiltController``'s search).
2. Performing alone (no teacher to watch): look at the landmarks: the pan that should show the
   most of them from the estimated pose (:func:`perception.landmarks.landmark_pan`), chosen again
   every ``relook_steps``.
3. Watching: follow the teacher while the own position's largest standard deviation is at most
   ``glance_sigma_m``; above it, glance at the landmarks until it is below ``glance_sigma_m / 2``
   or ``glance_max_steps`` have passed, then back to the teacher. A lost teacher is searched for
   with the pan sweep (which passes the landmarks too).

What a glance costs the teacher's tracking is measured by ``peoplebot track-bench``
(docs/perception.md, "Self-localisation").
"""

from __future__ import annotations

import dataclasses
import math

from perception.camera import PinholeCamera
from perception.landmarks import LandmarkMap, landmark_pan
from perception.localisation import LocalisationEstimate
from perception.pantilt import PanTiltCommand, PanTiltController

GAZE_TARGETS = ("search", "teacher", "landmarks")


@dataclasses.dataclass(frozen=True)
class GazeConfig:
    """When the head leaves the teacher for the landmarks.

    Attributes:
      glance_sigma_m: glance when the own position's largest standard deviation exceeds this,
        metres.
      glance_max_steps: the longest glance, control steps.
      relook_steps: the landmark pan is chosen again after this many steps, control steps.
      landmark_tilt_deg: the head's tilt when looking at landmarks, degrees (negative looks down).
    """

    glance_sigma_m: float = 0.03
    glance_max_steps: int = 10
    relook_steps: int = 5
    landmark_tilt_deg: float = -15.0

    def __post_init__(self):
        if not (math.isfinite(self.glance_sigma_m) and self.glance_sigma_m > 0):
            raise ValueError(f"glance_sigma_m must be > 0 metres, got {self.glance_sigma_m!r}")
        for name in ("glance_max_steps", "relook_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not -90.0 <= self.landmark_tilt_deg <= 90.0:
            raise ValueError(
                f"landmark_tilt_deg must be in [-90, 90] degrees, got {self.landmark_tilt_deg!r}"
            )


class GazeController:
    """Steers the head between the teacher and the landmarks (module docstring).

    Args:
      landmark_map: the arena's landmarks.
      intrinsics: the head camera's calibration.
      config: the policy's settings.
      controller: the head's controller (limits, rates, search sweep); a default one if None.
    """

    def __init__(
        self,
        landmark_map: LandmarkMap,
        intrinsics: PinholeCamera,
        config: GazeConfig = GazeConfig(),
        controller: PanTiltController | None = None,
    ):
        self.landmark_map = landmark_map
        self.intrinsics = intrinsics
        self.config = config
        self.controller = PanTiltController() if controller is None else controller
        self.target_ = "search"
        self._glance_steps = 0
        self._landmark_pan = None
        self._since_choice = 0
        self.glances_ = 0

    def step(
        self, estimate: LocalisationEstimate, teacher_xy, dt_s: float, watching: bool = True
    ) -> PanTiltCommand:
        """Returns the head's command for one control step of ``dt_s`` seconds.

        Args:
          estimate: the self-localisation filter's state after this step.
          teacher_xy: the tracked teacher's ``(x_m, y_m)``, world frame, or None.
          watching: False when performing alone (no teacher to watch).
        """
        c = self.config
        if estimate.pose is None:
            self.target_, self._landmark_pan = "search", None
            # The sweep needs no pose; the controller checks one is given.
            return self.controller.step((0.0, 0.0, 0.0), None, dt_s)
        sigma = estimate.position_sigma_m
        if watching:
            if self.target_ == "landmarks":
                self._glance_steps += 1
                if sigma <= 0.5 * c.glance_sigma_m or self._glance_steps > c.glance_max_steps:
                    self.target_ = "teacher"
            elif sigma > c.glance_sigma_m:
                self.target_, self._glance_steps, self._landmark_pan = "landmarks", 0, None
                self.glances_ += 1
            else:
                self.target_ = "teacher"
            if self.target_ == "teacher":
                return self.controller.step(estimate.pose, teacher_xy, dt_s)
        else:
            self.target_ = "landmarks"
        self._since_choice += 1
        if self._landmark_pan is None or self._since_choice >= c.relook_steps:
            self._landmark_pan, _ = landmark_pan(
                self.landmark_map,
                self.intrinsics,
                estimate.pose,
                c.landmark_tilt_deg,
                limits=self.controller.limits,
                mount=self.controller.mount,
            )
            self._since_choice = 0
        return self.controller.step_to(self._landmark_pan, c.landmark_tilt_deg, dt_s)
