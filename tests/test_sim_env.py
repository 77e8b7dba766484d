"""The imitation environment (``peoplebot_sim.task``): dm_env conformance, seeded determinism, bad
input, the teacher's go-pick-lift loop, and what the rendered cameras show to ``perception``."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import dataclasses
import math
import re

import cv2
import dm_env
import mujoco
import numpy as np
import pytest
from absl.testing import absltest
from dm_control import composer, mjcf
from dm_env import test_utils

from imitation import observers, performance
from imitation.streams import StreamGenerator
from peoplebot_sim import assets, cameras, directives, entities, task
from peoplebot_sim.rendering import FrameRenderer
from peoplebot_sim.teacher import Teacher, TeacherConfig
from perception import layout
from perception.markers import DetectorConfig
from perception.pantilt import head_camera
from perception.pipeline import Tracker
from perception.wallframe import ArenaGeometry, world_to_wall, world_to_wall_batch, wrap_degrees

STILL = np.zeros(len(task.ACTION_NAMES))  # the student stands still, gripper down and open


def random_actions(env, n: int, seed: int):
    """Yields ``n`` uniform random actions within the action spec."""
    spec = env.action_spec()
    rng = np.random.default_rng(seed)
    for _ in range(n):
        yield rng.uniform(spec.minimum, spec.maximum)


# ------------------------------------------------------------------------------ dm_env conformance
class EnvironmentTest(test_utils.EnvironmentTestMixin, absltest.TestCase):
    """dm_env's interface contract, over episodes of 1 s (10 steps) under random actions."""

    def make_object_under_test(self):
        return task.load(seed=0, time_limit=1.0)

    def make_action_sequence(self):
        yield from random_actions(self.environment, 25, seed=0)


class EnvironmentWithCameraTest(EnvironmentTest):
    """The same contract with the overhead camera observable on (small frames)."""

    def make_object_under_test(self):
        return task.load(seed=0, time_limit=1.0, cameras=("overhead",), width=64, height=48)


def test_camera_observables_have_the_configured_size():
    env = task.load(seed=0, cameras=("overhead", "head"), width=80, height=60)
    specs = env.observation_spec()
    observation = env.reset().observation
    for name in ("overhead_camera", "head_camera"):
        assert specs[name].shape == (60, 80, 3) and specs[name].dtype == np.uint8
        assert observation[name].shape == (60, 80, 3)
        assert observation[name].std() > 0  # not a blank frame
    env.close()


# ---------------------------------------------------------------------------------- determinism
def rollout(env, n_steps: int = 300, action_seed: int = 0) -> np.ndarray:
    """Returns one row per step: teacher ``x, y, yaw``, word index, directive index, student
    ``x, y, yaw``; the student drives under seeded random actions."""
    rows = [np.concatenate([env.reset().observation["teacher_pose"], [-1, -1], [0, 0, 0]])]
    for action in random_actions(env, n_steps, action_seed):
        o = env.step(action).observation
        rows.append(
            np.concatenate(
                [o["teacher_pose"], [o["teacher_word"], o["teacher_directive"]], o["student_pose"]]
            )
        )
    return np.array(rows)


def test_same_seed_same_trajectory_and_different_seeds_differ():
    first = rollout(task.load(seed=7))
    again = rollout(task.load(seed=7))
    other = rollout(task.load(seed=8))
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first[:, :3], other[:, :3])
    # The trajectory is not trivial: the teacher moves and changes directive.
    assert np.ptp(first[1:, 0]) + np.ptp(first[1:, 1]) > 0.5
    assert len(set(first[1:, 4])) > 1


def test_consecutive_observations_do_not_share_memory():
    env = task.load(seed=0, cameras=("overhead", "head"), width=32, height=24)
    previous = env.reset().observation
    for action in random_actions(env, 3, seed=0):
        current = env.step(action).observation
        for name, value in current.items():
            assert not np.shares_memory(value, previous[name]), name
        previous = current
    env.close()


# ------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "overrides, value",
    [
        ({"cameras": ("ceiling",)}, "ceiling"),
        ({"cameras": ("overhead", "student")}, "student"),
        ({"width": -320}, "-320"),
        ({"width": 0}, "0"),
        ({"height": -1}, "-1"),
        ({"height": 0}, "0"),
    ],
)
def test_bad_task_config_raises_naming_the_value(overrides, value):
    with pytest.raises(ValueError, match=value):
        task.TaskConfig(**overrides)


NOT_THREE = "must be None or three finite numbers"
OUTSIDE = "lies outside the arena: x and y must be within [+]-1.667 m for a robot of radius 0.333 m"


@pytest.mark.parametrize(
    "poses, message",
    [
        ({"student_pose": (100, 100, 0)}, rf"student_pose \(100.0, 100.0, 0.0\) {OUTSIDE}"),
        ({"teacher_pose": (0.0, -1.7, 0.0)}, rf"teacher_pose \(0.0, -1.7, 0.0\) {OUTSIDE}"),
        ({"student_pose": (1.68, 0.0, 0.0)}, rf"student_pose \(1.68, 0.0, 0.0\) {OUTSIDE}"),
        (
            {"student_pose": (0.0, 1.4, 0.0)},
            r"student_pose \(0.0, 1.4, 0.0\) overlaps the table: a robot of radius 0.333 m needs "
            r"its centre at least 0.333 m from the table's footprint \(x -0.5 to 0.5 m, y 1.6 to 2 "
            r"m\), got 0.200 m",
        ),
        # Off the table's corner: 0.212 m from it along each axis, 0.300 m diagonally.
        (
            {"teacher_pose": (0.712, 1.388, 0.0)},
            "teacher_pose .* overlaps the table: .* got 0.300 m",
        ),
        (
            {"student_pose": (0, 0, 0), "teacher_pose": (0, 0, 0)},
            r"teacher_pose \(0.0, 0.0, 0.0\) overlaps student_pose \(0.0, 0.0, 0.0\): the robots' "
            r"centres must be at least 0.666 m apart \(two robots of radius 0.333 m\), got 0.000 m",
        ),
        (
            {"teacher_pose": (-1.0, -1.2, 0.0)},
            r"teacher_pose \(-1.0, -1.2, 0.0\) overlaps the student's watching spot \(-1.45, -1.45",
        ),
        (
            {"student_pose": (0.0, 0.0, math.nan)},
            f"student_pose {NOT_THREE} .*, got \\(0.0, 0.0, nan\\)",
        ),
        ({"teacher_pose": np.array([0.0, np.inf, 0.0])}, f"teacher_pose {NOT_THREE}"),
        ({"student_pose": (0.0, 0.0)}, f"student_pose {NOT_THREE} .*, got \\(0.0, 0.0\\)"),
        ({"student_pose": ("0", "0", "0")}, f"student_pose {NOT_THREE}"),
        ({"student_pose": np.zeros((3, 1))}, f"student_pose {NOT_THREE}"),
        ({"student_pose": [0.0, [0.0], 0.0]}, f"student_pose {NOT_THREE}"),
        ({"student_pose": (True, False, True)}, f"student_pose {NOT_THREE}"),
    ],
)
def test_start_poses_off_the_free_floor_are_refused(start_task, poses, message):
    """A start must put the robot (the disc of ``entities.BASE_RADIUS_M``) inside the walls, clear
    of the table and of the other robot, in the configuration and in ``set_start`` alike."""
    with pytest.raises(ValueError, match=message):
        task.TaskConfig(**poses)
    with pytest.raises(ValueError, match=message):
        start_task.set_start(**poses)


@pytest.fixture(scope="module")
def start_task():
    return task.ImitationTask(task.TaskConfig())


def test_set_start_checks_the_robots_apart_against_the_configured_start():
    configured = task.ImitationTask(task.TaskConfig(student_pose=(0.0, 0.0, 0.0)))
    with pytest.raises(ValueError, match=r"teacher_pose \(0.5, 0.0, 0.0\) overlaps TaskConfig.stu"):
        configured.set_start(teacher_pose=(0.5, 0.0, 0.0))
    configured = task.ImitationTask(task.TaskConfig(teacher_pose=(1.0, 1.0, 0.0)))
    with pytest.raises(ValueError, match=r"TaskConfig.teacher_pose \(1.0, 1.0, 0.0\) overlaps st"):
        configured.set_start(student_pose=(1.2, 0.9, 0.0))
    configured.set_start(student_pose=(-1.0, -1.0, 0.0))  # the teacher stays clear of this one
    # Without a teacher in the world, its pose takes no room.
    task.TaskConfig(with_teacher=False, student_pose=(0, 0, 0), teacher_pose=(0, 0, 0))


def test_start_poses_of_the_experiment_are_accepted(start_task):
    """Every start the performance trials draw (the docked 'lift' start 0.425 m in front of the
    table, 'pick' starts 1.0-1.6 m from a wall), the dock at each wall, Fig. 4's start, the watching
    spot and poses 0.45 m from the walls put the robot on the free floor."""
    rng = np.random.default_rng(0)
    starts = [performance.sample_start(row, rng)[0] for row in performance.ROWS for _ in range(500)]
    starts += [performance.dock_pose_at(wall) for wall in ("top", "right", "bottom", "left")]
    starts += [performance.FIG4_START, task.STUDENT_WATCH_POSE, (1.55, -1.55, 2.0)]
    starts += [start_task.random_free_pose(rng, margin_m=0.45) for _ in range(500)]
    for start in starts:
        start_task.set_start(student_pose=start)
        assert task.TaskConfig(with_teacher=False, student_pose=start).student_pose == start
    docked = performance.dock_pose_at("top")
    assert start_task.geometry.table_gap_m(*docked[:2]) == pytest.approx(0.425)


def test_start_poses_are_any_array_like_and_the_run_starts_there():
    """A numpy array is a pose like any other (it once failed on its truth value); the start is
    kept as a tuple of floats and the student starts there."""
    config = task.TaskConfig(with_teacher=False, student_pose=np.array([0.5, -0.6, 0.3]))
    assert config.student_pose == (0.5, -0.6, 0.3)
    assert all(type(v) is float for v in config.student_pose)
    env = task.load(with_teacher=False, seed=0)
    env.task.set_start(student_pose=np.array([1, -1, 0]))
    np.testing.assert_allclose(env.reset().observation["student_pose"], [1, -1, 0], atol=1e-9)
    env.close()


def test_base_radius_holds_the_base_footprint_but_not_the_gripper():
    """``entities.BASE_RADIUS_M`` reaches the chassis' corners (the footprint, the one source) and
    every other collision geom of the base (wheels, casters, column, deck); the gripper's paddles
    reach beyond it."""
    model = mujoco.MjModel.from_xml_path(str(assets.PEOPLEBOT_XML))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    gripper = {model.body(name).id for name in ("gripper", "left_paddle", "right_paddle")}
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    reach = {"base": 0.0, "gripper": 0.0}
    for g in range(model.ngeom):
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue  # visual only
        centre, size = data.geom_xpos[g], model.geom_size[g]
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
            planar = math.hypot(*centre[:2]) + size[0]
        else:
            assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX, model.geom(g).name
            corners = centre + (signs * size) @ data.geom_xmat[g].reshape(3, 3).T
            planar = np.hypot(corners[:, 0], corners[:, 1]).max()
        part = "gripper" if model.geom_bodyid[g] in gripper else "base"
        reach[part] = max(reach[part], planar)
    assert reach["base"] == pytest.approx(entities.BASE_RADIUS_M, abs=1e-9)
    assert reach["gripper"] > entities.BASE_RADIUS_M + 0.02


def test_the_landmark_filters_footprint_is_the_models_outline():
    """``observers.ROBOT_FOOTPRINT_M`` (front, rear, half-width; the contact model's rectangle)
    is the outline of the PeopleBot's collision geoms at rest, robot frame, but the wheels'
    spheres, which bulge 5 cm beyond the chassis (the real wheels sit inside it)."""
    model = mujoco.MjModel.from_xml_path(str(assets.PEOPLEBOT_XML))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    points, wheels = [], {model.geom(name).id for name in ("left_wheel", "right_wheel")}
    for g in range(model.ngeom):
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue  # visual only
        centre, size = data.geom_xpos[g], model.geom_size[g]
        if g in wheels:
            assert abs(centre[1]) + size[0] == pytest.approx(0.265)
            continue
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
            points += [
                centre[:2] + size[0] * np.array(d) for d in ((1, 0), (-1, 0), (0, 1), (0, -1))
            ]
        else:
            corners = centre + (signs * size) @ data.geom_xmat[g].reshape(3, 3).T
            points += list(corners[:, :2])
    points = np.array(points)
    front, rear, half_width = observers.ROBOT_FOOTPRINT_M
    assert points[:, 0].max() == pytest.approx(front, abs=1e-9)
    assert -points[:, 0].min() == pytest.approx(rear, abs=1e-9)
    assert np.abs(points[:, 1]).max() == pytest.approx(half_width, abs=1e-9)


def test_bad_renderer_size_raises_naming_the_value():
    physics = mjcf.Physics.from_mjcf_model(task.ImitationTask().root_entity.mjcf_model)
    for size in ({"width": -5}, {"height": 0}):
        with pytest.raises(ValueError, match=str(next(iter(size.values())))):
            FrameRenderer(physics, **size)


def test_a_frame_renderer_leaves_the_camera_observables_seeing():
    """A video's renderer on the environment's physics (its own OpenGL context) must not blind the
    environment's camera observables (dm_control's context): the head camera still sees the
    arena after the renderer is made and used, frame for frame as before."""
    env = task.load(seed=0, cameras=("head",), width=64, height=48)
    try:
        still = np.zeros(env.action_spec().shape)
        env.reset()
        before = env.step(still).observation["head_camera"].astype(float)
        with FrameRenderer(env.physics, 64, 48, antialias=True) as renderer:
            assert renderer.render("overhead").mean() > 20
            after = env.step(still).observation["head_camera"].astype(float)
            assert after.mean() > 20 and np.abs(after - before).mean() < 5
    finally:
        env.close()


@pytest.fixture(scope="module")
def stepped_env():
    env = task.load(seed=0)
    env.reset()
    yield env
    env.close()


@pytest.mark.parametrize(
    "index, value, pattern",
    [
        (0, np.nan, "nan"),
        (1, np.inf, "inf"),
        (0, 0.9, "forward=0.9"),  # above the 0.75 m/s top speed
        (1, -2.0, "turn=-2.0"),
        (2, 0.5, "gripper_lift=0.5"),
        (4, 2.0, "head_pan=2.0"),
    ],
)
def test_bad_action_raises_naming_the_value(stepped_env, index, value, pattern):
    action = STILL.copy()
    action[index] = value
    with pytest.raises(ValueError, match=pattern):
        stepped_env.step(action)


@pytest.mark.parametrize("shape", [(5,), (7,), (2, 6)])
def test_action_of_the_wrong_shape_raises_naming_the_shape(stepped_env, shape):
    with pytest.raises(ValueError, match=re.escape(str(shape))):
        stepped_env.step(np.zeros(shape))


def test_unknown_word_or_directive_raises_naming_it_and_the_allowed():
    with pytest.raises(ValueError, match="'jump'.*go, pick, lift"):
        directives.word_index("jump")
    with pytest.raises(ValueError, match="'fly'.*forward, backward"):
        directives.directive_index("fly")
    with pytest.raises(ValueError, match="'left'"):
        directives.DriveSpeeds().command("left")


# ------------------------------------------------------------------------------------ the teacher
#: Seeds of the random teacher starts checked through the stream generator.
STREAM_SEEDS = (0, 1, 2, 3, 4)
#: Simulated seconds within which the teacher must complete two go-pick-lift cycles.
TWO_CYCLES_S = 300.0


@pytest.mark.parametrize("seed", STREAM_SEEDS)
def test_teacher_completes_cycles_from_random_starts_without_watchdog_events(seed):
    """From a random start the teacher completes two go-pick-lift cycles within 300 s simulated.

    Measured first (stream generator, the model of 2026-11-22 00:02, seeds 0-29, 300 s each): the
    first cycle ends after 46 s (median) and 151 s at most; cycles last 39 s (median), 85 s (90th
    percentile), 167 s at most; the second cycle ends by 260 s at the latest. 'go' is a random walk,
    so the tail is long (with the earlier model one composer run took 418 s to its first cycle).
    """
    generator = StreamGenerator(seed)
    stream = generator.generate(int(round(TWO_CYCLES_S / 0.1)))
    teacher = generator.task.teacher_controller
    assert teacher.cycles_completed >= 2
    assert teacher.events == []
    # Every word was performed.
    assert set(stream.word.tolist()) == {0, 1, 2}


def test_pick_triggers_on_a_drawn_share_of_entries_and_go_goes_on_otherwise():
    """Entering the trigger region, 'go' switches to 'pick' with ``pick_trigger_probability``
    (a drawn share of entries); otherwise it stays 'go' while inside, and draws again on its next
    entry. The trigger depth is drawn per cycle within ``pick_trigger_x_m``."""
    outside = (0.0, 0.0, math.pi / 2)  # the arena's centre, facing the table
    inside = (0.0, 0.6, math.pi / 2)  # 1.4 m from the top wall, on the centre line
    picked, stayed = 0, 0
    config = TeacherConfig(pick_trigger_x_m=(1.45, 1.6))
    for seed in range(400):
        teacher = Teacher(config, rng=seed)
        assert 1.45 <= teacher._trigger_x_m <= 1.6
        teacher.step(outside)
        teacher.step(inside)
        if teacher.word == "pick":
            picked += 1
            continue
        for _ in range(3):  # still inside: no new draw
            teacher.step(inside)
            assert teacher.word == "go"
        stayed += 1
    assert abs(picked / 400 - config.pick_trigger_probability) < 0.07, picked
    assert stayed == 400 - picked
    # Leaving and entering again draws again: with probability 1 every entry picks.
    teacher = Teacher(dataclasses.replace(config, pick_trigger_probability=1.0), rng=0)
    teacher.step(outside)
    teacher.step(inside)
    assert teacher.word == "pick"
    for bad in (0.0, 1.5):
        with pytest.raises(ValueError, match="teacher.pick_trigger_probability must be in"):
            TeacherConfig(pick_trigger_probability=bad)
    with pytest.raises(ValueError, match=r"teacher.pick_trigger_x_m must be \(min, max\)"):
        TeacherConfig(pick_trigger_x_m=(1.6, 1.2))
    with pytest.raises(
        ValueError, match="unknown teacher.docking 'straight'; allowed: funnel, lane, phased"
    ):
        TeacherConfig(docking="straight")
    with pytest.raises(ValueError, match="teacher.funnel_lookahead_m must be > 0 m, got 0.0"):
        TeacherConfig(funnel_lookahead_m=0.0)


def test_overshoot_shows_the_way_back_from_beyond_the_dock():
    """With ``teacher.funnel_overshoot_s`` the recorded stream holds 'pick' poses beyond the
    dock, where the commands are the controller's way back (square up, back out) while the wheels
    rolled on; every docking still settles and the watchdog never fires. Without it the teacher
    rarely stands there."""

    def record(overshoot_s):
        config = task.TaskConfig()
        config = dataclasses.replace(
            config, teacher=dataclasses.replace(config.teacher, funnel_overshoot_s=overshoot_s)
        )
        generator = StreamGenerator(7, config)
        teacher = generator.task.teacher_controller
        dock_y = teacher.dock_pose[1]
        beyond, rolled, picks, settles, word, phase = [], 0, 0, 0, None, None
        for _ in range(8000):
            stream = generator.generate(1)
            commanded = directives.DIRECTIVES[stream.directive[0]]
            picks += teacher.word == "pick" and word != "pick"
            settles += teacher.phase == "settle" and phase != "settle"
            word, phase = teacher.word, teacher.phase
            if word == "pick" and stream.pose_world[0][1] > dock_y + 0.03:
                beyond.append(commanded)
            rolled += teacher.executed == "forward" and commanded != "forward"
        assert teacher.events == []
        return beyond, rolled, picks, settles

    beyond, rolled, picks, settles = record(0.6)
    assert picks >= 10 and settles >= picks - 1
    assert len(beyond) >= 40 and "backward" in beyond and "forward" not in beyond
    assert rolled > 0
    plain, rolled, _, _ = record(0.0)
    assert len(plain) < len(beyond) / 3 and rolled == 0


def test_disturbances_turn_the_wheels_while_the_commands_stay_the_controllers():
    """With disturbances, the wheels sometimes turn while the teacher commands something else (only
    in 'pick', never while it settles), at about the configured rate; the stream records the
    commands. Undisturbed (``TeacherConfig.undisturbed``), what is executed is what is
    commanded, and a stream of it is the one of a controller without the feature."""
    config = task.TaskConfig()
    rates = config.teacher.slip_rate_per_s
    assert rates["pick"] > 0 and rates["lift"] == 0
    generator = StreamGenerator(7, config)
    teacher = generator.task.teacher_controller
    commanded, executed, phases, words = [], [], [], []
    for _ in range(6000):
        stream = generator.generate(1)
        commanded.append(directives.DIRECTIVES[stream.directive[0]])
        executed.append(teacher.executed)
        phases.append(teacher.phase)
        words.append(teacher.word)
    commanded, executed = np.array(commanded), np.array(executed)
    phases, words = np.array(phases), np.array(words)
    differ = commanded != executed
    assert differ.any() and teacher.events == []
    assert set(words[differ]) == {"pick"} and "settle" not in set(phases[differ])
    assert set(executed[differ]) <= {"turn_left", "turn_right"}
    # Disturbances begin at about the rate per second of 'pick' outside its settling.
    starts = differ & ~np.concatenate([[False], differ[:-1]])
    exposed = ((words == "pick") & (phases != "settle")).sum() * 0.1
    assert 0.4 * rates["pick"] < starts.sum() / exposed < 1.6 * rates["pick"]
    quiet = task.TaskConfig(teacher=config.teacher.undisturbed())
    generator = StreamGenerator(7, quiet)
    for _ in range(3000):
        generator.generate(1)
        assert generator.task.teacher_controller.executed == (
            generator.task.teacher_controller.directive
        )
    with pytest.raises(ValueError, match="slip_rate_per_s"):
        TeacherConfig(slip_rate_per_s={"go": -1.0, "pick": 0.0, "lift": 0.0})
    with pytest.raises(ValueError, match="slip_seconds"):
        TeacherConfig(slip_seconds=(2.0, 1.0))


class _SubstepContactTask(task.ImitationTask):
    """The imitation task that also counts teacher contacts at every physics substep."""

    substep_contacts = 0

    def after_substep(self, physics, random_state):
        if self.teacher_touches_obstacle(physics):
            self.substep_contacts += 1


def test_teacher_loops_in_the_environment_without_collisions():
    """Through composer (all hooks), 300 s simulated: two cycles or more, no contact of the teacher
    with a wall, the table or the student at any 10 ms substep, no watchdog event."""
    imitation = _SubstepContactTask(task.TaskConfig())
    env = composer.Environment(
        imitation,
        random_state=0,
        strip_singleton_obs_buffer_dim=True,
        raise_exception_on_physics_error=True,
    )
    env.reset()
    words = set()
    for _ in range(int(round(TWO_CYCLES_S / 0.1))):
        words.add(int(env.step(STILL).observation["teacher_word"]))
    teacher = imitation.teacher_controller
    assert teacher.cycles_completed >= 2
    assert imitation.collisions == 0
    assert imitation.substep_contacts == 0
    assert teacher.events == []
    assert words == {0, 1, 2}
    env.close()


# ------------------------------------------------------------------------------------- rendering
def test_overhead_frames_show_every_robots_top_marker():
    """OpenCV's ArUco detector (DICT_4X4_50, with the bit-reading parameters perception measured
    for 18-pixel markers: OpenCV's defaults miss about 2% of them) finds ids 0 (teacher) and 10
    (student) in the environment's overhead frames while the teacher drives (320x240)."""
    env = task.load(seed=1, cameras=("overhead",), width=320, height=240)
    env.reset()
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    config = DetectorConfig()
    params = cv2.aruco.DetectorParameters()
    params.perspectiveRemovePixelPerCell = config.bit_pixels_per_cell
    params.perspectiveRemoveIgnoredMarginPerCell = config.bit_margin_per_cell
    params.errorCorrectionRate = config.error_correction_rate
    params.minDistanceToBorder = config.min_distance_to_border_px
    detector = cv2.aruco.ArucoDetector(dictionary, params)
    top_ids = {layout.marker_id(robot, "top") for robot in layout.ROBOT_NAMES}
    assert top_ids == {0, 10}
    for step in range(1, 121):
        frame = env.step(STILL).observation["overhead_camera"]
        if step % 10:
            continue
        _, ids, _ = detector.detectMarkers(cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY))
        found = set() if ids is None else set(ids.ravel().tolist())
        assert top_ids <= found, f"step {step}: found {sorted(found)}"
    env.close()


@pytest.fixture(scope="module")
def posed_scene():
    """Returns the task and a physics whose robots are posed by hand (kinematics only)."""
    imitation = task.ImitationTask(task.TaskConfig())
    physics = mjcf.Physics.from_mjcf_model(imitation.root_entity.mjcf_model)
    return imitation, physics


def _pose_robots(imitation, physics, teacher, student, pan_rad=0.0, tilt_rad=0.0):
    imitation.teacher.set_planar_pose(physics, *teacher)
    imitation.student.set_planar_pose(physics, *student)
    physics.named.data.qpos["student/head_pan"] = pan_rad
    physics.named.data.qpos["student/head_tilt"] = tilt_rad
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)


def test_tracker_recovers_both_robots_poses_from_rendered_overhead_frames(posed_scene):
    """Robots posed anywhere, near walls and docked; 640x480 overhead frames (at 320x240 a top
    marker is about 18 px wide and single-frame headings err up to 2 deg); within 1.5 cm and 1.5 deg
    of the simulator's planar pose."""
    imitation, physics = posed_scene
    width, height = 640, 480
    rng = np.random.default_rng(0)
    camera = cameras.camera_model(physics, "overhead", width, height)
    tracker = Tracker()
    poses = [imitation.random_free_pose(rng, margin_m=0.45) for _ in range(10)]
    poses += [imitation.teacher_controller.dock_pose, (1.5, -1.5, 2.0), (-1.5, 1.45, -0.3)]
    with FrameRenderer(physics, width, height) as renderer:
        for teacher_pose in poses:
            student_pose = imitation.random_free_pose(rng, avoid=teacher_pose, margin_m=0.45)
            _pose_robots(imitation, physics, teacher_pose, student_pose)
            frame = tracker.estimate(renderer.render("overhead"), camera)
            for robot, truth in (("teacher", teacher_pose), ("student", student_pose)):
                assert layout.marker_id(robot, "top") in frame.visible_ids(robot)
                estimate = frame.poses[robot]
                error_cm = 100 * math.hypot(estimate.x_m - truth[0], estimate.y_m - truth[1])
                error_deg = abs(float(wrap_degrees(math.degrees(estimate.yaw_rad - truth[2]))))
                assert error_cm < 1.5 and error_deg < 1.5, (robot, truth, error_cm, error_deg)


@pytest.mark.parametrize(
    "student, pan_deg, tilt_deg",
    [
        ((-1.45, -1.45, math.pi / 4), 0.0, 0.0),
        ((0.3, -0.8, 2.0), 60.0, -20.0),
        ((1.2, 0.4, -2.5), -98.0, 30.0),
        ((-0.5, 1.0, 0.7), 45.0, 88.0),
    ],
)
def test_perception_head_camera_matches_the_models_head_camera(
    posed_scene, student, pan_deg, tilt_deg
):
    """perception.pantilt.head_camera (the student's pose, the head angles and HeadMount) projects
    world points where MuJoCo's 'student/head_camera' does, within 0.5 px."""
    imitation, physics = posed_scene
    width, height = 320, 240
    _pose_robots(
        imitation, physics, (1.6, 1.6, 0.0), student, math.radians(pan_deg), math.radians(tilt_deg)
    )
    simulator = cameras.camera_model(physics, "student/head_camera", width, height)
    perceived = head_camera(simulator, student, pan_deg, tilt_deg)
    # Points 1 to 3 m ahead of the simulator's camera, spread over its field of view.
    rng = np.random.default_rng(1)
    pixels = rng.uniform([10, 10], [width - 10, height - 10], size=(12, 2))
    rays = simulator.pixel_rays(pixels)
    points = simulator.position_world + rays * rng.uniform(1.0, 3.0, size=(12, 1))
    np.testing.assert_allclose(simulator.project(points), pixels, atol=1e-6)
    np.testing.assert_allclose(perceived.project(points), pixels, atol=0.5)
    np.testing.assert_allclose(perceived.position_world, simulator.position_world, atol=1e-3)


# ------------------------------------------------------------------------------------ wall frame
def test_wall_frame_beside_the_table_and_of_the_dock_pose():
    """The table stands against the middle of the top wall: poses in front of it are in the top
    wall's area; the dock pose faces the wall square on, at its middle."""
    dock_x, dock_y, dock_yaw = 0.0, 2.0 - 0.825, math.pi / 2
    pose = world_to_wall(dock_x, dock_y, dock_yaw)
    assert (pose.wall, pose.x_m, pose.y_m, pose.phi_deg) == (
        "top",
        pytest.approx(0.825),
        pytest.approx(0.0),
        0.0,
    )
    # Beside the table's ends (x = +-0.5 m) the robot is still in the top area, y = its x.
    for x in (-0.9, 0.9):
        beside = world_to_wall(x, 1.2, math.pi / 2)
        assert beside.wall == "top" and beside.y_m == pytest.approx(x)
    # Backing away from the table, facing it: phi stays 0; turned to the arena's centre: +-180.
    assert world_to_wall(0.0, 0.3, math.pi / 2).phi_deg == pytest.approx(0.0)
    assert abs(world_to_wall(0.0, 0.3, -math.pi / 2).phi_deg) == pytest.approx(180.0)


def test_batch_wall_frame_agrees_with_the_scalar_one_across_areas_and_wraps():
    rng = np.random.default_rng(2)
    x, y = rng.uniform(-2, 2, size=(2, 400))
    yaw = rng.uniform(-3 * math.pi, 3 * math.pi, size=400)
    x_m, y_m, phi, wall = world_to_wall_batch(x, y, yaw, ArenaGeometry())
    for i in range(400):
        one = world_to_wall(x[i], y[i], yaw[i])
        assert one.wall == ("top", "right", "bottom", "left")[wall[i]]
        np.testing.assert_allclose([x_m[i], y_m[i]], [one.x_m, one.y_m], atol=1e-12)
        assert wrap_degrees(phi[i] - one.phi_deg) == pytest.approx(0.0, abs=1e-9)
        assert -180.0 <= phi[i] < 180.0


def test_environment_wall_pose_matches_the_world_pose(stepped_env):
    observation = stepped_env.step(STILL).observation
    for robot in ("teacher", "student"):
        expected = world_to_wall(*observation[f"{robot}_pose"]).as_array()
        np.testing.assert_allclose(observation[f"{robot}_wall_pose"], expected)


def test_environment_episode_ends_at_the_time_limit():
    env = task.load(seed=0, time_limit=0.5)
    env.reset()
    types = [env.step(STILL).step_type for _ in range(5)]
    assert types == [dm_env.StepType.MID] * 4 + [dm_env.StepType.LAST]


@pytest.mark.parametrize(
    "student_pose, teacher_pose, what",
    [
        ((0.0, 0.9, math.pi / 2), (1.2, -1.2, 0.0), "table"),
        ((0.0, -1.0, 0.0), (0.9, -1.0, 0.0), "teacher"),
        ((0.0, 0.0, 0.0), (1.2, -1.2, 0.0), "right wall"),
    ],
)
def test_contact_detector_sees_the_table_the_other_robot_and_walls(
    student_pose, teacher_pose, what
):
    """Driving the student straight into an obstacle is reported as touching it, and not before."""
    env = task.load(seed=0)
    env.task.set_start(student_pose=student_pose, teacher_pose=teacher_pose)
    env.reset()
    assert not env.task.touches_obstacle(env.physics, env.task.student)
    action = np.zeros(6)
    action[0] = 0.3
    touched = False
    for _ in range(80):
        env.step(action)
        touched = env.task.touches_obstacle(env.physics, env.task.student)
        if touched:
            break
    env.close()
    assert touched, f"driving into the {what} was not detected"
