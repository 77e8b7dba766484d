"""Performance on command (the paper's Fig. 4): the student is told a word and drives itself.

At every control step the student observes its own pose (through the chosen vision mode), turns it
into the wall frame, and the associator's motor area (reconstructed through W_td with the motor input
omitted) gives the directive that drives its wheels. The teacher's controller, performing the same
word on the same robot from the same starts, is the reference.

Success, per trial (all in ``SuccessConfig``):

- ``go``: from a random free pose anywhere, for 60 s: never touches a wall or the table, visits at
  least two wall areas, and keeps moving (drives a path of at least 0.2 m in every 10 s window).
- ``pick`` (table wall): from a random pose in the table's wall area, 1.0-1.6 m from the wall, at most
  0.8 m either side of its middle, facing it within 45 deg (starts in the box's far corners, which
  lie in a side wall's area, are drawn again): within 60 s reaches the teacher's
  docked pose within 15 cm and 20 deg and **settles** there: it stays inside that tolerance for
  3 s on end, and touches nothing during the trial (passing through the dock does not count).
- ``pick`` (other walls): the same start relative to one of the three other walls; success is the
  equivalent docked pose at that wall (the wall frame cannot tell walls apart, so the student docks
  where it is).
- ``lift``: from the docked pose: within 60 s the robot's centre is at least 0.5 m farther from the
  table than when docked and the robot faces the arena's centre within 45 deg, without touching
  anything.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from associator import encoding
from associator.network import Associator
from imitation.limits import AccelerationLimitEstimator
from imitation.observers import StudentVision, pose_or_nan
from imitation.speedgain import SpeedGainEstimator
from peoplebot_sim.entities import BASE_RADIUS_M
from peoplebot_sim.hardware import Actuation, braking_travel
from peoplebot_sim.teacher import Teacher, TeacherConfig
from perception.drive import DriveSpeeds
from perception.wallframe import ArenaGeometry, WallPose, wall_to_world, world_to_wall, wrap_degrees

ROWS = ("go", "pick", "pick_other_wall", "lift")
ROW_WORD = {"go": "go", "pick": "pick", "pick_other_wall": "pick", "lift": "lift"}
#: The policies evaluated: the paper's network, the teacher (the reference), the hierarchical one.
POLICIES = ("student", "teacher", "student_hierarchical")
#: How the student's motor area drives its wheels: the graded activations or the winning directive.
DRIVE_MODES = ("graded", "directive")
#: The paper's Fig. 4 start: top middle of the arena, facing up (world x, y metres, yaw radians).
FIG4_START = (0.0, 0.6, math.pi / 2)


@dataclasses.dataclass(frozen=True)
class SuccessConfig:
    """The success definitions' numbers (metres, degrees, seconds); ``dock_settle_s``: how long a
    'pick' must stay inside the docking tolerance on end (0: reaching it once is enough)."""

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not (
                isinstance(value, (int, float)) and math.isfinite(value) and value >= 0
            ):
                raise ValueError(
                    f"performance.success.{field.name} must be a finite number >= 0, got {value!r}"
                )

    go_min_wall_areas: int = 2
    go_window_s: float = 10.0
    go_min_window_travel_m: float = 0.2
    dock_position_tol_m: float = 0.15
    dock_heading_tol_deg: float = 20.0
    dock_settle_s: float = 3.0
    lift_min_gap_m: float = 0.5
    lift_heading_tol_deg: float = 45.0


class StudentAgent:
    """The student as a policy for the dm-control environment: it observes (through its vision
    mode), encodes its own pose in the wall frame, and drives its wheels from the associator's motor
    area (reconstructed through W_td with the motor input omitted) for the instructed word.

    Args:
      model: a fitted ``Associator`` or ``HierarchicalAssociator``.
      word: the instruction.
      vision: how the student sees (``StudentVision`` with ``watch_teacher=False``).
      encoder: the vision encoder the model was trained with.
      action_spec: the environment's action spec (actions are clipped into it).
      drive: wheel speeds of the directives.
      graded: drive with the graded motor activations instead of the winning directive.
      brake_ahead: the acceleration limits of the robot it drives, if it is told them: it then
        asks the network at the pose where it would come to rest braking now from its measured
        speeds (``braking_pose``), as the teacher brakes ahead; None: at its pose.
      limit_estimator: not told them, it brakes ahead at the limits this estimator identifies
        from its commands and measured speeds (``imitation.limits``; ``brake_ahead`` then None).
      support: keep to the demonstrations (``SupportLookahead``; a model with
        ``pose_log_density``, the hierarchical one); None: drive with the read-out as it is.
      speed_gains: the lookahead follows each directive at the speeds this estimator finds the
        robot achieves (``imitation.speedgain``); None: at the nominal wheel commands.
    """

    def __init__(
        self,
        model: Associator,
        word: str,
        vision: StudentVision,
        encoder: encoding.VisionEncoder,
        action_spec,
        drive: DriveSpeeds = DriveSpeeds(),
        graded: bool = False,
        arena: ArenaGeometry = ArenaGeometry(),
        brake_ahead: Actuation | None = None,
        limit_estimator: AccelerationLimitEstimator | None = None,
        support: SupportLookahead | None = None,
        speed_gains: SpeedGainEstimator | None = None,
    ):
        if speed_gains is not None and support is None:
            raise ValueError("measured speeds are for the support lookahead, which is off")
        if support is not None and not hasattr(model, "pose_log_density"):
            raise ValueError(
                f"support lookahead needs a model with a demonstration density, "
                f"got {type(model).__name__}"
            )
        if brake_ahead is not None and limit_estimator is not None:
            raise ValueError(
                "a student is told its limits (brake_ahead) or estimates them, not both"
            )
        if word not in model.vocabulary:
            raise ValueError(
                f"unknown word {word!r}; the network knows: {', '.join(model.vocabulary)}"
            )
        self.model, self.word, self.vision, self.encoder = model, word, vision, encoder
        self.spec, self.drive, self.graded, self.arena = action_spec, drive, graded, arena
        self.brake_ahead, self.limit_estimator = brake_ahead, limit_estimator
        self.support, self.speed_gains = support, speed_gains
        self.reset()

    def reset(self, timestep=None, start_pose=None) -> None:
        """Starts a trial: the head mode's odometry starts from the known ``start_pose``."""
        wheels = None if timestep is None else timestep.observation["student_wheel_angles"]
        self.vision.reset(start_pose, wheels)
        self.directive, self.motor, self.own_pose = None, np.zeros(4), None
        self.own_covariance = None
        self.time_s = 0.0
        self.query_pose, self._last_pose, self._last_command = None, None, (0.0, 0.0)
        for estimator in (self.limit_estimator, self.speed_gains):
            if estimator is not None:
                estimator.reset()

    def command(self, own_pose, dt: float = 0.1) -> tuple[float, float]:
        """Returns ``(linear m/s, yaw rate rad/s)`` for an own-pose estimate (None: stand still);
        ``dt``: seconds since the previous estimate (for the measured speeds)."""
        last, self._last_pose = self._last_pose, own_pose
        limits = self.brake_ahead
        known = last is not None and own_pose is not None
        speeds = measured_speeds(last, own_pose, dt) if known else None
        if self.limit_estimator is not None:
            self.limit_estimator.update(self._last_command, speeds)
            limits = self.limit_estimator.limits
        if self.speed_gains is not None:
            self.speed_gains.update(self._last_command, speeds)
        self._last_command = self._command(own_pose, last, dt, limits)
        return self._last_command

    def _command(self, own_pose, last, dt: float, limits: Actuation | None):
        if own_pose is None:
            self.directive, self.motor, self.query_pose = None, np.zeros(4), None
            return 0.0, 0.0
        self.query_pose = own_pose
        if limits is not None and last is not None:
            self.query_pose = braking_pose(last, own_pose, dt, limits)
        wall = world_to_wall(*self.query_pose, self.arena)
        vision = self.encoder.encode(wall.x_m, wall.y_m, wall.phi_deg, clip=True)
        result = self.model.perform(vision, self.word)
        self.directive, self.motor = result.directive, result.motor
        if self.support is not None:
            self.motor = self.support.reweigh(
                self.model,
                self.word,
                self.motor,
                self.query_pose,
                self.drive,
                self.encoder,
                self.arena,
                gains=(1.0, 1.0) if self.speed_gains is None else self.speed_gains.gains,
            )
            self.directive = encoding.DIRECTIVES[int(np.argmax(self.motor))]
        if self.graded:
            return self.drive.graded_command(self.motor)
        return self.drive.command(self.directive)

    def step(self, timestep, dt: float = 0.1) -> np.ndarray:
        """Returns the action for one environment time step."""
        self.own_pose = self.vision.update(timestep.observation, self.time_s, dt)["student"]
        # The landmark filter's covariance of it ((3, 3), m^2 and rad^2; None in other modes).
        localisation = getattr(self.vision, "localisation", None)
        self.own_covariance = None if localisation is None else localisation.covariance
        self.time_s += dt
        return make_action(self.spec, self.command(self.own_pose, dt), self.vision.head_command)


@dataclasses.dataclass(frozen=True)
class SupportLookahead:
    """Keeps a student on its demonstrations: each directive's motor activation is multiplied by
    ``q(pose after horizon_s of that directive) ** weight`` (renormalised to the same sum), ``q``
    the word's demonstration density (``HierarchicalAssociator.pose_log_density``), so that where
    the read-out extrapolates beyond what the teacher showed (past the dock, say) the directives
    that lead back towards the demonstrations gain.

    Attributes:
      horizon_s: how far ahead each directive is followed at its wheel command, seconds (> 0).
      weight: the exponent on the density (> 0).
    """

    horizon_s: float
    weight: float

    def __post_init__(self):
        for name in ("horizon_s", "weight"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (
                isinstance(value, (int, float)) and math.isfinite(value) and value > 0
            ):
                raise ValueError(f"support lookahead {name} must be a number > 0, got {value!r}")

    def outcomes(self, pose, drive: DriveSpeeds, gains=(1.0, 1.0)) -> np.ndarray:
        """Returns (4, 3): where each directive (``DIRECTIVES`` order) takes a robot at ``pose``
        ``(x, y, yaw)`` (world metres and radians) in ``horizon_s`` at its wheel command scaled
        by ``gains`` (the fractions of the forward speed and the yaw rate the robot achieves)."""
        x, y, yaw = (float(v) for v in pose)
        out = np.empty((len(encoding.DIRECTIVES), 3))
        for i, directive in enumerate(encoding.DIRECTIVES):
            linear, turn = drive.command(directive)
            linear, turn = linear * gains[0], turn * gains[1]
            travel = linear * self.horizon_s
            out[i] = (
                x + travel * math.cos(yaw),
                y + travel * math.sin(yaw),
                yaw + turn * self.horizon_s,
            )
        return out

    def reweigh(
        self, model, word, motor, pose, drive, encoder, arena, gains=(1.0, 1.0)
    ) -> np.ndarray:
        """Returns the motor activations (4,) reweighted by the density at each directive's
        outcome (``outcomes``); unchanged where the word has no demonstrations near any outcome."""
        codes = []
        for x, y, yaw in self.outcomes(pose, drive, gains):
            wall = world_to_wall(x, y, yaw, arena)
            codes.append(encoder.encode(wall.x_m, wall.y_m, wall.phi_deg, clip=True))
        log_density = model.pose_log_density(np.stack(codes), word)
        if not np.all(np.isfinite(log_density)):
            return np.asarray(motor, float)
        motor = np.asarray(motor, float)
        weighted = motor * np.exp(self.weight * (log_density - log_density.max()))
        total = weighted.sum()
        return weighted * (motor.sum() / total) if total > 0 else motor


def braking_pose(previous, pose, dt: float, limits: Actuation) -> tuple[float, float, float]:
    """Returns where a robot at ``pose`` comes to rest if it brakes now at the acceleration limits
    ``limits`` from the speeds measured between ``previous`` and ``pose`` (each ``(x, y, yaw)``,
    world metres and radians, ``dt`` seconds apart): its heading turned on by the yaw rate's
    braking travel and its position moved by the forward speed's along the mean heading."""
    x, y, yaw = (float(v) for v in pose)
    speed_mps, yaw_rate_degps = measured_speeds(previous, pose, dt)
    turn = math.radians(braking_travel(yaw_rate_degps, limits.yaw_accel_degps2))
    travel = braking_travel(speed_mps, limits.linear_accel_mps2)
    heading = yaw + 0.5 * turn
    return x + travel * math.cos(heading), y + travel * math.sin(heading), yaw + turn


def measured_speeds(previous, pose, dt: float) -> tuple[float, float]:
    """Returns ``(forward speed m/s, yaw rate deg/s)`` between two poses ``(x, y, yaw)`` (world
    metres and radians) ``dt`` seconds apart, the speed along the later heading."""
    x0, y0, yaw0 = (float(v) for v in previous)
    x, y, yaw = (float(v) for v in pose)
    speed_mps = ((x - x0) * math.cos(yaw) + (y - y0) * math.sin(yaw)) / dt
    return speed_mps, wrap_degrees(math.degrees(yaw - yaw0)) / dt


def make_action(spec, drive_command, head_command=(0.0, 0.0)) -> np.ndarray:
    """Returns an action within ``spec``: wheels ``(linear, turn)``, gripper at rest, head angles."""
    action = np.zeros(spec.shape)
    action[0], action[1] = drive_command
    action[4], action[5] = head_command
    return np.clip(action, spec.minimum, spec.maximum)


class TeacherAgent:
    """The teacher's controller performing one word on the student's robot: the reference row. It
    reads the true pose (the teacher is a scripted demonstrator, not a learner) and performs
    undisturbed (``TeacherConfig.undisturbed``); once its behaviour is done it stands still
    (directive None), as a real robot would. ``vision``: where its pose comes from instead (a
    'truth'-mode vision under perception faults); it stands still while its pose is unknown."""

    def __init__(
        self,
        word: str,
        action_spec,
        drive: DriveSpeeds = DriveSpeeds(),
        arena: ArenaGeometry = ArenaGeometry(),
        rng=None,
        teacher_config: TeacherConfig = TeacherConfig(),
        vision=None,
    ):
        self.vision = vision
        self.word, self.spec, self.drive, self.arena, self._rng = (
            word,
            action_spec,
            drive,
            arena,
            rng,
        )
        self.teacher_config = teacher_config.undisturbed()
        self.reset()

    def reset(self, timestep=None, start_pose=None) -> None:
        self.controller = Teacher(self.teacher_config, arena=self.arena, rng=self._rng)
        self.controller.begin(self.word, loop=False)
        self.directive, self.motor = None, None
        if self.vision is not None:
            self.vision.reset()
            self.time_s = 0.0

    def step(self, timestep, dt: float = 0.1) -> np.ndarray:
        pose = timestep.observation["student_pose"]
        if self.vision is not None:
            pose = self.vision.update(timestep.observation, self.time_s, dt)["student"]
            self.time_s += dt
            if pose is None:
                self.directive = None
                return make_action(self.spec, (0.0, 0.0))
        directive = self.controller.step(pose, None, dt)
        if self.controller.finished:
            self.directive = None
            return make_action(self.spec, (0.0, 0.0))
        self.directive = directive
        return make_action(self.spec, self.drive.command(directive))

    @property
    def finished(self) -> bool:
        return self.controller.finished


def sample_start(
    row: str,
    rng: np.random.Generator,
    arena: ArenaGeometry = ArenaGeometry(),
    teacher: TeacherConfig = TeacherConfig(),
) -> tuple[tuple, str]:
    """Returns a random start ``(x, y, yaw)`` for a row and the wall its success refers to."""
    if row == "go":
        h = arena.half_side_m - 0.6
        while True:
            x, y = rng.uniform(-h, h, size=2)
            if arena.clear_of_table(x, y, 0.6):
                return (float(x), float(y), float(rng.uniform(-math.pi, math.pi))), "top"
    if row in ("pick", "pick_other_wall"):
        wall = "top" if row == "pick" else str(rng.choice(["right", "bottom", "left"]))
        while True:  # inside the wall's area: a corner of the box lies in a neighbour's area
            pose = WallPose(
                float(rng.uniform(1.0, 1.6)),
                float(rng.uniform(-0.8, 0.8)),
                float(rng.uniform(-45.0, 45.0)),
                wall,
            )
            start = wall_to_world(pose, arena)
            if world_to_wall(*start, arena).wall == wall:
                return start, wall
    if row == "lift":
        dock = Teacher(teacher, arena=arena).dock_pose
        while True:  # a draw over 4.6 sd towards the table would overlap it: drawn again
            start = (
                dock[0] + float(rng.normal(0, 0.02)),
                dock[1] + float(rng.normal(0, 0.02)),
                dock[2] + math.radians(float(rng.normal(0, 2.0))),
            )
            if arena.table_gap_m(start[0], start[1]) >= BASE_RADIUS_M:
                return start, "top"
    raise ValueError(f"unknown row {row!r}; allowed: {', '.join(ROWS)}")


def dock_pose_at(
    wall: str, arena: ArenaGeometry = ArenaGeometry(), teacher: TeacherConfig = TeacherConfig()
) -> tuple:
    """Returns the docked pose ``(x, y, yaw)`` in front of the middle of ``wall``."""
    return wall_to_world(WallPose(teacher.dock_x_m, 0.0, 0.0, wall), arena)


class SuccessMonitor:
    """Follows one trial and decides its success by the row's definition."""

    def __init__(
        self,
        row: str,
        wall: str,
        dt: float,
        config: SuccessConfig = SuccessConfig(),
        arena: ArenaGeometry = ArenaGeometry(),
        teacher: TeacherConfig = TeacherConfig(),
    ):
        if row not in ROWS:
            raise ValueError(f"unknown row {row!r}; allowed: {', '.join(ROWS)}")
        self.row, self.wall, self.dt, self.config, self.arena = row, wall, dt, config, arena
        self.touched = False
        self.touched_at_s: float | None = None
        self.reached = False
        self.reached_at_s: float | None = None
        self.inside_s = 0.0  # 'pick': seconds inside the docking tolerance on end, up to now
        self.longest_inside_s = 0.0
        self.areas: set[str] = set()
        self.positions: list[tuple[float, float]] = []
        self.dock = dock_pose_at(wall, arena, teacher)
        x0, x1, y0, y1 = arena.table_box
        self.docked_gap = y0 - self.dock[1]  # the docked robot's centre to the table's front edge

    def update(self, true_pose, touching: bool) -> bool:
        """Records one step of the true pose; returns True when the trial has already succeeded."""
        c = self.config
        x, y, yaw = (float(v) for v in true_pose)
        self.positions.append((x, y))
        if touching and not self.touched:  # times are the ends of the steps, from the start
            self.touched, self.touched_at_s = True, len(self.positions) * self.dt
        self.areas.add(world_to_wall(x, y, yaw, self.arena).wall)
        if self.touched or self.row == "go":
            return False
        if self.row in ("pick", "pick_other_wall"):
            dx, dy = x - self.dock[0], y - self.dock[1]
            heading = abs(float(wrap_degrees(math.degrees(yaw - self.dock[2]))))
            inside = (
                math.hypot(dx, dy) <= c.dock_position_tol_m and heading <= c.dock_heading_tol_deg
            )
            # A step inside counts its whole control period: a robot inside for n steps on end
            # has held the dock for n dt seconds.
            self.inside_s = self.inside_s + self.dt if inside else 0.0
            self.longest_inside_s = max(self.longest_inside_s, self.inside_s)
            if inside and self.inside_s >= c.dock_settle_s - 1e-9:
                self.reached = True
        elif self.row == "lift":
            x0, x1, y0, y1 = self.arena.table_box
            gap = math.hypot(max(x0 - x, 0.0, x - x1), max(y0 - y, 0.0, y - y1))
            facing = abs(float(wrap_degrees(math.degrees(math.atan2(-y, -x) - yaw))))
            if gap >= self.docked_gap + c.lift_min_gap_m and facing <= c.lift_heading_tol_deg:
                self.reached = True
        if self.reached and self.reached_at_s is None:
            self.reached_at_s = len(self.positions) * self.dt
        return self.reached

    def success(self) -> bool:
        """Returns the trial's verdict (call at its end)."""
        return self.verdict()[0]

    def verdict(self) -> tuple[bool, str]:
        """Returns the trial's verdict and its reason in one line (call at its end)."""
        c = self.config
        if self.touched:
            return False, f"touched a wall or the table at {self.touched_at_s:.1f} s"
        if self.row in ("pick", "pick_other_wall"):
            if self.reached:
                return True, (
                    f"docked and held the dock for {c.dock_settle_s:g} s "
                    f"(settled at {self.reached_at_s:.1f} s)"
                )
            if self.longest_inside_s == 0:
                return False, "never inside the docking tolerance"
            return False, (
                f"inside the docking tolerance for at most {self.longest_inside_s:.1f} s on end, "
                f"{c.dock_settle_s:g} s needed"
            )
        if self.row == "lift":
            if self.reached:
                return True, f"left the table and faced the centre at {self.reached_at_s:.1f} s"
            return False, "did not leave the table facing the centre"
        window = max(1, int(round(c.go_window_s / self.dt)))
        p = np.asarray(self.positions)
        if len(p) <= window:
            return False, f"ended before one {c.go_window_s:g} s window"
        # Path length driven in every window (driving back and forth counts, turning on the spot
        # does not).
        path = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        travel = path[window:] - path[:-window]
        if len(self.areas) < c.go_min_wall_areas:
            return False, f"visited {len(self.areas)} wall area(s), {c.go_min_wall_areas} needed"
        if not np.all(travel >= c.go_min_window_travel_m):
            stalled = int(np.argmax(travel < c.go_min_window_travel_m)) * self.dt
            return False, (
                f"drove under {c.go_min_window_travel_m:g} m in the {c.go_window_s:g} s from "
                f"{stalled:.1f} s"
            )
        return True, f"kept clear and moving, {len(self.areas)} wall areas visited"


@dataclasses.dataclass
class TrialResult:
    """One trial: its row, policy, start, verdict and its reason, duration and the true and
    estimated traces."""

    row: str
    policy: str
    start: tuple
    wall: str
    success: bool
    reason: str
    seconds: float
    touched: bool
    trace: np.ndarray  # (n, 3) true world poses
    estimate: np.ndarray  # (n, 3) the student's own-pose estimates (NaN when unknown)
    directives: list
    #: (n, 3, 3) the estimates' covariances (m^2, rad^2; NaN when the student has none: the
    #: truth, overhead and odometry modes, or no pose yet).
    estimate_covariance: np.ndarray | None = None


def run_trial(
    env,
    agent,
    row: str,
    start,
    wall: str,
    *,
    seconds: float = 60.0,
    config: SuccessConfig = SuccessConfig(),
    stop_on_success: bool = True,
    frame_callback=None,
) -> TrialResult:
    """Runs one trial of ``agent`` in a student-only environment ``env`` from ``start``, for at most
    ``seconds``.

    ``frame_callback(env, agent)`` is called after every step (for videos).
    """
    task = env.task
    task.set_start(student_pose=start)
    timestep = env.reset()
    agent.reset(timestep, start)
    dt = task.control_timestep
    monitor = SuccessMonitor(row, wall, dt, config, task.geometry, task.config.teacher)
    trace, estimates, covariances, chosen = [], [], [], []
    n_steps = int(round(seconds / dt))
    for _ in range(n_steps):
        # The pose the agent acts on (the teacher reads it; a student estimates it).
        acted_on = np.asarray(timestep.observation["student_pose"], dtype=float)
        action = agent.step(timestep, dt)
        timestep = env.step(action)
        true_pose = np.asarray(timestep.observation["student_pose"], dtype=float)
        trace.append(true_pose)
        estimates.append(pose_or_nan(getattr(agent, "own_pose", acted_on)))
        covariance = getattr(agent, "own_covariance", None)
        covariances.append(np.full((3, 3), np.nan) if covariance is None else covariance)
        chosen.append(agent.directive)
        touching = task.touches_obstacle(env.physics, task.student)
        succeeded = monitor.update(true_pose, touching)
        if frame_callback is not None:
            frame_callback(env, agent)
        if (succeeded and stop_on_success) or timestep.last():
            break
    success, reason = monitor.verdict()
    return TrialResult(
        row,
        "teacher" if isinstance(agent, TeacherAgent) else "student",
        tuple(float(v) for v in start),
        wall,
        success,
        reason,
        len(trace) * dt,
        monitor.touched,
        np.asarray(trace),
        np.asarray(estimates),
        chosen,
        np.asarray(covariances).reshape(-1, 3, 3),
    )
