"""A constant-velocity Kalman filter per robot, with explicit seen / predicted / lost states.

State ``(x_m, y_m, yaw_rad, vx_mps, vy_mps, yaw_rate_radps)`` in the world frame. Between frames
the pose moves at constant velocity with white acceleration noise; a measurement is a planar pose
``(x_m, y_m, yaw_rad)`` with its covariance (from :mod:`perception.pose`). Yaw innovations are
wrapped to [-pi, pi) and the yaw state is kept wrapped, so headings near +-180 deg filter correctly.

A track is

- ``"seen"``: updated with a measurement at this step;
- ``"predicted"``: not measured at this step but seen within ``max_coast_s``; the pose is the
  prediction;
- ``"lost"``: never seen, or not seen for more than ``max_coast_s``; no pose is reported (None).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from perception.pose import RobotPoseEstimate, wrap_radians

TRACK_STATUSES = ("seen", "predicted", "lost")


@dataclasses.dataclass(frozen=True)
class TrackingConfig:
    """Filter settings.

    Attributes:
      acceleration_std_mps2: white linear acceleration noise, m/s^2.
      yaw_acceleration_std_radps2: white angular acceleration noise, rad/s^2.
      max_coast_s: the longest a track is predicted without a measurement before it is lost,
        seconds.
      measurement_floor_std: smallest measurement standard deviations ``(m, m, rad)`` assumed,
        added in quadrature to a measurement's own covariance.
      gate_mahalanobis: a measurement farther than this (Mahalanobis distance, 3 dof) from the
        prediction is rejected as an outlier; ``inf`` disables gating. A track that keeps rejecting
        is lost after ``max_coast_s`` and then restarts from the next measurement.
      initial_velocity_std: standard deviations of the unknown initial velocity ``(m/s, rad/s)``.
      max_speed_mps, max_yaw_rate_radps: the fastest a robot moves and turns; the filtered
        velocity is clipped to them after every update. The yaw-rate bound below
        ``2 pi / max_coast_s`` keeps a track from locking onto a spin that turns a whole number of
        times between the frames it accepts (wrapped innovations cannot see it).
    """

    acceleration_std_mps2: float = 1.0
    yaw_acceleration_std_radps2: float = 3.0
    max_coast_s: float = 1.0
    measurement_floor_std: tuple[float, float, float] = (0.005, 0.005, np.radians(0.5))
    gate_mahalanobis: float = 6.0
    initial_velocity_std: tuple[float, float] = (0.5, 1.5)
    max_speed_mps: float = 1.5
    max_yaw_rate_radps: float = np.pi

    def __post_init__(self):
        for name in (
            "acceleration_std_mps2",
            "yaw_acceleration_std_radps2",
            "max_coast_s",
            "max_speed_mps",
            "max_yaw_rate_radps",
        ):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        if not self.gate_mahalanobis > 0:
            raise ValueError(
                f"gate_mahalanobis must be > 0 (inf disables), got {self.gate_mahalanobis!r}"
            )
        floor = np.asarray(self.measurement_floor_std, dtype=float)
        if floor.shape != (3,) or not np.all(np.isfinite(floor)) or np.any(floor <= 0):
            raise ValueError(
                f"measurement_floor_std must be 3 positive numbers, "
                f"got {self.measurement_floor_std!r}"
            )
        vel = np.asarray(self.initial_velocity_std, dtype=float)
        if vel.shape != (2,) or not np.all(np.isfinite(vel)) or np.any(vel <= 0):
            raise ValueError(
                f"initial_velocity_std must be 2 positive numbers, "
                f"got {self.initial_velocity_std!r}"
            )


@dataclasses.dataclass(frozen=True, eq=False)
class TrackEstimate:
    """One robot's filtered state at one time.

    Attributes:
      robot: its name.
      time_s: the time of this estimate, seconds.
      status: one of ``TRACK_STATUSES``.
      pose: ``(x_m, y_m, yaw_rad)``, world frame, shape (3,); None when lost.
      velocity: ``(vx_mps, vy_mps, yaw_rate_radps)``, shape (3,); None when lost.
      covariance: state covariance, shape (6, 6); None when lost.
      time_since_seen_s: seconds since the last accepted measurement; inf if never seen.
    """

    robot: str
    time_s: float
    status: str
    pose: np.ndarray | None
    velocity: np.ndarray | None
    covariance: np.ndarray | None
    time_since_seen_s: float


class KalmanTrack:
    """Tracks one robot's planar pose over time.

    Call :meth:`step` once per frame with the frame's time and the measurement, or None when the
    robot was not detected.
    """

    def __init__(self, robot: str, config: TrackingConfig = TrackingConfig()):
        self.robot = robot
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Forgets the state; the track is lost until the next measurement."""
        self.state_ = None
        self.covariance_ = None
        self.time_s_ = None
        self.last_seen_s_ = None

    def _transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Returns ``(F, Q)``: x' = F x, Q = G diag(q) G^T for white acceleration over ``dt``."""
        f = np.eye(6)
        f[0:3, 3:6] = dt * np.eye(3)
        qa = self.config.acceleration_std_mps2**2
        qw = self.config.yaw_acceleration_std_radps2**2
        q = np.zeros((6, 6))
        for i, var in ((0, qa), (1, qa), (2, qw)):
            q[i, i] = var * dt**4 / 4.0
            q[i, i + 3] = q[i + 3, i] = var * dt**3 / 2.0
            q[i + 3, i + 3] = var * dt**2
        return f, q

    def _predict(self, time_s: float) -> None:
        dt = time_s - self.time_s_
        if dt > 0:
            f, q = self._transition(dt)
            self.state_ = f @ self.state_
            self.state_[2] = wrap_radians(self.state_[2])
            self.covariance_ = f @ self.covariance_ @ f.T + q
        self.time_s_ = time_s

    def _measurement_covariance(self, covariance) -> np.ndarray:
        floor = np.diag(np.square(self.config.measurement_floor_std))
        if covariance is None:
            return floor
        covariance = np.asarray(covariance, dtype=float)
        if covariance.shape != (3, 3) or not np.all(np.isfinite(covariance)):
            raise ValueError(
                f"measurement covariance must be a finite 3x3 matrix, got shape {covariance.shape}"
            )
        return covariance + floor

    def step(self, time_s: float, measurement=None, covariance=None) -> TrackEstimate:
        """Advances the track to ``time_s`` and, if given, fuses a measurement; returns the
        estimate.

        Args:
          time_s: the frame's time in seconds; must not go backwards.
          measurement: ``(x_m, y_m, yaw_rad)``, a :class:`RobotPoseEstimate`, or None (not seen).
          covariance: measurement covariance, shape (3, 3); taken from a ``RobotPoseEstimate`` if
            None.
        """
        if not np.isfinite(time_s):
            raise ValueError(f"time_s must be finite, got {time_s!r}")
        if self.time_s_ is not None and time_s < self.time_s_:
            raise ValueError(f"time_s {time_s} goes backwards (last {self.time_s_})")
        if isinstance(measurement, RobotPoseEstimate):
            covariance = measurement.covariance if covariance is None else covariance
            measurement = measurement.as_array()
        if measurement is not None:
            measurement = np.asarray(measurement, dtype=float)
            if measurement.shape != (3,) or not np.all(np.isfinite(measurement)):
                raise ValueError(
                    f"measurement must be 3 finite numbers (x_m, y_m, yaw_rad), got {measurement!r}"
                )

        if self.state_ is not None:
            self._predict(time_s)
            if time_s - self.last_seen_s_ > self.config.max_coast_s:
                self.reset()
        seen = False
        if measurement is not None:
            r = self._measurement_covariance(covariance)
            if self.state_ is None:
                self._initialise(time_s, measurement, r)
                seen = True
            else:
                seen = self._update(measurement, r)
            if seen:
                self.last_seen_s_ = time_s
        self.time_s_ = time_s
        return self.estimate(seen)

    def _initialise(self, time_s: float, measurement: np.ndarray, r: np.ndarray) -> None:
        self.state_ = np.concatenate([measurement, np.zeros(3)])
        self.state_[2] = wrap_radians(self.state_[2])
        v, w = self.config.initial_velocity_std
        self.covariance_ = np.zeros((6, 6))
        self.covariance_[:3, :3] = r
        self.covariance_[3:, 3:] = np.diag([v**2, v**2, w**2])
        self.time_s_ = time_s

    def _update(self, measurement: np.ndarray, r: np.ndarray) -> bool:
        """Fuses one measurement (standard Kalman update, wrapped yaw innovation); False if gated
        out."""
        h = np.zeros((3, 6))
        h[:, :3] = np.eye(3)
        innovation = measurement - self.state_[:3]
        innovation[2] = wrap_radians(innovation[2])
        s = h @ self.covariance_ @ h.T + r
        if np.isfinite(self.config.gate_mahalanobis):
            d2 = float(innovation @ np.linalg.solve(s, innovation))
            if d2 > self.config.gate_mahalanobis**2:
                return False
        gain = self.covariance_ @ h.T @ np.linalg.inv(s)
        self.state_ = self.state_ + gain @ innovation
        self.state_[2] = wrap_radians(self.state_[2])
        self._bound_velocity()
        i_kh = np.eye(6) - gain @ h
        self.covariance_ = i_kh @ self.covariance_ @ i_kh.T + gain @ r @ gain.T  # Joseph form
        return True

    def _bound_velocity(self) -> None:
        """Clips the state's speed and yaw rate to what a robot can do (``max_speed_mps``,
        ``max_yaw_rate_radps``), keeping the direction of travel."""
        speed = float(np.hypot(self.state_[3], self.state_[4]))
        if speed > self.config.max_speed_mps:
            self.state_[3:5] *= self.config.max_speed_mps / speed
        limit = self.config.max_yaw_rate_radps
        self.state_[5] = float(np.clip(self.state_[5], -limit, limit))

    def predict_pose(self, time_s: float) -> np.ndarray | None:
        """Returns the pose ``(x_m, y_m, yaw_rad)`` the track expects at ``time_s`` without changing
        the track, or None if it is lost (or would be lost by then)."""
        if not np.isfinite(time_s):
            raise ValueError(f"time_s must be finite, got {time_s!r}")
        if self.state_ is None or time_s - self.last_seen_s_ > self.config.max_coast_s:
            return None
        dt = max(time_s - self.time_s_, 0.0)
        pose = self.state_[:3] + dt * self.state_[3:]
        pose[2] = wrap_radians(pose[2])
        return pose

    def estimate(self, seen: bool = False) -> TrackEstimate:
        """Returns the current estimate without advancing time."""
        time_s = float(self.time_s_) if self.time_s_ is not None else float("nan")
        if self.state_ is None:
            return TrackEstimate(self.robot, time_s, "lost", None, None, None, float("inf"))
        return TrackEstimate(
            robot=self.robot,
            time_s=time_s,
            status="seen" if seen else "predicted",
            pose=self.state_[:3].copy(),
            velocity=self.state_[3:].copy(),
            covariance=self.covariance_.copy(),
            time_since_seen_s=float(time_s - self.last_seen_s_),
        )
