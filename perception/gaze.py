"""Active perception: one pan-tilt head shared between watching the teacher and glancing at the
wall landmarks the student localises itself by.

The policy (:class:`GazeController`), once per control step:

1. No own pose yet (the filter is searching): sweep the pan between +-``sweep_pan_deg``, each
   sweep at the next of ``tilts_deg`` (the landmarks hang low: near ones need the lower tilt).
2. Performing alone (no teacher to watch): look at the landmarks: the head angles that should
   show the most of them from the estimated pose (:func:`perception.landmarks.landmark_view`),
   chosen again every ``relook_steps``.
3. Watching: follow the teacher while the own position's largest standard deviation is at most
   ``glance_sigma_m``, the heading's at most ``glance_sigma_deg`` and the last landmark fix was not
   rejected; otherwise glance at the landmarks until a fix is accepted with both deviations below
   half their thresholds, or
   ``glance_max_steps`` have passed, then back to the teacher. A lost teacher is searched for with
   the sweep of 1 (which passes the landmarks too).
4. Looking at landmarks with no fix accepted for ``sweep_after_steps`` (the estimate may be so
   wrong that the chosen pan shows none): sweep the pan until a fix is accepted (watching: for at
   most ``sweep_max_steps``; pressed against a wall, only the pan's far ends may show a landmark).

What a glance costs the teacher's tracking is measured by ``peoplebot track-bench``
(docs/perception.md, "Self-localisation").
"""

from __future__ import annotations

import dataclasses
import math

from perception.camera import PinholeCamera
from perception.landmarks import LandmarkMap, landmark_view
from perception.localisation import LocalisationEstimate
from perception.pantilt import PanTiltCommand, PanTiltController

#: What the head is doing: searching for a first fix, following the teacher, looking at the
#: landmarks, or sweeping for them.
GAZE_TARGETS = ("search", "teacher", "landmarks", "sweep")


@dataclasses.dataclass(frozen=True)
class GazeConfig:
    """When the head leaves the teacher for the landmarks, and where it looks for them.

    Attributes:
      glance_sigma_m: glance when the own position's largest standard deviation exceeds this,
        metres.
      glance_sigma_deg: glance when the heading's standard deviation exceeds this, degrees (a
        turn in place against a wall grows it, not the position's).
      glance_max_steps: the longest glance, control steps.
      relook_steps: the landmark view is chosen again after this many steps, control steps.
      tilts_deg: the head's tilts for landmarks, degrees (negative looks down).
      sweep_pan_deg: a sweep's pan amplitude, degrees.
      sweep_after_steps: looking at landmarks with no fix accepted for this many steps, sweep.
      sweep_max_steps: the longest sweep within a glance, control steps.
    """

    glance_sigma_m: float = 0.03
    glance_sigma_deg: float = 3.0
    glance_max_steps: int = 10
    relook_steps: int = 5
    tilts_deg: tuple[float, ...] = (-10.0, -20.0, -30.0)
    sweep_pan_deg: float = 98.0
    sweep_after_steps: int = 6
    sweep_max_steps: int = 30

    def __post_init__(self):
        if not (math.isfinite(self.glance_sigma_m) and self.glance_sigma_m > 0):
            raise ValueError(f"glance_sigma_m must be > 0 metres, got {self.glance_sigma_m!r}")
        if not (math.isfinite(self.glance_sigma_deg) and self.glance_sigma_deg > 0):
            raise ValueError(f"glance_sigma_deg must be > 0 degrees, got {self.glance_sigma_deg!r}")
        for name in ("glance_max_steps", "relook_steps", "sweep_after_steps", "sweep_max_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not self.tilts_deg or not all(-90.0 <= t <= 90.0 for t in self.tilts_deg):
            raise ValueError(
                f"tilts_deg must be one or more tilts in [-90, 90] degrees, got {self.tilts_deg!r}"
            )
        if not 0.0 < self.sweep_pan_deg <= 180.0:
            raise ValueError(
                f"sweep_pan_deg must be in (0, 180] degrees, got {self.sweep_pan_deg!r}"
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
        self._view = None
        self._since_choice = 0
        self._sweep_direction = 1.0
        self._sweeps = 0
        self._no_fix_steps = 0
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
            self.target_, self._view = "search", None
            return self._sweep(dt_s)
        self._no_fix_steps = 0 if estimate.accepted else self._no_fix_steps + 1
        sigma, sigma_deg = estimate.position_sigma_m, estimate.heading_sigma_deg
        doubtful = (
            sigma > c.glance_sigma_m or sigma_deg > c.glance_sigma_deg or estimate.rejections > 0
        )
        if watching:
            if self.target_ in ("landmarks", "sweep"):
                self._glance_steps += 1
                settled = (
                    estimate.accepted
                    and sigma <= 0.5 * c.glance_sigma_m
                    and sigma_deg <= 0.5 * c.glance_sigma_deg
                )
                longest = c.sweep_max_steps if self.target_ == "sweep" else c.glance_max_steps
                if settled or self._glance_steps > longest:
                    self.target_ = "teacher"
            elif doubtful:
                self.target_, self._glance_steps, self._view = "landmarks", 0, None
                self._no_fix_steps = 0
                self.glances_ += 1
            else:
                self.target_ = "teacher"
            if self.target_ == "teacher":
                if teacher_xy is None:  # lost: the sweep finds the teacher and the landmarks
                    return self._sweep(dt_s)
                return self.controller.step(estimate.pose, teacher_xy, dt_s)
        if self._no_fix_steps >= c.sweep_after_steps:
            if self.target_ != "sweep":  # a glance that turns into a sweep gets its full length
                self._glance_steps = 0
            self.target_, self._view = "sweep", None
            return self._sweep(dt_s)
        self.target_ = "landmarks"
        self._since_choice += 1
        if self._view is None or self._since_choice >= c.relook_steps:
            pan, tilt, _ = landmark_view(
                self.landmark_map,
                self.intrinsics,
                estimate.pose,
                c.tilts_deg,
                limits=self.controller.limits,
                mount=self.controller.mount,
            )
            self._view, self._since_choice = (pan, tilt), 0
        return self.controller.step_to(*self._view, dt_s)

    def _sweep(self, dt_s: float) -> PanTiltCommand:
        """Sweeps the pan between +-``sweep_pan_deg``, each sweep at the next tilt."""
        c = self.config
        limit = min(
            c.sweep_pan_deg, self.controller.limits.pan_max_deg, -self.controller.limits.pan_min_deg
        )
        if self.controller.pan_deg_ * self._sweep_direction >= limit - 1e-6:
            self._sweep_direction = -self._sweep_direction
            self._sweeps += 1
        tilt = c.tilts_deg[self._sweeps % len(c.tilts_deg)]
        return self.controller.step_to(self._sweep_direction * limit, tilt, dt_s)
