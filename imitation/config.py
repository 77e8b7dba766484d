"""The run's configuration: one typed, nested, frozen tree, written into every run folder.

``RunConfig`` holds everything that decides a run of ``peoplebot reproduce``: the world's timing,
the teacher, the drive, learning, the paper's network and the hierarchical associator by name, the
vision mode, the trials and their success rules, the videos. ``RunConfig.quick()`` is the small
preset. ``to_dict``/``from_dict`` convert to and from plain values (TOML or JSON: ``dump``/``load``);
an unknown key or a value of the wrong type is a ``ValueError`` naming the key.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
import sys

import tomli_w

from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator
from imitation import storage
from imitation.learning import MOTOR_SOURCES
from imitation.limits import BRAKE_LIMITS
from imitation.observers import OVERHEAD_REGISTRATIONS, SELF_LOCALISATIONS, VISION_MODES
from imitation.performance import DRIVE_MODES, SuccessConfig
from imitation.perturbations import PerturbationConfig
from imitation.randomisation import RandomisationConfig
from imitation.speedgain import SUPPORT_SPEEDS
from peoplebot_sim.task import TaskConfig
from peoplebot_sim.teacher import TeacherConfig
from perception.drive import DriveSpeeds

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: The largest run seed: the streams and the camera run draw seeds 2 seed + 1 to 2 seed + 3, which
#: numpy's legacy seeding (dm-control's environments) takes below 2**32.
MAX_SEED = (2**32 - 1 - 3) // 2

_NETWORK_DEFAULTS = Associator().get_params()
_HIERARCHY_DEFAULTS = HierarchicalAssociator().get_params()


# ------------------------------------------------------------------------------------- checks
def _check_positive(name: str, value) -> None:
    if isinstance(value, bool) or not (
        isinstance(value, (int, float)) and math.isfinite(value) and value > 0
    ):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def _check_count(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")


def _check_choice(name: str, value, allowed: tuple) -> None:
    if value not in allowed:
        raise ValueError(f"unknown {name} {value!r}; allowed: {', '.join(allowed)}")


def _check_pixels(section: str, width, height) -> None:
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or not 16 <= value <= 1280:
            raise ValueError(
                f"{section}.{name} must be an integer in [16, 1280] pixels, got {value!r}"
            )
        if value % 2:
            raise ValueError(f"{section}.{name} must be even (video encoding), got {value}")
    if height > 960:
        raise ValueError(f"{section}.height must be at most 960 pixels, got {height}")


def _validated(section: str, validator) -> None:
    """Runs an estimator's own parameter validation, naming the section in its error."""
    try:
        validator()
    except ValueError as error:
        raise ValueError(f"{section}: {error}") from None


@dataclasses.dataclass(frozen=True)
class TaskTiming:
    """The world's clocks: seconds per control step (one directive) and per physics step."""

    control_timestep: float = 0.1
    physics_timestep: float = 0.01

    def __post_init__(self):
        for name in ("control_timestep", "physics_timestep"):
            _check_positive(f"task.{name}", getattr(self, name))
        ratio = self.control_timestep / self.physics_timestep
        if abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(
                f"task.control_timestep {self.control_timestep} must be a multiple of "
                f"task.physics_timestep {self.physics_timestep}"
            )


@dataclasses.dataclass(frozen=True)
class LearningConfig:
    """Learning by watching.

    Attributes:
      train_steps, test_steps: teacher control steps watched for learning and for Table I.
      motor_source: 'teacher' (the teacher's directive is given, as in the paper) or 'vision'
        (inferred from the observed motion).
    """

    train_steps: int = 1_000_000
    test_steps: int = 1_000_000
    motor_source: str = "teacher"

    def __post_init__(self):
        _check_choice("learning.motor_source", self.motor_source, MOTOR_SOURCES)
        for name in ("train_steps", "test_steps"):
            _check_count(f"learning.{name}", getattr(self, name))


@dataclasses.dataclass(frozen=True)
class NetworkConfig:
    """The paper's network (``associator.Associator``) hyper-parameters; the defaults are the
    class's. Its planned step count is ``learning.train_steps`` and its seed the run's."""

    hidden_shape: tuple = _NETWORK_DEFAULTS["hidden_shape"]
    eta: float = _NETWORK_DEFAULTS["eta"]
    epsilon: float = _NETWORK_DEFAULTS["epsilon"]
    motor_change_boost: float = _NETWORK_DEFAULTS["motor_change_boost"]
    envelope_sigma: float = _NETWORK_DEFAULTS["envelope_sigma"]
    envelope_cutoff: float = _NETWORK_DEFAULTS["envelope_cutoff"]
    decay_fraction: float = _NETWORK_DEFAULTS["decay_fraction"]
    sleep_sign: str = _NETWORK_DEFAULTS["sleep_sign"]
    sleeps_per_wake: int = _NETWORK_DEFAULTS["sleeps_per_wake"]
    init_scale: float = _NETWORK_DEFAULTS["init_scale"]
    dtype: str = _NETWORK_DEFAULTS["dtype"]

    def __post_init__(self):
        _validated("network", Associator(**dataclasses.asdict(self)).validate_params)


@dataclasses.dataclass(frozen=True)
class HierarchyConfig:
    """The hierarchical associator (``associator.hierarchy``): whether to train and evaluate it
    beside the paper's network, and its own hyper-parameters (the defaults are the class's)."""

    enabled: bool = True
    motor_gain: float = _HIERARCHY_DEFAULTS["motor_gain"]
    link_floor: float = _HIERARCHY_DEFAULTS["link_floor"]
    word_bias: float = _HIERARCHY_DEFAULTS["word_bias"]
    transition_prior: float = _HIERARCHY_DEFAULTS["transition_prior"]
    word_transition_floor: float = _HIERARCHY_DEFAULTS["word_transition_floor"]
    pose_weight: float = _HIERARCHY_DEFAULTS["pose_weight"]
    pose_width_floor: float = _HIERARCHY_DEFAULTS["pose_width_floor"]
    min_word_samples: int = _HIERARCHY_DEFAULTS["min_word_samples"]
    unit_transition_prior: float = _HIERARCHY_DEFAULTS["unit_transition_prior"]
    pose_evidence: float = _HIERARCHY_DEFAULTS["pose_evidence"]
    perform_temperature: float = _HIERARCHY_DEFAULTS["perform_temperature"]
    perform_readout: str = _HIERARCHY_DEFAULTS["perform_readout"]
    pose_heading_bins: int = _HIERARCHY_DEFAULTS["pose_heading_bins"]
    pose_tail_dof: float = _HIERARCHY_DEFAULTS["pose_tail_dof"]
    transition_winner: str = _HIERARCHY_DEFAULTS["transition_winner"]
    pair_transition_prior: float = _HIERARCHY_DEFAULTS["pair_transition_prior"]

    def hyper_parameters(self) -> dict:
        """Returns the hierarchical associator's own hyper-parameters by name."""
        params = dataclasses.asdict(self)
        params.pop("enabled")
        return params

    def __post_init__(self):
        _validated(
            "hierarchical", HierarchicalAssociator(**self.hyper_parameters()).validate_params
        )


@dataclasses.dataclass(frozen=True)
class VisionConfig:
    """How the student sees the robots.

    Attributes:
      mode: 'truth' (the simulator's poses, the paper's setting), 'overhead' or 'head' (camera
        frames tracked by ``perception``).
      test_steps: steps watched through the camera for recognition (camera modes only).
      width, height: the student's camera frames, pixels.
      self_localisation: how the head mode knows the student's own pose: 'landmarks' (wheel
        odometry fused with the wall landmarks, from an unknown start) or 'odometry' (wheel
        odometry alone from the known start, for comparison).
      overhead_registration: where the overhead mode's camera pose comes from: 'believed' (its
        calibration as measured, with ``perturbations.calibration``'s error) or 'floor_markers'
        (fitted once to the camera's photo of the floor markers, its intrinsics as believed;
        ``observers.register_overhead``).
    """

    mode: str = "truth"
    test_steps: int = 20_000
    width: int = 320
    height: int = 240
    self_localisation: str = "landmarks"
    overhead_registration: str = "believed"

    def __post_init__(self):
        _check_choice("vision.mode", self.mode, VISION_MODES)
        _check_choice("vision.self_localisation", self.self_localisation, SELF_LOCALISATIONS)
        _check_choice(
            "vision.overhead_registration", self.overhead_registration, OVERHEAD_REGISTRATIONS
        )
        _check_count("vision.test_steps", self.test_steps)
        _check_pixels("vision", self.width, self.height)


@dataclasses.dataclass(frozen=True)
class PerformanceConfig:
    """Performing on instruction from random starts.

    Attributes:
      trials: random starts per word and policy.
      trial_seconds: the length of a trial.
      drive: how the student's motor area drives its wheels: 'graded' (the activations set the
        wheel speeds) or 'directive' (the strongest unit's directive at its fixed speeds).
      success: the success rules' numbers.
      brake_ahead: the students are told the acceleration limits of the robot they drive
        (``perturbations.actuation``, as the teacher's reference row is) and ask their network at
        the pose where braking now would bring them to rest (``performance.braking_pose``); no
        change on a robot without limits. On by default since version 0.9.0.
      brake_limits: where the limits the students brake ahead at come from: 'told' (the
        student robot's ``perturbations.actuation``) or 'estimated' (identified from the robot's
        response to the student's own commands during each trial, ``imitation.limits``: a robot
        of unknown limits).
      support_horizon_s, support_weight: the hierarchical student keeps to its demonstrations
        (``performance.SupportLookahead``): each directive's activation is weighed by the
        word's demonstration density where that directive would take the robot in
        ``support_horizon_s``, raised to ``support_weight``; both 0: off. On by default since
        version 0.10.0 (the values chosen on tuning seeds 0-3, docs/results.md).
      support_speeds: the speeds the lookahead follows each directive at: 'nominal' (the
        directives' wheel commands), 'measured' (those scaled by the fractions of them the
        robot is measured to achieve during the trial, ``imitation.speedgain``) or
        'measured_forward' (the forward speed scaled so, the yaw rate nominal: the default
        since version 0.11.0, chosen on tuning seeds 0-3, docs/results.md).
    """

    trials: int = 50
    trial_seconds: float = 60.0
    drive: str = "graded"
    success: SuccessConfig = SuccessConfig()
    brake_ahead: bool = True
    brake_limits: str = "told"
    support_horizon_s: float = 0.5
    support_weight: float = 0.5
    support_speeds: str = "measured_forward"

    def __post_init__(self):
        _check_count("performance.trials", self.trials)
        support = (self.support_horizon_s, self.support_weight)
        for name, value in zip(("support_horizon_s", "support_weight"), support, strict=True):
            if isinstance(value, bool) or not (
                isinstance(value, (int, float)) and math.isfinite(value) and value >= 0
            ):
                raise ValueError(f"performance.{name} must be a number >= 0, got {value!r}")
        if (support[0] > 0) != (support[1] > 0):
            raise ValueError(
                "performance.support_horizon_s and performance.support_weight must both be 0 "
                f"(off) or both above 0, got {support[0]!r} and {support[1]!r}"
            )
        _check_choice("performance.drive", self.drive, DRIVE_MODES)
        _check_choice("performance.brake_limits", self.brake_limits, BRAKE_LIMITS)
        _check_choice("performance.support_speeds", self.support_speeds, SUPPORT_SPEEDS)
        if not isinstance(self.brake_ahead, bool):
            raise ValueError(
                f"performance.brake_ahead must be true or false, got {self.brake_ahead!r}"
            )
        value = self.trial_seconds
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 5):
            raise ValueError(f"performance.trial_seconds must be at least 5 s, got {value!r}")


@dataclasses.dataclass(frozen=True)
class VideoConfig:
    """The videos of the student performing each word: whether to render them, their size, and
    whether to log each episode as a ROS 2 MCAP file too."""

    enabled: bool = True
    width: int = 640
    height: int = 480
    mcap: bool = False

    def __post_init__(self):
        _check_pixels("videos", self.width, self.height)


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """Everything that decides a run of ``peoplebot reproduce``.

    Attributes:
      seed: one seed for everything (streams, networks, trials).
      workers: parallel processes for streams and trials (does not change the results).
      task, teacher, drive: the world's clocks, the teacher's behaviour, the directives' speeds.
      learning, network, hierarchical: learning by watching and the two associators.
      vision, performance, videos: how the student sees, performs and is filmed.
      perturbations: how the student's robot differs from the simulator's best case when it is
        tested (recognition through the camera, performing, videos); the streams and the
        learning never see them (``imitation.perturbations``; all off by default).
      randomisation: domain randomisation of the training stream: the perception faults the
        student learns under (``imitation.randomisation``; on by default since version 0.7.0).
    """

    seed: int = 0
    workers: int = 2
    task: TaskTiming = TaskTiming()
    teacher: TeacherConfig = TeacherConfig()
    drive: DriveSpeeds = DriveSpeeds()
    learning: LearningConfig = LearningConfig()
    network: NetworkConfig = NetworkConfig()
    hierarchical: HierarchyConfig = HierarchyConfig()
    vision: VisionConfig = VisionConfig()
    performance: PerformanceConfig = PerformanceConfig()
    videos: VideoConfig = VideoConfig()
    perturbations: PerturbationConfig = PerturbationConfig()
    randomisation: RandomisationConfig = RandomisationConfig()

    def __post_init__(self):
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int)
            or not 0 <= self.seed <= MAX_SEED
        ):
            raise ValueError(f"seed must be an integer in [0, {MAX_SEED}], got {self.seed!r}")
        _check_count("workers", self.workers)

    @classmethod
    def quick(cls) -> RunConfig:
        """Returns the 'quick' preset: the same stages at a small scale (under a minute on 2 cores
        without videos)."""
        return cls(
            learning=LearningConfig(train_steps=60_000, test_steps=20_000),
            vision=VisionConfig(test_steps=600),
            performance=PerformanceConfig(trials=3, trial_seconds=40.0),
            videos=VideoConfig(width=320, height=240),
        )

    def task_config(self, **fields) -> TaskConfig:
        """Returns the world's configuration for this run (clocks, drive, teacher) with ``fields``
        (cameras, frame size, ...) set."""
        return TaskConfig(
            control_timestep=self.task.control_timestep,
            physics_timestep=self.task.physics_timestep,
            drive=self.drive,
            teacher=self.teacher,
            **fields,
        )

    def world_config(self, **fields) -> TaskConfig:
        """Returns the world the student is tested in: ``task_config(**fields)`` with the
        student robot's actuation and body perturbations and the room's appearance."""
        return dataclasses.replace(
            self.task_config(**fields),
            actuation=self.perturbations.actuation,
            body=self.perturbations.body,
            appearance=self.perturbations.appearance,
        )

    def network_params(self) -> dict:
        """Returns the paper's network's constructor arguments: the [network] section, the planned
        step count and the seed."""
        return {
            **dataclasses.asdict(self.network),
            "n_steps_total": self.learning.train_steps,
            "rng": self.seed,
        }

    def to_dict(self) -> dict:
        """Returns the tree as plain values (tuples as lists), as TOML and JSON hold it."""
        return _plain(dataclasses.asdict(self))

    @classmethod
    def from_dict(cls, data: dict, base: RunConfig | None = None) -> RunConfig:
        """Returns ``base`` (default: the defaults) with the values of ``data`` (a partial tree)."""
        return _merge(base if base is not None else cls(), data, "")

    def replace(self, changes: dict) -> RunConfig:
        """Returns a copy with dotted keys changed, e.g. ``{"learning.train_steps": 3000}``."""
        tree: dict = {}
        for key, value in changes.items():
            node = tree
            *parents, leaf = key.split(".")
            for part in parents:
                node = node.setdefault(part, {})
            node[leaf] = value
        return RunConfig.from_dict(tree, base=self)


def dump(config: RunConfig, path) -> None:
    """Writes the config as TOML (``.toml``) or JSON (anything else)."""
    path = pathlib.Path(path)
    data = config.to_dict()
    if path.suffix == ".toml":
        text = f"{_TOML_HEADER}\n{tomli_w.dumps(data)}"
    else:
        text = json.dumps(data, indent=2)
    storage.write_text(path, text)


_TOML_HEADER = (
    "# A run of `peoplebot reproduce`: every setting it was made with.\n"
    "# `peoplebot reproduce --config config.toml --out FOLDER` makes it again.\n"
)


def load(path, base: RunConfig | None = None) -> RunConfig:
    """Reads a (possibly partial) config from TOML (``.toml``) or JSON; missing keys keep ``base``'s
    values (default: the defaults)."""
    path = pathlib.Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise ValueError(f"cannot read config {path}: {error.strerror or error}") from None
    try:
        data = tomllib.loads(text) if path.suffix == ".toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as error:
        raise ValueError(
            f"config {path} is not valid {path.suffix[1:] or 'JSON'}: {error}"
        ) from None
    if not isinstance(data, dict):
        raise ValueError(f"config {path} must hold a table of settings, got {type(data).__name__}")
    return RunConfig.from_dict(data, base)


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    return value


def _merge(current, data, path: str):
    """Returns ``current`` (a config dataclass) with the values of ``data`` checked against the
    types of ``current``'s own values."""
    if not isinstance(data, dict):
        raise ValueError(f"config key '{path}' must be a table of settings, got {data!r}")
    fields = {f.name for f in dataclasses.fields(current)}
    unknown = sorted(set(data) - fields)
    if unknown:
        where = f"'{path}'" if path else "the top level"
        raise ValueError(
            f"unknown config key '{_join(path, unknown[0])}'; allowed at {where}: "
            f"{', '.join(sorted(fields))}"
        )
    changes = {
        name: _converted(getattr(current, name), value, _join(path, name))
        for name, value in data.items()
    }
    try:
        return dataclasses.replace(current, **changes)
    except ValueError as error:
        message = str(error)
        if path and path not in message:
            # A record that names its own field ("mass_fraction must ...") gets its dotted key.
            named = any(message.startswith(f"{name} ") for name in fields)
            message = f"{path}.{message}" if named else f"{path}: {message}"
        raise ValueError(message) from None


def _converted(current, value, key: str):
    """Returns ``value`` converted to the type of ``current``; ValueError naming ``key`` if it has
    another type."""
    if dataclasses.is_dataclass(current):
        return _merge(current, value, key)

    def wrong(expected: str):
        return ValueError(f"config key '{key}' must be {expected}, got {value!r}")

    if isinstance(current, bool):
        if not isinstance(value, bool):
            raise wrong("true or false")
        return value
    if isinstance(current, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise wrong("an integer")
        return value
    if isinstance(current, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise wrong("a number")
        return float(value)
    if isinstance(current, str):
        if not isinstance(value, str):
            raise wrong("a string")
        return value
    if isinstance(current, tuple):
        if not isinstance(value, (list, tuple)):
            raise wrong("a list")
        if current:
            kinds = {type(v) for v in current}
            example = current[0] if len(kinds) == 1 else None
            if example is not None:
                return tuple(_converted(example, v, f"{key}[{i}]") for i, v in enumerate(value))
        return tuple(value)
    if isinstance(current, dict):
        if not isinstance(value, dict) or set(value) != set(current):
            raise wrong(f"a table with the keys {', '.join(sorted(current))}")
        return {k: _converted(current[k], v, f"{key}.{k}") for k, v in value.items()}
    raise wrong(type(current).__name__)  # pragma: no cover


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name
