"""Perturbations toward real robots: the ``[perturbations]`` section of the run configuration.

Each family acts at the layer where it happens on a robot:

- ``perception``: the poses the student's vision reports (noise, latency, frame dropout, burst
  occlusion), applied to ``StudentVision``'s output by ``PerturbedVision``;
- ``image``: the camera's frames before tracking (``perception.degrade``);
- ``appearance``: the room the cameras see: lighting, shadows, surface colours
  (``peoplebot_sim.appearance``, in the physics through ``RunConfig.world_config``);
- ``calibration``: the calibration the student believes (``believed_calibration``); the world, and
  so every rendered frame, stays the simulator's;
- ``proprioception``: the wheel encoder readings the student's odometry reads;
- ``actuation`` and ``body``: the student robot's firmware and body in the physics
  (``peoplebot_sim.hardware``, through ``RunConfig.world_config``).

Every default is 0 (off); a family at 0 is skipped entirely, so a run without perturbations is
bit-identical to one made before they existed. Randomness comes from generators derived from the
run seed and a tag per use (``rng_for``), never from global state. Sources of every number:
``docs/transfer.md``.
"""

from __future__ import annotations

import collections
import copy
import dataclasses
import math

import numpy as np

from imitation.observers import (
    OVERHEAD_REGISTRATIONS,
    Calibration,
    StudentVision,
    register_overhead,
)
from peoplebot_sim.appearance import Appearance
from peoplebot_sim.hardware import Actuation, Body
from perception.degrade import ImageDegradation
from perception.pantilt import HeadMount
from perception.wallframe import wrap_degrees

#: Tags of the random generators derived from the run seed, one per use.
RNG_TAGS = {
    "calibration": 1601,
    "vision": 1602,
    "image": 1603,
    "encoders": 1604,
    "randomisation": 1605,
}


def rng_for(seed, use: str, *keys: int) -> np.random.Generator:
    """Returns the generator of one use (``RNG_TAGS``) of the run ``seed`` (an int or a list of
    ints, e.g. a trial's key), further keyed by ``keys``."""
    seed = list(seed) if isinstance(seed, (list, tuple)) else [seed]
    return np.random.default_rng([*seed, RNG_TAGS[use], *keys])


def _check(record, section: str, fractions: tuple = (), signed: tuple = ()) -> None:
    """Raises ValueError naming ``perturbations.<section>.<field>`` for a value that is not a
    finite number >= 0 (``signed``: any finite number; ``fractions``: in [0, 1))."""
    for field in dataclasses.fields(record):
        value = getattr(record, field.name)
        key = f"perturbations.{section}.{field.name}"
        if isinstance(value, bool) or not (
            isinstance(value, (int, float)) and math.isfinite(value)
        ):
            raise ValueError(f"{key} must be a finite number, got {value!r}")
        if field.name in fractions and not 0 <= value < 1:
            raise ValueError(f"{key} must be a fraction in [0, 1), got {value!r}")
        if field.name not in signed and value < 0:
            raise ValueError(f"{key} must be >= 0 (0: off), got {value!r}")


@dataclasses.dataclass(frozen=True)
class PerceptionFaults:
    """Faults of the poses the student's vision reports (0: off).

    Attributes:
      position_noise_cm: Gaussian noise on x and y, standard deviation in cm (world frame).
      heading_noise_deg: Gaussian noise on the heading, standard deviation in degrees.
      latency_ms: age of each reported pose, milliseconds; fractions of a control step are
        interpolated between the two nearest estimates.
      dropout_fraction: fraction of frames lost (every robot unknown in that frame).
      occlusion_fraction: long-run fraction of time each robot is hidden, in bursts.
      occlusion_burst_s: mean length of one occlusion burst, seconds (with occlusion_fraction).
    """

    position_noise_cm: float = 0.0
    heading_noise_deg: float = 0.0
    latency_ms: float = 0.0
    dropout_fraction: float = 0.0
    occlusion_fraction: float = 0.0
    occlusion_burst_s: float = 1.0

    def __post_init__(self):
        _check(self, "perception", fractions=("dropout_fraction", "occlusion_fraction"))
        if self.occlusion_burst_s <= 0:
            raise ValueError(
                f"perturbations.perception.occlusion_burst_s must be > 0 seconds, got "
                f"{self.occlusion_burst_s!r}"
            )

    @property
    def active(self) -> bool:
        return dataclasses.replace(self, occlusion_burst_s=1.0) != PerceptionFaults()


@dataclasses.dataclass(frozen=True)
class CalibrationError:
    """How the calibration the student believes differs from the world (0: exact). The
    directions of the position and rotation errors are drawn once per run from its seed.

    Attributes:
      focal_fraction: believed focal length / true one - 1 (overhead and head cameras).
      position_cm: distance of the believed camera position from the true one, cm (the overhead
        camera's pose; the head camera's mount on the robot).
      rotation_deg: angle of the believed camera orientation from the true one, degrees (the
        overhead camera about a random axis; the head as pan and tilt zero offsets).
    """

    focal_fraction: float = 0.0
    position_cm: float = 0.0
    rotation_deg: float = 0.0

    def __post_init__(self):
        _check(self, "calibration", signed=("focal_fraction",))
        if not self.focal_fraction > -1:
            raise ValueError(
                "perturbations.calibration.focal_fraction must be greater than -1, got "
                f"{self.focal_fraction!r}"
            )

    @property
    def active(self) -> bool:
        return self != CalibrationError()


@dataclasses.dataclass(frozen=True)
class ProprioceptionFaults:
    """Faults of the student's own sensors (0: off).

    Attributes:
      wheel_encoder_noise_deg: Gaussian noise on each wheel angle reading, degrees.
    """

    wheel_encoder_noise_deg: float = 0.0

    def __post_init__(self):
        _check(self, "proprioception")

    @property
    def active(self) -> bool:
        return self != ProprioceptionFaults()


@dataclasses.dataclass(frozen=True)
class PerturbationConfig:
    """Every perturbation of a run, by family (all off by default); see the module's docstring."""

    perception: PerceptionFaults = PerceptionFaults()
    image: ImageDegradation = ImageDegradation()
    appearance: Appearance = Appearance()
    calibration: CalibrationError = CalibrationError()
    proprioception: ProprioceptionFaults = ProprioceptionFaults()
    actuation: Actuation = Actuation()
    body: Body = Body()

    @property
    def active(self) -> bool:
        """Returns whether any perturbation is on."""
        return self != PerturbationConfig()

    @property
    def vision_active(self) -> bool:
        """Returns whether any perturbation acts on what the student's vision reports."""
        return self.perception.active or self.image.active or self.proprioception.active


# ----------------------------------------------------------------------------- presets and grids
#: Named level sets; every number's source is in docs/transfer.md.
PRESETS = {
    "realistic": PerturbationConfig(
        perception=PerceptionFaults(position_noise_cm=0.5, heading_noise_deg=1.0, latency_ms=50.0),
        image=ImageDegradation(noise_sigma=3.0, blur_px=3.0, jpeg_quality=90),
        calibration=CalibrationError(focal_fraction=0.02, position_cm=1.0, rotation_deg=1.0),
        proprioception=ProprioceptionFaults(wheel_encoder_noise_deg=0.1),
        actuation=Actuation(command_latency_ms=50.0, linear_accel_mps2=0.3, yaw_accel_degps2=100.0),
        body=Body(caster_friction=0.05),
    ),
}

#: The ARIA firmware's default acceleration limits as one named level of the 'acceleration'
#: family (docs/transfer.md).
ARIA_ACCELERATION = {"actuation.linear_accel_mps2": 0.3, "actuation.yaw_accel_degps2": 100.0}


def _levels(*keys_and_values) -> tuple:
    """Returns a family's levels: for each value, the dotted keys (under ``perturbations``) set."""
    *keys, values = keys_and_values
    return tuple({key: value for key in keys} for value in values)


#: Each family's default grid of levels, from 0 (off) past the anchors until the student fails;
#: a level is a dict of dotted keys under ``perturbations``. Sources: docs/transfer.md.
FAMILIES = {
    "pose_noise": _levels(
        "perception.position_noise_cm", "perception.heading_noise_deg", (0, 0.5, 1, 2, 5, 10)
    ),
    "latency": _levels("perception.latency_ms", (0, 50, 100, 200, 400, 800)),
    "dropout": _levels("perception.dropout_fraction", (0, 0.1, 0.25, 0.5, 0.75, 0.9)),
    "occlusion": _levels("perception.occlusion_fraction", (0, 0.05, 0.1, 0.2, 0.4)),
    "pixel_noise": _levels("image.noise_sigma", (0, 2, 5, 10, 20, 40)),
    "motion_blur": _levels("image.blur_px", (0, 3, 5, 9, 15, 25)),
    "jpeg": _levels("image.jpeg_quality", (0, 90, 70, 50, 30, 10)),
    "exposure": _levels("image.exposure_stops", (0, -0.5, -1, -2, -3)),
    "lens_distortion": _levels("image.distortion_k1", (0, -0.02, -0.05, -0.1, -0.2)),
    "lighting": _levels("appearance.light_fraction", (0, -0.1, -0.3, -0.5, -0.7, -0.85)),
    "shadows": (
        {},
        {"appearance.shadows": True},
        {"appearance.shadows": True, "appearance.light_tilt_deg": 30.0},
        {"appearance.shadows": True, "appearance.light_tilt_deg": 60.0},
    ),
    "surface_colour": _levels("appearance.surface_tint_fraction", (0, 0.1, 0.25, 0.5, 0.75, 1.0)),
    "focal_error": _levels("calibration.focal_fraction", (0, 0.01, 0.02, 0.05, 0.1, 0.2)),
    "mount_position": _levels("calibration.position_cm", (0, 0.5, 1, 2, 5, 10)),
    "mount_rotation": _levels("calibration.rotation_deg", (0, 1, 2, 5, 10, 20)),
    "encoder_noise": _levels("proprioception.wheel_encoder_noise_deg", (0, 0.1, 0.5, 1, 2, 5)),
    "command_latency": _levels("actuation.command_latency_ms", (0, 50, 100, 200, 400)),
    "acceleration": (
        {},
        {"actuation.linear_accel_mps2": 1.0, "actuation.yaw_accel_degps2": 300.0},
        ARIA_ACCELERATION,
        {"actuation.linear_accel_mps2": 0.15, "actuation.yaw_accel_degps2": 50.0},
        {"actuation.linear_accel_mps2": 0.075, "actuation.yaw_accel_degps2": 25.0},
    ),
    "wheel_trim": tuple(
        {"body.left_wheel_radius_fraction": t / 2, "body.right_wheel_radius_fraction": -t / 2}
        for t in (0, 0.01, 0.02, 0.05, 0.1, 0.2)
    ),
    "mass": _levels("body.mass_fraction", (0, 0.02, 0.05, 0.1, 0.2, 0.5)),
    "floor_friction": _levels("body.floor_friction_fraction", (0, -0.1, -0.3, -0.5, -0.7, -0.9)),
    "caster_friction": _levels("body.caster_friction", (0, 0.02, 0.05, 0.1, 0.2, 0.4)),
}


#: Per family, the two levels besides 0 that a default ``peoplebot transfer`` measures: the level
#: nearest its anchor (or the ``realistic`` preset) and one past it (docs/transfer.md).
ANCHOR_LEVELS = {
    "pose_noise": (1, 4),
    "latency": (1, 3),
    "dropout": (1, 3),
    "occlusion": (1, 3),
    "pixel_noise": (1, 3),
    "motion_blur": (1, 3),
    "jpeg": (1, 3),
    "exposure": (1, 3),
    "lens_distortion": (1, 3),
    "lighting": (1, 3),
    "shadows": (1, 3),
    "surface_colour": (1, 3),
    "focal_error": (2, 4),
    "mount_position": (2, 4),
    "mount_rotation": (1, 3),
    "encoder_noise": (1, 3),
    "command_latency": (1, 3),
    "acceleration": (2, 3),
    "wheel_trim": (2, 4),
    "mass": (1, 4),
    "floor_friction": (1, 3),
    "caster_friction": (2, 4),
}

#: The vision modes in which each section of the perturbations acts: the camera's frames, the
#: room's appearance and the calibration only where a camera is watched; the wheel encoders only
#: where odometry gives the student's own pose (the head mode).
SECTION_MODES = {
    "perception": ("truth", "overhead", "head"),
    "image": ("overhead", "head"),
    "appearance": ("overhead", "head"),
    "calibration": ("overhead", "head"),
    "proprioception": ("head",),
    "actuation": ("truth", "overhead", "head"),
    "body": ("truth", "overhead", "head"),
}


def acts_in(family: str, mode: str) -> bool:
    """Returns whether ``family``'s levels change anything in the vision ``mode``."""
    sections = {key.split(".", 1)[0] for level in FAMILIES[family] for key in level}
    return any(mode in SECTION_MODES[section] for section in sections)


def preset(name: str) -> PerturbationConfig:
    """Returns the named level set; ValueError listing the names for an unknown one."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; allowed: {', '.join(PRESETS)}")
    return PRESETS[name]


# ----------------------------------------------------------------------------- calibration
def believed_calibration(
    calibration: Calibration, error: CalibrationError, rng: np.random.Generator
) -> Calibration:
    """Returns the calibration the student believes: ``calibration`` (the world's) with
    ``error`` (focal length scaled; the overhead camera moved by ``position_cm`` and turned by
    ``rotation_deg`` in directions drawn from ``rng``; the head's mount moved likewise and its pan
    and tilt zeros offset). Returns ``calibration`` itself when ``error`` is off."""
    if not error.active:
        return calibration
    believed = copy.copy(calibration)
    direction = _unit(rng.normal(size=3))
    axis = _unit(rng.normal(size=3))
    split = float(rng.uniform(0.0, 2.0 * math.pi))
    offset_m = direction * error.position_cm / 100.0
    turn = _rotation(axis, math.radians(error.rotation_deg))
    overhead = _scaled_focal(calibration.overhead, error.focal_fraction)
    believed.overhead = overhead.with_pose(
        turn @ np.asarray(overhead.rotation_world_from_camera),
        np.asarray(overhead.position_world) + offset_m,
    )
    believed.head_intrinsics = _scaled_focal(calibration.head_intrinsics, error.focal_fraction)
    mount = np.asarray(calibration.head_mount.position_m, dtype=float) + offset_m
    believed.head_mount = HeadMount(tuple(float(v) for v in mount))
    pan, tilt = calibration.head_angle_offsets_deg
    believed.head_angle_offsets_deg = (
        pan + error.rotation_deg * math.cos(split),
        tilt + error.rotation_deg * math.sin(split),
    )
    return believed


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Returns the rotation matrix of ``angle_rad`` about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * k + (1 - math.cos(angle_rad)) * k @ k


def _scaled_focal(camera, fraction: float):
    if not fraction:
        return camera
    return camera.with_focal_scale(1.0 + fraction)


# ----------------------------------------------------------------------------- poses
class PoseCorruptor:
    """Applies ``PerceptionFaults`` to a stream of pose reports, one per control step: at capture,
    noise, frame dropout and per-robot burst occlusion; then the latency (dm_control's
    observables corrupt before they buffer and delay).

    Args:
      faults: the levels.
      dt: seconds per report (the control step).
      rng: draws the noise, the dropped frames and the occlusions.
      perceived: the robots whose poses come from perception (others pass unchanged but delayed).
    """

    def __init__(self, faults: PerceptionFaults, dt: float, rng, perceived=("teacher", "student")):
        self.faults, self.dt, self.rng = faults, float(dt), rng
        self.perceived = tuple(perceived)
        delay = faults.latency_ms / 1000.0 / self.dt
        self._whole = int(math.floor(delay + 1e-9))
        self._fraction = delay - self._whole if delay - self._whole > 1e-9 else 0.0
        burst_steps = max(faults.occlusion_burst_s / self.dt, 1.0)
        f = faults.occlusion_fraction
        self._p_end = 1.0 / burst_steps
        self._p_start = f * self._p_end / (1.0 - f) if f else 0.0
        self.reset()

    def reset(self) -> None:
        """Starts afresh: nothing captured yet, nobody occluded."""
        self._history = collections.deque(maxlen=self._whole + 2)
        self._occluded: dict = {}
        self.dropped = 0
        self.steps = 0

    def step(self, poses: dict) -> dict:
        """Returns the reports the student receives now for this step's ``poses`` (robot -> world
        ``(x_m, y_m, yaw_rad)`` or None)."""
        f = self.faults
        self.steps += 1
        captured = {}
        dropped = f.dropout_fraction > 0 and self.rng.random() < f.dropout_fraction
        self.dropped += int(dropped)
        for robot, pose in poses.items():
            if robot not in self.perceived:
                captured[robot] = pose
                continue
            if f.occlusion_fraction:
                was = self._occluded.get(robot, False)
                draw = self.rng.random()
                self._occluded[robot] = draw >= self._p_end if was else draw < self._p_start
            if pose is None or dropped or self._occluded.get(robot, False):
                captured[robot] = None
                continue
            pose = np.array(pose, dtype=float)
            if f.position_noise_cm:
                pose[:2] += self.rng.normal(0.0, f.position_noise_cm / 100.0, 2)
            if f.heading_noise_deg:
                pose[2] = _wrap_rad(
                    pose[2] + math.radians(self.rng.normal(0.0, f.heading_noise_deg))
                )
            captured[robot] = pose
        self._history.append(captured)
        return {robot: self._delayed(robot) for robot in poses}

    def _delayed(self, robot: str):
        n = len(self._history)
        if n <= self._whole:
            return None
        newer = self._history[n - 1 - self._whole].get(robot)
        if not self._fraction:
            return newer
        if n <= self._whole + 1:
            return None
        older = self._history[n - 2 - self._whole].get(robot)
        if newer is None or older is None:
            return None
        a = self._fraction
        out = (1 - a) * np.asarray(newer, float) + a * np.asarray(older, float)
        out[2] = _wrap_rad(newer[2] + a * _wrap_rad(older[2] - newer[2]))
        return out


def _wrap_rad(angle: float) -> float:
    return math.radians(float(wrap_degrees(math.degrees(angle))))


# ----------------------------------------------------------------------------- the vision
class PerturbedVision:
    """``StudentVision`` on a perturbed robot: the camera frames are degraded before tracking,
    the wheel encoder readings get noise, and the reported poses pass through ``PoseCorruptor``.
    Other attributes are the wrapped vision's.

    The poses that come from perception get the perception faults: both robots in the 'truth'
    mode (a stand-in for a perception system) and the 'overhead' mode, the teacher in the 'head'
    mode (the student's own pose there is its odometry).
    """

    def __init__(self, vision: StudentVision, perturbations: PerturbationConfig, dt: float, seed):
        self.vision, self.perturbations = vision, perturbations
        perceived = ("teacher",) if vision.mode == "head" else ("teacher", "student")
        self._poses = None
        if perturbations.perception.active:
            self._poses = PoseCorruptor(
                perturbations.perception, dt, rng_for(seed, "vision"), perceived
            )
        self._image_rng = rng_for(seed, "image")
        self._encoder_rng = rng_for(seed, "encoders")

    def __getattr__(self, name):
        return getattr(self.vision, name)

    def _wheels(self, angles):
        sigma = self.perturbations.proprioception.wheel_encoder_noise_deg
        if angles is None or not sigma:
            return angles
        return np.asarray(angles, float) + np.radians(self._encoder_rng.normal(0.0, sigma, 2))

    def reset(self, start_pose=None, wheel_angles=None) -> None:
        """Starts afresh (see ``StudentVision.reset``)."""
        self.vision.reset(start_pose, self._wheels(wheel_angles))
        if self._poses is not None:
            self._poses.reset()

    def update(self, observation: dict, time_s: float, dt: float) -> dict:
        """Returns what the perturbed student believes (see ``StudentVision.update``)."""
        seen = dict(observation)
        if self.perturbations.image.active:
            for name in ("overhead_camera", "head_camera"):
                if name in seen:
                    seen[name] = self.perturbations.image.apply(seen[name], self._image_rng)
        if "student_wheel_angles" in seen:
            seen["student_wheel_angles"] = self._wheels(seen["student_wheel_angles"])
        out = self.vision.update(seen, time_s, dt)
        return out if self._poses is None else self._poses.step(out)


def student_vision(
    mode: str,
    calibration,
    perturbations: PerturbationConfig,
    dt: float,
    seed,
    watch_teacher: bool = True,
    self_localisation: str = "landmarks",
    overhead_registration: str = "believed",
):
    """Returns the student's vision in ``mode`` (the head mode's own pose by
    ``self_localisation``) with the calibration it believes (the overhead camera registered from
    the floor markers with ``overhead_registration`` 'floor_markers') and the vision
    perturbations; the plain ``StudentVision`` on the given calibration when they are off."""
    if overhead_registration not in OVERHEAD_REGISTRATIONS:
        raise ValueError(
            f"unknown overhead registration {overhead_registration!r}; allowed: "
            f"{', '.join(OVERHEAD_REGISTRATIONS)}"
        )
    if calibration is not None:
        calibration = believed_calibration(
            calibration, perturbations.calibration, rng_for(seed_of(seed), "calibration")
        )
        if mode == "overhead" and overhead_registration == "floor_markers":
            calibration = register_overhead(calibration)
    vision = StudentVision(
        mode, calibration, watch_teacher=watch_teacher, self_localisation=self_localisation
    )
    if not perturbations.vision_active:
        return vision
    return PerturbedVision(vision, perturbations, dt, seed)


def teacher_vision(perturbations: PerturbationConfig, dt: float, seed):
    """Returns the teacher reference's pose source under the perception faults (its true pose
    through ``PoseCorruptor``), or None when they are off (it reads the true pose)."""
    if not perturbations.perception.active:
        return None
    only = PerturbationConfig(perception=perturbations.perception)
    return PerturbedVision(StudentVision("truth", None, watch_teacher=False), only, dt, seed)


def seed_of(seed) -> int:
    """Returns the run seed of a seed key (an int, or a list whose first element it is): the
    calibration belongs to the robot, the same in every trial of a run."""
    return int(seed[0]) if isinstance(seed, (list, tuple)) else int(seed)
