"""The imitation task: a teacher PeopleBot loops go-pick-lift while a student PeopleBot watches.

``load()`` builds a ``dm_env.Environment`` (dm-control composer). The action drives the student; the
scripted teacher (``peoplebot_sim.teacher``) drives itself through the same four directives.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from dm_control import composer
from dm_control.composer.observation import observable
from dm_env import specs

from peoplebot_sim import appearance, directives, entities, hardware
from peoplebot_sim.teacher import Teacher, TeacherConfig
from perception.wallframe import ArenaGeometry, world_to_wall

#: Student actuators in action order, with units.
ACTION_NAMES = ("forward", "turn", "gripper_lift", "gripper_paddles", "head_pan", "head_tilt")
ACTION_UNITS = ("m/s", "rad/s", "m", "m", "rad", "rad")
CAMERA_NAMES = ("overhead", "head")
#: Where the student watches from, world (x m, y m, yaw rad): the bottom-left corner, facing the centre.
STUDENT_WATCH_POSE = (-1.45, -1.45, math.pi / 4)


def teacher_actuation(teacher: TeacherConfig) -> hardware.Actuation:
    """Returns the teacher robot's command path: the firmware's acceleration limits its controller
    is told (``TeacherConfig.robot_linear_accel_mps2``, ``robot_yaw_accel_degps2``; 0: none), so
    the demonstrations are recorded on a robot that has them."""
    return hardware.Actuation(
        linear_accel_mps2=teacher.robot_linear_accel_mps2,
        yaw_accel_degps2=teacher.robot_yaw_accel_degps2,
    )


def start_pose(name: str, pose, arena: ArenaGeometry) -> tuple[float, float, float]:
    """Returns a robot's start ``pose`` ``(x m, y m, yaw rad)`` as a tuple of floats; raises
    ValueError naming ``name`` unless it is an array-like of three finite numbers that puts the
    robot (the disc of ``entities.BASE_RADIUS_M`` around its centre) on the free floor of
    ``arena``: inside the walls and clear of the table."""
    try:
        values = np.asarray(pose)
    except (TypeError, ValueError):
        values = np.empty(0)
    if values.shape != (3,) or values.dtype.kind not in "iuf" or not np.all(np.isfinite(values)):
        raise ValueError(
            f"{name} must be None or three finite numbers (x m, y m, yaw rad), got {pose!r}"
        )
    pose = tuple(float(v) for v in values)
    x, y, _ = pose
    radius = entities.BASE_RADIUS_M
    limit = arena.half_side_m - radius
    if abs(x) > limit or abs(y) > limit:
        raise ValueError(
            f"{name} {pose} lies outside the arena: x and y must be within +-{limit:.3f} m for a "
            f"robot of radius {radius:.3f} m"
        )
    gap = arena.table_gap_m(x, y)
    if gap < radius:
        x0, x1, y0, y1 = arena.table_box
        raise ValueError(
            f"{name} {pose} overlaps the table: a robot of radius {radius:.3f} m needs its centre "
            f"at least {radius:.3f} m from the table's footprint (x {x0:g} to {x1:g} m, y {y0:g} "
            f"to {y1:g} m), got {gap:.3f} m"
        )
    return pose


def check_apart(student: tuple[str, tuple], teacher: tuple[str, tuple]) -> None:
    """Raises ValueError unless the two robots' start poses, ``(what, pose)`` each, keep their
    discs (``entities.BASE_RADIUS_M``) apart."""
    (student_name, student_pose), (teacher_name, teacher_pose) = student, teacher
    least = 2 * entities.BASE_RADIUS_M
    distance = math.hypot(student_pose[0] - teacher_pose[0], student_pose[1] - teacher_pose[1])
    if distance < least:
        raise ValueError(
            f"{teacher_name} {tuple(teacher_pose)} overlaps {student_name} {tuple(student_pose)}: "
            f"the robots' centres must be at least {least:.3f} m apart (two robots of radius "
            f"{entities.BASE_RADIUS_M:.3f} m), got {distance:.3f} m"
        )


def _student_start(
    override, config: TaskConfig, configured: str = "TaskConfig.student_pose"
) -> tuple[str, tuple]:
    """Returns which student start applies, ``(what, pose)``: the override, the configured one
    (called ``configured``) or the watching spot."""
    if override is not None:
        return "student_pose", override
    if config.student_pose is not None:
        return configured, config.student_pose
    return "the student's watching spot", STUDENT_WATCH_POSE


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """How the imitation world is built.

    Attributes:
      with_teacher: put the scripted teacher in the arena (off for the student performing alone).
      cameras: camera observables to enable, from ``CAMERA_NAMES`` (empty for speed).
      width, height: camera frame size in pixels.
      control_timestep: seconds per environment step (one directive).
      physics_timestep: seconds per physics step; must divide ``control_timestep``.
      drive: the directives' wheel-servo targets.
      teacher: the teacher's behaviour parameters.
      student_pose: the student's start ``(x, y, yaw)``; None draws nothing and uses the watching spot.
      teacher_pose: the teacher's start ``(x, y, yaw)``; None draws a random free pose each episode.
        Each start is three finite numbers (any array-like, stored as a tuple of floats) that put
        the robot on the free floor (``start_pose``), and the teacher's keeps clear of the
        student's (``check_apart``).
      time_limit: episode length in seconds (``float('inf')`` for endless).
      actuation, body: how the student's command path and body differ from the nominal robot
        (``peoplebot_sim.hardware``; the defaults are the nominal robot).
      appearance: the room's lighting, shadows in the cameras and surface colours
        (``peoplebot_sim.appearance``; the default is the nominal arena).
    """

    with_teacher: bool = True
    cameras: tuple = ()
    width: int = 320
    height: int = 240
    control_timestep: float = 0.1
    physics_timestep: float = 0.01
    drive: directives.DriveSpeeds = directives.DriveSpeeds()
    teacher: TeacherConfig = TeacherConfig()
    student_pose: tuple | None = None
    teacher_pose: tuple | None = None
    time_limit: float = float("inf")
    actuation: hardware.Actuation = hardware.Actuation()
    body: hardware.Body = hardware.Body()
    appearance: appearance.Appearance = appearance.Appearance()

    def __post_init__(self):
        for camera in self.cameras:
            if camera not in CAMERA_NAMES:
                raise ValueError(f"unknown camera {camera!r}; allowed: {', '.join(CAMERA_NAMES)}")
        for name in ("width", "height"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or not 16 <= value <= 1280:
                raise ValueError(
                    f"{name} must be an integer number of pixels in [16, 1280], got {value!r}"
                )
        if self.height > 960:
            raise ValueError(
                f"height must be at most 960 pixels (the model's offheight), got {self.height}"
            )
        for name in ("control_timestep", "physics_timestep"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number of seconds, got {value!r}")
        ratio = self.control_timestep / self.physics_timestep
        if abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(
                f"control_timestep {self.control_timestep} must be a multiple of physics_timestep "
                f"{self.physics_timestep}"
            )
        if not self.time_limit > 0:
            raise ValueError(f"time_limit must be positive seconds, got {self.time_limit!r}")
        arena = ArenaGeometry()  # the task's (ImitationTask.geometry)
        for name in ("student_pose", "teacher_pose"):
            pose = getattr(self, name)
            if pose is not None:
                object.__setattr__(self, name, start_pose(name, pose, arena))
        if self.with_teacher and self.teacher_pose is not None:
            check_apart(
                _student_start(None, self, "student_pose"), ("teacher_pose", self.teacher_pose)
            )


class ImitationTask(composer.Task):
    """The teacher loops go-pick-lift; the agent's action drives the student."""

    def __init__(self, config: TaskConfig = TaskConfig()):
        self.config = config
        self.geometry = ArenaGeometry()
        self._arena = entities.Arena()
        appearance.apply_appearance(self._arena.mjcf_model, config.appearance)
        self._student = entities.PeopleBot("student")
        hardware.apply_body(self._student.mjcf_model, self._arena.floor, config.body)
        self._arena.attach(self._student).add("freejoint")
        self._teacher = None
        if config.with_teacher:
            self._teacher = entities.PeopleBot("teacher")
            self._arena.attach(self._teacher).add("freejoint")
        self._table = entities.Table()
        self._arena.attach(self._table).pos = entities.table_position(self.geometry)
        self._object = entities.GraspObject()
        frame = self._arena.attach(self._object)
        frame.pos = entities.object_position(self.geometry)
        frame.add("freejoint")
        self.teacher_controller = Teacher(config.teacher, self.geometry)
        self.collisions = 0
        self._in_contact = False
        self._last_directive = "forward"
        self.set_timesteps(config.control_timestep, config.physics_timestep)
        self._command_filter = None
        if config.actuation.active:
            self._command_filter = hardware.CommandFilter(config.actuation, config.physics_timestep)
        self._teacher_filter = None  # the teacher robot's firmware (``teacher_actuation``)
        teacher_firmware = teacher_actuation(config.teacher)
        if config.with_teacher and teacher_firmware.active:
            self._teacher_filter = hardware.CommandFilter(teacher_firmware, config.physics_timestep)
        self._teacher_command = np.zeros(2)
        self._task_observables = self._make_observables()

    # ------------------------------------------------------------------ entities
    @property
    def root_entity(self):
        return self._arena

    @property
    def arena(self) -> entities.Arena:
        return self._arena

    @property
    def student(self) -> entities.PeopleBot:
        return self._student

    @property
    def teacher(self) -> entities.PeopleBot | None:
        return self._teacher

    @property
    def grasp_object(self) -> entities.GraspObject:
        return self._object

    @property
    def task_observables(self):
        return self._task_observables

    def _make_observables(self):
        c = self.config
        shadows = {"shadow": c.appearance.shadows}
        obs = {
            "student_pose": observable.Generic(self._student.planar_pose),
            "student_wall_pose": observable.Generic(lambda p: self._wall_pose(self._student, p)),
            # Proprioception, as on the real robot: wheel encoders and head joint angles (rad).
            "student_wheel_angles": observable.Generic(
                lambda p: p.data.qpos[self._qpos_addresses(p)[:2]].copy()
            ),
            "student_head_angles": observable.Generic(
                lambda p: p.data.qpos[self._qpos_addresses(p)[2:]].copy()
            ),
        }
        if self._teacher is not None:
            obs["teacher_pose"] = observable.Generic(self._teacher.planar_pose)
            obs["teacher_wall_pose"] = observable.Generic(
                lambda p: self._wall_pose(self._teacher, p)
            )
            obs["teacher_word"] = observable.Generic(
                lambda _: np.array(directives.word_index(self.teacher_controller.word), np.int32)
            )
            obs["teacher_directive"] = observable.Generic(
                lambda _: np.array(directives.directive_index(self._last_directive), np.int32)
            )
        obs["overhead_camera"] = observable.MJCFCamera(
            self._arena.overhead_camera,
            width=c.width,
            height=c.height,
            render_flag_overrides=shadows,
        )
        obs["head_camera"] = observable.MJCFCamera(
            self._student.head_camera,
            width=c.width,
            height=c.height,
            render_flag_overrides=shadows,
        )
        # With composer's default update interval, delay and buffer size, each observable is computed
        # once per control step, after its last substep.
        for name, ob in obs.items():
            camera = name.removesuffix("_camera")
            ob.enabled = camera in c.cameras if name.endswith("_camera") else True
        return obs

    def _qpos_addresses(self, physics) -> np.ndarray:
        """Returns the qpos addresses of the student's left and right wheels, head pan and tilt."""
        key = id(physics.model.ptr)
        if getattr(self, "_qpos_key", None) != key:
            model = physics.model
            names = ("left_wheel", "right_wheel", "head_pan", "head_tilt")
            self._qpos_adr = np.array(
                [model.jnt_qposadr[model.name2id(f"student/{n}", "joint")] for n in names]
            )
            self._qpos_key = key
        return self._qpos_adr

    def _wall_pose(self, robot, physics) -> np.ndarray:
        x, y, yaw = robot.planar_pose(physics)
        return world_to_wall(x, y, yaw, self.geometry).as_array()

    # ------------------------------------------------------------------ spec
    def action_spec(self, physics):
        self._actuator_ids(physics)
        if self._action_spec is not None:
            return self._action_spec
        acts = [self._student.actuators[n] for n in ACTION_NAMES]
        ranges = physics.bind(acts).ctrlrange
        self._action_spec = specs.BoundedArray(
            shape=(len(acts),),
            dtype=np.float64,
            minimum=ranges[:, 0],
            maximum=ranges[:, 1],
            name="\t".join(f"{n} ({u})" for n, u in zip(ACTION_NAMES, ACTION_UNITS, strict=True)),
        )
        return self._action_spec

    def get_reward(self, physics):
        return 0.0

    def should_terminate_episode(self, physics):
        return physics.data.time >= self.config.time_limit - 1e-9

    def get_discount(self, physics):
        return 1.0

    # ------------------------------------------------------------------ episode
    def set_start(self, student_pose=None, teacher_pose=None) -> None:
        """Overrides the configured start poses ``(x, y, yaw)`` for the next episodes (None: back to
        the configuration's); ValueError for a pose off the free floor or robots that overlap (see
        ``TaskConfig``)."""
        if student_pose is not None:
            student_pose = start_pose("student_pose", student_pose, self.geometry)
        if teacher_pose is not None:
            teacher_pose = start_pose("teacher_pose", teacher_pose, self.geometry)
        if self._teacher is not None:
            teacher = ("teacher_pose", teacher_pose)
            if teacher_pose is None:
                teacher = ("TaskConfig.teacher_pose", self.config.teacher_pose)
            if teacher[1] is not None:  # a drawn teacher pose keeps clear of the student
                check_apart(_student_start(student_pose, self.config), teacher)
        self._start_override = (student_pose, teacher_pose)

    def initialize_episode(self, physics, random_state):
        rng = np.random.default_rng(random_state.randint(2**31))
        student_override, teacher_override = getattr(self, "_start_override", (None, None))
        _, student_pose = _student_start(student_override, self.config)
        self._student.set_planar_pose(physics, *student_pose)
        physics.named.data.qpos["student/head_pan"] = 0.0
        physics.named.data.qpos["student/head_tilt"] = 0.0
        if self._teacher is not None:
            pose = teacher_override if teacher_override is not None else self.config.teacher_pose
            if pose is None:
                pose = self.random_free_pose(rng, avoid=student_pose)
            self._teacher.set_planar_pose(physics, *pose)
        self._object.set_pose(
            physics,
            position=np.array(entities.object_position(self.geometry)),
            quaternion=np.array([1.0, 0, 0, 0]),
        )
        self.teacher_controller.reset(rng)
        self._last_directive = self.teacher_controller.directive
        if self._command_filter is not None:
            self._command_filter.reset()
        if self._teacher_filter is not None:
            self._teacher_filter.reset()
        self._teacher_command = np.zeros(2)
        self.collisions = 0
        self._in_contact = False

    def random_free_pose(
        self, rng, avoid=None, margin_m: float = 0.6
    ) -> tuple[float, float, float]:
        """Returns a random ``(x, y, yaw)`` at least ``margin_m`` from walls, clear of the table and of
        the pose ``avoid``."""
        h = self.geometry.half_side_m - margin_m
        for _ in range(1000):
            x, y = rng.uniform(-h, h, size=2)
            clear_table = self.geometry.clear_of_table(x, y, margin_m)
            clear_robot = avoid is None or math.hypot(x - avoid[0], y - avoid[1]) > 1.0
            if clear_table and clear_robot:
                return float(x), float(y), float(rng.uniform(-math.pi, math.pi))
        raise RuntimeError("found no free pose in 1000 draws")

    def before_step(self, physics, action, random_state):
        action = np.asarray(action, dtype=float)
        spec = self.action_spec(physics)
        if action.shape != spec.shape:
            raise ValueError(
                f"action must have shape {spec.shape} ({', '.join(ACTION_NAMES)}), "
                f"got {action.shape}"
            )
        if not np.all(np.isfinite(action)):
            raise ValueError(f"action must be finite, got {action}")
        bad = (action < spec.minimum - 1e-9) | (action > spec.maximum + 1e-9)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"action {ACTION_NAMES[i]}={action[i]} is outside "
                f"[{spec.minimum[i]}, {spec.maximum[i]}] {ACTION_UNITS[i]}"
            )
        physics.data.ctrl[self._actuator_ids(physics)] = action
        if self._teacher is not None:
            self.drive_teacher(physics)

    def before_substep(self, physics, action, random_state):
        """Passes the student's wheel command through its firmware's command path
        (``TaskConfig.actuation``), and the teacher's through its own (``teacher_actuation``),
        once per physics step; nothing for a robot that is nominal."""
        if self._command_filter is not None:
            setpoint = self._command_filter.step(np.asarray(action, dtype=float)[:2])
            physics.data.ctrl[self._actuator_ids(physics)[:2]] = setpoint
        if self._teacher_filter is not None:  # the ids were looked up in before_step
            setpoint = self._teacher_filter.step(self._teacher_command)
            physics.data.ctrl[list(self._teacher_ids)] = setpoint

    def _actuator_ids(self, physics) -> np.ndarray:
        key = id(physics.model.ptr)
        if getattr(self, "_ids_key", None) != key:
            bind = physics.bind
            self._student_ids = np.array(
                [bind(self._student.actuators[n]).element_id for n in ACTION_NAMES]
            )
            if self._teacher is not None:
                self._teacher_ids = (
                    bind(self._teacher.actuators["forward"]).element_id,
                    bind(self._teacher.actuators["turn"]).element_id,
                )
            self._action_spec = None
            self._ids_key = key
        return self._student_ids

    def drive_teacher(self, physics) -> str:
        """Steps the teacher's controller and sets its wheel servos; returns its directive."""
        student = self._student.planar_pose(physics)
        directive = self.teacher_controller.step(
            self._teacher.planar_pose(physics), student, self.config.control_timestep
        )
        self._actuator_ids(physics)
        executed = self.teacher_controller.executed  # the wheels: a disturbance's turn, if any
        self._teacher_command = np.asarray(self.config.drive.command(executed), dtype=float)
        if self._teacher_filter is None:  # else the firmware sets the servos each physics step
            physics.data.ctrl[list(self._teacher_ids)] = self._teacher_command
        self._last_directive = directive
        return directive

    def after_step(self, physics, random_state):
        if self._teacher is not None:
            touching = self.teacher_touches_obstacle(physics)
            if touching and not self._in_contact:
                self.collisions += 1
            self._in_contact = touching

    def teacher_touches_obstacle(self, physics) -> bool:
        """Returns whether any teacher geom touches a wall, the table or the student."""
        return self.touches_obstacle(physics, self._teacher)

    def touches_obstacle(self, physics, robot: entities.PeopleBot) -> bool:
        """Returns whether any geom of ``robot`` touches a wall, the table or the other robot."""
        own, obstacle = self._contact_masks(physics)[robot.role]
        n = physics.data.ncon
        if n == 0:
            return False
        g1 = physics.data.contact.geom1[:n]
        g2 = physics.data.contact.geom2[:n]
        return bool(np.any((own[g1] & obstacle[g2]) | (own[g2] & obstacle[g1])))

    def _contact_masks(self, physics) -> dict:
        """Returns, per robot role, boolean masks over geoms: the robot's own geoms, and the geoms
        it must not touch (walls, the table, the other robot). Cached per compiled model."""
        key = id(physics.model.ptr)
        cached = getattr(self, "_contact_masks_cache", None)
        if cached is not None and cached[0] == key:
            return cached[1]
        model = physics.model
        geom_root = model.body_rootid[model.geom_bodyid]
        names = [model.id2name(g, "geom") or "" for g in range(model.ngeom)]
        walls = np.array(
            [geom_root[g] == 0 and names[g].startswith("wall") for g in range(model.ngeom)]
        )
        table_body = self._table.mjcf_model.find("body", "table")
        table = geom_root == model.body_rootid[physics.bind(table_body).element_id]
        robots = [r for r in (self._student, self._teacher) if r is not None]
        roots = {r.role: model.body_rootid[physics.bind(r.root_body).element_id] for r in robots}
        masks = {}
        for robot in robots:
            own = geom_root == roots[robot.role]
            others = np.zeros(model.ngeom, bool)
            for role, root in roots.items():
                if role != robot.role:
                    others |= geom_root == root
            masks[robot.role] = (own, walls | table | others)
        self._contact_masks_cache = (key, masks)
        return masks


def load(config: TaskConfig | None = None, seed=None, **overrides) -> composer.Environment:
    """Returns the imitation environment (a ``dm_env.Environment``).

    Args:
      config: the task configuration; keyword ``overrides`` replace its fields.
      seed: seed of the environment's randomness (teacher start, jitter); one seed, one trajectory.
    """
    config = dataclasses.replace(config or TaskConfig(), **overrides)
    task = ImitationTask(config)
    # The model never changes between episodes: compile it once (composer recompiles by default).
    return composer.Environment(
        task,
        random_state=seed,
        strip_singleton_obs_buffer_dim=True,
        raise_exception_on_physics_error=True,
        recompile_mjcf_every_episode=False,
    )
