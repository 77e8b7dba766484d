"""The performing agents (``imitation.performance``): every action the student or the teacher
sends satisfies the environment's action spec, in every vision mode; bad settings are refused by
name."""

import peoplebot_sim  # noqa: F401  (sets MUJOCO_GL=egl before mujoco loads)

# isort: split
import math

import numpy as np
import pytest

from associator import encoding
from associator.network import Performance
from imitation import learning, performance, trials
from imitation.cli import main
from imitation.config import RunConfig
from imitation.observers import Calibration, StudentVision
from imitation.performance import StudentAgent, TeacherAgent, make_action
from imitation.recognition import watch_with_vision
from imitation.speedgain import SpeedGainEstimator
from peoplebot_sim import hardware, task
from peoplebot_sim.teacher import Teacher, TeacherConfig
from perception.drive import DriveSpeeds
from perception.wallframe import ArenaGeometry, WallPose, wall_to_world, world_to_wall

ARENA = ArenaGeometry()

WORDS = ("go", "pick", "lift")
WIDTH, HEIGHT = 320, 240  # the trials' camera size


def truth_student(model, spec, word: str = "go", **options) -> StudentAgent:
    """Returns a student told ``word`` that sees the simulator's poses, with ``options`` for
    ``StudentAgent``."""
    return StudentAgent(
        model,
        word,
        StudentVision("truth", watch_teacher=False),
        encoding.VisionEncoder(half_side_m=ARENA.half_side_m),
        spec,
        **options,
    )


def drive_and_check(env, agent, start, n_steps: int) -> np.ndarray:
    """Runs ``agent`` from ``start`` for ``n_steps``, validating every action against the spec
    before the environment sees it; returns the actions (n_steps, 6)."""
    spec = env.action_spec()
    env.task.set_start(student_pose=start)
    timestep = env.reset()
    agent.reset(timestep, start)
    actions = []
    for _ in range(n_steps):
        action = agent.step(timestep)
        assert isinstance(action, np.ndarray) and action.shape == spec.shape
        assert np.all(np.isfinite(action)), action
        spec.validate(action)
        actions.append(action)
        timestep = env.step(action)
    return np.array(actions)


@pytest.fixture(scope="module")
def student_env():
    env = task.load(with_teacher=False, seed=0)
    yield env
    env.close()


@pytest.mark.parametrize("graded", [False, True])
def test_student_actions_in_truth_mode_satisfy_the_spec(student_env, trained_associator, graded):
    """Each word, from the paper's start and from a start near a wall, 40 steps; the wheels are
    actually driven (not only zeros), the gripper rests and the head stays still."""
    spec = student_env.action_spec()
    for word in WORDS:
        for start in (performance.FIG4_START, (-1.5, -1.2, 2.5)):
            agent = truth_student(trained_associator, spec, word, graded=graded)
            actions = drive_and_check(student_env, agent, start, 40)
            assert np.any(actions[:, :2] != 0), (word, start)
            np.testing.assert_array_equal(actions[:, 2:], 0.0)
            assert agent.directive in ("forward", "backward", "turn_right", "turn_left")
            assert agent.motor.shape == (4,) and np.all(np.isfinite(agent.motor))


def test_braking_pose_is_where_braking_at_the_limits_brings_the_robot_to_rest():
    """0.3 m/s braked at 0.3 m/s^2 rolls 0.15 m; 60 deg/s braked at 100 deg/s^2 turns 18 deg more,
    and the position moves along the mean heading; backing, it rolls on backwards; without limits
    the pose is the robot's."""
    aria = hardware.Actuation(linear_accel_mps2=0.3, yaw_accel_degps2=100.0)
    x, y, yaw = performance.braking_pose((0.0, 0.0, 0.0), (0.03, 0.0, 0.0), 0.1, aria)
    np.testing.assert_allclose((x, y, yaw), (0.18, 0.0, 0.0), atol=1e-12)
    turned = math.radians(6.0)
    x, y, yaw = performance.braking_pose((0.0, 0.0, 0.0), (0.0, 0.0, turned), 0.1, aria)
    np.testing.assert_allclose((x, y, yaw), (0.0, 0.0, turned + math.radians(18.0)), atol=1e-12)
    pose = (0.02 * math.cos(turned), 0.02 * math.sin(turned), turned)  # 0.2 m/s while turning
    x, y, yaw = performance.braking_pose((0.0, 0.0, 0.0), pose, 0.1, aria)
    travel, heading = 0.2**2 / 0.6, turned + math.radians(9.0)
    np.testing.assert_allclose(
        (x, y), (pose[0] + travel * math.cos(heading), pose[1] + travel * math.sin(heading))
    )
    x, _, _ = performance.braking_pose((0.5, 0.0, 0.0), (0.47, 0.0, 0.0), 0.1, aria)
    assert x == pytest.approx(0.47 - 0.15)
    still = performance.braking_pose((0.0, 0.0, 0.0), (0.03, 0.01, 0.1), 0.1, hardware.Actuation())
    assert still == pytest.approx((0.03, 0.01, 0.1))


def test_a_student_told_its_limits_asks_its_network_at_its_braking_pose(
    student_env, trained_associator
):
    """With ``brake_ahead`` the student's network is asked at ``braking_pose`` of its last two
    pose estimates, which lies ahead of a moving robot; without, at its pose; the run's setting
    hands the agent the student robot's actuation limits."""
    aria = hardware.Actuation(linear_accel_mps2=0.3, yaw_accel_degps2=100.0)
    spec = student_env.action_spec()
    agents = {
        told: truth_student(trained_associator, spec, brake_ahead=aria if told else None)
        for told in (False, True)
    }
    for told, agent in agents.items():
        student_env.task.set_start(student_pose=performance.FIG4_START)
        timestep = student_env.reset()
        agent.reset(timestep, performance.FIG4_START)
        ahead, previous = [], None
        for _ in range(30):
            timestep = student_env.step(agent.step(timestep))
            if not told:
                assert agent.query_pose is agent.own_pose
            elif previous is not None:
                expected = performance.braking_pose(previous, agent.own_pose, 0.1, aria)
                np.testing.assert_allclose(agent.query_pose, expected)
                ahead.append(np.hypot(*np.subtract(expected[:2], agent.own_pose[:2])))
            previous = agent.own_pose
        if told:
            assert max(ahead) > 0.02, ahead  # it drives: the query runs ahead of it
    config = RunConfig().replace(
        {"performance.brake_ahead": True, "perturbations.actuation.linear_accel_mps2": 0.3}
    )
    told = trials.make_agent(config, "student", "go", student_env, trained_associator, None)
    assert told.brake_ahead == hardware.Actuation(linear_accel_mps2=0.3)
    default = trials.make_agent(RunConfig(), "student", "go", student_env, trained_associator, None)
    assert default.brake_ahead == hardware.Actuation()  # on by default; no limits: no look-ahead
    off = RunConfig().replace({"performance.brake_ahead": False})
    untold = trials.make_agent(off, "student", "go", student_env, trained_associator, None)
    assert untold.brake_ahead is None


class _DensityModel:
    """A stand-in for the hierarchical network: it drives 'forward' (0.6) or turns left (0.4)
    everywhere, and its demonstration density falls with the squared distance of a pose's
    wall-frame x from ``x_m`` (in vision-code units)."""

    vocabulary = WORDS

    def __init__(self, x_m: float):
        self.x_units = x_m / ARENA.half_side_m * (encoding.N_X - 1)
        self.motor = np.array([0.6, 0.0, 0.0, 0.4])

    def perform(self, vision, word):
        return Performance("forward", self.motor, np.zeros(0))

    def pose_log_density(self, vision, word):
        return -((encoding.vision_code_centres(vision)[:, 0] - self.x_units) ** 2)


def test_support_lookahead_reweighs_each_directive_by_the_density_where_it_leads(student_env):
    """Each directive is followed for ``horizon_s`` at its wheel command, and its activation is
    multiplied by the density there raised to ``weight`` (the sum kept): facing a wall 1 m away
    with demonstrations only 1.2 m from it, 'forward' (which leads away from them) loses against
    the turn in place, and directives without activation stay at 0; a student
    driving with it commands what the reweighed activations say; the run config's default (0.5 s,
    0.5) and its off (both 0) reach the hierarchical student."""
    lookahead = performance.SupportLookahead(horizon_s=0.5, weight=1.0)
    drive = DriveSpeeds()
    ends = lookahead.outcomes((0.0, 0.0, math.pi / 2), drive)
    np.testing.assert_allclose(ends[0], (0.0, 0.175, math.pi / 2), atol=1e-12)  # forward
    np.testing.assert_allclose(ends[1], (0.0, -0.175, math.pi / 2), atol=1e-12)  # backward
    np.testing.assert_allclose(ends[2], (0.0, 0.0, math.pi / 2 - math.radians(30)), atol=1e-12)
    np.testing.assert_allclose(ends[3], (0.0, 0.0, math.pi / 2 + math.radians(30)), atol=1e-12)
    model = _DensityModel(x_m=1.2)
    enc = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    pose = (0.0, ARENA.half_side_m - 1.0, math.pi / 2)  # 1 m from the top wall, facing it
    motor = lookahead.reweigh(model, "go", model.motor, pose, drive, enc, ARENA)
    assert motor.sum() == pytest.approx(1.0) and motor[1] == 0.0 and motor[2] == 0.0
    codes = []
    for x, y, yaw in lookahead.outcomes(pose, drive):
        wall = world_to_wall(x, y, yaw, ARENA)
        codes.append(enc.encode(wall.x_m, wall.y_m, wall.phi_deg, clip=True))
    density = model.pose_log_density(np.stack(codes), "go")
    assert density[0] < density[3]  # forward leads away from the demonstrations
    expected = model.motor * np.exp(density - density.max())
    np.testing.assert_allclose(motor, expected / expected.sum())
    assert motor[0] < 0.6 and motor[3] > 0.4
    stronger = performance.SupportLookahead(horizon_s=0.5, weight=4.0)
    assert stronger.reweigh(model, "go", model.motor, pose, drive, enc, ARENA)[0] < motor[0]
    # Where every outcome is equally likely nothing changes.
    flat = _DensityModel(x_m=1.0)
    flat.pose_log_density = lambda vision, word: np.zeros(len(vision))
    np.testing.assert_allclose(
        lookahead.reweigh(flat, "go", flat.motor, pose, drive, enc, ARENA), flat.motor
    )
    spec = student_env.action_spec()
    agent = StudentAgent(
        model,
        "go",
        StudentVision("truth", watch_teacher=False),
        enc,
        spec,
        graded=True,
        support=lookahead,
    )
    agent.reset()
    linear, turn = agent.command(pose)
    np.testing.assert_allclose(agent.motor, motor)
    assert (linear, turn) == pytest.approx(drive.graded_command(motor))
    assert agent.directive == "turn_left"  # forward 0.6 alone would have won
    for bad in (0.0, -1.0, float("nan"), True):
        with pytest.raises(ValueError, match="support lookahead horizon_s must be a number > 0"):
            performance.SupportLookahead(horizon_s=bad, weight=1.0)
    assert trials._support(RunConfig()) == performance.SupportLookahead(0.5, 0.5)  # default
    off = {"performance.support_horizon_s": 0.0, "performance.support_weight": 0.0}
    assert trials._support(RunConfig().replace(off)) is None
    config = RunConfig().replace(
        {"performance.support_horizon_s": 0.5, "performance.support_weight": 2.0}
    )
    assert trials._support(config) == performance.SupportLookahead(0.5, 2.0)
    told = trials.make_agent(config, "student_hierarchical", "go", student_env, model, None)
    assert told.support == performance.SupportLookahead(0.5, 2.0)


def test_measured_speeds_reach_the_hierarchical_students_lookahead(student_env, trained_associator):
    """'nominal' gives no estimator; 'measured' gives the hierarchical student one of both axes,
    'measured_forward' (the default) one of the forward axis, and the paper's network none; a
    student whose robot did not move between two commands follows the directives at the lower
    fractions it measured; an estimator without a lookahead and an unknown choice are refused
    by name."""
    nominal = RunConfig().replace({"performance.support_speeds": "nominal"})
    assert "speed_gains" not in trials._support_arguments(nominal, "student_hierarchical")
    model = _DensityModel(x_m=1.2)
    made = trials.make_agent(RunConfig(), "student_hierarchical", "go", student_env, model, None)
    assert made.speed_gains.axes == ("forward",)
    measured = RunConfig().replace({"performance.support_speeds": "measured"})
    agent = trials.make_agent(measured, "student_hierarchical", "go", student_env, model, None)
    assert isinstance(agent.speed_gains, SpeedGainEstimator)
    assert agent.speed_gains.axes == ("forward", "yaw")
    flat = trials.make_agent(measured, "student", "go", student_env, trained_associator, None)
    assert flat.support is None and flat.speed_gains is None
    pose = (0.0, ARENA.half_side_m - 1.0, math.pi / 2)
    agent.reset()
    first = agent.command(pose)
    agent.command(pose)  # the robot stood still under the first command
    gains = agent.speed_gains.gains
    assert all(g < 1.0 for g, sent in zip(gains, first, strict=True) if sent != 0.0)
    assert gains != (1.0, 1.0)
    enc = encoding.VisionEncoder(half_side_m=ARENA.half_side_m)
    expected = agent.support.reweigh(
        model, "go", model.motor, pose, DriveSpeeds(), enc, ARENA, gains=gains
    )
    np.testing.assert_allclose(agent.motor, expected)
    with pytest.raises(ValueError, match="measured speeds are for the support lookahead"):
        truth_student(model, student_env.action_spec(), speed_gains=SpeedGainEstimator())
    with pytest.raises(ValueError, match=r"performance\.support_speeds"):
        RunConfig().replace({"performance.support_speeds": "guessed"})


def test_support_lookahead_needs_a_network_with_a_density(student_env, trained_associator):
    with pytest.raises(
        ValueError, match="needs a model with a demonstration density, got Associator"
    ):
        truth_student(
            trained_associator,
            student_env.action_spec(),
            support=performance.SupportLookahead(0.5, 1.0),
        )
    config = RunConfig().replace(
        {"performance.support_horizon_s": 0.5, "performance.support_weight": 2.0}
    )
    flat = trials.make_agent(config, "student", "go", student_env, trained_associator, None)
    assert flat.support is None  # the paper's network drives as printed


def test_a_student_not_told_its_limits_identifies_them_and_brakes_ahead_at_them(
    student_env, trained_associator
):
    """With a limit estimator the student, driving a robot with ARIA's limits it is not told,
    identifies them from its own commands and measured speeds (within one step of the candidate
    grid) and asks its network at ``braking_pose`` at the limits identified so far; the run's
    setting hands the agent an estimator instead of the robot's limits."""
    from imitation.limits import AccelerationLimitEstimator

    config = RunConfig().replace(
        {
            "perturbations.actuation.linear_accel_mps2": 0.3,
            "perturbations.actuation.yaw_accel_degps2": 100.0,
            "performance.brake_limits": "estimated",
        }
    )
    env = trials.student_environment(config)
    agent = trials.make_agent(config, "student", "go", env, trained_associator, None)
    assert agent.brake_ahead is None and agent.limit_estimator is not None
    env.task.set_start(student_pose=performance.FIG4_START)
    timestep = env.reset()
    agent.reset(timestep, performance.FIG4_START)
    previous, linear = None, []
    for _ in range(40):
        timestep = env.step(agent.step(timestep))
        limits = agent.limit_estimator.limits
        if previous is not None:
            expected = performance.braking_pose(previous, agent.own_pose, 0.1, limits)
            np.testing.assert_allclose(agent.query_pose, expected)
        previous = agent.own_pose
        linear.append(limits.linear_accel_mps2)
    assert 0.3 / 1.2 < linear[-1] < 0.3 * 1.2, linear  # it drove: the forward limit is identified
    with pytest.raises(ValueError, match="not both"):
        truth_student(
            trained_associator,
            env.action_spec(),
            brake_ahead=hardware.Actuation(),
            limit_estimator=AccelerationLimitEstimator(0.1),
        )


def test_student_actions_with_the_overhead_camera_satisfy_the_spec(trained_associator):
    env = task.load(with_teacher=False, cameras=("overhead",), width=WIDTH, height=HEIGHT, seed=0)
    calibration = Calibration(env.physics, WIDTH, HEIGHT)
    agent = StudentAgent(
        trained_associator,
        "go",
        StudentVision("overhead", calibration, watch_teacher=False),
        encoding.VisionEncoder(half_side_m=ARENA.half_side_m),
        env.action_spec(),
    )
    seen = 0
    env.task.set_start(student_pose=performance.FIG4_START)
    timestep = env.reset()
    agent.reset(timestep, performance.FIG4_START)
    for _ in range(30):
        action = agent.step(timestep)
        assert np.all(np.isfinite(action))
        env.action_spec().validate(action)
        seen += agent.own_pose is not None
        timestep = env.step(action)
    env.close()
    assert seen >= 25, f"the overhead camera should see the student on most steps, saw {seen}/30"


def test_student_actions_with_the_head_camera_satisfy_the_spec(student_env, trained_associator):
    """Head mode performing alone by odometry: the own pose is odometry; the head is not
    commanded."""
    spec = student_env.action_spec()
    for word in WORDS:
        vision = StudentVision(
            "head",
            Calibration(student_env.physics, WIDTH, HEIGHT),
            watch_teacher=False,
            self_localisation="odometry",
        )
        agent = StudentAgent(
            trained_associator,
            word,
            vision,
            encoding.VisionEncoder(half_side_m=ARENA.half_side_m),
            spec,
        )
        actions = drive_and_check(student_env, agent, performance.FIG4_START, 30)
        assert agent.own_pose is not None
        np.testing.assert_array_equal(actions[:, 4:], 0.0)


def test_student_performing_by_landmarks_finds_itself_and_looks_at_them(trained_associator):
    """Head mode performing alone by landmarks (the default), from a start it is not told: it
    finds itself within 3 s, within 8 cm and 2 deg while its first frames vote on the head's tilt
    offset (``LocatorConfig.tilt_search_deg``; the camera here is exact), within 1 cm from its
    tenth fix on, and the head moves (it looks at the landmarks); every action satisfies the
    spec."""
    env = task.load(with_teacher=False, seed=0, cameras=("head",), width=WIDTH, height=HEIGHT)
    vision = StudentVision("head", Calibration(env.physics, WIDTH, HEIGHT), watch_teacher=False)
    agent = StudentAgent(
        trained_associator,
        "go",
        vision,
        encoding.VisionEncoder(half_side_m=ARENA.half_side_m),
        env.action_spec(),
    )
    start = (-0.6, -1.0, 1.2)
    env.task.set_start(student_pose=start)
    timestep = env.reset()
    agent.reset(timestep, start)
    errors, heads = [], []
    for step in range(40):
        action = agent.step(timestep)
        env.action_spec().validate(action)
        heads.append(action[4:])
        if agent.own_pose is None:
            assert step < 30, "the student should find itself within 3 s"
        else:
            truth = timestep.observation["student_pose"]
            heading = abs((agent.own_pose[2] - truth[2] + np.pi) % (2 * np.pi) - np.pi)
            errors.append((np.hypot(*(agent.own_pose[:2] - truth[:2])), np.degrees(heading)))
        timestep = env.step(action)
    env.close()
    errors = np.array(errors)
    assert len(errors) >= 10
    assert errors[:, 0].max() < 0.08 and errors[:, 1].max() < 2.0, errors
    assert errors[10:, 0].max() < 0.01, errors
    assert np.any(np.array(heads) != 0)


def test_landmarks_need_the_head_camera(student_env):
    vision = StudentVision("head", Calibration(student_env.physics, WIDTH, HEIGHT))
    timestep = student_env.reset()
    vision.reset(None, timestep.observation["student_wheel_angles"])
    with pytest.raises(ValueError, match="cameras=\\('head',\\)"):
        vision.update(timestep.observation, 0.0, 0.1)
    with pytest.raises(ValueError, match="vision.self_localisation.*landmarks, odometry"):
        RunConfig.quick().replace({"vision.self_localisation": "gps"})
    with pytest.raises(ValueError, match="'gps'"):
        StudentVision("head", self_localisation="gps")


def test_head_camera_pan_tilt_commands_stay_within_the_spec(trained_associator):
    """Head mode watching the teacher: the pan-tilt controller's commands are clipped into the
    head joints' ranges."""
    env = task.load(cameras=("head",), width=WIDTH, height=HEIGHT, seed=1)
    spec = env.action_spec()
    vision = StudentVision("head", Calibration(env.physics, WIDTH, HEIGHT), watch_teacher=True)
    agent = StudentAgent(
        trained_associator,
        "go",
        vision,
        encoding.VisionEncoder(half_side_m=ARENA.half_side_m),
        spec,
    )
    timestep = env.reset()
    agent.reset(timestep, timestep.observation["student_pose"])
    heads = []
    for _ in range(40):
        action = agent.step(timestep)
        assert np.all(np.isfinite(action))
        spec.validate(action)
        heads.append(action[4:])
        timestep = env.step(action)
    env.close()
    assert np.any(np.array(heads) != 0), "the pan-tilt controller should move the head"


@pytest.mark.parametrize("word", WORDS)
def test_teacher_agent_actions_satisfy_the_spec(student_env, word):
    rng = np.random.default_rng(0)
    start, _ = performance.sample_start("go" if word == "go" else word, rng)
    agent = TeacherAgent(word, student_env.action_spec(), rng=0)
    actions = drive_and_check(student_env, agent, start, 60)
    assert np.any(actions[:, :2] != 0)


def test_teacher_reference_docks_settles_and_then_stands_still(student_env):
    """The teacher's own 'pick' from a trial start passes the settling rule, and once its docking
    is done it sends zero wheel commands (no repeat of its last turn) and stays docked."""
    start, wall = performance.sample_start("pick", np.random.default_rng(4))
    agent = TeacherAgent("pick", student_env.action_spec(), rng=0)
    drive, finished = [], []
    result = performance.run_trial(
        student_env,
        agent,
        "pick",
        start,
        wall,
        stop_on_success=False,
        frame_callback=lambda env, a: (drive.append(a.directive), finished.append(a.finished)),
    )
    assert result.success, result.reason
    assert "held the dock" in result.reason
    assert result.seconds == pytest.approx(60.0)  # not cut short when the teacher finished
    done = finished.index(True)
    assert done < len(finished) - 50
    assert all(d is None for d in drive[done:])
    dock = performance.dock_pose_at("top")
    end = result.trace[-1]
    assert np.hypot(end[0] - dock[0], end[1] - dock[1]) < 0.05
    moved = np.abs(np.diff(result.trace[done + 5 :], axis=0)).max(axis=0)
    assert np.all(moved[:2] < 1e-3) and moved[2] < 1e-3, moved


@pytest.mark.parametrize("lateral_m", [-0.6, 0.6])
def test_lane_docking_backs_up_from_near_the_table_and_docks(student_env, lateral_m):
    """Started nearer the table than the pre-dock point and off the docking lane, the teacher backs
    up towards that point instead of turning its back to the table, then drives in and holds the
    dock; on the lane it drives in without backing up."""

    def run(pose):
        agent = TeacherAgent(
            "pick", student_env.action_spec(), rng=0, teacher_config=TeacherConfig(docking="lane")
        )
        directives = []
        result = performance.run_trial(
            student_env,
            agent,
            "pick",
            wall_to_world(pose),
            "top",
            frame_callback=lambda env, a: directives.append(a.directive),
        )
        return result, directives

    result, directives = run(WallPose(1.05, lateral_m, 0.0, "top"))
    assert result.success, result.reason
    assert "backward" in directives
    facing = [abs(world_to_wall(*pose).phi_deg) for pose in result.trace]
    assert max(facing) < 90.0, max(facing)  # the table stays in front of it
    result, directives = run(WallPose(1.4, 0.05, 0.0, "top"))
    assert result.success, result.reason
    assert "backward" not in directives


def _teacher_pick(env, pose: WallPose, teacher_config: TeacherConfig):
    """Runs the teacher's 'pick' from a wall-frame pose for a whole trial; returns the trial, its
    directives and phases."""
    agent = TeacherAgent("pick", env.action_spec(), rng=0, teacher_config=teacher_config)
    steps = []
    result = performance.run_trial(
        env,
        agent,
        "pick",
        wall_to_world(pose),
        "top",
        stop_on_success=False,
        frame_callback=lambda e, a: steps.append((a.directive, a.controller.phase)),
    )
    return result, steps


@pytest.mark.parametrize("lateral_m", [-0.6, 0.6])
def test_funnel_docking_pursues_the_centre_line_and_docks_along_the_table(student_env, lateral_m):
    """The funnel docking never backs up from a trial start: near the table and far off the centre
    line it turns along the table and drives to the dock, the table always on its side or ahead;
    from farther out its offset shrinks as it drives in (pursuit). Both end centred and square."""
    config = TeacherConfig(docking="funnel")
    for start in (
        WallPose(1.05, lateral_m, 0.0, "top"),
        WallPose(1.55, lateral_m / 2, 20.0, "top"),
    ):
        result, steps = _teacher_pick(student_env, start, config)
        assert result.success, result.reason
        assert "backward" not in [d for d, _ in steps]
        walls = [world_to_wall(*pose, wall="top") for pose in result.trace]
        assert max(abs(w.phi_deg) for w in walls) < 100.0
        assert max(abs(w.y_m) for w in walls) <= abs(start.y_m) + 0.02
        end = walls[-1]
        assert abs(end.y_m) <= config.funnel_tolerance_m + 0.01
        assert abs(end.x_m - config.dock_x_m) < 0.08 and abs(end.phi_deg) < 8.0


def test_funnel_docking_backs_out_square_from_nearer_the_table_than_the_dock():
    """Nearer the table than the dock the funnel docking backs out square to it; at the dock,
    centred, it is done (None) and the teacher squares up and settles."""
    teacher = Teacher(TeacherConfig(docking="funnel"), rng=0)
    dock_x, dock_y, _ = teacher.dock_pose
    teacher.begin("pick")
    assert teacher._funnel_docking(dock_x + 0.1, dock_y + 0.05, np.pi / 2) == "backward"
    assert teacher._funnel_docking(dock_x + 0.1, dock_y + 0.05, np.pi / 2 + 0.5) == "turn_right"
    assert teacher._funnel_docking(dock_x + 0.02, dock_y - 0.01, np.pi / 2) is None
    # Beside the dock at its depth: along the table, towards the centre line.
    assert teacher._funnel_docking(dock_x + 0.2, dock_y, np.pi) == "forward"
    assert teacher._funnel_docking(dock_x - 0.2, dock_y, 0.0) == "forward"


def _drawn_per_pick(teacher: Teacher, *names: str, picks: int = 200) -> np.ndarray:
    """Begins 'pick' ``picks`` times; returns each named drawn value per pick, shape
    (len(names), picks)."""
    draws = []
    for _ in range(picks):
        teacher.begin("pick")
        draws.append([getattr(teacher, name) for name in names])
    return np.array(draws).T


def test_funnel_docking_first_pursues_its_drawn_miss_then_the_dock():
    """Each 'pick' draws a miss: beyond its drawn depth the teacher pursues the line beside the
    centre line, nearer the table the dock; the reference's controller (``undisturbed``) never
    misses."""
    config = TeacherConfig(docking="funnel", funnel_miss_m=0.25, funnel_miss_depth_fraction=1.0)
    teacher = Teacher(config, rng=3)
    dock_x, dock_y, _ = teacher.dock_pose
    miss, depth = _drawn_per_pick(teacher, "_miss_m", "_miss_depth_m")
    assert np.all(np.abs(miss) <= 0.25) and miss.min() < -0.2 and miss.max() > 0.2
    assert np.all((depth >= 0) & (depth <= config.funnel_lookahead_m))
    teacher._miss_m, teacher._miss_depth_m = 0.2, 0.1
    # Far out: straight on along the miss line; on the centre line it turns towards the miss line.
    assert teacher._funnel_docking(dock_x + 0.2, dock_y - 0.6, np.pi / 2) == "forward"
    assert teacher._funnel_docking(dock_x, dock_y - 0.6, np.pi / 2) == "turn_right"
    # Nearer than the drawn depth: at the dock.
    assert teacher._funnel_docking(dock_x + 0.2, dock_y - 0.05, np.pi / 2) == "turn_left"
    assert config.undisturbed().funnel_miss_m == 0.0
    quiet = Teacher(config.undisturbed(), rng=3)
    quiet.begin("pick")
    assert quiet._miss_m == 0.0
    # ``funnel_miss_depth_fraction`` draws the depths within that share of the lookahead, the
    # same draws scaled (1 is the range above; the default since version 0.13.0 is half of it).
    near = TeacherConfig(docking="funnel", funnel_miss_m=0.25, funnel_miss_depth_fraction=0.3)
    _, near_depth = _drawn_per_pick(Teacher(near, rng=3), "_miss_m", "_miss_depth_m")
    np.testing.assert_allclose(near_depth, 0.3 * depth)
    default = TeacherConfig(docking="funnel", funnel_miss_m=0.25)
    _, default_depth = _drawn_per_pick(Teacher(default, rng=3), "_miss_m", "_miss_depth_m")
    np.testing.assert_allclose(default_depth, 0.5 * depth)
    with pytest.raises(ValueError, match="funnel_miss_depth_fraction must be in"):
        TeacherConfig(funnel_miss_depth_fraction=0.0)


def test_funnel_overshoot_rolls_on_past_the_dock_and_the_teacher_backs_out():
    """With ``funnel_overshoot_s`` each 'pick' draws how long its wheels roll on at the dock;
    arrived, they drive forward that long while the teacher commands its controller's directive;
    more than ``funnel_tolerance_m`` past the dock it backs out square to the table, also while
    squaring or settling. Without it (the default, and the reference's ``undisturbed``) nothing
    is drawn and a robot past the dock counts as arrived, as before the option existed."""
    config = TeacherConfig(docking="funnel", funnel_overshoot_s=0.6)
    teacher = Teacher(config, rng=5)
    dock_x, dock_y, _ = teacher.dock_pose
    (rolls,) = _drawn_per_pick(teacher, "_roll_on_s")
    assert np.all((rolls >= 0) & (rolls <= 0.6)) and rolls.min() < 0.05 and rolls.max() > 0.55
    # Arrived: the wheels roll on for the drawn time (0.5 s: 5 steps of 0.1 s), then obey.
    teacher.begin("pick")
    teacher._roll_on_s = 0.5
    teacher.phase = "square"
    executed = [teacher._disturbed("turn_left", 0.1) for _ in range(7)]
    assert executed == ["forward"] * 5 + ["turn_left"] * 2
    # Past the dock, square or settling: it backs out (turning square first when askew).
    for phase in ("square", "settle"):
        teacher.phase = phase
        assert teacher._pick(dock_x + 0.02, dock_y + 0.1, np.pi / 2, None) == "backward"
        assert teacher.phase == "back_up"
    teacher.phase = "settle"
    assert teacher._pick(dock_x, dock_y + 0.1, np.pi / 2 + 0.5, None) == "turn_right"
    # Within the tolerance past the dock it has arrived; beyond it, it backs out.
    assert teacher._funnel_docking(dock_x + 0.02, dock_y + 0.04, np.pi / 2) is None
    assert teacher._funnel_docking(dock_x + 0.02, dock_y + 0.06, np.pi / 2) == "backward"
    # The default draws nothing and keeps the old arrival rule.
    plain = Teacher(TeacherConfig(docking="funnel"), rng=5)
    plain.begin("pick")
    assert plain._roll_on_s == 0.0
    assert plain._funnel_docking(dock_x + 0.02, dock_y + 0.1, np.pi / 2) is None
    assert config.undisturbed().funnel_overshoot_s == 0.0
    with pytest.raises(ValueError, match="teacher.funnel_overshoot_s must be a finite number"):
        TeacherConfig(funnel_overshoot_s=-0.1)


@pytest.mark.parametrize("settle", ["align", "pattern"])
def test_settling_turns_towards_square_or_follows_the_pattern(settle):
    """Docked askew, the 'align' settle turns back towards square at every step (alternating about
    it once square); the 'pattern' settle turns as its pattern says whatever the heading."""
    config = TeacherConfig(settle=settle, slip_rate_per_s={"go": 0.0, "pick": 0.0, "lift": 0.0})
    teacher = Teacher(config, rng=0)
    dock_x, dock_y, dock_yaw = teacher.dock_pose
    teacher.begin("pick")
    teacher.phase, teacher._settle_steps = "settle", 0
    askew = dock_yaw - np.radians(10.0)  # turned right of square
    turns = [teacher.step((dock_x, dock_y, askew)) for _ in range(4)]
    if settle == "align":
        assert turns == ["turn_left"] * 4
    else:
        assert turns == list(config.settle_pattern[:4])
    with pytest.raises(
        ValueError, match="unknown teacher.settle 'wiggle'; allowed: align, pattern"
    ):
        TeacherConfig(settle="wiggle")


@pytest.mark.parametrize("row", ["pick", "pick_other_wall"])
def test_pick_starts_lie_in_their_wall_area_within_the_stated_box(row):
    """The box's far corners (1.6 m out, 0.8 m aside) lie in a neighbouring wall's area; those
    starts are redrawn, so every 'pick' starts where the wall frame refers to its own wall."""
    rng = np.random.default_rng(3)
    walls = set()
    for _ in range(300):
        start, wall = performance.sample_start(row, rng)
        pose = world_to_wall(*start)
        walls.add(wall)
        assert pose.wall == wall
        assert 1.0 <= pose.x_m <= 1.6 and abs(pose.y_m) <= 0.8 and abs(pose.phi_deg) <= 45.0
    assert walls == ({"top"} if row == "pick" else {"right", "bottom", "left"})


def test_make_action_clips_into_the_spec(student_env):
    spec = student_env.action_spec()
    for drive, head in (
        ((5.0, -9.0), (4.0, -3.0)),
        ((-5.0, 9.0), (-4.0, 3.0)),
        ((0.1, 0.2), (0.3, 0.4)),
    ):
        action = make_action(spec, drive, head)
        spec.validate(action)
        np.testing.assert_array_equal(
            action[[0, 1, 4, 5]],
            np.clip([*drive, *head], spec.minimum[[0, 1, 4, 5]], spec.maximum[[0, 1, 4, 5]]),
        )
        np.testing.assert_array_equal(action[2:4], 0.0)


# ------------------------------------------------------------------------------ refused settings
def test_unknown_vision_mode_is_refused_by_name():
    with pytest.raises(ValueError, match="'sonar'.*truth, overhead, head"):
        StudentVision("sonar")
    with pytest.raises(ValueError, match="'sonar'"):
        RunConfig.quick().replace({"vision.mode": "sonar"})
    with pytest.raises(ValueError, match="'truth'"):
        watch_with_vision(0, 10, "truth", progress=False)
    with pytest.raises(ValueError, match="calibration"):
        StudentVision("overhead")


def test_unknown_motor_source_is_refused_by_name():
    with pytest.raises(ValueError, match="'telepathy'.*teacher, vision"):
        learning.check_motor_source("telepathy")
    with pytest.raises(ValueError, match="'telepathy'"):
        RunConfig.quick().replace({"learning.motor_source": "telepathy"})


def test_unknown_word_is_refused_by_name(student_env, trained_associator):
    spec = student_env.action_spec()
    with pytest.raises(ValueError, match="'jump'"):
        TeacherAgent("jump", spec)
    with pytest.raises(ValueError, match="'jump'"):
        StudentAgent(
            trained_associator,
            "jump",
            StudentVision("truth"),
            encoding.VisionEncoder(half_side_m=ARENA.half_side_m),
            spec,
        )


def test_unknown_row_is_refused_by_name():
    with pytest.raises(ValueError, match="'dance'.*go, pick, pick_other_wall, lift"):
        performance.sample_start("dance", np.random.default_rng(0))


@pytest.mark.parametrize(
    "field, value",
    [
        ("learning.train_steps", 0),
        ("performance.trials", -1),
        ("workers", 0),
        ("learning.test_steps", 2.5),
        ("performance.trial_seconds", 4.0),
        ("performance.trial_seconds", float("nan")),
        ("performance.brake_ahead", "yes"),
        ("performance.brake_limits", "guessed"),
        ("vision.overhead_registration", "tape"),
        ("performance.support_weight", -1.0),
        ("performance.support_horizon_s", float("inf")),
        ("performance.support_weight", 0.0),  # the horizon left at 0.5 s
    ],
)
def test_bad_reproduce_settings_are_refused_by_name(field, value):
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        RunConfig.quick().replace({field: value})


def test_cli_refuses_an_unknown_vision_mode(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "--quick", "--vision", "sonar"])
    assert exit_info.value.code == 2
    assert "sonar" in capsys.readouterr().err
