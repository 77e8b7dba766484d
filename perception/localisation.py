"""Self-localisation: the student's base pose from wheel odometry and wall landmarks (an EKF).

State: ``(x_m, y_m, yaw_rad)`` of the robot frame in the world (x east, y north; yaw
counter-clockwise from +x), with its 3x3 covariance.

Motion model (each control step, from the wheel encoders; ``perception.odometry``'s geometry): the
wheels roll ``d_left``, ``d_right`` metres, so the base travels ``ds = (d_left + d_right) / 2``
along its mean heading ``yaw + dtheta / 2`` and turns ``dtheta = (d_right - d_left) / track``.
Their errors are independent, zero-mean, with variances growing with the motion (a random walk)::

    var(ds)     = k_distance^2 |ds| + floor_distance^2
    var(dtheta) = k_turn^2 |dtheta| + k_turn_per_distance^2 |ds| + floor_turn^2

propagated through the motion's Jacobians (``P <- F P F^T + G Q G^T``).

Contact (with ``wall_half_side_m`` and ``footprint_m``): when a step ends with the robot's
footprint, at the estimated pose, within ``contact_margin_m`` of a wall (a corner), of a fixed
obstacle in ``obstacle_boxes_m`` (the table) or of a moving one the caller names (a disc: the
other robot where it was last tracked), the robot is taken to be touching it: the encoders count
what the wheels turned, but the base may have moved anything from none of it to all of it
(pushing on, the wheels slip; turning in place, a corner rubbing on the wall may hold it). The
step's distance is then applied scaled by ``contact_distance_scale`` and its turn by
``contact_turn_scale``, and both get the extra standard deviation ``contact_slip_sigma`` times
the measured step, so the covariance grows with every slipping step instead of staying
confident while blind.

Doubt: a rejected fix shows that the wheels may have lied (a push by the other robot, a slip the
contact model did not foresee); until ``doubt_fixes`` fixes have been accepted after it every
step gets the slip's extra noise (unscaled), so that a robot still being pushed is followed by
its fixes instead of re-initialised again and again.

Measurement model: a :class:`~perception.landmarks.LandmarkFix`, the pose fitted to every visible
landmark's corners at once, with the fit's covariance (corner noise ``corner_sigma_px``) plus a
floor ``fix_floor_sigma`` for what the corner noise does not cover (the head's calibration, the
robot's rocking). Innovation ``nu = fix - x`` (yaw wrapped), ``S = P + R``; a fix whose normalised
innovation squared ``nu^T S^-1 nu`` exceeds ``gate_nis`` is rejected (a Mahalanobis gate), and
the state's covariance is inflated by ``reject_inflation`` (fading memory: the wheels may have
slipped).

Without a known start the filter is ``searching`` until a fix from at least two landmarks (no
prior: :meth:`LandmarkLocator.locate` tries every IPPE start) initialises it, or from one after
``single_init_after_steps``. With ``free_half_side_m`` the predicted position is held inside the
arena (a state constraint, by projection). A kidnapping (the robot
moved by hand, or slipping against a wall) shows as fixes rejected in a row: after
``reinit_after`` of them the filter re-initialises from the latest image: a fresh multi-landmark
fit, or else the latest fix (fitted from the prediction, so even one landmark's flip is resolved).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from perception.landmarks import LandmarkFix, LandmarkLocator
from perception.odometry import DriveGeometry, arc_chord
from perception.pose import check_planar_pose, wrap_radians

LOCALISATION_STATUSES = ("searching", "tracking")
#: The 95% point of chi-square with 2 degrees of freedom: the 95% position ellipse is
#: ``d^T P_xy^-1 d <= CHI2_2DOF_95``.
CHI2_2DOF_95 = 5.991


@dataclasses.dataclass(frozen=True)
class LocaliserConfig:
    """The filter's noise model, gate and (re)initialisation (the numbers: docs/perception.md,
    "Self-localisation").

    Attributes:
      k_distance: distance noise, m per sqrt(m) travelled.
      k_turn: turn noise, rad per sqrt(rad) turned.
      k_turn_per_distance: heading noise from driving, rad per sqrt(m).
      floor_distance_m, floor_turn_rad: per-step noise floors.
      fix_floor_sigma: standard deviations (m, m, rad) added in quadrature to every fix.
      gate_nis: largest normalised innovation squared accepted (chi-square, 3 degrees of
        freedom: 16.27 is its 99.9% point).
      reinit_after: rejected fixes in a row that re-initialise the filter from the latest fix.
      init_inflation: a fix's covariance is multiplied by this when it initialises the filter.
      reject_inflation: the state's covariance is multiplied by this at each rejected fix (1
        keeps it); a run of consistent fixes the odometry contradicts then passes the gate even
        from a single landmark, which cannot re-initialise the filter.
      single_init_after_steps: searching this many steps without a fix from two landmarks, one
        landmark may initialise the filter (its flip is resolved by the level robot: on synthetic
        corners the error is 2.8 cm median, 20 cm p95, docs/perception.md).
      wall_half_side_m: the walls' inner faces, metres from the arena's centre along x and y (a
        square arena centred on the world origin); with ``footprint_m`` it turns on the contact
        model (module docstring). None: no contact model.
      footprint_m: the robot's outline around its frame's origin, metres: ``(front, rear,
        half_width)`` (a rectangle, robot frame, x forward).
      obstacle_boxes_m: fixed obstacles, ``(x_min, x_max, y_min, y_max)`` world metres each
        (axis-aligned boxes: the table).
      contact_margin_m: the footprint this close to a wall or an obstacle is in contact, metres.
      contact_distance_scale, contact_turn_scale: the shares of a step's distance and turn in
        contact that are applied to the state (measured in the simulator: the base moves a median
        3-22% of the encoders' distance and turns a median 100% of their turn,
        docs/perception.md).
      contact_slip_sigma: the extra standard deviation of a step in contact, as a share of it.
      doubt_fixes: after a rejected fix, the steps carry the slip's noise until this many fixes
        have been accepted (0: never).
      free_half_side_m: where the robot frame's origin can be: within this of the arena's centre
        along x and y (a square arena centred on the world origin, less the robot's half-width);
        an estimate outside is moved back to the edge (wheels slipping against a wall drive the
        odometry through it). None: no bound.
    """

    k_distance: float = 0.02
    k_turn: float = 0.05
    k_turn_per_distance: float = 0.02
    floor_distance_m: float = 0.001
    floor_turn_rad: float = 0.001
    fix_floor_sigma: tuple[float, float, float] = (0.005, 0.005, 0.004)
    gate_nis: float = 16.27
    reinit_after: int = 5
    init_inflation: float = 4.0
    reject_inflation: float = 2.0
    single_init_after_steps: int = 30
    wall_half_side_m: float | None = None
    footprint_m: tuple[float, float, float] | None = None
    obstacle_boxes_m: tuple[tuple[float, float, float, float], ...] = ()
    contact_margin_m: float = 0.03
    contact_distance_scale: float = 0.25
    contact_turn_scale: float = 1.0
    contact_slip_sigma: float = 1.0
    doubt_fixes: int = 5
    free_half_side_m: float | None = None

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            values = value if isinstance(value, tuple) else (value,)
            if field.name == "fix_floor_sigma" and len(values) != 3:
                raise ValueError(f"fix_floor_sigma must be 3 numbers (m, m, rad), got {value!r}")
            if field.name == "footprint_m" and value is not None and len(values) != 3:
                raise ValueError(
                    f"footprint_m must be 3 numbers (front, rear, half_width) in metres, got {value!r}"
                )
            if field.name in ("free_half_side_m", "wall_half_side_m", "footprint_m") and (
                value is None
            ):
                continue
            if field.name == "obstacle_boxes_m":
                for box in value:
                    box = tuple(box)
                    if (
                        len(box) != 4
                        or not all(math.isfinite(v) for v in box)
                        or not (box[0] < box[1] and box[2] < box[3])
                    ):
                        raise ValueError(
                            "obstacle_boxes_m must hold (x_min, x_max, y_min, y_max) boxes in "
                            f"metres, min < max, got {box!r}"
                        )
                continue
            if field.name == "doubt_fixes":
                if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                    raise ValueError(f"doubt_fixes must be an integer >= 0, got {value!r}")
                continue
            if field.name in ("reinit_after", "single_init_after_steps"):
                if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                    raise ValueError(f"{field.name} must be an integer >= 1, got {value!r}")
                continue
            for v in values:
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise ValueError(f"{field.name} must be finite numbers, got {value!r}")
                if v < 0 or (field.name in ("gate_nis", "init_inflation") and v <= 0):
                    raise ValueError(
                        f"{field.name} must be >= 0 (gate, inflation > 0), got {value!r}"
                    )
                if field.name == "reject_inflation" and v < 1:
                    raise ValueError(f"reject_inflation must be >= 1, got {value!r}")
                if field.name.startswith("contact_") and field.name.endswith("_scale") and v > 1:
                    raise ValueError(f"{field.name} must be in [0, 1], got {value!r}")


@dataclasses.dataclass(frozen=True, eq=False)
class LocalisationEstimate:
    """The filter after one step.

    Attributes:
      pose: ``(x_m, y_m, yaw_rad)``, world frame, shape (3,); None while searching.
      covariance: of ``pose``, shape (3, 3); None while searching.
      status: one of ``LOCALISATION_STATUSES``.
      fix: this step's landmark fix, None when there was none.
      accepted: whether ``fix`` updated the filter (None without a fix); a fix that initialises or
        re-initialises the filter counts as accepted.
      nis: the fix's normalised innovation squared (NaN without a fix or while searching).
      reinitialised: the filter was (re)initialised from ``fix`` this step.
      rejections: fixes rejected in a row so far (a sign the pose may be wrong).
      steps_since_fix: control steps since the last accepted fix (0 this step; counted from the
        start while searching).
      contact: the last odometry step was taken as slipping against a wall or an obstacle (the
        contact model).
      doubting: the wheels are doubted since a rejected fix (the module docstring).
    """

    pose: np.ndarray | None
    covariance: np.ndarray | None
    status: str
    fix: LandmarkFix | None = None
    accepted: bool | None = None
    nis: float = float("nan")
    reinitialised: bool = False
    rejections: int = 0
    steps_since_fix: int = 0
    contact: bool = False
    doubting: bool = False

    @property
    def marker_ids(self) -> tuple[int, ...]:
        """Returns the ids of the landmarks this step's fix used (empty without one)."""
        return () if self.fix is None else self.fix.marker_ids

    @property
    def position_sigma_m(self) -> float:
        """Returns the position's largest standard deviation, metres (infinite while searching)."""
        if self.covariance is None:
            return math.inf
        return float(math.sqrt(max(np.linalg.eigvalsh(self.covariance[:2, :2])[-1], 0.0)))

    @property
    def heading_sigma_deg(self) -> float:
        """Returns the heading's standard deviation, degrees (infinite while searching)."""
        if self.covariance is None:
            return math.inf
        return math.degrees(math.sqrt(max(float(self.covariance[2, 2]), 0.0)))


class SelfLocaliser:
    """Tracks the student's pose from wheel encoders and landmark fixes (EKF; module docstring).

    Args:
      locator: makes the landmark fixes (the map, the head camera, the mount).
      config: the filter's noise model and gates.
      geometry: wheel radius and track width, for the encoders.
    """

    def __init__(
        self,
        locator: LandmarkLocator,
        *,
        config: LocaliserConfig = LocaliserConfig(),
        geometry: DriveGeometry = DriveGeometry(),
    ):
        self.locator = locator
        self.config = config
        self.geometry = geometry
        self.reset()

    def reset(self, start_pose=None, start_covariance=None, wheel_angles=None) -> None:
        """Starts afresh: from a known ``start_pose`` (x_m, y_m, yaw_rad) with ``start_covariance``
        (default tiny), or searching (None). ``wheel_angles``: the encoders' readings now, radians
        (left, right); else the first :meth:`predict_wheels` only records them."""
        self.pose_ = None
        self.covariance_ = None
        if start_pose is not None:
            self.pose_ = np.array(check_planar_pose(start_pose, "start_pose"))
            covariance = (
                np.diag([1e-6, 1e-6, 1e-6]) if start_covariance is None else start_covariance
            )
            covariance = np.array(covariance, dtype=float)
            if covariance.shape != (3, 3) or not np.all(np.isfinite(covariance)):
                raise ValueError(
                    f"start_covariance must be a finite 3x3 matrix, got shape {covariance.shape}"
                )
            self.covariance_ = covariance
        self.rejections_ = 0
        self.steps_since_fix_ = 0
        self.contact_ = False
        self.doubt_ = 0
        self._wheels = None
        if wheel_angles is not None:
            self._wheels = self._check_wheels(wheel_angles)

    @property
    def status(self) -> str:
        """Returns "searching" before the first pose, then "tracking"."""
        return "searching" if self.pose_ is None else "tracking"

    def estimate(self, **record) -> LocalisationEstimate:
        """Returns the filter's present state as a record (``record``: this step's fix fields)."""
        if record.get("accepted"):
            self.steps_since_fix_ = 0
        return LocalisationEstimate(
            None if self.pose_ is None else self.pose_.copy(),
            None if self.covariance_ is None else self.covariance_.copy(),
            self.status,
            **record,
            rejections=self.rejections_,
            steps_since_fix=self.steps_since_fix_,
            contact=self.contact_,
            doubting=self.doubt_ > 0,
        )

    @staticmethod
    def _check_wheels(wheel_angles) -> tuple[float, float]:
        values = np.asarray(wheel_angles, dtype=float)
        if values.shape != (2,) or not np.all(np.isfinite(values)):
            raise ValueError(
                f"wheel_angles must be two finite radians (left, right), got {wheel_angles!r}"
            )
        return float(values[0]), float(values[1])

    def predict_wheels(self, wheel_angles, movers=()) -> None:
        """Advances the state with the encoders' new readings ``(left, right)``, radians
        (``movers``: as :meth:`predict`)."""
        left, right = self._check_wheels(wheel_angles)
        if self._wheels is not None:
            r = self.geometry.wheel_radius_m
            d_left, d_right = (left - self._wheels[0]) * r, (right - self._wheels[1]) * r
            self.predict(
                (d_left + d_right) / 2.0, (d_right - d_left) / self.geometry.track_m, movers
            )
        self._wheels = (left, right)

    def predict(self, distance_m: float, turn_rad: float, movers=()) -> None:
        """Advances the state by one odometry step: ``distance_m`` along the mean heading, then
        ``turn_rad`` in all (the motion model in the module docstring). ``movers``: moving
        obstacles now, discs ``(x_m, y_m, radius_m)`` in the world frame (the other robot)."""
        if not (math.isfinite(distance_m) and math.isfinite(turn_rad)):
            raise ValueError(
                f"distance_m and turn_rad must be finite, got {distance_m}, {turn_rad}"
            )
        if self.pose_ is None:
            return
        c = self.config
        self.contact_ = self.in_contact(distance_m, turn_rad, movers)
        # The slip's variances, from the measured step (zero out of contact and doubt).
        slip = c.contact_slip_sigma if self.contact_ or self.doubt_ > 0 else 0.0
        slip_q = np.diag([(slip * distance_m) ** 2, (slip * turn_rad) ** 2])
        if self.contact_:
            distance_m *= c.contact_distance_scale
            turn_rad *= c.contact_turn_scale
        chord, heading = arc_chord(self.pose_[2], distance_m, turn_rad)
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        f = np.array([[1.0, 0.0, -chord * sin_h], [0.0, 1.0, chord * cos_h], [0.0, 0.0, 1.0]])
        g = np.array([[cos_h, -0.5 * chord * sin_h], [sin_h, 0.5 * chord * cos_h], [0.0, 1.0]])
        q = np.diag(
            [
                c.k_distance**2 * abs(distance_m) + c.floor_distance_m**2,
                c.k_turn**2 * abs(turn_rad)
                + c.k_turn_per_distance**2 * abs(distance_m)
                + c.floor_turn_rad**2,
            ]
        )
        q = q + slip_q
        self.pose_ = self.pose_ + np.array([chord * cos_h, chord * sin_h, turn_rad])
        self.pose_[2] = float(wrap_radians(self.pose_[2]))
        if c.free_half_side_m is not None:  # the state constraint: projected back inside
            limit = c.free_half_side_m
            self.pose_[:2] = np.clip(self.pose_[:2], -limit, limit)
        covariance = f @ self.covariance_ @ f.T + g @ q @ g.T
        self.covariance_ = 0.5 * (covariance + covariance.T)

    def footprint_corners(self, pose) -> np.ndarray:
        """Returns the footprint's corners at ``pose`` (x_m, y_m, yaw_rad), world metres, shape
        (4, 2) (``config.footprint_m`` must be set)."""
        front, rear, half_width = self.config.footprint_m
        local = np.array(
            [[front, half_width], [front, -half_width], [-rear, -half_width], [-rear, half_width]]
        )
        c, s = math.cos(pose[2]), math.sin(pose[2])
        return local @ np.array([[c, s], [-s, c]]) + np.asarray(pose[:2], dtype=float)

    def in_contact(self, distance_m: float, turn_rad: float, movers=()) -> bool:
        """Returns True when the step ``(distance_m, turn_rad)`` from the estimated pose ends with
        the footprint within ``contact_margin_m`` of a wall, an obstacle box or one of ``movers``
        (discs ``(x_m, y_m, radius_m)``, world frame); False without the contact model, a pose
        or a motion."""
        c = self.config
        if self.pose_ is None or c.wall_half_side_m is None or c.footprint_m is None:
            return False
        if distance_m == 0.0 and turn_rad == 0.0:
            return False
        chord, heading = arc_chord(self.pose_[2], distance_m, turn_rad)
        after = self.pose_ + np.array(
            [chord * math.cos(heading), chord * math.sin(heading), turn_rad]
        )
        corners = self.footprint_corners(after)
        margin = c.contact_margin_m
        if np.max(np.abs(corners)) > c.wall_half_side_m - margin:
            return True
        front, rear, half_width = c.footprint_m
        cos_h, sin_h = math.cos(after[2]), math.sin(after[2])

        def footprint_distance(points_xy) -> np.ndarray:
            """Distances of world points to the footprint rectangle (0 inside), metres."""
            d = np.atleast_2d(np.asarray(points_xy, dtype=float)) - after[:2]
            along, across = d[:, 0] * cos_h + d[:, 1] * sin_h, -d[:, 0] * sin_h + d[:, 1] * cos_h
            outside_x = np.maximum(np.maximum(along - front, -rear - along), 0.0)
            outside_y = np.maximum(np.abs(across) - half_width, 0.0)
            return np.hypot(outside_x, outside_y)

        for x0, x1, y0, y1 in c.obstacle_boxes_m:
            inside = (
                (corners[:, 0] > x0 - margin)
                & (corners[:, 0] < x1 + margin)
                & (corners[:, 1] > y0 - margin)
                & (corners[:, 1] < y1 + margin)
            )
            box_corners = ((x0, y0), (x0, y1), (x1, y0), (x1, y1))
            if np.any(inside) or np.any(footprint_distance(box_corners) < margin):
                return True
        for mover in movers:
            x, y, radius = (float(v) for v in mover)
            if footprint_distance((x, y))[0] < radius + margin:
                return True
        return False

    def fix_covariance(self, fix: LandmarkFix) -> np.ndarray:
        """Returns the measurement covariance R of a fix: its fit's covariance plus the floor."""
        return fix.covariance + np.diag(np.square(self.config.fix_floor_sigma))

    def correct(self, found, pan_deg: float, tilt_deg: float) -> LocalisationEstimate:
        """Fuses one image's landmarks; returns the state after it.

        Args:
          found: ``(marker_id, corners_px (4, 2))`` detections (``LandmarkLocator.detect``; other
            ids are ignored).
          pan_deg, tilt_deg: the head's measured angles for the image.
        """
        self.steps_since_fix_ += 1
        if self.pose_ is None:
            patient = self.steps_since_fix_ > self.config.single_init_after_steps
            fix = self.locator.locate(found, pan_deg, tilt_deg, min_markers=1 if patient else None)
            if fix is None:
                return self.estimate()
            return self._initialise(fix, min_markers=1 if patient else None)
        fix = self.locator.locate(found, pan_deg, tilt_deg, prior=self.pose_)
        if fix is None:
            fix = self.locator.locate(found, pan_deg, tilt_deg)
            if fix is None:
                return self.estimate()
        r = self.fix_covariance(fix)
        innovation = fix.pose - self.pose_
        innovation[2] = float(wrap_radians(innovation[2]))
        s = self.covariance_ + r
        nis = float(innovation @ np.linalg.solve(s, innovation))
        if not nis <= self.config.gate_nis:
            self.rejections_ += 1
            self.doubt_ = self.config.doubt_fixes
            # Fading memory: a rejected fix is evidence that the odometry slipped (a collision, a
            # push), so the state is trusted less and a run of consistent fixes gets through.
            self.covariance_ = self.covariance_ * self.config.reject_inflation
            if self.rejections_ >= self.config.reinit_after:
                # Re-initialise from a fit that owes nothing to the (wrong) prediction, or else
                # from this one (a single landmark, its flip resolved by starting from the
                # prediction).
                fresh = self.locator.locate(found, pan_deg, tilt_deg)
                return self._initialise(fix if fresh is None else fresh, nis, min_markers=1)
            return self.estimate(fix=fix, accepted=False, nis=nis)
        self.rejections_ = 0
        self.doubt_ = max(self.doubt_ - 1, 0)
        gain = self.covariance_ @ np.linalg.inv(s)
        self.pose_ = self.pose_ + gain @ innovation
        self.pose_[2] = float(wrap_radians(self.pose_[2]))
        # Joseph form: stays symmetric positive definite.
        i_k = np.eye(3) - gain
        covariance = i_k @ self.covariance_ @ i_k.T + gain @ r @ gain.T
        self.covariance_ = 0.5 * (covariance + covariance.T)
        return self.estimate(fix=fix, accepted=True, nis=nis)

    def _initialise(
        self, fix: LandmarkFix, nis: float = float("nan"), min_markers: int | None = None
    ) -> LocalisationEstimate:
        """(Re)starts the state at ``fix`` if it uses at least ``min_markers`` landmarks (default
        the locator's ``min_markers_global``)."""
        if min_markers is None:
            min_markers = self.locator.config.min_markers_global
        if len(fix.marker_ids) < min_markers:
            return self.estimate(fix=fix, accepted=False, nis=nis)
        self.pose_ = fix.pose.copy()
        self.covariance_ = self.config.init_inflation * self.fix_covariance(fix)
        self.rejections_ = 0
        return self.estimate(fix=fix, accepted=True, nis=nis, reinitialised=True)

    def update(self, wheel_angles, found, pan_deg: float, tilt_deg: float) -> LocalisationEstimate:
        """One control step: :meth:`predict_wheels`, then :meth:`correct`."""
        self.predict_wheels(wheel_angles)
        return self.correct(found, pan_deg, tilt_deg)
